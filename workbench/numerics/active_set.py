"""The primal active-set method of :mod:`workbench.numerics.solve` frame by frame, compiled with numba.

The reduced problems of eq. 5 are tiny (``n`` about 18) and there is one per frame: NumPy's batched version pays
for array passes over all pending frames on every iteration, while a compiled loop keeps one frame's ``n x n``
system in cache and stops each frame as soon as it is done. Frames run in parallel threads. The method and its
rules (which variable is pinned or freed, when a frame is finished) are those of
:func:`workbench.numerics.bounded.primal_active_set`; each pinned system is solved by a Cholesky factorisation of its free
block, which the caller's ridge keeps positive definite.
"""

from __future__ import annotations

import numpy as np

from workbench.numerics.compiled import njit, prange

_BLOCKS = 64
"""Blocks of frames the parallel loop hands out (each allocates its work space once)."""

FINISHED, UNFINISHED, SINGULAR = 0, 1, 2
"""Status of a frame: finished, out of iterations, or a free block that was not positive definite."""


@njit(cache=True, fastmath=False)
def _free_block_solve(gram, rhs, free, out, factor, index, y):
    """``out[F] = G_FF^-1 rhs[F]`` by Cholesky; False if ``G_FF`` is not positive definite (``factor``, ``index``
    and ``y`` are work space)."""
    n = gram.shape[0]
    k = 0
    for i in range(n):
        if free[i]:
            index[k] = i
            k += 1
    for a in range(k):
        for b in range(a + 1):
            total = gram[index[a], index[b]]
            for j in range(b):
                total -= factor[a, j] * factor[b, j]
            if a == b:
                if total <= 0.0:
                    return False
                factor[a, a] = np.sqrt(total)
            else:
                factor[a, b] = total / factor[b, b]
    for a in range(k):
        total = rhs[index[a]]
        for j in range(a):
            total -= factor[a, j] * y[j]
        y[a] = total / factor[a, a]
    for a in range(k - 1, -1, -1):
        total = y[a]
        for j in range(a + 1, k):
            total -= factor[j, a] * y[j]
        y[a] = total / factor[a, a]
    for a in range(k):
        out[index[a]] = y[a]
    return True


@njit(cache=True)
def _one_frame(gram, c, lo, hi, w, max_iter, threshold, g_max, curvature, movable, flags, b, z, factor, index, y):
    """The primal active-set method on one frame, from feasible ``w`` (changed in place); ``flags`` (3, n) and
    the rest after it are work space.

    Returns (status, iterations)."""
    n = gram.shape[0]
    at_lo, at_hi, free = flags[0], flags[1], flags[2]
    for i in range(n):
        at_lo[i] = w[i] <= lo[i]
        at_hi[i] = (w[i] >= hi[i]) and not at_lo[i]
    c_size = 0.0
    for i in range(n):
        c_size = max(c_size, abs(c[i]))
    freed = -1
    for iteration in range(1, max_iter + 1):
        for i in range(n):
            free[i] = not (at_lo[i] or at_hi[i])
        for i in range(n):  # b_F = c_F - G_FA w_A; pinned entries keep w
            if free[i]:
                total = c[i]
                for j in range(n):
                    if not free[j]:
                        total -= gram[i, j] * w[j]
                b[i] = total
            else:
                z[i] = w[i]
        if not _free_block_solve(gram, b, free, z, factor, index, y):
            return SINGULAR, iteration
        step = np.inf
        for i in range(n):
            if free[i]:
                if z[i] < lo[i]:
                    step = min(step, (w[i] - lo[i]) / (w[i] - z[i]))
                elif z[i] > hi[i]:
                    step = min(step, (hi[i] - w[i]) / (z[i] - w[i]))
        if step < np.inf:  # blocked: move towards z until the first free variable reaches its bound, pin it
            stuck = False
            for i in range(n):
                if not free[i]:
                    continue
                below, above = z[i] < lo[i], z[i] > hi[i]
                ratio = np.inf
                if below:
                    ratio = (w[i] - lo[i]) / (w[i] - z[i])
                elif above:
                    ratio = (hi[i] - w[i]) / (z[i] - w[i])
                w[i] = min(max(w[i] + step * (z[i] - w[i]), lo[i]), hi[i])
                if ratio <= step:
                    if below:
                        w[i], at_lo[i] = lo[i], True
                    else:
                        w[i], at_hi[i] = hi[i], True
                    if i == freed and step <= 0.0:
                        stuck = True
            freed = -1
            if stuck:  # the variable just freed went straight back: rounding, the KKT check judges the frame
                return FINISHED, iteration
            continue
        w_size = 0.0
        for i in range(n):
            w[i] = z[i]
            w_size = max(w_size, abs(w[i]))
        small = threshold * (c_size + g_max * w_size)
        best, best_pull = -1, 0.0
        for i in range(n):
            if not (at_lo[i] or at_hi[i]) or not movable[i]:
                continue
            grad = -c[i]
            for j in range(n):
                grad += gram[i, j] * w[j]
            if (at_lo[i] and grad < -small) or (at_hi[i] and grad > small):
                pull = grad * grad / curvature[i]
                if pull > best_pull:
                    best, best_pull = i, pull
        if best < 0:
            return FINISHED, iteration
        at_lo[best], at_hi[best] = False, False
        freed = best
    return UNFINISHED, max_iter


@njit(cache=True)
def _admm_one(c, lo, hi, s, inverse, gain, steps, relax, offset, z, x):
    """The ADMM warm start of :func:`workbench.numerics.bounded.admm` on one frame; ``s`` (the start) is overwritten by
    the feasible result ``z`` (``offset``, ``z`` and ``x`` are work space). Products run along rows."""
    n = c.shape[0]
    offset[:] = 0.0
    for i in range(n):
        ci = c[i]
        for j in range(n):
            offset[j] += ci * inverse[i, j]
    for i in range(n):
        s[i] = min(max(s[i], lo[i]), hi[i])
    for _ in range(steps):
        for i in range(n):
            z[i] = min(max(s[i], lo[i]), hi[i])
        x[:] = offset
        for i in range(n):
            vi = 2.0 * z[i] - s[i]
            for j in range(n):
                x[j] += vi * gain[i, j]
        for j in range(n):
            s[j] += relax * (x[j] - z[j])
    for i in range(n):
        s[i] = min(max(s[i], lo[i]), hi[i])


@njit(cache=True, parallel=True)
def primal_active_set_frames(gram, rhs, lo, hi, start, max_iter, threshold, inverse, gain, admm_steps, relax):
    """:func:`workbench.numerics.bounded.admm` and :func:`workbench.numerics.bounded.primal_active_set` for a gram shared by every
    frame, one frame per loop pass.

    Parameters
    ----------
    gram : ndarray of shape (n, n)
        Symmetric positive definite (regularised if needed).
    rhs : ndarray of shape (n_frames, n)
    lo, hi : ndarray of shape (n,)
    start : ndarray of shape (n_frames, n)
        Finite weights to start the ADMM warm start from.
    max_iter : int
        Pinned solves per frame at most.
    threshold : float
    inverse, gain : ndarray of shape (n, n)
        ``(G + R)^-1`` and ``R (G + R)^-1`` of the warm start (``R`` its diagonal penalty).
    admm_steps : int
    relax : float
        Over-relaxation of the warm start.

    Returns
    -------
    weights : ndarray of shape (n_frames, n)
    status : ndarray of int, shape (n_frames,)
        :data:`FINISHED`, :data:`UNFINISHED` or :data:`SINGULAR`.
    iterations : ndarray of int, shape (n_frames,)
    """
    n_frames, n = rhs.shape
    weights = start.copy()
    status = np.empty(n_frames, dtype=np.int64)
    iterations = np.empty(n_frames, dtype=np.int64)
    g_max = np.abs(gram).max()
    curvature = np.empty(n)
    movable = np.empty(n, dtype=np.bool_)
    for i in range(n):
        curvature[i] = gram[i, i] if gram[i, i] > 0 else 1.0
        movable[i] = lo[i] < hi[i]
    n_blocks = min(n_frames, _BLOCKS)
    for block in prange(n_blocks):  # work space once per block of frames, not per frame
        flags = np.empty((3, n), dtype=np.bool_)
        vectors = np.empty((5, n))
        factor = np.empty((n, n))
        index = np.empty(n, dtype=np.int64)
        for f in range(block * n_frames // n_blocks, (block + 1) * n_frames // n_blocks):
            _admm_one(rhs[f], lo, hi, weights[f], inverse, gain, admm_steps, relax, vectors[0], vectors[1], vectors[2])
            status[f], iterations[f] = _one_frame(
                gram,
                rhs[f],
                lo,
                hi,
                weights[f],
                max_iter,
                threshold,
                g_max,
                curvature,
                movable,
                flags,
                vectors[0],
                vectors[1],
                factor,
                index,
                vectors[2],
            )
    return weights, status, iterations


@njit(cache=True, parallel=True)
def kkt_violation_frames(gram, rhs, weights, lo, hi, g_max, bound_size):
    """:func:`workbench.numerics.solve.kkt_violation` for a gram shared by every frame, frame by frame.

    Parameters
    ----------
    gram : ndarray of shape (n, n)
    rhs, weights : ndarray of shape (n_frames, n)
    lo, hi : ndarray of shape (n,)
    g_max : float
        ``max|G|``.
    bound_size : float
        The largest finite bound's magnitude (0 if none).

    Returns
    -------
    ndarray of shape (n_frames,)
    """
    n_frames, n = rhs.shape
    out = np.empty(n_frames)
    for f in prange(n_frames):
        w = weights[f]
        w_size, c_size, finite = 0.0, 0.0, True
        for i in range(n):
            w_size = max(w_size, abs(w[i]))
            c_size = max(c_size, abs(rhs[f, i]))
            finite = finite and np.isfinite(w[i])
        g_scale = c_size + g_max * w_size
        g_scale = g_scale if g_scale > 0 else 1.0
        w_scale = max(w_size, bound_size)
        w_scale = w_scale if w_scale > 0 else 1.0
        worst = 0.0
        for i in range(n):
            grad = -rhs[f, i]
            for j in range(n):
                grad += gram[i, j] * w[j]
            as_free = abs(grad) / g_scale
            as_lower = max(-grad, 0.0) / g_scale + max(w[i] - lo[i], 0.0) / w_scale
            as_upper = max(grad, 0.0) / g_scale + max(hi[i] - w[i], 0.0) / w_scale
            infeasible = max(max(lo[i] - w[i], w[i] - hi[i]), 0.0) / w_scale
            score = min(min(as_free, as_lower), as_upper) + infeasible
            if np.isnan(score):
                worst = np.inf
            worst = max(worst, score)
        out[f] = worst if finite else np.inf
    return out
