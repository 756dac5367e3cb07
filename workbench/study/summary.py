"""A run's results as the values its record keeps: the metrics of each data variant, its rows, the paired comparisons
of its rows over the evaluated frames (a block bootstrap), and the arrays of ``inputs.npz`` and
``alpha_per_frame.npz``. The record (:mod:`workbench.record.record`) writes them as they are."""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from workbench.numerics.intuitiveness import intuitiveness
from workbench.stats.ratios import ratio_of_means, ratio_of_pooled
from workbench.stats.statistics import paired_mean_difference, paired_pooled_difference, paired_ratio_interval
from workbench.study.claims import fold_headline_alphas
from workbench.study.results import StudyResult


def intuitiveness_table(result: StudyResult) -> list[dict]:
    """Per hand shape and projection: relative distance and cosine between ``e_i^H`` and ``e_i^QE``."""
    records = []
    n_hand = result.capture.hand.shape[0]
    for projection, qe in result.quasi_eigen.items():
        distance, cosine = intuitiveness(result.capture.hand, qe.shapes[:n_hand])
        for name, d, c, norm in zip(
            result.capture.hand_names, distance, cosine, np.linalg.norm(result.capture.hand, axis=1)
        ):
            records.append(
                {
                    "projection": projection,
                    "shape": name,
                    "relative_distance": float(d),
                    "cosine": float(c),
                    "hand_norm": float(norm),
                }
            )
    return records


def alpha_per_frame_arrays(results) -> dict:
    """Per-frame alpha of every table row, for plots over time: ``<data>.absolute`` and ``<data>.displacement``
    of shape (n_rows, n_eval_frames), ``<data>.error_mm`` (RMS point error over the face region, NaN where a row
    has none), ``<data>.basis`` / ``<data>.solver`` naming the rows in table order, and the evaluated frames'
    take, frame number in the file and time (``<data>.take``, ``.frame``, ``.seconds``)."""
    arrays = {}
    for result in results:
        n_frames = len(result.capture.eval)
        arrays[f"{result.data}.basis"] = np.array([row.basis for row in result.rows])
        arrays[f"{result.data}.solver"] = np.array([row.solver for row in result.rows])
        arrays[f"{result.data}.absolute"] = np.array([row.alpha.absolute_per_frame for row in result.rows])
        arrays[f"{result.data}.displacement"] = np.array([row.alpha.displacement_per_frame for row in result.rows])
        arrays[f"{result.data}.error_mm"] = np.array(
            [np.full(n_frames, np.nan) if row.frame_error_mm is None else row.frame_error_mm for row in result.rows]
        )
        arrays.update(result.capture.timeline().as_arrays(f"{result.data}."))
    return arrays


def comparison_pairs(rows: Sequence) -> list[tuple[int, int]]:
    """The pairs of table rows a run compares frame by frame: every two bases under the same solver (PCA, whose
    row has no solver, under each), and every basis under two solvers.

    Parameters
    ----------
    rows : sequence of Row

    Returns
    -------
    list of (int, int)
        Indices into ``rows``.
    """
    solvers = list(dict.fromkeys(row.solver for row in rows if row.solver != "projection"))
    pairs = []
    for solver in solvers:
        members = [i for i, row in enumerate(rows) if row.solver in (solver, "projection")]
        pairs += [(a, b) for k, a in enumerate(members) for b in members[k + 1 :]]
    for basis in dict.fromkeys(row.basis for row in rows if row.solver != "projection"):
        members = [i for i, row in enumerate(rows) if row.basis == basis and row.solver != "projection"]
        pairs += [(a, b) for k, a in enumerate(members) for b in members[k + 1 :]]
    return list(dict.fromkeys(pairs))


def headline_alpha_column(metric: Mapping, aggregate: str | None = None) -> str:
    """The alpha table's column of the run's headline alpha (``alpha_abs_mean``, ...): the ``metric`` group's
    normalisation with its aggregate (or ``aggregate``)."""
    normalisation = "abs" if metric["headline_normalisation"] == "absolute" else "disp"
    return f"alpha_{normalisation}_{aggregate or metric['headline_aggregate']}"


def headline_column(config: Mapping) -> str:
    """The alpha table's column of a run's headline alpha, from its whole config (:func:`headline_alpha_column`; a
    config without a ``metric`` group takes the defaults, absolute normalisation and the mean)."""
    metric = config.get("metric", {})
    return headline_alpha_column(
        {
            "headline_normalisation": metric.get("headline_normalisation", "absolute"),
            "headline_aggregate": metric.get("headline_aggregate", "mean"),
        }
    )


def timeline_batches(result) -> dict:
    """The ``takes`` (as integer codes, compared once here) and ``seconds`` of a result's evaluated frames, as the
    batch-means intervals take them."""
    timeline = result.capture.timeline()
    return {"takes": np.unique(timeline.take, return_inverse=True)[1], "seconds": timeline.seconds}


def frame_comparisons(result, metric: Mapping) -> list[dict]:
    """Paired comparisons of a result's rows on the evaluated frames, in the run's headline alpha: for every pair
    of :func:`comparison_pairs`, the difference ``a - b`` with its batch-means interval over time
    (:mod:`workbench.stats.statistics`).

    Parameters
    ----------
    result : StudyResult
    metric : mapping
        The ``metric`` config group: the headline's normalisation and aggregate.

    Returns
    -------
    list of dict
        ``a`` and ``b`` as ``[basis, solver]``, ``column``, and the :class:`Interval`'s fields.
    """
    normalisation, aggregate = metric["headline_normalisation"], metric["headline_aggregate"]
    column = headline_alpha_column(metric)
    where = timeline_batches(result)
    found = []
    for a, b in comparison_pairs(result.rows):
        first, second = result.rows[a].alpha, result.rows[b].alpha
        if aggregate == "mean":
            values = [getattr(alpha, f"{normalisation}_per_frame") for alpha in (first, second)]
            interval = paired_mean_difference(*values, **where)
        else:
            reference = first.position_sq if normalisation == "absolute" else first.displacement_sq
            interval = paired_pooled_difference(first.error_sq, second.error_sq, reference, **where)
        found.append(
            {
                "a": [result.rows[a].basis, result.rows[a].solver],
                "b": [result.rows[b].basis, result.rows[b].solver],
                "column": column,
                **interval.as_dict(),
            }
        )
    return found


CLAIM_ROWS = {"H/QE": (("H", "lstsq"), ("QE", "lstsq")), "QE/PCA": (("QE", "lstsq"), ("PCA", "projection"))}
"""The paper's two claims as ratios of two rows (basis, solver): QE far better than H, QE nearly as accurate as PCA."""


def claim_ratios(result, metric: Mapping) -> dict:
    """``H/QE`` and ``QE/PCA`` (least squares) of a result in the run's headline alpha, each with its interval: over
    the folds for a cross-validated variant (paired t on log ratios of each fold's headline alpha), else batch means over the
    evaluated frames (:mod:`workbench.stats.ratios`).

    Parameters
    ----------
    result : StudyResult
    metric : mapping
        The ``metric`` config group: the headline's normalisation and aggregate.

    Returns
    -------
    dict
        ``H/QE`` and ``QE/PCA`` -> ``column`` and the :class:`Interval`'s fields; a claim whose rows the result
        lacks is left out.
    """
    normalisation, aggregate = metric["headline_normalisation"], metric["headline_aggregate"]
    index = {(row.basis, row.solver): i for i, row in enumerate(result.rows)}
    where = None if result.folds else timeline_batches(result)
    found = {}
    for claim, (a, b) in CLAIM_ROWS.items():
        if a not in index or b not in index:
            continue
        first, second = result.rows[index[a]].alpha, result.rows[index[b]].alpha
        if result.folds:  # each fold's headline alpha, as the claims take it (workbench.study.claims)
            values = fold_headline_alphas(result, (index[a], index[b]), metric)
            found[claim] = {"column": headline_alpha_column(metric), **paired_ratio_interval(*values).as_dict()}
        elif aggregate == "mean":
            per_frame = [getattr(alpha, f"{normalisation}_per_frame") for alpha in (first, second)]
            found[claim] = {
                "column": headline_alpha_column(metric),
                **ratio_of_means(*per_frame, **where).as_dict(),
                "per_take": take_ratios(*per_frame, result.capture.timeline().take),
            }
        else:
            found[claim] = {
                "column": headline_alpha_column(metric),
                **ratio_of_pooled(first.error_sq, second.error_sq, **where).as_dict(),
            }
    return found


def take_ratios(a: np.ndarray, b: np.ndarray, takes: np.ndarray) -> dict:
    """Take -> ``mean(a) / mean(b)`` over its frames (both defined), and the share of its frames where ``a > b``:
    what each take says on its own when the takes are few. Empty for a single take.

    Parameters
    ----------
    a, b : ndarray of shape (n_frames,)
    takes : ndarray of shape (n_frames,)
    """
    names = list(dict.fromkeys(np.asarray(takes).tolist()))
    if len(names) < 2:
        return {}
    found = {}
    for name in names:
        where = (np.asarray(takes) == name) & np.isfinite(a) & np.isfinite(b)
        if where.any() and np.any(b[where]):
            found[str(name)] = {
                "ratio": float(a[where].mean() / b[where].mean()),
                "share_above": float(np.mean(a[where] > b[where])),
            }
    return found


def data_metrics(result) -> dict:
    """The part of ``metrics.json`` about one data variant: frames, points, spectrum, empty axes, intuitiveness."""
    capture, eigenfaces = result.capture, result.eigenfaces
    return {
        "n_points": capture.n_points,
        "n_train_frames": len(capture.train),
        "n_eval_frames": len(capture.eval),
        "n_eval_takes": int(np.unique(result.capture.timeline().take).size),
        "notes": list(capture.notes),
        "face_region": result.face_region,
        "offset": dict(result.offset),
        "protocol": result.protocol,
        "pca": {
            "m": eigenfaces.n_components_,
            "coverage_reached": eigenfaces.coverage_,
            "method": eigenfaces.method_,
            "rank": int(eigenfaces.explained_variance_.size),
            "explained_variance_ratio": eigenfaces.explained_variance_ratio_[:60].tolist(),
        },
        "quasi_eigen": {
            projection: {
                "empty_axes": [j + 1 for j in qe.empty_axes],
                "appended_axes": [j + 1 for j in qe.appended_axes],
                "axis_sums": qe.axis_sums.tolist(),
                "thresholds": qe.thresholds.tolist(),
                "hand_residual": qe.hand_residual,
            }
            for projection, qe in result.quasi_eigen.items()
        },
        "intuitiveness": intuitiveness_table(result),
        **({"basis_intuitiveness": result.basis_intuitiveness} if result.basis_intuitiveness else {}),
        **fold_metrics(result),
    }


def fold_metrics(result) -> dict:
    """A cross-validated variant's per-fold values (``folds``) and its paired comparisons over the folds
    (``fold_comparisons``, n = the number of folds); empty for any other variant."""
    from workbench.study.crossval import fold_comparisons

    if not result.folds:
        return {}
    return {"folds": result.folds, "fold_comparisons": fold_comparisons(result.folds, comparison_pairs(result.rows))}


def input_arrays(result) -> dict:
    """The arrays of ``inputs.npz``: what figures 2-4 need to recompute a few frames with the core."""
    capture = result.capture
    return {
        "train": capture.train,
        "eval": capture.eval,
        "neutral": capture.neutral,
        "hand": capture.hand,
        "hand_names": np.array(capture.hand_names),
        "mean": result.eigenfaces.mean_,
        "components": result.eigenfaces.components_,
        **({"faces": capture.faces} if capture.faces is not None else {}),
        **({"eval_visible": capture.eval_visible} if capture.eval_visible is not None else {}),
        **({"point_support": capture.point_support} if capture.point_support is not None else {}),
        **capture.timeline().as_arrays("eval_"),
    }


def results_metrics(
    results: Sequence[StudyResult],
    table,
    comparisons: Mapping[str, list] | None = None,
    ratios: Mapping[str, dict] | None = None,
    claims: Mapping | None = None,
) -> dict:
    """What a run found, as ``metrics.json`` keeps it: ``dataset`` (the first variant's capture), ``data`` (each
    data variant's :func:`data_metrics` and its comparisons) and ``rows`` (every table row with its solver
    diagnostics).

    Parameters
    ----------
    results : sequence of StudyResult
        One per data variant.
    table : pandas.DataFrame
        The run's alpha table (``workbench.study.table.alpha_table`` of every result, concatenated).
    comparisons : mapping, optional
        Data variant -> its :func:`frame_comparisons`, kept as ``data.<variant>.comparisons``.
    ratios : mapping, optional
        Data variant -> its :func:`claim_ratios`, kept as ``data.<variant>.ratios``.
    claims : mapping, optional
        The paper's claims (:func:`workbench.study.claims.claims_at_m_equals_n`), kept as ``claims``.

    Returns
    -------
    dict
    """
    capture = results[0].capture
    rows = [(result, result_row) for result in results for result_row in result.rows]
    return {
        "dataset": {
            "name": capture.name,
            "units": capture.units,
            "origin": capture.origin,
            "frame_rate": capture.frame_rate,
            "hand_names": list(capture.hand_names),
            "provenance": capture.provenance,
        },
        "data": {
            result.data: dict(
                data_metrics(result),
                comparisons=(comparisons or {}).get(result.data, []),
                ratios=(ratios or {}).get(result.data, {}),
            )
            for result in results
        },
        "rows": [
            dict(
                table.iloc[i].to_dict(),
                train_on=result.train_on or result.data,
                eval_on=result.eval_on or result.data,
                solver_iterations=row.n_iterations,
                solver_fallback_frames=row.n_fallback_frames,
                solver_max_kkt_violation=row.max_kkt_violation,
                max_abs_weight=row.max_abs_weight,
                basis_conditioning=row.conditioning.as_dict() if row.conditioning else None,
                undefined_displacement_frames=row.alpha.n_undefined_displacement_frames,
                weights=row.weight_statistics.as_dict() if row.weight_statistics else None,
                error_mm_quantiles=row.error_mm.quantiles.tolist() if row.error_mm else None,
                offset_error_share=row.offset_error_share,
            )
            for i, (result, row) in enumerate(rows)
        ],
        **({"claims": dict(claims)} if claims is not None else {}),
    }


def saved_inputs(results: Sequence[StudyResult]) -> dict:
    """Data variant -> the arrays of its inputs file (``save_inputs``): the variants scored on their own points
    under the paper's protocol. Bases carried onto other points (``dataset.eval_on``) live in two point sets, no
    single inputs file; the figures show the paper's protocol, so held-out frames (``dataset.held_out``) are not
    saved either."""
    return {
        result.data: input_arrays(result)
        for result in results
        if result.transfer == "identity" and result.protocol == "training frames"
    }
