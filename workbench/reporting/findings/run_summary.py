"""The summary a run's report opens with: the paper's two claims, each as a ratio with its interval and a verdict,
on the training frames and held out at m = n, with what the design rests on (at most about 200 words).

Claim 1, QE far better than H (the paper's H/QE 7.2): reproduced when the interval of H/QE lies wholly above 1.
Claim 2, QE nearly as accurate as PCA (the paper's QE/PCA 1.16): reproduced when the interval of QE/PCA lies wholly
at or below 1.16, not reproduced when wholly above. Either is "not decided" when its interval holds the threshold
(:func:`workbench.stats.ratios.claim_verdict`); where QE <= PCA holds by construction, claim 2 is stated so, not
tested. Both claims are one metric, the run's headline alpha with least squares.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import pandas as pd

from workbench.reporting.findings.claims import PAPER_RATIOS, claim_verdicts, ratio_interval_text
from workbench.reporting.findings.comparisons import primary_data
from workbench.reporting.findings.run import PAPER_BASES, _alpha, caveat_texts
from workbench.stats.identities import identity_lookup, run_identities
from workbench.stats.statistics import Interval
from workbench.study.protocols import HELD_OUT
from workbench.study.regime import PAPER_REGIME_SUFFIX, is_paper_regime

SUMMARY_WORDS = 200
"""The summary's length limit in words."""


def claims_text(ratios: Mapping[str, Mapping], qe_spans_pca: bool = False) -> str:
    """The two claims' verdicts with their ratios and intervals (:func:`workbench.reporting.findings.claims.claim_verdicts`,
    brief), e.g. ``QE better than H: reproduced, H/QE 5.51 [4.54, 6.47]; the paper's 7.2 lies above it; QE nearly as
    accurate as PCA (QE/PCA <= 1.16): not reproduced, QE/PCA 3.12 [2.33, 3.92]``.

    Parameters
    ----------
    ratios : mapping
        ``H/QE`` and ``QE/PCA`` -> stored :class:`Interval` fields (``metrics.json`` ``data.<variant>.ratios``).
    qe_spans_pca : bool
        Whether QE <= PCA holds by construction.

    Returns
    -------
    str
        Empty unless both ratios are there.
    """
    if not {"H/QE", "QE/PCA"} <= set(ratios):
        return ""
    found = claim_verdicts(
        Interval.from_dict(ratios["H/QE"]), Interval.from_dict(ratios["QE/PCA"]), qe_spans_pca, brief=True
    )
    return f"{found.h_over_qe}; {found.qe_over_pca}"


def ratios_text(ratios: Mapping[str, Mapping]) -> str:
    """``H/QE 2.9 [2.1, 3.7]; QE/PCA 1.4 [0.9, 1.8]``: the ratios alone, with their intervals."""
    return "; ".join(ratio_interval_text(Interval.from_dict(value), key, brief=True) for key, value in ratios.items())


def design_text(facts: Mapping) -> str:
    """What the lead variant's ratio intervals rest on: frames, takes, batches and degrees of freedom."""
    interval = Interval.from_dict(next(iter((facts.get("ratios") or {}).values()), {"estimate": math.nan}))
    frames, takes = facts.get("n_eval_frames"), facts.get("n_eval_takes")
    if not frames:
        return ""
    text = f"{frames} frames" + (f" of {takes} take{'s' if takes != 1 else ''}" if takes else "")
    degrees = getattr(interval, "degrees", math.nan)
    if interval.block_frames:
        batches = f"batches of {interval.block_frames} frames" + (
            f", {degrees:.2g} degrees of freedom" if math.isfinite(degrees) else ""
        )
        text += f", {batches}"
    takes_said = interval_by_take(facts)
    return text + (f"; {takes_said}" if takes_said else "")


def interval_by_take(facts: Mapping) -> str:
    """What each take says on its own about H/QE (its ratio and the share of frames where H's alpha exceeds QE's),
    when the record has several takes: few takes make few batches, and this is what the interval cannot show."""
    per_take = ((facts.get("ratios") or {}).get("H/QE") or {}).get("per_take") or {}
    if len(per_take) < 2:
        return ""
    ratios = ", ".join(f"{value['ratio']:.3g}" for value in per_take.values())
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


def held_out_regime_text(metrics: Mapping, data: str) -> str:
    """The claims on the held-out variants at m = n of the lead variant's data (``<data> held-out ... m=n``)."""
    base = data[: -len(PAPER_REGIME_SUFFIX) - 1] if is_paper_regime(data) else data
    parts = []
    for name, facts in (metrics.get("data") or {}).items():
        if name == data or not is_paper_regime(name) or not name.startswith(f"{base} held-out"):
            continue
        ratios = facts.get("ratios") or {}
        if ratios:
            shown = ratios_text(ratios)
            replicates = next(iter(ratios.values())).get("n")
            unit = "folds" if facts.get("folds") else "frames"
            protocol = name[len(f"{base} held-out ") : -len(PAPER_REGIME_SUFFIX) - 1]
            protocol = HELD_OUT.get(protocol, protocol).removeprefix("held-out ")
            parts.append(f"{protocol} ({replicates} {unit}) {shown.replace('; ', ', ')}")
    return "Held out at m = n: " + "; ".join(parts) + "." if parts else ""


def beside_regime_text(table: pd.DataFrame, data: str, column: str, metrics: Mapping | None = None) -> str:
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
    spans = identity_lookup(run_identities(rows, facts), column)(("QE", "lstsq"), ("PCA", "projection"))
    return (
        f" Beside it, the coverage rule on {base} (m = {int(part['m'].iloc[0])}): H/QE "
        f"{values['H'] / values['QE']:.3g}, QE/PCA {values['QE'] / values['PCA']:.3g}"
        + (" (QE <= PCA by construction: rank m + 1)." if spans else ".")
    )


def run_summary(table: pd.DataFrame, column: str, metrics: Mapping) -> str:
    """The summary a report opens with (at most about 200 words): the paper's two claims and their verdicts on the
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
    spans = identity_lookup(run_identities(rows, facts), column)(("QE", "lstsq"), ("PCA", "projection"))
    ratios = facts.get("ratios") or {
        key: {"estimate": values[a] / values[b], "low": math.nan, "high": math.nan, "null": 1.0}
        for key, (a, b) in {"H/QE": ("H", "QE"), "QE/PCA": ("QE", "PCA")}.items()
    }
    m, n = int(part["m"].iloc[0]), int(part.loc[part["basis"] == "H", "n"].iloc[0])
    regime = "the paper's regime m = n" if m == n else f"not the paper's regime (basis.n_components={n} gives it)"
    coverage = (facts.get("pca") or {}).get("coverage_reached")
    reach = f", coverage {coverage:.4f}" if coverage is not None else ""
    caveats = caveat_texts(metrics)
    conditioning, design = conditioning_text(part, rows), design_text(facts)
    sentences = [
        f"Kim & Ko claim QE far better than H (H/QE {PAPER_RATIOS['H/QE']:.2g}) and nearly as accurate as PCA "
        f"(QE/PCA {PAPER_RATIOS['QE/PCA']:.3g}) at m = n = 18.",
        f"On {data} (m = {m}, n = {n}: {regime}{reach}), `{column}` with least squares: "
        f"{claims_text(ratios, spans is not None)}.",
        held_out_regime_text(metrics, data),
        beside_regime_text(table, data, column, metrics).strip(),
        f"{conditioning}." if conditioning else "",
        f"Intervals (95 %) rest on {design}." if design else "",
        f"Caveat: {caveats[0]}." if caveats else "",
    ]
    # within the budget: the coverage rule's sentence goes first, then the caveat's last clause, then its reason
    if len(" ".join(sentences).split()) > SUMMARY_WORDS:
        sentences[3] = ""
    if len(" ".join(sentences).split()) > SUMMARY_WORDS and caveats:
        sentences[-1] = f"Caveat: {caveats[0].rsplit('; ', 1)[0]}."
    if len(" ".join(sentences).split()) > SUMMARY_WORDS and caveats:  # what the data are, without why it matters
        sentences[-1] = f"Caveat: {caveats[0].split(': ', 1)[0]}."
    return " ".join(sentence for sentence in sentences if sentence)
