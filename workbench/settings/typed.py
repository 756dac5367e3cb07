"""The settings of a study, checked once and typed: what the study and the dataset stage take.

:func:`study_settings` checks a composed or resolved config (:func:`workbench.settings.schema.check_study_config`)
and turns it into the schema's own dataclasses, every setting the config leaves out at its schema default, so that
below it settings are attributes (``settings.basis.coverage``, ``settings.dataset.eval_fraction``) and no default is
restated. The operations on settings a study makes (:func:`changed_dataset`, :func:`without_settings`) and the
canonical form the dataset cache keys captures by (:func:`canonical_settings`) live here too.
"""

from __future__ import annotations

import json
from dataclasses import MISSING as NO_DEFAULT
from dataclasses import asdict, dataclass, field, fields, is_dataclass, make_dataclass, replace
from typing import Any, Mapping, Optional, Sequence

from omegaconf import MISSING, OmegaConf

from workbench.core.errors import WorkbenchError
from workbench.core.solvers import BOUNDS, SOLVER_KINDS
from workbench.settings.schema import (
    DATASET_EXTRA_SCHEMAS,
    DATASET_EXTRAS,
    DATASET_SCHEMAS,
    BasisSchema,
    MetricSchema,
    PaperSchema,
    PathsSchema,
    SolverSchema,
    check_dataset_group,
    checked_settings,
    nested_schema,
)


def typed(schema: type, values: Mapping):
    """``values`` as an instance of the dataclass ``schema``: nested schemas typed in turn, a field ``values``
    leaves out at its default (None where the schema has no default). The values are not checked here."""
    given = {}
    for spec in fields(schema):
        if spec.name in values:
            value, nested = values[spec.name], nested_schema(spec)
            given[spec.name] = typed(nested, value) if nested is not None and isinstance(value, Mapping) else value
        else:
            given[spec.name] = default_value(spec)
    return schema(**given)


def default_value(spec):
    """A typed field's value when its setting is left out: the schema default (None where it has none)."""
    if spec.default_factory is not NO_DEFAULT:
        return spec.default_factory()
    return None if spec.default is NO_DEFAULT or spec.default == MISSING else spec.default


def _dataset_class(kind: str) -> type:
    """The typed settings of a dataset kind: its schema, then the settings only added with ``+``
    (:data:`~workbench.settings.schema.DATASET_EXTRAS`, None when not given; a group of them typed by its schema,
    :data:`~workbench.settings.schema.DATASET_EXTRA_SCHEMAS`)."""
    extras = [name for name, kinds in DATASET_EXTRAS.items() if kind in kinds]
    return make_dataclass(
        f"{DATASET_SCHEMAS[kind].__name__.removesuffix('Schema')}Settings",
        [(name, DATASET_EXTRA_SCHEMAS.get(name, Any), field(default=None)) for name in extras],
        bases=(DATASET_SCHEMAS[kind],),
    )


DATASET_SETTINGS = {kind: _dataset_class(kind) for kind in DATASET_SCHEMAS}
"""Dataset kind -> its typed settings (a subclass of the kind's schema)."""
for _settings in DATASET_SETTINGS.values():  # module attributes, so that pickle finds them by name
    _settings.__module__ = __name__
    globals()[_settings.__name__] = _settings


def dataset_settings(values) -> Any:
    """A ``dataset`` group given alone (the Python API's :func:`workbench.api.build_captures`, a test's builder call)
    as its kind's typed settings (:data:`DATASET_SETTINGS`), checked first
    (:func:`~workbench.settings.schema.check_dataset_group`); typed settings are returned as they are (they were
    checked when they were made). :func:`study_settings` checks and types the whole study instead.

    Raises
    ------
    WorkbenchError
        Naming the first setting that breaks its rule, or a ``kind`` the workbench has no builder for.
    """
    if is_dataclass(values):
        return values
    if OmegaConf.is_config(values):
        values = OmegaConf.to_container(values, resolve=True)
    if not isinstance(values, Mapping):
        raise WorkbenchError(f"the dataset settings must be a mapping, got {type(values).__name__}")
    check_dataset_group(values)
    return _typed_dataset(values)


def _typed_dataset(values: Mapping) -> Any:
    """A checked ``dataset`` group as its kind's typed settings."""
    kind = values.get("kind")
    if kind not in DATASET_SETTINGS:
        raise WorkbenchError(f"dataset.kind must be one of {sorted(DATASET_SETTINGS)}, got {kind!r}")
    return typed(DATASET_SETTINGS[kind], values)


SCORING_ONLY = ("held_out", "folds", "fold_gap_s")
"""Dataset settings that choose which built frames are held out and scored, not what is built: left out of the
build and of its cache key, so the same data are built once whatever is held out of them."""


def changed_dataset(settings, **changes) -> Any:
    """The typed dataset settings with some values changed (a name, a number, a list): the study's own changes
    (the clean capture, the variants built for ``eval_on``), neither typed nor checked again."""
    return replace(settings, **changes)


def without_settings(settings, names: Sequence[str]) -> Any:
    """The typed dataset settings with ``names`` back at their schema defaults (None for a setting added with
    ``+``): what a build does not depend on (:data:`SCORING_ONLY`, ``hand_basis``)."""
    return replace(settings, **{spec.name: default_value(spec) for spec in fields(settings) if spec.name in names})


def clean_dataset(dataset) -> Any:
    """The dataset settings of the clean capture of the same take: the synthetic actor without marker noise and
    without marker dropout (same seed, so the same performance and head motion).

    Raises
    ------
    WorkbenchError
        For a dataset whose clean version is unknown (a real capture's noise cannot be switched off).
    """
    if dataset.kind != "synthetic":
        raise WorkbenchError(
            f"basis.coverage_on 'clean' and metric.score_clean need the clean version of the "
            f"capture, which only the synthetic actor has (dataset.kind synthetic), got {dataset.kind!r}"
        )
    return changed_dataset(dataset, marker_noise_mm=0.0, gap_rate=0.0)


def built_settings(settings) -> tuple[Any, dict]:
    """The typed dataset settings a build reads, without :data:`SCORING_ONLY` and ``hand_basis`` (its file is read
    after the build, outside the cache: the same data are cached once, a changed file read afresh), and their
    canonical form (:func:`canonical_settings`), what the dataset cache keys the build by."""
    built = without_settings(settings, ("hand_basis", *SCORING_ONLY))
    return built, canonical_settings(built)


def canonical_settings(settings) -> dict:
    """Typed settings as plain JSON values (every field, nested groups as mappings, keys sorted): what the dataset
    cache keys captures by (:func:`workbench.dataset.cache.dataset_key`)."""
    return json.loads(json.dumps(asdict(settings), sort_keys=True, default=str))


def solver_options(solver: SolverSchema) -> dict:
    """One ``solver`` entry as the keyword arguments of :func:`workbench.numerics.solve.solve_weights`: a kind that
    does not bound the weights (least squares) takes no bounds (:data:`workbench.core.solvers.SOLVER_KINDS`)."""
    entry = SOLVER_KINDS.get(solver.kind)  # a kind of none (a bare typed entry): its bounds, for the solve to judge
    bounded = entry is None or entry.constrained
    return {"kind": solver.kind, **{bound: getattr(solver, bound) if bounded else None for bound in BOUNDS}}


@dataclass
class StudySettings:
    """A study's settings, checked and typed.

    Attributes
    ----------
    dataset : the kind's typed settings (:data:`DATASET_SETTINGS`)
    basis : BasisSchema
    solvers : dict
        Solver name -> :class:`~workbench.settings.schema.SolverSchema`, in the configured order.
    metric : MetricSchema
    paths : PathsSchema
    study : str
    save_inputs : bool
    paper : PaperSchema or None
    """

    dataset: Any
    basis: BasisSchema
    solvers: dict
    metric: MetricSchema
    paths: PathsSchema
    study: Optional[str] = None
    save_inputs: bool = False
    paper: Optional[PaperSchema] = None


def study_settings(cfg, overrides: Sequence[str] = ()) -> StudySettings:
    """Check a study config and type it; typed settings are returned as they are.

    Parameters
    ----------
    cfg : omegaconf.DictConfig, mapping or StudySettings
        A composed study config, or one resolved (a record's ``config.yaml``).
    overrides : sequence of str
        The overrides that made it (a retired setting given again is refused).

    Raises
    ------
    WorkbenchError
        Naming the first setting that breaks its rule (:func:`workbench.settings.schema.check_study_config`).
    """
    if isinstance(cfg, StudySettings):
        return cfg
    plain, _ = checked_settings(cfg, overrides)
    metric, paths, paper = plain.get("metric") or {}, plain.get("paths") or {}, plain.get("paper")
    return StudySettings(
        dataset=_typed_dataset(plain["dataset"]),
        basis=typed(BasisSchema, plain["basis"]),
        solvers={name: typed(SolverSchema, spec) for name, spec in plain["solver"].items()},
        metric=typed(MetricSchema, metric),
        paths=typed(PathsSchema, paths),
        study=plain.get("study"),
        save_inputs=plain.get("save_inputs") is True,
        paper=typed(PaperSchema, paper) if isinstance(paper, Mapping) else None,
    )
