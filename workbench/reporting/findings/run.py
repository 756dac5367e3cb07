"""The findings of a run or a sweep, stated in sentences generated from its numbers (never written by hand).

:func:`run_findings` reads an alpha table (the columns of :data:`workbench.reporting.text.run.TABLE_COLUMNS`), the per-shape
intuitiveness and the facts the run recorded (``metrics.json``: paired comparisons, the offset of the affine
projection, the face region, the dataset's provenance), and says per data variant: the ordering of H, QE,
QE-linear and PCA under each solver, where every ``<`` is a paired per-frame difference whose 95 % interval
excludes zero (:mod:`workbench.stats.statistics`); the ratios H/QE and QE/PCA under every alpha variant beside
the paper's; m beside the paper's; what the constrained solvers do to QE and QE-linear against H, and why, from
the offset numbers; the weights an animator would face; the error in millimetres as a distribution; which hand
shapes the projection changes most; and the caveats that apply to the data. :func:`fit_findings` keeps a report's
findings within :data:`FINDINGS_WORDS` words, leaving out :class:`Detail` lines first.

The findings of a sweep and of the other bases are in :mod:`workbench.reporting.findings.sweep`.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import pandas as pd

from workbench.core.solvers import constrained_solvers, solver_text
from workbench.reporting.findings.caveats import stabilisation_caveat, weights_caveat
from workbench.reporting.findings.claims import NOT_TESTED, entry_text, lead_entries
from workbench.reporting.findings.claims import m_text as claims_m_text
from workbench.reporting.findings.comparisons import (
    adjusted_comparisons,
    finite_value,
    multiplicity_text,
    primary_data,
)
from workbench.stats.identities import identity_lookup, run_identities, scored_on_training_frames
from workbench.stats.statistics import (
    SIGNED,
    comparison_name,
    short_interval_text,
)
from workbench.stats.statistics import ordering_text as stated_ordering
from workbench.stats.stored import comparison_lookup
from workbench.study.claims import base_variant
from workbench.study.regime import is_paper_regime, paper_regime_name

PAPER_BASES = ("H", "QE", "PCA")
RUN_BASES = ("H", "QE", "QE-linear", "PCA")
QE_BASES = ("QE", "QE-linear")
ALPHA_VARIANTS = {
    "alpha_abs_mean": "abs mean",
    "alpha_abs_pooled": "abs pooled",
    "alpha_disp_mean": "disp mean",
    "alpha_disp_pooled": "disp pooled",
}
PCA_KEY = ("PCA", "projection")
FINDINGS_WORDS = 800
"""The most words a report's findings section holds (as ``wc -w`` counts its Markdown: a bullet's ``-`` is one);
:func:`fit_findings` leaves out :class:`Detail` lines beyond it."""


class Detail(str):
    """A finding that may be left out when the findings run over :data:`FINDINGS_WORDS`: its numbers are in the
    table ``where`` names. Lines of higher ``rank`` go first, the later of equal rank before the earlier."""

    rank: int
    where: str

    def __new__(cls, text: str, rank: int = 1, where: str = "the tables below") -> "Detail":
        line = super().__new__(cls, text)
        line.rank, line.where = rank, where
        return line


def words(blocks: Sequence) -> int:
    """The words of a section's paragraphs and bullet lists as ``wc -w`` counts their Markdown (``- `` of each
    bullet one word; tables and figures not counted)."""
    total = 0
    for block in blocks:
        if isinstance(block, str):
            total += len(block.split())
        elif isinstance(block, list):
            total += sum(len(str(item).split()) + 1 for item in block)
    return total


def fit_findings(sections: list, budget: int = FINDINGS_WORDS) -> list:
    """The report's sections with its findings within ``budget`` words: the :class:`Detail` lines of the bullet
    lists left out, highest rank (then latest) first, until the section fits, and one line saying what was left
    out and where its numbers are. Unchanged when the findings fit or there is no section 'Findings'."""
    found = next((section for section in sections if getattr(section, "heading", None) == "Findings"), None)
    if found is None or words(found.blocks) <= budget:
        return sections
    lists = [block for block in found.blocks if isinstance(block, list)]
    candidates = sorted(
        (
            (line.rank, k, j)
            for k, block in enumerate(lists)
            for j, line in enumerate(block)
            if isinstance(line, Detail)
        ),
        reverse=True,
    )
    dropped: list[Detail] = []
    note_words = 40  # the note that says what was left out
    for _, k, j in candidates:
        if words(found.blocks) + note_words <= budget:
            break
        dropped.append(lists[k][j])
        lists[k][j] = None
    for block in lists:
        block[:] = [line for line in block if line is not None]
    if dropped and lists:
        where = ", ".join(dict.fromkeys(line.where for line in dropped))
        lists[-1].append(
            f"**left out**: {len(dropped)} more finding{'s' if len(dropped) > 1 else ''}, to keep "
            f"this section within {budget} words; their numbers are in {where}."
        )
    return sections


def _alpha(part: pd.DataFrame, basis: str, solver: str, column: str) -> float:
    """The alpha of a basis under a solver in one data variant's rows (PCA: its projection row), NaN if absent."""
    rows = part[(part["basis"] == basis) & ((part["solver"] == solver) | (part["solver"] == "projection"))]
    return float(rows[column].iloc[0]) if len(rows) and column in rows else math.nan


def _fmt(value: float) -> str:
    return f"{value:.3g}"


def _percent(share: float) -> str:
    return f"{100 * share:.0f} %"


def paired_ordering_text(
    part: pd.DataFrame, solver: str, column: str, compare, bases: Sequence[str] = RUN_BASES, identity=None
) -> str:
    """The bases of one data variant from best to worst under a solver, ``<`` only where the paired per-frame
    difference's interval excludes zero, ``~`` with the interval where it does not, ``,`` without a comparison.

    Parameters
    ----------
    part : pandas.DataFrame
        The alpha-table rows of one data variant.
    solver : str
    column : str
    compare : callable or None
        ``compare((basis, solver), (basis, solver))`` -> the :class:`Interval` of the difference, or None.
    bases : sequence of str
    identity : callable, optional
        ``identity(a, b)`` -> the :class:`workbench.stats.identities.Identity` saying ``a <= b`` by
        construction, or None (:func:`workbench.stats.identities.identity_lookup`).
    """
    values = {
        (basis, "projection" if basis == "PCA" else solver): _alpha(part, basis, solver, column) for basis in bases
    }
    reason = None if identity is None else (lambda a, b: getattr(identity(a, b), "reason", None))
    return stated_ordering(
        values,
        compare or (lambda a, b: None),
        name=lambda key: key[0],
        digits=3,
        identity=reason,
        detail=lambda *args: "",
    )


def ratio_text(
    part: pd.DataFrame,
    paper_alpha: Mapping[str, float],
    solver: str = "lstsq",
    column: str = "alpha_abs_mean",
    spread: bool = True,
    paper_shown: bool = True,
    error: str = "",
    settings: Mapping | None = None,
) -> str:
    """H/QE and QE/PCA of one data variant in the headline column (with ``paper_shown``, beside the paper's), then
    ``error`` (:func:`error_text`), and (with ``spread``) how far the four alpha variants move H/QE (every variant's value is in the table 'Alpha beside
    the paper')."""
    columns = [name for name in ALPHA_VARIANTS if name in part.columns]
    if column not in columns:
        return ""
    texts = []
    for a, b in (("H", "QE"), ("QE", "PCA")):
        first, second = _alpha(part, a, solver, column), _alpha(part, b, solver, column)
        if math.isnan(first) or math.isnan(second):
            continue
        paper = paper_alpha.get(a, math.nan) / paper_alpha.get(b, math.nan)
        texts.append(
            f"{a}/{b} {first / second:.3g}" + (f" (paper {paper:.3g})" if paper_shown and math.isfinite(paper) else "")
        )
    if not texts:
        return ""
    ratios = [_alpha(part, "H", solver, name) / _alpha(part, "QE", solver, name) for name in columns]
    spread = (
        f"; over the {len(columns)} alpha variants H/QE runs from {min(ratios):.3g} to {max(ratios):.3g}, so "
        "no one ratio compares across datasets"
        if spread and len(columns) > 1 and all(map(math.isfinite, ratios))
        else ""
    )
    return f"with {solver_text(solver, settings)}, " + ", ".join(texts) + (f"; {error}" if error else "") + spread


def m_text(part: pd.DataFrame, paper: Mapping) -> str:
    """m beside the paper's, and whether the hand shapes can span the eigenfaces."""
    m = round(float(part["m"].iloc[0]), 1)
    n = float(part.loc[part["basis"] == "H", "n"].iloc[0]) if (part["basis"] == "H").any() else math.nan
    spans = "can span" if m <= n else "cannot span"
    reach = (
        f" reach coverage {float(part['coverage'].iloc[0]):.3g}"
        if "coverage" in part.columns
        else " (mean over the runs)"
    )
    return f"m = {m:g} eigenfaces{reach} (paper: m = {paper.get('m')}); the {n:g} hand shapes {spans} them" + (
        ", so QE can match PCA" if m <= n else ", so QE cannot reach PCA"
    )


def _verdict(compare, a: tuple, b: tuple, worse: str, better: str) -> str:
    """``worse than H (QE - H +0.135, 95 % interval [+0.09, +0.18] (method, n = k))`` / ``not distinguishable from
    H (...)`` from a paired interval of ``a - b``, or nothing without one."""
    interval = compare(a, b) if compare else None
    if interval is None:
        return ""
    detail = short_interval_text(interval, comparison_name(a[0], b[0], interval), SIGNED)
    if not interval.excludes_null:
        return f"not distinguishable from {b[0]}"
    return f"{worse if interval.sign > 0 else better} {b[0]} ({detail})"


def constraint_text(part: pd.DataFrame, column: str, solver: str, compare=None, settings: Mapping | None = None) -> str:
    """What a constrained solver does to QE and QE-linear against H, relative to least squares, with the paired
    comparison of each against H under that solver."""
    h0, h1 = _alpha(part, "H", "lstsq", column), _alpha(part, "H", solver, column)
    moves, verdicts = [], []
    for basis in QE_BASES:
        q0, q1 = _alpha(part, basis, "lstsq", column), _alpha(part, basis, solver, column)
        if math.isnan(q0) or math.isnan(q1):
            continue
        moves.append(f"{basis}'s alpha x{q1 / q0:.2f} ({_fmt(q0)} to {_fmt(q1)})")
        verdict = _verdict(compare, (basis, solver), ("H", solver), "worse than", "better than")
        verdicts.append(
            f"{basis} is {verdict}" if verdict else f"{basis} {_fmt(q1)} against H {_fmt(h1)} (no paired interval)"
        )
    return f"with {solver_text(solver, settings)} " + ", ".join(moves) + f", H's x{h1 / h0:.2f}; " + ", ".join(verdicts)


def _row(rows: Sequence[Mapping], data: str, basis: str, solver: str) -> Mapping:
    """A row of ``metrics.json`` (empty when absent)."""
    return next(
        (row for row in rows if row.get("data") == data and row.get("basis") == basis and row.get("solver") == solver),
        {},
    )


OFFSET_SHARE_STATED = 0.1
"""Below this share of the constrained QE's squared error along ``(I - P) mu`` the offset is not offered as the
reason constraints hurt QE."""
LINEAR_LOSS_STATED = 0.5
"""The offset is offered as a reason only when QE-linear's relative loss under the constraint is below this
fraction of QE's (``x1.8`` against ``x7.1``: yes; ``x1.54`` against ``x1.62``: no)."""


def offset_text(
    data: str, part: pd.DataFrame, column: str, solver: str, facts: Mapping, rows: Sequence[Mapping], settings=None
) -> str:
    """Why a constraint on the weights costs affine QE more than QE-linear, from the numbers the run kept: the
    offset ``(I - P) mu`` that every affine QE shape carries, what the weights' sum does to it under least squares
    and under the constraint, and how QE-linear (shapes in the eigenfaces' span, no offset) fares with as many
    frames needing negative weights. Empty when the run kept no offset."""
    offset = facts.get("offset") or {}
    qe0, qe1 = _row(rows, data, "QE", "lstsq"), _row(rows, data, "QE", solver)
    lin0, lin1 = _row(rows, data, "QE-linear", "lstsq"), _row(rows, data, "QE-linear", solver)
    if not offset or not qe0.get("weights") or not qe1.get("weights"):
        return ""
    share0, share1 = qe0.get("offset_error_share", math.nan), qe1.get("offset_error_share", math.nan)
    verb = "need" if finite_value(qe0["weights"].get("needs_negative_share")) else "have"
    text = (
        f"every affine QE shape carries (I-P) mu, the capture mean's part outside the eigenfaces' span "
        f"({offset['norm']:.3g} mm"
        + (
            f", {_percent(offset['ratio'])} of the median frame's displacement"
            if math.isfinite(offset.get("ratio", math.nan))
            else ""
        )
        + f"); QE's least-squares weights sum to {qe0['weights']['sum_median']:.2f} (median), "
        f"{_percent(needs_negative(qe0['weights']))} of frames {verb} a negative weight; with "
        f"{solver_text(solver, settings)} the sum is {qe1['weights']['sum_median']:.2f} and "
        f"{_percent(share1)} of QE's squared error lies along (I-P) mu (least squares: {_percent(share0)})"
    )
    if lin0.get("weights") and lin1.get("weights"):
        l0, l1 = _alpha(part, "QE-linear", "lstsq", column), _alpha(part, "QE-linear", solver, column)
        q0, q1 = _alpha(part, "QE", "lstsq", column), _alpha(part, "QE", solver, column)
        verb = "need" if finite_value(lin0["weights"].get("needs_negative_share")) else "have"
        text += (
            f". QE-linear (no offset): {_percent(needs_negative(lin0['weights']))} of frames {verb} a negative "
            f"weight, alpha x{l1 / l0:.2f} against QE's x{q1 / q0:.2f}"
        )
        needs_negative_too = needs_negative(lin0["weights"]) >= 0.8 * needs_negative(qe0["weights"])
        loses_less = l1 / l0 - 1.0 < LINEAR_LOSS_STATED * (q1 / q0 - 1.0)
        if needs_negative_too and loses_less and share1 >= OFFSET_SHARE_STATED:
            text += (
                ". So negative weights alone do not explain the loss; the offset does in part: the constraint "
                "can no longer hold the weights' sum where the offset needs it"
            )
        elif needs_negative_too and not loses_less:
            text += (
                ". QE-linear, needing as many negative weights, loses almost as much: these numbers do not "
                "single out the offset"
            )
    return text


def minimum_norm_label(row: Mapping, solver: str) -> str:
    """`` (minimum-norm, rank r of n)`` for least-squares weights of a rank-deficient basis (many weight vectors
    give its error; the solver returned the shortest), else empty."""
    conditioning = row.get("basis_conditioning") or {}
    rank, size = conditioning.get("rank"), conditioning.get("n_shapes")
    if solver != "lstsq" or rank is None or size is None or rank >= size:
        return ""
    return f" (minimum-norm, rank {rank} of {size})"


def needs_negative(weights: Mapping) -> float:
    """The share of frames needing a negative weight (nnls error above lstsq's beyond the tie tolerance), or, for
    records without it, the share with a negative least-squares weight."""
    value = weights.get("needs_negative_share")
    return value if finite_value(value) else weights["negative_share"]


def weights_text(data: str, solvers: Sequence[str], rows: Sequence[Mapping]) -> str:
    """The animator's side: under least squares (else the first solver), each basis's largest |w| and roughness
    (the share of frames outside [0, 1] and the sparsity are in the table 'Error in millimetres and the weights');
    least-squares weights of a rank-deficient basis labelled minimum-norm with the rank (they describe the
    pseudo-inverse's choice, not the basis); and the share of frames that need a negative weight
    (:func:`workbench.numerics.metrics.needs_negative_share`)."""
    parts, needing = [], []
    for solver in [solver for solver in solvers if solver == "lstsq"] or list(solvers)[:1]:
        found = [(basis, _row(rows, data, basis, solver)) for basis in RUN_BASES]
        found = [(basis, row) for basis, row in found if row.get("weights")]
        if found:
            parts.append(
                f"{solver}: "
                + "; ".join(
                    f"{basis}{minimum_norm_label(row, solver)} {row['weights']['max_abs']:.3g}, "
                    f"{row['weights']['roughness']:.3g}"
                    for basis, row in found
                )
            )
        if solver == "lstsq":
            needing = [
                f"{basis} {_percent(row['weights']['needs_negative_share'])}"
                for basis, row in found
                if finite_value(row["weights"].get("needs_negative_share"))
            ]
    if not parts:
        return ""
    return (
        "the weights an animator would get (largest |w|, roughness in 1/s^4; more in the table 'Error in "
        "millimetres and the weights'), "
        + "; ".join(parts)
        + (f"; frames that need a negative weight (nnls error above lstsq's): {', '.join(needing)}" if needing else "")
    )


def error_text(part: pd.DataFrame, solver: str, facts: Mapping) -> str:
    """The median per-frame error in millimetres over the face region, each basis under a solver (the region,
    percentiles and maxima in the table 'Error in millimetres and the weights')."""
    if "err_mm_median" not in part.columns:
        return ""
    entries = [
        f"{basis} {value:.3g}"
        for basis in RUN_BASES
        if not math.isnan(value := _alpha(part, basis, solver, "err_mm_median"))
    ]
    if not entries:
        return ""
    return f"median per-frame error ({solver}) " + ", ".join(entries) + " mm"


def closeness_text(intuitiveness: Sequence[Mapping], projection: str = "affine", count: int = 2) -> str:
    """Where a projection loses a hand shape's look: the shapes it changes most, and the median closeness.

    Parameters
    ----------
    intuitiveness : sequence of mapping
        ``metrics.json`` rows: ``shape``, ``projection``, ``relative_distance``, ``cosine``.
    projection : str
    count : int
        Shapes named.
    """
    rows = sorted(
        (row for row in intuitiveness if row["projection"] == projection), key=lambda row: -row["relative_distance"]
    )
    if not rows:
        return ""
    cosines = sorted(row["cosine"] for row in rows)
    median = (
        cosines[len(cosines) // 2]
        if len(cosines) % 2
        else (cosines[len(cosines) // 2 - 1] + cosines[len(cosines) // 2]) / 2
    )
    named = ", ".join(f"{row['shape']} (cosine {row['cosine']:.2f})" for row in rows[:count])
    return f"{named}; median cosine of the {len(rows)} shapes {median:.2f}"


def closeness_line(intuitiveness: Sequence[Mapping]) -> str:
    """The shapes each projection (QE, QE-linear) changes most, in one sentence."""
    parts = [
        f"{label}: {text}"
        for label, projection in (("QE", "affine"), ("QE-linear", "linear"))
        if (text := closeness_text(intuitiveness, projection))
    ]
    return ("the projection changes most, " + "; ".join(parts)) if parts else ""


def caveat_texts(metrics: Mapping) -> list[str]:
    """The caveats that apply to a run, from its facts: what the data are made of, a stabilisation the face moves
    and quasi-eigen weights no animator could use (:mod:`workbench.reporting.findings.caveats`, each against its
    stated threshold), and which data variants were scored on the frames their bases were fitted on. ``metrics``
    is a record's ``metrics.json`` in the current layout (:func:`workbench.record.record.current_metrics`: every
    data variant states its protocol and notes), or a part of it."""
    dataset = metrics.get("dataset") or {}
    provenance = dataset.get("provenance") or {}
    kind = provenance.get("kind")
    caveats = []
    if kind == "ict_livelink":
        driven = sorted({shape for shapes in (provenance.get("arkit_mapping") or {}).values() for shape in shapes})
        hand = dataset.get("hand_names") or []
        among = sum(name in driven for name in hand)
        caveats.append(
            f"the capture is a noise-free linear blend of {len(driven) or 'the'} ICT FaceKit shapes, "
            f"{'all ' if among == len(hand) else ''}{among} of the {len(hand)} hand shapes among them: H, and "
            "QE made from H's shapes, are scored on motion built from H's own shapes, and PCA on a blend of fixed "
            "shapes, which flatters all three against a real capture"
        )
    if provenance.get("performer_and_basis") == "different faces":
        scale = (provenance.get("placement") or {}).get("scale")
        caveats.append(
            "the hand shapes come from another face (ICT FaceKit"
            + (f", scaled by {scale:.3f} into the performer's frame" if scale else "")
            + "): H's error includes the mismatch between the two faces, not only the motion its shapes "
            "cannot span"
        )
    if kind == "synthetic":
        caveats.append(
            "the data are generated by the workbench from the muscles whose full contractions are the hand shapes "
            "(combined non-linearly), and QE is made from those shapes too: H and QE are both scored on motion "
            "built from H's own shapes, which flatters H against a real capture; H against QE here weighs the "
            "generator's non-linearity against PCA's truncation, not a sculpted basis"
        )
    caveats += [text for text in (stabilisation_caveat(metrics), weights_caveat(metrics)) if text]
    trained = [
        data
        for data, facts in (metrics.get("data") or {}).items()
        if facts["protocol"] == "training frames"
        and not any(note.startswith(("split 'tail'", "split 'other_take'")) for note in facts["notes"])
    ]
    if trained:
        held = any(facts["protocol"] != "training frames" for facts in (metrics.get("data") or {}).values())
        caveats.append(
            f"{', '.join(trained)} {'is' if len(trained) == 1 else 'are'} scored on the training frames "
            "(split 'same', the paper's protocol): PCA and QE are fitted to the frames they reconstruct"
            + ("; the held-out variants are not" if held else "; no frames were held out")
        )
    return caveats


def held_out_text(
    held: pd.DataFrame,
    trained: pd.DataFrame,
    column: str,
    facts: Mapping,
    trained_facts: Mapping,
    solver: str = "lstsq",
) -> str:
    """A held-out variant against its training frames: each basis's alpha under a solver held out over trained
    (both values, and what was held out, are in the table 'Training frames and held-out frames')."""
    parts = []
    for basis in RUN_BASES:
        a, b = _alpha(held, basis, solver, column), _alpha(trained, basis, solver, column)
        if not (math.isnan(a) or math.isnan(b)):
            parts.append(f"{basis} x{a / b:.3g}")
    if not parts:
        return ""
    return "held out / training frames: " + ", ".join(parts)


def run_findings(
    table: pd.DataFrame,
    column: str,
    paper: Mapping,
    intuitiveness: Mapping[str, Sequence[Mapping]],
    metrics: Mapping | None = None,
    config: Mapping | None = None,
) -> list[str]:
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
    metrics : mapping, optional
        The run's ``metrics.json``: its paired comparisons, offsets, weights and face regions, and the dataset's
        provenance. Without it no ordering is claimed (values are listed from smallest to largest).
    config : mapping, optional
        The run's resolved config (the split).

    Returns
    -------
    list of str
        The "how to read" line (interval method, primary contrasts, Holm) once, then per data variant its ordering,
        ratios, m and median error; the constraints, their cause, the weights and the shapes the projection changes
        are said for the lead variant scored on its training frames only (the others' are in the report's tables),
        then the caveats.
    """
    metrics, config = metrics or {}, config or {}
    settings = config.get("solver")  # each solver's kind and bounds
    data_facts, rows = metrics.get("data") or {}, metrics.get("rows") or []
    solvers = [solver for solver in dict.fromkeys(table["solver"]) if solver != "projection"]
    parts = dict(list(table.groupby("data", sort=False)))
    adjusted = adjusted_comparisons(metrics, settings)
    lines = [multiplicity_text(metrics, settings)] if adjusted else []
    lines += claims_lines(metrics)
    trained = [data for data in parts if scored_on_training_frames(data_facts.get(data) or {})]
    detailed = (primary_data(metrics) if primary_data(metrics) in trained else trained[0]) if len(trained) > 1 else None
    said = {"paper": False}  # the paper's ratios: said on the first line that gives ratios
    for data, part in parts.items():
        facts = data_facts.get(data) or {}
        compare = comparison_lookup(adjusted[data]) if adjusted.get(data) else None
        bases = [basis for basis in RUN_BASES if (part["basis"] == basis).any()]
        trained_here = facts.get("protocol", "training frames") == "training frames"  # held out: its own line
        if paper_regime_name(data) in parts and "lstsq" in solvers and trained_here:  # beside the paper's regime
            lines.append(
                f"**{data}** (the coverage rule, beside {paper_regime_name(data)}): "
                f"{_ratios(part, paper, column, False, said, settings=settings)}; {m_text(part, paper)}."
            )
            continue
        identity = identity_lookup(
            run_identities([row for row in rows if row.get("data") == data], facts, settings), column
        )
        lead = detailed is None or data == detailed
        shown = solvers if lead or "lstsq" not in solvers else ["lstsq"]  # the others' are in the tables
        ordering = "; ".join(
            f"{solver}: {paired_ordering_text(part, solver, column, compare, bases, identity)}" for solver in shown
        )
        claim = "" if compare else " (no paired intervals in this record: no order is claimed)"
        if facts.get("protocol", "training frames") != "training frames":
            base = next((row["train_on"] for row in rows if row.get("data") == data), None)
            text = held_out_text(part, parts[base], column, facts, data_facts.get(base) or {}) if base in parts else ""
            m_base = f"; training frames: m = {float(parts[base]['m'].iloc[0]):g}" if base in parts else ""
            lines.append(
                Detail(
                    f"**{data}** ({fitted_m_text(part, facts)}{m_base}): `{column}` from best to "
                    f"worst{claim}, {ordering}" + (f"; {text}" if text else "") + ".",
                    1,
                    "the table 'Training frames and held-out frames'",
                )
            )
            continue  # its error in mm: the table 'Training frames and held-out frames'
        lines.append(f"**{data}**: `{column}` from best to worst{claim}, {ordering}.")
        if "lstsq" in solvers:
            ratios = _ratios(
                part, paper, column, lead, said, error_text(part, "lstsq", facts) if lead else "", settings
            )
            if ratios:
                lines.append(f"**{data}**: {ratios}.")
        if not lead:  # the lead variant's details stand for the others' (m: table 'Run facts'; mm: the tables)
            continue
        if not is_paper_regime(data):  # at m = n by construction
            lines.append(f"**{data}**: {m_text(part, paper)}.")
        lines += _detail_lines(data, part, column, solvers, compare, facts, rows, intuitiveness.get(data, []), settings)
    lines += [f"**caveat**: {caveat}." for caveat in caveat_texts(metrics)]
    return lines


def fitted_m_text(part: pd.DataFrame, facts: Mapping) -> str:
    """``m = 8``, or ``m = [8, 9, 8, 8, 9]`` for a cross-validated variant whose folds kept different m."""
    folds = [int(m) for m in (facts.get("folds") or {}).get("m") or []]
    if len(set(folds)) > 1:
        return f"m = {folds}"
    return f"m = {float(part['m'].iloc[0]):g}"


def claims_lines(metrics: Mapping) -> list[str]:
    """The paper's two claims as the run stored them (:mod:`workbench.study.claims`), one line per protocol of the
    lead variant: the same verdicts as the summary and the first printed sentence; nothing is decided here."""
    claims = metrics.get("claims")
    if not claims:  # a record written before claims were kept: its summary says so
        return []
    entries = lead_entries(claims, base_variant(primary_data(metrics) or ""))
    if not entries:
        return [f"**the paper's claims**: {claims.get('not_tested') or NOT_TESTED}."]
    return [
        f"**the paper's claims** on {entry['data']} ({entry['protocol_text']}, {claims_m_text(entry)}, "
        f"`{claims['column']}`, {claims['solver']}): {entry_text(entry)}."
        for entry in entries
    ]


def _ratios(part: pd.DataFrame, paper: Mapping, column: str, spread: bool, said: dict, error="", settings=None) -> str:
    """:func:`ratio_text` with least squares, the paper's ratios beside the first that is said only."""
    shown = not said["paper"]
    text = ratio_text(
        part, paper.get("alpha", {}), column=column, spread=spread, paper_shown=shown, error=error, settings=settings
    )
    said["paper"] = said["paper"] or bool(text)
    return text


def _detail_lines(
    data: str,
    part: pd.DataFrame,
    column: str,
    solvers: Sequence[str],
    compare,
    facts: Mapping,
    rows: Sequence[Mapping],
    intuitiveness: Sequence[Mapping],
    settings: Mapping | None = None,
) -> list[str]:
    """The findings said for the lead data variant only: what the constrained solvers do and why, the weights
    and the shapes the projection changes most (see :func:`run_findings`); each a :class:`Detail` that
    :func:`fit_findings` may leave out."""
    lines = []
    # the first constrained solver (nnls) said; the others' alpha is in the table 'Alpha beside the paper'
    constrained = constrained_solvers(solvers, settings)[:1] if "lstsq" in solvers else []
    for k, solver in enumerate(constrained):
        lines.append(
            Detail(
                f"**{data}**: " + constraint_text(part, column, solver, compare, settings) + ".",
                2,
                "the tables 'Alpha beside the paper' and 'Paired comparisons within the run'",
            )
        )
        why = offset_text(data, part, column, solver, facts, rows, settings) if k == 0 else ""
        if why:
            lines.append(Detail(f"**{data}**: why: {why}.", 3, "the run record (metrics.json: offset)"))
    weights = weights_text(data, solvers, rows)
    if weights:
        lines.append(Detail(f"**{data}**: {weights}.", 4, "the table 'Error in millimetres and the weights'"))
    closeness = closeness_line(intuitiveness)
    if closeness:
        lines.append(Detail(f"**{data}**: {closeness}.", 5, "the figures of the hand shapes' intuitiveness"))
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
        rows.append(
            {
                "data": data,
                "points": values["n_points"],
                "training frames": values["n_train_frames"],
                "evaluated frames": values["n_eval_frames"],
                "m": pca["m"],
                "coverage": round(float(pca["coverage_reached"]), 4),
                "PCA method": pca["method"],
                "empty PCA axes": "; ".join(
                    f"{projection}: {', '.join(map(str, qe['empty_axes'])) or 'none'}"
                    for projection, qe in values["quasi_eigen"].items()
                ),
            }
        )
    return pd.DataFrame.from_records(rows)


def shared_notes(metrics: Mapping) -> tuple[list[str], dict[str, list[str]]]:
    """The run's notes, those every data variant shares once and the rest per variant (``metrics`` in the current
    layout, :func:`workbench.record.record.current_metrics`).

    Returns
    -------
    shared : list of str
    own : dict
        Data variant -> its notes not in ``shared``.
    """
    notes = {data: list(values["notes"]) for data, values in metrics["data"].items()}
    first = next(iter(notes.values()), [])
    shared = [note for note in first if all(note in other for other in notes.values())]
    return shared, {data: [note for note in own if note not in shared] for data, own in notes.items()}
