"""Dataset ``mesh_sequence``: dense mesh sequences (4-D scans, VOCASET-style registered meshes) for mesh training.

The sequence is one array of vertex positions ``(frames, vertices, 3)`` with the triangles beside it, in a NumPy
``.npz`` (arrays named by ``vertices_key`` and ``faces_key``), a ``.npy`` (positions only; triangles from the hand
basis) or an HDF5 file (``.h5``/``.hdf5``, datasets at those paths). The neutral face is one frame of the sequence
or a separate OBJ of the same topology. The hand basis (``dataset.blendshapes``) is a blendshape folder or a
``.glb`` with morph targets on the same vertices (a rig registered to the scans).
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from workbench.dataset.capture import Capture
from workbench.dataset.hand_basis import check_same_points, read_shape_file, shape_subset
from workbench.dataset.meshes import read_obj, triangulate
from workbench.dataset.real import (data_path, frame_selection, integer_setting, origin_text, positive_setting)
from workbench.errors import WorkbenchError

TRAIN_ON = ("mesh",)
SEQUENCE_SUFFIXES = (".npz", ".npy", ".h5", ".hdf5")


def read_mesh_sequence(path: Path, vertices_key: str, faces_key: str | None) -> tuple[np.ndarray, np.ndarray | None]:
    """Vertex positions ``(n_frames, n_vertices, 3)`` (file units) and triangles ``(n, 3)`` or None of a sequence file.

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
    arrays = _hdf5_arrays(path, vertices_key, faces_key) if suffix in (".h5", ".hdf5") else \
        _numpy_arrays(path, vertices_key, faces_key)
    vertices, faces = arrays
    if vertices.ndim != 3 or vertices.shape[2] != 3 or vertices.shape[0] < 2 or vertices.shape[1] < 3:
        raise WorkbenchError(f"{path}: '{vertices_key}' must have shape (n_frames >= 2, n_vertices >= 3, 3), got "
                             f"{vertices.shape}")
    bad = np.flatnonzero(~np.all(np.isfinite(vertices), axis=(1, 2)))
    if bad.size:
        raise WorkbenchError(f"{path}: '{vertices_key}' frame {int(bad[0])} holds NaN or Inf ({bad.size} such frames)")
    if faces is not None:
        if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
            raise WorkbenchError(f"{path}: '{faces_key}' must be integer triangles of shape (n, 3), got "
                                 f"{faces.dtype} {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= vertices.shape[1]):
            raise WorkbenchError(f"{path}: '{faces_key}' refers to vertex {int(faces.max())}, outside the "
                                 f"{vertices.shape[1]} vertices (0-based)")
    return vertices.astype(np.float64, copy=False), faces


def _numpy_arrays(path: Path, vertices_key: str, faces_key: str | None):
    try:
        loaded = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as error:
        raise WorkbenchError(f"{path}: not a readable NumPy file ({error})") from None
    if isinstance(loaded, np.ndarray):  # .npy: positions only
        return loaded, None
    with loaded:
        if vertices_key not in loaded.files:
            raise WorkbenchError(f"{path}: no array '{vertices_key}' (dataset.vertices_key); it has {loaded.files}")
        faces = loaded[faces_key] if faces_key and faces_key in loaded.files else None
        return loaded[vertices_key], faces


def _hdf5_arrays(path: Path, vertices_key: str, faces_key: str | None):
    import h5py

    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise WorkbenchError(f"{path}: not a readable HDF5 file ({error})") from None
    with handle:
        if vertices_key not in handle or not isinstance(handle[vertices_key], h5py.Dataset):
            raise WorkbenchError(f"{path}: no dataset '{vertices_key}' (dataset.vertices_key); it has "
                                 f"{sorted(handle.keys())}")
        faces = handle[faces_key][()] if faces_key and faces_key in handle else None
        return handle[vertices_key][()], faces


def build_mesh_sequence(cfg: Mapping) -> dict[str, Capture]:
    """A dense mesh sequence with a hand basis on the same vertices (see ``conf/dataset/mesh_sequence.yaml``).

    Returns
    -------
    dict
        ``{"mesh": Capture}``.
    """
    from workbench.dataset import split_frames, train_on_list

    train_on_list(cfg, TRAIN_ON)
    path = data_path(cfg, cfg.get("sequence"), "sequence")
    unit_mm = positive_setting(cfg.get("unit_mm", 1.0), "dataset.unit_mm")
    frame_rate = positive_setting(cfg.get("frame_rate"), "dataset.frame_rate")
    vertices, faces = read_mesh_sequence(path, str(cfg.get("vertices_key") or "vertices"), cfg.get("faces_key"))
    vertices = vertices * unit_mm
    if cfg.get("neutral"):
        neutral_path = data_path(cfg, cfg["neutral"], "neutral")
        neutral_mesh = read_obj(neutral_path)
        if neutral_mesh.n_vertices != vertices.shape[1]:
            raise WorkbenchError(f"dataset.neutral {neutral_path}: {neutral_mesh.n_vertices} vertices, but the "
                                 f"sequence has {vertices.shape[1]}")
        neutral = neutral_mesh.vertices * unit_mm
        faces = faces if faces is not None else triangulate(neutral_mesh.polygon_sizes, neutral_mesh.polygon_vertices)
        neutral_text = f"neutral: {neutral_path.name}"
    else:
        frame = integer_setting(cfg.get("neutral_frame", 0), "dataset.neutral_frame", minimum=0)
        if frame >= len(vertices):
            raise WorkbenchError(f"dataset.neutral_frame {frame} is outside the sequence's {len(vertices)} frames")
        neutral = vertices[frame].copy()
        neutral_text = f"neutral: frame {frame} of the sequence"

    spec = dict(cfg.get("blendshapes") or {})
    if not spec.get("path"):
        raise WorkbenchError("dataset.blendshapes.path is not set: a mesh sequence needs a hand basis on its vertices "
                             "(a blendshape folder or a .glb)")
    basis_path = data_path(cfg, spec["path"], "blendshapes.path")
    if not basis_path.exists():
        raise WorkbenchError(f"dataset.blendshapes.path {basis_path}: not found")
    basis = read_shape_file(spec, "dataset.blendshapes", basis_path)
    rms = check_same_points(neutral, basis.neutral, "dataset.blendshapes", basis_path, f"the sequence {path.name}")
    hand_names, hand = shape_subset(basis, cfg.get("hand_shapes"), "dataset.hand_shapes")
    faces = faces if faces is not None else basis.triangles

    index = frame_selection(len(vertices), cfg.get("frame_step", 1), cfg.get("max_frames"), "dataset.max_frames")
    displacements = (vertices[index] - neutral).reshape(len(index), -1)
    train, evaluate = split_frames(displacements, cfg.get("split", "same"), cfg.get("eval_fraction", 0.2))
    step = int(cfg.get("frame_step", 1))
    notes = (f"mesh sequence {path.name}: {len(index)} of {len(vertices)} frames (every {step}), "
             f"{vertices.shape[1]} vertices, file units x {unit_mm:g} -> mm; {neutral_text}",
             f"hand basis: {len(hand_names)} shapes of {basis_path.name} (its neutral {rms:.3g} mm RMS from the "
             "sequence's)",
             f"split '{cfg.get('split', 'same')}': {len(train)} training frames, {len(evaluate)} evaluated")
    return {"mesh": Capture(
        name=f"mesh sequence {path.name}", neutral=neutral.reshape(-1), train=train, eval=evaluate,
        hand=hand.reshape(len(hand_names), -1), hand_names=hand_names,
        point_labels=tuple(f"v{i}" for i in range(vertices.shape[1])), units="mm",
        origin=origin_text("origin of the sequence file", neutral), frame_rate=frame_rate / step,
        provenance={"kind": "mesh_sequence", "data_root": str(cfg.get("data_root")),
                    "files": {"sequence": str(cfg["sequence"]), "blendshapes": str(spec["path"])},
                    "unit_mm": unit_mm, "n_frames_in_file": len(vertices), "frames_used": len(index),
                    "frame_step": step, "train_on": "mesh"},
        notes=notes, faces=np.asarray(faces, dtype=np.int64))}
