"""Reconstruction error (eq. 6) in its variants, RMS error, and how recognisable each quasi-eigen face stays.

Pure numerical code. Frames are rows of arrays of shape ``(n_frames, 3 * n_points)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import WorkbenchError
from workbench.tolerances import TOL, Tolerances

NORMALISATIONS = ("absolute", "displacement")


def _check_frames(name: str, array, *, n_dims: int | None = None, points: bool = False) -> np.ndarray:
    """``array`` as a non-empty 2-D float array (frames x dims), or a :class:`WorkbenchError` naming ``name``."""
    try:
        array = np.asarray(array, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise WorkbenchError(f"{name} must be a numeric array of shape (n_frames, n_dims): {error}") from None
    if array.ndim != 2 or array.size == 0:
        raise WorkbenchError(f"{name} must be a non-empty array of shape (n_frames, n_dims), got shape {array.shape}")
    if n_dims is not None and array.shape[1] != n_dims:
        raise WorkbenchError(f"{name} has {array.shape[1]} columns, but the captured frames have {n_dims}")
    if points and array.shape[1] % 3:
        raise WorkbenchError(f"{name} must have 3 * n_points columns (x, y, z per point), got {array.shape[1]}")
    return array


def _check_same_shape(reference, reconstruction, *, points: bool = False) -> tuple[np.ndarray, np.ndarray]:
    reference = _check_frames("reference", reference, points=points)
    reconstruction = _check_frames("reconstruction", reconstruction, points=points)
    if reconstruction.shape != reference.shape:
        raise WorkbenchError(f"reconstruction has shape {reconstruction.shape}, but the reference has "
                             f"{reference.shape}; they must match")
    return reference, reconstruction


def _check_finite(name: str, per_frame: np.ndarray) -> None:
    """Raise naming the first frame whose squared norm (or error) is not finite: its input holds NaN or Inf."""
    bad = np.flatnonzero(~np.isfinite(per_frame))
    if bad.size:
        raise WorkbenchError(f"{name} holds NaN or Inf values in {bad.size} frame(s), the first frame {int(bad[0])}; "
                             "alpha needs finite frames")


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
    reference, reconstruction = _check_same_shape(reference, reconstruction)
    error = np.linalg.norm(reference - reconstruction, axis=1)
    norm = np.linalg.norm(reference, axis=1)
    _check_finite("reference", norm)
    _check_finite("reconstruction", error)
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
    reference, reconstruction = _check_same_shape(reference, reconstruction)
    norm = np.linalg.norm(reference)
    if not 0.0 < norm < np.inf:
        raise WorkbenchError(f"pooled alpha needs a finite, non-zero reference, got norm {norm}")
    return float(100.0 * np.linalg.norm(reference - reconstruction) / norm)


def rms_point_error(reference: np.ndarray, reconstruction: np.ndarray) -> float:
    """Root-mean-square 3-D point error over all points and frames, in data units (millimetres).

    Parameters
    ----------
    reference, reconstruction : ndarray of shape (n_frames, 3 * n_points)

    Returns
    -------
    float
    """
    reference, reconstruction = _check_same_shape(reference, reconstruction, points=True)
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
                    squares: tuple[np.ndarray, np.ndarray] | None = None,
                    visible: np.ndarray | None = None) -> AlphaSummary:
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
    visible : ndarray of bool, shape (n_frames, n_points), optional
        Points each frame saw (capture gaps): every measure is then taken over the visible points only, errors
        and references alike, and ``captured`` may hold NaN at the others. None: every point.

    Returns
    -------
    AlphaSummary

    Raises
    ------
    WorkbenchError
        Shapes that do not match (``neutral`` of length ``n_dims = 3 * n_points``, ``reconstructed`` and each
        chunk it returns of the shape of the frames it reconstructs), empty frames, a ``chunk_frames`` below 1,
        or NaN/Inf in ``neutral``, in the captured frames (at visible points) or in the reconstruction.
    """
    captured = _check_frames("captured", captured, points=True)
    n_frames, n_dims = captured.shape
    neutral = np.asarray(neutral, dtype=np.float64)
    if neutral.shape != (n_dims,):
        raise WorkbenchError(f"neutral must have shape ({n_dims},) to match the captured frames, got {neutral.shape}")
    if not np.all(np.isfinite(neutral)):
        raise WorkbenchError("neutral holds NaN or Inf values; alpha needs finite neutral positions")
    if not callable(reconstructed):
        reconstructed = _check_frames("reconstructed", reconstructed, n_dims=n_dims)
        if reconstructed.shape[0] != n_frames:
            raise WorkbenchError(f"reconstructed has {reconstructed.shape[0]} frames, but captured has {n_frames}")
    if isinstance(chunk_frames, bool) or not isinstance(chunk_frames, (int, np.integer)) or chunk_frames < 1:
        raise WorkbenchError(f"chunk_frames must be a positive integer, got {chunk_frames!r}")
    if visible is not None and np.shape(visible) != (n_frames, n_dims // 3):
        raise WorkbenchError(f"visible must have shape ({n_frames}, {n_dims // 3}) (frames x points), got "
                             f"{np.shape(visible)}")
    if squares is not None and any(np.shape(square) != (n_frames,) for square in squares):
        raise WorkbenchError(f"squares must be two arrays of shape ({n_frames},), got "
                             f"{[np.shape(square) for square in squares]}")
    # Eq. 6 in both normalisations from three row-wise squared norms, one pass over the frames each: the error
    # v* - v equals d* - d, and |v0 + d*|^2 = |v0|^2 + 2 v0.d* + |d*|^2 (same values as alpha_per_frame and
    # alpha_pooled, without forming the absolute positions).
    error_sq = np.empty(captured.shape[0])
    for start in range(0, captured.shape[0], chunk_frames):
        rows = slice(start, start + chunk_frames)
        estimate = reconstructed(rows) if callable(reconstructed) else reconstructed[rows]
        if np.shape(estimate) != captured[rows].shape:
            raise WorkbenchError(f"reconstructed returned shape {np.shape(estimate)} for frames "
                                 f"{rows.start}-{min(rows.stop, n_frames) - 1}; expected {captured[rows].shape}")
        difference = captured[rows] - estimate
        if visible is not None:
            difference = np.where(np.repeat(visible[rows], 3, axis=1), difference, 0.0)
        error_sq[rows] = np.einsum("ij,ij->i", difference, difference)
    with np.errstate(invalid="ignore", over="ignore"):  # NaN or Inf in the frames is named just below
        displacement_sq, position_sq = (squares if squares is not None
                                        else reference_squares(neutral, captured, visible=visible))
    n_compared = visible.sum() if visible is not None else captured.shape[0] * (captured.shape[1] // 3)
    return summarise_squares(error_sq, displacement_sq, position_sq, n_compared, tol=tol)


def summarise_squares(error_sq: np.ndarray, displacement_sq: np.ndarray, position_sq: np.ndarray,
                      n_compared_points: int, *, tol: Tolerances = TOL) -> AlphaSummary:
    """Every error measure of one reconstruction from per-frame squared norms (eq. 6 in both normalisations).

    Parameters
    ----------
    error_sq : ndarray of shape (n_frames,)
        ``|d* - d|^2`` (equal to ``|v* - v|^2``).
    displacement_sq, position_sq : ndarray of shape (n_frames,)
        ``|d*|^2`` and ``|v0 + d*|^2`` (:func:`reference_squares`).
    n_compared_points : int
        Points compared over all frames (the RMS divides by it).
    tol : Tolerances

    Returns
    -------
    AlphaSummary
    """
    _check_finite("captured", displacement_sq)
    _check_finite("captured", position_sq)
    _check_finite("reconstructed", error_sq)
    absolute = _alpha_from_squares(error_sq, position_sq, tol)
    displacement = _alpha_from_squares(error_sq, displacement_sq, tol)
    n_undefined = int(np.isnan(displacement).sum())
    return AlphaSummary(
        absolute_per_frame=absolute,
        displacement_per_frame=displacement,
        absolute_mean=float(np.nanmean(absolute)),
        absolute_pooled=float(100.0 * np.sqrt(error_sq.sum() / position_sq.sum())),
        displacement_mean=float(np.nanmean(displacement)) if n_undefined < len(displacement) else float("nan"),
        displacement_pooled=float(100.0 * np.sqrt(error_sq.sum() / displacement_sq.sum())),
        rms_mm=float(np.sqrt(error_sq.sum() / n_compared_points)),
        n_undefined_displacement_frames=n_undefined,
    )


def reference_squares(neutral: np.ndarray, captured: np.ndarray, *,
                      visible: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Squared norms of each captured frame as a displacement, ``|d*|^2``, and as positions, ``|v0 + d*|^2``.

    Parameters
    ----------
    neutral : ndarray of shape (n_dims,)
    captured : ndarray of shape (n_frames, n_dims)
    visible : ndarray of bool, shape (n_frames, n_points), optional
        Sum over the visible points of each frame only (NaN elsewhere is ignored).

    Returns
    -------
    displacement_sq, position_sq : ndarray of shape (n_frames,)
    """
    if visible is not None:
        seen = np.repeat(visible, 3, axis=1)
        displacement = np.where(seen, captured, 0.0)
        position = np.where(seen, captured + neutral, 0.0)
        return (np.einsum("ij,ij->i", displacement, displacement), np.einsum("ij,ij->i", position, position))
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
    hand, quasi_eigen = _check_frames("hand", hand), _check_frames("quasi_eigen", quasi_eigen)
    if quasi_eigen.shape != hand.shape:
        raise WorkbenchError(f"quasi_eigen has shape {quasi_eigen.shape}, but hand has {hand.shape}; one quasi-eigen "
                             "face per hand shape")
    hand_norm = np.linalg.norm(hand, axis=1)
    if not np.all(hand_norm > 0):
        raise WorkbenchError(f"hand shape(s) {np.flatnonzero(~(hand_norm > 0)).tolist()} are all zero or not finite; "
                             "their distance to a quasi-eigen face is undefined")
    qe_norm = np.linalg.norm(quasi_eigen, axis=1)
    relative_distance = np.linalg.norm(quasi_eigen - hand, axis=1) / hand_norm
    cosine = np.einsum("ij,ij->i", hand, quasi_eigen) / (hand_norm * qe_norm)
    return relative_distance, cosine


@dataclass(frozen=True)
class Conditioning:
    """How well a basis determines its weights (eq. 5): ill-conditioned bases give wild, unstable weights.

    Attributes
    ----------
    condition_number : float
        Largest over smallest singular value of the basis (``inf`` when rank-deficient).
    rank : int
        Numerical rank (singular values above ``eps * max(n_dims, n_shapes) * largest``, as ``numpy.linalg.lstsq``).
    n_shapes : int
    zero_shapes : tuple of int
        Shapes with no displacement at all.
    near_duplicates : tuple of (int, int, float)
        Pairs ``(i, j, cosine)`` of shapes whose directions agree to ``|cosine| >= duplicate_cosine``.
    """

    condition_number: float
    rank: int
    n_shapes: int
    zero_shapes: tuple
    near_duplicates: tuple

    def as_dict(self) -> dict:
        return {"condition_number": self.condition_number, "rank": self.rank, "n_shapes": self.n_shapes,
                "zero_shapes": list(self.zero_shapes),
                "near_duplicates": [[i, j, round(c, 6)] for i, j, c in self.near_duplicates]}


def basis_conditioning(shapes: np.ndarray, *, duplicate_cosine: float = 0.995) -> Conditioning:
    """Condition number, rank, zero shapes and near-duplicate pairs of a basis.

    Parameters
    ----------
    shapes : ndarray of shape (n_shapes, n_dims)
    duplicate_cosine : float
        Pairs at or above this ``|cosine|`` are reported as near duplicates.

    Returns
    -------
    Conditioning
    """
    singular = np.linalg.svd(shapes, compute_uv=False)
    cutoff = np.finfo(float).eps * max(shapes.shape) * singular.max(initial=0.0)
    rank = int((singular > cutoff).sum())
    full = rank == shapes.shape[0] and singular.size == shapes.shape[0]
    condition = float(singular.max() / singular.min()) if full else float("inf")
    norms = np.linalg.norm(shapes, axis=1)
    zero = tuple(int(i) for i in np.flatnonzero(norms == 0.0))
    unit = shapes / np.where(norms > 0, norms, 1.0)[:, None]
    cosine = unit @ unit.T
    i, j = np.triu_indices(len(shapes), k=1)
    close = np.abs(cosine[i, j]) >= duplicate_cosine
    pairs = tuple((int(a), int(b), float(cosine[a, b])) for a, b in zip(i[close], j[close]))
    return Conditioning(condition_number=condition, rank=rank, n_shapes=shapes.shape[0], zero_shapes=zero,
                        near_duplicates=pairs)
