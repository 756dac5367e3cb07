"""One run of a study: dataset -> bases -> solve -> metrics, returned as plain results.

``run_study`` takes a study's checked, typed settings (:mod:`workbench.settings.typed`) and returns one :class:`~workbench.study.results.StudyResult`
per data variant (``dataset.train_on``: markers, mesh, ...); writing files is ``workbench.record.record``'s job and printing is
``workbench.reporting.text.run``'s."""

from __future__ import annotations

from dataclasses import replace
from typing import Callable, Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset import build_from_settings
from workbench.dataset.capture import Capture
from workbench.dataset.transfer import point_transfer
from workbench.settings.schema import BasisSchema
from workbench.settings.typed import StudySettings, changed_dataset, clean_dataset, solver_options
from workbench.study.crossval import FOLDED, cross_validated
from workbench.study.fitting import fit_alternative_bases, fit_bases, pca_subspace
from workbench.study.protocols import (
    CLEAN_M_NOTE,
    HELD_OUT,
    clean_frames,
    data_variants,
    held_out_capture,
    held_out_protocols,
    select_shapes,
    subset_hand_shapes,
    with_clean_m,
)
from workbench.study.regime import paper_regime_fit, paper_regime_name
from workbench.study.results import StudyResult, Timings
from workbench.study.scoring import basis_intuitiveness, face_region, offset_facts, score_alternative_bases, score_bases


def run_study(settings: StudySettings) -> list[StudyResult]:
    """Build the data, then for each data variant fit eigenfaces and quasi-eigen faces on the training frames
    and score every basis on the evaluated ones (of the same variant, or of each ``dataset.eval_on`` variant).

    Parameters
    ----------
    settings : StudySettings
        A study's settings, checked and typed (:func:`workbench.settings.typed.study_settings` of a composed or
        resolved config; :func:`workbench.api.run_study` takes the config itself).

    Returns
    -------
    list of StudyResult
        One per ``dataset.train_on`` variant, in the configured order (times each ``dataset.eval_on`` variant
        when that is set); they share one :class:`Timings`.
    """
    if not isinstance(settings, StudySettings):
        raise WorkbenchError(
            f"run_study takes a study's checked settings (workbench.settings.typed.study_settings), got "
            f"{type(settings).__name__}; workbench.run_study takes a config"
        )
    timings = Timings()
    solvers = {name: solver_options(solver) for name, solver in settings.solvers.items()}
    dataset, basis = settings.dataset, settings.basis
    train_names, eval_names = data_variants(dataset.train_on, getattr(dataset, "eval_on", None))  # not every kind's
    build_names = train_names + [name for name in eval_names or () if name not in train_names]
    # the same built data whatever is held out of it (build_captures leaves out settings.typed.SCORING_ONLY)
    built = changed_dataset(dataset, train_on=build_names) if eval_names else dataset
    score_clean = settings.metric.score_clean is True
    with timings.stage("dataset"):
        captures = build_from_settings(built, cache_dir=settings.paths.cache_dir)
        clean = (
            build_from_settings(clean_dataset(built), cache_dir=settings.paths.cache_dir)
            if basis.coverage_on == "clean" or score_clean
            else None
        )
    if eval_names:
        return carried_results(captures, clean, train_names, eval_names, basis, score_clean, solvers, timings)
    results = []
    for data, capture in captures.items():
        capture, m = fitted_capture(
            capture,
            basis.hand_subset,
            basis.subset_seed,
            basis.coverage,
            clean[data] if basis.coverage_on == "clean" else None,
        )
        fitted = basis if m is None else replace(basis, n_components=m)
        score = scorer(solvers, timings, clean[data] if score_clean else None)
        trained = with_paper_regime(
            score(data, capture, fitted),
            basis.paper_regime,
            fitted.n_components,
            lambda name, part, n, previous: score(
                name, part, replace(fitted, n_components=n, alternatives=[]), previous
            ),
        )
        results += trained
        for protocol in held_out_protocols(dataset.held_out):
            results += held_out_results(
                data,
                capture,
                protocol,
                fitted,
                score,
                len(trained) > 1,
                eval_fraction=dataset.eval_fraction,
                folds=dataset.folds,
                fold_gap_s=dataset.fold_gap_s,
            )
    return results


def fitted_capture(
    capture: Capture, hand_subset, subset_seed: int, coverage: float, clean: Capture | None
) -> tuple[Capture, int | None]:
    """The capture a data variant's bases are fitted on (the hand shapes ``basis.hand_subset`` keeps, drawn with
    ``basis.subset_seed``) and the number of eigenfaces they are fitted with: the m chosen by ``basis.coverage`` on
    ``clean``, the same data variant of the clean capture (``basis.coverage_on`` clean;
    :func:`workbench.study.protocols.with_clean_m`), when given; None (the basis settings' own m) otherwise."""
    return with_clean_m(subset_hand_shapes(capture, hand_subset, subset_seed), coverage, clean)


Score = Callable[[str, Capture, BasisSchema, "StudyResult | None"], StudyResult]
"""``(name, capture, basis, previous) -> StudyResult``: the run's method on one capture (:func:`scorer`), taking
what it can from ``previous``, the result of a fit of the very same frames (or None)."""

Refit = Callable[[str, Capture, int, StudyResult], StudyResult]
"""``(name, capture, n, previous) -> StudyResult``: a :data:`Score` of the basis settings of ``previous``'s fit at
``n_components`` n, without alternative bases (the paper's m = n variant, :func:`with_paper_regime`)."""


def scorer(solvers: Mapping[str, Mapping], timings: Timings, clean: Capture | None) -> Score:
    """:func:`run_on_capture` with the run's solvers and timings, every row also scored against the clean frames
    of ``clean`` (``metric.score_clean``) when given."""

    def score(name: str, capture: Capture, basis: BasisSchema, previous: StudyResult | None = None) -> StudyResult:
        truth = clean_frames(capture, clean) if clean is not None else None
        return run_on_capture(name, capture, basis, solvers, timings, truth=truth, previous=previous)

    return score


def held_out_results(
    data: str,
    capture: Capture,
    protocol: str,
    basis: BasisSchema,
    score: Score,
    trained_regime: bool,
    *,
    eval_fraction: float,
    folds: int,
    fold_gap_s: float,
) -> list[StudyResult]:
    """One ``dataset.held_out`` protocol of a data variant: the coverage rule's result, named
    ``<data> held-out <protocol>``, after its m = n variant (:func:`with_paper_regime`) fitted on the same training
    frames (each fold's) and scored on the same held-out frames.

    Parameters
    ----------
    data : str
    capture : Capture
        Trained and evaluated on the same frames (split 'same').
    protocol : str
        Of :data:`workbench.study.protocols.HELD_OUT`.
    basis : BasisSchema
        The settings the coverage rule's bases are fitted with.
    score : Score
    trained_regime : bool
        Whether the run has the variant ``<data> m=n`` on the training frames: the m = n variant's held-out frames
        are then compared with that variant's (its ``train_on``), else with ``data``'s.
    eval_fraction, folds, fold_gap_s
        ``dataset.eval_fraction`` (the held-out tail's share of the frames), ``dataset.folds`` and
        ``dataset.fold_gap_s`` (the cross-validated protocols' folds and the seconds left out at their edges).
    """

    def at(n: int | None) -> BasisSchema:
        """The basis settings of the coverage rule's fit (n None) or of the m = n fit."""
        return basis if n is None else replace(basis, n_components=n, alternatives=[])

    if protocol in FOLDED:
        source = capture

        def fit(name: str, part: Capture, n: int | None = None, previous: StudyResult | None = None) -> StudyResult:
            # each fold is fitted on frames of its own: nothing of ``previous`` (the pooled folds) serves them
            return cross_validated(
                data, part, protocol, folds, fold_gap_s, lambda fold, frames: score(fold, frames, at(n)), name=name
            )

    else:
        source = held_out_capture(capture, protocol, eval_fraction)

        def fit(name: str, part: Capture, n: int | None = None, previous: StudyResult | None = None) -> StudyResult:
            return replace(score(name, part, at(n), previous), train_on=data, eval_on=data, protocol=HELD_OUT[protocol])

    base = paper_regime_name(data) if trained_regime else data
    return with_paper_regime(
        fit(f"{data} held-out {protocol}", source),
        basis.paper_regime,
        basis.n_components,
        lambda name, part, n, previous: replace(fit(name, part, n, previous), train_on=base, eval_on=base),
        source,
    )


def with_paper_regime(
    result: StudyResult,
    paper_regime: bool,
    n_components: int | None,
    refit: Refit,
    source: Capture | None = None,
) -> list[StudyResult]:
    """``basis.paper_regime``: the variant fitted at m = n (:func:`workbench.study.regime.paper_regime_fit`), named
    ``<data> m=n``, first, then the coverage rule's ``result``; only ``result`` (with a note saying why) when there
    is no separate m = n fit.

    Parameters
    ----------
    result : StudyResult
        The coverage rule's, on training frames or on held-out frames (cross-validated: its ``folds`` give each
        fold's m and training frames).
    paper_regime : bool
        ``basis.paper_regime``, checked.
    n_components : int or None
        ``n_components`` of the basis settings ``result`` was fitted with (set: no m = n fit).
    refit : Refit
        Fits and scores the m = n variant as ``result`` was, with its basis settings at ``n_components`` n and
        without alternative bases: ``(name, capture, n, previous)``, handed ``result`` as ``previous`` (the same
        training and evaluated frames: its fit's decomposition and its scoring pass serve the m = n fit).
    source : Capture, optional
        The capture ``refit`` takes (``result.capture`` when not given; a cross-validated variant's folds are cut
        from the capture before pooling).
    """
    folds = result.folds or {}
    handed, result = result, replace(result, span_pass=None)  # the pass serves the refit only
    capture, n, note = paper_regime_fit(
        result.capture if source is None else source,
        paper_regime,
        n_components,
        folds.get("m", result.eigenfaces.n_components_),
        folds.get("n_train_frames"),
        held_out=result.protocol != "training frames",
    )
    if n is None:
        return [
            replace(result, capture=replace(result.capture, notes=result.capture.notes + (note,))) if note else result
        ]
    regime = refit(paper_regime_name(result.data), capture, n, handed)
    return [replace(regime, span_pass=None), result]


def carried_results(
    captures: Mapping[str, Capture],
    clean: Mapping[str, Capture] | None,
    train_names: Sequence[str],
    eval_names: Sequence[str],
    basis: BasisSchema,
    score_clean: bool,
    solvers: Mapping[str, Mapping],
    timings: Timings,
) -> list[StudyResult]:
    """``dataset.eval_on``: the bases fitted on each training variant, carried onto the points of each evaluated
    variant (:func:`workbench.dataset.transfer.point_transfer`) and scored there, one result per pair (also
    against the clean frames with ``score_clean``, ``metric.score_clean``)."""
    masked = [name for name in eval_names if captures[name].eval_visible is not None]
    if masked:
        raise WorkbenchError(
            f"dataset.gap_policy 'masked' leaves gaps in the evaluated frames of {masked}; "
            "carrying bases onto them (dataset.eval_on) is not supported: use gap_policy linear "
            "or drop, or leave dataset.eval_on unset"
        )
    results = []
    for train_on in train_names:
        source, m = fitted_capture(
            captures[train_on],
            basis.hand_subset,
            basis.subset_seed,
            basis.coverage,
            clean[train_on] if basis.coverage_on == "clean" else None,
        )
        fitted = basis if m is None else replace(basis, n_components=m)
        eigenfaces, quasi_eigen = fit_bases(source, fitted, timings)
        for eval_on in eval_names:
            target = select_shapes(captures[eval_on], source.hand_names)
            with timings.stage("transfer"):
                transfer = point_transfer(source.neutral.reshape(-1, 3), target.neutral.reshape(-1, 3))
            note = (
                f"bases fitted on '{train_on}' ({source.n_points} points) and carried onto '{eval_on}' "
                f"({target.n_points} points): {transfer.describe()}"
            )
            m_notes = tuple(note for note in source.notes if note.startswith(CLEAN_M_NOTE))
            target = replace(target, notes=target.notes + m_notes + (note,))
            carried = {
                projection: replace(qe, shapes=transfer.apply(qe.shapes)) for projection, qe in quasi_eigen.items()
            }
            carried_pca = pca_subspace(eigenfaces, transfer)
            rows, weights, _ = score_bases(
                target,
                eigenfaces,
                carried,
                carried_pca,
                solvers,
                timings,
                truth=clean_frames(target, clean[eval_on]) if score_clean else None,
            )
            results.append(
                StudyResult(
                    data=f"{train_on}->{eval_on}",
                    capture=target,
                    eigenfaces=eigenfaces,
                    quasi_eigen=carried,
                    rows=rows,
                    weights=weights,
                    timings=timings,
                    train_on=train_on,
                    eval_on=eval_on,
                    transfer=transfer.method,
                    face_region=face_region(target).description,
                    offset=offset_facts(carried_pca, rows),
                )
            )
    return results


def run_on_capture(
    data: str,
    capture: Capture,
    basis: BasisSchema,
    solvers: Mapping[str, Mapping],
    timings: Timings,
    truth: np.ndarray | None = None,
    previous: StudyResult | None = None,
) -> StudyResult:
    """The paper's method on one capture: eigenfaces, quasi-eigen faces, weights of every basis and solver, alpha.

    Parameters
    ----------
    data : str
        Name of the data variant, kept in the result.
    capture : Capture
    basis : BasisSchema
        The ``basis`` settings, typed.
    solvers : mapping
        Solver name -> keyword arguments of :func:`workbench.numerics.solve.solve_weights`
        (:func:`workbench.settings.typed.solver_options`).
    timings : Timings
        Stage times are added to it.
    truth : ndarray of shape (n_eval_frames, 3 * n_points), optional
        The clean frames; every row is also scored against them (``metric.score_clean``).
    previous : StudyResult, optional
        A result fitted on the very same training frames and scored on the very same evaluated frames (the
        coverage rule's, for the m = n variant): its eigenfaces' decomposition and its scoring pass are reused
        where they serve.

    Returns
    -------
    StudyResult
        With the scoring pass (``span_pass``) that a later scoring of the same frames can be handed.
    """
    eigenfaces, quasi_eigen = fit_bases(capture, basis, timings, None if previous is None else previous.eigenfaces)
    rows, weights, span_pass = score_bases(
        capture,
        eigenfaces,
        quasi_eigen,
        pca_subspace(eigenfaces),
        solvers,
        timings,
        truth=truth,
        kept_pass=None if previous is None else previous.span_pass,
    )
    alternatives = fit_alternative_bases(capture, basis, timings)
    measured = {}
    if alternatives:
        more_rows, more_weights = score_alternative_bases(capture, alternatives, solvers, timings, truth=truth)
        rows, weights = rows + more_rows, {**weights, **more_weights}
        with timings.stage("intuitiveness"):
            measured = basis_intuitiveness(
                capture,
                eigenfaces,
                quasi_eigen,
                alternatives,
                weights,
                basis.intuitiveness.locality_energy,
                basis.intuitiveness.usage_threshold,
            )
    return StudyResult(
        data=data,
        capture=capture,
        eigenfaces=eigenfaces,
        quasi_eigen=quasi_eigen,
        rows=rows,
        weights=weights,
        timings=timings,
        train_on=data,
        eval_on=data,
        basis_intuitiveness=measured,
        face_region=face_region(capture).description,
        offset=offset_facts(pca_subspace(eigenfaces), rows),
        span_pass=span_pass,
    )
