"""Dataset ``animface``: real optical facial capture (AnimFace C3D takes) with an ICT FaceKit hand basis.

The performer and the hand basis come from different faces, as in the paper (its hand shapes were sculpted on
a model apart from the actor). The capture's head motion is removed on rigid markers, the ICT face is placed on
the performer by a similarity alignment, each marker gets a vertex (the correspondence table), and the hand basis
is the ICT shapes at those vertices, scaled into the performer's frame. ``markers`` trains on the markers
directly, the face markers only (the rigid markers remove head motion and are not scored: after stabilisation
they move only by its residual, which would dilute alpha and give PCA noise to fit); ``mesh`` on the ICT face-region
vertices, moved by a radial-basis interpolation of every marker's displacement (the paper's "markers interpolated
onto the mesh"; the rigid markers anchor the forehead and nose bridge there). The capture's noise floor
(:class:`NoiseFloor`) is reported with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.capture import Capture, Timeline
from workbench.dataset.common import (
    interpolated_frames,
    largest_point_norm,
    marker_jitter_rms,
    masked_frames,
    masked_training_frames,
    name_list,
    point_operator_matrix,
    split_frames,
)
from workbench.dataset.correspondence import MarkerPlacement, MarkerTable, place_markers, read_marker_table
from workbench.dataset.gaps import apply_gap_policy, gap_mask
from workbench.dataset.hand_basis import check_hand_shapes
from workbench.dataset.rbf import mesh_rbf_matrix, rbf_epsilon
from workbench.dataset.real import (
    ANIMFACE_CREDIT,
    ICT_CREDIT,
    conf_path,
    data_path,
    frame_selection,
    hand_shape_names,
    load_basis,
    mesh_point_indices,
    origin_text,
)
from workbench.dataset.rigid import Similarity, Stabilised, stabilise
from workbench.dataset.storage import FrameStorage
from workbench.formats.c3d import MarkerTake
from workbench.formats.obj import Blendshapes, expression_names
from workbench.formats.plausibility import (
    check_rigid_set,
    face_size_problems,
    face_spread,
    frame_rate_problems,
    outlier_problems,
    parked_marker_problems,
    settle,
    take_motion_problems,
    take_units_problems,
    with_warnings,
)
from workbench.formats.registry import format_for

DIFFERENT_FACES = (
    "performer and basis come from different faces: the motion is the AnimFace performer's, the hand "
    "shapes are the ICT FaceKit generic face's"
)
ORIGIN = (
    "ICT FaceKit model origin (midline, near the centre of the head) placed on the performer by the "
    "similarity alignment; axes x to the face's left, y up, z out of the face"
)
FACE_SCALE_RANGE = (0.5, 2.0)
"""Scales of the similarity alignment (basis face onto the performer) that two human faces can differ by; outside
it the takes' ``POINT:UNITS`` and ``dataset.blendshapes.unit_mm`` disagree (a unit mismatch gives 10, 25.4 or 1000)."""
JITTER_ESTIMATOR = "sqrt(mean |x[t-1] - 2 x[t] + x[t+1]|^2 / 6) over the face markers after stabilisation"
"""How the noise floor's marker jitter is estimated (:func:`workbench.dataset.common.marker_jitter_rms`)."""


@dataclass(frozen=True)
class NoiseFloor:
    """How precisely the capture locates the face: differences of error smaller than this are below its noise.

    Attributes
    ----------
    stabilisation_residual_mm : float
        RMS distance of the rigid markers from their reference after the per-frame Kabsch alignment, over every
        frame used (marker noise plus whatever of the rigid set is not rigid: the forehead moves with the brows).
    jitter_mm : float
        RMS length of the face markers' frame-to-frame jitter after stabilisation, by
        :func:`workbench.dataset.common.marker_jitter_rms` (second differences; an upper bound).
    """

    stabilisation_residual_mm: float
    jitter_mm: float

    def describe(self) -> str:
        return (
            f"noise floor: stabilisation residual {self.stabilisation_residual_mm:.2f} mm, jitter "
            f"{self.jitter_mm:.3f} mm; differences below it are below the capture's noise"
        )

    def as_dict(self) -> dict:
        return {"stabilisation_residual_rms": self.stabilisation_residual_mm, "marker_jitter_rms": self.jitter_mm}


def noise_floor(residuals: Sequence[np.ndarray], face_trajectories: Sequence[np.ndarray]) -> NoiseFloor:
    """The capture's noise floor from its takes.

    Parameters
    ----------
    residuals : sequence of ndarray of shape (n_frames,)
        Per take, each frame's stabilisation residual (:attr:`workbench.dataset.rigid.Stabilised.residual_rms`,
        NaN where a frame could not be aligned).
    face_trajectories : sequence of ndarray of shape (n_frames, n_face_markers, 3)
        Per take, the face markers after stabilisation, consecutive frames.

    Returns
    -------
    NoiseFloor
    """
    residual = np.concatenate([np.asarray(frames, dtype=np.float64) for frames in residuals])
    return NoiseFloor(
        stabilisation_residual_mm=float(np.sqrt(np.nanmean(residual**2))),
        jitter_mm=marker_jitter_rms(face_trajectories),
    )


@dataclass(frozen=True)
class StabilisedTakes:
    """The selected frames of every take, head motion removed, concatenated in time.

    Attributes
    ----------
    positions : ndarray of shape (n_frames, n_markers, 3)
        Markers in the table's order, in the neutral frame's head pose, in mm.
    neutral : ndarray of shape (n_markers, 3)
        The neutral frame's markers.
    notes : list of str
        One entry per take: frames kept and the stabilisation residual.
    record : dict
        Per take, for the provenance.
    timeline : Timeline
        Take name, frame number in its file and time of every frame of ``positions``.
    visible : ndarray of shape (n_frames, n_markers) of bool, or None
        Under gap policy ``masked``: the markers each frame saw (``positions`` is filled there for training).
    warnings : list of str
        Plausibility problems kept under ``dataset.plausibility: warn``.
    neutral_rest : NeutralRest or None
        How far the neutral frame is from the rest pose of its take.
    face : ndarray of shape (n_markers,) of bool or None
        The table's face markers (the scored ones): all but ``dataset.rigid_markers``.
    noise_floor : NoiseFloor or None
    """

    positions: np.ndarray
    neutral: np.ndarray
    notes: list
    record: dict
    timeline: Timeline
    visible: np.ndarray | None = None
    warnings: list = ()
    neutral_rest: "NeutralRest | None" = None
    face: np.ndarray | None = None
    noise_floor: NoiseFloor | None = None


@dataclass(frozen=True)
class NeutralRest:
    """The neutral frame against the rest pose of its take (the median of every frame, head motion removed).

    Every displacement is measured from the neutral frame, so a neutral away from rest puts its offset into
    every frame, and into the capture mean that the affine quasi-eigen faces carry (eq. 4).

    Attributes
    ----------
    frame : int
        The neutral frame (of its file).
    rms_mm, largest_mm : float
        RMS and largest distance of its markers from the median pose.
    largest_marker : str
    nearest_frame : int
        The take's frame nearest the median pose (RMS over the markers), and ``nearest_rms_mm`` its distance.
    nearest_rms_mm : float
    """

    frame: int
    rms_mm: float
    largest_mm: float
    largest_marker: str
    nearest_frame: int
    nearest_rms_mm: float

    def describe(self, take: str) -> str:
        nearest = (
            "the take's frame nearest that pose"
            if self.nearest_frame == self.frame
            else f"the take's frame nearest that pose is {self.nearest_frame} ({self.nearest_rms_mm:.2f} mm)"
        )
        return (
            f"the neutral, {take} frame {self.frame}, lies {self.rms_mm:.2f} mm RMS (largest {self.largest_mm:.1f} "
            f"mm, {self.largest_marker}) from the median pose of its take, head motion removed: "
            + ("it is " if self.nearest_frame == self.frame else "")
            + nearest
        )


def neutral_rest(markers: np.ndarray, labels: Sequence[str], frame: int) -> NeutralRest:
    """How far a take's neutral frame is from the take's rest pose, the median of its frames.

    Parameters
    ----------
    markers : ndarray of shape (n_frames, n_markers, 3)
        Every frame of the take, head motion removed (NaN where a marker is missing).
    labels : sequence of str
        One per marker.
    frame : int
        The neutral frame.

    Returns
    -------
    NeutralRest
    """
    rest = np.nanmedian(markers, axis=0)
    distance = np.linalg.norm(markers - rest, axis=2)
    rms = np.sqrt(np.nanmean(distance**2, axis=1))
    nearest = int(np.nanargmin(rms))
    largest = int(np.nanargmax(distance[frame]))
    return NeutralRest(
        frame=frame,
        rms_mm=float(rms[frame]),
        largest_mm=float(distance[frame, largest]),
        largest_marker=str(labels[largest]),
        nearest_frame=nearest,
        nearest_rms_mm=float(rms[nearest]),
    )


def rest_frame(take: MarkerTake, rigid_index, table_index, labels: Sequence[str]) -> int:
    """The take's rest face: its frame nearest the median pose of its frames, head motion removed (on the first
    frame that saw every rigid marker; another reference moves every frame alike and changes no distance).

    Parameters
    ----------
    take : MarkerTake
    rigid_index, table_index : sequence of int
        The rigid markers and the table's markers among the take's.
    labels : sequence of str
        The table's marker names.

    Returns
    -------
    int
        A frame of the take's file.
    """
    return rest_frame_of(take.positions, rigid_index, table_index, labels, where=str(take.path))


def rest_frame_of(
    positions: np.ndarray, rigid_index, table_index, labels: Sequence[str], *, where: str = "markers"
) -> int:
    """:func:`rest_frame` on an array of positions of shape (n_frames, n_markers, 3) in mm; ``where`` names them in
    the error raised when no frame sees every rigid marker."""
    seen = np.flatnonzero(np.isfinite(positions[:, rigid_index]).all(axis=(1, 2)))
    if seen.size == 0:
        raise WorkbenchError(
            f"{where}: no frame sees every rigid marker (dataset.rigid_markers); set dataset.neutral_frame"
        )
    reference = positions[seen[0], rigid_index]
    markers = stabilise(positions, rigid_index, reference).markers[:, table_index]
    return neutral_rest(markers, labels, int(seen[0])).nearest_frame


def face_markers(table: MarkerTable, rigid_labels: Sequence[str]) -> np.ndarray:
    """Which markers of the table are scored: all but the rigid ones; shape (n_markers,) of bool."""
    face = np.array([label not in rigid_labels for label in table.labels])
    if not face.any():
        raise WorkbenchError(
            f"every marker of {table.path.name} is one of dataset.rigid_markers: no face marker is left to score"
        )
    return face


def stabilised_span(
    take: MarkerTake, selected: np.ndarray, rigid_labels: Sequence[str], table: MarkerTable, reference: np.ndarray
) -> Stabilised:
    """The table's markers of every frame of ``take`` from the first ``selected`` frame to the last, head motion
    removed, and the stabilisation residual of each frame: the noise floor is measured on consecutive frames, the
    capture's own, whatever ``dataset.frame_step``.

    Parameters
    ----------
    take : MarkerTake
    selected : ndarray of shape (n_selected,) of int
        Frames of the file used, increasing.
    rigid_labels : sequence of str
    table : MarkerTable
    reference : ndarray of shape (n_rigid, 3)
        The rigid markers' reference positions.

    Returns
    -------
    Stabilised
        ``markers`` of shape (selected[-1] - selected[0] + 1, n_table_markers, 3).
    """
    dense = stabilise(
        take.positions[selected[0] : selected[-1] + 1],
        take.index_of(rigid_labels, named_in="dataset.rigid_markers"),
        reference,
    )
    return Stabilised(
        markers=dense.markers[:, take.index_of(table.labels, named_in=str(table.path))], residual_rms=dense.residual_rms
    )


def stabilised_takes(takes: Sequence[MarkerTake], table: MarkerTable, cfg: Mapping) -> StabilisedTakes:
    """Select frames, remove head motion on ``dataset.rigid_markers`` and concatenate the takes.

    The rigid markers' reference is their position in the neutral frame (``dataset.neutral_take``,
    ``dataset.neutral_frame``; a null frame is the take's rest face, :func:`rest_frame`). Gaps (samples the file
    lacks, plus ``dataset.gap_rate`` of simulated dropout) are handled after stabilisation by ``dataset.gap_policy``
    (:func:`workbench.dataset.gaps.apply_gap_policy`; the default ``drop`` keeps the frames that saw every marker
    of the table), per take.
    """
    rigid_labels = list(cfg.rigid_markers or [])
    neutral_take = int(cfg.neutral_take)
    if not 0 <= neutral_take < len(takes):
        raise WorkbenchError(f"dataset.neutral_take {neutral_take} is not one of the {len(takes)} takes")
    first = takes[neutral_take]
    rigid_index = first.index_of(rigid_labels, named_in="dataset.rigid_markers")
    table_index = first.index_of(table.labels, named_in=str(table.path))
    if cfg.neutral_frame is None:
        neutral_frame = rest_frame(first, rigid_index, table_index, table.labels)
    else:
        neutral_frame = int(cfg.neutral_frame)
    if not 0 <= neutral_frame < first.n_frames:
        raise WorkbenchError(
            f"dataset.neutral_take {neutral_take} / neutral_frame {neutral_frame} is not a frame of "
            f"the {len(takes)} takes"
        )
    reference = first.positions[neutral_frame, rigid_index]
    if not np.all(np.isfinite(reference)):
        raise WorkbenchError(
            f"{first.path}: frame {neutral_frame} (the neutral) misses a rigid marker; choose "
            "another dataset.neutral_frame"
        )
    check_rigid_set(rigid_labels, reference, f"{first.path} frame {neutral_frame}")
    face = face_markers(table, rigid_labels)
    # The rigid reference is the neutral frame's own, so the neutral frame is already in the head frame.
    neutral = first.positions[neutral_frame, table_index]
    rest = neutral_rest(
        stabilise(first.positions, rigid_index, reference).markers[:, table_index], table.labels, neutral_frame
    )

    policy = cfg.gap_policy
    rate = float(cfg.gap_rate)
    gap_seed = int(cfg.gap_seed)
    pieces, visible, notes, record, timelines, problems, residuals, trajectories = [], [], [], {}, [], [], [], []
    for number, take in enumerate(takes):
        selected = frame_selection(
            take.n_frames, cfg.frame_step, cfg.max_frames_per_take, "dataset.max_frames_per_take"
        )
        dense = stabilised_span(take, selected, rigid_labels, table, reference)
        residuals.append(dense.residual_rms)
        trajectories.append(dense.markers[:, face])
        markers, residual_rms = dense.markers[selected - selected[0]], dense.residual_rms[selected - selected[0]]
        problems += outlier_problems(markers, table.labels, str(take.path), frames=selected)
        if rate > 0:
            rng = np.random.default_rng(np.random.SeedSequence(gap_seed, spawn_key=(number,)))
            mask = gap_mask(len(markers), markers.shape[1], rate, float(cfg.gap_mean_frames), rng)
            markers = np.where(mask[:, :, None], np.nan, markers)
        outcome = apply_gap_policy(markers, policy, cfg.gap_max_fill_frames)
        pieces.append(outcome.positions)
        timelines.append(Timeline.uniform(take.path.stem, selected[outcome.kept], take.frame_rate))
        visible.append(outcome.visible)
        residual_mean, residual_max = float(np.nanmean(residual_rms)), float(np.nanmax(residual_rms))
        report = outcome.report
        notes.append(
            f"{take.path.stem} {len(outcome.positions)} frames (residual mean {residual_mean:.2f}, max "
            f"{residual_max:.2f} mm" + (f"; {report.describe()}" if report.n_missing_samples else "") + ")"
        )
        record[take.path.name] = {
            "frames_in_file": take.n_frames,
            "frame_rate_in_file": take.frame_rate,
            "frames_used": len(outcome.positions),
            "frames_dropped_for_gaps": report.n_dropped_frames,
            "missing_samples_in_file": take.n_missing,
            "simulated_dropout_rate": rate,
            "gaps": report.as_dict(),
            "units_in_file": take.units,
            "stabilisation_residual_rms_mm": {"mean": residual_mean, "max": residual_max},
            "noise_floor_mm": noise_floor(residuals[-1:], trajectories[-1:]).as_dict(),
        }
    positions = np.concatenate(pieces)
    if len(positions) < 2:
        raise WorkbenchError(f"{len(positions)} frames in the takes after gap policy {policy!r}; need at least 2")
    return StabilisedTakes(
        positions=positions,
        neutral=neutral,
        notes=notes,
        record=record,
        timeline=Timeline.concatenate(timelines),
        visible=np.concatenate(visible) if policy == "masked" else None,
        warnings=settle(problems, cfg.plausibility),
        neutral_rest=rest,
        face=face,
        noise_floor=noise_floor(residuals, trajectories),
    )


def take_problems(takes: Sequence[MarkerTake]) -> list[str]:
    """Plausibility of the raw takes: per-take units (face size), frame rates, markers parked at the origin,
    markers jumping together between frames and takes that never move."""
    problems = take_units_problems(
        {str(take.path): face_spread(take.positions) for take in takes}, {str(take.path): take.units for take in takes}
    )
    for take in takes:
        problems += frame_rate_problems(take.frame_rate, str(take.path), "POINT:RATE")
        problems += parked_marker_problems(take.positions, take.labels, str(take.path))
        problems += take_motion_problems(take.positions, str(take.path), take.units)
    return problems


def check_distinct_takes(take_files: Sequence[str], takes: Sequence[MarkerTake]) -> None:
    """Refuse a take listed twice, or two files holding the same frames: concatenating them would count the same
    motion twice (always an error: no one means it)."""
    seen = {}
    for name, take in zip(take_files, takes):
        key = (take.positions.shape, np.nan_to_num(take.positions).tobytes())
        if key in seen:
            same = "is listed twice" if seen[key] == name else f"holds the same frames as {seen[key]}"
            raise WorkbenchError(
                f"dataset.takes: {name} {same}; each take must be a different recording (its frames "
                "would be counted twice)"
            )
        seen[key] = name


def mesh_operator(
    basis: Blendshapes, scale: float, marker_vertices: np.ndarray, mesh_points: np.ndarray, rbf: Mapping
) -> np.ndarray:
    """The RBF interpolation from marker displacements to mesh points of the scaled basis face (a linear map).

    Parameters
    ----------
    basis : Blendshapes
    scale : float
        Performer size over basis size: the face interpolated on is ``scale * basis.neutral``.
    marker_vertices : ndarray of shape (n_markers,) of int
    mesh_points : ndarray of shape (n_points,) of int
    rbf : mapping
        ``dataset.rbf`` (metric, kernel, smoothing, epsilon, degree), checked.

    Returns
    -------
    ndarray of shape (n_points, n_markers)
        Mesh displacements are ``operator @ marker_displacements`` per coordinate.
    """
    return mesh_rbf_matrix(
        scale * basis.neutral,
        basis.triangles,
        marker_vertices,
        mesh_points,
        metric=rbf["metric"],
        kernel=rbf["kernel"],
        smoothing=float(rbf["smoothing"]),
        epsilon=rbf_epsilon(rbf["epsilon"]),
        degree=int(rbf["degree"]),
    )


def within_marker_reach(vertices: np.ndarray, marker_vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Which mesh points lie within the markers' reach: no farther from the nearest marker than the median
    distance between neighbouring markers. Farther points (neck, back of the head, ears) get their motion by
    extrapolation of the marker interpolation.

    Parameters
    ----------
    vertices : ndarray of shape (n_vertices, 3)
    marker_vertices : ndarray of shape (n_markers,) of int
    points : ndarray of shape (n_points,) of int
        The mesh points of the capture.

    Returns
    -------
    ndarray of shape (n_points,) of bool
    """
    from scipy.spatial import cKDTree

    tree = cKDTree(vertices[marker_vertices])
    spacing = float(np.median(tree.query(vertices[marker_vertices], k=2)[0][:, 1]))
    return tree.query(vertices[points])[0] <= spacing


def build_animface(cfg, storage: FrameStorage = FrameStorage()) -> dict[str, Capture]:
    """Real optical takes with ICT hand shapes, on the markers and/or interpolated onto the ICT face.

    Parameters
    ----------
    cfg : AnimfaceSettings
        The typed ``dataset`` settings, checked (see ``conf/dataset/animface.yaml``).
    storage : FrameStorage
        Where the interpolated mesh frames are written, a chunk of frames at a time (``dataset.storage``,
        ``dataset.dtype``); the markers' frames are kept as it says once built.

    Returns
    -------
    dict
        ``train_on`` name (``markers`` or ``mesh``) -> :class:`Capture`, from the same takes.
    """
    names = name_list(cfg.train_on)
    placed = _placed_takes(cfg)
    shared = _shared_facts(cfg, placed)
    return {name: _variant_capture(name, cfg, placed, shared, storage) for name in names}


@dataclass(frozen=True)
class _Placed:
    """AnimFace takes read, stabilised and placed on the ICT face (:func:`_placed_takes`); coordinates in mm in the
    ICT head frame at the performer's size."""

    take_files: list
    takes: list
    warnings: list
    hand_names: list
    basis: Blendshapes
    table: MarkerTable
    stable: StabilisedTakes
    placement: MarkerPlacement
    similarity: Similarity
    scale: float
    neutral: np.ndarray
    displacements: np.ndarray
    hand: np.ndarray


def read_take(path) -> MarkerTake:
    """One take, read by the marker-take format of its suffix (:data:`workbench.formats.registry.FORMATS`)."""
    return format_for(path, "marker take", "dataset.takes").read(path)


def _placed_takes(cfg: Mapping) -> _Placed:
    """Read and check the takes, stabilise them, place the basis face on the performer's markers and express the
    capture in the ICT head frame."""
    take_files = list(cfg.takes or [])
    if not take_files:
        raise WorkbenchError("dataset.takes is empty: list the C3D files to use (relative to the data root)")
    takes = [read_take(data_path(cfg.data_root, name, "takes")) for name in take_files]
    check_distinct_takes(take_files, takes)
    warnings = settle(take_problems(takes), cfg.plausibility)
    if len({take.frame_rate for take in takes}) != 1:
        raise WorkbenchError(
            f"the takes have different frame rates {[take.frame_rate for take in takes]} Hz; "
            "concatenating them needs one"
        )
    folder = data_path(cfg.data_root, cfg.blendshapes.folder, "blendshapes.folder")
    hand_names = hand_shape_names(cfg.hand_shapes, expression_names(folder, cfg.blendshapes.neutral))
    basis = load_basis(cfg, hand_names)
    warnings += settle(
        face_size_problems(basis.neutral, str(folder), "dataset.blendshapes.unit_mm", basis.unit_mm),
        cfg.plausibility,
    )
    table = read_marker_table(conf_path(cfg.marker_table, "marker_table"), n_vertices=len(basis.neutral))
    stable = stabilised_takes(takes, table, cfg)
    warnings += stable.warnings

    placement = place_markers(
        table,
        stable.neutral,
        basis.neutral,
        refine_iterations=int(cfg.refine_iterations),
    )
    similarity, scale = placement.mesh_to_capture, placement.mesh_to_capture.scale
    if not FACE_SCALE_RANGE[0] <= scale <= FACE_SCALE_RANGE[1]:
        raise WorkbenchError(
            f"unit mismatch: the basis face must be scaled by {scale:.4g} to fit the performer's markers "
            f"({table.path.name}), and two faces differ by less than {FACE_SCALE_RANGE[1]:g}x; check "
            f"dataset.blendshapes.unit_mm ({cfg.blendshapes.unit_mm} mm per OBJ unit) against the takes' "
            f"POINT:UNITS ({', '.join(sorted({take.units for take in takes}))})"
        )
    # Express the capture in the ICT head frame (axes and origin) while keeping the performer's size: the rigid
    # part of the inverse similarity. The ICT face then sits at scale * its own coordinates.
    neutral = placement.in_mesh_frame(stable.neutral)
    displacements = placement.in_mesh_frame(stable.positions) - neutral
    hand = scale * basis.shapes(hand_names)
    check_hand_shapes(hand.reshape(len(hand_names), -1), hand_names, f"dataset.blendshapes.folder {folder}")
    return _Placed(
        take_files=take_files,
        takes=takes,
        warnings=warnings,
        hand_names=hand_names,
        basis=basis,
        table=table,
        stable=stable,
        placement=placement,
        similarity=similarity,
        scale=scale,
        neutral=neutral,
        displacements=displacements,
        hand=hand,
    )


def _shared_facts(cfg: Mapping, placed: _Placed) -> tuple[list[str], dict, float, dict]:
    """What every data variant of the capture says about itself: notes, provenance, frame rate, RBF settings."""
    takes, stable, placement, similarity = placed.takes, placed.stable, placed.placement, placed.similarity
    scale, table, take_files = placed.scale, placed.table, placed.take_files
    rbf = {key: getattr(cfg.rbf, key) for key in ("metric", "kernel", "smoothing", "epsilon", "degree")}
    rigid_labels = list(cfg.rigid_markers or [])
    neutral_name = f"{takes[int(cfg.neutral_take)].path.stem} frame {stable.neutral_rest.frame}"
    frame_step = int(cfg.frame_step)
    frame_rate = takes[0].frame_rate / frame_step
    notes_common = [
        DIFFERENT_FACES + f" (scaled by {scale:.3f} into the performer's frame)",
        f"takes recorded at {takes[0].frame_rate:g} Hz, every {frame_step} frame used ({frame_rate:g} frames per "
        "second), concatenated in time: " + "; ".join(stable.notes),
        f"head motion removed per frame (Kabsch) on rigid markers {', '.join(rigid_labels)}, to their positions in "
        f"{neutral_name} (the neutral); residual = their RMS distance from it",
        stable.neutral_rest.describe(takes[int(cfg.neutral_take)].path.stem),
        stable.noise_floor.describe() + " (residual: RMS of the rigid markers after alignment; jitter: RMS of the "
        "face markers' second difference over frames / sqrt(6), an upper bound)",
        placement.describe(),
    ]
    provenance = {
        "kind": "animface",
        "data_root": str(cfg.data_root),
        "takes": take_files,
        "per_take": stable.record,
        "frame_rate_in_file": takes[0].frame_rate,
        "frame_step": frame_step,
        "credits": [ANIMFACE_CREDIT, ICT_CREDIT],
        "performer_and_basis": "different faces",
        "neutral": neutral_name,
        "neutral_from_rest_mm": {
            "rms": stable.neutral_rest.rms_mm,
            "largest": stable.neutral_rest.largest_mm,
            "take_frame_nearest_rest": stable.neutral_rest.nearest_frame,
        },
        "rigid_markers": rigid_labels,
        "blendshapes": cfg.blendshapes.folder,
        "noise_floor_mm": dict(stable.noise_floor.as_dict(), jitter_estimator=JITTER_ESTIMATOR),
        "marker_table": str(table.path),
        "rbf": rbf,
        "placement": {
            "scale": scale,
            "rotation": similarity.rotation.tolist(),
            "translation_mm": similarity.translation.tolist(),
            "landmark_rms_mm": placement.landmark_rms,
            "refine_iterations": placement.refine_iterations,
            "vertices": dict(zip(table.labels, placement.vertices.tolist())),
            "distance_mm": dict(zip(table.labels, np.round(placement.distances, 2).tolist())),
        },
    }
    return notes_common, provenance, frame_rate, rbf


def _variant_capture(name: str, cfg: Mapping, placed: _Placed, shared: tuple, storage: FrameStorage) -> Capture:
    """One data variant (``markers`` or ``mesh``) of the placed takes (:func:`_shared_facts` in ``shared``)."""
    notes_common, provenance, frame_rate, rbf = shared
    basis, table, stable, placement, scale = placed.basis, placed.table, placed.stable, placed.placement, placed.scale
    neutral, displacements, hand, hand_names = placed.neutral, placed.displacements, placed.hand, placed.hand_names
    warnings = placed.warnings
    notes = list(notes_common)
    support = None
    face = stable.face
    if name == "markers":
        points_neutral, frames = neutral[face], displacements[:, face]
        points_hand, faces = hand[:, placement.vertices[face]], None
        labels = tuple(label for label, scored in zip(table.labels, face) if scored)
        notes.append(
            f"markers: the {len(labels)} face markers of {table.path.name}; the {int((~face).sum())} rigid "
            "ones remove head motion only and are not scored (they move only by the stabilisation "
            "residual)"
        )
    else:
        mesh_points = mesh_point_indices(len(basis.neutral), cfg.mesh_vertex_step, hand, hand_names)
        operator = mesh_operator(basis, scale, placement.vertices, mesh_points, rbf)
        frames = interpolated_frames(operator, displacements, storage)
        points_neutral, points_hand = scale * basis.neutral[mesh_points], hand[:, mesh_points]
        labels = tuple(f"v{i}" for i in mesh_points)
        faces = basis.triangles if len(mesh_points) == len(basis.neutral) else None
        support = within_marker_reach(scale * basis.neutral, placement.vertices, mesh_points)
        notes.append(
            f"mesh: {len(mesh_points)} ICT face-region vertices moved by an RBF interpolation "
            f"({rbf['kernel']}, {rbf['metric']} distance, smoothing {float(rbf['smoothing']):g}) of the "
            "marker displacements: the performer's motion carried onto the ICT face, not a scan of "
            f"the performer; largest displacement {largest_point_norm(frames):.1f} mm on the "
            f"mesh, {np.linalg.norm(displacements, axis=2).max():.1f} mm at the markers; "
            f"{int((~support).sum())} vertices farther from every marker than the markers' median "
            "spacing are extrapolated (the colour maps of the report fade there into the plain shade)"
        )
    if name == "markers":
        frames = frames.reshape(len(frames), -1)
    train, evaluate = split_frames(frames, cfg.split, cfg.eval_fraction)
    notes.append(f"split '{cfg.split}': {len(train)} training frames, {len(evaluate)} evaluated")
    eval_visible = None
    if stable.visible is not None and name == "markers":
        visible = stable.visible[:, face]
        eval_visible = visible[len(visible) - len(evaluate) :]
        evaluate = masked_frames(evaluate, eval_visible)
        train, note = masked_training_frames(train, visible[: len(train)], cfg.gap_fit_on)
        notes.append(
            f"masked solve: each evaluated frame's weights and alpha use only the markers it saw "
            f"({int((~eval_visible).sum())} of {eval_visible.size} evaluated marker samples missing); " + note
        )
    elif stable.visible is not None:
        notes.append("mesh: interpolated from the markers with their gaps filled linearly (the RBF needs every marker)")
    mapped = {}
    if name == "mesh":  # the PCA of the mesh frames is computed on the markers and lifted
        mapped = {
            "train_source": displacements.reshape(len(displacements), -1)[: len(train)],
            "train_operator": point_operator_matrix(operator),
        }
    return Capture(
        name="AnimFace optical capture (real performer) with ICT FaceKit hand shapes (a different face)",
        neutral=points_neutral.reshape(-1),
        train=train,
        eval=evaluate,
        hand=points_hand.reshape(len(hand_names), -1),
        hand_names=tuple(hand_names),
        point_labels=labels,
        units="mm",
        origin=origin_text(ORIGIN, points_neutral),
        frame_rate=float(frame_rate),
        **with_warnings(notes, dict(provenance, train_on=name), warnings),
        faces=faces,
        eval_visible=eval_visible,
        point_support=support,
        eval_timeline=stable.timeline[len(stable.timeline) - len(evaluate) :],
        **mapped,
    )
