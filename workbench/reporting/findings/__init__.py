"""Findings and claims stated from the numbers: the findings of a run (run), its paired comparisons within the run
(comparisons) and its summary (run_summary), those of a sweep and of the other bases (sweep) and the sweep's summary
(sweep_summary), and the paper's claims' verdicts (claims)."""
