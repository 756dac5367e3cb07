"""Scoring the bases on the evaluated frames: the weights under each solver, alpha (eq. 6), the per-frame error over the
face region, the part of the error outside the hand basis's span, and the intuitiveness of every basis."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.capture import Capture
from workbench.numerics.bases import Eigenfaces
from workbench.numerics.frames import frame_chunks
from workbench.numerics.metrics import (
    AlphaSummary,
    basis_conditioning,
    error_distribution,
    needs_negative_share,
    reference_squares,
    rms_error,
    summarise_alpha,
    summarise_squares,
    weight_statistics,
)
from workbench.numerics.reduced import FrameProjections, SpanPass, Subspace, project_frames, region_error_sq
from workbench.numerics.solve import in_span_difference, reconstruct, reduce_basis, solve_projected, solve_weights
from workbench.study.results import QE_LABELS, Row, Timings


def clean_scores(
    capture: Capture,
    truth: np.ndarray,
    rows: Sequence[Row],
    shapes: Mapping[str, np.ndarray],
    weights: Mapping,
    pca_reconstruction=None,
) -> list[Row]:
    """The rows with ``clean_alpha`` set: each basis's reconstruction of the evaluated (noisy) frames scored
    against the clean frames, so that a basis that reproduces the noise (over-fitting) is told from one that
    removes it (denoising).

    Parameters
    ----------
    capture : Capture
        The evaluated capture (its neutral positions).
    truth : ndarray of shape (n_eval_frames, 3 * n_points)
        The clean frames (:func:`clean_frames`).
    rows : sequence of Row
    shapes : mapping
        Basis label -> shapes of shape (n, 3 * n_points) at the evaluated points.
    weights : mapping
        ``(basis, solver)`` -> weights of shape (n_eval_frames, n).
    pca_reconstruction : callable, optional
        A ``slice`` of frames -> PCA's reconstruction of them, for the ``PCA`` row.

    Returns
    -------
    list of Row
    """
    squares = reference_squares(capture.neutral, truth)
    scored = []
    for row in rows:
        if row.basis == "PCA":
            estimate = pca_reconstruction
        else:
            estimate = lambda frames, b=shapes[row.basis], w=weights[(row.basis, row.solver)]: (  # noqa: E731
                reconstruct(b, w[frames])
            )
        summary = None if estimate is None else summarise_alpha(capture.neutral, truth, estimate, squares=squares)
        scored.append(replace(row, clean_alpha=summary))
    return scored


def score_bases(
    capture: Capture,
    eigenfaces: Eigenfaces,
    quasi_eigen: Mapping,
    pca: Subspace,
    solvers: Mapping[str, Mapping],
    timings: Timings,
    truth: np.ndarray | None = None,
    kept_pass: SpanPass | None = None,
) -> tuple[list, dict, SpanPass | None]:
    """Weights (eq. 5) and alpha (eq. 6) of H and every quasi-eigen basis with every solver, then PCA.

    Parameters
    ----------
    capture : Capture
        The evaluated data; its ``hand`` is the H basis.
    eigenfaces : Eigenfaces
        For ``m`` of the PCA row (and its reconstruction under capture gaps).
    quasi_eigen : mapping
        Projection name -> :class:`workbench.numerics.bases.QuasiEigenBasis` at the capture's points.
    pca : Subspace
        PCA's reconstruction at the capture's points (:func:`pca_subspace`).
    solvers : mapping
    timings : Timings
    truth : ndarray of shape (n_eval_frames, 3 * n_points), optional
        The clean frames: every row is also scored against them (:func:`clean_scores`).
    kept_pass : SpanPass, optional
        The pass of an earlier scoring of these very evaluated frames (its ``span_pass``), which serves this one
        when its span holds these bases (:func:`workbench.numerics.reduced.project_through_span`).

    Returns
    -------
    rows : list of Row
    weights : dict
        ``(basis, solver)`` -> ndarray of shape (n_eval_frames, n_shapes).
    span_pass : SpanPass or None
        The pass through the bases' joint span that scored them, for a later scoring of the same frames; None
        when the pass went over each basis.
    """
    bases = [("H", "-", capture.hand)] + [
        (QE_LABELS[projection], projection, qe.shapes) for projection, qe in quasi_eigen.items()
    ]
    with timings.stage("metrics"):
        conditioning = {label: basis_conditioning(shapes) for label, _, shapes in bases}
    region_errors, span_pass = None, None
    if capture.eval_visible is None:
        offset, _ = outside_offset(pca)
        extra = {"PCA": pca, **({OFFSET: Subspace(offset[:, None])} if offset is not None else {})}
        rows, weights, projections, region_errors = projected_rows(
            capture,
            bases,
            solvers,
            timings,
            conditioning,
            extra,
            also_span=reusable_eigenfaces(eigenfaces, pca),
            kept_pass=kept_pass,
        )
        span_pass = projections.span_pass
        if region_errors is not None:
            region_errors[("PCA", "projection")] = region_error_sq(projections.region, "PCA")
        with timings.stage("pca_reconstruction"):
            summary = summarise_squares(
                projections.distance_sq["PCA"],
                projections.displacement_sq,
                projections.position_sq,
                len(capture.eval) * capture.n_points,
            )
        pca_fit = (pca.columns.T, projections.coordinates["PCA"], pca.offset)
        if offset is not None:
            rows = offset_error_shares(
                rows,
                weights,
                {label: shapes for label, _, shapes in bases},
                offset,
                projections.coordinates[OFFSET][:, 0],
            )
    else:
        rows, weights = masked_rows(capture, bases, solvers, timings, conditioning)
        with timings.stage("pca_reconstruction"):
            # with gaps the orthogonal projection becomes least squares on the eigenfaces over the seen points
            visible = capture.eval_visible
            offsets = solve_weights(eigenfaces.components_, capture.eval - eigenfaces.mean_, visible=visible).weights
            summary = summarise_alpha(
                capture.neutral,
                capture.eval,
                lambda rows: eigenfaces.mean_ + reconstruct(eigenfaces.components_, offsets[rows]),
                squares=reference_squares(capture.neutral, capture.eval, visible=visible),
                visible=visible,
            )
        pca_fit = (eigenfaces.components_, offsets, eigenfaces.mean_)
    rows.append(Row(basis="PCA", projection="-", solver="projection", n_shapes=eigenfaces.n_components_, alpha=summary))
    basis_shapes = {label: shapes for label, _, shapes in bases}
    with timings.stage("frame_measures"):
        rows = frame_measures(capture, rows, weights, basis_shapes, pca_fit, region_errors)
    if truth is not None:
        directions, coefficients, mean = pca_fit
        with timings.stage("metrics"):
            rows = clean_scores(
                capture,
                truth,
                rows,
                basis_shapes,
                weights,
                lambda frames: mean + reconstruct(directions, coefficients[frames]),
            )
    return rows, weights, span_pass


OFFSET = "(I-P) mu"
"""Label of the capture mean's part outside the eigenfaces' span among the subspaces of the projection pass."""


def outside_offset(pca: Subspace) -> tuple[np.ndarray | None, float]:
    """The capture mean's part outside the eigenfaces' span, ``(I - P) mu``: every affine quasi-eigen face is
    ``P e_i^H + (I - P) mu`` (eq. 3-4), so each carries this same offset, while PCA adds it once as its mean.

    Parameters
    ----------
    pca : Subspace
        The eigenfaces (orthonormal columns) and the mean ``mu`` as offset, at the evaluated points.

    Returns
    -------
    unit : ndarray of shape (n_dims,) or None
        Its direction; None when it is zero (to rounding).
    norm : float
    """
    if pca.offset is None:
        return None, 0.0
    mean = np.asarray(pca.offset, dtype=float)
    outside = mean - pca.columns @ (pca.columns.T @ mean)
    norm = float(np.linalg.norm(outside))
    if not norm > 1e-9 * max(float(np.linalg.norm(mean)), 1e-300):
        return None, norm
    return outside / norm, norm


def offset_facts(pca: Subspace, rows: Sequence[Row]) -> dict:
    """``norm`` of :func:`outside_offset` and its ``ratio`` to the median evaluated frame's displacement norm (NaN
    when that median is 0: most evaluated frames at rest, as the face region's ground truth of a short take)."""
    _, norm = outside_offset(pca)
    squares = rows[0].alpha.displacement_sq if rows else None
    if squares is None or not len(squares):
        return {}
    median = float(np.median(np.sqrt(squares)))
    return {"norm": norm, "ratio": norm / median if median > 0 else float("nan")}


def offset_error_shares(
    rows: Sequence[Row], weights: Mapping, shapes: Mapping[str, np.ndarray], unit: np.ndarray, frames_along: np.ndarray
) -> list[Row]:
    """The rows with the share of their squared error that lies along ``unit`` (``offset_error_share``).

    Parameters
    ----------
    rows : sequence of Row
    weights : mapping
        ``(basis, solver)`` -> weights of shape (n_frames, n).
    shapes : mapping
        Basis label -> shapes of shape (n, n_dims).
    unit : ndarray of shape (n_dims,)
    frames_along : ndarray of shape (n_frames,)
        Each evaluated frame's coordinate along ``unit``.
    """
    along = {label: basis @ unit for label, basis in shapes.items()}
    shared = []
    for row in rows:
        key = (row.basis, row.solver)
        if key in weights and row.basis in along and row.alpha.error_sq is not None:
            residual = frames_along - weights[key] @ along[row.basis]
            total = float(row.alpha.error_sq.sum())
            row = replace(row, offset_error_share=float(residual @ residual) / total if total > 0 else float("nan"))
        shared.append(row)
    return shared


@dataclass(frozen=True)
class FaceRegion:
    """The points the per-frame error in millimetres is taken over.

    Attributes
    ----------
    points : ndarray of shape (n_points,) of bool, or None
        None: every point of the capture.
    description : str
    """

    points: np.ndarray | None
    description: str


def face_region(capture: Capture) -> FaceRegion:
    """The face region of a capture's points, per dataset.

    - markers (no triangles): every marker of the capture (head markers used only to remove head motion are not
      among its points);
    - the synthetic mesh: the vertices some hand shape moves (the muscles' reach); the rest is the static head
      around the face;
    - the AnimFace mesh: the vertices within reach of the markers (``point_support``); the rest is extrapolated;
    - the ICT FaceKit mesh: its face region, vertices [0, 9409) of the model (the capture holds no others);
    - another mesh: every vertex.
    """
    kind, n = capture.provenance.get("kind"), capture.n_points
    if capture.provenance.get("train_on", "markers" if capture.faces is None else "mesh") == "markers":
        return FaceRegion(None, f"the face region: every one of the {n} markers")
    if kind == "synthetic":
        moved = np.linalg.norm(capture.hand.reshape(len(capture.hand), n, 3), axis=2).max(axis=0) > 0.0
        return FaceRegion(
            None if moved.all() else moved,
            f"the face region: the {int(moved.sum())} of {n} mesh vertices some hand shape moves (the "
            "muscles' reach; the rest of the head patch never moves)",
        )
    if capture.point_support is not None and not capture.point_support.all():
        return FaceRegion(
            np.asarray(capture.point_support, dtype=bool),
            f"the face region: the {int(capture.point_support.sum())} of {n} vertices within reach of "
            "the markers (the others' motion is extrapolated)",
        )
    if kind == "ict_livelink":
        region = capture.provenance.get("region_vertices")
        return FaceRegion(None, f"the ICT face region (the {n} vertices of [0, {region}) of the model)")
    return FaceRegion(None, f"the face region: every one of the {n} vertices")


def frame_measures(
    capture: Capture,
    rows: Sequence[Row],
    weights: Mapping,
    shapes: Mapping[str, np.ndarray],
    pca_fit: tuple | None = None,
    region_errors: Mapping | None = None,
) -> list[Row]:
    """The rows with their per-frame error in millimetres over the face region (and its distribution) and the
    statistics of their weights.

    Parameters
    ----------
    capture : Capture
    rows : sequence of Row
    weights : mapping
        ``(basis, solver)`` -> weights of shape (n_eval_frames, n).
    shapes : mapping
        Basis label -> shapes of shape (n, n_dims) (for the error over a part of the points).
    pca_fit : tuple, optional
        PCA's reconstruction ``offset + coefficients @ directions`` as ``(directions (k, n_dims), coefficients
        (n_eval_frames, k), offset (n_dims,))``, for its row.
    region_errors : mapping, optional
        ``(basis, solver)`` -> squared error of each frame over the face region, taken in the projection pass
        (:func:`projected_rows` with ``region``); a pass over the frames computes them when None.

    Returns
    -------
    list of Row
    """
    region, timeline = face_region(capture), capture.timeline()
    takes = np.unique(timeline.take, return_inverse=True)[1]  # compared once, as integers
    points = np.ones(capture.n_points, dtype=bool) if region.points is None else region.points
    visible = capture.eval_visible
    counts = visible[:, points].sum(axis=1) if visible is not None else int(points.sum())
    if region.points is None:
        explicit = {}
    elif region_errors is not None:
        explicit = region_errors
    else:
        fits = {}
        for row in rows:
            key = (row.basis, row.solver)
            if key in weights:
                fits[key] = (shapes[row.basis], weights[key], None)
            elif row.basis == "PCA" and pca_fit is not None:
                fits[key] = pca_fit
        explicit = region_pass_error_sq(capture.eval, points, fits, visible)
    measured = []
    for row in rows:
        key = (row.basis, row.solver)
        error_sq = explicit.get(key, row.alpha.error_sq if region.points is None else None)
        per_frame = rms_error(error_sq, counts) if error_sq is not None else None
        statistics = weight_statistics(weights[key], timeline.seconds, takes) if key in weights else None
        measured.append(
            replace(
                row,
                weight_statistics=statistics,
                frame_error_mm=per_frame,
                error_mm=error_distribution(per_frame) if per_frame is not None else None,
            )
        )
    return with_needs_negative_share(measured)


def with_needs_negative_share(rows: Sequence[Row]) -> list[Row]:
    """The rows, each lstsq row's weight statistics given the share of frames that need negative weights: those
    whose nnls error (the same basis) exceeds the lstsq error beyond the tie tolerance
    (:func:`workbench.numerics.metrics.needs_negative_share`)."""
    nnls = {row.basis: row.alpha.error_sq for row in rows if row.solver == "nnls"}
    measured = []
    for row in rows:
        if row.solver == "lstsq" and row.basis in nnls and row.weight_statistics is not None:
            share = needs_negative_share(row.alpha.error_sq, nnls[row.basis], row.alpha.displacement_sq)
            row = replace(row, weight_statistics=replace(row.weight_statistics, needs_negative_share=share))
        measured.append(row)
    return measured


def region_pass_error_sq(frames, points: np.ndarray, fits: Mapping, visible: np.ndarray | None = None) -> dict:
    """Squared reconstruction error of each frame over some points only, one pass over the frames for every fit.

    Each fit's error is ``|x - o|^2 - 2 w.(S (x - o)) + w^T S S^T w`` over the points' coordinates, from one
    product of the frames with every fit's shapes and offset (no reconstruction is formed); frames where those
    terms cancel to below ``EXPLICIT_BELOW`` of their size get the explicit residual, as
    :func:`workbench.numerics.reduced.project_frames` does.

    Parameters
    ----------
    frames : ndarray of shape (n_frames, 3 * n_points) or FramesOnDisk
    points : ndarray of shape (n_points,) of bool
    fits : mapping
        Key -> ``(shapes (k, n_dims), weights (n_frames, k), offset (n_dims,) or None)``: the reconstruction
        ``offset + weights @ shapes``.
    visible : ndarray of shape (n_frames, n_points) of bool, optional
        Points each frame saw; only those count (then every residual is formed explicitly).

    Returns
    -------
    dict
        Key -> ndarray of shape (n_frames,).
    """
    from workbench.numerics.reduced import EXPLICIT_BELOW

    dims = np.repeat(points, 3)
    # one block of columns per distinct basis and offset (a basis solved by several solvers is taken once)
    blocks, parts, where, quadratic = {}, {}, {}, {}
    for key, (shapes, weights, offset) in fits.items():
        basis = (id(shapes), id(offset))
        if basis not in blocks:
            restricted = np.zeros(int(dims.sum())) if offset is None else np.asarray(offset, dtype=float)[dims]
            blocks[basis] = (shapes[:, dims], restricted)
            where[basis] = sum(len(block) + 1 for block, _ in list(blocks.values())[:-1])
            quadratic[basis] = (
                blocks[basis][0] @ blocks[basis][0].T,
                blocks[basis][0] @ restricted,
                float(restricted @ restricted),
            )
        parts[key] = (*blocks[basis], weights, basis)
    together = np.vstack([np.vstack([shapes, offset]) for shapes, offset in blocks.values()]).T
    errors = {key: np.empty(frames.shape[0]) for key in fits}
    for rows, chunk in frame_chunks(frames):
        chunk = chunk[:, dims]
        if visible is not None:
            seen = np.repeat(visible[rows][:, points], 3, axis=1)
            for key, (shapes, offset, weights, _) in parts.items():
                difference = np.where(seen, chunk - weights[rows] @ shapes - offset, 0.0)
                errors[key][rows] = np.einsum("ij,ij->i", difference, difference)
            continue
        products, squares = chunk @ together, np.einsum("ij,ij->i", chunk, chunk)
        for key, (shapes, offset, weights, basis) in parts.items():
            gram, shapes_offset, offset_sq = quadratic[basis]
            k, w, first = shapes.shape[0], weights[rows], where[basis]
            along = products[:, first : first + k] - shapes_offset  # S (x - o)
            frame_offset = products[:, first + k]
            error = (
                squares
                - 2.0 * frame_offset
                + offset_sq
                - 2.0 * np.einsum("ij,ij->i", w, along)
                + np.einsum("ij,ij->i", w @ gram, w)
            )
            close = np.flatnonzero(error <= EXPLICIT_BELOW * (squares + offset_sq))
            if close.size:
                residual = chunk[close] - w[close] @ shapes - offset
                error[close] = np.einsum("ij,ij->i", residual, residual)
            errors[key][rows] = np.maximum(error, 0.0)
    return errors


def reusable_eigenfaces(eigenfaces: Eigenfaces, pca: Subspace) -> np.ndarray | None:
    """The eigenfaces beyond PCA's m that a later fit at m = n of the same frames reuses (``n_reusable``), as
    columns of shape (n_dims, n_reusable): the scoring pass takes them into its span, so the m = n variant's bases
    read no frame again. None when there are none, or when PCA's subspace was carried onto other points."""
    wanted = eigenfaces.n_reusable or 0
    if wanted <= eigenfaces.n_components_ or pca.columns.shape[0] != eigenfaces.components_.shape[1]:
        return None
    try:
        return eigenfaces.with_n_components(wanted).components_.T
    except WorkbenchError:  # fewer pairs found than n
        return None


def projected_rows(
    capture: Capture,
    bases: Sequence[tuple],
    solvers: Mapping[str, Mapping],
    timings: Timings,
    conditioning: Mapping | None = None,
    subspaces: Mapping[str, Subspace] | None = None,
    also_span: np.ndarray | None = None,
    kept_pass: SpanPass | None = None,
) -> tuple[list, dict, FrameProjections, dict | None]:
    """Weights (eq. 5) and alpha (eq. 6) of each basis with every solver, from one pass over the evaluated frames.

    The pass (:func:`workbench.numerics.reduced.project_frames`) takes the frames' coordinates in every basis's span and
    in ``subspaces``; each solver then works on the ``n``-dimensional coordinates and alpha comes from them, so
    the frames are read once whatever the number of bases and solvers.

    Parameters
    ----------
    capture : Capture
        Without capture gaps (``eval_visible`` None).
    bases : sequence of (label, projection, shapes)
        ``shapes`` of shape (n, n_dims).
    solvers : mapping
    timings : Timings
    conditioning : mapping, optional
        Label -> :class:`Conditioning`, kept in the rows with each basis's largest weight; None: neither.
    subspaces : mapping, optional
        More affine subspaces to take in the same pass (label -> :class:`Subspace`), e.g. PCA's.
    also_span : ndarray of shape (n_dims, j), optional
        Directions a later pass over the same frames will need (:func:`workbench.numerics.reduced.project_frames`).
    kept_pass : SpanPass, optional
        An earlier pass over these very frames, handed to :func:`workbench.numerics.reduced.project_frames`.

    Returns
    -------
    rows : list of Row
        Solver by solver, bases in the given order.
    weights : dict
        ``(basis, solver)`` -> ndarray of shape (n_eval_frames, n).
    projections : FrameProjections
    region_errors : dict or None
        ``(basis, solver)`` -> squared error of each frame over the capture's face region (:func:`face_region`), taken
        in the same pass; None where the region is every point.
    """
    points = face_region(capture).points
    with timings.stage("projection"):
        reductions = {label: reduce_basis(shapes) for label, _, shapes in bases}
        projections = project_frames(
            capture.eval,
            {**{label: Subspace(r.u) for label, r in reductions.items()}, **(subspaces or {})},
            capture.neutral,
            region=None if points is None else np.repeat(points, 3),
            also_span=also_span,
            kept=kept_pass,
        )
    n_compared = len(capture.eval) * capture.n_points
    rows, weights = [], {}
    region_errors = None if projections.region is None else {}
    for solver_name, solver in solvers.items():
        for label, projection, shapes in bases:
            reduction, coordinates = reductions[label], projections.coordinates[label]
            with timings.stage(f"solve_{solver_name}"):
                solution = solve_projected(reduction, coordinates, **solver)
            with timings.stage("metrics"):
                difference = in_span_difference(reduction, coordinates, solution.weights)
                error_sq = projections.distance_sq[label] + np.einsum("ij,ij->i", difference, difference)
                summary = summarise_squares(error_sq, projections.displacement_sq, projections.position_sq, n_compared)
                if projections.region is not None:
                    region_errors[(label, solver_name)] = region_error_sq(projections.region, label, difference)
            weights[(label, solver_name)] = solution.weights
            rows.append(solved_row(label, projection, solver_name, shapes, summary, solution, conditioning))
    return rows, weights, projections, region_errors


def masked_rows(
    capture: Capture,
    bases: Sequence[tuple],
    solvers: Mapping[str, Mapping],
    timings: Timings,
    conditioning: Mapping | None = None,
) -> tuple[list, dict]:
    """:func:`projected_rows` under capture gaps: each frame solved and scored on the points it saw."""
    visible = capture.eval_visible
    with timings.stage("metrics"):
        squares = reference_squares(capture.neutral, capture.eval, visible=visible)
    rows, weights = [], {}
    for solver_name, solver in solvers.items():
        for label, projection, shapes in bases:
            with timings.stage(f"solve_{solver_name}"):
                solution = solve_weights(shapes, capture.eval, visible=visible, **solver)
            with timings.stage("metrics"):
                summary = summarise_alpha(
                    capture.neutral,
                    capture.eval,
                    lambda rows: reconstruct(shapes, solution.weights[rows]),
                    squares=squares,
                    visible=visible,
                )
            weights[(label, solver_name)] = solution.weights
            rows.append(solved_row(label, projection, solver_name, shapes, summary, solution, conditioning))
    return rows, weights


def solved_row(
    label: str,
    projection: str,
    solver_name: str,
    shapes: np.ndarray,
    summary: AlphaSummary,
    solution,
    conditioning: Mapping | None,
) -> Row:
    """The table row of one basis solved with one solver (its largest weight and conditioning with
    ``conditioning``)."""
    extra = (
        {}
        if conditioning is None
        else {"max_abs_weight": float(np.abs(solution.weights).max()), "conditioning": conditioning[label]}
    )
    return Row(
        basis=label,
        projection=projection,
        solver=solver_name,
        n_shapes=shapes.shape[0],
        alpha=summary,
        n_iterations=solution.n_iterations,
        n_fallback_frames=solution.n_fallback_frames,
        max_kkt_violation=solution.max_kkt_violation,
        **extra,
    )


def score_alternative_bases(
    capture: Capture,
    bases: Mapping[str, np.ndarray],
    solvers: Mapping[str, Mapping],
    timings: Timings,
    truth: np.ndarray | None = None,
) -> tuple[list, dict]:
    """Weights (eq. 5) and alpha (eq. 6) of each alternative basis with every solver, exactly as H and QE (and
    against the clean frames ``truth`` when given).

    Returns
    -------
    rows : list of Row
        Projection ``-``; solver by solver, bases in the configured order.
    weights : dict
        ``(basis, solver)`` -> ndarray of shape (n_eval_frames, n).
    """
    listed = [(label, "-", shapes) for label, shapes in bases.items()]
    if getattr(capture, "eval_visible", None) is not None:  # frames with capture gaps: visible points only
        (rows, weights), region_errors = masked_rows(capture, listed, solvers, timings), None
    else:
        rows, weights, _, region_errors = projected_rows(capture, listed, solvers, timings)
    with timings.stage("frame_measures"):
        rows = frame_measures(capture, rows, weights, bases, region_errors=region_errors)
    if truth is not None:
        rows = clean_scores(capture, truth, rows, dict(bases), weights)
    return rows, weights


def basis_intuitiveness(
    capture: Capture,
    eigenfaces: Eigenfaces,
    quasi_eigen: Mapping,
    alternatives: Mapping[str, np.ndarray],
    weights: Mapping,
    locality_energy: float,
    usage_threshold: float,
) -> dict:
    """Closeness to the hand shapes, locality and usage of H, each quasi-eigen basis, PCA and the alternatives
    (:mod:`workbench.numerics.intuitiveness`), as plain values for the run record.

    Parameters
    ----------
    capture : Capture
    eigenfaces : Eigenfaces
    quasi_eigen : mapping
        Projection -> :class:`workbench.numerics.bases.QuasiEigenBasis`.
    alternatives : mapping
        Label -> shapes of shape (n, n_dims).
    weights : mapping
        ``(basis, solver)`` -> weights of the evaluated frames, shape (n_eval_frames, n).
    locality_energy, usage_threshold : float
        ``basis.intuitiveness.locality_energy`` and ``basis.intuitiveness.usage_threshold``.

    Returns
    -------
    dict
        ``locality_energy``, ``usage_threshold``, ``point_weights`` and ``bases``: one entry per basis with
        ``basis``, ``n``, ``matched_abs_cosine`` (mean over matched pairs), ``locality`` (mean over elements),
        ``usage`` (solver -> mean elements used per evaluated frame) and ``elements`` (per element: the matched
        hand shape, its ``|cosine|`` and the element's locality).
    """
    from workbench.numerics.intuitiveness import (
        locality,
        matched_closeness,
        point_areas,
        usage,
    )

    energy, threshold = float(locality_energy), float(usage_threshold)
    areas = point_areas(capture.neutral, capture.faces)
    bases = {
        "H": capture.hand,
        **{QE_LABELS[p]: qe.shapes for p, qe in quasi_eigen.items()},
        "PCA": eigenfaces.components_,
        **alternatives,
    }
    per_basis = {label: {solver: w for (b, solver), w in weights.items() if b == label} for label in bases}
    if getattr(capture, "eval_visible", None) is None:  # PCA's weights: the projection coefficients
        per_basis["PCA"] = {"projection": (capture.eval - eigenfaces.mean_) @ eigenfaces.components_.T}
    entries = []
    for label, shapes in bases.items():
        element, hand_index, cosine = matched_closeness(shapes, capture.hand)
        local = locality(shapes, areas, energy)
        entries.append(
            {
                "basis": label,
                "n": int(shapes.shape[0]),
                "matched_abs_cosine": float(cosine.mean()),
                "locality": float(np.nanmean(local)),
                "usage": {solver: float(usage(w, shapes, threshold).mean()) for solver, w in per_basis[label].items()},
                "elements": [
                    {
                        "element": int(e),
                        "hand_shape": capture.hand_names[h],
                        "abs_cosine": float(c),
                        "locality": float(local[e]),
                    }
                    for e, h, c in zip(element, hand_index, cosine)
                ],
            }
        )
    return {
        "locality_energy": energy,
        "usage_threshold": threshold,
        "point_weights": "mesh triangle areas" if capture.faces is not None else "equal per point",
        "bases": entries,
    }
