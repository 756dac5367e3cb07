"""Within one run: the per-frame error in millimetres as a distribution, and what the weights look like.

Both read what the run record keeps (``metrics.json``: each row's error quantiles and weight statistics); nothing
is recomputed.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter

from workbench.core.solvers import solver_line_style
from workbench.reporting.figures import basis_colour, new_figure, shown_as_pixels, wrap_title, wrap_to_width

WEIGHT_PANELS = (
    ("max_abs", "largest |w|", True),
    ("outside_unit_share", "frames with a weight outside [0, 1]", False),
    ("sparsity", "Hoyer sparsity (1: one shape per frame)", False),
    ("roughness", "roughness: mean (d^2 w / dt^2)^2, 1/s^4", True),
)
PANEL_WIDTH = 6.2
"""Inches of figure width per panel of the error curves."""
PANEL_TEXT_WIDTH = 5.0
"""Inches a panel's subtitle may take: its axes' width (the panel less its axis labels), so that two panels'
subtitles never run into each other nor past the figure's edge."""
CDF_LEGEND_TITLE = (
    "basis (colour) and solver (solid: least squares, PCA by projection; dashed: non-negative; "
    "dotted: box [0, 1])\ngrey lines: median and 95th percentile"
)


def minor_tick_text(value: float, _position=None) -> str:
    """A log axis's minor tick label: only at 2 and 5 times a power of ten (``0.2``, ``0.05``), the others bare."""
    if value <= 0:
        return ""
    mantissa = value / 10 ** math.floor(math.log10(value) + 1e-9)
    return f"{value:g}" if min(abs(mantissa - 2), abs(mantissa - 5)) < 1e-6 else ""


def plot_error_cdf(
    curves: Mapping[str, Mapping[tuple, np.ndarray]],
    probabilities: np.ndarray,
    *,
    title: str,
    regions: Mapping[str, str] | None = None,
    settings: Mapping | None = None,
) -> Figure:
    """Cumulative per-frame error curves: for each error in millimetres, the share of frames reconstructed at least
    that well; one panel per data variant, one line per basis (colour) and solver (line style).

    Parameters
    ----------
    curves : mapping
        Data variant -> ((basis, solver) -> error quantiles in mm, ndarray of shape (n_probabilities,)).
    probabilities : ndarray of shape (n_probabilities,)
        The probabilities of the quantiles (0 to 1).
    title : str
    regions : mapping, optional
        Data variant -> the face region the errors are taken over (shown under each panel's title).
    settings : mapping, optional
        The run's ``solver`` settings: each solver's kind, whose line style draws it (its name's kind without).

    Returns
    -------
    matplotlib.figure.Figure
    """
    variants = [data for data, lines in curves.items() if lines]
    if not variants:
        raise ValueError("plot_error_cdf needs at least one data variant with error quantiles")
    columns = min(len(variants), 2)
    rows = math.ceil(len(variants) / columns)
    width = PANEL_WIDTH * columns
    figure = new_figure(width, 3.9 * rows + 0.6)
    axes = figure.subplots(rows, columns, squeeze=False).ravel()
    for ax, data in zip(axes, variants):
        for (basis, solver), quantiles in curves[data].items():
            # every second recorded quantile (steps of 2 % of the frames, both ends kept): the same smooth curve in
            # half the points, and half the file
            shown = np.unique(np.r_[np.arange(0, len(probabilities), 2), len(probabilities) - 1])
            ax.plot(
                quantiles[shown],
                probabilities[shown],
                color=basis_colour(basis),
                linestyle="-" if solver == "projection" else solver_line_style(solver, settings),
                linewidth=1.4,
                label=f"{basis} {solver}" if solver != "projection" else basis,
            )
        ax.set_xscale("log")
        # plain millimetres (0.1, 0.2, 0.5), not 2 x 10^-1 labels on every minor tick that run into each other
        ax.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
        ax.xaxis.set_minor_formatter(FuncFormatter(minor_tick_text))
        ax.set_xlabel("per-frame RMS error over the face region (mm, log scale)", fontsize=9)
        ax.set_ylabel("share of frames with at most this error", fontsize=9)
        ax.set_ylim(0.0, 1.0)
        ax.axhline(0.5, color="#999999", linewidth=0.6)
        ax.axhline(0.95, color="#999999", linewidth=0.6, linestyle="--")
        region = (regions or {}).get(data)
        subtitle = f"data: {data}" + (f"\n{region}" if region else "")
        ax.set_title(wrap_to_width(subtitle, PANEL_TEXT_WIDTH, 9), fontsize=9, loc="left")
        ax.grid(alpha=0.3, which="both")
    for ax in axes[len(variants) :]:
        ax.set_visible(False)
    handles, labels = axes[0].get_legend_handles_labels()
    # the title on lines no wider than one panel, so that it is whole however narrow the figure is shown
    figure.legend(
        handles,
        labels,
        loc="outside lower center",
        ncols=min(len(labels), 5),
        fontsize=8,
        frameon=False,
        title=wrap_to_width(CDF_LEGEND_TITLE, PANEL_TEXT_WIDTH, 8),
        title_fontsize=8,
    )
    figure.suptitle(wrap_title(title, width), fontsize=10)
    return figure


def bar_text(value: float) -> str:
    """A bar's label: two significant digits, an exponent without its plus sign and leading zero (``9.1e4``), no
    label for a missing value."""
    if not math.isfinite(value):
        return ""
    text = f"{value:.2g}"
    mantissa, _, exponent = text.partition("e")
    return f"{mantissa}e{int(exponent)}" if exponent else text


def name_bases(ax, bases: Sequence[str], minimum_norm: Mapping[str, str], note: bool) -> None:
    """A panel's basis names, ``*`` on those whose least-squares weights are minimum-norm, and (``note``) under it
    a line per such basis with its rank: narrower than the panel, which the layout would otherwise widen."""
    ax.set_xticks(np.arange(len(bases)), [f"{b}*" if b in minimum_norm else b for b in bases], fontsize=8)
    if minimum_norm and note:
        ax.annotate(
            "\n".join(["* lstsq weights:", *(f"{b} {text}" for b, text in minimum_norm.items())]),
            (0.0, 0.0),
            xycoords="axes fraction",
            xytext=(0, -22),
            textcoords="offset points",
            ha="left",
            va="top",
            fontsize=7.5,
        )


def plot_weight_statistics(
    statistics: Mapping[str, Mapping[tuple, Mapping[str, float]]],
    *,
    title: str,
    minimum_norm: Mapping[str, Mapping[str, str]] | None = None,
) -> Figure:
    """The weights an animator would get: largest |w|, share of frames outside [0, 1], sparsity and roughness of
    each basis under each solver; one row of four panels per data variant, bars grouped by basis, one bar per
    solver.

    Parameters
    ----------
    statistics : mapping
        Data variant -> ((basis, solver) -> the weight statistics, ``max_abs``, ``outside_unit_share``,
        ``sparsity``, ``roughness``).
    title : str
    minimum_norm : mapping, optional
        Data variant -> (basis -> ``minimum-norm, rank r of n``) for the bases whose least-squares weights are
        the minimum-norm choice of a rank-deficient basis: their names get a ``*`` and the row a note saying so.

    Returns
    -------
    matplotlib.figure.Figure
    """
    variants = [data for data, values in statistics.items() if values]
    if not variants:
        raise ValueError("plot_weight_statistics needs at least one data variant with weight statistics")
    width = 15.0
    figure = new_figure(width, 2.9 * len(variants) + 0.9)
    axes = figure.subplots(len(variants), len(WEIGHT_PANELS), squeeze=False)
    for row, data in zip(axes, variants):
        keys = list(statistics[data])
        bases = list(dict.fromkeys(basis for basis, _ in keys))
        solvers = list(dict.fromkeys(solver for _, solver in keys))
        step = 0.8 / len(solvers)
        for ax, (field, label, log) in zip(row, WEIGHT_PANELS):
            values = {
                solver: [statistics[data].get((basis, solver), {}).get(field, math.nan) for basis in bases]
                for solver in solvers
            }
            # a panel's labels upright where one is wider than a bar (9.1e4 beside 9.1e4 would print over each other)
            upright = max(len(bar_text(value)) for shown in values.values() for value in shown) > 4
            for k, solver in enumerate(solvers):
                positions = np.arange(len(bases)) + (k - (len(solvers) - 1) / 2) * step
                bars = ax.bar(
                    positions,
                    values[solver],
                    width=step * 0.92,
                    color=[basis_colour(b) for b in bases],
                    alpha=1.0 - 0.3 * k,
                    edgecolor="#333333",
                    linewidth=0.4,
                    label=solver,
                )
                ax.bar_label(
                    bars,
                    labels=[bar_text(value) for value in values[solver]],
                    fontsize=6,
                    padding=1,
                    rotation=90 if upright else 0,
                )
            if log:
                ax.set_yscale("log")
            if field == "max_abs":
                ax.axhline(1.0, color="#444444", linewidth=0.8, linestyle=":")
            name_bases(ax, bases, (minimum_norm or {}).get(data) or {}, note=field == WEIGHT_PANELS[0][0])
            if data == variants[0]:
                ax.set_title(label, fontsize=8.5, loc="left")
            if field == WEIGHT_PANELS[0][0]:
                ax.set_ylabel(f"data: {data}", fontsize=9)
            ax.grid(axis="y", alpha=0.3, which="both")
            ax.margins(y=0.18)
            # room above the highest bar for its label, more for upright ones (on a log axis, a share of its decades)
            room = 0.25 if upright else 0.12
            low, high = ax.get_ylim()
            ax.set_ylim(low, high * (high / low) ** room if log else high + room * (high - low))
    handles, labels = axes[0, 0].get_legend_handles_labels()
    figure.legend(
        handles,
        labels,
        loc="outside lower center",
        ncols=len(labels),
        fontsize=8,
        frameon=False,
        title="solver (left to right in each group, lighter each); dotted line: |w| = 1",
        title_fontsize=8,
    )
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return shown_as_pixels(figure)
