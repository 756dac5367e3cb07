"""The headline figure a run report opens with: the paper's comparison with its intervals.

Left, the headline alpha of H, QE and PCA with least squares (PCA by projection) at the paper's regime (m = n, the
record's lead data variant) and, beside it, with the coverage rule, each level with the 95 % batch-means interval
of its mean over the frames (:func:`workbench.stats.statistics.batch_means_interval`; mean-of-frames columns only).
Right, the paper's two claims as paired differences on the same frames, QE - H and QE - PCA, with the intervals
the report's comparisons table holds; a difference that holds by construction (:mod:`workbench.stats.identities`)
is drawn at its measured size with its interval too, as a diamond marked "by construction": its sign is no test
verdict, its size is measured.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

from workbench.reporting.figures import OKABE_ITO, basis_colour, new_figure, wrap_title
from workbench.stats.identities import identity_lookup, run_identities
from workbench.stats.statistics import Interval, batch_means_interval, comparison_lookup
from workbench.study.regime import PAPER_REGIME_SUFFIX, is_paper_regime

HEADLINE_BASES = (("H", "lstsq"), ("QE", "lstsq"), ("PCA", "projection"))
CONTRASTS = ((("QE", "lstsq"), ("H", "lstsq")), (("QE", "lstsq"), ("PCA", "projection")))
PER_FRAME = {"alpha_abs_mean": "absolute", "alpha_disp_mean": "displacement"}
"""Headline columns that are means over frames, and the per-frame array (``alpha_per_frame.npz``) behind each."""
VARIANT_MARKERS = ("o", "s")
IDENTITY_MARKER = "D"
"""The marker of a paired difference that holds by construction (drawn at its measured size, not tested)."""


def headline_variants(metrics: Mapping) -> list[str]:
    """The data variants the figure shows: the lead one (the paper's regime m = n when the run has it) and the
    coverage rule's fit of the same data beside it."""
    data = list(metrics.get("data") or {})
    if not data:
        return []
    lead = data[0]
    beside = lead[: -len(PAPER_REGIME_SUFFIX) - 1] if is_paper_regime(lead) else None
    return [lead, *([beside] if beside in data else [])]


def level_interval(per_frame: Mapping | None, data: str, basis: str, solver: str, column: str) -> Interval | None:
    """The mean over frames of a row's per-frame alpha with its batch-means interval, or None when the column is
    no mean over frames or the arrays lack the row."""
    kind = PER_FRAME.get(column)
    if per_frame is None or kind is None or f"{data}.{kind}" not in per_frame:
        return None
    rows = [
        k
        for k, (b, s) in enumerate(zip(per_frame[f"{data}.basis"], per_frame[f"{data}.solver"]))
        if str(b) == basis and str(s) == solver
    ]
    if not rows:
        return None
    series = np.asarray(per_frame[f"{data}.{kind}"][rows[0]], dtype=float)
    valid = np.isfinite(series)
    takes = per_frame.get(f"{data}.take")
    seconds = per_frame.get(f"{data}.seconds")
    return batch_means_interval(
        series[valid][None, :],
        lambda means: means[0],
        takes=None if takes is None else np.asarray(takes)[valid],
        seconds=None if seconds is None else np.asarray(seconds)[valid],
    )


def headline_tables(
    table: pd.DataFrame, metrics: Mapping, per_frame: Mapping | None, column: str
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """What the figure draws.

    Returns
    -------
    levels : pandas.DataFrame
        ``data``, ``m``, ``n``, ``basis``, ``alpha``, ``low``, ``high`` (NaN without an interval).
    contrasts : pandas.DataFrame
        ``data``, ``contrast`` (``QE - H``), ``estimate``, ``low``, ``high``, ``identity`` (the reason it holds by
        construction, or empty).
    """
    levels, contrasts = [], []
    rows = metrics.get("rows") or []
    for data in headline_variants(metrics):
        part = table[table["data"] == data]
        if part.empty:
            continue
        m = int(part["m"].iloc[0])
        n = int(part.loc[part["basis"] == "H", "n"].iloc[0]) if (part["basis"] == "H").any() else m
        for basis, solver in HEADLINE_BASES:
            found = part[(part["basis"] == basis) & (part["solver"] == solver)]
            if found.empty:
                continue
            interval = level_interval(per_frame, data, basis, solver, column)
            levels.append(
                {
                    "data": data,
                    "m": m,
                    "n": n,
                    "basis": basis,
                    "alpha": float(found[column].iloc[0]),
                    "low": interval.low if interval else math.nan,
                    "high": interval.high if interval else math.nan,
                }
            )
        facts = (metrics.get("data") or {}).get(data) or {}
        compare = comparison_lookup(facts.get("comparisons") or [])
        identity = identity_lookup(run_identities([row for row in rows if row.get("data") == data], facts), column)
        for a, b in CONTRASTS:
            found = identity(a, b)
            interval = compare(a, b)
            if interval is None and found is None:
                continue
            contrasts.append(
                {
                    "data": data,
                    "contrast": f"{a[0]} - {b[0]}",
                    "estimate": interval.estimate if interval else math.nan,
                    "low": interval.low if interval else math.nan,
                    "high": interval.high if interval else math.nan,
                    "identity": "" if found is None else "by construction",
                }
            )
    return pd.DataFrame.from_records(levels), pd.DataFrame.from_records(contrasts)


def variant_label(levels: pd.DataFrame, data: str) -> str:
    """``markers m=n: m = n = 18`` / ``markers: coverage rule, m = 10``, with H/QE and QE/PCA."""
    part = levels[levels["data"] == data].set_index("basis")
    m, n = int(part["m"].iloc[0]), int(part["n"].iloc[0])
    regime = f"m = n = {m}" if m == n else f"coverage rule, m = {m}"
    ratios = [
        f"{a}/{b} {part.loc[a, 'alpha'] / part.loc[b, 'alpha']:.3g}"
        for a, b in (("H", "QE"), ("QE", "PCA"))
        if a in part.index and b in part.index
    ]
    return f"{regime}" + (f" ({', '.join(ratios)})" if ratios else "")


def figure_headline(levels: pd.DataFrame, contrasts: pd.DataFrame, column: str, title: str) -> Figure:
    """The two panels: levels with their intervals per basis and variant (log scale), and the paired differences
    QE - H and QE - PCA with theirs (an identity as a diamond at its measured size, labelled so)."""
    figure = new_figure(9.0, 4.2)
    left, right = figure.subplots(1, 2, width_ratios=[1.1, 1.0])
    variants = list(dict.fromkeys(levels["data"]))
    offsets = np.linspace(-0.15, 0.15, len(variants)) if len(variants) > 1 else [0.0]
    bases = [basis for basis, _ in HEADLINE_BASES if basis in set(levels["basis"])]
    for k, data in enumerate(variants):
        part = levels[levels["data"] == data].set_index("basis")
        for x, basis in enumerate(bases):
            if basis not in part.index:
                continue
            row = part.loc[basis]
            colour = basis_colour(basis)
            bounds = np.array([[row["alpha"] - row["low"]], [row["high"] - row["alpha"]]])
            left.errorbar(
                x + offsets[k],
                row["alpha"],
                yerr=None if math.isnan(row["low"]) else bounds,
                fmt=VARIANT_MARKERS[k % 2],
                color=colour,
                mfc=colour if k == 0 else "white",
                mew=1.5,
                ms=7,
                capsize=4,
                lw=1.5,
            )
        left.plot(
            [],
            [],
            VARIANT_MARKERS[k % 2],
            color=OKABE_ITO["black"],
            mfc=OKABE_ITO["black"] if k == 0 else "white",
            label=variant_label(levels, data),
        )
    left.set_xticks(range(len(bases)), bases)
    left.set_xlim(-0.5, len(bases) - 0.5)
    left.set_yscale("log")
    left.set_ylabel(f"{column} (%)")
    left.set_title("alpha (lstsq; PCA: projection), 95 % interval", fontsize=10)
    left.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 3.0, 5.0)))
    left.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    left.yaxis.set_minor_formatter(NullFormatter())
    left.grid(axis="y", which="both", alpha=0.3)
    figure.legend(loc="outside lower center", ncols=len(variants), fontsize=9, frameon=False)
    names = list(dict.fromkeys(contrasts["contrast"])) if len(contrasts) else []
    for k, data in enumerate(variants):
        part = contrasts[contrasts["data"] == data] if len(contrasts) else contrasts
        for row in part.to_dict("records"):
            draw_contrast(right, row, names.index(row["contrast"]) - offsets[k], k)
    if len(contrasts) and contrasts["identity"].astype(bool).any():
        right.plot(
            [], [], IDENTITY_MARKER, color=OKABE_ITO["black"], mfc="#999999", label="holds by construction, not tested"
        )
        right.legend(loc="best", fontsize=8, frameon=False, handletextpad=0.3)
    right.axvline(0.0, color=OKABE_ITO["black"], lw=0.8)
    right.set_yticks(range(len(names)), names)
    right.set_ylim(len(names) - 0.5, -0.5)
    right.set_xlabel(f"paired difference in {column} (%)")
    right.set_title("the paper's claims: below 0 = QE better", fontsize=10)
    right.grid(axis="x", alpha=0.3)
    figure.suptitle(wrap_title(title, 9.0), fontsize=11)
    return figure


def draw_contrast(ax, row: Mapping, y: float, k: int) -> None:
    """One paired difference at its measured estimate with its 95 % interval; one that holds by construction
    (``row["identity"]``) with a diamond and the words beside it, as an identity has a size too (only when the
    run stored no interval for it is it named at 0 without a marker)."""
    shade = OKABE_ITO["black"]
    measured = not math.isnan(row["estimate"])
    if row["identity"]:
        ax.annotate(
            "by construction" if measured else "<= 0 by construction (not measured)",
            (row["estimate"] if measured else 0.0, y),
            # outward from the other variant's marker of the same difference (the lead variant is drawn lower)
            xytext=(0, -8 if k == 0 else 8),
            textcoords="offset points",
            ha="center" if measured else "right",
            va="top" if k == 0 else "bottom",
            fontsize=8,
            color=shade,
        )
    if not measured:
        return
    bounds = np.array([[row["estimate"] - row["low"]], [row["high"] - row["estimate"]]])
    ax.errorbar(
        row["estimate"],
        y,
        xerr=None if math.isnan(row["low"]) else bounds,
        fmt=IDENTITY_MARKER if row["identity"] else VARIANT_MARKERS[k % 2],
        color=shade,
        mfc=shade if k == 0 else "white",
        mew=1.5,
        ms=7,
        capsize=4,
        lw=1.5,
    )


def headline_spec(record, column: str, label: str) -> tuple:
    """The figure spec (stem, title, caption, draw) of a run report's headline figure, a row of
    :func:`workbench.reporting.report.run_figures.make_figures` once the report adds its section; ``draw`` returns the
    reason when the run lacks H, QE or PCA with least squares.

    Parameters
    ----------
    record : workbench.record.record.RunRecord
    column : str
        The headline alpha column.
    label : str
        The dataset in a few words (the title's).
    """

    def draw(_, options):
        levels, contrasts = headline_tables(record.table, record.metrics, record.load_alpha_per_frame(), column)
        if levels.empty or len(set(levels["basis"])) < len(HEADLINE_BASES):
            return "the run has no H, QE and PCA with least squares to compare"
        return figure_headline(levels, contrasts, column, f"The paper's comparison, with intervals: {label}")

    caption = (
        f"`{column}` of H, QE (lstsq) and PCA (projection) on the lead data variant (filled: the paper's "
        "regime m = n when the run has it) and with the coverage rule beside it (open); left: each level with "
        "the 95 % batch-means interval of its mean over the frames (log scale; means of frames only); right: "
        "the paired differences QE - H and QE - PCA on the same frames with their 95 % intervals (the primary "
        "contrasts; every number in the table 'Paired comparisons within the run'). A diamond marks a difference "
        "that holds by construction (an identity such as QE spanning PCA's subspace): drawn at its measured size with "
        "its interval, its sign is no test verdict."
    )
    return ("headline", "The paper's comparison, with intervals", caption, draw)
