"""The synthetic actor's captures (``dataset.kind: synthetic``): stabilised markers, the dense mesh, the markers
interpolated onto it, and the face region; takes and meshes kept for the next run of a sweep in the same process."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Mapping, Sequence

import numpy as np

from workbench.core.resources import require_memory
from workbench.dataset.cache import code_fingerprint, kept_in_memory, on_forget
from workbench.dataset.capture import Capture, Timeline
from workbench.dataset.common import (
    interpolated_frames,
    masked_frames,
    masked_training_frames,
    name_list,
    point_operator_matrix,
    split_frames,
)
from workbench.dataset.decimate import Decimation, decimate
from workbench.dataset.gaps import apply_gap_policy, gap_mask
from workbench.dataset.rbf import mesh_rbf_matrix
from workbench.dataset.rigid import stabilise
from workbench.dataset.storage import FrameStorage

KEPT_BYTES = 1 << 30
"""Takes kept in memory beyond the last two, and face markers at all, only while each kind holds at most 1 GiB."""


def build_synthetic(cfg, storage: FrameStorage = FrameStorage()) -> dict[str, Capture]:
    """The synthetic actor's capture: stabilised markers, the dense mesh and/or the markers interpolated onto it.

    Parameters
    ----------
    cfg : SyntheticSettings
        The typed ``dataset`` settings, checked (see ``conf/dataset/synthetic.yaml``); nothing is checked again.
    storage : FrameStorage
        Where the dense mesh frames are written, chunk by chunk (``dataset.storage``, ``dataset.dtype``).

    Returns
    -------
    dict
        ``train_on`` name (``markers``, ``mesh`` or ``mesh_rbf``) -> :class:`Capture`, all from the same take
        (with ``split: other_take``, the evaluated frames come from a second take of the same actor).
    """
    names = name_list(cfg.train_on)
    eval_seed = cfg.seed + 1 if cfg.eval_seed is None else cfg.eval_seed
    seeds = [cfg.seed] + ([eval_seed] if cfg.split == "other_take" else [])  # two seeds differ: checked
    require_memory(
        synthetic_values(
            cfg.n_frames,
            cfg.n_face_markers + cfg.n_head_markers,
            cfg.mesh_rows * cfg.mesh_cols if {"mesh", "mesh_rbf", "face"} & set(names) else 0,
            cfg.storage,
            cfg.dtype,
        )
        * len(seeds),
        "the synthetic dataset",
        "dataset.n_frames, dataset.mesh_rows/mesh_cols or dataset.train_on",
    )
    keys = [_take_key(cfg, seed) for seed in seeds]
    takes = [_synthetic_take(key) for key in keys]
    decimation = _mesh_decimation(int(cfg.mesh_rows), int(cfg.mesh_cols), cfg.mesh_fraction)
    hand_mesh = takes[0].hand_shapes_mesh()
    markers = (
        [
            _marker_frames(
                key, cfg.gap_rate, cfg.gap_policy, cfg.gap_max_fill_frames, cfg.gap_mean_frames, cfg.stabilise
            )
            for key in keys
        ]
        if {"markers", "mesh_rbf"} & set(names)
        else None
    )
    return {
        name: _synthetic_capture(
            takes,
            keys,
            hand_mesh,
            decimation,
            markers,
            name,
            storage,
            mesh_fraction=cfg.mesh_fraction,
            split=cfg.split,
            eval_fraction=cfg.eval_fraction,
            frame_rate=cfg.frame_rate,
            gap_fit_on=cfg.gap_fit_on,
        )
        for name in names
    }


def synthetic_values(n_frames: int, n_markers: int, n_mesh_points: int, storage: str, dtype: str) -> int:
    """Float64 values one synthetic take holds in memory: every marker's track, and the mesh's (``n_mesh_points``,
    0 when no data variant lives on the mesh; x, y and z per point and frame; in the storage's dtype, none with
    ``dataset.storage=disk``)."""
    stored = 0.0 if storage == "disk" else 0.5 if dtype == "float32" else 1.0
    return int(n_frames * (n_markers + stored * n_mesh_points) * 3)


def _take_key(cfg: Mapping, seed: int) -> tuple:
    """The generation parameters of a take, hashable (the cache key of :func:`_synthetic_take`)."""
    return (
        ("n_frames", cfg.n_frames),
        ("frame_rate", cfg.frame_rate),
        ("n_face_markers", cfg.n_face_markers),
        ("n_head_markers", cfg.n_head_markers),
        ("head_rotation_deg", cfg.head_rotation_deg),
        ("head_translation_mm", cfg.head_translation_mm),
        ("marker_noise_mm", cfg.marker_noise_mm),
        ("seed", seed),
        ("mesh_rows", cfg.mesh_rows),
        ("mesh_cols", cfg.mesh_cols),
    )


@kept_in_memory(slots=4, always=2, max_bytes=KEPT_BYTES)
def _synthetic_take(key: tuple):
    """The take of these parameters; kept for the next runs of a sweep in the same process (its arrays are
    read-only, and the take is a deterministic function of its parameters). Four while small: a sweep over seeds
    with ``split: other_take`` at two sizes (the ``generalisation`` study) reads takes seed and seed + 1 at each
    size, and two kept made it generate 20 takes for its 30 runs, against the 12 it has (a take of 35,000 frames
    holds 70 MB)."""
    from workbench.dataset.synthetic import synthetic_take_of

    return synthetic_take_of(**dict(key))  # the dataset settings, checked


@lru_cache(maxsize=4)
def _mesh_decimation(mesh_rows: int, mesh_cols: int, fraction: float) -> Decimation:
    from workbench.dataset.synthetic import face_mesh_of

    mesh = face_mesh_of(mesh_rows, mesh_cols)  # dataset.mesh_rows/mesh_cols, checked
    return decimate(mesh.vertices, mesh.faces, fraction)


@lru_cache(maxsize=2)
def _mesh_frames(key: tuple, mesh_fraction: float, storage: FrameStorage = FrameStorage()):
    """Dense ground-truth displacements at the kept vertices, shape (n_frames, 3 * n_kept), read-only, written
    chunk by chunk into ``storage`` (an array of its dtype, or a file found again when it exists).

    The muscles act on each point alone, so deforming only the kept vertices gives exactly their rows of the
    full mesh sequence, at a cost that falls with the mesh density.
    """
    from workbench.dataset.synthetic import deform_displacements

    take = _synthetic_take(key)
    kept = _mesh_decimation(take.mesh.grid_shape[0], take.mesh.grid_shape[1], mesh_fraction).kept
    rest = take.mesh.vertices[kept]
    return storage.generate(
        "synthetic_mesh",
        (key, mesh_fraction, code_fingerprint()),
        take.n_frames,
        3 * len(rest),
        lambda rows, out: deform_displacements(rest, take.activations[rows], out),
        desc="mesh frames",
    )


@lru_cache(maxsize=4)
def face_region(mesh_rows: int, mesh_cols: int, n_face_markers: int) -> tuple[np.ndarray, np.ndarray]:
    """The face region of the synthetic mesh: the vertices the face markers cover, inside the markers' convex hull
    in the face plane, at full resolution; one evaluation set for bases fitted on any data variant.

    Returns
    -------
    vertices : ndarray of shape (n_region,) of int
        Mesh vertex indices, ascending.
    faces : ndarray of shape (n_region_faces, 3) of int
        The mesh's triangles with every corner in the region, as indices into ``vertices``.
    """
    from scipy.spatial import Delaunay

    from workbench.dataset.synthetic import face_mesh_of
    from workbench.dataset.synthetic.actor import place_face_markers

    mesh = face_mesh_of(mesh_rows, mesh_cols)  # dataset.mesh_rows/mesh_cols, checked
    markers = mesh.face_plane[place_face_markers(mesh, n_face_markers)]
    inside = Delaunay(markers).find_simplex(mesh.face_plane) >= 0
    vertices = np.flatnonzero(inside)
    renumber = np.full(mesh.n_vertices, -1)
    renumber[vertices] = np.arange(vertices.size)
    faces = renumber[mesh.faces[inside[mesh.faces].all(axis=1)]]
    for array in (vertices, faces):
        array.setflags(write=False)
    return vertices, faces


@lru_cache(maxsize=2)
def _face_region_frames(key: tuple, storage: FrameStorage = FrameStorage()):
    """Dense ground-truth displacements at the face region's vertices (:func:`face_region`), shape
    (n_frames, 3 * n_region), deformed at those vertices only (the muscles act on each point alone)."""
    from workbench.dataset.synthetic import deform_displacements

    take = _synthetic_take(key)
    vertices, _ = face_region(*take.mesh.grid_shape, len(take.face_marker_vertices))
    rest = take.mesh.vertices[vertices]
    return storage.generate(
        "synthetic_face",
        (key, code_fingerprint()),
        take.n_frames,
        3 * len(rest),
        lambda rows, out: deform_displacements(rest, take.activations[rows], out),
        desc="face frames",
    )


def forget_kept_frames() -> None:
    """Forget the dense frames kept in the process for the next run of a sweep (:func:`_mesh_frames`,
    :func:`_face_region_frames`), so the next build finds its files on disk again or writes them anew (the cache
    calls it when it removes a damaged one)."""
    _mesh_frames.cache_clear()
    _face_region_frames.cache_clear()


@kept_in_memory(slots=4, always=0, max_bytes=KEPT_BYTES)
def _marker_frames(
    key: tuple, rate: float, policy: str, max_fill: int | None, mean_frames: float, stabilised: bool
) -> "MarkerFrames":
    """:func:`_face_marker_frames` of the take of ``key``, kept for the next run of a sweep in the same process
    (read-only, as the take's): the runs of a sweep over other settings, such as ``dataset.split``, share them.
    The dataset settings the markers depend on (``gap_rate``, ``gap_policy``, ``gap_max_fill_frames``,
    ``gap_mean_frames``, ``stabilise``) are part of the key."""
    found = _face_marker_frames(_synthetic_take(key), rate, policy, max_fill, mean_frames, stabilised)
    for array in (found.frames, found.kept, found.visible):
        if array is not None:
            array.flags.writeable = False
    return found


def _face_marker_frames(
    take, rate: float, policy: str, max_fill: int | None, mean_frames: float, stabilised: bool
) -> "MarkerFrames":
    """Stabilised face markers of one take as displacements from rest, after the gap policy.

    With ``drop`` and ``linear`` the policy acts on all markers before head-motion removal (gaps filled or frames
    dropped, as a capture pipeline does); with ``masked`` the head motion is removed on the head markers each
    frame has, and the face markers keep their gaps for the evaluation (see :mod:`workbench.dataset.gaps`).
    """
    positions, notes, gaps, visible = take.markers, [], {}, None
    kept = np.ones(len(positions), dtype=bool)
    rate = float(rate)
    head = np.asarray(take.head_marker_index)
    face_index = np.setdiff1d(np.arange(take.markers.shape[1]), head)
    if rate > 0:
        # the take draws from the first three children of its seed; gaps use the fourth
        rng = np.random.default_rng(np.random.SeedSequence(take.provenance["seed"], spawn_key=(3,)))
        mask = gap_mask(positions.shape[0], positions.shape[1], rate, float(mean_frames), rng)
        positions = np.where(mask[:, :, None], np.nan, positions)
        if policy != "masked":
            outcome = apply_gap_policy(positions, policy, max_fill)
            positions, kept, report = outcome.positions, outcome.kept, outcome.report
    if stabilised:
        stable = stabilise(positions, head, take.head_marker_rest)
        positions = stable.markers
        notes.append(
            f"head motion removed with {head.size} head markers; rigid residual RMS "
            f"{np.nanmean(stable.residual_rms):.3f} mm (mean over frames)"
        )
    else:
        notes.append("head motion NOT removed (dataset.stabilise=false)")
    if rate > 0 and policy == "masked":
        outcome = apply_gap_policy(positions[:, face_index], policy)
        positions, kept, report, visible = outcome.positions, outcome.kept, outcome.report, outcome.visible
    else:
        positions = positions[:, face_index]
    if rate > 0:
        gaps = dict(report.as_dict(), rate=rate, mean_frames=float(mean_frames))
        where = "before" if policy != "masked" else "after"
        notes.append(
            f"marker dropout (seed {take.provenance['seed']}): {report.describe()} ({where} head-motion removal)"
        )
    neutral = take.mesh.vertices[take.face_marker_vertices]
    return MarkerFrames(positions - neutral, tuple(notes), gaps, kept, visible)


@dataclass(frozen=True)
class MarkerFrames:
    """Face markers of one synthetic take after gaps and stabilisation.

    Attributes
    ----------
    frames : ndarray of shape (n_kept, n_face_markers, 3)
        Displacements from rest, complete (filled where the gap policy fills).
    notes : tuple of str
    gaps : dict
        The gap policy's report (empty without dropout).
    kept : ndarray of shape (n_frames,) of bool
        Frames of the take that the gap policy kept (the dense mesh keeps the same ones).
    visible : ndarray of shape (n_kept, n_face_markers) of bool, or None
        Markers each kept frame saw, under the ``masked`` policy.
    """

    frames: np.ndarray
    notes: tuple
    gaps: dict
    kept: np.ndarray
    visible: np.ndarray | None


def _synthetic_capture(
    takes: Sequence,
    keys: Sequence[tuple],
    hand_mesh: np.ndarray,
    decimation: Decimation,
    markers,
    train_on: str,
    storage: FrameStorage = FrameStorage(),
    *,
    mesh_fraction: float,
    split: str,
    eval_fraction: float,
    frame_rate: float,
    gap_fit_on: str,
) -> Capture:
    """One data variant of the synthetic take(s).

    Parameters
    ----------
    takes : sequence of SyntheticTake
        The take, and with ``split: other_take`` the take the evaluated frames come from.
    keys : sequence of tuple
        Each take's generation parameters (:func:`_take_key`).
    hand_mesh : ndarray of shape (18, n_vertices, 3)
    decimation : Decimation
        The kept mesh vertices (all of them at ``mesh_fraction`` 1).
    markers : list of the results of :func:`_face_marker_frames`, one per take, or None
    train_on : {"markers", "mesh", "mesh_rbf", "face"}
    storage : FrameStorage
    mesh_fraction, split, eval_fraction, frame_rate, gap_fit_on
        Those of the ``dataset`` settings, checked.
    """
    take, notes = takes[0], []
    vertices = take.mesh.vertices
    provenance = dict(take.provenance, train_on=train_on)
    points, faces, labels, per_take, visible, source, operator = _variant_frames(
        takes, keys, decimation, markers, train_on, mesh_fraction, storage, notes, provenance
    )
    if markers is not None and markers[0].gaps and train_on != "mesh":
        provenance["gaps"] = markers[0].gaps
    eval_visible = None
    mapped = {}
    timelines = [
        Timeline.uniform(
            f"synthetic seed {t.provenance['seed']}",
            np.flatnonzero(part.kept) if markers is not None else np.arange(t.n_frames),
            float(frame_rate),
        )
        for t, part in zip(takes, markers or [None] * len(takes))
    ]
    if split == "other_take":
        train, evaluate = per_take
        timeline = timelines[1]
        eval_visible = visible[1] if visible else None
        if source is not None:
            mapped = {"train_source": source[0], "train_operator": point_operator_matrix(operator)}
        notes.append(
            f"split 'other_take': {len(train)} training frames of take seed {takes[0].provenance['seed']}, "
            f"{len(evaluate)} evaluated of take seed {takes[1].provenance['seed']}"
        )
        provenance["eval_seed"] = takes[1].provenance["seed"]
    else:
        train, evaluate = split_frames(per_take[0], split, eval_fraction)
        timeline = timelines[0][len(timelines[0]) - len(evaluate) :]
        eval_visible = visible[0][len(visible[0]) - len(evaluate) :] if visible else None
        if source is not None:
            mapped = {"train_source": source[0][: len(train)], "train_operator": point_operator_matrix(operator)}
        notes.append(f"split '{split}': {len(train)} training frames, {len(evaluate)} evaluated")
    if eval_visible is not None:
        evaluate = masked_frames(evaluate, eval_visible)
        train, note = masked_training_frames(train, visible[0][: len(train)], gap_fit_on)
        notes.append(
            f"masked solve: each evaluated frame's weights and alpha use only the markers it saw "
            f"({int((~eval_visible).sum())} of {eval_visible.size} evaluated marker samples missing); " + note
        )
    hand = hand_mesh[:, points]
    return Capture(
        name="synthetic actor (generated by the workbench; not real capture)",
        neutral=vertices[points].reshape(-1),
        train=train,
        eval=evaluate,
        hand=hand.reshape(hand.shape[0], -1),
        hand_names=tuple(take.muscle_names),
        point_labels=labels,
        units="mm",
        origin="centre of the synthetic head (face points lie 60-110 mm from it)",
        frame_rate=float(frame_rate),
        provenance=provenance,
        notes=tuple(notes),
        faces=faces,
        eval_visible=eval_visible,
        eval_timeline=timeline,
        **mapped,
    )


def _variant_frames(
    takes: Sequence,
    keys: Sequence[tuple],
    decimation: Decimation,
    markers,
    train_on: str,
    mesh_fraction: float,
    storage: FrameStorage,
    notes: list,
    provenance: dict,
) -> tuple:
    """The points, frames per take and marker visibility of one data variant; adds its notes and provenance.

    Returns
    -------
    tuple
        ``points`` (the mesh vertices or marker vertices used), ``faces`` (or None), ``labels``, ``per_take`` (frames
        of each take), ``visible`` (per take, or None), ``source`` (the marker frames a ``mesh_rbf`` variant is
        interpolated from, or None) and ``operator`` (that interpolation, or None).
    """
    take = takes[0]
    vertices = take.mesh.vertices
    faces, source, operator, visible = None, None, None, None
    if train_on == "markers":
        points = take.face_marker_vertices
        per_take = [part.frames.reshape(len(part.frames), -1) for part in markers]
        notes += markers[0].notes
        labels = tuple(take.marker_labels[i] for i in take.face_marker_index)
        visible = [part.visible for part in markers] if markers[0].visible is not None else None
    elif train_on == "face":
        points, faces = face_region(*take.mesh.grid_shape, len(take.face_marker_vertices))
        labels = tuple(f"v{i}" for i in points)
        per_take = [_face_region_frames(key, storage) for key in keys]
        if markers is not None:  # the frames the markers' gap policy kept
            per_take = [frames[part.kept] for frames, part in zip(per_take, markers)]
        provenance.update(n_face_region_points=int(points.size))
        notes.append(
            f"the dense ground-truth mesh's face region: the {points.size} of {len(vertices)} vertices inside "
            "the face markers' convex hull (face plane), at full resolution whatever dataset.mesh_fraction "
            "(no head motion, no marker noise)"
        )
    else:
        points = decimation.kept
        faces = decimation.faces
        labels = tuple(f"v{i}" for i in points)
        if decimation.fraction < 1.0:
            notes.append(
                f"mesh decimated to {points.size} of {len(vertices)} vertices (mesh_fraction "
                f"{decimation.fraction}, quadric edge collapse); data and shapes taken at the kept vertices"
            )
        provenance.update(mesh_fraction=decimation.fraction, n_mesh_points=int(points.size))
        if train_on == "mesh":
            per_take = [_mesh_frames(key, mesh_fraction, storage) for key in keys]
            if markers is not None:  # the frames the markers' gap policy kept
                per_take = [frames[part.kept] for frames, part in zip(per_take, markers)]
            notes.append("the dense ground-truth mesh (no head motion, no marker noise)")
        else:
            operator = mesh_rbf_matrix(  # the thin-plate spline with a linear polynomial, as the note says
                vertices,
                take.mesh.faces,
                take.face_marker_vertices,
                points,
                metric="euclidean",
                kernel="thin_plate_spline",
                smoothing=0.0,
                epsilon=1.0,
                degree=1,
            )
            per_take = [interpolated_frames(operator, part.frames, storage) for part in markers]
            source = [part.frames.reshape(len(part.frames), -1) for part in markers]
            notes += markers[0].notes
            notes.append(
                f"stabilised markers interpolated onto {points.size} mesh vertices by a thin-plate-spline "
                "RBF (Euclidean, linear polynomial)"
            )
    return points, faces, labels, per_take, visible, source, operator


on_forget(forget_kept_frames)
