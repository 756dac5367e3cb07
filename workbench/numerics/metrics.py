"""Reconstruction error (eq. 6) in its variants, RMS error, and how recognisable each quasi-eigen face stays.

Pure numerical code. Frames are rows of arrays of shape ``(n_frames, 3 * n_points)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.tolerances import TOL, Tolerances
from workbench.numerics.validation import FRAMES, check_matrix


def _check_same_shape(reference, reconstruction, *, points: bool = False) -> tuple[np.ndarray, np.ndarray]:
    reference = check_matrix("reference", reference, FRAMES, points=points, finite=False)
    reconstruction = check_matrix("reconstruction", reconstruction, FRAMES, points=points, finite=False)
    if reconstruction.shape != reference.shape:
        raise WorkbenchError(
            f"reconstruction has shape {reconstruction.shape}, but the reference has {reference.shape}; they must match"
        )
    return reference, reconstruction


def _check_finite(name: str, per_frame: np.ndarray) -> None:
    """Raise naming the first frame whose squared norm (or error) is not finite: its input holds NaN or Inf."""
    bad = np.flatnonzero(~np.isfinite(per_frame))
    if bad.size:
        raise WorkbenchError(
            f"{name} holds NaN or Inf values in {bad.size} frame(s), the first frame {int(bad[0])}; "
            "alpha needs finite frames"
        )


def alpha_per_frame(reference: np.ndarray, reconstruction: np.ndarray, *, tol: Tolerances = TOL) -> np.ndarray:
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


def point_norms(flat: np.ndarray) -> np.ndarray:
    """Length of each 3-D point of flattened point sets ``[x0, y0, z0, x1, ...]``.

    The squares added as ``(x^2 + y^2) + z^2``, in the order ``np.linalg.norm(..., axis=-1)`` adds them, so the
    numbers are the same; written out over the three coordinates it runs several times faster on frames than the
    generic reduction over an axis of length 3.

    Parameters
    ----------
    flat : ndarray of shape (..., 3 * n_points)

    Returns
    -------
    ndarray of shape (..., n_points)
    """
    flat = np.asarray(flat)
    x, y, z = (flat[..., axis::3] for axis in range(3))
    return np.sqrt(x * x + y * y + z * z)


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
    return float(rms_error(np.sum((reference - reconstruction) ** 2), reference.shape[0] * n_points))


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
    error_sq, displacement_sq, position_sq : ndarray of shape (n_frames,), or None
        Per frame ``|v* - v|^2``, ``|d*|^2`` and ``|v0 + d*|^2`` over the compared points (what the pooled alpha
        sums; paired comparisons of pooled alphas resample them).
    """

    absolute_per_frame: np.ndarray
    displacement_per_frame: np.ndarray
    absolute_mean: float
    absolute_pooled: float
    displacement_mean: float
    displacement_pooled: float
    rms_mm: float
    n_undefined_displacement_frames: int
    error_sq: np.ndarray | None = None
    displacement_sq: np.ndarray | None = None
    position_sq: np.ndarray | None = None

    def table_values(self) -> dict:
        """The five numbers of an alpha-table row under the table's column names: ``alpha_abs_mean``,
        ``alpha_abs_pooled``, ``alpha_disp_mean``, ``alpha_disp_pooled`` and ``rms_mm``."""
        return {
            "alpha_abs_mean": self.absolute_mean,
            "alpha_abs_pooled": self.absolute_pooled,
            "alpha_disp_mean": self.displacement_mean,
            "alpha_disp_pooled": self.displacement_pooled,
            "rms_mm": self.rms_mm,
        }


def summarise_alpha(
    neutral: np.ndarray,
    captured: np.ndarray,
    reconstructed,
    *,
    tol: Tolerances = TOL,
    chunk_frames: int = 4096,
    squares: tuple[np.ndarray, np.ndarray] | None = None,
    visible: np.ndarray | None = None,
) -> AlphaSummary:
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
    captured = check_matrix("captured", captured, FRAMES, points=True, finite=False)
    n_frames, n_dims = captured.shape
    neutral = np.asarray(neutral, dtype=np.float64)
    if neutral.shape != (n_dims,):
        raise WorkbenchError(f"neutral must have shape ({n_dims},) to match the captured frames, got {neutral.shape}")
    if not np.all(np.isfinite(neutral)):
        raise WorkbenchError("neutral holds NaN or Inf values; alpha needs finite neutral positions")
    if not callable(reconstructed):
        reconstructed = check_matrix("reconstructed", reconstructed, FRAMES, n_columns=n_dims, finite=False)
        if reconstructed.shape[0] != n_frames:
            raise WorkbenchError(f"reconstructed has {reconstructed.shape[0]} frames, but captured has {n_frames}")
    if isinstance(chunk_frames, bool) or not isinstance(chunk_frames, (int, np.integer)) or chunk_frames < 1:
        raise WorkbenchError(f"chunk_frames must be a positive integer, got {chunk_frames!r}")
    if visible is not None and np.shape(visible) != (n_frames, n_dims // 3):
        raise WorkbenchError(
            f"visible must have shape ({n_frames}, {n_dims // 3}) (frames x points), got {np.shape(visible)}"
        )
    if squares is not None and any(np.shape(square) != (n_frames,) for square in squares):
        raise WorkbenchError(
            f"squares must be two arrays of shape ({n_frames},), got {[np.shape(square) for square in squares]}"
        )
    # Eq. 6 in both normalisations from three row-wise squared norms, one pass over the frames each: the error
    # v* - v equals d* - d, and |v0 + d*|^2 = |v0|^2 + 2 v0.d* + |d*|^2 (same values as alpha_per_frame and
    # alpha_pooled, without forming the absolute positions).
    error_sq = np.empty(captured.shape[0])
    for start in range(0, captured.shape[0], chunk_frames):
        rows = slice(start, start + chunk_frames)
        estimate = reconstructed(rows) if callable(reconstructed) else reconstructed[rows]
        if np.shape(estimate) != captured[rows].shape:
            raise WorkbenchError(
                f"reconstructed returned shape {np.shape(estimate)} for frames "
                f"{rows.start}-{min(rows.stop, n_frames) - 1}; expected {captured[rows].shape}"
            )
        difference = captured[rows] - estimate
        if visible is not None:
            difference = np.where(np.repeat(visible[rows], 3, axis=1), difference, 0.0)
        error_sq[rows] = np.einsum("ij,ij->i", difference, difference)
    with np.errstate(invalid="ignore", over="ignore"):  # NaN or Inf in the frames is named just below
        displacement_sq, position_sq = (
            squares if squares is not None else reference_squares(neutral, captured, visible=visible)
        )
    n_compared = visible.sum() if visible is not None else captured.shape[0] * (captured.shape[1] // 3)
    return summarise_squares(error_sq, displacement_sq, position_sq, n_compared, tol=tol)


def summarise_squares(
    error_sq: np.ndarray,
    displacement_sq: np.ndarray,
    position_sq: np.ndarray,
    n_compared_points: int,
    *,
    tol: Tolerances = TOL,
) -> AlphaSummary:
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
        rms_mm=float(rms_error(error_sq.sum(), n_compared_points)),
        n_undefined_displacement_frames=n_undefined,
        error_sq=error_sq,
        displacement_sq=displacement_sq,
        position_sq=position_sq,
    )


def reference_squares(
    neutral: np.ndarray, captured: np.ndarray, *, visible: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
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
    defined = reference_sq > tol.zero_displacement**2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(defined, 100.0 * np.sqrt(error_sq / reference_sq), np.nan)


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
        return {
            "condition_number": self.condition_number,
            "rank": self.rank,
            "n_shapes": self.n_shapes,
            "zero_shapes": list(self.zero_shapes),
            "near_duplicates": [[i, j, round(c, 6)] for i, j, c in self.near_duplicates],
        }


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
    return Conditioning(
        condition_number=condition, rank=rank, n_shapes=shapes.shape[0], zero_shapes=zero, near_duplicates=pairs
    )


# ---------------------------------------------------------------------------------------------------------------
# Error as a distribution over frames, and the animator's side: what the weights look like
# ---------------------------------------------------------------------------------------------------------------

ERROR_QUANTILES = np.linspace(0.0, 1.0, 101)
"""Probabilities at which the per-frame error distribution is kept (its cumulative curve)."""


@dataclass(frozen=True)
class ErrorDistribution:
    """The distribution over frames of one reconstruction's per-frame error.

    Attributes
    ----------
    median, p95, max : float
        Of the per-frame values (frames without a value left out).
    quantiles : ndarray of shape (101,)
        The values at probabilities 0, 0.01, ..., 1 (:data:`ERROR_QUANTILES`): the cumulative error curve.
    """

    median: float
    p95: float
    max: float
    quantiles: np.ndarray


def error_distribution(per_frame: np.ndarray) -> ErrorDistribution:
    """Median, 95th percentile, maximum and the quantile curve of per-frame errors.

    Parameters
    ----------
    per_frame : ndarray of shape (n_frames,)
        NaN for frames without a value.

    Returns
    -------
    ErrorDistribution
        All NaN when no frame has a value.
    """
    values = np.asarray(per_frame, dtype=float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return ErrorDistribution(math.nan, math.nan, math.nan, np.full(ERROR_QUANTILES.size, math.nan))
    quantiles = np.quantile(values, ERROR_QUANTILES)
    return ErrorDistribution(
        median=float(np.median(values)),
        p95=float(np.quantile(values, 0.95)),
        max=float(values.max()),
        quantiles=quantiles,
    )


def rms_error(error_sq, n_points) -> np.ndarray:
    """RMS 3-D point error, ``sqrt(|v* - v|^2 / n_points)``, in data units (millimetres): per frame, or pooled
    over frames when given the sums. The one home of the RMS error (:func:`rms_point_error`,
    :attr:`AlphaSummary.rms_mm`, the per-frame errors of a run and of the report's figures).

    Parameters
    ----------
    error_sq : float or ndarray of shape (n_frames,)
        Squared error summed over the compared points (of each frame, or of all frames).
    n_points : int or ndarray of shape (n_frames,)
        Points compared (in each frame: fewer under capture gaps); none gives NaN.

    Returns
    -------
    ndarray of the shape of ``error_sq``
    """
    n_points = np.broadcast_to(np.asarray(n_points, dtype=float), np.shape(error_sq))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(n_points > 0, np.sqrt(np.asarray(error_sq, dtype=float) / n_points), np.nan)


@dataclass(frozen=True)
class WeightStatistics:
    """What an animator would face in one basis's weights over a take.

    Attributes
    ----------
    max_abs : float
        Largest ``|w|`` over frames and shapes.
    outside_unit_share : float
        Share of frames with at least one weight below 0 or above 1 (by more than ``TOL.weight_bound``).
    negative_share : float
        Share of frames with at least one weight below 0 (same tolerance).
    sparsity : float
        Hoyer's sparsity, ``(sqrt(n) - |w|_1 / |w|_2) / (sqrt(n) - 1)``, mean over frames: 1 when one shape
        alone moves the face, 0 when every shape has the same ``|w|``; frames with all weights zero (or zero but
        for round-off: :data:`STILL_WEIGHTS`) left out.
    roughness : float
        Mean over shapes and frames of the squared second time derivative of the weights, in 1/s^4: second
        differences over the frames' times, within each take (frames at a take's ends have none).
    sum_median : float
        Median over frames of ``sum_i w_i``.
    needs_negative_share : float
        Share of frames whose non-negative solution's error exceeds this (least-squares) solution's by more than
        ``TOL.tie_rel`` (:func:`needs_negative_share`): the frames that need a negative weight, whichever weights
        the least-squares solver returned. NaN where not computed (no nnls row beside it, or not least squares).
    """

    max_abs: float
    outside_unit_share: float
    negative_share: float
    sparsity: float
    roughness: float
    sum_median: float
    needs_negative_share: float = math.nan

    def as_dict(self) -> dict:
        return {
            "max_abs": self.max_abs,
            "outside_unit_share": self.outside_unit_share,
            "negative_share": self.negative_share,
            "sparsity": self.sparsity,
            "roughness": self.roughness,
            "sum_median": self.sum_median,
            "needs_negative_share": self.needs_negative_share,
        }


def needs_negative_share(
    error_sq_lstsq: np.ndarray,
    error_sq_nnls: np.ndarray,
    reference_sq: np.ndarray | None = None,
    *,
    tol: Tolerances = TOL,
) -> float:
    """Share of frames that need a negative weight: the non-negative solution's error exceeds the least-squares
    error by more than ``tol.tie_rel`` of the larger error or of the frame's reference norm (whichever is larger,
    so that two errors of rounding size on a frame the basis reproduces are a tie).

    A negative weight in the least-squares solution is not enough: for a rank-deficient basis the least-squares
    weights are the minimum-norm choice among many with the same error, and one of those may be non-negative.

    Parameters
    ----------
    error_sq_lstsq, error_sq_nnls : ndarray of shape (n_frames,)
        Per-frame squared reconstruction errors of one basis under least squares and non-negative weights.
    reference_sq : ndarray of shape (n_frames,), optional
        Per-frame squared norm of what is reconstructed (the captured displacement).
    tol : Tolerances

    Returns
    -------
    float
        In [0, 1]; NaN without frames.
    """
    lstsq, nnls = (
        np.sqrt(np.maximum(np.asarray(values, dtype=float), 0.0)) for values in (error_sq_lstsq, error_sq_nnls)
    )
    if lstsq.shape != nnls.shape or lstsq.ndim != 1:
        raise WorkbenchError(
            f"per-frame errors of the two solvers must be 1-D of one length, got shapes {lstsq.shape} and {nnls.shape}"
        )
    if lstsq.size == 0:
        return math.nan
    scale = np.maximum(lstsq, nnls)
    if reference_sq is not None:
        scale = np.maximum(scale, np.sqrt(np.maximum(np.asarray(reference_sq, dtype=float), 0.0)))
    return float(np.mean(nnls - lstsq > tol.tie_rel * scale))


STILL_WEIGHTS = math.sqrt(np.finfo(float).eps)
"""A frame whose weights' norm is at most this share of the largest frame's has no motion but round-off (a take's
neutral frame: AnimFace's displacement there is 6e-14 mm, its largest 94 mm). Its weights are round-off too, and
their sparsity, 0/0 in exact arithmetic, is whatever the round-off makes it (that one frame moved the AnimFace
reference report's mean sparsity by 3e-4 to 6e-3, relative, under another BLAS kernel): it is left out, as that of
weights all zero. A frame moving 1.5e-8 of the largest frame (nanometres) is one no capture resolves."""


def hoyer_sparsity(weights: np.ndarray) -> np.ndarray:
    """Hoyer's sparsity of each frame's weights (Hoyer 2004, *Non-negative matrix factorization with sparseness
    constraints*), ``(sqrt(n) - |w|_1 / |w|_2) / (sqrt(n) - 1)``; none for a frame without motion
    (:data:`STILL_WEIGHTS`).

    Parameters
    ----------
    weights : ndarray of shape (n_frames, n_shapes)
        ``n_shapes >= 2``.

    Returns
    -------
    ndarray of shape (n_frames,)
        In [0, 1]; NaN for a frame whose weights are all zero, or zero but for round-off.
    """
    weights = np.asarray(weights, dtype=float)
    root = math.sqrt(weights.shape[1])
    l1, l2 = np.abs(weights).sum(axis=1), np.linalg.norm(weights, axis=1)
    largest = np.max(l2, where=np.isfinite(l2), initial=0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(l2 > STILL_WEIGHTS * largest, (root - l1 / l2) / (root - 1.0), np.nan)  # 0 when all are 0


def second_derivative(values: np.ndarray, seconds: np.ndarray, takes=None) -> np.ndarray:
    """Second time derivative of per-frame values by finite differences on (possibly uneven) frame times.

    For frames ``i - 1, i, i + 1`` of one take with steps ``h1 = t_i - t_{i-1}``, ``h2 = t_{i+1} - t_i``:
    ``2 (h1 x_{i+1} - (h1 + h2) x_i + h2 x_{i-1}) / (h1 h2 (h1 + h2))`` (``(x_{i+1} - 2 x_i + x_{i-1}) / h^2`` for
    even steps).

    Parameters
    ----------
    values : ndarray of shape (n_frames, k)
    seconds : ndarray of shape (n_frames,)
        Time of each frame, increasing within each take.
    takes : ndarray of shape (n_frames,), optional
        Take of each frame; no difference spans two takes.

    Returns
    -------
    ndarray of shape (n_inner, k)
        At every frame with a neighbour on each side in its take.
    """
    values, seconds = np.asarray(values, dtype=float), np.asarray(seconds, dtype=float)
    inner = np.ones(max(len(seconds) - 2, 0), dtype=bool)
    if takes is not None:
        takes = np.asarray(takes)
        inner &= (takes[:-2] == takes[1:-1]) & (takes[1:-1] == takes[2:])
    h1, h2 = (seconds[1:-1] - seconds[:-2])[inner], (seconds[2:] - seconds[1:-1])[inner]
    if np.any(h1 <= 0) or np.any(h2 <= 0):
        raise WorkbenchError("frame times must increase within each take to take time derivatives of the weights")
    before, here, after = values[:-2][inner], values[1:-1][inner], values[2:][inner]
    scale = (2.0 / (h1 * h2 * (h1 + h2)))[:, None]
    return scale * (h1[:, None] * after - (h1 + h2)[:, None] * here + h2[:, None] * before)


def weight_statistics(
    weights: np.ndarray, seconds: np.ndarray, takes=None, *, tol: Tolerances = TOL
) -> WeightStatistics:
    """Range, bounds, sparsity and temporal roughness of a basis's weights over the evaluated frames.

    Parameters
    ----------
    weights : ndarray of shape (n_frames, n_shapes)
    seconds : ndarray of shape (n_frames,)
        Time of each frame within its take.
    takes : ndarray of shape (n_frames,), optional
        Take of each frame.
    tol : Tolerances
        ``weight_bound``: how far past 0 or 1 a weight must be to count as outside.

    Returns
    -------
    WeightStatistics
    """
    weights = check_matrix("weights", weights, FRAMES, finite=False)
    if np.shape(seconds) != (len(weights),):
        raise WorkbenchError(
            f"seconds must give the time of each of the {len(weights)} frames, got shape {np.shape(seconds)}"
        )
    below, above = weights < -tol.weight_bound, weights > 1.0 + tol.weight_bound
    sparsity = hoyer_sparsity(weights) if weights.shape[1] > 1 else np.full(len(weights), np.nan)
    curvature = second_derivative(weights, seconds, takes)
    return WeightStatistics(
        max_abs=float(np.abs(weights).max()),
        outside_unit_share=float((below | above).any(axis=1).mean()),
        negative_share=float(below.any(axis=1).mean()),
        sparsity=float(np.nanmean(sparsity)) if np.isfinite(sparsity).any() else math.nan,
        roughness=float(np.mean(curvature**2)) if curvature.size else math.nan,
        sum_median=float(np.median(weights.sum(axis=1))),
    )
