"""Comparisons as a record stores them (``a``, ``b`` and the fields of an :class:`~workbench.stats.statistics.Interval`
each): Holm's adjustment over a run's family (:func:`holm_adjusted`) and the interval of any ordered pair
(:func:`comparison_lookup`)."""

from __future__ import annotations

import math
from typing import Callable, Mapping, Sequence

from workbench.stats.multiplicity import holm
from workbench.stats.statistics import Interval, holm_intervals, reversed_interval


def holm_adjusted(comparisons: Mapping[str, Sequence[Mapping]], primary: Callable[[str, Mapping], bool]) -> dict:
    """Stored comparisons with Holm's adjustment over the family of the non-primary ones.

    Parameters
    ----------
    comparisons : mapping
        Data variant -> its stored comparisons (``a``, ``b`` and :class:`Interval` fields, ``p_value`` among them).
    primary : callable
        ``primary(data, entry)``: whether a comparison is a primary contrast (stated at its own confidence).

    Returns
    -------
    dict
        The same entries (copies), each non-primary one with ``p_adjusted`` (NaN where it had no p-value),
        ``holm_family`` (the family's size) and, for a t interval, ``adjusted_low``, ``adjusted_high`` and
        ``adjusted_confidence`` (:func:`holm_intervals`); the family is every non-primary comparison of every data
        variant.
    """
    adjusted = {data: [dict(entry) for entry in entries] for data, entries in comparisons.items()}
    family = [entry for data, entries in adjusted.items() for entry in entries if not primary(data, entry)]
    for entry, value in zip(family, holm([entry.get("p_value", math.nan) for entry in family])):
        entry["p_adjusted"], entry["holm_family"] = float(value), len(family)
    complete = [entry for entry in family if {"estimate", "low", "high"} <= entry.keys()]
    for entry, interval in zip(complete, holm_intervals([Interval.from_dict(entry) for entry in complete])):
        entry.update(
            adjusted_low=interval.adjusted_low,
            adjusted_high=interval.adjusted_high,
            adjusted_confidence=interval.adjusted_confidence,
        )
    return adjusted


def comparison_lookup(comparisons: Sequence[Mapping]) -> Callable[[tuple, tuple], Interval | None]:
    """``compare(a, b)`` over stored comparisons (``a``, ``b`` and :class:`Interval` fields each): the interval of
    ``a`` against ``b``, the stored one of ``b`` against ``a`` reversed (:func:`reversed_interval`), or None."""
    stored = {(tuple(entry["a"]), tuple(entry["b"])): Interval.from_dict(entry) for entry in comparisons}

    def compare(a, b) -> Interval | None:
        a, b = tuple(a), tuple(b)
        if (a, b) in stored:
            return stored[a, b]
        if (b, a) in stored:
            return reversed_interval(stored[b, a])
        return None

    return compare
