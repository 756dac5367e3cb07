"""The paper's two claims as data, computed once per run: at m = n, in the run's headline alpha with least squares,
on the training frames and on each held-out protocol, one ratio on the log scale with its interval, what the
interval rests on, and the verdicts. The record keeps them (``metrics.json`` ``claims``); every surface that states
a verdict (the first printed sentence, the summary, the findings, the comparisons table's primary rows, the
headline figure, sweep summaries) renders these and computes none.

Kim & Ko report, with least squares at m = n = 18, H 5.2, QE 0.72 and PCA 0.62 % (alpha):

- claim 1, QE far better than H (H/QE 7.2). Tested as **superiority**: the direction is "reproduced" when the
  interval of H/QE lies wholly above 1, "reversed" when wholly below 1, else "not decided"; the size is stated
  apart: the paper's 7.2 lies inside, above or below the interval.
- claim 2, QE nearly as accurate as PCA (QE/PCA 1.16). Tested as **non-inferiority** against the margin the
  settings declare before the data are seen (``metric.claim_margin``): "reproduced" when the interval of QE/PCA
  lies wholly at or below the margin, "not reproduced" when wholly above it, else "not decided"; consistency with
  the paper is stated apart: its 1.16 lies inside the interval or not. Where QE <= PCA holds by construction the
  claim is "not tested at m = n" and says why.

An interval that cannot inform gives "not estimable" instead of a verdict: no finite bounds; over time, the
workbench's rule (``Interval.not_estimable``: too few degrees of freedom, or the persistence at its cap
:data:`workbench.stats.time_series.PERSISTENCE_MAX`); over folds, fewer than :data:`MIN_DEGREES` degrees of freedom.
An interval over time that is estimable is the workbench's own, widened where few batches fit
(:data:`workbench.stats.time_series.THIN_DESIGN`), so a verdict rests only on an interval whose design covers.
docs/statistics.md states the rule and its measured coverage.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from workbench.stats.identities import run_identities
from workbench.stats.ratios import ratio_of_means, ratio_of_pooled
from workbench.stats.statistics import CONFIDENCE, Interval, paired_ratio_interval
from workbench.stats.time_series import PERSISTENCE_MAX, persistence, take_spans

CLAIMS_FORMAT = 1
"""The layout of ``metrics.json`` ``claims``; records written before it have none (their reports say so)."""
CLAIM_ROWS = {"H/QE": (("H", "lstsq"), ("QE", "lstsq")), "QE/PCA": (("QE", "lstsq"), ("PCA", "projection"))}
"""The paper's two claims as ratios of two rows (basis, solver): QE far better than H, QE nearly as accurate as PCA."""
PAPER_ALPHA = {"H": 5.2, "QE": 0.72, "PCA": 0.62}
"""The paper's alpha (%) of the hand basis, the quasi-eigen faces and PCA, with least squares at m = n = 18."""
PAPER_RATIOS = {"H/QE": PAPER_ALPHA["H"] / PAPER_ALPHA["QE"], "QE/PCA": PAPER_ALPHA["QE"] / PAPER_ALPHA["PCA"]}
"""The paper's ratios, from its absolute alpha: H/QE 7.2, QE/PCA 1.16."""
MIN_DEGREES = 3.0
"""An interval over folds on fewer degrees of freedom than this is not estimable: its t quantile exceeds 3.2 (4.3 at
2 degrees, leave-one-take-out over three takes; 12.7 at 1), so its width says more about the quantile than about the
data. Intervals over time follow the workbench's own rule (``workbench.stats.time_series.MIN_DEGREES``)."""
CLAIM_MARGIN = 1.5
"""The default non-inferiority margin of claim 2 (``metric.claim_margin``): about ``7.2 ** 0.2``, PCA's advantage
over QE at most a fifth of QE's advantage over H in the paper, on the log scale (docs/statistics.md)."""

TRAINING = "training"
"""The protocol key of the frames the bases were fitted on."""
PROTOCOL_TEXT = {
    TRAINING: "training frames",
    "tail": "held-out tail of each take",
    "take": "held-out last take",
    "kfold": "held-out blocked k-fold",
    "take_out": "held-out leave-one-take-out",
}
"""Protocol key -> how its frames are described."""

REPRODUCED = "reproduced"
REVERSED = "reversed"
NOT_REPRODUCED = "not reproduced"
NOT_DECIDED = "not decided"
NOT_ESTIMABLE = "not estimable"
NOT_TESTED = "not tested at m = n"
INSIDE, ABOVE, BELOW = "inside", "above", "below"
"""Where the paper's value lies relative to an interval."""


def protocol_key(data: str) -> str:
    """``markers held-out kfold m=n`` -> ``kfold``; a variant scored on its training frames -> ``training``."""
    if " held-out " not in data:
        return TRAINING
    return data.split(" held-out ", 1)[1].split(" ", 1)[0]


def base_variant(data: str) -> str:
    """The data variant a claim's variant derives from: ``markers held-out tail m=n`` -> ``markers``."""
    return data.split(" held-out ", 1)[0].removesuffix(" m=n")


def result_identities(results: Sequence, solvers: Mapping | None = None) -> dict:
    """Data variant -> the orderings its rows hold by construction
    (:func:`workbench.stats.identities.run_identities`), from the results as ``metrics.json`` would keep them.

    Parameters
    ----------
    results : sequence of workbench.study.results.StudyResult
    solvers : mapping, optional
        The run's ``solver`` settings (each solver's kind and bounds), which decide the solvers' nesting.
    """
    found = {}
    for result in results:
        rows = [
            {
                "basis": row.basis,
                "solver": row.solver,
                "n": row.n_shapes,
                "train_on": result.train_on or result.data,
                "eval_on": result.eval_on or result.data,
                "basis_conditioning": row.conditioning.as_dict() if row.conditioning else None,
            }
            for row in result.rows
        ]
        facts = {
            "pca": {"m": result.eigenfaces.n_components_, "method": result.eigenfaces.method_},
            "protocol": result.protocol,
            "notes": list(result.capture.notes),
            "quasi_eigen": {
                projection: {"hand_residual": qe.hand_residual, "appended_axes": list(qe.appended_axes)}
                for projection, qe in (getattr(result, "quasi_eigen", None) or {}).items()
            },
            **({"folds": result.folds} if getattr(result, "folds", None) else {}),
        }
        found[result.data] = run_identities(rows, facts, solvers)
    return found


def _fitted_m(result) -> list[int]:
    """The m of every fit behind a result: each fold's for a cross-validated variant, else the one fit's."""
    if result.folds:
        return [int(m) for m in result.folds["m"]]
    return [int(result.eigenfaces.n_components_)]


def _influence(a: np.ndarray, b: np.ndarray, pooled: bool) -> np.ndarray:
    """Per-frame influence of the log ratio of two means (or of two pooled alphas, from squared errors) on the
    frames where both are finite: the series whose mean's error the interval measures.

    Parameters
    ----------
    a, b : ndarray of shape (n_frames,)

    Returns
    -------
    ndarray of shape (n_valid,)
    """
    valid = np.isfinite(a) & np.isfinite(b)
    a, b = a[valid], b[valid]
    if not (a.mean() > 0 and b.mean() > 0):
        return np.zeros(0)
    return (0.5 if pooled else 1.0) * (a / a.mean() - b / b.mean())


def _frame_ratio(result, pair, metric: Mapping) -> tuple[Interval, dict]:
    """The ratio of two rows over the evaluated frames with its batch-means interval, and what it rests on."""
    normalisation, aggregate = metric["headline_normalisation"], metric["headline_aggregate"]
    first, second = (result.rows[i].alpha for i in pair)
    timeline = result.capture.timeline()
    takes = np.unique(timeline.take, return_inverse=True)[1]
    where = {"takes": takes, "seconds": timeline.seconds}
    if aggregate == "mean":
        a, b = (np.asarray(getattr(alpha, f"{normalisation}_per_frame"), dtype=float) for alpha in (first, second))
        interval = ratio_of_means(a, b, **where)
        influence = _influence(a, b, False)
        valid = np.isfinite(a) & np.isfinite(b)
    else:
        a, b = np.asarray(first.error_sq, dtype=float), np.asarray(second.error_sq, dtype=float)
        interval = ratio_of_pooled(a, b, **where)
        influence = _influence(a, b, True)
        valid = np.ones(a.size, bool)
    phi = float(persistence(influence, takes[valid])) if influence.size else math.nan
    n = len(a)
    length = int(interval.block_frames)
    n_takes = len(take_spans(takes, n))
    rests = {
        "unit": "frames",
        "frames": n,
        "takes": n_takes,
        "batch_frames": length,
        "batches": int(n // length) if length else 0,
        "folds": 0,
        "persistence": phi,
    }
    return interval, rests


def fold_headline_alphas(result, pair, metric: Mapping) -> tuple[np.ndarray, np.ndarray]:
    """Each fold's headline alpha of two rows, of shape (n_folds,): the mean of the fold's per-frame alphas (the
    pooled rows keep the folds' held-out frames in fold order), or the fold's pooled alpha."""
    normalisation, aggregate = metric["headline_normalisation"], metric["headline_aggregate"]
    if aggregate == "pooled":
        column = f"alpha_{'abs' if normalisation == 'absolute' else 'disp'}_pooled"
        keys = [(basis, solver) for basis, _, solver in result.folds["rows"]]
        rows = [result.rows[i] for i in pair]
        return tuple(np.asarray(result.folds[column][keys.index((r.basis, r.solver))], float) for r in rows)
    edges = np.cumsum([0, *result.folds["n_eval_frames"]])
    found = []
    for i in pair:
        values = np.asarray(getattr(result.rows[i].alpha, f"{normalisation}_per_frame"), dtype=float)
        found.append(np.array([np.nanmean(values[lo:hi]) for lo, hi in zip(edges[:-1], edges[1:])]))
    return tuple(found)


def _fold_ratio(result, pair, metric: Mapping) -> tuple[Interval, dict]:
    """The ratio of two rows over the folds (paired t on log ratios of the folds' headline alphas), and what it
    rests on."""
    a, b = fold_headline_alphas(result, pair, metric)
    interval = paired_ratio_interval(a, b)
    rests = {
        "unit": "folds",
        "frames": int(sum(result.folds["n_eval_frames"])),
        "takes": int(np.unique(result.capture.timeline().take).size),
        "batch_frames": 0,
        "batches": int(result.folds["n_folds"]),
        "folds": int(result.folds["n_folds"]),
        "persistence": math.nan,
    }
    return interval, rests


def rests_on_text(interval: Interval, rests: Mapping) -> str:
    """``800 frames of 1 take, 3 batches of 267, 2.996 degrees of freedom``: what one interval rests on."""
    takes = rests.get("takes") or 0
    of_takes = f" of {takes} take{'s' if takes != 1 else ''}" if takes else ""
    degrees = f", {interval.degrees:.4g} degrees of freedom" if math.isfinite(interval.degrees) else ""
    if rests.get("unit") == "folds":
        return f"{rests['folds']} folds ({rests['frames']} held-out frames{of_takes}), paired t on log ratios{degrees}"
    return f"{rests['frames']} frames{of_takes}, {rests['batches']} batches of {rests['batch_frames']}{degrees}"


def not_estimable_reason(interval: Interval, rests: Mapping, min_degrees: float = MIN_DEGREES) -> str:
    """Why an interval cannot inform a verdict (empty when it can): no finite bounds; for an interval over time,
    the workbench's rule (:attr:`workbench.stats.statistics.Interval.not_estimable`: too few degrees of freedom or
    the persistence at its cap); for one over folds, fewer than ``min_degrees`` degrees of freedom."""
    if not interval.defined:
        return "no interval (a ratio with a side at 0, or too few frames or folds)"
    stated = getattr(interval, "not_estimable", "")
    if stated:
        return f"{stated} ({rests_on_text(interval, rests)})"
    if rests.get("unit") == "folds" and not interval.degrees >= min_degrees:
        return f"fewer than {min_degrees:g} degrees of freedom ({rests_on_text(interval, rests)})"
    phi = rests.get("persistence", math.nan)
    if math.isfinite(phi) and phi >= PERSISTENCE_MAX:
        return (
            f"the frames' persistence is at its cap {PERSISTENCE_MAX:g}: the log ratio drifts over all "
            f"{rests['frames']} frames, whose mean has no usable error"
        )
    return ""


def paper_side(interval: Interval, paper: float) -> str:
    """Where the paper's value lies relative to the interval: :data:`INSIDE`, :data:`ABOVE` or :data:`BELOW`."""
    if paper > interval.high:
        return ABOVE
    return BELOW if paper < interval.low else INSIDE


def claim_entry(
    name: str,
    interval: Interval,
    rests: Mapping,
    column: str,
    margin: float,
    by_construction: str = "",
    min_degrees: float = MIN_DEGREES,
) -> dict:
    """One ratio of one protocol as the record keeps it: the interval's fields, the log-scale statistic, what it
    rests on and the verdicts.

    Parameters
    ----------
    name : {"H/QE", "QE/PCA"}
    interval : Interval
        The ratio with its interval (null 1).
    rests : mapping
        ``unit`` (frames or folds), ``frames``, ``takes``, ``batches``, ``batch_frames``, ``folds``,
        ``persistence``.
    column : str
        The headline alpha column both rows are read in.
    margin : float
        Claim 2's non-inferiority margin.
    by_construction : str
        Why QE <= PCA holds whatever the data (claim 2 then not tested); empty when it does not.
    min_degrees : float

    Returns
    -------
    dict
        ``column``, the :class:`Interval`'s fields, ``log_estimate``/``log_low``/``log_high``, the ``rests``
        fields, ``rests_on`` (text), ``why_not_estimable`` (empty when estimable), ``verdict`` and, for H/QE,
        ``size`` (the paper's 7.2 relative to the interval), for QE/PCA ``consistency`` (the paper's 1.16
        relative to it), ``margin`` and ``not_tested``.
    """
    paper = PAPER_RATIOS[name]
    entry = {
        "column": column,
        **interval.as_dict(),
        **{f"log_{key}": math.log(value) if value > 0 else math.nan for key, value in _bounds(interval).items()},
        **rests,
        "rests_on": rests_on_text(interval, rests),
        "paper": paper,
    }
    why = not_estimable_reason(interval, rests, min_degrees)
    entry["why_not_estimable"] = why
    if name == "H/QE":
        entry["verdict"] = NOT_ESTIMABLE if why else _direction(interval)
        entry["size"] = "" if why else paper_side(interval, paper)
        return entry
    entry["margin"] = margin
    entry["not_tested"] = by_construction
    if by_construction:
        entry["verdict"], entry["consistency"] = NOT_TESTED, ""
        return entry
    entry["verdict"] = NOT_ESTIMABLE if why else _non_inferiority(interval, margin)
    entry["consistency"] = "" if why else paper_side(interval, paper)
    return entry


def _bounds(interval: Interval) -> dict:
    return {"estimate": interval.estimate, "low": interval.low, "high": interval.high}


def _direction(interval: Interval) -> str:
    """Claim 1's direction: H/QE's interval wholly above 1, wholly below, or holding 1."""
    if interval.low > 1.0:
        return REPRODUCED
    return REVERSED if interval.high < 1.0 else NOT_DECIDED


def _non_inferiority(interval: Interval, margin: float) -> str:
    """Claim 2 against the margin: QE/PCA's interval wholly at or below it, wholly above it, or holding it."""
    if interval.high <= margin:
        return REPRODUCED
    return NOT_REPRODUCED if interval.low > margin else NOT_DECIDED


def _qe_spans_pca(identities: Sequence) -> str:
    """Why QE <= PCA holds by construction in a variant (empty when it does not)."""
    for item in identities:
        if (item.smaller, item.larger) == (("QE", "lstsq"), ("PCA", "projection")):
            return f"QE <= PCA holds by construction ({item.reason})"
    return ""


def claims_at_m_equals_n(
    results: Sequence, metric: Mapping, margin: float = CLAIM_MARGIN, solvers: Mapping | None = None
) -> dict:
    """The paper's two claims of a run, as ``metrics.json`` keeps them (``claims``).

    Parameters
    ----------
    results : sequence of workbench.study.results.StudyResult
        The run's data variants; those at m = n (every fold at m = n for a cross-validated one), scored on their
        own points with H, QE and PCA, are the claims' protocols.
    metric : mapping
        The ``metric`` config group: the headline's normalisation and aggregate.
    margin : float
        Claim 2's non-inferiority margin (``metric.claim_margin``).
    solvers : mapping, optional
        The run's ``solver`` settings (:func:`result_identities`).

    Returns
    -------
    dict
        ``format``, ``column``, ``solver``, ``paper``, ``margin``, ``min_degrees``, ``confidence``,
        ``not_tested`` (why no variant is at m = n; empty otherwise) and ``entries``: one per variant at m = n,
        with ``data``, ``base`` (the variant it derives from), ``protocol`` (:data:`PROTOCOL_TEXT` key),
        ``protocol_text``, ``m`` (one per fit), ``n`` and ``H/QE`` / ``QE/PCA`` (:func:`claim_entry`).
    """
    normalisation = "abs" if metric["headline_normalisation"] == "absolute" else "disp"
    column = f"alpha_{normalisation}_{metric['headline_aggregate']}"
    identities = result_identities(results, solvers)
    entries, seen_m = [], []
    for result in results:
        if result.transfer != "identity":
            continue
        n = len(result.capture.hand_names)
        fitted = _fitted_m(result)
        seen_m.append((result.data, fitted, n))
        index = {(row.basis, row.solver): i for i, row in enumerate(result.rows)}
        if any(m != n for m in fitted) or not all(key in index for pair in CLAIM_ROWS.values() for key in pair):
            continue
        spans = _qe_spans_pca(identities.get(result.data, []))
        entry = {
            "data": result.data,
            "base": base_variant(result.data),
            "protocol": protocol_key(result.data),
            "m": fitted,
            "n": n,
        }
        entry["protocol_text"] = PROTOCOL_TEXT.get(entry["protocol"], entry["protocol"])
        for name, (a, b) in CLAIM_ROWS.items():
            pair = (index[a], index[b])
            interval, rests = _fold_ratio(result, pair, metric) if result.folds else _frame_ratio(result, pair, metric)
            entry[name] = claim_entry(name, interval, rests, column, margin, spans if name == "QE/PCA" else "")
        entries.append(entry)
    not_tested = ""
    if not entries:
        fitted = "; ".join(f"{data}: m = {m[0] if len(set(m)) == 1 else m}, n = {n}" for data, m, n in seen_m)
        not_tested = (
            f"{NOT_TESTED}: no variant is fitted at m = n with H, QE and PCA under least squares ({fitted}; "
            "basis.paper_regime=true adds one)"
        )
    return {
        "format": CLAIMS_FORMAT,
        "column": column,
        "solver": "lstsq",
        "paper": dict(PAPER_RATIOS),
        "margin": float(margin),
        "min_degrees": MIN_DEGREES,
        "confidence": CONFIDENCE,
        "not_tested": not_tested,
        "entries": entries,
    }
