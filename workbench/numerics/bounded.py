"""The bounded problem of eq. 5 for many frames at once, in NumPy: the ADMM warm start and the batched primal
active-set method that :func:`workbench.numerics.solve.solve_weights` runs when every frame has its own gram (masked frames);
:mod:`workbench.numerics.active_set` compiles the same method frame by frame for a gram shared by every frame.
"""

from __future__ import annotations

import numpy as np

# ADMM warm start: penalty ``rho_i = ADMM_RHO * G_ii`` and over-relaxation (see :func:`admm`; the number of
# iterations is ``workbench.numerics.solve._ADMM_STEPS``).
ADMM_RHO = 0.1
ADMM_RELAX = 1.6

# Right-hand sides per factorisation when frames share a free set, and matrix entries per batched solve call
# (memory bound), see ``_pinned_solve``.
MAX_SHARED = 32
SYSTEM_ENTRIES = 2**22


def frames_of(per_frame, frames):
    """The values of ``frames``: a shared value (an ``(n, n)`` gram, a float ridge) itself, or those rows of
    per-frame ones (``(n_frames, n, n)`` grams, ``(n_frames,)`` ridges)."""
    return per_frame if np.ndim(per_frame) in (0, 2) else per_frame[frames]


def times(rows, gram):
    """``rows[f] @ gram`` (shared gram) or ``rows[f] @ gram[f]`` (per-frame grams), shape (n_frames, n)."""
    return rows @ gram if gram.ndim == 2 else np.einsum("fi,fij->fj", rows, gram)


def largest_entry(gram):
    """``max|G|``: a float for a shared gram, shape (n_frames,) for per-frame grams."""
    return np.abs(gram).max() if gram.ndim == 2 else np.abs(gram).max(axis=(1, 2))


def admm(gram, c, lo, hi, start, steps: int):
    """Feasible weights after a few over-relaxed ADMM iterations from ``start``, for all frames at once.

    ADMM on ``min 0.5 w^T G w - c^T w + [z in box]`` subject to ``w = z``, with scaled multipliers ``u``,
    penalty ``R = diag(ADMM_RHO * G_ii)`` and relaxation ``a = ADMM_RELAX``:
    ``x = (G + R)^-1 (c + R (z - u))``, ``x <- a x + (1 - a) z``, ``z = clip(x + u)``, ``u <- u + x - z``.
    It is run on ``s = z + u`` alone (``z = clip(s)``, ``u = s - z``), which gives the update
    ``s <- s + a (x - z)`` with ``x = (G + R)^-1 (c + R (2 z - s))``.  ``G + R`` is positive definite even
    when ``G`` is singular.  The result only guides :func:`primal_active_set`; it need not be converged.

    Parameters
    ----------
    gram : ndarray of shape (n, n) or (n_frames, n, n)
        Symmetric positive semi-definite; one for every frame, or one per frame.
    c : ndarray of shape (n_frames, n)
    lo, hi : ndarray of shape (n,)
    start : ndarray of shape (n_frames, n)
        Finite weights, e.g. the unconstrained ones.
    steps : int

    Returns
    -------
    ndarray of shape (n_frames, n)
        ``z``, within the bounds.
    """
    penalty = ADMM_RHO * positive(np.diagonal(gram, axis1=-2, axis2=-1).copy())
    inverse = np.linalg.inv(gram + penalty[..., None] * np.eye(gram.shape[-1]))
    offset = times(c, inverse)
    gain = penalty[..., :, None] * inverse
    s = np.clip(start, lo, hi)
    for _ in range(steps):
        z = np.clip(s, lo, hi)
        x = times(2.0 * z - s, gain)
        x += offset
        x -= z
        x *= ADMM_RELAX
        s += x
    return np.clip(s, lo, hi)


def primal_active_set(gram, rhs, lo, hi, start, max_iter: int, threshold: float):
    """Batched primal active-set iterations (Lawson-Hanson NNLS, Stark-Parker BVLS) for all frames at once.

    Every frame keeps feasible weights ``w`` and a set of variables pinned at a bound (initially those of
    ``start`` that lie on a bound).  An iteration solves the pinned systems of all unfinished frames at once
    (:func:`_pinned_solve`, solution ``z``) and then, per frame:

    * if ``z`` violates a bound, ``w`` moves towards ``z`` until the first free variable reaches its bound,
      and that variable is pinned.  ``z`` minimises the (convex) objective on the subspace through ``w``
      where the pinned variables are fixed, so the objective does not increase;
    * otherwise ``w = z``, and the pinned variable whose gradient pulls it off its bound (by more than
      ``threshold``, scaled as in :func:`kkt_violation`) with the largest predicted decrease
      ``g_i^2 / G_ii`` is freed.  The minimiser of the enlarged subspace is strictly lower and the freed
      variable moves into the box towards it, so the objective at successive subspace minimisers strictly
      decreases and no free set comes back: the method cannot cycle.  Without such a variable the frame
      is finished.

    A freed variable that the next solve would move out of the box (possible only through rounding, when its
    gradient was noise) finishes the frame as it is; the KKT check of the caller judges it.

    Parameters
    ----------
    gram : ndarray of shape (n, n) or (n_frames, n, n)
        Symmetric positive definite (regularised if needed); one for every frame, or one per frame.
    rhs : ndarray of shape (n_frames, n)
    lo, hi : ndarray of shape (n,)
    start : ndarray of shape (n_frames, n)
        Weights to start from; non-finite entries become 0 and all are clipped to the bounds.
    max_iter : int
        Batched solves at most.
    threshold : float

    Returns
    -------
    weights : ndarray of shape (n_frames, n)
        Within the bounds for every frame, finished or not.
    done : ndarray of bool, shape (n_frames,)
        Frames that finished within ``max_iter`` iterations.
    n_iterations : int
    """
    w = np.clip(np.where(np.isfinite(start), start, 0.0), lo, hi)
    at_lo = w <= lo
    at_hi = (w >= hi) & ~at_lo
    upper = bool(np.isfinite(hi).any())
    weights = w.copy()
    done = np.zeros(len(rhs), dtype=bool)
    pending = np.arange(len(rhs))
    c = rhs
    c_size = np.abs(rhs).max(axis=1)
    shared = gram.ndim == 2
    g_max = largest_entry(gram)
    curvature = positive(np.diagonal(gram, axis1=-2, axis2=-1).copy())
    freed = np.full(len(rhs), -1)
    n_iter = 0
    while pending.size and n_iter < max_iter:
        n_iter += 1
        z = _pinned_solve(gram, c, w, ~(at_lo | at_hi))
        below = z < lo  # pinned variables sit exactly on their bound: only free ones can be outside
        above = (z > hi) if upper else np.zeros_like(below)
        blocked = (below | above).any(axis=1)
        finished = np.zeros(len(z), dtype=bool)
        k = np.flatnonzero(blocked)
        if k.size:
            _step_to_bounds(k, w, z, below, above, lo, hi, upper, at_lo, at_hi, freed, finished)
        u = np.flatnonzero(~blocked)
        if u.size:
            _free_or_finish(
                u, w, z, gram, c, c_size, g_max, curvature, threshold, lo < hi, upper, at_lo, at_hi, freed, finished
            )
        weights[pending] = w
        if finished.any():
            done[pending[finished]] = True
            keep = ~finished
            pending, w, c, c_size, at_lo, at_hi, freed = (
                pending[keep],
                w[keep],
                c[keep],
                c_size[keep],
                at_lo[keep],
                at_hi[keep],
                freed[keep],
            )
            if not shared:
                gram, g_max, curvature = gram[keep], g_max[keep], curvature[keep]
    return weights, done, n_iter


def _step_to_bounds(k, w, z, below, above, lo, hi, upper: bool, at_lo, at_hi, freed, finished) -> None:
    """The frames ``k`` whose solve ``z`` left the box: step from ``w`` toward ``z`` up to the first bound and pin
    the variables that reach it; a frame that cannot move and pins again the variable it last freed is finished.
    Updates ``w``, ``at_lo``, ``at_hi``, ``freed`` and ``finished`` in place (a step of :func:`primal_active_set`)."""
    wk, zk, bk, ak = w[k], z[k], below[k], above[k]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(bk, (wk - lo) / (wk - zk), np.inf)
        if upper:
            ratio = np.where(ak, (hi - wk) / (zk - wk), ratio)
    step = ratio.min(axis=1)
    hit = ratio <= step[:, None]
    pin_lo, pin_hi = hit & bk, hit & ak
    wk = np.clip(wk + step[:, None] * (zk - wk), lo, hi)
    np.copyto(wk, np.broadcast_to(lo, wk.shape), where=pin_lo)
    np.copyto(wk, np.broadcast_to(hi, wk.shape), where=pin_hi)
    w[k] = wk
    at_lo[k] |= pin_lo
    at_hi[k] |= pin_hi
    last = freed[k]
    finished[k] = (step <= 0.0) & (last >= 0) & hit[np.arange(k.size), np.maximum(last, 0)]
    freed[k] = -1


def _free_or_finish(
    u, w, z, gram, c, c_size, g_max, curvature, threshold: float, movable, upper: bool, at_lo, at_hi, freed, finished
) -> None:
    """The frames ``u`` whose solve ``z`` stayed in the box: take ``z``, and free the pinned variable whose gradient
    pulls hardest out of its bound, or finish the frame when none does. Updates ``w``, ``at_lo``, ``at_hi``,
    ``freed`` and ``finished`` in place (a step of :func:`primal_active_set`)."""
    shared = gram.ndim == 2
    wu = z[u]
    grad = times(wu, frames_of(gram, u)) - c[u]
    small = (threshold * (c_size[u] + (g_max if shared else g_max[u]) * np.abs(wu).max(axis=1)))[:, None]
    wanted = at_lo[u] & (grad < -small)
    if upper:
        wanted |= at_hi[u] & (grad > small)
    pull = grad * grad * (wanted & movable) / (curvature if shared else curvature[u])
    best = pull.argmax(axis=1)
    grows = pull[np.arange(u.size), best] > 0.0
    at_lo[u[grows], best[grows]] = False
    at_hi[u[grows], best[grows]] = False
    freed[u] = np.where(grows, best, -1)
    w[u] = wu
    finished[u] = ~grows


def _pinned_solve(gram, c, w, free):
    """Weights equal to ``w`` on pinned variables and solving ``G_FF x_F = c_F - G_FA w_A`` on free ones.

    Each frame's system is ``G`` with the rows and columns of its pinned variables replaced by those of the
    identity, right-hand side ``w_i`` on them.  Frames with the same free set -- usually many: a take has far
    fewer distinct active sets than frames -- share one such matrix and are packed as the columns of one
    multi-right-hand-side system, at most ``width`` per system, so the batched solve factorises one matrix per
    distinct set (or per ``width`` frames) instead of one per frame.

    Parameters
    ----------
    gram : ndarray of shape (n, n) or (n_frames, n, n)
        Symmetric; one for every frame, or one per frame.
    c : ndarray of shape (n_frames, n)
    w : ndarray of shape (n_frames, n)
        Finite; its pinned entries are kept (exactly).
    free : ndarray of bool, shape (n_frames, n)

    Returns
    -------
    ndarray of shape (n_frames, n)
    """
    n_frames, n = c.shape
    pinned = w * ~free
    b = (c - times(pinned, gram) if pinned.any() else c) * free + pinned  # pinned all zero: the nnls case
    if gram.ndim == 3:  # one gram per frame: nothing to share, one batched solve per block of frames
        out = np.empty_like(b)
        block = max(1, SYSTEM_ENTRIES // (n * n))
        for part in range(0, n_frames, block):
            rows = slice(part, part + block)
            out[rows] = _identity_pinned_solve(gram[rows], free[rows], b[rows, :, None])[:, :, 0]
        return out
    _, first, group, count = np.unique(
        _set_key(free), return_index=True, return_inverse=True, return_counts=True, axis=0
    )
    group = group.ravel()
    width = int(min(MAX_SHARED, -(-n_frames // first.size)))
    order = np.argsort(group, kind="stable")
    group = group[order]
    rank = np.arange(n_frames) - (np.cumsum(count) - count)[group]
    n_systems = -(-count // width)
    system = (np.cumsum(n_systems) - n_systems)[group] + rank // width
    slot = rank % width
    owner = np.repeat(free[first], n_systems, axis=0)
    x = np.zeros((owner.shape[0], n, width))
    x[system, :, slot] = b[order]
    block = max(1, SYSTEM_ENTRIES // (n * n))
    for part in range(0, len(owner), block):
        x[part : part + block] = _identity_pinned_solve(gram, owner[part : part + block], x[part : part + block])
    out = np.empty_like(b)
    out[order] = x[system, :, slot]
    return out


def _identity_pinned_solve(gram, free, rhs):
    """Solve ``M_k X_k = rhs_k`` for every k, ``M_k`` being ``gram`` with identity rows and columns where
    ``free[k]`` is False.

    Parameters
    ----------
    gram : ndarray of shape (n, n) or (n_systems, n, n)
    free : ndarray of bool, shape (n_systems, n)
    rhs : ndarray of shape (n_systems, n, width)

    Returns
    -------
    ndarray of shape (n_systems, n, width)
    """
    n = gram.shape[-1]
    matrices = np.where(free[:, :, None] & free[:, None, :], gram, 0.0)
    matrices[:, np.arange(n), np.arange(n)] += ~free
    try:
        return np.linalg.solve(matrices, rhs)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(matrices) @ rhs


def _set_key(free):
    """One key per row of a boolean mask, equal for equal rows: a bit mask when ``n <= 62``, else the row."""
    n = free.shape[1]
    if n <= 62:
        return free @ (np.int64(1) << np.arange(n, dtype=np.int64))
    return free


def positive(x: np.ndarray) -> np.ndarray:
    return np.where(x > 0, x, 1.0)
