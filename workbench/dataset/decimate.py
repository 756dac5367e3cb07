"""Mesh density: decimate a mesh to a fraction of its vertices, keeping a subset of the original vertices.

Quadric edge collapse (``fast-simplification``) decides which vertices go; the vertices that are never collapsed
away are kept *at their original positions*, so every per-vertex quantity (capture frames, hand shapes) is
carried onto the decimated mesh by selecting rows, without resampling. The triangles of the decimated mesh come
from replaying the collapses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.core.errors import WorkbenchError


@dataclass(frozen=True)
class Decimation:
    """Which vertices a decimation kept.

    Attributes
    ----------
    kept : ndarray of shape (n_kept,) of int
        Original indices of the kept vertices, ascending.
    faces : ndarray of shape (n_faces, 3) of int
        Triangles over the kept vertices (indices into ``kept``).
    fraction : float
        The requested fraction.
    """

    kept: np.ndarray
    faces: np.ndarray
    fraction: float


def decimate(vertices: np.ndarray, faces: np.ndarray, fraction: float) -> Decimation:
    """Decimate a triangle mesh to about ``fraction`` of its triangles (and so of its vertices).

    Parameters
    ----------
    vertices : ndarray of shape (n_vertices, 3)
    faces : ndarray of shape (n_faces, 3) of int
    fraction : float
        In (0, 1] (``dataset.mesh_fraction``, checked with the settings, or a report's share of a mesh); 1 keeps the
        mesh as it is.

    Returns
    -------
    Decimation
    """
    vertices = np.array(vertices, dtype=np.float64, order="C")
    faces = np.array(faces, dtype=np.int32, order="C")
    if fraction == 1.0:
        return Decimation(kept=np.arange(len(vertices)), faces=faces.astype(np.int64), fraction=1.0)
    import fast_simplification

    _, _, collapses = fast_simplification.simplify(
        vertices, faces, target_reduction=1.0 - float(fraction), return_collapses=True
    )
    _, new_faces, mapping = fast_simplification.replay_simplification(vertices, faces, collapses)
    removed = np.unique(np.asarray(collapses)[:, 1]) if len(collapses) else np.empty(0, dtype=np.int64)
    kept = np.setdiff1d(np.arange(len(vertices)), removed)
    # replay numbers the surviving vertices in their original order; check that before trusting new_faces
    if not np.array_equal(np.asarray(mapping)[kept], np.arange(kept.size)):
        raise WorkbenchError(
            "mesh decimation: the kept vertices are not numbered in their original order "
            "(unexpected fast-simplification behaviour); cannot carry data onto them"
        )
    return Decimation(kept=kept, faces=np.asarray(new_faces, dtype=np.int64), fraction=float(fraction))
