"""Head-motion removal: per-frame rigid alignment of head markers (Kabsch), batched over frames."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import WorkbenchError


def kabsch(moving: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Best rigid transforms taking each frame's points onto a reference, ``R p + t ~ q`` in least squares.

    Parameters
    ----------
    moving : ndarray of shape (n_frames, n_points, 3)
        Points in each frame (at least 3 not collinear).
    reference : ndarray of shape (n_points, 3)
        Where the points should go.

    Returns
    -------
    rotations : ndarray of shape (n_frames, 3, 3)
        Proper rotations (determinant +1).
    translations : ndarray of shape (n_frames, 3)
    """
    moving_centre = moving.mean(axis=1)
    reference_centre = reference.mean(axis=0)
    covariance = np.einsum("fki,kj->fij", moving - moving_centre[:, None], reference - reference_centre)
    u, _, vt = np.linalg.svd(covariance)
    # Flip the last singular direction where the best orthogonal map would be a reflection.
    d = np.sign(np.linalg.det(np.einsum("fij,fjk->fik", u, vt)))
    d[d == 0] = 1.0
    u[:, :, 2] *= d[:, None]
    rotations = np.einsum("fij,fjk->fki", u, vt)  # (U V^T)^T = V U^T
    translations = reference_centre - np.einsum("fij,fj->fi", rotations, moving_centre)
    return rotations, translations


@dataclass(frozen=True)
class Stabilised:
    """Markers with the rigid head motion removed.

    Attributes
    ----------
    markers : ndarray of shape (n_frames, n_markers, 3)
        All markers in the head frame of the reference.
    residual_rms : ndarray of shape (n_frames,)
        RMS distance of the rigid markers from their reference after alignment (noise plus any non-rigidity).
    """

    markers: np.ndarray
    residual_rms: np.ndarray


def stabilise(markers: np.ndarray, rigid_index, reference: np.ndarray) -> Stabilised:
    """Remove rigid head motion by aligning each frame's rigid markers to their reference positions.

    Parameters
    ----------
    markers : ndarray of shape (n_frames, n_markers, 3)
    rigid_index : array-like of int
        Which markers move only with the head (at least 3).
    reference : ndarray of shape (n_rigid, 3)
        Their positions in the head frame.

    Returns
    -------
    Stabilised
    """
    rigid_index = np.asarray(rigid_index)
    if rigid_index.size < 3:
        raise WorkbenchError(f"stabilisation needs at least 3 rigid markers, got {rigid_index.size}")
    if reference.shape != (rigid_index.size, 3):
        raise WorkbenchError(f"rigid reference must have shape ({rigid_index.size}, 3), got {reference.shape}")
    rotations, translations = kabsch(markers[:, rigid_index], reference)
    aligned = np.einsum("fij,fmj->fmi", rotations, markers) + translations[:, None, :]
    residual = np.sqrt(np.mean(np.sum((aligned[:, rigid_index] - reference) ** 2, axis=2), axis=1))
    return Stabilised(markers=aligned, residual_rms=residual)
