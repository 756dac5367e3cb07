"""A basis as a glTF rig: the neutral mesh, morph targets an animation tool plays back exactly and one morph-weight
animation per take. ``workbench export`` writes its ``<basis>.glb`` with it, :func:`workbench.api.write_rig` a rig
of a fitted estimator, and the report's rig panel the rigs it poses: one writer, one file layout.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.reporting.export.bases import (
    AXES,
    PCA_MEAN,
    TARGETS_TEXT,
    ExportedBasis,
    PlaybackTargets,
    playback_targets,
)

GENERATOR = "quasi-eigen workbench"
"""``asset.generator`` of every glTF file the workbench writes (:func:`workbench.formats.gltf.glb_bytes`)."""


@dataclass(frozen=True)
class RigTake:
    """The frames of one take as one animation of the rig.

    Attributes
    ----------
    name : str
        The take's name; the animation is ``<basis>_<solver>_<name>``.
    rows : slice
        Its rows among the basis's weights.
    seconds : ndarray of shape (n,)
        Key times from the take's first frame, increasing.
    extras : dict
        The animation's ``extras`` (its take, frame rate, frames).
    """

    name: str
    rows: slice
    seconds: np.ndarray
    extras: dict = field(default_factory=dict)


def rig_mesh(basis: ExportedBasis, neutral: np.ndarray, triangles: np.ndarray, takes: Sequence[RigTake], extras: dict):
    """The morph mesh of one basis, ready for :func:`workbench.formats.gltf.glb_bytes`.

    Parameters
    ----------
    basis : workbench.reporting.export.ExportedBasis
        Shapes (n_shapes, 3 * n_vertices) in mm and the weights (n_frames, n_shapes) the animations play.
    neutral : ndarray of shape (n_vertices, 3)
        mm.
    triangles : ndarray of shape (n_triangles, 3) of int
    takes : sequence of RigTake
        One animation each; none for a rig without animations.
    extras : dict
        Facts for ``asset.extras`` beside the basis, its solver and how targets map to shapes.

    Returns
    -------
    mesh : workbench.formats.gltf.MorphMesh
    targets : workbench.reporting.export.PlaybackTargets
        The morph targets (names, scales, weights in [0, 1]) of :func:`workbench.reporting.export.playback_targets`.
    """
    from workbench.formats.gltf import MorphAnimation, MorphMesh

    n_points = len(neutral)
    targets = playback_targets(basis.names, basis.weights, basis.sculpted)
    animations = tuple(
        MorphAnimation(
            name=f"{basis.label}_{basis.solver}_{take.name}",
            seconds=take.seconds,
            weights=targets.weights[take.rows],
            extras=dict(take.extras),
        )
        for take in takes
    )
    mesh = MorphMesh(
        neutral=neutral,
        triangles=np.asarray(triangles),
        names=targets.names,
        deltas=targets.deltas(basis.shapes).reshape(len(targets.names), n_points, 3),
        animations=animations,
        extras={**extras, "basis": basis.label, "solver": basis.solver, "targets": TARGETS_TEXT},
        mesh_extras={"targetShapes": [basis.names[i] for i in targets.shapes], "targetScales": targets.scales.tolist()},
    )
    return mesh, targets


def rig_bytes(basis: ExportedBasis, neutral: np.ndarray, triangles: np.ndarray, takes, extras: dict) -> bytes:
    """:func:`rig_mesh` as the bytes of a ``.glb`` file (the mesh and its node named ``face``)."""
    from workbench.formats.gltf import glb_bytes

    mesh, _ = rig_mesh(basis, neutral, triangles, takes, extras)
    return glb_bytes(mesh, mesh_name="face", generator=GENERATOR)


def target_rows(targets: PlaybackTargets, names: Sequence[str]) -> list[dict]:
    """Each morph target's entry in a manifest: its name, the shape it is a multiple of and the multiple."""
    return [
        {"target": name, "shape": names[shape], "scale": float(scale)}
        for name, shape, scale in zip(targets.names, targets.shapes, targets.scales)
    ]


# --- a fitted estimator's rig (workbench.api.write_rig) ---


def estimator_basis(estimator, basis: str, frames, solver: str | None) -> ExportedBasis:
    """One basis of a fitted :class:`workbench.numerics.estimator.QuasiEigenFaces` as the export holds a run's.

    ``QE`` and ``H`` are the quasi-eigen faces (appended eigenfaces are not sculpted) and the hand shapes; ``PCA`` is
    ``pca_mean`` (weight 1 in every frame) then the eigenfaces, as the export writes PCA. With no frames the
    weights are one row of zeros (a rig without animations).
    """
    from workbench.numerics.estimator import BASES, QuasiEigenFaces

    if not isinstance(estimator, QuasiEigenFaces):
        raise WorkbenchError(f"write_rig: estimator must be a fitted QuasiEigenFaces, got {type(estimator).__name__}")
    if basis not in BASES:
        raise WorkbenchError(f"write_rig: basis must be one of {', '.join(map(repr, BASES))}; got {basis!r}")
    estimator._check_fitted()  # NotFittedError, as the estimator's own methods raise it
    n_hand = len(estimator.hand_shapes_)
    if basis == "PCA":
        if solver is not None:
            raise WorkbenchError(f"write_rig: solver must be None for basis 'PCA' (a projection), got {solver!r}")
        names = (PCA_MEAN,) + tuple(f"pca_{j + 1:02d}" for j in range(estimator.m_))
        shapes = np.vstack([estimator.mean_, estimator.eigenfaces_])
        sculpted = (True,) + (False,) * estimator.m_
    else:
        names = tuple(estimator.shape_names_) if basis == "QE" else tuple(estimator.shape_names_[:n_hand])
        shapes = estimator.shapes_ if basis == "QE" else estimator.hand_shapes_
        sculpted = tuple(i < n_hand for i in range(len(names)))
    if frames is None:
        weights = np.zeros((1, len(names)))
    elif basis == "PCA":
        coefficients = estimator.transform(frames, basis="PCA")
        weights = np.hstack([np.ones((len(coefficients), 1)), coefficients])
    else:
        weights = estimator.transform(frames, basis=basis, solver=solver)
    return ExportedBasis(
        label=basis,
        names=names,
        shapes=np.asarray(shapes, dtype=np.float64),
        weights=weights,
        solver="projection" if basis == "PCA" else solver or estimator.solver,
        alpha={},
        sculpted=sculpted,
    )


def check_rig_path(path: str | os.PathLike) -> Path:
    """``path`` as a ``.glb`` file write_rig may write: new, or a rig the workbench wrote before (replaced); a
    :class:`WorkbenchError` for any other existing file, a folder or a missing parent folder."""
    import json
    import struct

    path = Path(path)
    if path.suffix.lower() != ".glb":
        raise WorkbenchError(f"write_rig: {path} must end in .glb (binary glTF 2.0)")
    if not path.parent.is_dir():
        raise WorkbenchError(f"write_rig: folder {path.parent} does not exist")
    if path.is_symlink() or (path.exists() and not path.is_file()):
        raise WorkbenchError(f"write_rig: {path} is a folder or a symbolic link; give a new file's path")
    if path.exists():
        ours = False
        with open(path, "rb") as stream:
            head = stream.read(20)
            if len(head) == 20 and head[:4] == b"glTF":
                (length,) = struct.unpack_from("<I", head, 12)
                try:
                    ours = json.loads(stream.read(length)).get("asset", {}).get("generator") == GENERATOR
                except (ValueError, AttributeError):  # not JSON, or not an object: not a rig of ours
                    ours = False
        if not ours:
            raise WorkbenchError(
                f"write_rig: {path} exists and is not a rig the workbench wrote; it is left alone (choose a new path)"
            )
    return path


def write_estimator_rig(
    path: str | os.PathLike,
    estimator,
    *,
    triangles,
    basis: str = "QE",
    frames=None,
    seconds=None,
    frame_rate: float = 60.0,
    solver: str | None = None,
    take: str = "take",
) -> dict:
    """Write a fitted estimator's rig as :func:`workbench.api.write_rig` documents; returns its facts."""
    from workbench.core.files import write_atomic

    path = check_rig_path(path)
    exported = estimator_basis(estimator, basis, frames, solver)
    if estimator.neutral_ is None:
        raise WorkbenchError(
            "write_rig needs the neutral face: fit with QuasiEigenFaces(neutral=<array of shape (n_dims,)>)"
        )
    if not (isinstance(frame_rate, (int, float)) and not isinstance(frame_rate, bool) and frame_rate > 0):
        raise WorkbenchError(f"write_rig: frame_rate must be a positive number, got {frame_rate!r}")
    takes = []
    if frames is not None:
        n_frames = len(exported.weights)
        times = np.arange(n_frames) / float(frame_rate) if seconds is None else np.asarray(seconds, dtype=np.float64)
        if times.shape != (n_frames,) or not np.all(np.isfinite(times)):
            raise WorkbenchError(
                f"write_rig: seconds must be {n_frames} finite times, one per frame; got {times.shape}"
            )
        extras = {"take": take, "frame_rate": float(frame_rate), "frames": [0, n_frames - 1]}
        takes.append(RigTake(name=take, rows=slice(0, n_frames), seconds=times - times[0], extras=extras))
    elif seconds is not None:
        raise WorkbenchError("write_rig: seconds are the times of frames; give frames too")
    neutral = estimator.neutral_.reshape(-1, 3)
    triangles = np.asarray(triangles)
    if triangles.ndim != 2 or triangles.shape[-1:] != (3,) or not np.issubdtype(triangles.dtype, np.integer):
        raise WorkbenchError(f"write_rig: triangles must be integers of shape (n_triangles, 3), got {triangles.shape}")
    extras = {"units": "metres", "axes": AXES, "frame_rate": float(frame_rate), "source": "QuasiEigenFaces"}
    mesh, targets = rig_mesh(exported, neutral, triangles, takes, extras)
    from workbench.formats.gltf import glb_bytes

    write_atomic(path, glb_bytes(mesh, mesh_name="face", generator=GENERATOR))
    return {
        "path": str(path),
        "basis": exported.label,
        "solver": exported.solver,
        "shapes": list(exported.names),
        "targets": target_rows(targets, exported.names),
        "animations": [animation.name for animation in mesh.animations],
        "weights": exported.weights if frames is not None else None,
    }
