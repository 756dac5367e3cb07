"""Reconstruction error (eq. 6) in its variants, RMS error, and how recognisable each quasi-eigen face stays.

Pure numerical code. Frames are rows of arrays of shape ``(n_frames, 3 * n_points)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.tolerances import TOL, Tolerances

NORMALISATIONS = ("absolute", "displacement")


def alpha_per_frame(reference: np.ndarray, reconstruction: np.ndarray, *,
                    tol: Tolerances = TOL) -> np.ndarray:
    """``alpha[%] = 100 |v* - v| / |v*|`` for each frame (eq. 6).

    Which vectors are passed decides the normalisation: absolute positions ``v* = v0 + d*`` give the paper's
    literal formula (its value depends on where the coordinate origin is); displacements ``d*`` give the
    origin-free ``100 |d* - d| / |d*|``.

    Parameters
    ----------
    reference : ndarray of shape (n_frames, n_dims)
        Captured frames ``v*`` (or ``d*``).
    reconstruction : ndarray of shape (n_frames, n_dims)
        Reconstructed frames ``v`` (or ``d``).
    tol : Tolerances
        Frames whose reference norm is below ``zero_displacement`` get NaN (alpha is undefined there).

    Returns
    -------
    ndarray of shape (n_frames,)
    """
    error = np.linalg.norm(reference - reconstruction, axis=1)
    norm = np.linalg.norm(reference, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(norm > tol.zero_displacement, 100.0 * error / norm, np.nan)


def alpha_pooled(reference: np.ndarray, reconstruction: np.ndarray) -> float:
    """Eq. 6 pooled over all frames: ``100 sqrt(sum_frames |v* - v|^2) / sqrt(sum_frames |v*|^2)``.

    Parameters
    ----------
    reference, reconstruction : ndarray of shape (n_frames, n_dims)

    Returns
    -------
    float
    """
    return float(100.0 * np.linalg.norm(reference - reconstruction) / np.linalg.norm(reference))


def rms_point_error(reference: np.ndarray, reconstruction: np.ndarray) -> float:
    """Root-mean-square 3-D point error over all points and frames, in data units (millimetres).

    Parameters
    ----------
    reference, reconstruction : ndarray of shape (n_frames, 3 * n_points)

    Returns
    -------
    float
    """
    n_points = reference.shape[1] // 3
    return float(np.sqrt(np.sum((reference - reconstruction) ** 2) / (reference.shape[0] * n_points)))


@dataclass(frozen=True)
class AlphaSummary:
    """Eq. 6 in both normalisations, per frame and aggregated.

    Attributes
    ----------
    absolute_per_frame, displacement_per_frame : ndarray of shape (n_frames,)
        Per-frame alpha in percent; NaN where the frame's reference norm is zero.
    absolute_mean, displacement_mean : float
        Mean of the per-frame values (NaN frames left out).
    absolute_pooled, displacement_pooled : float
        Pooled over all frames.
    rms_mm : float
        RMS 3-D point error.
    n_undefined_displacement_frames : int
        Frames left out of ``displacement_mean`` because their captured displacement is zero.
    """

    absolute_per_frame: np.ndarray
    displacement_per_frame: np.ndarray
    absolute_mean: float
    absolute_pooled: float
    displacement_mean: float
    displacement_pooled: float
    rms_mm: float
    n_undefined_displacement_frames: int


def summarise_alpha(neutral: np.ndarray, captured: np.ndarray, reconstructed, *,
                    tol: Tolerances = TOL, chunk_frames: int = 4096,
                    squares: tuple[np.ndarray, np.ndarray] | None = None) -> AlphaSummary:
    """Every error measure of one reconstruction.

    Parameters
    ----------
    neutral : ndarray of shape (n_dims,)
        Neutral positions ``v0`` (their origin is the origin of the absolute alpha).
    captured : ndarray of shape (n_frames, n_dims)
        Captured displacements ``d*``.
    reconstructed : ndarray of shape (n_frames, n_dims), or callable
        Reconstructed displacements ``d``, or a function of a ``slice`` of frames returning those frames'
        reconstruction, so that a mesh-scale reconstruction is never held whole.
    tol : Tolerances
    chunk_frames : int
        Frames handled at once; memory beyond the inputs stays O(chunk_frames * n_dims).
    squares : tuple of two ndarrays of shape (n_frames,), optional
        :func:`reference_squares` of ``(neutral, captured)``, when several reconstructions of the same frames
        are scored (saves two passes over the frames each).

    Returns
    -------
    AlphaSummary
    """
    # Eq. 6 in both normalisations from three row-wise squared norms, one pass over the frames each: the error
    # v* - v equals d* - d, and |v0 + d*|^2 = |v0|^2 + 2 v0.d* + |d*|^2 (same values as alpha_per_frame and
    # alpha_pooled, without forming the absolute positions).
    error_sq = np.empty(captured.shape[0])
    for start in range(0, captured.shape[0], chunk_frames):
        rows = slice(start, start + chunk_frames)
        estimate = reconstructed(rows) if callable(reconstructed) else reconstructed[rows]
        difference = captured[rows] - estimate
        error_sq[rows] = np.einsum("ij,ij->i", difference, difference)
    displacement_sq, position_sq = squares if squares is not None else reference_squares(neutral, captured)
    absolute = _alpha_from_squares(error_sq, position_sq, tol)
    displacement = _alpha_from_squares(error_sq, displacement_sq, tol)
    n_undefined = int(np.isnan(displacement).sum())
    n_points = captured.shape[1] // 3
    return AlphaSummary(
        absolute_per_frame=absolute,
        displacement_per_frame=displacement,
        absolute_mean=float(np.nanmean(absolute)),
        absolute_pooled=float(100.0 * np.sqrt(error_sq.sum() / position_sq.sum())),
        displacement_mean=float(np.nanmean(displacement)) if n_undefined < len(displacement) else float("nan"),
        displacement_pooled=float(100.0 * np.sqrt(error_sq.sum() / displacement_sq.sum())),
        rms_mm=float(np.sqrt(error_sq.sum() / (captured.shape[0] * n_points))),
        n_undefined_displacement_frames=n_undefined,
    )


def reference_squares(neutral: np.ndarray, captured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Squared norms of each captured frame as a displacement, ``|d*|^2``, and as positions, ``|v0 + d*|^2``.

    Parameters
    ----------
    neutral : ndarray of shape (n_dims,)
    captured : ndarray of shape (n_frames, n_dims)

    Returns
    -------
    displacement_sq, position_sq : ndarray of shape (n_frames,)
    """
    displacement_sq = np.einsum("ij,ij->i", captured, captured)
    position_sq = np.maximum(displacement_sq + 2.0 * (captured @ neutral) + neutral @ neutral, 0.0)
    return displacement_sq, position_sq


def _alpha_from_squares(error_sq: np.ndarray, reference_sq: np.ndarray, tol: Tolerances) -> np.ndarray:
    """Per-frame ``100 |error| / |reference|`` from squared norms, NaN where the reference is (near) zero."""
    defined = reference_sq > tol.zero_displacement ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(defined, 100.0 * np.sqrt(error_sq / reference_sq), np.nan)


def intuitiveness(hand: np.ndarray, quasi_eigen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far each quasi-eigen face moved from its hand shape.

    Parameters
    ----------
    hand : ndarray of shape (n_shapes, n_dims)
        Hand-made shapes ``e_i^H`` (displacements).
    quasi_eigen : ndarray of shape (n_shapes, n_dims)
        Their quasi-eigen faces ``e_i^QE``, in the same order.

    Returns
    -------
    relative_distance : ndarray of shape (n_shapes,)
        ``|e_i^QE - e_i^H| / |e_i^H|`` (0 = unchanged).
    cosine : ndarray of shape (n_shapes,)
        ``e_i^QE . e_i^H / (|e_i^QE| |e_i^H|)`` (1 = same direction).
    """
    hand_norm = np.linalg.norm(hand, axis=1)
    qe_norm = np.linalg.norm(quasi_eigen, axis=1)
    relative_distance = np.linalg.norm(quasi_eigen - hand, axis=1) / hand_norm
    cosine = np.einsum("ij,ij->i", hand, quasi_eigen) / (hand_norm * qe_norm)
    return relative_distance, cosine
