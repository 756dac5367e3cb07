"""The study layer: one run of a study, from its config to plain results (no files written).

:mod:`~workbench.study.run` (``run_study``: the order of the stages), :mod:`~workbench.study.protocols` (which frames
and hand shapes are fitted and scored), :mod:`~workbench.study.fitting` (the bases), :mod:`~workbench.study.scoring`
(alpha, errors, intuitiveness), :mod:`~workbench.study.results` (what a run returns) and
:mod:`~workbench.study.summary` (the results as the values a record keeps).
"""

from workbench.study.run import run_study

__all__ = ["run_study"]
