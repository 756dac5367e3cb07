"""The rules a setting's value must meet, in one place: each a check and the words that state it.

A rule is a dict ``{"check": callable, "rule": text}``; a value that breaks it gives the one line every setting
gives, ``<key> must be <rule>, got <value>``. The study's schema (:mod:`workbench.settings.schema`) attaches rules to the
fields of its dataclasses and applies them when a config is composed; the loaders, which the Python API calls
without the schema, apply the same rules to the values they are given with :func:`checked` and the ``*_setting``
functions below, so that a rule is stated once and says the same words wherever it is broken. Values from Python
may be NumPy scalars; NumPy's booleans count as true/false, never as numbers.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import field
from typing import Any, Callable, Mapping

from workbench.core.errors import WorkbenchError

# ---------------------------------------------------------------------------------------------------------------
# Predicates and rules
# ---------------------------------------------------------------------------------------------------------------


def _boolean(value) -> bool:
    """True or false, Python's or NumPy's (without importing NumPy: ``workbench --help`` imports these rules)."""
    return isinstance(value, bool) or (type(value).__module__ == "numpy" and type(value).__name__ in ("bool_", "bool"))


def _number(value) -> bool:
    """A finite real number (not a boolean); NumPy's scalars are registered as ``numbers.Real``."""
    return isinstance(value, numbers.Real) and not _boolean(value) and math.isfinite(value)


def _integer(value, *, whole_floats: bool = False) -> bool:
    """A whole number (not a boolean); with ``whole_floats``, a float with no fraction counts too."""
    if _boolean(value):
        return False
    return isinstance(value, numbers.Integral) or (
        whole_floats and isinstance(value, numbers.Real) and math.isfinite(value) and float(value).is_integer()
    )


def rule(check: Callable[[Any], bool], text: str, *, optional: bool = False) -> dict:
    """A rule: ``check(value)`` must hold (null is allowed with ``optional``), stated by ``text``."""
    return {
        "check": (lambda value: value is None or check(value)) if optional else check,
        "rule": text + (" or null" if optional else ""),
    }


def interval(
    low: float | None = None,
    high: float | None = None,
    *,
    low_open: bool = False,
    high_open: bool = False,
    optional: bool = False,
) -> dict:
    """A finite number in an interval (either end open or absent)."""

    def check(value):
        return (
            _number(value)
            and (low is None or (value > low if low_open else value >= low))
            and (high is None or (value < high if high_open else value <= high))
        )

    if low is not None and high is not None:
        text = f"in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
    elif low is not None:
        text = f"a finite number {'>' if low_open else '>='} {low:g}"
    else:
        text = "a finite number"
    return rule(check, text, optional=optional)


def integer(low: int, high: int | None = None, *, optional: bool = False, whole_floats: bool = False) -> dict:
    """A whole number ``>= low`` (and ``<= high``); with ``whole_floats``, ``2.0`` counts as 2 (values computed in
    Python; a composed config's integers are ints)."""
    text = f"an integer >= {low}" if high is None else f"an integer in [{low}, {high}]"
    return rule(
        lambda value: _integer(value, whole_floats=whole_floats) and value >= low and (high is None or value <= high),
        text,
        optional=optional,
    )


def one_of(*choices: str) -> dict:
    """One of ``choices``."""
    return rule(lambda value: isinstance(value, str) and value in choices, f"one of {choices}")


def key_of(table: Mapping) -> dict:
    """One of the keys of ``table``, as it holds them when a value is checked (a table that can grow: the solver
    kinds, :data:`workbench.core.solvers.SOLVER_KINDS`); stated as :func:`one_of` states its choices."""
    return {"check": lambda value: isinstance(value, str) and value in table, "rule": lambda: f"one of {tuple(table)}"}


BOOLEAN = rule(_boolean, "true or false")
"""A true/false setting: ``maybe``, 1 or ``"true"`` is not taken as true."""
SEED = rule(lambda value: _integer(value) and value >= 0, "a non-negative integer")
"""A seed of a ``numpy.random.Generator``."""
POSITIVE = rule(lambda value: _number(value) and value > 0, "a positive, finite number")
"""A scale, a rate or a unit."""
GAP_POLICIES = ("drop", "linear", "masked")
"""``dataset.gap_policy``: how missing marker samples are handled (``workbench.dataset.gaps``)."""
GAP_FIT_ON = ("complete", "filled")
"""``dataset.gap_fit_on``: which frames the bases are fitted on under the ``masked`` gap policy."""
COVERAGE_ON = ("training", "clean")
"""``basis.coverage_on``: where the coverage rule chooses m (the training frames, or the clean capture)."""
RBF_METRICS = ("euclidean", "geodesic")
"""``dataset.rbf.metric``: the distance the marker-to-mesh interpolation uses."""
RBF_KERNELS = (
    "cubic",
    "gaussian",
    "inverse_multiquadric",
    "inverse_quadratic",
    "linear",
    "multiquadric",
    "quintic",
    "thin_plate_spline",
)
"""``dataset.rbf.kernel``: SciPy ``RBFInterpolator``'s kernels (:data:`workbench.dataset.rbf.KERNELS`)."""
RBF_SCALE_INVARIANT = ("linear", "thin_plate_spline", "cubic", "quintic")
"""The kernels of :data:`RBF_KERNELS` that need no shape parameter (``dataset.rbf.epsilon``)."""


# ---------------------------------------------------------------------------------------------------------------
# Applying a rule to one value
# ---------------------------------------------------------------------------------------------------------------


def checked(value, key: str, spec: dict):
    """``value`` if it meets the rule ``spec``, else a :class:`WorkbenchError` naming ``key`` and the rule.

    Parameters
    ----------
    value
        The configured value.
    key : str
        Its config key for the message, e.g. ``"dataset.frame_step"``.
    spec : dict
        A rule (:func:`rule`, :func:`interval`, :func:`integer`, :func:`one_of`, ...); its words may be a callable
        that states them when called (:func:`key_of`).
    """
    if not spec["check"](value):
        words = spec["rule"]() if callable(spec["rule"]) else spec["rule"]
        raise WorkbenchError(f"{key} must be {words}, got {value!r}")
    return value


def integer_setting(value, key: str, *, minimum: int) -> int:
    """A whole-number setting (an int, or a float with no fraction) ``>= minimum``, as an int."""
    return int(checked(value, key, integer(minimum, whole_floats=True)))


def bool_setting(value, key: str) -> bool:
    """A true/false setting as a bool (:data:`BOOLEAN`)."""
    return bool(checked(value, key, BOOLEAN))


def seed_setting(value, key: str) -> int:
    """A seed setting as an int (:data:`SEED`)."""
    return int(checked(value, key, SEED))


def positive_setting(value, key: str) -> float:
    """A positive, finite number setting as a float (:data:`POSITIVE`)."""
    return float(checked(value, key, POSITIVE))


def number_setting(value, key: str, text: str, check: Callable[[float], bool]) -> float:
    """A finite number setting as a float if ``check(value)`` holds, the rule stated by ``text``."""
    return float(checked(value, key, rule(lambda number: _number(number) and check(float(number)), text)))


def meta(default, check: dict) -> Any:
    """A dataclass field with a default (or ``MISSING``) and its rule."""
    if isinstance(default, (list, dict)):
        return field(default_factory=lambda: type(default)(default), metadata=check)
    return field(default=default, metadata=check)
