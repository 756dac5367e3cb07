"""The kinds of solve of eq. 5 a study's solvers take (``solver.<name>.kind``): one table, one entry each.

An entry says what the settings, the solve and the report need of a kind: the bounds it takes from a solver's
settings or fixes itself, how the findings name a solver of the kind from the bounds it had, and how the figures
draw it. The table sits below both the settings and the numerics, which are siblings, so that both read it; each
kind's solve is registered under the same kind beside the solving code (:data:`workbench.numerics.solve.SOLVES`).
A new kind is its solve and one entry here (and, to choose it as ``solver=<kind>``, a file in ``conf/solver``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

BOUNDS = ("lower", "upper")
"""The settings of a solver besides its kind: ``solver.<name>.lower`` and ``solver.<name>.upper``."""


@dataclass(frozen=True)
class SolverKind:
    """One kind of solve of eq. 5.

    Attributes
    ----------
    options : tuple of str
        The bounds (of :data:`BOUNDS`) the kind takes from a solver's settings, at least one of them set; empty
        for a kind whose bounds are its own.
    lower, upper : float or None
        The bounds of a kind that fixes them (None: that side open; the solve accepts a setting equal to them), or
        the defaults of those it takes (``conf/solver/<kind>.yaml``, and the findings of a run without settings).
    description : str
        How the findings name a solver of the kind: formatted with its bounds, ``{lower}`` and ``{upper}``
        (``:g``; an open side ``-inf`` or ``inf``), e.g. ``box [{lower}, {upper}] weights``.
    line_style : str
        The Matplotlib line style of its curves.
    hatch : str
        The Matplotlib hatch of its bars (line hatches: a dotted one is 70 kB of SVG per colour).
    """

    options: tuple[str, ...]
    lower: float | None
    upper: float | None
    description: str
    line_style: str
    hatch: str

    @property
    def constrained(self) -> bool:
        """Whether the kind bounds the weights (least squares does not)."""
        return bool(self.options) or self.lower is not None or self.upper is not None

    def bounds(self, lower: float | None = None, upper: float | None = None) -> tuple[float | None, float | None]:
        """The bounds a solver of this kind applies, given its settings (its own for a kind that fixes them)."""
        return (lower if "lower" in self.options else self.lower), (upper if "upper" in self.options else self.upper)

    def describe(self, lower: float | None = None, upper: float | None = None) -> str:
        """:attr:`description` with the bounds a solver of this kind applies, given its settings."""
        low, high = self.bounds(lower, upper)
        return self.description.format(
            lower=f"{-math.inf if low is None else low:g}", upper=f"{math.inf if high is None else high:g}"
        )


SOLVER_KINDS: dict[str, SolverKind] = {
    "lstsq": SolverKind((), None, None, "least squares", line_style="-", hatch=""),
    "nnls": SolverKind((), 0.0, None, "non-negative weights", line_style="--", hatch="//"),
    "box": SolverKind(BOUNDS, 0.0, 1.0, "box [{lower}, {upper}] weights", line_style=":", hatch="xx"),
}
"""Kind -> :class:`SolverKind`, in the order the settings, the findings and the figures list them."""


def solver_kind(name: str, settings: Mapping | None = None) -> tuple[str | None, SolverKind | None]:
    """The kind of the solver ``name`` and its entry: as the run's solver settings say (``solver.<name>.kind``),
    else ``name`` itself when it is a kind (the solvers of ``conf/solver`` are named by their kind); None, None
    for neither."""
    kind = ((settings or {}).get(name) or {}).get("kind", name)
    return kind, SOLVER_KINDS.get(kind)


def solver_text(name: str, settings: Mapping | None = None) -> str:
    """How the findings name the solver ``name``: its kind's description with the bounds the run's solver settings
    (``solver``) gave it, the kind's defaults without them, or the name itself for a solver of no known kind."""
    _, entry = solver_kind(name, settings)
    if entry is None:
        return name
    given = (settings or {}).get(name) or {}
    if not given:
        return entry.describe(entry.lower, entry.upper)
    return entry.describe(given.get("lower"), given.get("upper"))


def constrained_solvers(names, settings: Mapping | None = None) -> list[str]:
    """The solvers among ``names`` whose kind bounds the weights (:func:`solver_kind`), in the table's order of
    their kinds (non-negative weights before a box), then as given."""
    order = list(SOLVER_KINDS)
    kinds = {name: solver_kind(name, settings) for name in names}
    bounded = [name for name, (_, entry) in kinds.items() if entry is not None and entry.constrained]
    return sorted(bounded, key=lambda name: order.index(kinds[name][0]))


def solver_line_style(name: str, settings: Mapping | None = None) -> str:
    """The line style of the solver ``name``'s curves (:func:`solver_kind`); ``-.`` for a solver of no known kind."""
    entry = solver_kind(name, settings)[1]
    return "-." if entry is None else entry.line_style


def solver_hatch(name: str, settings: Mapping | None = None) -> str:
    """The hatch of the solver ``name``'s bars (:func:`solver_kind`); none for a solver of no known kind."""
    entry = solver_kind(name, settings)[1]
    return "" if entry is None else entry.hatch
