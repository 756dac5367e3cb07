"""The paper's two claims as a report states them: the text of the verdicts the run stored (``metrics.json``
``claims``, :func:`workbench.study.claims.claims_at_m_equals_n`). Nothing here decides or computes a verdict; the
first printed sentence, the summary, the findings, the comparisons table's primary rows, the headline figure and
sweep summaries all read them through this module, so that each claim has one verdict per protocol everywhere.

Claim 1 ("QE better than H") is superiority of QE over H: its direction (H/QE above 1) and, apart, where the
paper's 7.2 lies. Claim 2 ("QE nearly as accurate as PCA") is non-inferiority against the declared margin
(``metric.claim_margin``) and, apart, whether the paper's 1.16 lies inside the interval.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

from workbench.study.claims import (
    ABOVE,
    BELOW,
    NOT_DECIDED,
    NOT_ESTIMABLE,
    NOT_REPRODUCED,
    NOT_TESTED,
    PAPER_RATIOS,
    PROTOCOL_TEXT,
    REPRODUCED,
    REVERSED,
    TRAINING,
)

__all__ = [
    "CLAIM_1",
    "CLAIM_2",
    "NOT_DECIDED",
    "NOT_ESTIMABLE",
    "NOT_REPRODUCED",
    "NOT_TESTED",
    "PAPER_RATIOS",
    "REPRODUCED",
    "REVERSED",
    "NO_CLAIMS",
]

CLAIM_1 = "QE better than H"
CLAIM_2 = "QE nearly as accurate as PCA"
NO_CLAIMS = "the record keeps no claims (written before runs stored them): rerun it for the paper's claims"
RATIOS = {"H/QE": CLAIM_1, "QE/PCA": CLAIM_2}
"""Each claim's ratio -> its name."""
PROTOCOL_TRAINING = PROTOCOL_TEXT[TRAINING]


def number(value: float) -> str:
    """Three significant digits, trailing zeros kept (``1.00``, ``2.05``, ``746``); ``-`` for NaN."""
    if not math.isfinite(value):
        return "-" if math.isnan(value) else str(value)
    return f"{value:#.3g}".rstrip(".") if abs(value) < 1e3 else f"{value:.3g}"


def ratio_text(entry: Mapping, name: str) -> str:
    """``H/QE 2.05 [1.31, 3.23]``, or ``H/QE not estimable: <why>`` (no numbers) when the interval cannot inform."""
    if entry.get("why_not_estimable"):
        return f"{name} {NOT_ESTIMABLE}: {entry['why_not_estimable']}"
    return f"{name} {number(entry['estimate'])} [{number(entry['low'])}, {number(entry['high'])}]"


def why_short(stored: Mapping) -> str:
    """Why a ratio is not estimable, without what its interval rests on (said once, per interval, elsewhere)."""
    return stored["why_not_estimable"].split(" (", 1)[0]


def first_claim_text(entry: Mapping) -> str:
    """Claim 1 on one protocol: ``QE better than H: reproduced, H/QE 2.05 [1.31, 3.23] above 1; the paper's 7.2 lies
    above the interval`` (direction, then size)."""
    if entry["verdict"] == NOT_ESTIMABLE:
        return f"{CLAIM_1}: {NOT_ESTIMABLE}: H/QE {why_short(entry)}"
    where = {REPRODUCED: "above 1", REVERSED: "below 1", NOT_DECIDED: "holds 1"}[entry["verdict"]]
    size = {ABOVE: "above", BELOW: "below"}.get(entry["size"], "inside")
    return (
        f"{CLAIM_1}: {entry['verdict']}, {ratio_text(entry, 'H/QE')} {where}; "
        f"the paper's {PAPER_RATIOS['H/QE']:.2g} lies {size} the interval"
    )


def second_claim_text(entry: Mapping) -> str:
    """Claim 2 on one protocol: ``QE nearly as accurate as PCA (QE/PCA <= 1.5): reproduced, QE/PCA 1.10 [1.02,
    1.19]; the paper's 1.16 lies inside the interval`` (non-inferiority, then consistency with the paper)."""
    head = f"{CLAIM_2} (QE/PCA <= {entry['margin']:g})"
    if entry["verdict"] == NOT_TESTED:
        return f"{CLAIM_2}: {NOT_TESTED}: {entry['not_tested']}"
    if entry["verdict"] == NOT_ESTIMABLE:
        return f"{head}: {NOT_ESTIMABLE}: QE/PCA {why_short(entry)}"
    consistency = (
        "lies inside the interval"
        if entry["consistency"] not in (ABOVE, BELOW)
        else f"lies {entry['consistency']} the interval"
    )
    return (
        f"{head}: {entry['verdict']}, {ratio_text(entry, 'QE/PCA')}; "
        f"the paper's {PAPER_RATIOS['QE/PCA']:.3g} {consistency}"
    )


def entry_text(entry: Mapping) -> str:
    """Both claims on one protocol (:func:`first_claim_text`; :func:`second_claim_text`)."""
    return f"{first_claim_text(entry['H/QE'])}; {second_claim_text(entry['QE/PCA'])}"


def short_ratio_text(stored: Mapping, name: str) -> str:
    """``H/QE 2.05 [1.31, 3.23] reproduced``, or ``H/QE not estimable (fewer than 3 degrees of freedom)``, or
    ``QE/PCA not tested at m = n``: one claim on one protocol in a few words."""
    if stored["verdict"] == NOT_TESTED:
        return f"{name} {NOT_TESTED}"
    if stored["verdict"] == NOT_ESTIMABLE:
        return f"{name} {NOT_ESTIMABLE}: {why_short(stored)}"
    return f"{ratio_text(stored, name)} {stored['verdict']}"


def short_entry_text(entry: Mapping) -> str:
    """Both claims on one protocol in a few words (:func:`short_ratio_text`)."""
    one, two = entry["H/QE"], entry["QE/PCA"]
    if one["verdict"] == two["verdict"] == NOT_ESTIMABLE and why_short(one) == why_short(two):
        return f"H/QE and QE/PCA {NOT_ESTIMABLE}: {why_short(one)}"
    return f"{short_ratio_text(entry['H/QE'], 'H/QE')}, {short_ratio_text(entry['QE/PCA'], 'QE/PCA')}"


def m_text(entry: Mapping) -> str:
    """``m = 18``, or ``m = [18, 17, 18]`` when a cross-validated protocol's folds differ."""
    values = list(entry["m"])
    return f"m = {values[0]}" if len(set(values)) == 1 else f"m = {values}"


def lead_entries(claims: Mapping | None, base: str | None = None) -> list[dict]:
    """The stored claims of one data variant (``base``, else the first variant's) on every protocol, training
    frames first."""
    entries = list((claims or {}).get("entries") or [])
    if not entries:
        return []
    base = base if base is not None and any(e["base"] == base for e in entries) else entries[0]["base"]
    chosen = [entry for entry in entries if entry["base"] == base]
    return sorted(chosen, key=lambda entry: entry["protocol"] != TRAINING)


def verdict_word(entry: Mapping, name: str) -> str:
    """The decision alone (``reproduced``, ``not decided``, ``not estimable``, ...) of one claim on one protocol."""
    return entry[name]["verdict"]


def claims_sentence(claims: Mapping | None, base: str | None = None) -> str:
    """The first sentence a run prints: both claims on the training frames with their intervals, then each
    held-out protocol's verdicts.

    Parameters
    ----------
    claims : mapping or None
        ``metrics.json`` ``claims``.
    base : str, optional
        The data variant (default: the first with claims).

    Returns
    -------
    str
        Empty when there are no claims at all.
    """
    if not claims:
        return ""
    entries = lead_entries(claims, base)
    if not entries:
        return f"The paper's claims: {claims.get('not_tested') or NOT_TESTED}."
    head = f"The paper's claims at m = n ({claims['solver']}, {claims['column']})"
    parts = []
    for entry in entries:
        if entry["protocol"] == TRAINING:
            parts.append(f"on {entry['data']} ({m_text(entry)}): {entry_text(entry)}")
        else:
            parts.append(f"{entry['protocol_text']} ({m_text(entry)}): {short_entry_text(entry)}")
    return f"{head}, {'; '.join(parts)}."


def agreement_sentence(entries: Sequence[Mapping]) -> str:
    """One sentence: whether each held-out protocol gives the training frames' verdicts, and where not, with the
    verdicts on both sides (``Against the training frames (claim 1 reproduced, claim 2 not decided), held out
    differs on the blocked k-fold (claim 1 not decided, claim 2 reproduced).``)."""
    training = next((entry for entry in entries if entry["protocol"] == TRAINING), None)
    held = [entry for entry in entries if entry["protocol"] != TRAINING]
    if training is None or not held:
        return ""
    claims = (("H/QE", "claim 1"), ("QE/PCA", "claim 2"))
    differ = []
    for entry in held:
        changed = [
            f"{claim} {entry[name]['verdict']}"
            for name, claim in claims
            if entry[name]["verdict"] != training[name]["verdict"]
        ]
        if changed:
            differ.append(f"the {entry['protocol_text'].removeprefix('held-out ')} ({', '.join(changed)})")
    if not differ:
        return "Held out, every protocol gives the training frames' verdicts."
    there = ", ".join(f"{claim} {training[name]['verdict']}" for name, claim in claims)
    return f"Against the training frames ({there}), held out differs on " + " and ".join(differ) + "."


def compact_rests_on(stored: Mapping) -> str:
    """``1500 frames, 17 batches, 24.3 d.f.`` / ``5 folds of 1500 frames, 4 d.f.`` (degrees of freedom)."""
    degrees = stored["degrees"]
    said = f", {degrees:.3g} d.f." if math.isfinite(degrees) else ", no d.f."  # degrees of freedom
    if stored["unit"] == "folds":
        return f"{stored['folds']} folds of {stored['frames']} frames{said}"
    takes = stored["takes"]
    of_takes = f" of {takes} takes" if takes > 1 else ""
    return f"{stored['frames']} frames{of_takes}, {stored['batches']} batches{said}"


def rests_on_sentence(entries: Sequence[Mapping], confidence: float = 0.95) -> str:
    """``Intervals (95 %) rest on: training frames H/QE 1500 frames, 17 batches, 24.3 d.f., QE/PCA
    ...``: each interval's own frames, batches (or folds) and degrees of freedom; a claim that is not estimable or
    not tested has no interval, and says why where its verdict stands."""
    parts = []
    for entry in entries:
        stated = [name for name in ("H/QE", "QE/PCA") if entry[name]["verdict"] not in (NOT_ESTIMABLE, NOT_TESTED)]
        said = [(name, compact_rests_on(entry[name])) for name in stated]  # a claim not estimable says why in place
        if not said:
            continue
        if len(said) == 2 and said[0][1] == said[1][1]:
            text = f"both {said[0][1]}"
        else:
            text = ", ".join(f"{name} {basis}" for name, basis in said)
        parts.append(f"{entry['protocol_text'].removeprefix('held-out ')} {text}")
    return f"Intervals ({100 * confidence:g} %) rest on: " + "; ".join(parts).removesuffix(".") + "." if parts else ""


def primary_verdicts(claims: Mapping | None, data: str) -> dict:
    """``(a, b)`` rows -> the stored claim of one data variant that tests that contrast: ``(("H", "lstsq"), ("QE",
    "lstsq"))`` -> the H/QE entry, ``(("QE", "lstsq"), ("PCA", "projection"))`` -> the QE/PCA entry (either order
    of the pair). Empty when the variant has no stored claims."""
    entry = next((e for e in (claims or {}).get("entries") or [] if e["data"] == data), None)
    if entry is None:
        return {}
    found = {}
    for name, pair in (
        ("H/QE", (("H", "lstsq"), ("QE", "lstsq"))),
        ("QE/PCA", (("QE", "lstsq"), ("PCA", "projection"))),
    ):
        found[pair] = found[pair[::-1]] = dict(entry[name], ratio=name)
    return found


def claim_cell(stored: Mapping) -> str:
    """A stored claim as one table cell: ``H/QE 2.05 [1.31, 3.23]: reproduced``."""
    if stored["verdict"] == NOT_TESTED:
        return f"{stored['ratio']}: {NOT_TESTED}"
    if stored["verdict"] == NOT_ESTIMABLE:
        return f"{stored['ratio']}: {NOT_ESTIMABLE}"
    return f"{ratio_text(stored, stored['ratio'])}: {stored['verdict']}"


def _span(values: Sequence[float]) -> str:
    """``1.55-1.97`` over the runs (three significant digits), or one value where they agree; ``-`` for none."""
    values = [float(value) for value in values if value is not None and math.isfinite(float(value))]
    if not values:
        return "-"
    low, high = f"{min(values):.3g}", f"{max(values):.3g}"
    return low if low == high else f"{low}-{high}"


def why_not_tested(claims: Mapping, base: str = "") -> str:
    """Why a run stored no claim at m = n for ``base``, without the per-variant m it lists (those differ between
    runs): ``no variant is fitted at m = n with H, QE and PCA under least squares; basis.paper_regime=true adds
    one``, or, where it stored claims of other variants only, which."""
    others = list(dict.fromkeys(entry["base"] for entry in claims.get("entries") or [] if entry["base"] != base))
    if others:
        return f"the run's claims are of {', '.join(others)} (its variants at m = n), not of {base}"
    reason = str(claims.get("not_tested") or NOT_TESTED).removeprefix(f"{NOT_TESTED}: ")
    head, _, rest = reason.partition(" (")
    hint = rest.rsplit("; ", 1)[-1].removesuffix(")") if "; " in rest else ""
    return f"{head}; {hint}" if hint else head


def base_entries(claims: Mapping | None, base: str) -> list[dict]:
    """The stored claims of the base variant ``base`` on every protocol, training frames first; empty when the run
    stored none for it (unlike :func:`lead_entries`, no other variant's stand in)."""
    chosen = [entry for entry in (claims or {}).get("entries") or [] if entry["base"] == base]
    return sorted(chosen, key=lambda entry: entry["protocol"] != TRAINING)


def counted_verdicts(claims: Sequence[Mapping | None], base: str) -> dict:
    """The verdicts a group of runs stored, counted: ``(protocol text, "H/QE" or "QE/PCA")`` -> verdict -> runs,
    training frames first; a run that stored no claim at m = n counts as :data:`NOT_TESTED` on the training frames.
    Every sweep surface (its summary, its findings, ``workbench collect``) states these counts and decides none."""
    counted: dict = {}
    for stored in claims:
        entries = base_entries(stored, base) if stored else []
        if stored and not entries:
            entries = [{"protocol_text": PROTOCOL_TRAINING, **{name: {"verdict": NOT_TESTED} for name in RATIOS}}]
        for entry in entries:
            for name in RATIOS:
                verdicts = counted.setdefault((entry["protocol_text"], name), {})
                verdicts[entry[name]["verdict"]] = verdicts.get(entry[name]["verdict"], 0) + 1
    return counted


def counted_claims_text(claims: Sequence[Mapping | None], base: str) -> str:
    """The paper's claims as a group of runs (a sweep cell) stored them, counted over the runs per protocol, each
    claim's ratio as a range over the runs where estimable: ``the paper's claims at m = n, as each run stored them
    (its own interval; claim 2 against the margin 1.5): training frames: QE better than H reproduced in 4, not
    decided in 1 (H/QE 1.55-1.97); ...``, or ``... not tested at m = n in all 5 runs: <why>``.

    Parameters
    ----------
    claims : sequence of mapping or None
        Each run's ``metrics.json`` ``claims`` (None: a record written before runs kept them).
    base : str
        The data variant the claims are of (:func:`workbench.study.claims.base_variant` of the lead variant).
    """
    if not claims or any(stored is None for stored in claims):
        return f"{NO_CLAIMS[0].upper()}{NO_CLAIMS[1:]} (some of these runs)"
    if not any(base_entries(stored, base) for stored in claims):
        reasons = list(dict.fromkeys(why_not_tested(stored, base) for stored in claims))
        runs = len(claims)
        return (
            f"the paper's claims ({CLAIM_1}; {CLAIM_2}): {NOT_TESTED} in {'all ' if runs > 1 else ''}{runs} "
            f"run{'s' if runs != 1 else ''}: {' / '.join(reasons)}"
        )
    estimates: dict = {}
    for stored in claims:
        for entry in base_entries(stored, base):
            for name in RATIOS:
                if entry[name]["verdict"] not in (NOT_ESTIMABLE, NOT_TESTED):
                    estimates.setdefault((entry["protocol_text"], name), []).append(entry[name]["estimate"])
    parts: dict = {}
    for (protocol, name), verdicts in counted_verdicts(claims, base).items():
        counted = ", ".join(f"{verdict} in {count}" for verdict, count in verdicts.items())
        values = estimates.get((protocol, name))
        sizes = f" ({name} {_span(values)})" if values else ""
        parts.setdefault(protocol, []).append(f"{RATIOS[name]} {counted}{sizes}")
    margin = next(stored.get("margin") for stored in claims)
    return (
        f"the paper's claims at m = n, as each run stored them (its own interval; claim 2 against the margin "
        f"{margin:g}): " + ". ".join(f"{protocol}: {'; '.join(said)}" for protocol, said in parts.items())
    )
