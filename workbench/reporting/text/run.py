"""What a run prints: one sentence on what was reproduced, the header, the alpha table and the headline below it,
within :data:`PRINT_WIDTH` columns (:func:`fit_width`) or, with ``--wide`` and in the record, in full."""

from __future__ import annotations

from typing import Mapping, Sequence

import pandas as pd

from workbench.core.errors import WorkbenchError
from workbench.reporting.tables.width import PRINT_WIDTH, fit_width  # noqa: F401 (part of what a run prints)
from workbench.settings.typed import StudySettings
from workbench.study.table import ALPHA_TABLE_COLUMNS, CLEAN_COLUMNS, FRAME_COLUMNS, ROW_NAME_COLUMNS


def printed_tables(table: pd.DataFrame) -> str:
    """The alpha table as a run prints it: alpha beside the paper's, then the per-frame error and the weights, then
    (``metric.score_clean``) alpha against the clean frames.

    Parameters
    ----------
    table : pandas.DataFrame
        From :func:`workbench.study.table.alpha_table` (several data variants concatenated).

    Returns
    -------
    str
        Markdown tables, each after the first under a line naming its columns.
    """
    from workbench.reporting.tables.cells import markdown_frame

    names = [column for column in ROW_NAME_COLUMNS if column in table.columns]
    text = markdown_frame(table[[*names, *[c for c in ALPHA_TABLE_COLUMNS if c in table.columns]]])
    frame = [column for column in FRAME_COLUMNS if column in table.columns]
    if frame:
        text += (
            "\nper-frame error over the face region (mm: median, 95th percentile, maximum over frames) and the "
            "weights (largest |w|; share of frames with a weight outside [0, 1]; Hoyer sparsity, 1 = one shape "
            "per frame; roughness = mean squared second time derivative, 1/s^4):\n\n"
            + markdown_frame(table[[*names, *frame]])
        )
    clean = [column for column in CLEAN_COLUMNS if column in table.columns]
    if clean:
        text += (
            "\nthe same reconstructions scored against the clean frames (no marker noise, no dropout; "
            "metric.score_clean):\n\n" + markdown_frame(table[[*names, *clean]])
        )
    return text


COMPACT_NAMES = {
    "alpha_abs_mean": "abs_mean",
    "alpha_abs_pooled": "abs_pooled",
    "alpha_disp_mean": "disp_mean",
    "alpha_disp_pooled": "disp_pooled",
    "rms_mm": "rms_mm",
    "paper_alpha": "paper",
}
"""The alpha table's columns printed by default, with their short headers."""


def compact_tables(table: pd.DataFrame) -> str:
    """The alpha table as printed by default, within :data:`PRINT_WIDTH` for the data variants of the shipped
    datasets: the names, ``m`` and the alpha columns under short headers (:data:`COMPACT_NAMES`), the numbers as
    :func:`printed_tables` prints them; the other columns and tables are left to ``--wide`` and the record.

    Parameters
    ----------
    table : pandas.DataFrame
        From :func:`workbench.study.table.alpha_table` (several data variants concatenated).

    Returns
    -------
    str
        A line saying what the short headers are and where the rest is, then the Markdown table.
    """
    from workbench.reporting.tables.cells import frame_cells, markdown_table

    names = [column for column in ("data", "basis", "solver") if column in table.columns]
    columns = [column for column in ("m", *COMPACT_NAMES) if column in table.columns]
    header, rows, numeric = frame_cells(table[[*names, *columns]])
    return (
        "alpha in % (abs_mean is the record's alpha_abs_mean, and so on; paper: Kim & Ko's value); the projection, "
        "n, coverage, the per-frame errors and the weights: workbench --wide, or the record's alpha_table.md\n\n"
        + markdown_table([COMPACT_NAMES.get(name, name) for name in header], rows, numeric)
    )


def reproduced_sentence(claims: Mapping | None) -> str:
    """One sentence on the paper's two claims, first in what a run prints: the verdicts the run stored
    (:func:`workbench.study.claims.claims_at_m_equals_n`) on the training frames at m = n, with their intervals,
    and each held-out protocol's (:func:`workbench.reporting.findings.claims.claims_sentence`).

    Parameters
    ----------
    claims : mapping or None
        The run's ``claims`` (as ``metrics.json`` keeps them).

    Returns
    -------
    str
        One line (empty without claims).
    """
    from workbench.reporting.findings.claims import claims_sentence

    return claims_sentence(claims)


def study_header(results: Sequence, settings: StudySettings) -> str:
    """The lines printed above the alpha table: data, m, coverage, and the choices the paper leaves open.

    Parameters
    ----------
    results : sequence of workbench.study.results.StudyResult
        One per data variant, all from the same dataset.
    settings : StudySettings
        The study's checked, typed settings (:func:`workbench.settings.typed.study_settings`).

    Returns
    -------
    str
    """
    paper, basis = settings.paper, settings.basis
    first = results[0].capture
    rule = (
        f"fixed m = {basis.n_components}"
        if basis.n_components is not None
        else f"m of the clean capture at coverage threshold {basis.coverage}"
        if basis.coverage_on == "clean"
        else f"coverage threshold {basis.coverage}"
    )
    lines = [
        f"Study '{settings.study}' on {first.name}",
        f"  alpha in % (eq. 6). abs: 100|v*-v|/|v*|, positions with the origin at the {first.origin}; "
        "disp: 100|d*-d|/|d*|; mean: of per-frame values; pooled: over all frames",
        "  QE: affine projects through the capture mean (eq. 3-4 as written), linear through the neutral face",
        "  PCA: mean plus orthogonal projection; paper_alpha: Kim & Ko's reported values on their own capture and "
        "coordinate origin, not a target for these data (compare ratios; see the note under the table)",
    ]
    lines[1:1] = regime_lines(results, settings)
    for result in results:
        capture, eigenfaces = result.capture, result.eigenfaces
        empty = "; ".join(
            f"{projection}: {[j + 1 for j in qe.empty_axes] or 'none'}"
            + (f" (appended {[j + 1 for j in qe.appended_axes]})" if qe.appended_axes else "")
            for projection, qe in result.quasi_eigen.items()
        )
        from workbench.study.regime import is_paper_regime

        lines += (
            [
                f"data '{result.data}': {len(capture.train)} training frames, {len(capture.eval)} evaluated, "
                f"{capture.n_points} points, {len(capture.hand_names)} hand shapes",
                f"  m = {eigenfaces.n_components_} eigenfaces reach coverage {eigenfaces.coverage_:.4f} "
                f"({'m = n, basis.paper_regime' if is_paper_regime(result.data) else rule}); "
                f"paper: m = {paper.m} at {paper.coverage}",
                f"  empty PCA axes (1-based, eps {basis.empty_axis_eps} x {basis.empty_axis_scale}): {empty}",
            ]
            if not result.folds
            else fold_lines(result)
        )
        lines += conditioning_lines(result.rows)
        lines += [f"  note: {note}" for note in capture.notes]
    return "\n".join(lines) + "\n"


def fold_lines(result) -> list[str]:
    """The header lines of a cross-validated variant (``dataset.held_out`` kfold or take_out): the folds, each
    fold's m, every row's pooled held-out alpha with its per-fold values, and the paired ratios over folds."""
    from workbench.stats.statistics import paired_ratio_interval
    from workbench.study.regime import is_paper_regime

    folds = result.folds
    chosen = (
        "m = n in each fold (basis.paper_regime)"
        if is_paper_regime(result.data)
        else "m chosen in each fold by the coverage rule on its training frames"
    )
    lines = [
        f"  {folds['n_folds']} folds; {chosen}: m = {folds['m']}, held-out frames per fold {folds['n_eval_frames']}",
        "  held-out alpha_abs_pooled over all folds' held-out frames [per fold]:",
    ]
    rows = folds["rows"]
    for i, (basis, _, solver) in enumerate(rows):
        per_fold = ", ".join(f"{value:.3g}" for value in folds["alpha_abs_pooled"][i])
        lines.append(f"    {basis} {solver}: {result.rows[i].alpha.absolute_pooled:.3g} [{per_fold}]")
    solver = next((row[2] for row in rows if row[2] != "projection"), None)
    index = {(basis, row_solver): i for i, (basis, _, row_solver) in enumerate(rows)}
    for first, second in (("H", "QE"), ("QE", "PCA")):
        a = index.get((first, solver))
        b = index.get((second, solver), index.get((second, "projection")))
        if a is None or b is None:
            continue
        interval = paired_ratio_interval(folds["alpha_abs_pooled"][a], folds["alpha_abs_pooled"][b])
        lines.append(
            f"  {first}/{second} ({solver}), geometric mean of per-fold ratios: {interval.estimate:.3g}, "
            f"95 % interval [{interval.low:.3g}, {interval.high:.3g}] (paired t on log ratios over folds, "
            f"n = {interval.n})"
        )
    return lines


HEADLINE_COLUMNS = {
    ("absolute", "mean"): "absolute_mean",
    ("absolute", "pooled"): "absolute_pooled",
    ("displacement", "mean"): "displacement_mean",
    ("displacement", "pooled"): "displacement_pooled",
}
"""``metric.headline_normalisation`` and ``headline_aggregate`` -> the :class:`workbench.numerics.metrics.AlphaSummary` field."""


def regime_lines(results: Sequence, settings: StudySettings) -> list[str]:
    """The header's first comparison: H/QE and QE/PCA with least squares at the paper's regime m = n (the variants
    ``basis.paper_regime`` adds, or a variant whose m already equals n), each with QE's and H's conditioning
    and largest weight, then the coverage rule's variants beside them.

    Parameters
    ----------
    results : sequence of workbench.study.results.StudyResult
    settings : StudySettings
        The study's checked, typed settings (``metric``, ``paper``).

    Returns
    -------
    list of str
        Empty when no variant has H, QE and PCA with lstsq scored on its training frames.
    """
    metric, paper = settings.metric, settings.paper
    field = HEADLINE_COLUMNS[metric.headline_normalisation, metric.headline_aggregate]
    regime, rule = [], []
    for result in results:
        if result.protocol != "training frames":
            continue
        text = regime_text(result, field)
        if text:
            m, n = result.eigenfaces.n_components_, len(result.capture.hand_names)
            (regime if m == n else rule).append(f"    {result.data} (m = {m}, n = {n}): {text}")
    if not regime and not rule:
        return []
    reported = paper.alpha
    head = (
        f"  the paper's regime m = n (paper: H/QE {reported.H / reported.QE:.2g}, QE/PCA "
        f"{reported.QE / reported.PCA:.3g} at m = n = "
        f"{paper.m}; alpha {field}, lstsq; cond: the basis's condition number, or its rank when deficient):"
    )
    lines = [head] + (regime or ["    none in this run (basis.n_components fixes m, or paper_regime is off)"])
    if rule:
        lines += ["  beside it, the coverage rule's m:"] + rule
    held = held_out_regime_lines(results, field)
    if held:
        lines += ["  the paper's regime m = n on held-out frames (dataset.held_out; folds pooled):"] + held
    return lines


def held_out_regime_lines(results: Sequence, field: str) -> list[str]:
    """H/QE and QE/PCA with least squares of the variants scored on held-out frames at m = n (in every fold), one
    line each (their conditioning is that of each fold's fit: in the run's tables)."""
    lines = []
    for result in results:
        folds, n = result.folds or {}, len(result.capture.hand_names)
        m = folds.get("m", result.eigenfaces.n_components_)
        text = regime_text(result, field, conditioning=False)
        if result.protocol != "training frames" and text and all(value == n for value in (m if folds else [m])):
            lines.append(f"    {result.data} (m = {m}, n = {n}): {text}")
    return lines


def regime_text(result, field: str, conditioning: bool = True) -> str:
    """H/QE and QE/PCA of one variant (least squares, alpha ``field``), with H's and QE's conditioning and largest
    |w| (unless ``conditioning`` is false); empty when H, QE or PCA is missing."""
    rows = {(row.basis, row.solver): row for row in result.rows}
    found = {
        basis: rows.get((basis, solver)) for basis, solver in (("H", "lstsq"), ("QE", "lstsq"), ("PCA", "projection"))
    }
    if any(row is None for row in found.values()):
        return ""
    alpha = {basis: getattr(row.alpha, field) for basis, row in found.items()}

    def basis_conditioning(basis: str) -> str:
        report, row = found[basis].conditioning, found[basis]
        cond = (
            "?"
            if report is None
            else f"rank {report.rank}/{report.n_shapes}"
            if report.rank < report.n_shapes
            else f"cond {report.condition_number:.3g}"
        )
        return f"{basis} {cond}, max |w| {row.max_abs_weight:.3g}"

    ratios = (
        f"H/QE {alpha['H'] / alpha['QE']:.3g}, QE/PCA {alpha['QE'] / alpha['PCA']:.3g} (H {alpha['H']:.3g}, "
        f"QE {alpha['QE']:.3g}, PCA {alpha['PCA']:.3g})"
    )
    return f"{ratios}; {basis_conditioning('QE')}; {basis_conditioning('H')}" if conditioning else ratios


ILL_CONDITIONED = 1e6
"""A full-rank basis whose condition number exceeds this gets a warning: its weights amplify noise that much."""


def conditioning_lines(rows: Sequence) -> list[str]:
    """Header lines on how well each basis determines its weights: condition number or rank, and warnings for
    zero shapes, near-duplicate shapes and ill-conditioning (weights then swing wildly from frame to frame).

    Parameters
    ----------
    rows : sequence of workbench.study.results.Row
        Rows with ``conditioning`` set (the first row of each basis is used).

    Returns
    -------
    list of str
    """
    seen, parts, warnings = set(), [], []
    for row in rows:
        report = getattr(row, "conditioning", None)
        if report is None or row.basis in seen:
            continue
        seen.add(row.basis)
        if report.rank < report.n_shapes:
            parts.append(
                f"{row.basis} rank {report.rank} of {report.n_shapes} (weights not unique; minimum-norm for lstsq)"
            )
        else:
            parts.append(f"{row.basis} condition number {report.condition_number:.3g}")
        problems = []
        if report.zero_shapes:
            problems.append(f"all-zero shapes {list(report.zero_shapes)}")
        if report.near_duplicates:
            problems.append(
                "near-duplicate shapes " + ", ".join(f"{i}~{j} (cos {c:.4f})" for i, j, c in report.near_duplicates[:5])
            )
        if report.rank == report.n_shapes and report.condition_number > ILL_CONDITIONED:
            problems.append(f"condition number {report.condition_number:.3g} > {ILL_CONDITIONED:g}")
        if problems and row.basis == "H":
            largest = max(r.max_abs_weight for r in rows if r.basis == row.basis)
            warnings.append(
                f"  WARNING: basis {row.basis} is ill-conditioned: {'; '.join(problems)}; its weights "
                f"are unstable (largest |w| {largest:.3g})"
            )
    return ([f"  bases: {'; '.join(parts)}"] if parts else []) + warnings


PAPER_ALPHA_NOTE = (
    "paper_alpha is Kim & Ko's own capture (35,000 frames, 66 markers), its own coordinate origin and "
    "absolute alpha: absolute alpha divides by |v*| and so moves with where the origin lies, and "
    "another face, capture and hand basis give other values; compare the ratios H/QE and QE/PCA "
    "(paper 7.2 and 1.16), not alpha itself"
)


def headline(
    table: pd.DataFrame,
    metric: Mapping,
    paper_alpha: Mapping[str, float],
    comparisons: Mapping[str, Sequence[Mapping]] | None = None,
    identities: Mapping[str, Sequence] | None = None,
    claims: Mapping | None = None,
) -> str:
    """One line per solver: the configured alpha of every basis beside the paper's values; with ``comparisons``
    the bases from best to worst, ``<`` only where the paired per-frame difference's interval excludes zero, and,
    with ``claims``, H against QE and QE against PCA (lstsq) of a variant with stored claims by the claim's ratio
    test (:func:`workbench.reporting.findings.comparisons.with_claims`), as every other surface states them.

    Parameters
    ----------
    table : pandas.DataFrame
        From :func:`workbench.study.table.alpha_table`.
    metric : mapping
        The ``metric`` config group: ``headline_normalisation`` (absolute | displacement) and
        ``headline_aggregate`` (mean | pooled).
    paper_alpha : mapping
        The paper's alpha per basis label.
    comparisons : mapping, optional
        Data variant -> its paired comparisons (:func:`workbench.study.summary.frame_comparisons`).
    identities : mapping, optional
        Data variant -> the orderings that hold by construction (:func:`workbench.study.claims.result_identities`): printed ``<=`` with
        their reason, never tested.
    claims : mapping, optional
        The run's stored claims (:func:`workbench.study.claims.claims_at_m_equals_n`).

    Returns
    -------
    str
    """
    from workbench.study.summary import headline_alpha_column

    normalisation, aggregate = metric["headline_normalisation"], metric["headline_aggregate"]
    if normalisation not in ("absolute", "displacement") or aggregate not in ("mean", "pooled"):
        raise WorkbenchError(
            f"metric.headline_normalisation must be absolute|displacement and headline_aggregate "
            f"mean|pooled, got {normalisation!r}, {aggregate!r}"
        )
    column = headline_alpha_column(metric)
    if comparisons is not None and claims:
        from workbench.reporting.findings.comparisons import with_claims

        comparisons = with_claims({"data": {d: {"comparisons": c} for d, c in comparisons.items()}, "claims": claims})
    lines = []
    several = table["data"].nunique() > 1
    for data, part in table.groupby("data", sort=False):
        pca = part.loc[part["basis"] == "PCA", column].iloc[0]
        for solver in part.loc[part["basis"] != "PCA", "solver"].unique():
            rows = part[part["solver"] == solver].set_index("basis")[column]
            prefix = (f"{data}: " if several else "") + f"{column} with {solver}: "
            if comparisons is None:
                lines.append(
                    prefix + ", ".join(f"{basis} {rows[basis]:.2f}" for basis in rows.index) + f", PCA {pca:.2f}"
                )
                continue
            from workbench.stats.identities import identity_lookup
            from workbench.stats.statistics import ordering_text
            from workbench.stats.stored import comparison_lookup

            values = {
                **{(basis, solver): float(rows[basis]) for basis in rows.index},
                ("PCA", "projection"): float(pca),
            }
            lookup = identity_lookup((identities or {}).get(data, []), column)
            lines.append(
                prefix
                + ordering_text(
                    values,
                    comparison_lookup(comparisons.get(data, [])),
                    name=lambda key: key[0],
                    digits=3,
                    identity=lambda a, b: getattr(lookup(a, b), "reason", None),
                )
            )
    if comparisons is not None:
        lines.append(
            "'<': the paired per-frame difference's 95 % batch-means interval excludes 0 (H against QE and QE "
            "against PCA with lstsq at m = n: the paper's claim, its ratio's interval excludes 1); '~': it does "
            "not (the two are not distinguishable on these frames); '=': equal within the tie tolerance; "
            "'<= by construction': an identity of the bases and solvers, not a finding (docs/statistics.md)"
        )
    paper = ", ".join(f"{basis} {value}" for basis, value in paper_alpha.items())
    lines.append(f"paper (Kim & Ko, absolute alpha, QP solver with unstated constraints): {paper}")
    lines.append(PAPER_ALPHA_NOTE)
    return "\n".join(lines) + "\n"
