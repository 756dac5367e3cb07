"""Settings with no effect in a run: for each setting, the rule that says why the rest of the config leaves it unused
(:data:`INEFFECTIVE`), and the settings a command line gives that have none, one sentence each
(:func:`ineffective_settings`, which :func:`workbench.settings.schema.checked_settings` warns of or refuses)."""

from __future__ import annotations

from typing import Callable, Mapping, Optional, Sequence

from workbench.settings.bases import ALTERNATIVE_BASES


def _variants(dataset: Mapping) -> set:
    chosen = set()
    for key in ("train_on", "eval_on"):
        value = dataset.get(key)
        chosen |= {value} if isinstance(value, str) else set(value or ())
    return chosen


def _held_out(plain: Mapping) -> list:
    value = plain["dataset"].get("held_out") or []
    return [value] if isinstance(value, str) else list(value)


def _alternatives(plain: Mapping) -> list:
    value = plain["basis"].get("alternatives") or []
    return [value] if isinstance(value, str) else list(value)


def _unsized() -> list[str]:
    return [label for label, basis in ALTERNATIVE_BASES.items() if not basis.sized]


def _drawing() -> list[str]:
    return [label for label, basis in ALTERNATIVE_BASES.items() if basis.draws]


INEFFECTIVE: dict[str, Callable[[Mapping], Optional[str]]] = {
    "dataset.eval_fraction": lambda c: (
        None
        if c["dataset"].get("split") == "tail" or "tail" in _held_out(c)
        else f"only dataset.split=tail or dataset.held_out=tail uses it (this run: split={c['dataset'].get('split')})"
    ),
    "dataset.folds": lambda c: None if "kfold" in _held_out(c) else "only dataset.held_out=kfold uses it",
    "dataset.fold_gap_s": lambda c: None if "kfold" in _held_out(c) else "only dataset.held_out=kfold uses it",
    "dataset.eval_seed": lambda c: (
        None
        if c["dataset"].get("split") == "other_take"
        else f"only dataset.split=other_take uses it (this run: split={c['dataset'].get('split')})"
    ),
    "dataset.gap_mean_frames": lambda c: (
        None
        if (c["dataset"].get("gap_rate") or 0) > 0
        else "it shapes the simulated dropout, and dataset.gap_rate is 0"
    ),
    "dataset.gap_seed": lambda c: (
        None if (c["dataset"].get("gap_rate") or 0) > 0 else "it seeds the simulated dropout, and dataset.gap_rate is 0"
    ),
    "dataset.gap_max_fill_frames": lambda c: (
        None
        if c["dataset"].get("gap_policy") == "linear"
        else f"only dataset.gap_policy=linear fills gaps (this run: {c['dataset'].get('gap_policy')})"
    ),
    "dataset.gap_fit_on": lambda c: (
        None
        if c["dataset"].get("gap_policy") == "masked"
        else f"only dataset.gap_policy=masked uses it (this run: {c['dataset'].get('gap_policy')})"
    ),
    "dataset.mesh_fraction": lambda c: (
        None
        if _variants(c["dataset"]) & {"mesh", "mesh_rbf"}
        else "no data variant of this run lives on the mesh (dataset.train_on/eval_on)"
    ),
    "dataset.mesh_vertex_step": lambda c: (
        None
        if "mesh" in _variants(c["dataset"])
        else "no data variant of this run lives on the mesh (dataset.train_on)"
    ),
    "dataset.rbf": lambda c: (
        None
        if "mesh" in _variants(c["dataset"])
        else "the RBF carries markers onto the mesh, and no data variant of this run lives on the mesh"
    ),
    "dataset.neutral_frame": lambda c: (
        None
        if c["dataset"].get("kind") != "mesh_sequence" or not c["dataset"].get("neutral")
        else "dataset.neutral names the neutral face"
    ),
    "dataset.weight_frame_rate": lambda c: (
        None if c["dataset"].get("weight_curves") else "only weight curves given with dataset.weight_curves use it"
    ),
    "basis.coverage": lambda c: (
        None if c["basis"].get("n_components") is None else f"basis.n_components={c['basis']['n_components']} fixes m"
    ),
    "basis.paper_regime": lambda c: (
        None
        if c["basis"].get("n_components") is None and not c["dataset"].get("eval_on")
        else "it adds an m = n fit beside the coverage rule's m, and basis.n_components fixes m (or dataset.eval_on carries "
        "the bases onto other points)"
    ),
    "basis.subset_seed": lambda c: (
        None
        if str(c["basis"].get("hand_subset")).startswith("random")
        else f"only basis.hand_subset=random<k> draws (this run: {c['basis'].get('hand_subset')})"
    ),
    "basis.alternatives_n": lambda c: (
        None
        if any(ALTERNATIVE_BASES[name].sized for name in _alternatives(c))
        else f"no basis.alternatives other than {' and '.join(_unsized())} are fitted"
    ),
    "basis.alternatives_seed": lambda c: (
        None
        if any(ALTERNATIVE_BASES[name].draws for name in _alternatives(c))
        else f"only basis.alternatives {' and '.join(_drawing())} draw"
    ),
    **{
        f"basis.{basis.options_key}": (
            lambda c, label=label: None if label in _alternatives(c) else f"{label} is not in basis.alternatives"
        )
        for label, basis in ALTERNATIVE_BASES.items()
    },
    "basis.intuitiveness": lambda c: (
        None if _alternatives(c) else "intuitiveness is measured only with basis.alternatives"
    ),
}
"""Setting -> why it has no effect in a run (None when it has one)."""


def ineffective_settings(plain: Mapping, overrides: Sequence[str]) -> list[str]:
    """The settings given in ``overrides`` that have no effect in the run ``plain`` describes, one sentence each."""
    found = []
    for override in overrides:
        key = str(override).split("=", 1)[0].lstrip("+~")
        for setting, reason in INEFFECTIVE.items():
            if key == setting or key.startswith(setting + "."):
                why = reason(plain)
                if why is not None:
                    found.append(f"{key} has no effect in this run: {why}")
    return found
