"""The summary a run's report opens with: the paper's two claims as the run stored them
(:mod:`workbench.study.claims`), on the training frames and on each held-out protocol at m = n, whether held out
agrees with the training frames, and what each interval rests on (at most about 250 words). Nothing here decides a
verdict: the text renders the record's ``claims`` (:mod:`workbench.reporting.findings.claims`).
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import pandas as pd

from workbench.reporting.findings.claims import (
    NO_CLAIMS,
    NOT_TESTED,
    PAPER_RATIOS,
    agreement_sentence,
    entry_text,
    lead_entries,
    m_text,
    number,
    rests_on_sentence,
    short_entry_text,
)
from workbench.reporting.findings.comparisons import primary_data
from workbench.reporting.findings.run import PAPER_BASES, _alpha, caveat_texts
from workbench.stats.identities import identity_lookup, run_identities
from workbench.study.claims import TRAINING, base_variant
from workbench.study.regime import PAPER_REGIME_SUFFIX, is_paper_regime

SUMMARY_WORDS = 250
"""A run summary's words at most: 200 until the claims were stored (issue 52) and the summary gained each held-out
protocol's verdicts, the sentence on where they differ from the training frames and what each interval rests on;
50 more keep the caveat and the conditioning of a paper-size run with two held-out protocols."""
"""The summary's length limit in words."""


def claims_text(claims: Mapping | None, data: str) -> str:
    """The stored claims of one variant's training frames
    (:func:`workbench.reporting.findings.claims.entry_text`), e.g. ``QE better than H: reproduced, H/QE 5.51
    [4.54, 6.47] above 1; the paper's 7.2 lies above the interval; QE nearly as accurate as PCA (QE/PCA <= 1.5):
    ...``; empty when the record keeps none for it."""
    entry = next((e for e in lead_entries(claims, base_variant(data)) if e["protocol"] == TRAINING), None)
    return entry_text(entry) if entry else ""


def held_out_claims_text(entries: Sequence[Mapping]) -> str:
    """``Held out at m = n: held-out tail of each take (m = 18): QE better than H: ...; ...``: every held-out
    protocol's stored claims."""
    parts = [
        f"{entry['protocol_text'].removeprefix('held-out ')}"
        + (f" ({m_text(entry)})" if len(set(entry["m"])) > 1 else "")
        + f": {short_entry_text(entry)}"
        for entry in entries
        if entry["protocol"] != TRAINING
    ]
    return "Held out at m = n: " + "; ".join(parts) + "." if parts else ""


def interval_by_take(facts: Mapping) -> str:
    """What each take says on its own about H/QE (its ratio and the share of frames where H's alpha exceeds QE's),
    when the record has several takes: few takes make few batches, and this is what the interval cannot show."""
    per_take = ((facts.get("ratios") or {}).get("H/QE") or {}).get("per_take") or {}
    if len(per_take) < 2:
        return ""
    ratios = ", ".join(number(value["ratio"]) for value in per_take.values())
    low, high = (100 * f(value["share_above"] for value in per_take.values()) for f in (min, max))
    shares = f"{low:.0f} %" if round(low) == round(high) else f"{low:.0f}-{high:.0f} %"
    return f"H/QE per take {ratios}, H worse than QE on {shares} of each take's frames"


def conditioning_text(part: pd.DataFrame, rows: Sequence[Mapping]) -> str:
    """H's and QE's condition numbers (or ranks) and largest least-squares |w| side by side."""
    found = []
    for basis in ("H", "QE"):
        conditioning = next(
            (
                row.get("basis_conditioning")
                for row in rows
                if row.get("basis") == basis and row.get("solver") == "lstsq" and row.get("basis_conditioning")
            ),
            None,
        )
        largest = _alpha(part, basis, "lstsq", "w_max_abs")
        if not conditioning or math.isnan(largest):
            return ""
        cond = (
            f"rank {conditioning['rank']} of {conditioning['n_shapes']}"
            if conditioning["rank"] < conditioning["n_shapes"]
            else f"condition number {conditioning['condition_number']:.3g}"
        )
        found.append(f"{basis} {cond}, largest |w| {largest:.3g}")
    return "; ".join(found) + " (the least-squares weights an animator gets)"


def beside_regime_text(
    table: pd.DataFrame, data: str, column: str, metrics: Mapping | None = None, solvers: Mapping | None = None
) -> str:
    """The summary's sentence on the coverage rule's run beside the paper's regime: its m, H/QE and QE/PCA with
    least squares, and (given the run's ``metrics``) whether QE <= PCA holds there by construction (empty unless
    ``data`` is an m = n variant of ``basis.paper_regime`` whose coverage-rule variant is in the table)."""
    if not is_paper_regime(data):
        return ""
    base = data[: -len(PAPER_REGIME_SUFFIX) - 1]
    part = table[table["data"] == base]
    values = {basis: _alpha(part, basis, "lstsq", column) for basis in PAPER_BASES}
    if not len(part) or any(math.isnan(value) for value in values.values()):
        return ""
    rows = [row for row in (metrics or {}).get("rows") or [] if row.get("data") == base]
    facts = ((metrics or {}).get("data") or {}).get(base) or {}
    spans = identity_lookup(run_identities(rows, facts, solvers), column)(("QE", "lstsq"), ("PCA", "projection"))
    return (
        f" Beside it, the coverage rule on {base} (m = {int(part['m'].iloc[0])}): H/QE "
        f"{values['H'] / values['QE']:.3g}, QE/PCA {values['QE'] / values['PCA']:.3g}"
        + (" (QE <= PCA by construction: rank m + 1)." if spans else ".")
    )


def run_summary(table: pd.DataFrame, column: str, metrics: Mapping, solvers: Mapping | None = None) -> str:
    """The summary a report opens with (at most about 250 words): the paper's two claims and their verdicts on the
    lead variant (the paper's regime when the run has it), held out at m = n, the coverage m reaches, H's and QE's
    conditioning, what the intervals rest on, and the caveat that matters most. Pages put it above the findings.

    Parameters
    ----------
    table : pandas.DataFrame
        The run's alpha table.
    column : str
        The headline alpha column.
    metrics : mapping
        The run's ``metrics.json``.
    solvers : mapping, optional
        The run's ``solver`` settings (its config): their bounds decide which solvers nest.

    Returns
    -------
    str
        Empty when the lead data variant lacks H, QE or PCA with least squares.
    """
    data = primary_data(metrics) or (table["data"].iloc[0] if len(table) else None)
    part = table[table["data"] == data]
    values = {basis: _alpha(part, basis, "lstsq", column) for basis in PAPER_BASES}
    if not len(part) or any(math.isnan(value) for value in values.values()):
        return ""
    facts = (metrics.get("data") or {}).get(data) or {}
    rows = [row for row in metrics.get("rows") or [] if row.get("data") == data]
    claims = metrics.get("claims")
    entries = lead_entries(claims, base_variant(data))
    m, n = int(part["m"].iloc[0]), int(part.loc[part["basis"] == "H", "n"].iloc[0])
    regime = "the paper's regime m = n" if m == n else f"not the paper's regime (basis.n_components={n} gives it)"
    coverage = (facts.get("pca") or {}).get("coverage_reached")
    reach = f", coverage {coverage:.4f}" if coverage is not None else ""
    caveats = caveat_texts(metrics)
    conditioning = conditioning_text(part, rows)
    training = claims_text(claims, data) if claims else ""
    if not claims:
        said = f"{NO_CLAIMS}."
    elif training:
        said = f"On {data} (m = {m}, n = {n}: {regime}{reach}), `{claims['column']}` with least squares: {training}."
    else:
        said = f"On {data} (m = {m}, n = {n}: {regime}{reach}): {claims.get('not_tested') or NOT_TESTED}."
    takes_said = interval_by_take(facts)
    sentences = [
        f"Kim & Ko claim QE far better than H (H/QE {PAPER_RATIOS['H/QE']:.2g}) and nearly as accurate as PCA "
        f"(QE/PCA {PAPER_RATIOS['QE/PCA']:.3g}) at m = n = 18.",
        said,
        held_out_claims_text(entries),
        agreement_sentence(entries),
        beside_regime_text(table, data, column, metrics, solvers).strip(),
        f"{conditioning}." if conditioning else "",
        rests_on_sentence(entries) + (f" {takes_said[0].upper()}{takes_said[1:]}." if takes_said else ""),
        caveat_sentence(caveats, caveats[0] if caveats else ""),
    ]
    # within the budget: the coverage rule's sentence goes first, then the conditioning, then the caveat's last
    # clause, then its reason, then the caveat itself (the summary still says how many the findings hold); the
    # claims and what each interval rests on stay
    for index in (4, 5):
        if len(" ".join(sentences).split()) > SUMMARY_WORDS:
            sentences[index] = ""
    for shorter in (lambda text: text.rsplit("; ", 1)[0], lambda text: text.split(": ", 1)[0], lambda text: ""):
        if len(" ".join(sentences).split()) > SUMMARY_WORDS and caveats:
            sentences[-1] = caveat_sentence(caveats, shorter(caveats[0]))
    return " ".join(sentence for sentence in sentences if sentence)


def caveat_sentence(caveats: Sequence[str], first: str) -> str:
    """``Caveat: <first>. 2 more caveats in the findings.``, or ``3 caveats in the findings.`` when the first is
    left out to keep the summary within its words: the summary always says that caveats exist."""
    more = len(caveats) - (1 if first else 0)
    rest = f"{more}{' more' if first else ''} caveat{'s' if more != 1 else ''} in the findings." if more else ""
    return " ".join(part for part in (f"Caveat: {first}." if first else "", rest) if part)
