"""Dataset ``mesh_sequence``: dense mesh sequences (4-D scans, VOCASET-style registered meshes) for mesh training.

The sequence is one array of vertex positions ``(frames, vertices, 3)`` with the triangles beside it, in a NumPy
``.npz`` (arrays named by ``vertices_key`` and ``faces_key``), a ``.npy`` (positions only; triangles from the hand
basis) or an HDF5 file (``.h5``/``.hdf5``, datasets at those paths). The neutral face is one frame of the sequence
or a separate OBJ of the same topology. The hand basis (``dataset.blendshapes``) is a blendshape folder or a
``.glb`` with morph targets on the same vertices (a rig registered to the scans).

A ``.npy`` is memory-mapped and an HDF5 dataset read by slices, a chunk of frames at a time, and the displacements
are written chunk by chunk into the configured frame storage; a ``.npz`` (possibly compressed, so not mappable) is
read whole.
"""

from __future__ import annotations

import hashlib
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Mapping

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.cache import code_fingerprint
from workbench.dataset.capture import Capture
from workbench.dataset.common import array_digest, split_frames, train_on_list
from workbench.dataset.hand_basis import check_same_points, read_shape_file, shape_subset
from workbench.dataset.real import data_path, frame_selection, origin_text
from workbench.dataset.storage import FrameStorage
from workbench.formats.obj import read_obj, triangulate
from workbench.formats.plausibility import (
    SequenceMotion,
    face_size_problems,
    plausibility_policy,
    settle,
    with_warnings,
)
from workbench.numerics.frames import chunk_frames
from workbench.settings.rules import integer_setting, positive_setting

TRAIN_ON = ("mesh",)
SEQUENCE_SUFFIXES = (".npz", ".npy", ".h5", ".hdf5")


@contextmanager
def open_mesh_sequence(path: Path, vertices_key: str, faces_key: str | None) -> Iterator[MeshSequence]:
    """A sequence file opened for reading its frames on demand, checked (a pass over every frame, a chunk at a
    time). A ``.npy`` is memory-mapped and HDF5 read by slices; a ``.npz`` is read whole (a compressed archive
    cannot be mapped).

    Raises
    ------
    WorkbenchError
        If the file is missing or of another kind, lacks the named arrays, or they have the wrong shape or values.
    """
    suffix = path.suffix.lower()
    if not path.is_file():
        raise WorkbenchError(f"{path}: mesh sequence file not found")
    if suffix not in SEQUENCE_SUFFIXES:
        raise WorkbenchError(f"{path}: a mesh sequence must be one of {', '.join(SEQUENCE_SUFFIXES)}")
    opened = (
        _hdf5_arrays(path, vertices_key, faces_key)
        if suffix in (".h5", ".hdf5")
        else _numpy_arrays(path, vertices_key, faces_key)
    )
    with opened as (vertices, faces):
        if len(vertices.shape) != 3 or vertices.shape[2] != 3 or vertices.shape[0] < 2 or vertices.shape[1] < 3:
            raise WorkbenchError(
                f"{path}: '{vertices_key}' must have shape (n_frames >= 2, n_vertices >= 3, 3), got {vertices.shape}"
            )
        digest, problems = _check_values(path, vertices_key, vertices)
        if faces is not None:
            if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
                raise WorkbenchError(
                    f"{path}: '{faces_key}' must be integer triangles of shape (n, 3), got {faces.dtype} {faces.shape}"
                )
            if faces.size and (faces.min() < 0 or faces.max() >= vertices.shape[1]):
                raise WorkbenchError(
                    f"{path}: '{faces_key}' refers to vertex {int(faces.max())}, outside the "
                    f"{vertices.shape[1]} vertices (0-based)"
                )
        yield MeshSequence(vertices, faces, digest, tuple(problems))


@dataclass(frozen=True)
class MeshSequence:
    """An open sequence file.

    Attributes
    ----------
    vertices : array-like of shape (n_frames, n_vertices, 3)
        Positions in file units, read on demand by slicing (a memory map, an HDF5 dataset or an array).
    faces : ndarray of shape (n, 3) of int, or None
    digest : str
        Content hash of the positions.
    problems : tuple of str
        What the plausibility checks found (vertices far outside the face, jumps between frames, a static
        sequence), for ``dataset.plausibility`` to settle.
    """

    vertices: object
    faces: np.ndarray | None
    digest: str
    problems: tuple = ()

    @property
    def n_frames(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[1])

    def frames(self, start: int, stop: int, step: int = 1) -> np.ndarray:
        """Positions of frames ``start:stop:step``, float64, shape (n, n_vertices, 3)."""
        return np.asarray(self.vertices[start:stop:step], dtype=np.float64)


def _check_values(path: Path, vertices_key: str, vertices) -> tuple[str, list[str]]:
    """Content hash of the positions and the plausibility problems of the sequence, read a chunk of frames at a
    time; an error names a type that is not real numbers, and the first frame holding NaN or Inf."""
    dtype = np.dtype(vertices.dtype)
    if not (np.issubdtype(dtype, np.floating) or np.issubdtype(dtype, np.integer)) or dtype == np.bool_:
        raise WorkbenchError(f"{path}: '{vertices_key}' must hold real numbers (vertex positions), got {dtype}")
    n_frames, per_frame = vertices.shape[0], vertices.shape[1] * 3
    size = chunk_frames(per_frame)
    digest = hashlib.sha256(f"{dtype.str} {tuple(vertices.shape)}".encode())
    motion = SequenceMotion(str(path))
    first, count = None, 0
    for start in range(0, n_frames, size):
        chunk = np.ascontiguousarray(_read_chunk(path, vertices, start, start + size))
        digest.update(chunk)
        finite = np.all(np.isfinite(chunk), axis=(1, 2))
        bad = np.flatnonzero(~finite)
        if bad.size and first is None:
            first = start + int(bad[0])
        count += bad.size
        if count == 0:
            motion.add(start, chunk)
    if count:
        raise WorkbenchError(f"{path}: '{vertices_key}' frame {first} holds NaN or Inf ({count} such frames)")
    return digest.hexdigest(), motion.problems()


def _read_chunk(path: Path, vertices, start: int, stop: int) -> np.ndarray:
    """Frames ``start:stop`` of the file, or a one-line error when its data end early (a truncated file)."""
    try:
        return vertices[start:stop]
    except (OSError, ValueError, EOFError) as error:
        raise WorkbenchError(
            f"{path}: frames {start}-{stop - 1} cannot be read ({error}); the file is damaged or truncated"
        ) from None


@contextmanager
def _numpy_arrays(path: Path, vertices_key: str, faces_key: str | None):
    import zipfile
    import zlib

    damaged = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error)
    try:
        loaded = np.load(path, mmap_mode="r", allow_pickle=False)  # memory-maps a .npy; a .npz ignores it
    except damaged as error:
        raise WorkbenchError(f"{path}: not a readable NumPy file ({error})") from None
    if isinstance(loaded, np.ndarray):  # .npy: positions only
        yield loaded, None
        return
    with loaded:
        if vertices_key not in loaded.files:
            raise WorkbenchError(f"{path}: no array '{vertices_key}' (dataset.vertices_key); it has {loaded.files}")
        try:  # a .npz's arrays are read here: a truncated or damaged archive fails now
            faces = loaded[faces_key] if faces_key and faces_key in loaded.files else None
            vertices = loaded[vertices_key]
        except damaged as error:
            raise WorkbenchError(
                f"{path}: an array of the archive cannot be read ({type(error).__name__}: "
                f"{error}); the file is damaged or truncated"
            ) from None
    yield vertices, faces


@contextmanager
def _hdf5_arrays(path: Path, vertices_key: str, faces_key: str | None):
    import h5py

    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise WorkbenchError(f"{path}: not a readable HDF5 file ({error})") from None
    with handle:
        if vertices_key not in handle or not isinstance(handle[vertices_key], h5py.Dataset):
            raise WorkbenchError(
                f"{path}: no dataset '{vertices_key}' (dataset.vertices_key); it has {sorted(handle.keys())}"
            )
        faces = handle[faces_key][()] if faces_key and faces_key in handle else None
        yield handle[vertices_key], faces


def build_mesh_sequence(cfg: Mapping, storage: FrameStorage = FrameStorage()) -> dict[str, Capture]:
    """A dense mesh sequence with a hand basis on the same vertices (see ``conf/dataset/mesh_sequence.yaml``).

    Parameters
    ----------
    cfg : mapping
        The ``dataset`` config group.
    storage : FrameStorage
        Where the displacements are written, a chunk of frames at a time (``dataset.storage``, ``dataset.dtype``):
        the sequence is read on demand (but a ``.npz`` whole), so the whole float64 array is never held.

    Returns
    -------
    dict
        ``{"mesh": Capture}``.
    """
    train_on_list(cfg, TRAIN_ON)
    path = data_path(cfg, cfg.get("sequence"), "sequence")
    unit_mm = positive_setting(cfg.get("unit_mm", 1.0), "dataset.unit_mm")
    frame_rate = positive_setting(cfg.get("frame_rate"), "dataset.frame_rate")
    plausibility_policy(cfg)  # checked before the file is read
    with open_mesh_sequence(path, str(cfg.get("vertices_key") or "vertices"), cfg.get("faces_key")) as sequence:
        return _mesh_sequence_capture(cfg, storage, path, sequence, unit_mm, frame_rate)


def _mesh_sequence_capture(
    cfg: Mapping, storage: FrameStorage, path: Path, sequence: MeshSequence, unit_mm: float, frame_rate: float
) -> dict[str, Capture]:
    n_frames, n_vertices, faces = sequence.n_frames, sequence.n_vertices, sequence.faces
    warnings = settle(sequence.problems, plausibility_policy(cfg))
    if cfg.get("neutral"):
        neutral_path = data_path(cfg, cfg["neutral"], "neutral")
        neutral_mesh = read_obj(neutral_path)
        if neutral_mesh.n_vertices != n_vertices:
            raise WorkbenchError(
                f"dataset.neutral {neutral_path}: {neutral_mesh.n_vertices} vertices, but the sequence has {n_vertices}"
            )
        neutral = neutral_mesh.vertices * unit_mm
        faces = faces if faces is not None else triangulate(neutral_mesh.polygon_sizes, neutral_mesh.polygon_vertices)
        neutral_text = f"neutral: {neutral_path.name}"
    else:
        frame = integer_setting(cfg.get("neutral_frame", 0), "dataset.neutral_frame", minimum=0)
        if frame >= n_frames:
            raise WorkbenchError(f"dataset.neutral_frame {frame} is outside the sequence's {n_frames} frames")
        neutral = sequence.frames(frame, frame + 1)[0] * unit_mm
        neutral_text = f"neutral: frame {frame} of the sequence"

    spec = dict(cfg.get("blendshapes") or {})
    if not spec.get("path"):
        raise WorkbenchError(
            "dataset.blendshapes.path is not set: a mesh sequence needs a hand basis on its vertices "
            "(a blendshape folder or a .glb)"
        )
    basis_path = data_path(cfg, spec["path"], "blendshapes.path")
    if not basis_path.exists():
        raise WorkbenchError(f"dataset.blendshapes.path {basis_path}: not found")
    basis = read_shape_file(spec, "dataset.blendshapes", basis_path)
    rms = check_same_points(neutral, basis.neutral, "dataset.blendshapes", basis_path, f"the sequence {path.name}")
    warnings += settle(face_size_problems(neutral, str(path), "dataset.unit_mm", unit_mm), plausibility_policy(cfg))
    hand_names, hand = shape_subset(basis, cfg.get("hand_shapes"), "dataset.hand_shapes")
    faces = faces if faces is not None else basis.triangles

    index = frame_selection(n_frames, cfg.get("frame_step", 1), cfg.get("max_frames"), "dataset.max_frames")
    step = int(cfg.get("frame_step", 1))

    def chunk_of(rows: slice) -> np.ndarray:
        # frame_selection takes every step-th frame from the start: a chunk of them is one strided slice
        positions = sequence.frames(int(index[rows.start]), int(index[rows.stop - 1]) + 1, step)
        return (positions * unit_mm - neutral).reshape(len(positions), -1)

    key = (sequence.digest, array_digest(neutral), float(unit_mm), array_digest(index), code_fingerprint())
    displacements = storage.build("mesh_sequence", key, len(index), 3 * n_vertices, chunk_of)
    train, evaluate = split_frames(displacements, cfg.get("split", "same"), cfg.get("eval_fraction", 0.2))
    notes = (
        f"mesh sequence {path.name}: {len(index)} of {n_frames} frames (every {step}), "
        f"{n_vertices} vertices, file units x {unit_mm:g} -> mm; {neutral_text}",
        f"hand basis: {len(hand_names)} shapes of {basis_path.name} (its neutral {rms:.3g} mm RMS from the sequence's)",
        f"split '{cfg.get('split', 'same')}': {len(train)} training frames, {len(evaluate)} evaluated",
    )
    provenance = {
        "kind": "mesh_sequence",
        "data_root": str(cfg.get("data_root")),
        "files": {"sequence": str(cfg["sequence"]), "blendshapes": str(spec["path"])},
        "unit_mm": unit_mm,
        "n_frames_in_file": n_frames,
        "frames_used": len(index),
        "frame_step": step,
        "train_on": "mesh",
    }
    return {
        "mesh": Capture(
            name=f"mesh sequence {path.name}",
            neutral=neutral.reshape(-1),
            train=train,
            eval=evaluate,
            hand=hand.reshape(len(hand_names), -1),
            hand_names=hand_names,
            point_labels=tuple(f"v{i}" for i in range(n_vertices)),
            units="mm",
            origin=origin_text("origin of the sequence file", neutral),
            frame_rate=frame_rate / step,
            **with_warnings(notes, provenance, warnings),
            faces=np.asarray(faces, dtype=np.int64),
        )
    }
