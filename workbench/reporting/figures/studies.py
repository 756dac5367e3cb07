"""Plots of the studies: coverage curve, alpha against a swept setting, marker versus mesh, alpha over time.

The sweep plots read one tidy table (a :class:`pandas.DataFrame`, one row per swept value x data variant x
basis x solver), the schema ``workbench collect`` and :func:`workbench.reporting.tables.runs.summarise` produce:

========================  ====================================================================================
column                    meaning
========================  ====================================================================================
``data``                  data variant (``markers``, ``mesh``, ...)
``basis``                 ``H``, ``QE``, ``QE-linear``, ``PCA``
``solver``                ``lstsq``, ``nnls``, ``box``; ``projection`` for PCA
``<x>``                   the swept setting, named by its config key (``basis.coverage``,
                          ``dataset.marker_noise_mm``, ...) or a table column (``m``, ``n_hand``); numeric,
                          or text (categories, drawn in order of appearance)
``<y>``                   an alpha column of the alpha table (``alpha_abs_mean``, ...), the mean over seeds
``<y>_ci_low/_ci_high``   95 % interval of that estimate over seeds (or plain ``ci_low``/``ci_high``,
                          which then belong to ``<y>``); optional, no band when absent or NaN; never below
                          zero (alpha and errors are positive: a table whose interval reaches below zero is
                          refused, see :mod:`workbench.stats.statistics`)
``n_seeds``               runs behind the estimate; optional, named beside the intervals
``ci_method``             how the intervals were computed; optional, named beside them
========================  ====================================================================================
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from workbench.core.errors import WorkbenchError
from workbench.core.solvers import solver_hatch
from workbench.reporting.figures import (
    DATA_COLOURS,
    basis_colour,
    basis_label,
    fixed_decimals,
    new_figure,
    replicates_legend,
    wrap_title,
)
from workbench.reporting.tables.runs import interval_label
from workbench.study.regime import PAPER_REGIME_SUFFIX

BASIS_ORDER = ("H", "QE", "QE-linear", "PCA")
AXIS_LABELS = {
    "alpha_abs_mean": "alpha, absolute, mean of frames (%)",
    "alpha_abs_pooled": "alpha, absolute, pooled (%)",
    "alpha_disp_mean": "alpha, displacement, mean of frames (%)",
    "alpha_disp_pooled": "alpha, displacement, pooled (%)",
    "rms_mm": "RMS point error (mm)",
    "m": "eigenfaces m",
    "n": "basis size n",
    "n_hand": "hand shapes in the basis",
    "basis.hand_subset": "hand shapes kept",
    "basis.coverage": "coverage threshold",
    "basis.n_components": "eigenfaces m (fixed)",
    "dataset.marker_noise_mm": "marker noise (mm per coordinate)",
    "dataset.n_frames": "frames in the capture",
}


def axis_label(column: str) -> str:
    if column.startswith("clean_") and column.removeprefix("clean_") in AXIS_LABELS:
        return f"{AXIS_LABELS[column.removeprefix('clean_')]}\nagainst the clean frames"
    return AXIS_LABELS.get(column, column)


def ci_columns(table: pd.DataFrame, y: str) -> tuple[str, str] | None:
    """The confidence-interval columns of ``y`` in a tidy table, or None when it has none."""
    for low, high in ((f"{y}_ci_low", f"{y}_ci_high"), ("ci_low", "ci_high")):
        if low in table.columns and high in table.columns:
            return low, high
    return None


def check_positive_intervals(table: pd.DataFrame, y: str, ci: tuple[str, str] | None) -> None:
    """Refuse intervals of a positive quantity that reach below zero (a Student-t interval over a few seeds)."""
    if ci is None:
        return
    low = pd.to_numeric(table[ci[0]], errors="coerce")
    if (low < 0).any():
        raise WorkbenchError(
            f"the interval of {y} reaches below zero ({low.min():.3g}); {y} cannot be negative: "
            "use a geometric interval (workbench.stats.statistics.geometric_interval)"
        )


def check_columns(table: pd.DataFrame, columns) -> None:
    """Refuse a table that lacks any of ``columns``, naming them and the columns it has."""
    missing = [column for column in columns if column not in table.columns]
    if missing:
        raise WorkbenchError(f"the table has no column(s) {missing}; it has {list(table.columns)}")


def _solver_rows(table: pd.DataFrame, solver: str) -> pd.DataFrame:
    """Rows of one solver plus the PCA rows (PCA reconstructs by projection, without a solver)."""
    return table[(table["solver"] == solver) | (table["basis"] == "PCA")]


def ordered_bases(bases) -> list[str]:
    """The bases present, the paper's in their order (:data:`BASIS_ORDER`) first, then the others as they come."""
    present = list(dict.fromkeys(bases))
    return [b for b in BASIS_ORDER if b in present] + [b for b in present if b not in BASIS_ORDER]


def plot_coverage_curve(
    ratios: Mapping[str, np.ndarray],
    chosen_m: Mapping[str, int],
    *,
    threshold: float | None,
    title: str,
    paper_m: int | None = None,
    basis_size: int | None = None,
) -> Figure:
    """Cumulative explained variance against m, the coverage threshold and the chosen m, per data variant.

    Left: the cumulative explained variance near the chosen m. Right: the variance left out,
    ``1 - cumulative``, on a log scale over every recorded eigenvalue, where the threshold ``1 - coverage``
    and the noise floor are readable.

    Parameters
    ----------
    ratios : mapping
        Data variant -> ndarray of shape (k,), explained-variance ratios of the leading eigenvalues, descending.
    chosen_m : mapping
        Data variant -> the m the run kept.
    threshold : float or None
        The coverage threshold (None when m was fixed).
    title : str
    paper_m : int, optional
        The paper's m (18), marked by a vertical line.
    basis_size : int, optional
        The hand basis size n, marked by a vertical line: with m > n the quasi-eigen faces cannot span the
        eigenfaces.

    Returns
    -------
    matplotlib.figure.Figure
    """
    width = 10.0
    figure = new_figure(width, 4.4)
    near, tail = figure.subplots(1, 2)
    zoom = max(3 * max(chosen_m.values()), 12)
    for k, (data, ratio) in enumerate(ratios.items()):
        cumulative = np.cumsum(np.asarray(ratio, dtype=float))
        m_values = np.arange(1, len(cumulative) + 1)
        colour = DATA_COLOURS.get(data, f"C{k}")
        m = chosen_m[data]
        label = f"{data}: m = {m}" + (f", {cumulative[m - 1]:.4f}" if m <= len(cumulative) else "")
        near.plot(m_values[:zoom], cumulative[:zoom], marker="o", markersize=3, color=colour, label=label)
        left_out = np.clip(1.0 - cumulative, 1e-12, None)
        tail.semilogy(m_values, left_out, marker="o", markersize=2, color=colour, label=data)
        if m <= len(cumulative):
            near.plot([m], [cumulative[m - 1]], marker="o", markersize=11, markerfacecolor="none", color=colour)
            tail.plot([m], [left_out[m - 1]], marker="o", markersize=11, markerfacecolor="none", color=colour)
    marks = [(paper_m, "paper: m = {}", "#b8860b", ":"), (basis_size, "hand shapes n = {}", "0.45", "-.")]
    if paper_m is not None and paper_m == basis_size:  # one line, one label: two would hide each other
        marks = [(paper_m, "paper: m = {0}; hand shapes n = {0}", "#b8860b", "-.")]
    for value, text, colour, style in marks:
        if value is None:
            continue
        for ax in (near, tail):
            if ax is tail or value <= zoom:
                ax.axvline(
                    value,
                    color=colour,
                    linestyle=style,
                    linewidth=1.4,
                    label=text.format(value) if ax is near or value > zoom else None,
                )
    if threshold is not None:
        near.axhline(threshold, color="0.2", linestyle="--", linewidth=1, label=f"threshold {threshold}")
        tail.axhline(
            1.0 - threshold, color="0.2", linestyle="--", linewidth=1, label=f"1 - threshold = {1.0 - threshold:.3g}"
        )
    near.set_xlabel("eigenfaces m")
    near.set_ylabel("cumulative explained variance")
    near.set_title("near the chosen m (circled)", fontsize=10)
    tail.set_xlabel("eigenfaces m")
    tail.set_ylabel("variance left out (1 - cumulative)")
    tail.set_title(f"every recorded eigenvalue (first {max(len(r) for r in ratios.values())})", fontsize=10)
    for ax in (near, tail):
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right" if ax is near else "upper right", fontsize=9)
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return figure


LINE_STYLES = ("-", "--", ":", "-.")
MAX_PANEL_COLUMNS = 3
MARKERS = ("o", "s", "^", "D", "v", "P")


def plot_alpha_against(
    table: pd.DataFrame,
    x: str,
    y: str = "alpha_abs_mean",
    *,
    solver: str = "lstsq",
    title: str,
    by: Sequence[str] = (),
    log_x: bool = False,
    points: pd.DataFrame | None = None,
    panels: Sequence[str] = ("data",),
    not_replicates: str = "",
) -> Figure:
    """Alpha against a swept setting, one line per basis and one panel per data variant, with the 95 % interval
    over seeds as a band where the table has one (its method and n in the title) and every seed's own value as a
    small point; where the runs are not replicates, the legend says so.

    Parameters
    ----------
    table : pandas.DataFrame
        A tidy table (module docstring) with columns ``data``, ``basis``, ``solver``, ``x``, ``y``.
    x : str
        Column of the swept setting; a text or boolean column is drawn as categories.
    y : str
        Alpha column.
    solver : str
        Rows of this solver are drawn (and PCA's).
    title : str
    by : sequence of str
        Other swept settings of a grid: each combination of their values gets its own line per basis (line style
        and marker), so that lines never join points of different settings.
    log_x : bool
        Logarithmic x axis.
    points : pandas.DataFrame, optional
        One row per run and table row (columns as ``table``): every seed's value, drawn as small points.
    panels : sequence of str
        Columns whose combinations get a panel each (default: the data variant).
    not_replicates : str
        Why the seeds are not replicates (:func:`workbench.reporting.tables.runs.not_replicates_reason`), said in
        the legend; empty when they are.

    Returns
    -------
    matplotlib.figure.Figure
    """
    panels = list(panels)
    check_columns(table, ["data", "basis", "solver", x, y, *by, *panels])
    rows = _solver_rows(table, solver)
    if rows.empty:
        raise WorkbenchError(f"the table has no rows for solver {solver!r}")
    ci = ci_columns(rows, y)
    check_positive_intervals(rows, y, ci)
    panel_values = list(dict.fromkeys(rows[panels].astype(str).itertuples(index=False, name=None)))
    n_cols = min(len(panel_values), MAX_PANEL_COLUMNS)
    n_rows = -(-len(panel_values) // n_cols)
    width = max(4.6 * n_cols + 0.8, 8.0 if by else 0.0)
    figure = new_figure(width, 3.9 * n_rows + 0.7 + 0.25 * len(by))
    grid = figure.subplots(n_rows, n_cols, squeeze=False, sharey=True)
    axes = grid.ravel()[: len(panel_values)]
    for unused in grid.ravel()[len(panel_values) :]:
        unused.set_visible(False)
    rows, seeds, categories = _positions(rows, points, x, solver)
    groups = list(rows.groupby(list(by), sort=False, dropna=False)) if by else [((), rows)]

    def in_panel(frame: pd.DataFrame, panel: tuple) -> pd.Series:
        return (frame[panels].astype(str) == pd.Series(panel, index=panels)).all(axis=1)

    for ax, panel in zip(axes, panel_values):
        span = float(np.ptp(rows[x].to_numpy(dtype=float))) or 1.0
        for k, (values, group) in enumerate(groups):
            values = values if isinstance(values, tuple) else (values,)
            setting = ", ".join(f"{key.split('.')[-1]}={value}" for key, value in zip(by, values))
            part = group[in_panel(group, panel)]
            for b, basis in enumerate(ordered_bases(part["basis"])):
                line = part[part["basis"] == basis].sort_values(x, kind="stable")
                label = f"{basis} ({setting})" if setting else basis_label(basis)
                mine = None
                if seeds is not None:
                    mine = seeds[in_panel(seeds, panel) & (seeds["basis"] == basis)]
                    for key, value in zip(by, values):
                        mine = mine[mine[key].astype(str) == str(value)]
                _draw_basis(ax, line, x, y, ci, basis_colour(basis), label, k, span * 0.012 * (b - 1.5 + 4 * k), mine)
        _label_panel(ax, x, categories, panels, panel, log_x)
    for row in grid:
        row[0].set_ylabel(axis_label(y))
    drawn = ci is not None and rows[list(ci)].notna().any(axis=None)
    band = f" ({interval_label(rows)}" + ("; points: each seed)" if points is not None else ")") if drawn else ""
    handles, labels = axes[-1].get_legend_handles_labels()
    # As many legend columns as the longest label leaves room for (about 5 points per character at size 8).
    columns = max(1, min(4, int(width * 72 / (5.0 * max(len(label) for label in labels) + 40))))
    replicates_legend(figure, handles, labels, not_replicates, width, ncols=columns, fontsize=8)
    figure.suptitle(wrap_title(f"{title}\nsolver {solver}{band}", width), fontsize=11)
    return figure


def _positions(
    rows: pd.DataFrame, points: pd.DataFrame | None, x: str, solver: str
) -> tuple[pd.DataFrame, pd.DataFrame | None, list[str] | None]:
    """The rows and every seed's points (``points`` of ``solver``, or None) with a categorical ``x`` (a text or
    boolean setting, e.g. basis.hand_subset=all|upper|lower) replaced by its positions in order of appearance,
    and those categories (None for a numeric ``x``)."""
    categories = None
    if not pd.api.types.is_numeric_dtype(rows[x]) or pd.api.types.is_bool_dtype(rows[x]):
        categories = list(dict.fromkeys(rows[x].astype(str)))
        rows = rows.assign(**{x: rows[x].astype(str).map({c: i for i, c in enumerate(categories)})})
    seeds = None
    if points is not None:
        seeds = _solver_rows(points, solver)
        if categories is not None:
            seeds = seeds.assign(**{x: seeds[x].astype(str).map({c: i for i, c in enumerate(categories)})})
    return rows, seeds, categories


def _label_panel(ax, x: str, categories: list[str] | None, panels: Sequence[str], panel: tuple, log_x: bool) -> None:
    """The x axis (categories as ticks, log scale), title and grid of one panel of :func:`plot_alpha_against`."""
    if categories is not None:
        ax.set_xticks(range(len(categories)), categories)
    ax.set_xlabel(axis_label(x))
    ax.set_title(", ".join(f"{key.split('.')[-1]}: {value}" for key, value in zip(panels, panel)), fontsize=10)
    ax.grid(alpha=0.3)
    if log_x:
        ax.set_xscale("log")


def _draw_basis(
    ax, line: pd.DataFrame, x: str, y: str, ci, colour, label: str, k: int, dodge: float, seeds: pd.DataFrame | None
) -> None:
    """One basis's line of :func:`plot_alpha_against` in one setting ``k`` of the grid: the line, every seed's
    point (``seeds``), and the interval as a band (error bars where only some points have one); points with
    error bars, shifted by ``dodge``, where several settings share an x."""
    has_ci = ci is not None and line[list(ci)].notna().all(axis=None)
    if line[x].duplicated().any():
        # Several settings share an x (e.g. hand subsets 'lower' and 'random12', both 12 shapes):
        # points with error bars, never a line zigzagging between them.
        errors = np.vstack([line[y] - line[ci[0]], line[ci[1]] - line[y]]) if has_ci else None
        ax.errorbar(
            line[x] + dodge,
            line[y],
            yerr=errors,
            color=colour,
            marker=MARKERS[k % len(MARKERS)],
            markersize=5,
            linestyle="none",
            capsize=3,
            label=label,
        )
        return
    ax.plot(
        line[x],
        line[y],
        marker=MARKERS[k % len(MARKERS)],
        markersize=4,
        color=colour,
        linestyle=LINE_STYLES[k % len(LINE_STYLES)],
        label=label,
    )
    if seeds is not None:
        ax.scatter(seeds[x], seeds[y], s=9, color=colour, alpha=0.45, linewidths=0, zorder=3)
    if has_ci:
        ax.fill_between(line[x], line[ci[0]], line[ci[1]], color=colour, alpha=0.15, linewidth=0)
    elif ci is not None and line[list(ci)].notna().any(axis=None):
        # some points lack an interval (one run kept that m): error bars where there is one
        known = line.dropna(subset=list(ci))
        ax.errorbar(
            known[x],
            known[y],
            yerr=np.vstack([known[y] - known[ci[0]], known[ci[1]] - known[y]]),
            color=colour,
            linestyle="none",
            capsize=3,
            alpha=0.6,
        )


def plot_marker_vs_mesh(
    table: pd.DataFrame,
    y: str | Sequence[str] = ("rms_mm", "alpha_disp_pooled"),
    *,
    solver: str = "lstsq",
    title: str,
    not_replicates: str = "",
) -> Figure:
    """Each basis fitted on each data variant, scored on one evaluation set per panel (bars, with the 95 %
    interval where the table has one): values compare within a panel, never across panels, whose points differ.

    Parameters
    ----------
    table : pandas.DataFrame
        Alpha table or tidy table: ``data`` (``train->eval`` when fitted on one variant and scored on another, or
        a variant scored on its own points), ``basis``, ``solver`` and the ``y`` columns; ``train_on`` and
        ``eval_on`` are read from ``data`` when absent.
    y : str or sequence of str
        The measures, one row of panels each (default: RMS error in mm and pooled displacement alpha, which do not
        depend on where the coordinate origin is).
    solver : str
    title : str
    not_replicates : str
        Why the seeds are not replicates, said in the legend (:func:`plot_alpha_against`); empty when they are.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per measure and evaluation set.
    """
    measures = [y] if isinstance(y, str) else list(y)
    check_columns(table, ["data", "basis", "solver", *measures])
    rows = _solver_rows(table, solver)
    if "eval_on" not in rows.columns:
        parts = rows["data"].astype(str).str.split("->")
        rows = rows.assign(train_on=parts.str[0], eval_on=parts.str[-1])
    evaluated = list(dict.fromkeys(rows["eval_on"]))
    trained = list(dict.fromkeys(rows["train_on"]))
    bases = ordered_bases(rows["basis"])
    figure_width = max(6.8, 5.0 * len(evaluated))
    figure = new_figure(figure_width, 3.9 * len(measures) + 1.2)
    grid = figure.subplots(len(measures), len(evaluated), squeeze=False)
    notes, legend = [], {}
    for measure, axes in zip(measures, grid):
        ci = ci_columns(rows, measure)
        check_positive_intervals(rows, measure, ci)
        for ax, evaluation in zip(axes, evaluated):
            # the variants fitted and scored on this set, side by side and centred on each basis's tick (a panel
            # holding one variant has one bar per tick, centred, and no empty slot)
            parts = []
            for train in trained:
                part = rows[(rows["eval_on"] == evaluation) & (rows["train_on"] == train)]
                part = part.drop_duplicates("basis").set_index("basis").reindex(bases)
                if not part[measure].isna().all():
                    parts.append((train, part))
            width = 0.8 / max(len(parts), 1)
            for k, (train, part) in enumerate(parts):
                errors = None
                if ci is not None and part[list(ci)].notna().all(axis=None):
                    errors = np.vstack([part[measure] - part[ci[0]], part[ci[1]] - part[measure]])
                positions = np.arange(len(bases)) + (k - (len(parts) - 1) / 2) * width
                colour = DATA_COLOURS.get(train.removesuffix(f" {PAPER_REGIME_SUFFIX}"), f"C{trained.index(train)}")
                bars = ax.bar(
                    positions,
                    part[measure],
                    width=width * 0.95,
                    yerr=errors,
                    capsize=3,
                    color=colour,
                    label=f"fitted on {train}",
                )
                legend.setdefault(f"fitted on {train}", bars)
                ax.bar_label(bars, fmt="%.3g", fontsize=7, padding=2)
            ax.set_xticks(np.arange(len(bases)), [basis_label(b).replace(" (", "\n(") for b in bases], fontsize=8)
            ax.set_ylabel(axis_label(measure), fontsize=9)
            points = rows.loc[rows["eval_on"] == evaluation, "n_points"] if "n_points" in rows.columns else []
            where = f"scored on {evaluation}" + (f" ({round(float(points.iloc[0]))} points)" if len(points) else "")
            ax.set_title(where, fontsize=9, loc="left")
            ax.grid(axis="y", alpha=0.3)
            ax.margins(y=0.15)
        if ci is not None and rows[list(ci)].notna().any(axis=None):
            notes.append(interval_label(rows))
    # every colour drawn in any panel has its entry (a panel alone may hold only some of the variants)
    replicates_legend(
        figure, list(legend.values()), list(legend), not_replicates, figure_width, ncols=max(1, len(legend)), fontsize=8
    )
    band = f", error bars: {notes[0]}" if notes else ""
    figure.suptitle(wrap_title(f"{title}\nsolver {solver}{band}", figure_width), fontsize=10)
    return figure


def envelope(x: np.ndarray, y: np.ndarray, bins: int = 360) -> tuple[np.ndarray, np.ndarray]:
    """A long series drawn with fewer points and the same look: in each of ``bins`` runs of consecutive points (a
    point and a half wide in a page-wide plot: two pixels on a screen) only its lowest and highest, in their order.
    Series with at most ``2 * bins`` points come back whole.

    Parameters
    ----------
    x, y : ndarray of shape (n,)
    bins : int

    Returns
    -------
    x, y : ndarray of shape (at most 2 * bins,)
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if len(y) <= 2 * bins:
        return x, y
    kept = []
    for run in np.array_split(np.arange(len(y)), bins):
        finite = run[np.isfinite(y[run])]
        if finite.size == 0:
            kept.append(run[0])  # a gap stays a gap
            continue
        kept += sorted({int(finite[np.argmin(y[finite])]), int(finite[np.argmax(y[finite])])})
    return x[kept], y[kept]


def plot_alpha_over_time(
    series: Mapping[str, Mapping[str, np.ndarray]],
    seconds: np.ndarray,
    *,
    ylabel: str,
    title: str,
    takes: Sequence[tuple[str, float]] = (),
) -> Figure:
    """Per-frame alpha over the take, one panel per data variant and one line per basis, with the boundaries of
    concatenated takes.

    Parameters
    ----------
    series : mapping
        Data variant -> (basis label -> ndarray of shape (n_frames,), per-frame alpha; NaN where undefined).
    seconds : ndarray of shape (n_frames,)
        Time of each frame on one axis through the takes (:meth:`workbench.dataset.capture.Timeline.elapsed`).
    ylabel : str
    title : str
    takes : sequence of (str, float)
        Each take's name and start time on that axis; with two or more, their boundaries are drawn and named.

    Returns
    -------
    matplotlib.figure.Figure
    """
    figure = new_figure(9.0, 3.1 * len(series) + 1.0)
    axes = figure.subplots(len(series), 1, squeeze=False, sharex=True)[:, 0]
    seconds = np.asarray(seconds, dtype=float)
    decimals = fixed_decimals(
        [np.nanmean(np.asarray(values, dtype=float)) for per_basis in series.values() for values in per_basis.values()],
        significant=3,
    )
    for ax, (data, per_basis) in zip(axes, series.items()):
        if len(takes) > 1:
            for name, start in takes:
                ax.axvline(start, color="0.35", linewidth=0.8, linestyle=":")
                ax.annotate(
                    name,
                    (start, 1.0),
                    xycoords=("data", "axes fraction"),
                    xytext=(3, -3),
                    textcoords="offset points",
                    fontsize=7,
                    color="0.3",
                    va="top",
                )
        for basis in ordered_bases(per_basis):
            values = np.asarray(per_basis[basis], dtype=float)
            ax.plot(
                *envelope(seconds, values),
                color=basis_colour(basis),
                linewidth=0.7,
                linestyle="--" if basis == "PCA" else "-",
                label=f"{basis_label(basis)}: mean {np.nanmean(values):.{decimals}f}",
            )
        ax.set_ylabel(ylabel, fontsize=9)
        ax.set_title(f"data: {data}", fontsize=10, loc="left")
        ax.grid(alpha=0.3)
        # Above the panel, right-aligned: inside it would hide the peaks.
        ax.legend(fontsize=8, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=2, frameon=False)
    axes[-1].set_xlabel("time in the take (s)" if len(takes) < 2 else "time through the takes, one after another (s)")
    figure.suptitle(wrap_title(title, 9.0), fontsize=11)
    return figure


def plot_alpha_per_solver(
    table: pd.DataFrame, y: str, negative_share: Mapping[str, Mapping[str, float]], *, title: str, settings=None
) -> Figure:
    """Alpha of each basis under each solver (bars), one panel per data variant, with the share of frames whose
    unconstrained weights go negative: the frames a non-negative or box constraint must change.

    Parameters
    ----------
    table : pandas.DataFrame
        An alpha table: ``data``, ``basis``, ``solver``, ``y``.
    y : str
        Alpha column.
    negative_share : mapping
        Data variant -> (basis -> fraction of evaluated frames with at least one negative least-squares weight).
    title : str
    settings : mapping, optional
        The run's ``solver`` settings: each solver's kind, whose hatch draws it (its name's kind without).

    Returns
    -------
    matplotlib.figure.Figure
    """
    check_columns(table, ["data", "basis", "solver", y])
    data_variants = list(dict.fromkeys(table["data"]))
    solvers = [s for s in dict.fromkeys(table["solver"]) if s != "projection"]
    width = max(6.0, 4.8 * len(data_variants))
    figure = new_figure(width, 4.6)
    axes = figure.subplots(1, len(data_variants), squeeze=False)[0]
    decimals = fixed_decimals(table[y].to_numpy(dtype=float), significant=3)
    for ax, data in zip(axes, data_variants):
        part = table[table["data"] == data]
        bases = [b for b in ordered_bases(part["basis"]) if b != "PCA"]
        step = 0.8 / len(solvers)
        for k, solver in enumerate(solvers):
            values = part[part["solver"] == solver].set_index("basis").reindex(bases)[y]
            positions = np.arange(len(bases)) + (k - (len(solvers) - 1) / 2) * step
            bars = ax.bar(
                positions,
                values,
                width=step * 0.92,
                color=[basis_colour(b) for b in bases],
                alpha=1.0 - 0.25 * k,
                hatch=solver_hatch(solver, settings),
                edgecolor="white",
                label=solver,
            )
            ax.bar_label(bars, fmt=f"%.{decimals}f", fontsize=7, padding=1)
        pca = part.loc[part["basis"] == "PCA", y]
        if len(pca):
            ax.axhline(float(pca.iloc[0]), color=basis_colour("PCA"), linestyle="--", linewidth=1)
        shares = negative_share.get(data, {})
        ax.set_xticks(
            np.arange(len(bases)),
            [f"{b}\n{100 * shares[b]:.0f} % of frames\nneed w < 0" if b in shares else b for b in bases],
            fontsize=8,
        )
        ax.set_ylabel(axis_label(y), fontsize=9)
        ax.set_title(
            f"data: {data}" + (f"; PCA (dashed) {float(pca.iloc[0]):.{decimals}f}" if len(pca) else ""),
            fontsize=10,
            loc="left",
        )
        ax.grid(axis="y", alpha=0.3)
        ax.margins(y=0.15)
    handles, labels = axes[-1].get_legend_handles_labels()
    figure.legend(
        handles,
        labels,
        loc="outside lower center",
        ncols=len(labels),
        fontsize=8,
        frameon=False,
        title="solver (hatching); dashed: PCA by projection",
        title_fontsize=8,
    )
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return figure
