"""Holm's step-down adjustment of a family of p-values (Holm 1979) and the confidence of each member's step: arrays
in, arrays out (:func:`workbench.stats.statistics.holm_intervals` turns them into intervals)."""

from __future__ import annotations

import math

import numpy as np


def _ascending(p_values) -> tuple[np.ndarray, np.ndarray]:
    """The p-values as a flat float array, and the indices of its finite ones from smallest to largest (ties in
    input order): the order both Holm's adjustment and its step levels walk."""
    values = np.asarray(p_values, dtype=float).ravel()
    finite = np.flatnonzero(np.isfinite(values))
    return values, finite[np.argsort(values[finite], kind="stable")]


def holm(p_values) -> np.ndarray:
    """Holm's step-down adjustment of p-values for multiple comparisons (Holm 1979): with the ``m`` finite
    p-values sorted, ``p_(k)`` becomes ``max_{j <= k} min(1, (m - j + 1) p_(j))``; an adjusted p-value below
    ``1 - confidence`` rejects its null with the family-wise error rate held at that level.

    Parameters
    ----------
    p_values : array_like of shape (m,)
        NaN for a comparison without a p-value (left out of ``m``, NaN in the result).

    Returns
    -------
    ndarray of shape (m,)
        In the input order.
    """
    values, order = _ascending(p_values)
    adjusted = np.full(values.shape, math.nan)
    steps = (len(order) - np.arange(len(order))) * values[order]
    adjusted[order] = np.minimum(np.maximum.accumulate(steps), 1.0)
    return adjusted


def holm_levels(p_values, confidence: float = 0.95) -> np.ndarray:
    """The confidence of each member's Holm step: with the ``k`` finite p-values sorted and ``j`` the first step
    that fails (``p_(j) >= alpha / (k - j + 1)``, ``alpha = 1 - confidence``; ``k + 1`` when none fails), the member
    of rank ``i`` gets ``1 - alpha / (k - min(i, j) + 1)``. A t interval at that confidence excludes the null value
    exactly when the member's Holm-adjusted p-value is below ``alpha``.

    Parameters
    ----------
    p_values : array_like of shape (m,)
        NaN for a member without a p-value (NaN in the result, left out of ``k``).
    confidence : float

    Returns
    -------
    ndarray of shape (m,)
        In the input order.
    """
    values, order = _ascending(p_values)
    levels = np.full(values.shape, math.nan)
    alpha, k = 1.0 - confidence, len(order)
    thresholds = alpha / (k - np.arange(k))  # step i (0-based) rejects when p_(i) < alpha / (k - i)
    failed = np.flatnonzero(values[order] >= thresholds)
    first = int(failed[0]) if failed.size else k
    levels[order] = 1.0 - alpha / (k - np.minimum(np.arange(k), first))
    return levels
