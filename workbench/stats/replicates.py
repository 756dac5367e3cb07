"""Which runs of a sweep are replicates: runs that differ in a seed are replicates only when the seed changes the
data the bases are fitted on or scored against.

A sweep compares two bases over its replicates (seeds) by the paired t-interval on log ratios
(:func:`workbench.stats.statistics.paired_ratio_interval`): the spread of the per-seed ratios stands for the spread
of new data. A seed that changes only an optimiser's start (ICA's initial rotation, NMF's start:
``basis.alternatives_seed``), or a draw that the run does not make (``basis.subset_seed`` without
``basis.hand_subset=random<k>``), leaves the data as they were: the runs are pseudo-replicates, their spread is the
optimiser's jitter on one data set, and no "A < B" is drawn from them (:func:`pseudo_replicate_reason`).

Config keys in, a reason out; nothing is read from disk.
"""

from __future__ import annotations

from typing import Callable, Mapping, Sequence

OPTIMISER_SEEDS: dict[str, str] = {
    "basis.alternatives_seed": "ICA's initial rotation and NMF's start",
}
"""Seeds that change only an optimiser's start, never the data -> what they seed."""
CONDITIONAL_SEEDS: dict[str, tuple[str, Callable[[object], bool], str]] = {
    "basis.subset_seed": (
        "basis.hand_subset",
        lambda value: str(value).startswith("random"),
        "the draw of hand shapes, made only for basis.hand_subset=random<k>",
    ),
}
"""Seeds that change the data only under a setting -> (that setting, whether its value makes the draw, what the
seed draws)."""
PSEUDO_REPLICATES = "not replicates"
"""The verdict of a comparison over pseudo-replicates (no "<" is drawn)."""


def changes_data(key: str, config: Mapping[str, object]) -> bool:
    """Whether runs differing in the seed ``key`` (a dotted config key) differ in their data, given the settings
    they share (``config``, dotted keys). A seed this module does not know is taken to change the data (as
    ``dataset.seed`` of the synthetic actor does)."""
    if key in OPTIMISER_SEEDS:
        return False
    if key in CONDITIONAL_SEEDS:
        setting, draws, _ = CONDITIONAL_SEEDS[key]
        return bool(draws(config.get(setting)))
    return True


def pseudo_replicate_reason(varying: Sequence[str], config: Mapping[str, object]) -> str:
    """Why the runs of one condition are not replicates, "" when they are.

    Parameters
    ----------
    varying : sequence of str
        The replicate (seed) settings whose values differ between the runs compared.
    config : mapping
        The settings the runs share (dotted keys: ``basis.hand_subset``, ...).

    Returns
    -------
    str
        "" when some varying seed changes the data (or none varies: nothing to say); otherwise which seeds vary
        and what they seed, ending "the data are the same in every run".
    """
    varying = list(varying)
    if not varying or any(changes_data(key, config) for key in varying):
        return ""
    what = [
        f"{key} ({OPTIMISER_SEEDS[key] if key in OPTIMISER_SEEDS else CONDITIONAL_SEEDS[key][2]})" for key in varying
    ]
    return f"the runs differ only in {', '.join(what)}: the data are the same in every run"
