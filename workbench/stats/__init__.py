"""Statistics of a run's errors: intervals over time, paired comparisons, Holm, and the orderings that hold by
construction (:mod:`~workbench.stats.identities`)."""
