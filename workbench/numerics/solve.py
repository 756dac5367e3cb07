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

The kinds, with the bounds each takes or fixes, are the table :data:`workbench.core.solvers.SOLVER_KINDS`; each
kind's solve is registered under its name in :data:`SOLVES`.

The constrained kinds are reduced once to the ``n_shapes x n_shapes`` problem

    min_w 0.5 w^T G w - c^T w   subject to the bounds,   G = B B^T,  c = B d*,

and solved for all frames together; only SciPy's last-resort solver below loops over frames.

1. Frames whose unconstrained (minimum-norm) weights satisfy the bounds are done: they minimise eq. 5.
2. The others get a warm start from a few over-relaxed ADMM iterations (:func:`admm`).  One ``n x n``
   inverse serves every frame and an iteration is one matrix product, so ten of them cost about as much as
   one or two batches of pinned solves over all frames, yet they leave most frames with nearly their final
   active sets (without them the next step needs two to three times as many solves on quasi-eigen bases).
3. A batched primal active-set method -- Lawson & Hanson's NNLS, with two-sided bounds as in Stark & Parker's
   BVLS -- makes every frame exact (:func:`primal_active_set`).  Each iteration solves one batch of pinned
   systems ``G_FF w_F = c_F - G_FA w_A`` (frames sharing a free set share one factorisation) and then, per
   frame, either steps towards that solution until the first free variable reaches its bound and pins it,
   or, when the solution is feasible, frees the pinned variable whose gradient pulls it off its bound the
   most.  The objective never increases, so the method cannot cycle.  A frame is finished when no pinned
   variable's scaled gradient (the measure of :func:`kkt_violation`) exceeds ``0.1 * tol.kkt``.

This replaces a primal-dual active-set method (Hintermueller, Ito & Kunisch), which changes many variables per
iteration but is not monotone: on rank-deficient, strongly correlated bases such as the quasi-eigen faces it
cycled or stalled on 14-30% of the frames, which then went to SciPy one by one (seconds instead of a
fraction of one).  From the ADMM start the primal method needs about one solve per frame on the full-rank
hand basis, as that method did, and about two on the quasi-eigen bases.

Frames still unfinished after ``tol.active_set_max_iter`` iterations, and frames whose KKT check fails, are
re-solved one by one with SciPy (``scipy.optimize.nnls`` or ``scipy.optimize.lsq_linear(method="bvls")``) on
the reduced problem; ``WeightSolution.n_fallback_frames`` counts them.

Capture gaps (occluded markers) are solved by masking: given which points of each frame were seen, each frame's
weights minimise eq. 5 over its visible points only (the targets may hold NaN elsewhere).  Each frame then has
its own gram ``G_f`` (a sum of per-point ``n x n`` blocks over its visible points, one matrix product for all
frames); the unconstrained weights come from a batched eigendecomposition of the ``G_f``, and the bounded ones
from the same ADMM start and primal active-set method, run with one gram per frame.

Rank-deficient bases (duplicate, linearly dependent or nearly collinear shapes; the quasi-eigen faces are 18
shapes in the 13- or 14-dimensional eigenface hyperplane) make ``G`` singular and the weights non-unique --
only the objective is.  When the smallest eigenvalue of ``G`` is at or below ``tol.gram_ridge`` times its
largest, the solvers work with ``G + r I``, ``r = tol.gram_ridge * lambda_max``, so that every pinned system
is solvable even when the free columns are dependent (the ADMM start may free more variables than the rank).
The primal method never adds such a column: one in the span of the free columns has a gradient of order
``r |w|`` at the free-subspace minimiser, below its threshold.  The KKT check uses the original ``G``: at a
KKT point of the regularised problem the two gradients differ by ``r w``, which is at most
``n_shapes * tol.gram_ridge`` relative to the check's scale (``max|G| >= lambda_max / n_shapes``), far below
``tol.kkt``.  So every optimal weight vector of a rank-deficient problem passes the check (a KKT point of
this convex problem is a minimiser), and weights that are not optimal fail it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Callable

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.interrupt import interrupts_deferred
from workbench.core.solvers import SOLVER_KINDS
from workbench.core.tolerances import TOL, Tolerances
from workbench.numerics.active_set import FINISHED, kkt_violation_frames, primal_active_set_frames
from workbench.numerics.bounded import (
    ADMM_RELAX,
    ADMM_RHO,
    admm,
    frames_of,
    largest_entry,
    positive,
    primal_active_set,
    times,
)
from workbench.numerics.validation import SOLVER, check_matrix

KINDS = tuple(SOLVER_KINDS)
"""The kinds of :data:`workbench.core.solvers.SOLVER_KINDS` as the package defines them (:data:`SOLVES` has each
kind's solve)."""

# ADMM warm start: iterations (its penalty and over-relaxation: ``workbench.numerics.bounded``).
_ADMM_STEPS = 10

# The primal active-set method frees a pinned variable only if its scaled gradient exceeds this fraction of
# ``Tolerances.kkt``.
_FREE_FRACTION = 0.1

# Termination tolerance of SciPy's BVLS on the fallback problem (scaled to O(1), see ``_per_frame``).
_BVLS_TOL = 1e-14


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
        Iterations (batched pinned solves) of the primal active-set method; 0 for ``"lstsq"`` and when
        every frame's unconstrained weights are feasible.  The fixed ADMM warm-start steps are not counted.
    n_fallback_frames : int
        Frames that needed SciPy's per-frame solver (iteration cap or a failed KKT check).
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
class WeightProblem:
    """One basis's problem of eq. 5 for every frame, as each kind's solve (:data:`SOLVES`) takes it.

    Attributes
    ----------
    start : ndarray of shape (n_frames, n_shapes)
        The minimum-norm unconstrained weights.
    lo, hi : ndarray of shape (n_shapes,) or None
        The bounds of every shape (None for a kind without bounds).
    tol : Tolerances
    terms : callable
        ``() -> (gram, rhs, ridge)``, computed when a solve asks: the gram ``G`` of shape (n_shapes, n_shapes), or
        (n_frames, n_shapes, n_shapes) under capture gaps, ``c`` of shape (n_frames, n_shapes) and the ridge added
        to ``G`` (see the module's notes).
    per_frame : callable
        ``(frames, solve_one) -> ndarray of shape (len(frames), n_shapes)``: SciPy's solver ``solve_one(design,
        target, lo, hi)`` (:func:`_nnls_one`, :func:`_bvls_one`) on the given frames' problems, one at a time.
    """

    start: np.ndarray
    lo: np.ndarray | None
    hi: np.ndarray | None
    tol: Tolerances
    terms: Callable[[], tuple]
    per_frame: Callable[[np.ndarray, Callable], np.ndarray]


def _least_squares(problem: WeightProblem) -> tuple[np.ndarray, int, int, float]:
    return problem.start, 0, 0, 0.0


def _bounded(problem: WeightProblem, solve_one: Callable) -> tuple[np.ndarray, int, int, float]:
    gram, rhs, ridge = problem.terms()
    fallback = lambda frames: problem.per_frame(frames, solve_one)  # noqa: E731
    return _solve_bounded(gram, rhs, problem.lo, problem.hi, problem.start, ridge, fallback, problem.tol)


SOLVES: dict[str, Callable[[WeightProblem], tuple]] = {
    "lstsq": _least_squares,
    "nnls": lambda problem: _bounded(problem, _nnls_one),
    "box": lambda problem: _bounded(problem, _bvls_one),
}
"""Kind (:data:`workbench.core.solvers.SOLVER_KINDS`) -> its solve: a :class:`WeightProblem` -> ``(weights,
n_iterations, n_fallback_frames, max_kkt_violation)`` as :class:`WeightSolution` keeps them."""


def _solution(kind: str, problem: WeightProblem, lower, upper) -> WeightSolution:
    weights, n_iterations, n_fallback, violation = SOLVES[kind](problem)
    return WeightSolution(weights, kind, lower, upper, n_iterations, n_fallback, violation)


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
    visible=None,
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
    visible : array_like of bool, shape (n_frames, n_points), optional
        Which points (``n_dims = 3 * n_points``, coordinates ``[x0, y0, z0, x1, ...]``) each frame saw.  Each
        frame's weights then minimise eq. 5 over its visible points only, and ``targets`` may hold NaN at the
        others.  Every frame must see at least one point.  None: every point of every frame.
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
    if visible is not None:
        return _solve_masked(basis, targets, visible, kind=kind, lower=lower, upper=upper, tol=tol)
    basis = check_matrix("basis", basis, SOLVER)
    targets = check_matrix("targets", targets, SOLVER)
    _check_columns(basis, targets)
    reduction = reduce_basis(basis)
    both = targets @ np.hstack([reduction.u, basis.T])  # one pass over the targets for both products
    k = reduction.u.shape[1]
    return solve_projected(reduction, both[:, :k], kind=kind, lower=lower, upper=upper, tol=tol, rhs=both[:, k:])


@dataclass(frozen=True)
class BasisReduction:
    """One thin SVD ``basis.T = u diag(singular) vt`` that every frame's problem of eq. 5 is reduced with.

    A frame ``d*`` enters only through its projection ``u^T d*`` (length ``k = min(n_dims, n_shapes)``):
    ``|d* - B^T w|^2 = |d* - u u^T d*|^2 + |u^T d* - diag(singular) vt w|^2``, so the projections of every basis
    can be taken in one pass over the frames (:func:`workbench.numerics.reduced.project_frames`).

    Attributes
    ----------
    basis : ndarray of shape (n_shapes, n_dims)
    u : ndarray of shape (n_dims, k)
        Orthonormal columns.
    singular : ndarray of shape (k,)
        Descending.
    vt : ndarray of shape (k, n_shapes)
    """

    basis: np.ndarray
    u: np.ndarray
    singular: np.ndarray
    vt: np.ndarray


def reduce_basis(basis) -> BasisReduction:
    """The thin SVD of a basis (:class:`BasisReduction`).

    Parameters
    ----------
    basis : array_like of shape (n_shapes, n_dims)
        Finite, non-empty.

    Returns
    -------
    BasisReduction
    """
    basis = check_matrix("basis", basis, SOLVER)
    u, singular, vt = np.linalg.svd(basis.T, full_matrices=False)
    return BasisReduction(basis=basis, u=u, singular=singular, vt=vt)


def solve_projected(
    reduction: BasisReduction,
    projected,
    *,
    kind: str = "lstsq",
    lower=None,
    upper=None,
    tol: Tolerances = TOL,
    rhs: np.ndarray | None = None,
) -> WeightSolution:
    """:func:`solve_weights` from the frames' projections ``targets @ reduction.u`` alone.

    Parameters
    ----------
    reduction : BasisReduction
    projected : array_like of shape (n_frames, k)
        ``targets @ reduction.u``.
    kind, lower, upper, tol
        As :func:`solve_weights`.
    rhs : ndarray of shape (n_frames, n_shapes), optional
        ``targets @ basis.T`` when the caller has the targets; from the projections otherwise (equal to rounding).

    Returns
    -------
    WeightSolution
    """
    projected = check_matrix("projected", projected, SOLVER)
    if projected.shape[1] != reduction.u.shape[1]:
        raise WorkbenchError(
            f"projected has {projected.shape[1]} columns but the basis reduction has {reduction.u.shape[1]}"
        )
    basis = reduction.basis
    kind = _check_kind(kind)
    lo, hi, lower_out, upper_out = _bounds(kind, lower, upper, basis.shape[0])
    reduced = _Reduction(n_dims=basis.shape[1], singular=reduction.singular, vt=reduction.vt, projected=projected)
    ridge = _ridge(reduction.singular, basis.shape[0], tol.gram_ridge)

    def terms():
        gram = basis @ basis.T
        return gram, (projected * reduction.singular) @ reduction.vt if rhs is None else rhs, ridge  # targets @ B^T

    def per_frame(frames, solve_one):
        return _per_frame(reduced, lo, hi, frames, solve_one, ridge)

    return _solution(kind, WeightProblem(_unconstrained(reduced), lo, hi, tol, terms, per_frame), lower_out, upper_out)


def in_span_error_sq(reduction: BasisReduction, projected: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``|u^T d* - diag(s) vt w|^2`` per frame, shape (n_frames,): the part of eq. 5's error inside the basis's
    span (the squared length of :func:`in_span_difference`, which takes the same arguments)."""
    difference = in_span_difference(reduction, projected, weights)
    return np.einsum("ij,ij->i", difference, difference)


def in_span_difference(reduction: BasisReduction, projected: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``u^T d* - diag(s) vt w`` per frame: the frame's coordinates in the basis's span less its reconstruction's.

    Parameters
    ----------
    reduction : BasisReduction
    projected : ndarray of shape (n_frames, k)
    weights : ndarray of shape (n_frames, n_shapes)

    Returns
    -------
    ndarray of shape (n_frames, k)
    """
    return projected - (weights @ reduction.vt.T) * reduction.singular


def _solve_masked(basis, targets, visible, *, kind, lower, upper, tol) -> WeightSolution:
    """:func:`solve_weights` over each frame's visible points, for all frames at once.

    With the basis's thin SVD ``B^T = U S V^T`` (rank ``r``, cut-off as for ``"lstsq"``), a frame's masked
    problem in ``y = S V^T w`` has the ``r x r`` gram ``U^T M_f U`` (a sum of per-point blocks over the visible
    points: one matrix product for all frames, near the identity when few points are missing). One batched
    Cholesky solve gives ``y`` for every frame, with ``tol.gram_ridge`` added to the diagonal so that a frame whose
    visible points do not determine all ``r`` directions still gets the minimum-norm ``y``; the unconstrained
    weights are ``w = V S^-1 y``, the minimum-norm minimiser when the visible points determine ``y``.  The bounded
    kinds run the same ADMM start and primal active-set method as the unmasked problem with one gram per frame,
    ``G_f = B M_f B^T``, every frame with the ridge ``tol.gram_ridge * s_max^2`` (a masked frame's gram can be
    singular even when the basis is not).
    """
    basis = check_matrix("basis", basis, SOLVER)
    targets = check_matrix("targets", targets, SOLVER, finite=False)
    _check_columns(basis, targets)
    kind = _check_kind(kind)
    lo, hi, lower_out, upper_out = _bounds(kind, lower, upper, basis.shape[0])
    visible = check_visible(visible, targets.shape)
    seen = np.repeat(visible, 3, axis=1)
    if not np.isfinite(targets[seen]).all():
        raise WorkbenchError(
            "targets must be finite at every visible point; found "
            f"{np.count_nonzero(~np.isfinite(targets[seen]))} NaN/Inf values there"
        )
    observed = np.where(seen, targets, 0.0)
    u, singular, vt = np.linalg.svd(basis.T, full_matrices=False)
    cutoff = np.finfo(float).eps * max(basis.shape) * singular.max(initial=0.0)
    rank = int((singular > cutoff).sum())
    start = np.zeros((len(targets), basis.shape[0]))
    if rank:
        u, singular, vt = u[:, :rank], singular[:rank], vt[:rank]
        reduced_gram = masked_grams(u.T, visible) + tol.gram_ridge * np.eye(rank)
        y = np.linalg.solve(reduced_gram, (observed @ u)[:, :, None])[:, :, 0]
        start = (y / singular) @ vt

    @cache
    def terms():
        largest = float(singular.max(initial=0.0)) ** 2
        return masked_grams(basis, visible), observed @ basis.T, tol.gram_ridge * largest if largest > 0 else 1.0

    def per_frame(frames, solve_one):
        # |L^T w - L^-1 c|^2 = w^T (G + r I) w - 2 c^T w + const, with G + r I = L L^T
        gram, rhs, ridge = terms()
        factor = np.linalg.cholesky(gram[frames] + ridge * np.eye(gram.shape[-1]))
        projected = np.linalg.solve(factor, rhs[frames][:, :, None])[:, :, 0]
        return _per_frame_designs(np.swapaxes(factor, 1, 2), projected, lo, hi, solve_one, np.zeros(len(frames)))

    return _solution(kind, WeightProblem(start, lo, hi, tol, terms, per_frame), lower_out, upper_out)


def masked_grams(basis: np.ndarray, visible: np.ndarray) -> np.ndarray:
    """Each frame's gram of the basis over its visible points, ``G_f = sum_{p visible in f} B_p B_p^T``.

    Parameters
    ----------
    basis : ndarray of shape (n_shapes, 3 * n_points)
    visible : ndarray of bool, shape (n_frames, n_points)

    Returns
    -------
    ndarray of shape (n_frames, n_shapes, n_shapes)
    """
    n = basis.shape[0]
    per_point = basis.reshape(n, -1, 3)
    point_grams = np.einsum("ipk,jpk->pij", per_point, per_point).reshape(-1, n * n)
    return (visible.astype(float) @ point_grams).reshape(-1, n, n)


def check_visible(visible, targets_shape: tuple[int, int]) -> np.ndarray:
    """A visibility mask as a boolean array of shape (n_frames, n_points), checked against the targets' shape.

    Parameters
    ----------
    visible : array_like of bool, shape (n_frames, n_points)
    targets_shape : tuple of int
        ``(n_frames, 3 * n_points)``.

    Returns
    -------
    ndarray of bool, shape (n_frames, n_points)
    """
    visible = np.asarray(visible)
    n_frames, n_dims = targets_shape
    if visible.dtype != bool:
        raise WorkbenchError(f"visible must be a boolean mask, got dtype {visible.dtype}")
    if visible.shape != (n_frames, n_dims // 3) or n_dims % 3:
        raise WorkbenchError(
            f"visible must have shape (n_frames, n_points) = ({n_frames}, {n_dims // 3}) for "
            f"targets of shape {targets_shape}, got {visible.shape}"
        )
    empty = np.flatnonzero(~visible.any(axis=1))
    if empty.size:
        raise WorkbenchError(
            f"visible: {empty.size} frame(s) see no point at all (first: frame {empty[0]}); drop them before solving"
        )
    return visible


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
    basis = check_matrix("basis", basis, SOLVER)
    weights = check_matrix("weights", weights, SOLVER)
    if weights.shape[1] != basis.shape[0]:
        raise WorkbenchError(f"weights has {weights.shape[1]} columns but basis has {basis.shape[0]} rows (n_shapes)")
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
    gram : array_like of shape (n_shapes, n_shapes) or (n_frames, n_shapes, n_shapes)
        Symmetric ``G = B B^T``, shared by every frame or one per frame (masked solves).
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
    n = gram.shape[-1]
    if gram.shape not in ((n, n), (len(rhs), n, n)) or rhs.shape[1] != n or weights.shape != rhs.shape:
        raise WorkbenchError(
            f"kkt_violation needs gram (n, n) or (n_frames, n, n), rhs and weights (n_frames, n); got gram "
            f"{gram.shape}, rhs {rhs.shape}, weights {weights.shape}"
        )
    lo = _bound_vector("lower", lower, n, -np.inf)[0]
    hi = _bound_vector("upper", upper, n, np.inf)[0]
    if gram.ndim == 2:  # one gram for every frame: compiled, frame by frame
        return kkt_violation_frames(
            np.ascontiguousarray(gram.T),
            np.ascontiguousarray(rhs),
            np.ascontiguousarray(weights),
            lo,
            hi,
            float(largest_entry(gram)),
            _largest_finite(lo, hi),
        )
    grad = times(weights, np.swapaxes(gram, -1, -2)) - rhs
    w_size = np.abs(weights).max(axis=1)
    g_scale = positive(np.abs(rhs).max(axis=1) + largest_entry(gram) * w_size)[:, None]
    w_scale = positive(np.maximum(w_size, _largest_finite(lo, hi)))[:, None]
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


def _check_columns(basis: np.ndarray, targets: np.ndarray) -> None:
    if targets.shape[1] != basis.shape[1]:
        raise WorkbenchError(
            f"targets has {targets.shape[1]} columns but basis has {basis.shape[1]} (n_dims must match)"
        )


def _check_kind(kind) -> str:
    if kind not in SOLVER_KINDS or kind not in SOLVES:
        raise WorkbenchError(f"kind must be one of {', '.join(k for k in SOLVER_KINDS if k in SOLVES)}; got {kind!r}")
    return kind


def _bounds(kind: str, lower, upper, n: int):
    """Per-shape bound vectors ``lo, hi`` (shape (n,)) and the bounds to record in the solution, by the kind's
    entry in :data:`workbench.core.solvers.SOLVER_KINDS`."""
    entry = SOLVER_KINDS[kind]
    if not entry.constrained:
        if lower is not None or upper is not None:
            raise WorkbenchError(f"lower and upper must be None for kind '{kind}' (use kind 'nnls' or 'box')")
        return None, None, None, None
    if not entry.options:  # bounds of its own: a setting may only repeat them
        if not (_is_fixed(lower, entry.lower) and _is_fixed(upper, entry.upper)):
            raise WorkbenchError(
                f"kind '{kind}' fixes lower={_bound_text(entry.lower)} and upper={_bound_text(entry.upper)}; "
                "use kind 'box' for other bounds"
            )
        lower, upper = entry.lower, entry.upper
        return (
            np.full(n, -np.inf if lower is None else lower),
            np.full(n, np.inf if upper is None else upper),
            lower,
            upper,
        )
    if lower is None and upper is None:
        raise WorkbenchError(f"kind '{kind}' needs lower or upper (or both); got neither")
    lo, lower_out = _bound_vector("lower", lower, n, -np.inf)
    hi, upper_out = _bound_vector("upper", upper, n, np.inf)
    _check_order(lo, hi, np.ndim(lower_out) == 0 and np.ndim(upper_out) == 0)
    return lo, hi, lower_out, upper_out


def _is_fixed(value, fixed: float | None) -> bool:
    """Whether a given bound is absent or the kind's own scalar ``fixed``."""
    return value is None or (
        fixed is not None and np.ndim(value) == 0 and np.isreal(value) and float(value) == float(fixed)
    )


def _bound_text(value: float | None) -> str:
    return "None" if value is None else f"{value:g}"


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


# ----------------------------------------------------------------------------------------------------------
# Reduction and the unconstrained solution
# ----------------------------------------------------------------------------------------------------------


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
# Bounded problem: ADMM warm start, batched primal active set, SciPy per frame where needed
# ----------------------------------------------------------------------------------------------------------


def _solve_bounded(gram, rhs, lo, hi, start, ridge, fallback, tol):
    """Bounded weights of every frame; returns (weights, n_iterations, n_fallback_frames, max violation).

    ``gram`` is one ``(n, n)`` matrix for every frame or one per frame, ``(n_frames, n, n)``, with ``ridge`` a
    float or one per frame; ``fallback(frames)`` solves the given frames one by one with SciPy.
    """
    n = gram.shape[-1]
    weights = start.copy()
    done = np.ones(len(rhs), dtype=bool)
    pending = np.flatnonzero(((start < lo) | (start > hi)).any(axis=1))
    n_iter = 0
    if pending.size:
        c = rhs[pending]
        work = frames_of(gram, pending) + np.multiply.outer(frames_of(ridge, pending), np.eye(n))
        if work.ndim == 2:  # one gram for every frame: compiled, frame by frame
            penalty = ADMM_RHO * positive(np.diagonal(work).copy())
            inverse = np.linalg.inv(work + np.diag(penalty))
            # Ctrl-C is held back until the compiled call has returned: numba boxes the tuple it returns without
            # checking its items, and an interrupt raised while it boxed them left a null item that unpacking the
            # tuple then dereferenced (the process died of SIGSEGV, not with the one line and exit status 130).
            with interrupts_deferred():
                found, status, iterations = primal_active_set_frames(
                    np.ascontiguousarray(work),
                    np.ascontiguousarray(c),
                    lo,
                    hi,
                    start[pending],
                    tol.active_set_max_iter,
                    _FREE_FRACTION * tol.kkt,
                    inverse,
                    penalty[:, None] * inverse,
                    _ADMM_STEPS,
                    ADMM_RELAX,
                )
            weights[pending], done[pending], n_iter = found, status == FINISHED, int(iterations.max())
        else:
            guess = admm(work, c, lo, hi, start[pending], _ADMM_STEPS)
            weights[pending], done[pending], n_iter = primal_active_set(
                work, c, lo, hi, guess, tol.active_set_max_iter, _FREE_FRACTION * tol.kkt
            )
    violation = kkt_violation(gram, rhs, weights, lo, hi)
    redo = np.flatnonzero(~done | (violation > tol.kkt))
    if redo.size:
        candidate = fallback(redo)
        candidate_violation = kkt_violation(frames_of(gram, redo), rhs[redo], candidate, lo, hi)
        better = ~done[redo] | (candidate_violation < violation[redo])
        weights[redo[better]] = candidate[better]
        violation[redo[better]] = candidate_violation[better]
    return weights, n_iter, int(redo.size), float(violation.max())


def _per_frame(reduction: _Reduction, lo, hi, frames: np.ndarray, solve_one: Callable, ridge: float) -> np.ndarray:
    """SciPy's per-frame solver on the reduced problem ``|diag(s) Vt w - (U^T d*)_f|^2`` for ``frames``."""
    design = reduction.singular[:, None] * reduction.vt
    return _per_frame_designs(
        np.broadcast_to(design, (len(frames),) + design.shape),
        reduction.projected[frames],
        lo,
        hi,
        solve_one,
        np.full(len(frames), ridge),
    )


def _per_frame_designs(designs, projected, lo, hi, solve_one: Callable, ridges) -> np.ndarray:
    """SciPy's per-frame solver on ``|design_f w - projected_f|^2``, one frame at a time.

    With a ridge the design gets ``sqrt(ridge) * I`` rows (zero targets), matching the batched solver.
    Design and targets are divided by the design's largest singular value so SciPy's absolute tolerances apply
    to an O(1) problem.

    Parameters
    ----------
    designs : ndarray of shape (n_frames, k, n)
    projected : ndarray of shape (n_frames, k)
    lo, hi : ndarray of shape (n,)
    solve_one : callable
        ``(design, target, lo, hi) -> weights`` of one frame: :func:`_nnls_one` or :func:`_bvls_one`.
    ridges : ndarray of shape (n_frames,)
    """
    n = designs.shape[2]
    # Shapes with lower == upper are fixed; SciPy's bounded solver needs lower < upper for the others.
    fixed = lo == hi
    weights = np.tile(np.where(fixed, lo, 0.0), (len(designs), 1))
    if fixed.all():
        return weights
    for f, (design, target, ridge) in enumerate(zip(designs, projected, ridges)):
        if ridge > 0.0:
            design = np.vstack([design, np.sqrt(ridge) * np.eye(n)])
            target = np.concatenate([target, np.zeros(n)])
        unit = float(np.linalg.norm(design, 2)) or 1.0
        design, target = design / unit, target / unit
        target = target - design[:, fixed] @ lo[fixed]
        weights[f, ~fixed] = solve_one(design[:, ~fixed], target, lo[~fixed], hi[~fixed])
    return weights


def _nnls_one(design, b, lo, hi) -> np.ndarray:
    from scipy.optimize import nnls  # imported when needed: scipy.optimize adds 0.17 s to every start-up

    return nnls(design, b, maxiter=50 * design.shape[1])[0]


def _bvls_one(design, b, lo, hi) -> np.ndarray:
    from scipy.optimize import lsq_linear

    n = design.shape[1]
    return lsq_linear(design, b, bounds=(lo, hi), method="bvls", tol=_BVLS_TOL, max_iter=50 * n + 100).x


def _largest_finite(lo: np.ndarray, hi: np.ndarray) -> float:
    finite = np.concatenate([lo[np.isfinite(lo)], hi[np.isfinite(hi)]])
    return float(np.abs(finite).max(initial=0.0))
