"""The findings of a run, stated in sentences generated from its numbers (never written by hand).

:func:`run_findings` reads an alpha table (the columns of :data:`workbench.report.TABLE_COLUMNS`) and the per-shape
intuitiveness of the run, and says per data variant: the ordering of H, QE and PCA under each solver, the ratios
H/QE and QE/PCA beside the paper's, m beside the paper's, what the constrained solvers do to QE against H, and
which hand shapes the projection changes most. Absolute alpha depends on the coordinate origin, so the
comparison with the paper is by ratios.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import pandas as pd

PAPER_BASES = ("H", "QE", "PCA")
CONSTRAINED = ("nnls", "box")
SOLVER_NAMES = {"lstsq": "least squares", "nnls": "non-negative weights", "box": "box [0, 1] weights"}


def _alpha(part: pd.DataFrame, basis: str, solver: str, column: str) -> float:
    """The alpha of a basis under a solver in one data variant's rows (PCA: its projection row), NaN if absent."""
    rows = part[(part["basis"] == basis) & ((part["solver"] == solver) | (part["solver"] == "projection"))]
    return float(rows[column].iloc[0]) if len(rows) else math.nan


def _fmt(value: float) -> str:
    return f"{value:.4g}"


def ordering_text(part: pd.DataFrame, solver: str, column: str, bases: Sequence[str] = PAPER_BASES) -> str:
    """``QE 0.147 < PCA 0.156 < H 0.303``: the bases of one data variant from best to worst under a solver.

    Parameters
    ----------
    part : pandas.DataFrame
        The alpha-table rows of one data variant.
    solver : str
    column : str
        Alpha column.
    bases : sequence of str
    """
    values = {basis: _alpha(part, basis, solver, column) for basis in bases}
    ranked = sorted(((value, basis) for basis, value in values.items() if not math.isnan(value)))
    return " < ".join(f"{basis} {_fmt(value)}" for value, basis in ranked)


def ratio_text(part: pd.DataFrame, column: str, paper_alpha: Mapping[str, float], solver: str = "lstsq") -> str:
    """H/QE and QE/PCA of one data variant beside the paper's (from its reported alpha)."""
    h, qe, pca = (_alpha(part, basis, solver, column) for basis in PAPER_BASES)
    paper = [paper_alpha.get(basis, math.nan) for basis in PAPER_BASES]
    return (f"H/QE = {h / qe:.2f} (paper {paper[0] / paper[1]:.2f}), QE/PCA = {qe / pca:.2f} "
            f"(paper {paper[1] / paper[2]:.2f})")


def constraint_text(part: pd.DataFrame, column: str, solver: str,
                    negative_share: Mapping[str, float] | None = None) -> str:
    """What a constrained solver does to QE against H, relative to least squares."""
    h0, h1 = _alpha(part, "H", "lstsq", column), _alpha(part, "H", solver, column)
    q0, q1 = _alpha(part, "QE", "lstsq", column), _alpha(part, "QE", solver, column)
    verdict = ("QE becomes worse than H" if q1 > h1 else "QE stays better than H")
    text = (f"with {SOLVER_NAMES.get(solver, solver)} QE's alpha goes from {_fmt(q0)} to {_fmt(q1)} "
            f"(x{q1 / q0:.2f}) and H's from {_fmt(h0)} to {_fmt(h1)} (x{h1 / h0:.2f}): {verdict} "
            f"({_fmt(q1)} against {_fmt(h1)})")
    if negative_share and "QE" in negative_share:
        text += (f"; under least squares {100 * negative_share['QE']:.0f} % of the frames give QE a negative weight "
                 f"(H: {100 * negative_share.get('H', math.nan):.0f} %), which the constraint must undo")
    return text


def closeness_text(intuitiveness: Sequence[Mapping], projection: str = "affine", count: int = 3) -> str:
    """Where QE loses a hand shape's look: the shapes the projection changes most, and the median closeness.

    Parameters
    ----------
    intuitiveness : sequence of mapping
        ``metrics.json`` rows: ``shape``, ``projection``, ``relative_distance``, ``cosine``.
    projection : str
    count : int
        Shapes named.
    """
    rows = sorted((row for row in intuitiveness if row["projection"] == projection),
                  key=lambda row: -row["relative_distance"])
    if not rows:
        return ""
    cosines = sorted(row["cosine"] for row in rows)
    median = cosines[len(cosines) // 2] if len(cosines) % 2 else (cosines[len(cosines) // 2 - 1]
                                                                    + cosines[len(cosines) // 2]) / 2
    named = ", ".join(f"{row['shape']} (cosine {row['cosine']:.2f}, relative distance {row['relative_distance']:.2f})"
                      for row in rows[:count])
    return (f"the projection changes most {named}; median cosine of the {len(rows)} shapes to their quasi-eigen "
            f"faces {median:.2f}")


def run_findings(table: pd.DataFrame, column: str, paper: Mapping, intuitiveness: Mapping[str, Sequence[Mapping]],
                 negative_share: Mapping[str, Mapping[str, float]] | None = None) -> list[str]:
    """The findings of a run, one Markdown line per data variant and topic.

    Parameters
    ----------
    table : pandas.DataFrame
        The run's alpha table.
    column : str
        The alpha column the findings use (the run's headline).
    paper : mapping
        ``m`` and ``alpha`` (basis -> the paper's value), as in the study config's ``paper`` node.
    intuitiveness : mapping
        Data variant -> its per-shape intuitiveness rows (``metrics.json``).
    negative_share : mapping, optional
        Data variant -> (basis -> share of frames with a negative least-squares weight).

    Returns
    -------
    list of str
    """
    lines = []
    solvers = [solver for solver in dict.fromkeys(table["solver"]) if solver != "projection"]
    for data, part in table.groupby("data", sort=False):
        m = round(float(part["m"].iloc[0]), 1)
        n = float(part.loc[part["basis"] == "H", "n"].iloc[0]) if (part["basis"] == "H").any() else math.nan
        ordering = "; ".join(f"{solver}: {ordering_text(part, solver, column)}" for solver in solvers)
        lines.append(f"**{data}**: `{column}` from best to worst, {ordering}.")
        if "lstsq" in solvers:
            lines.append(f"**{data}**: {ratio_text(part, column, paper.get('alpha', {}))} with least squares; "
                         "absolute alpha depends on the coordinate origin, the ratios compare across datasets.")
        spans = "can span" if m <= n else "cannot span"
        reach = (f" reach coverage {float(part['coverage'].iloc[0]):.4f}" if "coverage" in part.columns
                 else " (mean over the runs)")
        lines.append(f"**{data}**: m = {m:g} eigenfaces{reach} "
                     f"(paper: m = {paper.get('m')}); the {n:g} hand shapes {spans} them"
                     + (", so QE can match PCA" if m <= n else ", so QE cannot reach PCA") + ".")
        constrained = [s for s in CONSTRAINED if s in solvers and "lstsq" in solvers]
        for k, solver in enumerate(constrained):  # the share of negative weights is said once
            lines.append(f"**{data}**: " + constraint_text(part, column, solver,
                                                          (negative_share or {}).get(data) if k == 0 else None)
                         + ".")
        closeness = closeness_text(intuitiveness.get(data, []))
        if closeness:
            lines.append(f"**{data}**: {closeness}.")
    return lines


def facts_frame(metrics: Mapping) -> pd.DataFrame:
    """The run's facts in one table, a row per data variant: points, frames, m, coverage, empty axes.

    Parameters
    ----------
    metrics : mapping
        ``metrics.json`` of the run.
    """
    rows = []
    for data, values in metrics["data"].items():
        pca = values["pca"]
        rows.append({"data": data, "points": values["n_points"], "training frames": values["n_train_frames"],
                     "evaluated frames": values["n_eval_frames"], "m": pca["m"],
                     "coverage": round(float(pca["coverage_reached"]), 4), "PCA method": pca["method"],
                     "empty PCA axes": "; ".join(f"{projection}: {', '.join(map(str, qe['empty_axes'])) or 'none'}"
                                                 for projection, qe in values["quasi_eigen"].items())})
    return pd.DataFrame.from_records(rows)


def shared_notes(metrics: Mapping) -> tuple[list[str], dict[str, list[str]]]:
    """The run's notes, those every data variant shares once and the rest per variant.

    Returns
    -------
    shared : list of str
    own : dict
        Data variant -> its notes not in ``shared``.
    """
    notes = {data: list(values.get("notes", [])) for data, values in metrics["data"].items()}
    first = next(iter(notes.values()), [])
    shared = [note for note in first if all(note in other for other in notes.values())]
    return shared, {data: [note for note in own if note not in shared] for data, own in notes.items()}


def bases_findings(summary: pd.DataFrame, column: str) -> list[str]:
    """Findings of a run or sweep that scored other bases: per data variant, the bases from most to least
    accurate, and which is closest to the hand shapes and most local.

    Parameters
    ----------
    summary : pandas.DataFrame
        One row per data variant and basis: ``data``, ``basis``, ``column``, ``matched_abs_cosine``, ``locality``
        (means over the runs).
    column : str
    """
    lines = []
    for data, part in summary.groupby("data", sort=False):
        ranked = part.sort_values(column)
        lines.append(f"**{data}**: `{column}` from best to worst: "
                     + " < ".join(f"{row.basis} {_fmt(getattr(row, column))}" for row in ranked.itertuples()) + ".")
        others = part[part["basis"] != "H"]
        closest = others.sort_values("matched_abs_cosine", ascending=False).iloc[0]
        local = others.sort_values("locality").iloc[0]
        hand = part[part["basis"] == "H"]
        lines.append(f"**{data}**: closest to the hand shapes: {closest['basis']} (mean matched |cosine| "
                     f"{closest['matched_abs_cosine']:.2f}); most local: {local['basis']} ({100 * local['locality']:.0f} % "
                     "of the face holds its elements' displacement"
                     + (f", the hand shapes' {100 * float(hand['locality'].iloc[0]):.0f} %" if len(hand) else "")
                     + ").")
    return lines


def sweep_findings(summary: pd.DataFrame, swept: Sequence[str], column: str, solver: str,
                   paper: Mapping) -> list[str]:
    """Findings of a sweep from its means over the runs: the run findings when nothing but the seed was swept,
    else the ordering of H, QE and PCA at every swept value.

    Parameters
    ----------
    summary : pandas.DataFrame
        Means over the runs: the swept keys, ``data``, ``basis``, ``solver``, ``n``, ``m`` and ``column``.
    swept : sequence of str
    column : str
    solver : str
        The solver of the orderings.
    paper : mapping
    """
    if not swept:
        return run_findings(summary, column, paper, {})
    lines = []
    for values, group in summary.groupby(list(swept), sort=False):
        values = values if isinstance(values, tuple) else (values,)
        setting = ", ".join(f"{key} = {value}" for key, value in zip(swept, values))
        lines.append(f"{setting}: " + "; ".join(f"{data} {ordering_text(part, solver, column)}"
                                                for data, part in group.groupby("data", sort=False)))
    return lines
