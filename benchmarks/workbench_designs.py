"""Series like the workbench's own per-frame data, for the coverage of the within-run intervals
(``python benchmarks/run.py coverage``, the second table).

The first coverage table gives the two rows of a comparison independent errors over a constant reference. In the
workbench's runs the rows share the frame's difficulty: a hard frame (an extreme expression, a fast transition) is
hard for every basis, and the per-frame log alphas of H and QE correlate 0.85-0.92 (AnimFace, ICT); the reference
(the frame's displacement from the neutral face) varies from frame to frame with the expression; the errors have a
long right tail; the persistence of 120 Hz capture reaches 0.99; and a run may pool several takes of unequal
length (AnimFace's headline: three takes of 398, 375 and 226 frames).

:func:`design_series` draws, for ``count`` series at once (one seeded ``numpy.random.Generator``):

- a shared difficulty ``d_t`` and two own parts ``u_t``, ``v_t``: independent stationary AR(1) series of
  persistence ``phi`` and unit variance, restarted independently in each take;
- log errors ``log e_a = s (rho d + c u)`` and ``log e_b = s (rho d + c v) - log 4``, ``rho^2 = SHARED``
  (their correlation), ``c = sqrt(1 - rho^2)``; ``s`` the log-normal sigma (1: AnimFace's p95/median of about 5;
  1.5: a heavier tail, p95/median of the squared errors about 12);
- a reference ``r_t = 100 exp(s_r (rho_r d + c_r w))`` with its own AR(1) ``w``, correlated with the difficulty
  (a frame far from neutral is both hard and large), ``s_r = REFERENCE_SIGMA``, ``rho_r^2 = REFERENCE_SHARED``.

The per-frame alphas are ``100 sqrt(e / r)`` (eq. 6 of one frame). The two rows have the same distribution up to
the factor 4 in the errors, so whatever the dependence the true ratio of mean alphas and of pooled alphas is 2; the
true pooled difference ``100 (sqrt(E e_a / E r) - sqrt(E e_b / E r))`` and the true difference of mean alphas follow
from the log-normal's moments (:func:`true_value`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

SHARED = 0.88
"""Correlation of the two rows' log errors (the workbench's data: 0.85-0.92)."""
REFERENCE_SIGMA, REFERENCE_SHARED = 0.5, 0.5
"""Log-normal sigma of the reference and the share of its log variance that is the frame's difficulty."""
RATIO = 4.0
"""True ratio of the two rows' mean errors."""
GEOMETRIES = {"800": (800,), "4000": (4000,), "398+375+226": (398, 375, 226)}
"""Frames per take of each geometry (AnimFace's headline: three takes of 398, 375 and 226 frames)."""


def ar1_takes(rng: np.random.Generator, takes: tuple[int, ...], phi: float, count: int) -> np.ndarray:
    """``count`` series of stationary AR(1) takes of unit variance and persistence ``phi``, independent from take
    to take, concatenated: shape (count, sum(takes))."""
    parts = []
    for size in takes:
        noise = rng.standard_normal((count, size)) * math.sqrt(1.0 - phi**2)
        noise[:, 0] /= math.sqrt(1.0 - phi**2)
        parts.append(lfilter([1.0], [1.0, -phi], noise, axis=1))
    return np.concatenate(parts, axis=1)


def take_labels(takes: tuple[int, ...]) -> np.ndarray:
    """The take of each frame (0, 1, ...)."""
    return np.repeat(np.arange(len(takes)), takes)


def design_series(
    rng: np.random.Generator, takes: tuple[int, ...], phi: float, sigma: float, count: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Squared errors of two rows sharing the frame's difficulty and the frame's squared reference norm.

    Returns
    -------
    error_a, error_b, reference : ndarray of shape (count, sum(takes))
        ``error_a / error_b`` has true ratio of means :data:`RATIO`; the per-frame ratio of alphas is the square
        root of the errors' ratio (the ratio interval is given ``sqrt`` of them as alphas).
    """
    shared, own = math.sqrt(SHARED), math.sqrt(1.0 - SHARED)
    difficulty = ar1_takes(rng, takes, phi, count)
    first = sigma * (shared * difficulty + own * ar1_takes(rng, takes, phi, count))
    second = sigma * (shared * difficulty + own * ar1_takes(rng, takes, phi, count))
    ref_shared = math.sqrt(REFERENCE_SHARED)
    ref_own = math.sqrt(1.0 - REFERENCE_SHARED)
    log_reference = REFERENCE_SIGMA * (ref_shared * difficulty + ref_own * ar1_takes(rng, takes, phi, count))
    return np.exp(first), np.exp(second) / RATIO, 100.0 * np.exp(log_reference)


def alphas(error: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per-frame alphas ``100 sqrt(e / r)`` of squared errors and squared reference norms."""
    return 100.0 * np.sqrt(error / reference)


def true_value(kind: str, sigma: float) -> float:
    """The true value of a statistic of :func:`design_series` at log-normal sigma ``sigma``: ``ratio`` (of mean
    alphas or of pooled alphas: 2), ``pooled`` (the difference of the pooled alphas) or ``mean`` (the difference
    of the mean alphas)."""
    if kind == "ratio":
        return math.sqrt(RATIO)
    if kind == "pooled":
        mean_error = math.exp(sigma**2 / 2.0)
        mean_reference = 100.0 * math.exp(REFERENCE_SIGMA**2 / 2.0)
        return 100.0 * math.sqrt(mean_error / mean_reference) * (1.0 - 1.0 / math.sqrt(RATIO))
    if kind == "mean":  # 100 E exp((s X - s_r Y) / 2) / 10 with corr(X, Y) = sqrt(SHARED * REFERENCE_SHARED)
        together = math.sqrt(SHARED * REFERENCE_SHARED)
        log_variance = sigma**2 + REFERENCE_SIGMA**2 - 2.0 * sigma * REFERENCE_SIGMA * together
        return 10.0 * math.exp(log_variance / 8.0) * (1.0 - 1.0 / math.sqrt(RATIO))
    raise ValueError(f"no true value for {kind!r}")
