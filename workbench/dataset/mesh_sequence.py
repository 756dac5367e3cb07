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

from pathlib import Path
from typing import Mapping

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.cache import code_fingerprint
from workbench.dataset.capture import Capture
from workbench.dataset.common import array_digest, split_frames
from workbench.dataset.hand_basis import check_same_points, read_shape_file, shape_subset
from workbench.dataset.real import data_path, frame_selection, origin_text
from workbench.dataset.storage import FrameStorage
from workbench.formats.mesh_sequence import MeshSequence, open_mesh_sequence
from workbench.formats.obj import read_obj, triangulate
from workbench.formats.plausibility import (
    face_size_problems,
    settle,
    with_warnings,
)
from workbench.numerics.displacements import frames_mean_and_motion, positions_problem


def build_mesh_sequence(cfg, storage: FrameStorage = FrameStorage()) -> dict[str, Capture]:
    """A dense mesh sequence with a hand basis on the same vertices (see ``conf/dataset/mesh_sequence.yaml``).

    Parameters
    ----------
    cfg : typed dataset settings or mapping
        The ``dataset`` config group.
    storage : FrameStorage
        Where the displacements are written, a chunk of frames at a time (``dataset.storage``, ``dataset.dtype``):
        the sequence is read on demand (but a ``.npz`` whole), so the whole float64 array is never held.

    Returns
    -------
    dict
        ``{"mesh": Capture}``.
    """
    path = data_path(cfg.data_root, cfg.sequence, "sequence")
    unit_mm = float(cfg.unit_mm)
    frame_rate = float(cfg.frame_rate)
    with open_mesh_sequence(path, str(cfg.vertices_key or "vertices"), cfg.faces_key) as sequence:
        return _mesh_sequence_capture(cfg, storage, path, sequence, unit_mm, frame_rate)


def _mesh_sequence_capture(
    cfg: Mapping, storage: FrameStorage, path: Path, sequence: MeshSequence, unit_mm: float, frame_rate: float
) -> dict[str, Capture]:
    n_frames, n_vertices, faces = sequence.n_frames, sequence.n_vertices, sequence.faces
    warnings = settle(sequence.problems, cfg.plausibility)
    if cfg.neutral:
        neutral_path = data_path(cfg.data_root, cfg.neutral, "neutral")
        neutral_mesh = read_obj(neutral_path)
        if neutral_mesh.n_vertices != n_vertices:
            raise WorkbenchError(
                f"dataset.neutral {neutral_path}: {neutral_mesh.n_vertices} vertices, but the sequence has {n_vertices}"
            )
        neutral = neutral_mesh.vertices * unit_mm
        faces = faces if faces is not None else triangulate(neutral_mesh.polygon_sizes, neutral_mesh.polygon_vertices)
        neutral_text = f"neutral: {neutral_path.name}"
    else:
        frame = int(cfg.neutral_frame)
        if frame >= n_frames:
            raise WorkbenchError(f"dataset.neutral_frame {frame} is outside the sequence's {n_frames} frames")
        neutral = sequence.frames(frame, frame + 1)[0] * unit_mm
        neutral_text = f"neutral: frame {frame} of the sequence"

    spec = cfg.blendshapes
    if spec is None or not spec.path:
        raise WorkbenchError(
            "dataset.blendshapes.path is not set: a mesh sequence needs a hand basis on its vertices "
            "(a blendshape folder or a .glb)"
        )
    basis_path = data_path(cfg.data_root, spec.path, "blendshapes.path")
    if not basis_path.exists():
        raise WorkbenchError(f"dataset.blendshapes.path {basis_path}: not found")
    basis = read_shape_file(
        basis_path,
        "dataset.blendshapes",
        neutral=spec.neutral,
        unit_mm=spec.unit_mm,
        region_vertices=spec.region_vertices,
    )
    rms = check_same_points(neutral, basis.neutral, "dataset.blendshapes", basis_path, f"the sequence {path.name}")
    warnings += settle(face_size_problems(neutral, str(path), "dataset.unit_mm", unit_mm), cfg.plausibility)
    hand_names, hand = shape_subset(basis, cfg.hand_shapes, "dataset.hand_shapes")
    faces = faces if faces is not None else basis.triangles

    index = frame_selection(n_frames, cfg.frame_step, cfg.max_frames, "dataset.max_frames")
    step = int(cfg.frame_step)

    def chunk_of(rows: slice) -> np.ndarray:
        # frame_selection takes every step-th frame from the start: a chunk of them is one strided slice
        positions = sequence.frames(int(index[rows.start]), int(index[rows.stop - 1]) + 1, step)
        return (positions * unit_mm - neutral).reshape(len(positions), -1)

    key = (sequence.digest, array_digest(neutral), float(unit_mm), array_digest(index), code_fingerprint())
    displacements = storage.build("mesh_sequence", key, len(index), 3 * n_vertices, chunk_of)
    warnings += settle(_positions_problems(displacements, path), cfg.plausibility)
    train, evaluate = split_frames(displacements, cfg.split, cfg.eval_fraction)
    notes = (
        f"mesh sequence {path.name}: {len(index)} of {n_frames} frames (every {step}), "
        f"{n_vertices} vertices, file units x {unit_mm:g} -> mm; {neutral_text}",
        f"hand basis: {len(hand_names)} shapes of {basis_path.name} (its neutral {rms:.3g} mm RMS from the sequence's)",
        f"split '{cfg.split}': {len(train)} training frames, {len(evaluate)} evaluated",
    )
    provenance = {
        "kind": "mesh_sequence",
        "data_root": str(cfg.data_root),
        "files": {"sequence": str(cfg.sequence), "blendshapes": str(spec.path)},
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


def _positions_problems(displacements, path: Path) -> list[str]:
    """The sequence's frames minus its neutral, when they still look like positions: the neutral is not the
    sequence's face in its units (:mod:`workbench.numerics.displacements`)."""
    mean, motion = frames_mean_and_motion(displacements)
    problem = positions_problem(
        f"dataset.sequence {path.name}: its frames minus the neutral",
        mean,
        motion,
        "the neutral (dataset.neutral, or dataset.neutral_frame) must be the sequence's own face in the sequence's "
        "units (dataset.unit_mm scales both)",
    )
    return [problem] if problem else []
