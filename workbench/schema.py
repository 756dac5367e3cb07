"""The types of the config groups, as dataclasses in Hydra's ConfigStore.

Every study starts from :class:`StudySchema` (``studies/paper.yaml`` lists ``workbench_schema`` first in its
defaults) and every dataset file from its kind's schema, so a value of the wrong type (``solver.box.lower=x``,
``basis.projections=affine``) or a key that does not exist fails when the config is composed, before anything
runs, with one line naming the key and the type it takes. The range checks (``coverage`` in (0, 1], bounds in
order, ...) stay where the values are used. Fields are in the order of the YAML files, so that the resolved
config reads as before. ``Any`` marks settings that take a name or a list (``train_on``, ``hand_subset``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

from omegaconf import MISSING


@dataclass
class SparsePCASchema:
    alpha: float = 0.01
    max_iter: int = 100


@dataclass
class IterativeFitSchema:
    max_iter: int = 200
    tol: float = 1.0e-4


@dataclass
class SplocsSchema:
    sparsity_lambda: float = 2.0
    d_min: float = 0.1
    d_max: float = 0.7
    n_iterations: int = 10
    n_admm_iterations: int = 10
    rho: float = 10.0


@dataclass
class HandFitSchema:
    n_iterations: int = 5


@dataclass
class IntuitivenessSchema:
    locality_energy: float = 0.9
    usage_threshold: float = 0.1


@dataclass
class BasisSchema:
    coverage: float = MISSING
    n_components: Optional[int] = None
    coverage_on: str = "training"
    projections: List[str] = MISSING
    empty_axis_eps: float = MISSING
    empty_axis_scale: str = MISSING
    append_empty_axes: bool = False
    hand_subset: Any = "all"
    subset_seed: int = 0
    alternatives: List[str] = field(default_factory=list)
    alternatives_n: Optional[int] = None
    alternatives_seed: int = 0
    spca: SparsePCASchema = field(default_factory=SparsePCASchema)
    ica: IterativeFitSchema = field(default_factory=IterativeFitSchema)
    nmf: IterativeFitSchema = field(default_factory=IterativeFitSchema)
    splocs: SplocsSchema = field(default_factory=SplocsSchema)
    hand_fit: HandFitSchema = field(default_factory=HandFitSchema)
    intuitiveness: IntuitivenessSchema = field(default_factory=IntuitivenessSchema)


@dataclass
class SolverSchema:
    kind: str = MISSING
    lower: Optional[float] = None
    upper: Optional[float] = None


@dataclass
class MetricSchema:
    headline_normalisation: str = MISSING
    headline_aggregate: str = MISSING
    bootstrap_resamples: int = 2000
    bootstrap_seed: int = 0
    score_clean: bool = False


@dataclass
class PathsSchema:
    data_root: str = MISSING
    output_root: str = MISSING
    cache_dir: Optional[str] = None


@dataclass
class PaperSchema:
    alpha: Dict[str, float] = field(default_factory=dict)
    m: int = MISSING
    coverage: float = MISSING


@dataclass
class StudySchema:
    dataset: Any = MISSING
    basis: BasisSchema = MISSING
    solver: Dict[str, SolverSchema] = field(default_factory=dict)
    metric: MetricSchema = MISSING
    paths: PathsSchema = MISSING
    study: str = MISSING
    save_inputs: bool = False
    paper: PaperSchema = MISSING


@dataclass
class SyntheticSchema:
    kind: str = "synthetic"
    n_frames: int = MISSING
    frame_rate: float = MISSING
    n_face_markers: int = MISSING
    n_head_markers: int = MISSING
    head_rotation_deg: float = MISSING
    head_translation_mm: float = MISSING
    marker_noise_mm: float = MISSING
    seed: int = 0
    mesh_rows: int = MISSING
    mesh_cols: int = MISSING
    mesh_fraction: float = 1.0
    train_on: Any = "markers"
    eval_on: Any = None
    stabilise: bool = True
    split: str = "same"
    eval_fraction: float = 0.2
    held_out: Any = None
    eval_seed: Optional[int] = None
    gap_rate: float = 0.0
    gap_mean_frames: float = 12
    gap_policy: str = "linear"
    gap_max_fill_frames: Optional[int] = None
    gap_fit_on: str = "filled"
    storage: str = "memory"
    dtype: str = "float64"


@dataclass
class BlendshapesSchema:
    folder: str = MISSING
    neutral: str = MISSING
    unit_mm: float = MISSING
    region_vertices: Optional[int] = None


@dataclass
class IctLivelinkSchema:
    kind: str = "ict_livelink"
    data_root: str = MISSING
    blendshapes: BlendshapesSchema = MISSING
    livelink_csv: str = MISSING
    timecode_rate: float = MISSING
    arkit_overrides: Dict[str, Any] = field(default_factory=dict)
    frame_step: int = 1
    max_frames: Optional[int] = None
    hand_shapes: List[str] = MISSING
    marker_table: str = MISSING
    mesh_vertex_step: int = 1
    train_on: Any = MISSING
    split: str = "same"
    eval_fraction: float = 0.2
    held_out: Any = None
    plausibility: str = "error"
    storage: str = "memory"
    dtype: str = "float64"


@dataclass
class RbfSchema:
    metric: str = MISSING
    kernel: str = MISSING
    epsilon: float = MISSING
    smoothing: float = 0.0
    degree: int = 0


@dataclass
class AnimfaceSchema:
    kind: str = "animface"
    data_root: str = MISSING
    takes: List[str] = MISSING
    neutral_take: int = 0
    neutral_frame: int = 0
    rigid_markers: List[str] = MISSING
    frame_step: int = 1
    max_frames_per_take: Optional[int] = None
    marker_table: str = MISSING
    refine_iterations: int = MISSING
    blendshapes: BlendshapesSchema = MISSING
    hand_shapes: List[str] = MISSING
    rbf: RbfSchema = MISSING
    gap_policy: str = "drop"
    gap_max_fill_frames: Optional[int] = None
    gap_fit_on: str = "filled"
    gap_rate: float = 0.0
    gap_mean_frames: float = 12
    gap_seed: int = 0
    mesh_vertex_step: int = 1
    train_on: Any = MISSING
    split: str = "same"
    eval_fraction: float = 0.2
    held_out: Any = None
    plausibility: str = "error"
    storage: str = "memory"
    dtype: str = "float64"


DATASET_SCHEMAS = {"synthetic": SyntheticSchema, "ict_livelink": IctLivelinkSchema, "animface": AnimfaceSchema}


def register_schemas() -> None:
    """Store the schemas in Hydra's ConfigStore: ``workbench_schema`` (a study) and ``<kind>_dataset_schema``,
    outside any config group so that ``--help`` does not offer them as options."""
    from hydra.core.config_store import ConfigStore

    store = ConfigStore.instance()
    store.store(name="workbench_schema", node=StudySchema)
    for kind, schema in DATASET_SCHEMAS.items():
        store.store(name=f"{kind}_dataset_schema", node=schema)
