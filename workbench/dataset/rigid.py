"""Head-motion removal: per-frame rigid alignment of head markers (Kabsch), batched over frames; similarity
alignment of two point sets (Umeyama)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.core.errors import WorkbenchError


def kabsch(
    moving: np.ndarray, reference: np.ndarray, weights: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Best rigid transforms taking each frame's points onto a reference, ``R p + t ~ q`` in least squares.

    Parameters
    ----------
    moving : ndarray of shape (n_frames, n_points, 3)
        Points in each frame (at least 3 not collinear).
    reference : ndarray of shape (n_points, 3)
        Where the points should go.
    weights : ndarray of shape (n_frames, n_points), optional
        Non-negative weight of each point in each frame (0 leaves a point out, e.g. a missing marker; its
        coordinates must still be finite). Equal weights when None.

    Returns
    -------
    rotations : ndarray of shape (n_frames, 3, 3)
        Proper rotations (determinant +1).
    translations : ndarray of shape (n_frames, 3)
    """
    if weights is None:
        moving_centre = moving.mean(axis=1)
        reference_centre = reference.mean(axis=0)
        covariance = np.einsum("fki,kj->fij", moving - moving_centre[:, None], reference - reference_centre)
    else:
        total = weights.sum(axis=1, keepdims=True)
        moving_centre = np.einsum("fk,fki->fi", weights, moving) / total
        reference_centre = weights @ reference / total
        covariance = np.einsum(
            "fk,fki,fkj->fij", weights, moving - moving_centre[:, None], reference[None] - reference_centre[:, None]
        )
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

    Missing samples (NaN) are allowed: a frame is aligned on the rigid markers it has, and a frame with fewer
    than 3 of them cannot be aligned and comes back as NaN (its residual too). NaN markers stay NaN.

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
    rigid = markers[:, rigid_index]
    present = np.all(np.isfinite(rigid), axis=2)
    if present.all():
        rotations, translations = kabsch(rigid, reference)
    else:
        alignable = present.sum(axis=1) >= 3
        rotations = np.full((len(markers), 3, 3), np.nan)
        translations = np.full((len(markers), 3), np.nan)
        rotations[alignable], translations[alignable] = kabsch(
            np.where(present[alignable, :, None], rigid[alignable], 0.0),
            reference,
            weights=present[alignable].astype(np.float64),
        )
    aligned = np.einsum("fij,fmj->fmi", rotations, markers) + translations[:, None, :]
    squared = np.sum((aligned[:, rigid_index] - reference) ** 2, axis=2)
    seen = np.isfinite(squared).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        residual = np.sqrt(np.where(seen > 0, np.nansum(squared, axis=1) / seen, np.nan))
    return Stabilised(markers=aligned, residual_rms=residual)


@dataclass(frozen=True)
class Similarity:
    """A similarity transform ``x -> scale * rotation @ x + translation``.

    Attributes
    ----------
    scale : float
    rotation : ndarray of shape (3, 3)
        Proper rotation.
    translation : ndarray of shape (3,)
    """

    scale: float
    rotation: np.ndarray
    translation: np.ndarray

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Transform points of shape (..., 3)."""
        return self.scale * points @ self.rotation.T + self.translation


def similarity_transform(source: np.ndarray, target: np.ndarray) -> Similarity:
    """Least-squares similarity taking ``source`` points onto ``target`` points (Umeyama 1991, with scale).

    Parameters
    ----------
    source, target : ndarray of shape (n_points, 3)
        Corresponding points (at least 3 not collinear).

    Returns
    -------
    Similarity
        Minimises ``sum |scale R s_i + t - q_i|^2`` over proper rotations ``R``.
    """
    source, target = np.asarray(source, dtype=np.float64), np.asarray(target, dtype=np.float64)
    if source.shape != target.shape or source.ndim != 2 or source.shape[1] != 3 or source.shape[0] < 3:
        raise WorkbenchError(
            f"a similarity alignment needs two (n >= 3, 3) arrays of corresponding points, got "
            f"{source.shape} and {target.shape}"
        )
    source_centre, target_centre = source.mean(axis=0), target.mean(axis=0)
    source_centred, target_centred = source - source_centre, target - target_centre
    u, singular, vt = np.linalg.svd(target_centred.T @ source_centred / len(source))
    sign = np.ones(3)
    sign[2] = 1.0 if np.linalg.det(u) * np.linalg.det(vt) >= 0 else -1.0
    rotation = (u * sign) @ vt
    variance = np.mean(np.sum(source_centred**2, axis=1))
    if not variance > 0:
        raise WorkbenchError("a similarity alignment needs source points that are not all in one place")
    scale = float(np.sum(singular * sign) / variance)
    return Similarity(scale=scale, rotation=rotation, translation=target_centre - scale * rotation @ source_centre)
