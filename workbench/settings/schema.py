"""The settings of a study: their types and their ranges, as dataclasses in Hydra's ConfigStore.

Every study starts from :class:`StudySchema` (``studies/paper.yaml`` lists ``workbench_schema`` first in its
defaults) and every dataset file from its kind's schema, so a value of the wrong type (``solver.box.lower=x``,
``basis.projections=affine``) or a key that does not exist fails when the config is composed, before anything
runs, with one line naming the key and the type it takes. Each field's ``metadata`` holds the rule its value must
meet (a range, a set of names); :func:`check_study_config` applies them, refuses keys no schema knows (added with
``+``), names an interpolation that cannot be resolved, and finds settings given on the command line that have no
effect in the run. The command line runs it before Hydra makes the run folder (``workbench.record.tracking.RunFolders``)
and :func:`workbench.api.run` again, so every value is checked before anything is built or written. Fields are in
the order of the YAML files, so that the resolved config reads as before. ``Any`` marks settings that take a name
or a list (``train_on``, ``hand_subset``) and the true/false settings (so that ``save_inputs=2`` reaches the rule
instead of being read as true).
"""

from __future__ import annotations

import re
from dataclasses import MISSING as NO_DEFAULT
from dataclasses import dataclass, field, fields, is_dataclass, make_dataclass
from typing import Any, Dict, List, Mapping, Optional, Sequence

from omegaconf import MISSING

from workbench.core.errors import WorkbenchError, check_utf8
from workbench.core.frames import FRAME_DTYPES
from workbench.core.solvers import SOLVER_KINDS
from workbench.settings.bases import ALTERNATIVE_BASES
from workbench.settings.ineffective import (
    _alternatives,
    _held_out,
    ineffective_settings,
)
from workbench.settings.rules import (
    BOOLEAN,
    COVERAGE_ON,
    GAP_FIT_ON,
    GAP_POLICIES,
    POSITIVE,
    RBF_KERNELS,
    RBF_METRICS,
    RBF_SCALE_INVARIANT,
    SEED,
    _integer,
    _number,
    checked,
    integer,
    interval,
    key_of,
    meta,
    one_of,
    rule,
)

# ---------------------------------------------------------------------------------------------------------------
# The rules of the schema's fields (the generic ones live in workbench.settings.rules)
# ---------------------------------------------------------------------------------------------------------------


def names(*choices: str, optional: bool = False, allow_empty: bool = False) -> dict:
    """One of ``choices`` or a list of distinct ones."""

    def check(value):
        listed = [value] if isinstance(value, str) else value
        return (
            isinstance(listed, (list, tuple))
            and (allow_empty or len(listed) > 0)
            and all(isinstance(name, str) and name in choices for name in listed)
            and len(set(listed)) == len(listed)
        )

    return rule(check, f"one of {choices} or a list of distinct ones", optional=optional)


def plain_name_rule(value) -> bool:
    """A name that can become a file or folder name without leaving its parent (no separator, not '.' or '..')."""
    return (
        isinstance(value, str)
        and bool(value)
        and value not in (".", "..")
        and value == value.strip()
        and not any(character in value for character in "/\\\0")
        and not value.startswith(".")
    )


PLAIN_NAME = rule(plain_name_rule, "a plain name (it names a folder: not empty, no '/' or '\\', not starting with '.')")
TEXT = rule(lambda value: isinstance(value, str) and bool(value.strip()), "a non-empty text")
OPTIONAL_TEXT = rule(lambda value: isinstance(value, str) and bool(value.strip()), "a non-empty text", optional=True)
FRAME_RATE = interval(0, 10_000, low_open=True)
"""Frames per second of a face capture: optical systems record at up to a few hundred, high-speed cameras at a few
thousand; more is a unit error (a rate in mHz, a time base)."""
UNIT_MM = interval(0, 10_000, low_open=True)
"""Millimetres per file unit: 1 (mm), 10 (cm), 25.4 (inch), 1000 (m); beyond 10 m a unit no face mesh is stored in
(and values near the largest float overflow every sum of squares)."""
HAND_SUBSET = rule(
    lambda value: (
        (isinstance(value, str) and bool(re.fullmatch(r"all|upper|lower|random[1-9]\d*", value)))
        or (
            isinstance(value, (list, tuple))
            and len(value) > 0
            and all(map(plain_name_rule, value))
            and len(set(value)) == len(value)
        )
    ),
    "all, upper, lower, random<k> or a list of distinct hand-shape names",
)
ALTERNATIVE_NAMES = tuple(ALTERNATIVE_BASES)
SHAPE_NAMES = rule(
    lambda value: len(value) > 0 and len(set(value)) == len(value) and all(map(plain_name_rule, value)),
    "a non-empty list of distinct shape names (plain names: each names a file in an export)",
)
EVAL_FRACTION = interval(0, 1, low_open=True, high_open=True)
HELD_OUT_PROTOCOLS = {
    "tail": "held-out tail of each take",
    "take": "held-out last take",
    "kfold": "held-out blocked k-fold",
    "take_out": "held-out leave-one-take-out",
}
"""``dataset.held_out`` protocol -> how its frames are described (``workbench.study.protocols.HELD_OUT``; the
cross-validated ones are ``workbench.study.crossval.FOLDED``)."""
HELD_OUT = names(*HELD_OUT_PROTOCOLS, optional=True)
"""``dataset.held_out``: the held-out protocols scored beside the paper's."""
DATA_VARIANTS = {
    "synthetic": ("markers", "mesh", "mesh_rbf", "face"),
    "ict_livelink": ("mesh", "markers"),
    "animface": ("markers", "mesh"),
    "mesh_sequence": ("mesh",),
}
"""``dataset.kind`` -> the data variants its builder makes (the names ``dataset.train_on`` and ``dataset.eval_on``
take), in the order they are listed in messages."""
SYNTHETIC_VARIANTS = DATA_VARIANTS["synthetic"]
PLAUSIBILITY_POLICIES = ("error", "warn")
"""``dataset.plausibility``: what implausible input does (``workbench.formats.plausibility.settle``)."""
PLAUSIBILITY = one_of(*PLAUSIBILITY_POLICIES)
STORAGES = ("memory", "disk")
"""``dataset.storage``: frames kept in memory or in files of ``paths.cache_dir`` (``workbench.dataset.storage``)."""
STORAGE = one_of(*STORAGES)
DTYPE = one_of(*FRAME_DTYPES)
SPLITS = ("same", "tail")
"""``dataset.split`` of every kind; the synthetic actor adds ``other_take`` (a second take of the same actor)."""
SPLIT = one_of(*SPLITS)


# ---------------------------------------------------------------------------------------------------------------
# The schemas
# ---------------------------------------------------------------------------------------------------------------


@dataclass
class IntuitivenessSchema:
    locality_energy: float = meta(0.9, interval(0, 1, low_open=True))
    usage_threshold: float = meta(0.1, interval(0, 1, high_open=True))


@dataclass
class _BasisSettings:
    coverage: float = meta(MISSING, interval(0, 1, low_open=True))
    n_components: Optional[int] = meta(None, integer(1, optional=True))
    paper_regime: Any = meta(True, BOOLEAN)
    coverage_on: str = meta("training", one_of(*COVERAGE_ON))
    projections: List[str] = meta(MISSING, names("affine", "linear"))
    empty_axis_eps: float = meta(MISSING, interval(0))
    empty_axis_scale: str = meta(MISSING, one_of("axis_std", "absolute"))
    append_empty_axes: Any = meta(False, BOOLEAN)
    hand_subset: Any = meta("all", HAND_SUBSET)
    subset_seed: int = meta(0, SEED)
    alternatives: List[str] = meta([], names(*ALTERNATIVE_NAMES, allow_empty=True))
    alternatives_n: Optional[int] = meta(None, integer(1, optional=True))
    alternatives_seed: int = meta(0, SEED)


BasisSchema = make_dataclass(
    "BasisSchema",
    [
        *(
            (basis.options_key, basis.options, field(default_factory=basis.options))
            for basis in ALTERNATIVE_BASES.values()
        ),
        ("intuitiveness", IntuitivenessSchema, field(default_factory=IntuitivenessSchema)),
    ],
    bases=(_BasisSettings,),
)
BasisSchema.__module__ = __name__  # pickled by name: the joblib and SLURM launchers send the config store to workers
"""The ``basis`` group: :class:`_BasisSettings`, then the options of each alternative basis
(:data:`workbench.settings.bases.ALTERNATIVE_BASES`, ``basis.<options_key>``), then ``intuitiveness``, in the order
of ``conf/basis/default.yaml``."""


@dataclass
class SolverSchema:
    kind: str = meta(MISSING, key_of(SOLVER_KINDS))
    lower: Optional[float] = meta(None, interval(optional=True))
    upper: Optional[float] = meta(None, interval(optional=True))


@dataclass
class MetricSchema:
    headline_normalisation: str = meta(MISSING, one_of("absolute", "displacement"))
    headline_aggregate: str = meta(MISSING, one_of("mean", "pooled"))
    score_clean: Any = meta(False, BOOLEAN)
    claim_margin: float = meta(1.5, interval(1, 100, low_open=True))


@dataclass
class PathsSchema:
    data_root: str = meta(MISSING, TEXT)
    output_root: str = meta(MISSING, TEXT)
    cache_dir: Optional[str] = meta(None, OPTIONAL_TEXT)


@dataclass
class PaperAlphaSchema:
    """Alpha in percent (eq. 6) of each basis in the paper's section 5.5."""

    H: float = meta(MISSING, interval(0, 100, low_open=True))
    QE: float = meta(MISSING, interval(0, 100, low_open=True))
    PCA: float = meta(MISSING, interval(0, 100, low_open=True))


@dataclass
class PaperSchema:
    """Kim & Ko's reported figures, printed beside the run's for comparison."""

    alpha: PaperAlphaSchema = field(default_factory=PaperAlphaSchema)
    m: int = meta(MISSING, integer(1))
    coverage: float = meta(MISSING, interval(0, 1, low_open=True))


@dataclass
class StudySchema:
    dataset: Any = MISSING
    basis: BasisSchema = MISSING
    solver: Dict[str, SolverSchema] = field(default_factory=dict)
    metric: MetricSchema = MISSING
    paths: PathsSchema = MISSING
    study: str = meta(MISSING, PLAIN_NAME)
    save_inputs: Any = meta(False, BOOLEAN)
    paper: PaperSchema = MISSING


@dataclass
class FramesSchema:
    """The settings every dataset kind shares: which frames score the bases (``split``, ``held_out`` and their
    sizes) and how the frames are kept (``storage``, ``dtype``). Each kind's schema adds its own settings after
    these and names its ``kind``, which a resolved config lists first."""

    kind: str = MISSING
    split: str = meta("same", SPLIT)
    eval_fraction: float = meta(0.2, EVAL_FRACTION)
    held_out: Any = meta(None, HELD_OUT)
    folds: int = meta(5, integer(2))
    fold_gap_s: float = meta(0.5, interval(0))
    storage: str = meta("memory", STORAGE)
    dtype: str = meta("float64", DTYPE)


@dataclass
class SyntheticSchema(FramesSchema):
    kind: str = "synthetic"
    n_frames: int = meta(MISSING, integer(2))
    frame_rate: float = meta(MISSING, FRAME_RATE)
    n_face_markers: int = meta(MISSING, integer(3))
    n_head_markers: int = meta(MISSING, integer(3, 32))
    head_rotation_deg: float = meta(MISSING, interval(0, 45))
    head_translation_mm: float = meta(MISSING, interval(0, 200))
    marker_noise_mm: float = meta(
        MISSING,
        rule(
            lambda value: _number(value) and 0 <= value <= 10,
            "in [0, 10] (mm; optical marker noise is below a millimetre, and 10 mm is a tenth of the face)",
        ),
    )
    seed: int = meta(0, SEED)
    mesh_rows: int = meta(MISSING, integer(20))
    mesh_cols: int = meta(MISSING, integer(20))
    mesh_fraction: float = meta(1.0, interval(0, 1, low_open=True))
    train_on: Any = meta("markers", names(*SYNTHETIC_VARIANTS))
    eval_on: Any = meta(None, names(*SYNTHETIC_VARIANTS, optional=True))
    stabilise: Any = meta(True, BOOLEAN)
    split: str = meta("same", one_of(*SPLITS, "other_take"))  # a second take: the synthetic actor has one
    eval_seed: Optional[int] = meta(None, integer(0, optional=True))
    gap_rate: float = meta(0.0, interval(0, 1, high_open=True))
    gap_mean_frames: float = meta(12, interval(1))
    gap_policy: str = meta("linear", one_of(*GAP_POLICIES))
    gap_max_fill_frames: Optional[int] = meta(None, integer(1, optional=True))
    gap_fit_on: str = meta("filled", one_of(*GAP_FIT_ON))


@dataclass
class BlendshapesSchema:
    folder: str = meta(MISSING, TEXT)
    neutral: str = meta(MISSING, TEXT)
    unit_mm: float = meta(MISSING, UNIT_MM)
    region_vertices: Optional[int] = meta(None, integer(3, optional=True))


@dataclass
class IctLivelinkSchema(FramesSchema):
    kind: str = "ict_livelink"
    data_root: str = meta(MISSING, TEXT)
    blendshapes: BlendshapesSchema = MISSING
    livelink_csv: str = meta(MISSING, TEXT)
    timecode_rate: float = meta(MISSING, FRAME_RATE)
    arkit_overrides: Dict[str, Any] = field(default_factory=dict)
    frame_step: int = meta(1, integer(1))
    max_frames: Optional[int] = meta(None, integer(2, optional=True))
    hand_shapes: List[str] = meta(MISSING, SHAPE_NAMES)
    marker_table: str = meta(MISSING, TEXT)
    mesh_vertex_step: int = meta(1, integer(1))
    train_on: Any = meta(MISSING, names(*DATA_VARIANTS["ict_livelink"]))
    plausibility: str = meta("error", PLAUSIBILITY)


@dataclass
class RbfSchema:
    metric: str = meta("euclidean", one_of(*RBF_METRICS))
    kernel: str = meta("thin_plate_spline", one_of(*RBF_KERNELS))
    epsilon: Optional[float] = meta(None, interval(0, low_open=True, optional=True))  # null: 1 (scale-free kernels)
    smoothing: float = meta(0.0, interval(0))
    degree: int = meta(0, integer(-1, 2))


@dataclass
class AnimfaceSchema(FramesSchema):
    kind: str = "animface"
    data_root: str = meta(MISSING, TEXT)
    takes: List[str] = meta(MISSING, rule(lambda value: len(value) > 0, "a non-empty list of C3D files"))
    neutral_take: int = meta(0, integer(0))
    neutral_frame: Optional[int] = meta(None, integer(0, optional=True))  # null: the neutral take's rest face
    rigid_markers: List[str] = MISSING
    frame_step: int = meta(1, integer(1))
    max_frames_per_take: Optional[int] = meta(None, integer(2, optional=True))
    marker_table: str = meta(MISSING, TEXT)
    refine_iterations: int = meta(MISSING, integer(0))
    blendshapes: BlendshapesSchema = MISSING
    hand_shapes: List[str] = meta(MISSING, SHAPE_NAMES)
    rbf: RbfSchema = field(default_factory=RbfSchema)
    gap_policy: str = meta("drop", one_of(*GAP_POLICIES))
    gap_max_fill_frames: Optional[int] = meta(None, integer(1, optional=True))
    gap_fit_on: str = meta("filled", one_of(*GAP_FIT_ON))
    gap_rate: float = meta(0.0, interval(0, 1, high_open=True))
    gap_mean_frames: float = meta(12, interval(1))
    gap_seed: int = meta(0, SEED)
    mesh_vertex_step: int = meta(1, integer(1))
    train_on: Any = meta(MISSING, names(*DATA_VARIANTS["animface"]))
    plausibility: str = meta("error", PLAUSIBILITY)


@dataclass
class MeshSequenceBasisSchema:
    path: Optional[str] = meta(None, OPTIONAL_TEXT)
    neutral: str = meta("neutral.obj", TEXT)
    unit_mm: float = meta(1.0, UNIT_MM)
    region_vertices: Optional[int] = meta(None, integer(3, optional=True))


@dataclass
class MeshSequenceSchema(FramesSchema):
    kind: str = "mesh_sequence"
    data_root: str = meta(MISSING, TEXT)
    sequence: Optional[str] = meta(None, OPTIONAL_TEXT)
    vertices_key: str = meta("vertices", TEXT)
    faces_key: Optional[str] = meta("faces", OPTIONAL_TEXT)
    unit_mm: float = meta(1000.0, UNIT_MM)
    frame_rate: float = meta(60.0, FRAME_RATE)
    neutral_frame: int = meta(0, integer(0))
    neutral: Optional[str] = meta(None, OPTIONAL_TEXT)
    blendshapes: MeshSequenceBasisSchema = field(default_factory=MeshSequenceBasisSchema)
    hand_shapes: Optional[List[str]] = meta(None, rule(SHAPE_NAMES["check"], SHAPE_NAMES["rule"], optional=True))
    frame_step: int = meta(1, integer(1))
    max_frames: Optional[int] = meta(None, integer(2, optional=True))
    plausibility: str = meta("error", PLAUSIBILITY)
    train_on: Any = meta("mesh", names(*DATA_VARIANTS["mesh_sequence"]))


DATASET_SCHEMAS = {
    "synthetic": SyntheticSchema,
    "ict_livelink": IctLivelinkSchema,
    "animface": AnimfaceSchema,
    "mesh_sequence": MeshSequenceSchema,
}
DATASET_EXTRAS = {
    "hand_basis": ("synthetic", "ict_livelink", "animface", "mesh_sequence"),
    "weight_curves": ("ict_livelink",),
    "weight_frame_rate": ("ict_livelink",),
    "eval_on": ("ict_livelink", "animface"),
}
"""Dataset settings added with ``+`` (not in the kind's schema, so that configs without them hash as before) ->
the kinds that read them (docs/formats.md, docs/studies.md)."""


@dataclass
class HandBasisSchema:
    """``+dataset.hand_basis``: a hand basis read from a file in place of the dataset's own
    (:mod:`workbench.dataset.hand_basis`): an OBJ blendshape folder or a ``.glb`` file's morph targets."""

    path: str = meta(MISSING, TEXT)
    shapes: Optional[List[str]] = meta(
        None,
        rule(
            lambda value: (
                isinstance(value, (list, tuple))
                and all(isinstance(name, str) for name in value)
                and len(set(value)) == len(value)
            ),
            "a list of distinct shape names",
            optional=True,
        ),
    )
    neutral: Optional[str] = meta(None, OPTIONAL_TEXT)
    unit_mm: Optional[float] = meta(None, rule(POSITIVE["check"], POSITIVE["rule"], optional=True))
    mesh: Optional[str] = meta(None, OPTIONAL_TEXT)
    region_vertices: Optional[int] = meta(None, integer(3, optional=True, whole_floats=True))


DATASET_EXTRA_SCHEMAS = {"hand_basis": HandBasisSchema}
"""The dataset settings added with ``+`` that are groups of settings -> the schema each setting of the group is
checked against (a missing, null or empty group is not set)."""
DATASET_EXTRA_RULES = {
    "hand_basis": rule(
        lambda value: not value or (isinstance(value, Mapping) and value.get("path") is not None),
        "a mapping with a 'path' (an OBJ blendshape folder or a .glb file)",
    ),
    "weight_frame_rate": interval(0, 10_000, low_open=True, optional=True),
    "weight_curves": OPTIONAL_TEXT,
    "eval_on": lambda kind: names(*DATA_VARIANTS[kind], optional=True),
}
"""The rules of the dataset settings added with ``+`` (the rate numbers the frames of weight curves, as
:data:`FRAME_RATE` does a capture's)."""


def register_schemas() -> None:
    """Store the schemas in Hydra's ConfigStore: ``workbench_schema`` (a study) and ``<kind>_dataset_schema``,
    outside any config group so that ``--help`` does not offer them as options."""
    from hydra.core.config_store import ConfigStore

    store = ConfigStore.instance()
    store.store(name="workbench_schema", node=StudySchema)
    for kind, schema in DATASET_SCHEMAS.items():
        store.store(name=f"{kind}_dataset_schema", node=schema)


# ---------------------------------------------------------------------------------------------------------------
# Checking a composed config
# ---------------------------------------------------------------------------------------------------------------


def check_study_config(cfg, overrides: Sequence[str] = (), *, refuse_ineffective: bool = False) -> list[str]:
    """Check every setting of a composed study config against its schema's rule.

    Parameters
    ----------
    cfg : omegaconf.DictConfig or mapping
        A composed study config (its ``hydra`` node, if any, is left out).
    overrides : sequence of str
        The overrides that made it (``key=value``), to find settings given that have no effect in the run.
    refuse_ineffective : bool
        Refuse such settings (a plain run); otherwise return them (a sweep's run, where an override may matter to
        other runs of the sweep).

    Returns
    -------
    list of str
        One sentence per overridden setting with no effect in this run (empty when ``refuse_ineffective``).

    Raises
    ------
    WorkbenchError
        Naming the first setting that breaks its rule, a key no schema knows, or an interpolation that cannot be
        resolved.
    """
    return checked_settings(cfg, overrides, refuse_ineffective=refuse_ineffective)[1]


def checked_settings(cfg, overrides: Sequence[str] = (), *, refuse_ineffective: bool = False) -> tuple[dict, list[str]]:
    """:func:`check_study_config`, returning the resolved config it checked (without Hydra's node and the retired
    settings of an earlier version's record) beside the sentences on settings with no effect."""
    plain = _without_retired(resolved_settings(cfg), overrides)
    _check_text(plain, "")
    _check_keys(plain)
    for group in ("dataset", "basis", "solver"):
        if group not in plain:
            raise WorkbenchError(f"the study config has no {group} group: compose it with compose_config")
    _check_node(plain, StudySchema, "")
    kind = plain["dataset"].get("kind") if isinstance(plain.get("dataset"), Mapping) else None
    if kind not in DATASET_SCHEMAS:
        raise WorkbenchError(f"dataset.kind must be one of {sorted(DATASET_SCHEMAS)}, got {kind!r}")
    _check_node(
        plain["dataset"],
        DATASET_SCHEMAS[kind],
        "dataset.",
        extras={key for key, kinds in DATASET_EXTRAS.items() if kind in kinds},
    )
    _check_relations(plain)
    ineffective = ineffective_settings(plain, overrides)
    if ineffective and refuse_ineffective:
        raise WorkbenchError(
            f"{ineffective[0]}; leave it out" + (f" (and {len(ineffective) - 1} more)" if len(ineffective) > 1 else "")
        )
    return plain, [] if refuse_ineffective else ineffective


def check_dataset_group(values: Mapping) -> None:
    """Check a ``dataset`` group alone (a builder called without a study): every setting it gives against its
    kind's schema (settings it leaves out are not asked for)."""
    kind = values.get("kind")
    if kind not in DATASET_SCHEMAS:
        raise WorkbenchError(f"dataset.kind must be one of {sorted(DATASET_SCHEMAS)}, got {kind!r}")
    _check_node(
        values, DATASET_SCHEMAS[kind], "dataset.", extras={k for k, kinds in DATASET_EXTRAS.items() if kind in kinds}
    )
    if kind == "synthetic":
        _check_synthetic(values)
    if kind == "animface":
        _check_rbf(values.get("rbf") or {})


def _check_rbf(rbf: Mapping) -> None:
    """``dataset.rbf``: a kernel with a shape (not scale-free) needs its ``epsilon``."""
    kernel = given(rbf, RbfSchema, "kernel")
    if given(rbf, RbfSchema, "epsilon") is None and kernel not in RBF_SCALE_INVARIANT:
        raise WorkbenchError(f"dataset.rbf.epsilon must be set for the {kernel} kernel (a shape parameter in 1/mm)")


def resolved_settings(cfg) -> dict:
    """The config without Hydra's node, every interpolation resolved; one line naming the setting when one cannot
    be (a missing key, a recursive reference)."""
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    plain = {}
    for key in cfg:
        if key == "hydra":
            continue
        try:
            node = cfg[key]
            plain[key] = OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else node
        except OmegaConfBaseException as error:
            where = getattr(error, "full_key", None) or key
            reason = str(error).splitlines()[0] if str(error) else type(error).__name__
            raise WorkbenchError(f"setting {where} cannot be resolved: {reason}") from None
    return plain


RETIRED_SETTINGS = dict.fromkeys(
    ["metric.bootstrap_resamples", "metric.bootstrap_seed"],
    "the within-run intervals are batch means over time and draw nothing at random (docs/statistics.md)",
)
"""Settings earlier versions had, with why they went: a record written then still holds them."""


def retired_message(key: str) -> str:
    """The one line refusing a retired setting given again (:data:`RETIRED_SETTINGS`)."""
    return f"setting {key} was retired: {RETIRED_SETTINGS[key]}; leave it out"


def refuse_retired(overrides: Sequence[str]) -> None:
    """Refuse an override (``key=value``, ``+key=value``, ``++key=value``, ``~key``) of a retired setting, naming why
    it went: the command line and :func:`workbench.settings.config.compose` both check it before composing."""
    given = {str(override).lstrip("+~").split("=", 1)[0].strip() for override in overrides}
    for key in RETIRED_SETTINGS:
        if key in given:
            raise WorkbenchError(retired_message(key))


def _without_retired(plain: dict, overrides: Sequence[str]) -> dict:
    """``plain`` without the retired settings a record of an earlier version holds; one given as an override is
    refused, naming why it went."""
    refuse_retired(overrides)
    for key in RETIRED_SETTINGS:
        group, name = key.split(".")
        if isinstance(plain.get(group), Mapping) and name in plain[group]:
            plain[group] = {k: v for k, v in plain[group].items() if k != name}
    return plain


def _check_text(value, key: str) -> None:
    """Every text of the config (names, paths, keys) is valid UTF-8: the record's files hold them."""
    if isinstance(value, str):
        check_utf8(value, f"setting {key}")
    elif isinstance(value, Mapping):
        for name, item in value.items():
            check_utf8(str(name), f"the key of setting {key or 'the config'}")
            _check_text(item, f"{key}.{name}" if key else str(name))
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            _check_text(item, f"{key}[{i}]")


def _check_keys(plain: Mapping) -> None:
    """Refuse keys no schema knows: top-level and dataset keys added with ``+``."""
    known = {f.name for f in fields(StudySchema)}
    unknown = sorted(set(plain) - known)
    if unknown:
        raise WorkbenchError(f"setting {unknown[0]} does not exist (a study has {sorted(known)}); check its spelling")
    dataset = plain.get("dataset")
    kind = dataset.get("kind") if isinstance(dataset, Mapping) else None
    if kind not in DATASET_SCHEMAS:
        return
    allowed = {f.name for f in fields(DATASET_SCHEMAS[kind])}
    for key in dataset:
        if key not in allowed and kind not in DATASET_EXTRAS.get(key, ()):
            readers = DATASET_EXTRAS.get(key)
            why = (
                f"only dataset kind(s) {list(readers)} read it"
                if readers
                else f"dataset kind '{kind}' has no such setting"
            )
            raise WorkbenchError(f"dataset.{key} has no effect with dataset={kind}: {why}; leave it out")


def check_hydra_settings(node, prefix: str = "hydra.") -> None:
    """Refuse a key of Hydra's own settings that Hydra's schema does not have (``+hydra.nope=1``,
    ``++hydra.job.nope=1``: Hydra adds it and nothing reads it), in the words used for the study's settings.

    Parameters
    ----------
    node : omegaconf.DictConfig
        The composed config's ``hydra`` node (each of its parts checked against its dataclass, where it has one;
        free mappings such as ``hydra.job.env_set`` or ``hydra.callbacks`` take any key).
    prefix : str

    Raises
    ------
    WorkbenchError
    """
    from omegaconf import DictConfig, OmegaConf

    schema = OmegaConf.get_type(node)
    if is_dataclass(schema):
        groups = {spec.name: spec for spec in fields(schema)}.get("defaults")  # config groups, such as hydra/env
        chosen = groups.default_factory() if groups is not None and groups.default_factory is not NO_DEFAULT else []
        _check_known(node, schema, prefix, {key for entry in chosen if isinstance(entry, Mapping) for key in entry})
    for key, value in node.items_ex(resolve=False):
        if isinstance(value, DictConfig) and node.get(key) is not None:  # a mapping, not one set to null
            check_hydra_settings(value, f"{prefix}{key}.")


def _check_node(values: Mapping, schema, prefix: str, extras: set = frozenset()) -> None:
    """Apply the rules of ``schema``'s fields to ``values`` (recursing into nested schemas); a key the schema does
    not have (added with ``+`` or ``++``) is refused unless it is one of ``extras``."""
    if not isinstance(values, Mapping):
        raise WorkbenchError(f"{prefix.rstrip('.') or 'the config'} must be a mapping, got {values!r:.60}")
    _check_known(values, schema, prefix, extras)
    for key in extras & set(values):
        spec = DATASET_EXTRA_RULES.get(key)
        spec = spec(values.get("kind")) if callable(spec) else spec  # a rule that depends on the dataset's kind
        if spec is not None:
            checked(values[key], prefix + key, spec)
        if key in DATASET_EXTRA_SCHEMAS and values[key]:
            _check_node(values[key], DATASET_EXTRA_SCHEMAS[key], prefix + key + ".")
    for spec in fields(schema):
        key = prefix + spec.name
        if spec.name not in values:
            continue
        value = values[spec.name]
        nested = nested_schema(spec)
        if nested is not None and value is not None:
            _check_node(value, nested, key + ".")
        elif spec.name == "solver" and schema is StudySchema:
            _check_solvers(value)
        elif "check" in spec.metadata:
            checked(value, key, spec.metadata)


def _check_known(values: Mapping, schema, prefix: str, extras: set) -> None:
    """Refuse a key of ``values`` that ``schema`` has no field for (whatever the prefix that added it)."""
    known = [spec.name for spec in fields(schema)]
    for key in values:
        if key not in known and key not in extras:
            elsewhere = f" (did you mean dataset.{key}?)" if key in DATASET_EXTRAS and prefix != "dataset." else ""
            raise WorkbenchError(
                f"setting {prefix}{key} does not exist{elsewhere}; {prefix.rstrip('.') or 'a study'} "
                f"has {sorted(known)}: check its spelling or leave it out"
            )


def nested_schema(spec):
    """The dataclass of a field that holds a nested schema, or None."""
    if spec.default_factory is not NO_DEFAULT and is_dataclass(spec.default_factory):
        return spec.default_factory
    kind = spec.type if not isinstance(spec.type, str) else globals().get(spec.type)
    return kind if is_dataclass(kind) else None


def _check_solvers(solvers) -> None:
    if not isinstance(solvers, Mapping) or not solvers:
        raise WorkbenchError(f"the solver group is empty: choose one of solver={'|'.join(SOLVER_KINDS)}|all")
    for name, spec in solvers.items():
        _check_node(spec, SolverSchema, f"solver.{name}.")
        lower, upper = spec.get("lower"), spec.get("upper")
        given = bool(SOLVER_KINDS[spec["kind"]].options)  # a kind that takes its bounds from the settings
        if given and lower is None and upper is None:
            raise WorkbenchError(f"solver.{name} is a {spec['kind']} solver without bounds: set lower and/or upper")
        if given and lower is not None and upper is not None and lower > upper:
            raise WorkbenchError(f"solver.{name}.lower ({lower}) must not exceed solver.{name}.upper ({upper})")


def _check_relations(plain: Mapping) -> None:
    """Rules between settings."""
    splocs = plain["basis"].get("splocs") or {}
    if _number(splocs.get("d_min")) and _number(splocs.get("d_max")) and not splocs["d_min"] < splocs["d_max"]:
        raise WorkbenchError(
            f"basis.splocs.d_min ({splocs['d_min']}) must be below basis.splocs.d_max ({splocs['d_max']})"
        )
    basis, kind = plain["basis"], plain["dataset"].get("kind")
    if kind == "synthetic":
        _check_synthetic(plain["dataset"])
    if kind == "animface":
        _check_rbf(plain["dataset"].get("rbf") or {})
    _check_held_out(plain)
    if given(basis, BasisSchema, "coverage_on") == "clean" and basis.get("n_components") is not None:
        raise WorkbenchError(
            f"basis.coverage_on=clean chooses m from the clean capture, so basis.n_components must "
            f"be null, got {basis['n_components']}"
        )
    for key, wants_clean in (
        ("basis.coverage_on", basis.get("coverage_on") == "clean"),
        ("metric.score_clean", (plain.get("metric") or {}).get("score_clean") is True),
    ):
        if wants_clean and kind != "synthetic":
            raise WorkbenchError(f"{key} needs the clean capture, which only dataset.kind synthetic has, got {kind!r}")


def given(values: Mapping, schema, name: str):
    """The setting ``name`` of ``values`` as given, else ``schema``'s default for it (None where it has none): a
    rule between settings reads a setting left out as the run will, without restating its default."""
    if name in values:
        return values[name]
    spec = {spec.name: spec for spec in fields(schema)}[name]
    return None if spec.default is NO_DEFAULT or spec.default == MISSING else spec.default


def _check_held_out(plain: Mapping) -> None:
    """What ``dataset.held_out`` and ``dataset.eval_on`` (bases carried onto other points) cannot be combined with."""
    dataset, carried = plain["dataset"], plain["dataset"].get("eval_on") is not None
    held_out = _held_out(plain)
    if held_out and given(dataset, DATASET_SCHEMAS[dataset["kind"]], "split") != "same":
        raise WorkbenchError(
            f"dataset.held_out adds held-out frames beside the paper's protocol (split 'same'); "
            f"with dataset.split {dataset.get('split')!r} the run is already held out: leave "
            "one of them unset"
        )
    if held_out and carried:
        raise WorkbenchError(
            "dataset.held_out scores each data variant on its own held-out frames; with "
            "dataset.eval_on (bases carried onto other points) it is not supported: leave one unset"
        )
    if carried and _alternatives(plain):
        raise WorkbenchError(
            "basis.alternatives are fitted and scored on each data variant's own points; "
            "carrying them onto others (dataset.eval_on) is not supported: leave one of them unset"
        )


def _check_synthetic(dataset: Mapping) -> None:
    """The rules between the synthetic actor's settings: its markers fit its mesh, and a second take (split
    ``other_take``) has a seed of its own."""
    _check_marker_count(dataset)
    seed, eval_seed = given(dataset, SyntheticSchema, "seed"), dataset.get("eval_seed")
    if dataset.get("split") == "other_take" and _integer(seed) and eval_seed is not None and eval_seed == seed:
        raise WorkbenchError(
            f"dataset.eval_seed {eval_seed} equals dataset.seed: split 'other_take' evaluates on "
            "another take, so the two seeds must differ (null: seed + 1)"
        )


def _check_marker_count(dataset: Mapping) -> None:
    """The synthetic face's markers sit on vertices of its mesh: no more of them than the mesh has (checked here,
    before the dataset's memory estimate, so that the message names the setting at fault)."""
    markers, rows, cols = (dataset.get(key) for key in ("n_face_markers", "mesh_rows", "mesh_cols"))
    if all(map(_integer, (markers, rows, cols))) and markers > rows * cols:
        raise WorkbenchError(
            f"dataset.n_face_markers must not exceed the synthetic mesh's dataset.mesh_rows x "
            f"dataset.mesh_cols = {rows * cols} vertices (the markers sit on them), got {markers}"
        )
