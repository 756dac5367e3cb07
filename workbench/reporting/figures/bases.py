"""The plot of the other bases (``basis.alternatives``): alpha against each intuitiveness measure, one point per basis
and data variant, in the colours and markers of the bases' table, with labels placed clear of each other."""

from __future__ import annotations

import pandas as pd
from matplotlib.figure import Figure

from workbench.reporting.figures import basis_colour, new_figure, replicates_legend, wrap_title
from workbench.reporting.figures.studies import axis_label, check_columns, ordered_bases
from workbench.settings.bases import ALTERNATIVE_BASES

# Colours and markers of the bases beyond the paper's come from their table (the paper's keep theirs from
# workbench.reporting.figures).
OTHER_BASIS_COLOURS = {label: basis.colour for label, basis in ALTERNATIVE_BASES.items()}


BASIS_MARKERS = {
    "H": "s",
    "QE": "o",
    "QE-linear": "o",
    "PCA": "D",
    **{label: basis.marker for label, basis in ALTERNATIVE_BASES.items()},
}


HOLLOW_MARKERS = {"QE-linear", *(label for label, basis in ALTERNATIVE_BASES.items() if basis.hollow)}


INTUITIVENESS_AXES = (
    ("matched_abs_cosine", "closeness to the hand shapes:\nmean matched |cos| (higher: closer)"),
    (
        "locality",
        "locality: area holding {energy_percent:g} % of an\nelement's squared displacement (lower: more local)",
    ),
    ("usage", "usage: elements a frame uses\n(contribution > {threshold:g} x largest; lower: fewer)"),
)


def plot_alpha_against_intuitiveness(
    table: pd.DataFrame,
    y: str = "alpha_abs_mean",
    *,
    title: str,
    energy: float = 0.9,
    threshold: float = 0.1,
    not_replicates: str = "",
) -> Figure:
    """Alpha against each measure of intuitiveness, one point per basis: the trade-off in one picture.

    Parameters
    ----------
    table : pandas.DataFrame
        One row per data variant and basis: ``data``, ``basis``, ``y``, ``matched_abs_cosine``, ``locality``,
        ``usage``, each optionally with ``<column>_ci_low`` and ``<column>_ci_high`` (95 % interval over seeds,
        drawn as error bars).
    y : str
        Alpha column.
    title : str
    energy, threshold : float
        The locality energy and usage threshold the measures used (for the axis labels).
    not_replicates : str
        Why the runs behind the error bars are not replicates, said in the legend; empty when they are.

    Returns
    -------
    matplotlib.figure.Figure
        One row of three panels (closeness, locality, usage) per data variant, sharing the alpha axis.
    """
    check_columns(table, ["data", "basis", y, *(column for column, _ in INTUITIVENESS_AXES)])
    data_variants = list(dict.fromkeys(table["data"]))
    width = 12.0
    figure = new_figure(width, 3.8 * len(data_variants) + 1.2)
    grid = figure.subplots(len(data_variants), len(INTUITIVENESS_AXES), squeeze=False, sharey="row")
    bases = ordered_bases(table["basis"])
    labelled = []
    for row, data in zip(grid, data_variants):
        part = table[table["data"] == data].set_index("basis")
        for ax, (column, label) in zip(row, INTUITIVENESS_AXES):
            for basis in bases:
                if basis not in part.index or pd.isna(part.loc[basis, column]):
                    continue
                values = part.loc[basis]
                errors = {}
                for axis, name in (("xerr", column), ("yerr", y)):
                    low, high = f"{name}_ci_low", f"{name}_ci_high"
                    if low in part.columns and pd.notna(values[low]) and values[high] > values[low]:
                        errors[axis] = [[values[name] - values[low]], [values[high] - values[name]]]
                colour = OTHER_BASIS_COLOURS.get(basis, basis_colour(basis))
                ax.errorbar(
                    values[column],
                    values[y],
                    **errors,
                    color=colour,
                    marker=BASIS_MARKERS.get(basis, "o"),
                    markersize=8,
                    linestyle="none",
                    capsize=3,
                    markerfacecolor="none" if basis in HOLLOW_MARKERS else colour,
                    label=basis,
                )
                labelled.append((ax, values[column], values[y], basis, colour))
            ax.set_xlabel(label.format(energy_percent=energy * 100, threshold=threshold), fontsize=9)
            ax.grid(alpha=0.3)
            ax.margins(x=0.15, y=0.12)
        values = part[y].dropna()
        log_y = len(values) and values.min() > 0 and values.max() / values.min() > 5
        if log_y:  # a few bases far above the rest (the hand basis): a log axis keeps the rest apart
            from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

            row[0].set_yscale("log")
            row[0].yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            row[0].yaxis.set_major_formatter(FormatStrFormatter("%g"))
            row[0].yaxis.set_minor_formatter(NullFormatter())
        row[0].set_ylabel(f"{axis_label(y)}{', log scale' if log_y else ''}\n(lower: more accurate)", fontsize=9)
        row[0].set_title(f"data: {data}", fontsize=10, loc="left")
    handles, labels = grid[0, 0].get_legend_handles_labels()
    replicates_legend(figure, handles, labels, not_replicates, width, ncols=min(len(labels), 9), fontsize=9)
    figure.suptitle(wrap_title(title, width), fontsize=11)
    figure.draw_without_rendering()  # the final layout, so labels are placed where the points are drawn
    for ax in grid.ravel():
        place_labels(ax, [(x, y_value, text, colour) for owner, x, y_value, text, colour in labelled if owner is ax])
    return figure


# Where a point's label may go, in points from the point: right above, right below, left above, left below, above,
# below (text anchor given by the sign).
LABEL_OFFSETS = ((6, 4), (6, -4), (-6, 4), (-6, -4), (0, 9), (0, -9), (12, 12), (-12, -12))


def place_labels(ax, points, fontsize: float = 8) -> None:
    """Name points of a scatter plot with labels that overlap neither each other nor the points: each label takes
    the first place of :data:`LABEL_OFFSETS` (beside its point) that is free, else the least crowded one.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Laid out already (its data-to-display transform is final).
    points : sequence of (x, y, text, colour)
    fontsize : float
    """
    scale = ax.figure.dpi / 72.0  # display pixels per point
    centres = [ax.transData.transform((x, y)) for x, y, _, _ in points]
    marker = 5.0 * scale
    taken = [(cx - marker, cy - marker, cx + marker, cy + marker) for cx, cy in centres]

    def overlap(a, b) -> float:
        return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))

    for (x, y, text, colour), (cx, cy) in zip(points, centres):
        width, height = 0.6 * fontsize * len(text) * scale, fontsize * scale
        best = None
        for dx, dy in LABEL_OFFSETS:
            left = cx + dx * scale - (width if dx < 0 else width / 2 if dx == 0 else 0.0)
            bottom = cy + dy * scale - (height if dy < 0 else 0.0)
            box = (left, bottom, left + width, bottom + height)
            crowding = sum(overlap(box, other) for other in taken)
            if best is None or crowding < best[0]:
                best = (crowding, (dx, dy), box)
            if crowding == 0:
                break
        _, (dx, dy), box = best
        taken.append(box)
        ax.annotate(
            text,
            (x, y),
            textcoords="offset points",
            xytext=(dx, dy),
            fontsize=fontsize,
            color=colour,
            ha="right" if dx < 0 else "center" if dx == 0 else "left",
            va="top" if dy < 0 else "bottom",
        )
