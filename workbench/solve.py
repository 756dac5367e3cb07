"""Weights of every frame in a basis: Kim & Ko's eq. 5, for all frames at once.

Each captured frame's displacement ``d*`` (length ``n_dims = 3 * n_points``) is reconstructed from a basis of
``n_shapes`` shapes ``e_i`` by weights ``w`` minimising (eq. 5)

    | d* - sum_i w_i e_i |^2,

which the paper solves by quadratic programming.  Three kinds are offered:

``"lstsq"``
    Unconstrained least squares; one SVD of the basis serves every frame (minimum-norm weights when the
    basis is rank-deficient, with NumPy's default cut-off ``eps * max(n_dims, n_shapes)``).
``"nnls"``
    ``w >= 0``.
``"box"``
    ``lower <= w <= upper`` with scalar or per-shape bounds, either side possibly infinite.

The constrained kinds are reduced once to the ``n_shapes x n_shapes`` problem

    min_w 0.5 w^T G w - c^T w   subject to the bounds,   G = B B^T,  c = B d*,

and solved for all frames together by the primal-dual active-set method of Hintermueller, Ito & Kunisch
(SIAM J. Optim. 13(3), 2002): every iteration solves one batch of pinned linear systems, one per frame that
has not settled.  A frame whose active sets stop changing holds an exact KKT point.  Frames that cycle or
exceed ``tol.active_set_max_iter`` iterations, and frames whose KKT check fails, are re-solved one by one with
SciPy (``scipy.optimize.nnls`` or ``scipy.optimize.lsq_linear(method="bvls")``) on the reduced problem.

Rank-deficient bases (duplicate or nearly collinear shapes) make ``G`` singular.  When its smallest
eigenvalue is at or below ``tol.gram_ridge`` times its largest, the constrained solvers add
``tol.gram_ridge * largest eigenvalue`` to the diagonal of ``G`` (Tikhonov).  The weights are then the
minimiser of the slightly regularised problem -- no longer unique in the original problem -- and the objective
exceeds the minimum by at most ``0.5 * tol.gram_ridge * lambda_max * |w|^2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear, nnls

from workbench.errors import WorkbenchError
from workbench.tolerances import TOL, Tolerances

KINDS = ("lstsq", "nnls", "box")

# Projected-gradient steps that refine the first active-set guess of the batched solver.
_WARM_STEPS = 3

# Termination tolerance of SciPy's BVLS on the fallback problem (scaled to O(1), see ``_per_frame``).
_BVLS_TOL = 1e-14

# Fixed random multipliers that hash a frame's active sets to one integer (cycle detection).
_HASH = np.random.default_rng(20020101).integers(1, 2**63, size=4096, dtype=np.uint64) | np.uint64(1)


@dataclass(frozen=True)
class WeightSolution:
    """Weights of every frame in one basis (eq. 5) and how they were obtained.

    Attributes
    ----------
    weights : ndarray of shape (n_frames, n_shapes)
        Row ``f`` holds the weights ``w`` of frame ``f``; ``weights @ basis`` reconstructs the targets.
    kind : str
        ``"lstsq"``, ``"nnls"`` or ``"box"``.
    lower, upper : float, ndarray of shape (n_shapes,) or None
        Bounds that were applied (``0.0`` and ``None`` for ``"nnls"``; ``None`` for ``"lstsq"`` and for an
        unbounded side of ``"box"``).
    n_iterations : int
        Active-set iterations of the batched solver (0 for ``"lstsq"``).
    n_fallback_frames : int
        Frames that needed SciPy's per-frame solver (cycling, iteration cap or a failed KKT check).
    max_kkt_violation : float
        Largest scaled KKT violation over frames, see :func:`kkt_violation` (0 for ``"lstsq"``).
    """

    weights: np.ndarray
    kind: str
    lower: float | np.ndarray | None
    upper: float | np.ndarray | None
    n_iterations: int
    n_fallback_frames: int
    max_kkt_violation: float


@dataclass(frozen=True)
class _Reduction:
    """One SVD ``basis.T = U diag(s) Vt`` and what every frame needs from it.

    ``design`` (``diag(s) Vt``, shape (k, n_shapes)) and ``projected`` (``targets @ U``, shape (n_frames, k))
    give the reduced least-squares problem ``|design w - projected_f|^2``, equal to eq. 5 up to a constant.
    """

    n_dims: int
    singular: np.ndarray
    vt: np.ndarray
    projected: np.ndarray


# ----------------------------------------------------------------------------------------------------------
# Public API
# ----------------------------------------------------------------------------------------------------------


def solve_weights(
    basis,
    targets,
    *,
    kind: str = "lstsq",
    lower=None,
    upper=None,
    tol: Tolerances = TOL,
) -> WeightSolution:
    """Weights of every frame in ``basis`` minimising eq. 5, ``|d* - sum_i w_i e_i|^2``.

    Parameters
    ----------
    basis : array_like of shape (n_shapes, n_dims)
        One shape ``e_i`` per row (displacements from neutral, ``n_dims = 3 * n_points``).
    targets : array_like of shape (n_frames, n_dims)
        One captured displacement ``d*`` per row.
    kind : {"lstsq", "nnls", "box"}
        Unconstrained, ``w >= 0``, or ``lower <= w <= upper``.
    lower, upper : float, array_like of shape (n_shapes,) or None
        Bounds of ``"box"`` (at least one given; ``None`` or an infinite value leaves that side open).
        ``"nnls"`` accepts only ``lower`` in ``{None, 0}`` and ``upper=None``; ``"lstsq"`` accepts neither.
    tol : Tolerances
        ``kkt``, ``active_set_max_iter`` and ``gram_ridge`` are used.

    Returns
    -------
    WeightSolution
        ``weights`` of shape (n_frames, n_shapes) and solver diagnostics.

    Raises
    ------
    WorkbenchError
        Bad shapes, empty or non-finite arrays, an unknown ``kind`` or inconsistent bounds.
    """
    basis = _as_matrix("basis", basis)
    targets = _as_matrix("targets", targets)
    _check_columns(basis, targets)
    kind = _check_kind(kind)
    lo, hi, lower_out, upper_out = _bounds(kind, lower, upper, basis.shape[0])
    reduction = _reduce(basis, targets)
    start = _unconstrained(reduction)
    if kind == "lstsq":
        return WeightSolution(start, kind, None, None, 0, 0, 0.0)
    gram = basis @ basis.T
    rhs = targets @ basis.T
    weights, n_iter, n_fallback, violation = _solve_bounded(gram, rhs, lo, hi, start, reduction, kind, tol)
    return WeightSolution(weights, kind, lower_out, upper_out, n_iter, n_fallback, violation)


def reconstruct(basis, weights) -> np.ndarray:
    """Reconstructed displacements ``weights @ basis`` (the sum in eq. 5).

    Parameters
    ----------
    basis : array_like of shape (n_shapes, n_dims)
    weights : array_like of shape (n_frames, n_shapes)

    Returns
    -------
    ndarray of shape (n_frames, n_dims)
    """
    basis = _as_matrix("basis", basis)
    weights = _as_matrix("weights", weights)
    if weights.shape[1] != basis.shape[0]:
        raise WorkbenchError(
            f"weights has {weights.shape[1]} columns but basis has {basis.shape[0]} rows (n_shapes)"
        )
    return weights @ basis


def kkt_violation(gram, rhs, weights, lower, upper) -> np.ndarray:
    """Scaled KKT violation of ``min 0.5 w^T G w - c^T w`` s.t. ``lower <= w <= upper``, per frame.

    With the gradient ``g = G w - c``, each variable is scored by how far it is from the nearest of its three
    admissible states -- free (``|g_i|``), at its lower bound (``max(-g_i, 0)`` plus its distance above the
    bound) or at its upper bound (``max(g_i, 0)`` plus its distance below it) -- plus any infeasibility.
    Gradient terms are divided by ``max|c_f| + max|G| * max|w_f|`` (the size of the terms whose difference
    is ``g``), weight terms by the larger of ``max|w_f|`` and the largest finite bound (1 if both are 0).
    The measure is zero exactly at a KKT point and comparable with ``Tolerances.kkt``.

    Parameters
    ----------
    gram : array_like of shape (n_shapes, n_shapes)
        Symmetric ``G = B B^T``.
    rhs : array_like of shape (n_frames, n_shapes)
        ``c = targets @ B.T``, one row per frame.
    weights : array_like of shape (n_frames, n_shapes)
    lower, upper : float, array_like of shape (n_shapes,) or None
        ``None`` means unbounded on that side.

    Returns
    -------
    ndarray of shape (n_frames,)
        Non-negative; ``inf`` for frames with non-finite weights.
    """
    gram = np.asarray(gram, dtype=float)
    rhs = np.atleast_2d(np.asarray(rhs, dtype=float))
    weights = np.atleast_2d(np.asarray(weights, dtype=float))
    n = gram.shape[0]
    if gram.shape != (n, n) or rhs.shape[1] != n or weights.shape != rhs.shape:
        raise WorkbenchError(
            f"kkt_violation needs gram (n, n), rhs and weights (n_frames, n); got gram {gram.shape}, "
            f"rhs {rhs.shape}, weights {weights.shape}"
        )
    lo = _bound_vector("lower", lower, n, -np.inf)[0]
    hi = _bound_vector("upper", upper, n, np.inf)[0]
    grad = weights @ gram.T - rhs
    w_size = np.abs(weights).max(axis=1)
    g_scale = _positive(np.abs(rhs).max(axis=1) + np.abs(gram).max() * w_size)[:, None]
    w_scale = _positive(np.maximum(w_size, _largest_finite(lo, hi)))[:, None]
    with np.errstate(invalid="ignore"):
        as_free = np.abs(grad) / g_scale
        as_lower = np.maximum(-grad, 0.0) / g_scale + np.maximum(weights - lo, 0.0) / w_scale
        as_upper = np.maximum(grad, 0.0) / g_scale + np.maximum(hi - weights, 0.0) / w_scale
        infeasible = np.maximum(np.maximum(lo - weights, weights - hi), 0.0) / w_scale
        per_shape = np.minimum(np.minimum(as_free, as_lower), as_upper) + infeasible
    per_frame = per_shape.max(axis=1)
    per_frame[~np.isfinite(weights).all(axis=1) | np.isnan(per_frame)] = np.inf
    return per_frame


# ----------------------------------------------------------------------------------------------------------
# Input checks
# ----------------------------------------------------------------------------------------------------------


def _as_matrix(name: str, value) -> np.ndarray:
    """``value`` as a finite, non-empty 2D float array, or a WorkbenchError naming ``name``."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise WorkbenchError(f"{name} must be a numeric array ({exc})") from None
    if array.ndim != 2:
        raise WorkbenchError(f"{name} must be 2-dimensional, got shape {array.shape}")
    if array.size == 0:
        raise WorkbenchError(f"{name} must not be empty, got shape {array.shape}")
    if not np.isfinite(array).all():
        raise WorkbenchError(f"{name} must be finite, found {np.count_nonzero(~np.isfinite(array))} NaN/Inf")
    return array


def _check_columns(basis: np.ndarray, targets: np.ndarray) -> None:
    if targets.shape[1] != basis.shape[1]:
        raise WorkbenchError(
            f"targets has {targets.shape[1]} columns but basis has {basis.shape[1]} (n_dims must match)"
        )


def _check_kind(kind) -> str:
    if kind not in KINDS:
        raise WorkbenchError(f"kind must be one of {', '.join(KINDS)}; got {kind!r}")
    return kind


def _bounds(kind: str, lower, upper, n: int):
    """Per-shape bound vectors ``lo, hi`` (shape (n,)) and the bounds to record in the solution."""
    if kind == "lstsq":
        if lower is not None or upper is not None:
            raise WorkbenchError("lower and upper must be None for kind 'lstsq' (use kind 'nnls' or 'box')")
        return None, None, None, None
    if kind == "nnls":
        if upper is not None or (lower is not None and not _is_zero_scalar(lower)):
            raise WorkbenchError("kind 'nnls' fixes lower=0 and upper=None; use kind 'box' for other bounds")
        return np.zeros(n), np.full(n, np.inf), 0.0, None
    if lower is None and upper is None:
        raise WorkbenchError("kind 'box' needs lower or upper (or both); got neither")
    lo, lower_out = _bound_vector("lower", lower, n, -np.inf)
    hi, upper_out = _bound_vector("upper", upper, n, np.inf)
    _check_order(lo, hi, np.ndim(lower_out) == 0 and np.ndim(upper_out) == 0)
    return lo, hi, lower_out, upper_out


def _bound_vector(name: str, value, n: int, open_side: float):
    """One bound as a vector of shape (n,) plus the value to record (float, array copy or None)."""
    if value is None:
        return np.full(n, open_side), None
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise WorkbenchError(f"{name} must be a number or an array of shape ({n},) ({exc})") from None
    if array.ndim > 1 or (array.ndim == 1 and array.shape != (n,)):
        raise WorkbenchError(f"{name} must be a scalar or have shape ({n},) (n_shapes), got {array.shape}")
    if np.isnan(array).any():
        raise WorkbenchError(f"{name} must not contain NaN")
    if np.any(array == -open_side):
        raise WorkbenchError(f"{name} must not be {-open_side} (no weight could satisfy it)")
    record = float(array) if array.ndim == 0 else array.copy()
    return np.broadcast_to(array, (n,)).astype(float), record


def _check_order(lo: np.ndarray, hi: np.ndarray, scalar: bool) -> None:
    bad = np.flatnonzero(lo > hi)
    if bad.size == 0:
        return
    i = int(bad[0])
    if scalar:
        raise WorkbenchError(f"lower ({lo[i]:g}) must not exceed upper ({hi[i]:g})")
    raise WorkbenchError(f"lower[{i}] ({lo[i]:g}) must not exceed upper[{i}] ({hi[i]:g})")


def _is_zero_scalar(value) -> bool:
    return np.ndim(value) == 0 and np.isreal(value) and float(value) == 0.0


# ----------------------------------------------------------------------------------------------------------
# Reduction and the unconstrained solution
# ----------------------------------------------------------------------------------------------------------


def _reduce(basis: np.ndarray, targets: np.ndarray) -> _Reduction:
    """Thin SVD of ``basis.T`` (n_dims, n_shapes) and the targets projected on its left singular vectors."""
    u, singular, vt = np.linalg.svd(basis.T, full_matrices=False)
    return _Reduction(n_dims=basis.shape[1], singular=singular, vt=vt, projected=targets @ u)


def _unconstrained(reduction: _Reduction) -> np.ndarray:
    """Minimum-norm least-squares weights of every frame, shape (n_frames, n_shapes).

    Singular values at or below ``eps * max(n_dims, n_shapes) * s_max`` are treated as zero, as in
    ``numpy.linalg.lstsq``.
    """
    s = reduction.singular
    cutoff = np.finfo(float).eps * max(reduction.n_dims, reduction.vt.shape[1]) * s.max(initial=0.0)
    inverse = np.divide(1.0, s, out=np.zeros_like(s), where=s > cutoff)
    return (reduction.projected * inverse) @ reduction.vt


def _ridge(singular: np.ndarray, n_shapes: int, relative: float) -> float:
    """Tikhonov term for the gram ``G = V diag(s^2) V^T``: 0 unless ``G`` is (nearly) singular."""
    eig_max = float(singular.max(initial=0.0)) ** 2
    eig_min = float(singular.min()) ** 2 if singular.size == n_shapes else 0.0
    if eig_max == 0.0:
        return 1.0
    return relative * eig_max if eig_min <= relative * eig_max else 0.0


# ----------------------------------------------------------------------------------------------------------
# Bounded problem: batched primal-dual active set, SciPy per frame where needed
# ----------------------------------------------------------------------------------------------------------


def _solve_bounded(gram, rhs, lo, hi, start, reduction, kind, tol):
    """Bounded weights of every frame; returns (weights, n_iterations, n_fallback_frames, max violation)."""
    ridge = _ridge(reduction.singular, gram.shape[0], tol.gram_ridge)
    work = gram + ridge * np.eye(gram.shape[0])
    weights, settled, n_iter = _active_set(work, rhs, lo, hi, start, tol.active_set_max_iter)
    violation = kkt_violation(gram, rhs, weights, lo, hi)
    redo = np.flatnonzero(~settled | (violation > tol.kkt))
    if redo.size:
        candidate = _per_frame(reduction, lo, hi, redo, kind, ridge)
        candidate_violation = kkt_violation(gram, rhs[redo], candidate, lo, hi)
        better = ~settled[redo] | (candidate_violation < violation[redo])
        weights[redo[better]] = candidate[better]
        violation[redo[better]] = candidate_violation[better]
    return weights, n_iter, int(redo.size), float(violation.max())


def _active_set(gram, rhs, lo, hi, start, max_iter: int):
    """Primal-dual active-set iterations (Hintermueller-Ito-Kunisch) for all frames at once.

    Parameters
    ----------
    gram : ndarray of shape (n, n)
        Symmetric positive definite gram (regularised if needed).
    rhs : ndarray of shape (n_frames, n)
    lo, hi : ndarray of shape (n,)
    start : ndarray of shape (n_frames, n)
        Unconstrained weights.  Frames where they are feasible are settled at once; the others start from
        them clipped, improved by :func:`_warm_start`, whose multipliers give the first active sets.
    max_iter : int

    Returns
    -------
    weights : ndarray of shape (n_frames, n)
    settled : ndarray of bool, shape (n_frames,)
        Frames whose active sets stopped changing (their weights are a KKT point of ``gram``).
    n_iterations : int
    """
    weights = np.clip(start, lo, hi)
    pending = np.flatnonzero(((start < lo) | (start > hi)).any(axis=1))
    settled = np.ones(len(rhs), dtype=bool)
    settled[pending] = False
    scale = np.diag(gram).copy()
    c = rhs[pending]
    w = _warm_start(gram, c, weights[pending], lo, hi)
    at_lo, at_hi = _next_active(gram, c, w, lo, hi, scale)
    seen = _state_hash(at_lo, at_hi)[:, None]
    n_iter = 0
    while pending.size and n_iter < max_iter:
        n_iter += 1
        w = _pinned_solve(gram, c, lo, hi, at_lo, at_hi)
        new_lo, new_hi = _next_active(gram, c, w, lo, hi, scale, at_lo | at_hi)
        weights[pending] = w
        done = (new_lo == at_lo).all(axis=1) & (new_hi == at_hi).all(axis=1) & np.isfinite(w).all(axis=1)
        settled[pending[done]] = True
        code = _state_hash(new_lo, new_hi)
        cycling = (seen == code[:, None]).any(axis=1) | ~np.isfinite(w).all(axis=1)
        keep = ~done & ~cycling
        pending, at_lo, at_hi, c = pending[keep], new_lo[keep], new_hi[keep], c[keep]
        seen = np.column_stack([seen[keep], code[keep]])
    return weights, settled, n_iter


def _pinned_solve(gram, c, lo, hi, at_lo, at_hi):
    """Weights with active variables pinned at their bound and ``G_FF w_F = c_F - G_FA w_A`` on the rest.

    Frames are grouped by their number of free variables ``m`` (a loop over at most ``n + 1`` sizes, not
    over frames); each group's ``(m, m)`` blocks ``G_FF`` are gathered and solved in one batched call.

    Parameters
    ----------
    gram : ndarray of shape (n, n)
    c : ndarray of shape (n_frames, n)
    lo, hi : ndarray of shape (n,)
    at_lo, at_hi : ndarray of bool, shape (n_frames, n)
        Disjoint lower- and upper-active sets.

    Returns
    -------
    ndarray of shape (n_frames, n)
    """
    n = gram.shape[0]
    free = ~(at_lo | at_hi)
    w = np.where(at_lo, lo, 0.0) + np.where(at_hi, hi, 0.0)
    b = c - w @ gram.T
    n_free = free.sum(axis=1)
    for m in np.unique(n_free[n_free > 0]):
        rows = np.flatnonzero(n_free == m)
        cols = np.nonzero(free[rows])[1].reshape(rows.size, m)
        flat = rows[:, None] * n + cols
        system = gram.ravel().take(cols[:, :, None] * n + cols[:, None, :])
        np.put(w, flat, _batched_solve(system, np.take(b, flat)))
    return w


def _batched_solve(system: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``solve(system[f], b[f])`` for every f; pseudo-inverse for the batch if any matrix is singular."""
    try:
        return np.linalg.solve(system, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return (np.linalg.pinv(system) @ b[..., None])[..., 0]


def _warm_start(gram, c, w, lo, hi, steps: int = _WARM_STEPS):
    """A few projected-gradient steps (step ``1 / lambda_max(G)``) from feasible ``w``, shape (n_frames, n).

    Each step lowers the objective; the point is only used to guess the first active sets, so PDAS needs
    fewer batched solves (most frames settle after one).  A settled frame's weights do not depend on it.
    """
    step = 1.0 / np.linalg.eigvalsh(gram)[-1]
    for _ in range(steps):
        w = np.clip(w - step * (w @ gram.T - c), lo, hi)
    return w


def _next_active(gram, c, w, lo, hi, scale, active=None):
    """Active sets from multipliers ``lam = G w - c`` with ``k = diag(G)``, both of shape (n_frames, n).

    Lower-active where ``lam_i + k_i (lo_i - w_i) > 0``, upper-active where ``lam_i + k_i (hi_i - w_i) < 0``.
    After a pinned solve ``lam`` is zero on the free variables (``active`` marks the pinned ones).
    """
    lam = w @ gram.T - c
    if active is not None:
        lam = np.where(active, lam, 0.0)
    with np.errstate(invalid="ignore"):
        new_lo = lam + scale * (lo - w) > 0
        new_hi = lam + scale * (hi - w) < 0
    return new_lo, new_hi


def _state_hash(at_lo: np.ndarray, at_hi: np.ndarray) -> np.ndarray:
    """One uint64 per frame identifying its pair of active sets (for cycle detection)."""
    n = at_lo.shape[1]
    keys = _HASH[: 2 * n] if 2 * n <= _HASH.size else _extended_hash(2 * n)
    state = np.concatenate([at_lo, at_hi], axis=1).astype(np.uint64)
    with np.errstate(over="ignore"):
        return (state * keys).sum(axis=1, dtype=np.uint64)


def _extended_hash(size: int) -> np.ndarray:
    return np.random.default_rng(size).integers(1, 2**63, size=size, dtype=np.uint64) | np.uint64(1)


def _per_frame(reduction: _Reduction, lo, hi, frames: np.ndarray, kind: str, ridge: float) -> np.ndarray:
    """SciPy's per-frame solver on the reduced problem ``|diag(s) Vt w - (U^T d*)_f|^2`` for ``frames``.

    With a ridge the design gets ``sqrt(ridge) * I`` rows (zero targets), matching the batched solver.
    Design and targets are divided by the largest singular value so SciPy's absolute tolerances apply to
    an O(1) problem.
    """
    design = reduction.singular[:, None] * reduction.vt
    projected = reduction.projected[frames]
    if ridge > 0.0:
        n = design.shape[1]
        design = np.vstack([design, np.sqrt(ridge) * np.eye(n)])
        projected = np.hstack([projected, np.zeros((len(frames), n))])
    unit = float(reduction.singular.max(initial=0.0)) or 1.0
    design, projected = design / unit, projected / unit
    # Shapes with lower == upper are fixed; SciPy's bounded solver needs lower < upper for the others.
    fixed = lo == hi
    weights = np.tile(np.where(fixed, lo, 0.0), (len(frames), 1))
    if fixed.all():
        return weights
    projected = projected - design[:, fixed] @ lo[fixed]
    design, lo, hi = design[:, ~fixed], lo[~fixed], hi[~fixed]
    solve_one = _nnls_one if kind == "nnls" else _bvls_one
    weights[:, ~fixed] = np.array([solve_one(design, b, lo, hi) for b in projected])
    return weights


def _nnls_one(design, b, lo, hi) -> np.ndarray:
    return nnls(design, b, maxiter=50 * design.shape[1])[0]


def _bvls_one(design, b, lo, hi) -> np.ndarray:
    n = design.shape[1]
    return lsq_linear(design, b, bounds=(lo, hi), method="bvls", tol=_BVLS_TOL, max_iter=50 * n + 100).x


def _positive(x: np.ndarray) -> np.ndarray:
    return np.where(x > 0, x, 1.0)


def _largest_finite(lo: np.ndarray, hi: np.ndarray) -> float:
    finite = np.concatenate([lo[np.isfinite(lo)], hi[np.isfinite(hi)]])
    return float(np.abs(finite).max(initial=0.0))
