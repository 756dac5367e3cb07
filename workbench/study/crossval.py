"""Held-out frames by cross-validation (``dataset.held_out`` ``kfold`` and ``take_out``): the folds, each fold's
capture, and one pooled result per data variant with the per-fold values kept beside it.

Blocked k-fold over time cuts every take into ``dataset.folds`` contiguous blocks; fold ``k`` holds out the k-th
block of every take, and the training frames leave out a gap of ``dataset.fold_gap_s`` seconds at each edge of a
held-out block (neighbouring frames are autocorrelated), so a gap frame is neither fitted nor scored in that fold.
Leave-one-take-out holds out each take whole, fitted on the others. Each fold chooses its own m (the coverage rule
on its training frames); every basis is scored on the same held-out frames; the fold is the replicate.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable, Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.capture import Capture, Timeline
from workbench.numerics.metrics import error_distribution, summarise_squares
from workbench.stats.statistics import paired_ratio_interval
from workbench.study.regime import is_paper_regime

FOLDED = {"kfold": "held-out blocked k-fold", "take_out": "held-out leave-one-take-out"}
"""``dataset.held_out`` protocols scored by cross-validation -> how their frames are described."""


def fold_indices(
    timeline: Timeline, protocol: str, folds: int = 5, gap_s: float = 0.5
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The training and held-out frames of every fold.

    Parameters
    ----------
    timeline : Timeline
        Of the capture's frames (``n_frames``), takes in contiguous runs.
    protocol : {"kfold", "take_out"}
    folds : int
        Blocks per take (``kfold``), at least 2 (``dataset.folds``, checked with the study's settings).
    gap_s : float
        Seconds left out of training on each side of a held-out block (``kfold``; within the block's take), at
        least 0 (``dataset.fold_gap_s``).

    Returns
    -------
    list of (train, held) index arrays
        Ascending indices into the frames; ``held`` of the folds together cover every frame exactly once.
    """
    spans = timeline.take_spans()
    everything = np.arange(len(timeline))
    if protocol == "take_out":
        if len(spans) < 2:
            raise WorkbenchError(
                "dataset.held_out 'take_out' holds out each take in turn, and this capture has one take; use 'kfold'"
            )
        return [(np.setdiff1d(everything, np.arange(start, stop)), np.arange(start, stop)) for start, stop in spans]
    if protocol != "kfold":
        raise WorkbenchError(f"dataset.held_out: {protocol!r} is not cross-validated ({list(FOLDED)})")
    if any(stop - start < folds for start, stop in spans):
        raise WorkbenchError(
            f"dataset.folds {folds} needs every take to have at least {folds} frames, got takes of "
            f"{[stop - start for start, stop in spans]}"
        )
    seconds = np.asarray(timeline.seconds, dtype=float)
    result = []
    for k in range(folds):
        held, gap = [], []
        for start, stop in spans:
            block = np.array_split(np.arange(start, stop), folds)[k]
            held.append(block)
            take = np.arange(start, stop)
            near = (seconds[take] > seconds[block[0]] - gap_s) & (seconds[take] < seconds[block[-1]] + gap_s)
            gap.append(take[near])
        held_k = np.concatenate(held)
        train = np.setdiff1d(everything, np.concatenate([held_k, *gap]))
        if train.size < 2:
            raise WorkbenchError(f"dataset.fold_gap_s {gap_s} leaves fold {k + 1} fewer than 2 training frames")
        result.append((train, held_k))
    return result


def fold_capture(capture: Capture, train: np.ndarray, held: np.ndarray, note: str) -> Capture:
    """The capture fitted on frames ``train`` and scored on frames ``held`` (indices into its frames of split
    'same')."""
    from workbench.study.protocols import select_frames

    notes = tuple(n for n in capture.notes if not n.startswith("split '")) + (note,)
    timeline = capture.timeline()
    return replace(
        capture,
        train=select_frames(capture.train, train),
        eval=select_frames(capture.eval, held),
        eval_visible=None if capture.eval_visible is None else capture.eval_visible[held],
        train_source=None if capture.train_source is None else capture.train_source[train],
        eval_timeline=timeline[held],
        notes=notes,
    )


def cross_validated(
    data: str,
    capture: Capture,
    protocol: str,
    folds: int,
    fold_gap_s: float,
    fit_and_score: Callable[[str, Capture], object],
    name: str | None = None,
):
    """One data variant cross-validated: every fold fitted (m by the coverage rule on its training frames, or m = n
    for the paper's regime) and scored on its held-out frames, pooled into one result.

    Parameters
    ----------
    data : str
    capture : Capture
        Trained and evaluated on the same frames (split 'same').
    protocol : {"kfold", "take_out"}
    folds : int
        ``dataset.folds``: blocks per take (``kfold``), checked with the study's settings.
    fold_gap_s : float
        ``dataset.fold_gap_s``: seconds left out of training at each block's edges, checked likewise.
    fit_and_score : callable
        ``(name, capture) -> StudyResult`` (the run's method on one capture).
    name : str, optional
        The pooled result's name (``<data> held-out <protocol>`` when not given); a paper-regime name
        (:func:`workbench.study.regime.is_paper_regime`) says m = n in each fold instead of the coverage rule.

    Returns
    -------
    StudyResult
        Rows pooled over all held-out frames (:func:`pooled_rows`); ``folds`` holds each fold's m, frames and
        alphas.
    """
    if len(capture.train) != len(capture.eval) or (
        capture.train_source is not None and len(capture.train_source) != len(capture.train)
    ):
        raise WorkbenchError(
            "dataset.held_out needs the training and evaluated frames to be the same frames "
            "(split 'same'; with gap_policy masked, gap_fit_on filled)"
        )
    gap_s = fold_gap_s
    folds = fold_indices(capture.timeline(), protocol, folds, gap_s)
    name = name or f"{data} held-out {protocol}"
    parts = []
    for k, (train, held) in enumerate(folds):
        note = f"fold {k + 1} of {len(folds)}: {len(train)} training frames, {len(held)} evaluated"
        parts.append(fit_and_score(f"{name} fold {k + 1}", fold_capture(capture, train, held, note)))
    held_all = np.concatenate([held for _, held in folds])
    how = (
        f"{len(folds)} contiguous blocks of every take, a gap of {gap_s:g} s left out of training at each block's edges"
        if protocol == "kfold"
        else f"each of the {len(folds)} takes held out in turn"
    )
    note = (
        f"held out by cross-validation, {len(folds)} folds ({how}); every basis scored on the same held-out "
        f"frames, {'m = n' if is_paper_regime(name) else 'm chosen'} in each fold "
        f"(m = {[part.eigenfaces.n_components_ for part in parts]}); alpha pooled "
        "over all held-out frames, weight statistics per fold not pooled"
    )
    pooled = fold_capture(capture, np.arange(len(capture.train)), held_all, note)
    pooled = replace(pooled, notes=tuple(n for n in pooled.notes if not n.startswith("fold ")))
    first = parts[0]
    return replace(
        first,
        data=name,
        capture=pooled,
        rows=pooled_rows(pooled, [part.rows for part in parts]),
        weights=pooled_weights([part.weights for part in parts]),
        train_on=data,
        eval_on=data,
        protocol=FOLDED[protocol],
        basis_intuitiveness={},
        offset={},
        folds=fold_values(parts),
    )


def pooled_rows(capture: Capture, fold_rows: Sequence[Sequence]) -> list:
    """Each table row pooled over the folds: alpha from the folds' per-frame squares, the per-frame errors joined,
    solver diagnostics summed or maximised; weight statistics and conditioning (per fold) left out."""
    keys = [[(row.basis, row.projection, row.solver) for row in rows] for rows in fold_rows]
    if any(key != keys[0] for key in keys):
        raise WorkbenchError("cross-validation: the folds scored different rows; cannot pool them")
    n_compared = (
        int(capture.eval_visible.sum()) if capture.eval_visible is not None else len(capture.eval) * capture.n_points
    )
    pooled = []
    for i, first in enumerate(fold_rows[0]):
        rows = [rows[i] for rows in fold_rows]

        def joined(get):
            values = [get(row) for row in rows]
            return None if any(value is None for value in values) else np.concatenate(values)

        alpha = summarise_squares(
            *(joined(lambda row, f=f: getattr(row.alpha, f)) for f in ("error_sq", "displacement_sq", "position_sq")),
            n_compared,
        )
        clean = None
        if first.clean_alpha is not None:
            clean = summarise_squares(
                *(
                    joined(lambda row, f=f: getattr(row.clean_alpha, f))
                    for f in ("error_sq", "displacement_sq", "position_sq")
                ),
                n_compared,
            )
        frame_error = joined(lambda row: row.frame_error_mm)
        pooled.append(
            replace(
                first,
                alpha=alpha,
                clean_alpha=clean,
                n_shapes=max(row.n_shapes for row in rows),
                n_iterations=sum(row.n_iterations for row in rows),
                n_fallback_frames=sum(row.n_fallback_frames for row in rows),
                max_kkt_violation=max(row.max_kkt_violation for row in rows),
                max_abs_weight=max(row.max_abs_weight for row in rows),
                conditioning=None,
                weight_statistics=None,
                frame_error_mm=frame_error,
                error_mm=None if frame_error is None else error_distribution(frame_error),
                offset_error_share=float("nan"),
            )
        )
    return pooled


def pooled_weights(fold_weights: Sequence[Mapping]) -> dict:
    """``(basis, solver)`` -> the folds' weights stacked over the held-out frames, where every fold has as many
    columns (PCA's m may differ between folds: then left out)."""
    joined = {}
    for key in fold_weights[0]:
        parts = [weights.get(key) for weights in fold_weights]
        if all(part is not None and part.shape[1:] == parts[0].shape[1:] for part in parts):
            joined[key] = np.concatenate(parts)
    return joined


def fold_values(parts: Sequence) -> dict:
    """Per fold: its m, coverage, frames, every row's basis rank and pooled alphas (absolute and displacement), in
    row order.

    The ranks let the identities of each fold be decided as those of a run are
    (:func:`workbench.stats.identities.run_identities`): QE with least squares spans PCA's reconstruction and
    QE-linear's shapes in a fold where its affine shapes have rank ``m + 1`` for that fold's ``m``.

    Returns
    -------
    dict
        ``n_folds``, ``m``, ``coverage``, ``n_train_frames``, ``n_eval_frames`` (lists over folds), ``rows``
        (``[basis, projection, solver]`` per row), ``n_shapes`` (per row, the most over the folds), ``rank`` of
        shape (n_rows, n_folds) (the numerical rank of the row's basis in each fold, None where it was not
        measured, as for PCA), ``hand_residual`` (projection -> each fold's
        :attr:`workbench.numerics.bases.QuasiEigenBasis.hand_residual`) and ``alpha_abs_pooled`` / ``alpha_disp_pooled`` of shape (n_rows, n_folds) as
        nested lists.
    """
    return {
        "n_folds": len(parts),
        "m": [int(part.eigenfaces.n_components_) for part in parts],
        "coverage": [float(part.eigenfaces.coverage_) for part in parts],
        "n_train_frames": [len(part.capture.train) for part in parts],
        "n_eval_frames": [len(part.capture.eval) for part in parts],
        "rows": [[row.basis, row.projection, row.solver] for row in parts[0].rows],
        "n_shapes": [max(int(part.rows[i].n_shapes) for part in parts) for i in range(len(parts[0].rows))],
        "rank": [
            [None if part.rows[i].conditioning is None else int(part.rows[i].conditioning.rank) for part in parts]
            for i in range(len(parts[0].rows))
        ],
        "hand_residual": {
            projection: [float(part.quasi_eigen[projection].hand_residual) for part in parts]
            for projection in parts[0].quasi_eigen
        },
        "alpha_abs_pooled": [
            [float(part.rows[i].alpha.absolute_pooled) for part in parts] for i in range(len(parts[0].rows))
        ],
        "alpha_disp_pooled": [
            [float(part.rows[i].alpha.displacement_pooled) for part in parts] for i in range(len(parts[0].rows))
        ],
    }


def fold_comparisons(folds: Mapping, pairs: Sequence[tuple[int, int]], column: str = "alpha_abs_pooled") -> list:
    """Paired comparisons over the folds (the fold is the replicate): for each pair of rows, the geometric mean
    of the per-fold ratios ``a / b`` with its t-interval on log ratios, n = the number of folds.

    Parameters
    ----------
    folds : mapping
        :func:`fold_values`.
    pairs : sequence of (int, int)
        Row indices (``workbench.study.summary.comparison_pairs``).
    column : str

    Returns
    -------
    list of dict
        ``a`` and ``b`` as ``[basis, solver]``, ``column`` and the interval's fields.
    """
    rows, values = folds["rows"], folds[column]
    return [
        {
            "a": [rows[a][0], rows[a][2]],
            "b": [rows[b][0], rows[b][2]],
            "column": column,
            **paired_ratio_interval(values[a], values[b]).as_dict(),
        }
        for a, b in pairs
    ]
