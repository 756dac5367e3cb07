"""The headline figure a run report opens with: the paper's comparison with its intervals.

Left, the headline alpha of H, QE and PCA with least squares (PCA by projection) at the paper's regime (m = n, the
record's lead data variant) and, beside it, with the coverage rule, each level with the 95 % batch-means interval
of its mean over the frames (:func:`workbench.stats.statistics.batch_means_interval`; mean-of-frames columns only).
Right, the paper's two claims as the run stored them (``metrics.json`` ``claims``, :mod:`workbench.study.claims`):
H/QE and QE/PCA at m = n on a log axis with 1, the paper's 7.2 and 1.16 and claim 2's margin marked, the training
frames and each held-out protocol side by side, each with its interval and its verdict word, the same as the
summary's (nothing is decided here). A ratio that is not estimable is drawn as an open marker without bounds.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

from workbench.reporting.figures import OKABE_ITO, basis_colour, new_figure, wrap_title
from workbench.reporting.findings.claims import NOT_ESTIMABLE, NOT_TESTED, PAPER_RATIOS, lead_entries
from workbench.stats.statistics import Interval, batch_means_interval
from workbench.study.claims import base_variant
from workbench.study.regime import PAPER_REGIME_SUFFIX, is_paper_regime

HEADLINE_BASES = (("H", "lstsq"), ("QE", "lstsq"), ("PCA", "projection"))
PER_FRAME = {"alpha_abs_mean": "absolute", "alpha_disp_mean": "displacement"}
"""Headline columns that are means over frames, and the per-frame array (``alpha_per_frame.npz``) behind each."""
VARIANT_MARKERS = ("o", "s")


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


def no_interval_reason(per_frame: Mapping | None, column: str) -> str:
    """Why a level has no interval to draw at all: the record keeps no per-frame alphas, or the column is no mean
    over frames (a pooled alpha)."""
    if per_frame is None:
        return "the record keeps no per-frame alphas (save_inputs=true keeps them)"
    if column not in PER_FRAME:
        return f"{column} is no mean over frames"
    return "the per-frame alphas lack the row"


def headline_tables(
    table: pd.DataFrame, metrics: Mapping, per_frame: Mapping | None, column: str
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """What the figure draws.

    Returns
    -------
    levels : pandas.DataFrame
        ``data``, ``m``, ``n``, ``basis``, ``alpha``, ``low``, ``high`` (NaN without an interval, or with one that
        cannot inform), ``not_estimable`` (why it cannot, :attr:`workbench.stats.statistics.Interval.not_estimable`),
        ``no_interval`` (why there is none at all, :func:`no_interval_reason`).
    contrasts : pandas.DataFrame
        ``data``, ``contrast`` (``QE - H``), ``estimate``, ``low``, ``high``, ``identity`` (the reason it holds by
        construction, or empty).
    """
    levels = []
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
                    # the claims' rule: an interval that cannot inform is drawn without bounds
                    "low": interval.low if interval and interval.estimable else math.nan,
                    "high": interval.high if interval and interval.estimable else math.nan,
                    "not_estimable": interval.not_estimable if interval else "",
                    "no_interval": "" if interval else no_interval_reason(per_frame, column),
                }
            )
    return pd.DataFrame.from_records(levels), claim_table(metrics)


def claim_table(metrics: Mapping) -> pd.DataFrame:
    """The stored claims of the lead variant, one row per ratio and protocol: ``ratio`` (``H/QE``, ``QE/PCA``),
    ``protocol`` (its text), ``estimate``, ``low``, ``high`` (NaN where not estimable or not tested), ``verdict``
    and ``margin`` (claim 2's)."""
    records = []
    data = headline_variants(metrics)[:1]
    for entry in lead_entries(metrics.get("claims"), base_variant(data[0]) if data else None):
        for name in ("H/QE", "QE/PCA"):
            stored = entry[name]
            informs = stored["verdict"] not in (NOT_ESTIMABLE, NOT_TESTED)
            records.append(
                {
                    "ratio": name,
                    "protocol": entry["protocol_text"],
                    "estimate": stored["estimate"],
                    "low": stored["low"] if informs else math.nan,
                    "high": stored["high"] if informs else math.nan,
                    "verdict": stored["verdict"],
                    "margin": stored.get("margin", math.nan),
                }
            )
    return pd.DataFrame.from_records(records)


def variant_label(levels: pd.DataFrame, data: str) -> str:
    """``markers m=n: m = n = 18`` / ``markers: coverage rule, m = 10``, with H/QE and QE/PCA, and the bases whose
    level interval is not estimable (drawn without bounds)."""
    part = levels[levels["data"] == data].set_index("basis")
    m, n = int(part["m"].iloc[0]), int(part["n"].iloc[0])
    regime = f"m = n = {m}" if m == n else f"coverage rule, m = {m}"
    ratios = [
        f"{a}/{b} {part.loc[a, 'alpha'] / part.loc[b, 'alpha']:.3g}"
        for a, b in (("H", "QE"), ("QE", "PCA"))
        if a in part.index and b in part.index
    ]
    bare = [basis for basis in part.index if part.loc[basis, "not_estimable"]] if "not_estimable" in part else []
    return (
        f"{regime}"
        + (f" ({', '.join(ratios)})" if ratios else "")
        + (f"; no interval for {', '.join(bare)}: not estimable" if bare else "")
    )


def figure_headline(levels: pd.DataFrame, contrasts: pd.DataFrame, column: str, title: str) -> Figure:
    """The two panels: levels with their intervals per basis and variant (log scale), and the stored claims, H/QE
    and QE/PCA per protocol on a log axis with 1, 7.2, 1.16 and the margin marked (:func:`draw_claims`)."""
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
    missing = sorted(set(levels["no_interval"]) - {""}) if "no_interval" in levels else []
    left.set_title(
        "alpha (lstsq; PCA: projection), 95 % interval" + "".join(f"\n(no interval: {reason})" for reason in missing),
        fontsize=10 if not missing else 8,
    )
    left.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 3.0, 5.0)))
    left.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    left.yaxis.set_minor_formatter(NullFormatter())
    left.grid(axis="y", which="both", alpha=0.3)
    long = any(len(variant_label(levels, data)) > 60 for data in variants)
    figure.legend(loc="outside lower center", ncols=1 if long else len(variants), fontsize=9, frameon=False)
    draw_claims(right, contrasts)
    figure.suptitle(wrap_title(title, 9.0), fontsize=11)
    return figure


def draw_claims(ax, claims: pd.DataFrame) -> None:
    """The stored claims (:func:`claim_table`) on a log axis: one line per ratio and protocol, the estimate with its
    interval and the verdict word beside it; vertical lines at 1, the paper's 7.2 and 1.16, and claim 2's margin."""
    if claims.empty:
        ax.text(0.5, 0.5, "no stored claims", ha="center", va="center", transform=ax.transAxes, fontsize=9)
        ax.set_axis_off()
        return
    shade = OKABE_ITO["black"]
    labels = [f"{row['ratio']}, {row['protocol']}" for row in claims.to_dict("records")]
    for y, row in enumerate(claims.to_dict("records")):
        informs = math.isfinite(row["low"]) and math.isfinite(row["high"])
        estimate = row["estimate"] if math.isfinite(row["estimate"]) and row["estimate"] > 0 else 1.0
        bounds = np.array([[estimate - row["low"]], [row["high"] - estimate]]) if informs else None
        ax.errorbar(
            estimate,
            y,
            xerr=bounds,
            fmt="o" if row["ratio"] == "H/QE" else "s",
            color=shade,
            mfc=shade if informs else "white",
            mew=1.5,
            ms=7,
            capsize=4,
            lw=1.5,
        )
        ax.annotate(
            row["verdict"],
            (row["high"] if informs else estimate, y),
            xytext=(6, 0),
            textcoords="offset points",
            va="center",
            fontsize=8,
            color=shade,
        )
    ax.axvline(1.0, color=shade, lw=0.9)
    ax.axvline(PAPER_RATIOS["H/QE"], color=OKABE_ITO["vermillion"], lw=1.0, ls="--", label="paper H/QE 7.2")
    ax.axvline(PAPER_RATIOS["QE/PCA"], color=OKABE_ITO["blue"], lw=1.0, ls=":", label="paper QE/PCA 1.16")
    margins = claims["margin"].dropna()
    if len(margins):
        ax.axvline(
            float(margins.iloc[0]),
            color=OKABE_ITO["blue"],
            lw=1.0,
            ls="-.",
            label=f"claim 2 margin {margins.iloc[0]:g}",
        )
    ax.set_xscale("log")
    ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_yticks(range(len(labels)), labels, fontsize=8)
    ax.set_ylim(len(labels) + 0.7, -0.5)  # a blank band under the last row holds the legend, clear of any verdict
    ax.set_xlabel("ratio of alphas at m = n (log scale)")
    values = pd.concat([claims["low"], claims["high"], claims["estimate"]]).dropna()
    values = values[values > 0]
    ax.set_xlim(
        min(0.5, 0.7 * values.min()) if len(values) else 0.5, max(12.0, 1.4 * values.max()) if len(values) else 12.0
    )
    ax.set_title("the paper's claims (stored), m = n", fontsize=10)
    ax.grid(axis="x", which="major", alpha=0.3)
    ax.legend(loc="lower center", ncols=3, fontsize=7, frameon=False, handlelength=1.6, columnspacing=0.8)


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
        "the 95 % batch-means interval of its mean over the frames (log scale; means of frames only; none where it "
        "is not estimable, by the claims' rule); right: "
        "the paper's two claims as the run stored them, H/QE (circles) and QE/PCA (squares) at m = n on the training "
        "frames and each held-out protocol, with their 95 % intervals and verdicts (the summary's; log scale; "
        "lines at 1, the paper's 7.2 and 1.16, and claim 2's margin). An open marker without bounds: not "
        "estimable or not tested (the summary says why)."
    )
    return ("headline", "The paper's comparison, with intervals", caption, draw)
