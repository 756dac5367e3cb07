"""Bases of the study: eigenfaces (eq. 2), quasi-eigen faces (eq. 3-4) and the post-treatment.

Pure numerical code: arrays in, arrays and frozen dataclasses out. Frames are rows: a capture is an array of
shape ``(n_frames, n_dims)`` with ``n_dims = 3 * n_points`` (the paper's ``3N x L`` matrix, transposed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.tolerances import TOL, Tolerances
from workbench.numerics.frames import check_finite_chunk, frame_chunks, is_stored_frames
from workbench.numerics.randomized_pca import (  # noqa: F401  (re-exported: the randomised path's names)
    FIRST_EIGEN,
    RESIDUAL_RTOL,
    auto_solver,
    flip_signs,
    frames_normal_times,
    randomized_covariance_eigen,
    solver_costs,
)
from workbench.numerics.validation import CAPTURE, check_finite, check_matrix

PROJECTIONS = ("affine", "linear")
EMPTY_AXIS_SCALES = ("axis_std", "absolute")


def _shown(value) -> str:
    """A setting as an error message quotes it: text in quotes, numbers as written."""
    return repr(value) if isinstance(value, str) else str(value)


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def check_coverage(coverage) -> float:
    """``coverage`` as a float, or a :class:`WorkbenchError` unless it is a number in (0, 1]."""
    if not _is_number(coverage) or not 0.0 < coverage <= 1.0:
        raise WorkbenchError(f"coverage must be in (0, 1], got {_shown(coverage)}")
    return float(coverage)


def check_n_components(n_components) -> int | None:
    """``n_components`` as an int (or None), or a :class:`WorkbenchError` unless it is a positive integer."""
    if n_components is None:
        return None
    if not _is_number(n_components) or not float(n_components).is_integer() or n_components < 1:
        raise WorkbenchError(f"n_components must be a positive integer or None, got {_shown(n_components)}")
    return int(n_components)


def check_hand_basis(hand: np.ndarray, names, *, tol: Tolerances = TOL) -> None:
    """Raise a :class:`WorkbenchError` unless every hand shape moves some point and adds a direction of its own.

    The rules, in the order they are checked: no shape is all zero (norm at most ``tol.zero_displacement``);
    no two shapes are the same (their difference at most ``sqrt(tol.eigen_rel)`` times the largest shape);
    the shapes are linearly independent (every eigenvalue of their Gram matrix above ``tol.eigen_rel`` times the
    largest, the rule that sets the rank of a capture).

    Parameters
    ----------
    hand : ndarray of shape (n_shapes, n_dims)
        Finite hand-made shapes as displacements from neutral.
    names : sequence of str
        One name per shape, for the message.
    tol : Tolerances
    """
    names = list(names)
    norms = np.linalg.norm(hand, axis=1)
    zero = [names[i] for i in np.flatnonzero(norms <= tol.zero_displacement)]
    if zero:
        raise WorkbenchError(
            f"hand basis shape(s) {zero} are all zero (norm <= {tol.zero_displacement:g}); every "
            "hand shape must move some point"
        )
    gram = hand @ hand.T
    squared = np.diag(gram)
    distance_sq = squared[:, None] + squared[None, :] - 2.0 * gram
    first, second = np.triu_indices(len(names), k=1)
    same = np.flatnonzero(distance_sq[first, second] <= tol.eigen_rel * squared.max())
    if same.size:
        a, b = first[same[0]], second[same[0]]
        raise WorkbenchError(
            f"hand basis shapes {names[a]!r} and {names[b]!r} are the same shape (duplicates); "
            "every hand shape must differ from the others"
        )
    values, vectors = np.linalg.eigh(gram)
    dependent = values <= tol.eigen_rel * values[-1]
    if dependent.any():
        combination = np.abs(vectors[:, 0])
        involved = [names[i] for i in np.flatnonzero(combination >= np.sqrt(tol.eigen_rel) * combination.max())]
        raise WorkbenchError(
            f"hand basis is rank-deficient: its {len(names)} shapes span only "
            f"{int((~dependent).sum())} dimensions (shapes {involved} are linearly dependent); "
            "every hand shape must add a direction the others lack"
        )


def covariance_eigen(centred: np.ndarray, *, tol: Tolerances = TOL) -> tuple[np.ndarray, np.ndarray, str]:
    """Eigen-decomposition of the capture covariance ``C = D~ D~^T / L`` (eq. 2), largest first.

    Uses the covariance (``n_dims x n_dims``) or the frame Gram matrix (``L x L``), whichever is smaller; both
    have the same non-zero eigenvalues and the Gram eigenvectors are lifted to eigenfaces by ``D~^T``.

    Parameters
    ----------
    centred : ndarray of shape (n_frames, n_dims)
        The capture minus its mean (``D~`` transposed).
    tol : Tolerances
        ``eigen_rel`` sets which eigenvalues count as zero (rank of the capture).

    Returns
    -------
    eigenvalues : ndarray of shape (rank,)
        Non-zero eigenvalues, descending.
    eigenvectors : ndarray of shape (rank, n_dims)
        Unit eigenfaces as rows, with deterministic signs.
    method : str
        ``"covariance"`` or ``"gram"``.
    """
    n_frames, n_dims = centred.shape
    if n_dims <= n_frames:
        return (*eigen_of_covariance(centred.T @ centred / n_frames, tol=tol), "covariance")
    values, frame_vectors = np.linalg.eigh(centred @ centred.T / n_frames)
    values, frame_vectors = values[::-1], frame_vectors[:, ::-1]
    keep = _nonzero(values, tol)
    values = values[keep]
    # C e = lambda e with e = D~^T u / sqrt(L lambda), for each Gram eigenpair (lambda, u).
    vectors = (centred.T @ frame_vectors[:, keep]).T / np.sqrt(n_frames * values)[:, None]
    return values, flip_signs(vectors), "gram"


def eigen_of_covariance(covariance: np.ndarray, *, tol: Tolerances = TOL) -> tuple[np.ndarray, np.ndarray]:
    """Non-zero eigenpairs of a covariance matrix, largest first, as :func:`covariance_eigen` returns them.

    Parameters
    ----------
    covariance : ndarray of shape (n_dims, n_dims)
        Symmetric positive semi-definite.
    tol : Tolerances

    Returns
    -------
    eigenvalues : ndarray of shape (rank,)
    eigenvectors : ndarray of shape (rank, n_dims)
        Unit eigenfaces as rows, with deterministic signs.
    """
    values, vectors = np.linalg.eigh(covariance)
    values, vectors = values[::-1], vectors[:, ::-1].T
    keep = _nonzero(values, tol)
    return values[keep], flip_signs(vectors[keep])


def _nonzero(values: np.ndarray, tol: Tolerances) -> np.ndarray:
    """Which of the descending eigenvalues count as non-zero (above ``tol.eigen_rel`` times the largest)."""
    return values > tol.eigen_rel * values[0] if values[0] > 0 else np.zeros(values.shape, dtype=bool)


def frames_covariance(capture, mean: np.ndarray, chunk_size: int = 4096) -> np.ndarray:
    """The covariance ``D~^T D~ / L`` of a capture about ``mean``, shape (n_dims, n_dims), in one pass.

    Each chunk of frames is centred while it is in cache; the centred capture is never formed (on a
    35,000 x 198 capture the whole centred copy cost a third more than the product itself).

    Parameters
    ----------
    capture : ndarray of shape (n_frames, n_dims), or FramesOnDisk
        Float64 or float32; read a chunk at a time as float64.
    mean : ndarray of shape (n_dims,)
    chunk_size : int
        Frames per chunk.

    Returns
    -------
    ndarray of shape (n_dims, n_dims)
    """
    covariance = np.zeros((capture.shape[1], capture.shape[1]))
    for _, chunk in frame_chunks(capture, chunk_size):
        centred = chunk - mean
        covariance += centred.T @ centred
    return covariance / capture.shape[0]


def frames_statistics(name: str, capture) -> tuple[np.ndarray, float]:
    """Mean frame, shape (n_dims,), and total variance ``sum |y - mean|^2 / n_frames`` of a float32 or on-disk
    capture, in one float64 pass over chunks; a :class:`WorkbenchError` naming ``name`` for NaN or Inf."""
    sums, squares = np.zeros(capture.shape[1]), 0.0
    for rows, chunk in frame_chunks(capture):
        check_finite_chunk(name, rows, chunk)
        sums += chunk.sum(axis=0)
        squares += float(np.einsum("ij,ij->", chunk, chunk))
    mean = sums / capture.shape[0]
    return mean, max(squares / capture.shape[0] - float(mean @ mean), 0.0)


def n_components_for_coverage(explained_variance_ratio: np.ndarray, coverage: float) -> int:
    """Smallest ``m`` with ``sum_{i<=m} lambda_i / sum_i lambda_i >= coverage`` (section 4).

    Parameters
    ----------
    explained_variance_ratio : ndarray of shape (rank,)
        ``lambda_i / sum lambda``, descending.
    coverage : float
        Threshold in (0, 1]; the paper used 0.995.

    Returns
    -------
    int
    """
    coverage = check_coverage(coverage)
    cumulative = np.cumsum(explained_variance_ratio)
    # Round-off can leave the full sum a hair below 1; the last component always reaches full coverage.
    reached = np.flatnonzero(cumulative >= coverage - 1e-12)
    return int(reached[0]) + 1 if reached.size else len(cumulative)


class Eigenfaces:
    """PCA of a capture with ``m`` chosen by coverage or fixed: the eigenfaces ``E^PCA`` (eq. 2).

    Parameters
    ----------
    coverage : float, default 0.995
        Keep the smallest ``m`` whose cumulative explained variance reaches this (ignored when
        ``n_components`` is given).
    n_components : int or None
        Fixed ``m``; must not exceed the rank of the capture.
    svd_solver : {"auto", "exact", "randomized"}
        ``exact`` decomposes the covariance or the frame Gram matrix, whichever is smaller, and finds every
        eigenvalue. ``randomized`` finds only the leading ones by :func:`randomized_covariance_eigen`, enough
        to reach the coverage (doubling their number until it does); ratios are then taken against the total
        variance (the trace). ``auto`` is the one :func:`auto_solver` puts cheaper (:func:`solver_costs`), and
        ``exact`` while either dimension is at most ``RANDOMIZED_ABOVE``.
    seed : int
        Seed of the randomised solver's test matrix.
    tol : Tolerances
    n_reusable : int or None
        Leading eigenpairs the randomised solver also brings to convergence beyond the kept m, so that
        :meth:`with_n_components` up to that many takes them from this fit (the exact paths find them all).

    Attributes
    ----------
    mean_ : ndarray of shape (n_dims,)
        The capture mean ``mu`` (of whatever the capture holds; the workbench fits displacements from neutral).
    components_ : ndarray of shape (m, n_dims)
        Orthonormal eigenfaces, largest variance first.
    explained_variance_ : ndarray of shape (k,)
        Non-zero eigenvalues of the covariance, descending: all ``rank`` of them with the exact solver, the
        leading ``k >= m`` with the randomised one.
    explained_variance_ratio_ : ndarray of shape (k,)
        Each eigenvalue over the total variance.
    n_components_ : int
    coverage_ : float
        Cumulative explained variance of the kept components.
    method_ : str
        How it was decomposed (``"covariance"``, ``"gram"`` or ``"randomized"``).
    """

    RANDOMIZED_ABOVE = 500
    """``auto`` runs the exact path while either dimension is at most this (both take milliseconds there), else the
    path :func:`auto_solver`'s cost model puts cheaper."""

    def __init__(
        self,
        *,
        coverage: float = 0.995,
        n_components: int | None = None,
        svd_solver: str = "auto",
        seed: int = 0,
        tol: Tolerances = TOL,
        n_reusable: int | None = None,
    ):
        self.coverage = coverage
        self.n_components = n_components
        self.svd_solver = svd_solver
        self.seed = seed
        self.tol = tol
        self.n_reusable = n_reusable

    def fit(self, capture) -> "Eigenfaces":
        """Fit on a capture.

        Parameters
        ----------
        capture : array-like of shape (n_frames, n_dims), or FramesOnDisk
            A float32 or on-disk capture is read a chunk of frames at a time with float64 accumulation by the
            randomised solver (the exact one converts it whole).

        Returns
        -------
        self

        Raises
        ------
        WorkbenchError
            A capture that is not a finite, non-empty 2-D array of at least 2 frames, or has no variance; a
            ``coverage`` outside (0, 1]; an ``n_components`` that is not a positive integer or exceeds the rank.
        """
        stored = is_stored_frames(capture)
        if stored and (capture.ndim != 2 or 0 in capture.shape):
            raise WorkbenchError(f"capture must be a non-empty 2-D array (rows x dims), got shape {capture.shape}")
        # NaN and Inf: found by the randomised path's first pass, which sums the frames anyway
        capture = capture if stored else check_matrix("capture", capture, CAPTURE, finite=False)
        if capture.shape[0] < 2:
            raise WorkbenchError(f"capture needs at least 2 frames for PCA, got {capture.shape[0]}")
        n_components = check_n_components(self.n_components)
        coverage = check_coverage(self.coverage) if n_components is None else None
        if self.svd_solver not in ("auto", "exact", "randomized"):
            raise WorkbenchError(f"svd_solver must be auto, exact or randomized, got {self.svd_solver!r}")
        solver = self.svd_solver
        if solver == "auto":
            solver = auto_solver(*capture.shape, n_components, self.RANDOMIZED_ABOVE)
        if solver == "randomized":
            mean, total, values, vectors = self._randomized(capture, n_components, coverage)
            return self._keep(mean, values, vectors, total, "randomized", n_components, coverage)
        if not stored:
            check_finite("capture", capture, CAPTURE)
        if capture.shape[1] <= capture.shape[0]:  # the covariance is the smaller matrix: one pass over chunks
            mean = frames_statistics("capture", capture)[0] if stored else capture.mean(axis=0)
            values, vectors = eigen_of_covariance(frames_covariance(capture, mean), tol=self.tol)
            method, total = "covariance", values.sum()
        else:  # few frames: the frame Gram matrix needs the whole centred capture
            mean = frames_statistics("capture", capture)[0] if stored else capture.mean(axis=0)
            values, vectors, method = covariance_eigen(np.asarray(capture, dtype=np.float64) - mean, tol=self.tol)
            total = values.sum()
        return self._keep(mean, values, vectors, total, method, n_components, coverage)

    def fit_mapped(self, frames, operator) -> "Eigenfaces":
        """Fit on the capture ``frames @ operator.T`` without forming it: the PCA of data that is a fixed linear map
        of smaller data (mesh frames interpolated from markers by RBF), computed in the small space and lifted.

        With the thin QR ``operator = Q R``, the centred capture is ``S~ R^T Q^T`` (``S~`` the centred small
        frames), so its covariance has the eigenvalues of the ``k x k`` covariance of ``S~ R^T`` and the
        eigenfaces ``Q w`` for its eigenvectors ``w``: exact, at a cost independent of ``n_dims`` but for the QR.

        Parameters
        ----------
        frames : array-like of shape (n_frames, k)
            The small data (e.g. marker displacements, flattened).
        operator : array-like of shape (n_dims, k)
            The linear map (e.g. the RBF interpolation matrix, one block per coordinate).

        Returns
        -------
        self
            As :meth:`fit` on ``frames @ operator.T``, with ``method_ = "mapped"``.
        """
        frames = check_matrix("frames", frames, CAPTURE)
        operator = check_matrix("operator", operator, CAPTURE)
        if operator.shape[1] != frames.shape[1]:
            raise WorkbenchError(
                f"operator must have shape (n_dims, {frames.shape[1]}) to map the frames, got {operator.shape}"
            )
        if frames.shape[0] < 2:
            raise WorkbenchError(f"capture needs at least 2 frames for PCA, got {frames.shape[0]}")
        n_components = check_n_components(self.n_components)
        coverage = check_coverage(self.coverage) if n_components is None else None
        small_mean = frames.mean(axis=0)
        q, r = np.linalg.qr(operator)
        values, small_vectors, _ = covariance_eigen((frames - small_mean) @ r.T, tol=self.tol)
        vectors = flip_signs(small_vectors @ q.T)
        return self._keep(operator @ small_mean, values, vectors, values.sum(), "mapped", n_components, coverage)

    def _keep(self, mean, values, vectors, total, method, n_components, coverage) -> "Eigenfaces":
        """Choose m from the eigenpairs (by coverage or fixed) and set the fitted attributes."""
        if values.size == 0:
            raise WorkbenchError("capture has no variance: every frame is the same")
        ratio = values / total
        if n_components is None:
            m = n_components_for_coverage(ratio, coverage)
        else:
            m = n_components
            if not 1 <= m <= values.size:
                raise WorkbenchError(
                    f"basis.n_components must be between 1 and the capture's rank {values.size}, got "
                    f"{self.n_components}"
                )
        # for with_n_components: every eigenpair of an exact path, the converged ones of the randomised path
        reusable = vectors.shape[0] if method != "randomized" else min(vectors.shape[0], max(m, self.n_reusable or 0))
        self._eigenvectors, self._total = vectors[: max(m, reusable)], total
        self.mean_ = mean
        self.components_ = vectors[:m]
        self.explained_variance_ = values
        self.explained_variance_ratio_ = ratio
        self.n_components_ = m
        self.coverage_ = float(ratio[:m].sum())
        self.method_ = method
        return self

    def _randomized(self, capture, n_components: int | None, coverage: float | None):
        """Mean, total variance and the leading eigenpairs, as many as ``coverage`` or ``n_components`` (whichever
        is not None) needs: at least :data:`FIRST_EIGEN` for the coverage rule (so that a later
        :meth:`with_n_components` up to that many finds them converged), doubled until the coverage is reached."""
        rng = np.random.default_rng(self.seed)
        limit = min(capture.shape) - 1
        n_eigen = min(max(n_components or FIRST_EIGEN, self.n_reusable or 0), limit)

        def checked(ratios):  # the pairs this fit delivers (m on the current estimate) and those kept for reuse
            m = n_components or n_components_for_coverage(ratios, coverage)
            return max(m, self.n_reusable or 0)

        while True:
            mean, total, values, vectors, _ = randomized_covariance_eigen(capture, n_eigen, rng, n_checked=checked)
            keep = values > self.tol.eigen_rel * values[0] if values[0] > 0 else np.zeros(values.shape, bool)
            values, vectors = values[keep], vectors[keep]
            enough = n_components is not None or values.size < n_eigen or values.sum() >= (coverage - 1e-12) * total
            if enough or n_eigen >= limit:
                return mean, total, values, vectors
            n_eigen = min(2 * n_eigen, limit)

    def with_n_components(self, n_components) -> "Eigenfaces":
        """A copy of this fit keeping the leading ``n_components`` eigenfaces of the same decomposition: what
        :meth:`fit` with that ``n_components`` gives, without decomposing the capture again (the paper's m = n
        beside the coverage rule's m). The same arrays for the exact and mapped paths, which find every
        eigenpair; for the randomised one, up to its m or ``n_reusable``, whichever is larger (the pairs its
        convergence test checked, :func:`randomized_covariance_eigen`), of which a fresh fit would keep
        ``n_components``.

        Raises
        ------
        WorkbenchError
            Unfitted, or ``n_components`` not a positive integer or beyond the eigenpairs this fit found.
        """
        self._check_fitted()
        m = check_n_components(n_components)
        values, vectors = self.explained_variance_, self._eigenvectors
        if m is None or m > vectors.shape[0]:
            raise WorkbenchError(
                f"n_components must be between 1 and the {vectors.shape[0]} eigenpairs this fit can give (its m, or "
                f"n_reusable), got {n_components}"
            )
        if self.method_ == "randomized":  # a fresh randomised fit at n_components finds only that many
            values, vectors = values[:m], vectors[:m]
        copy = Eigenfaces(
            coverage=self.coverage,
            n_components=m,
            svd_solver=self.svd_solver,
            seed=self.seed,
            tol=self.tol,
            n_reusable=self.n_reusable,
        )
        return copy._keep(self.mean_, values, vectors, self._total, self.method_, m, None)

    def _check_fitted(self):
        if not hasattr(self, "components_"):
            raise WorkbenchError("Eigenfaces is not fitted yet: call fit(capture) first")

    def reconstruct(self, frames) -> np.ndarray:
        """PCA reconstruction: the mean plus the orthogonal projection onto the eigenfaces.

        Parameters
        ----------
        frames : array-like of shape (n_frames, n_dims)

        Returns
        -------
        ndarray of shape (n_frames, n_dims)
        """
        self._check_fitted()
        frames = check_matrix("frames", frames, CAPTURE, n_columns=self.mean_.shape[0])
        # (frames - mean) C^T without the centred copy of the frames
        coefficients = frames @ self.components_.T - self.mean_ @ self.components_.T
        reconstruction = coefficients @ self.components_
        reconstruction += self.mean_
        return reconstruction


def pca_to_qe_weights(
    hand: np.ndarray, components: np.ndarray, mean: np.ndarray, projection: str = "affine"
) -> np.ndarray:
    """``w_ij = e_j^PCA . (e_i^H - mu)`` (eq. 3), or ``e_j^PCA . e_i^H`` for the linear reading.

    Parameters
    ----------
    hand : ndarray of shape (n_shapes, n_dims)
        Hand-made shapes as displacements from neutral.
    components : ndarray of shape (m, n_dims)
        Orthonormal eigenfaces.
    mean : ndarray of shape (n_dims,)
        Capture mean ``mu`` in the same displacement space as ``hand``.
    projection : {"affine", "linear"}
        ``affine`` projects through ``mu`` exactly as eq. 3-4 are written; ``linear`` projects through the
        origin of displacement space (the neutral face), ignoring ``mu``.

    Returns
    -------
    ndarray of shape (n_shapes, m)
        ``W^{PCA-to-QE}``.
    """
    if projection not in PROJECTIONS:
        raise WorkbenchError(f"projection must be one of {PROJECTIONS}, got {projection!r}")
    offset = mean if projection == "affine" else np.zeros_like(mean)
    return (hand - offset) @ components.T


def quasi_eigen_faces(
    weights: np.ndarray, components: np.ndarray, mean: np.ndarray, projection: str = "affine"
) -> np.ndarray:
    """``e_i^QE = mu + sum_j w_ij e_j^PCA`` (eq. 4), or without ``mu`` for the linear reading.

    Parameters
    ----------
    weights : ndarray of shape (n_shapes, m)
        ``W^{PCA-to-QE}`` from :func:`pca_to_qe_weights`.
    components : ndarray of shape (m, n_dims)
    mean : ndarray of shape (n_dims,)
    projection : {"affine", "linear"}

    Returns
    -------
    ndarray of shape (n_shapes, n_dims)
        Quasi-eigen faces as displacements from neutral.
    """
    if projection not in PROJECTIONS:
        raise WorkbenchError(f"projection must be one of {PROJECTIONS}, got {projection!r}")
    projected = weights @ components
    return mean + projected if projection == "affine" else projected


def empty_axes(weights: np.ndarray, threshold) -> np.ndarray:
    """Post-treatment test: axes ``j`` with ``sum_i |w_ij| < epsilon`` are left empty by the quasi-eigen basis.

    Parameters
    ----------
    weights : ndarray of shape (n_shapes, m)
        ``W^{PCA-to-QE}``.
    threshold : float or ndarray of shape (m,)
        ``epsilon`` in data units, one value or one per axis.

    Returns
    -------
    ndarray of int
        Indices of the empty axes, ascending.
    """
    return np.flatnonzero(np.abs(weights).sum(axis=0) < threshold)


@dataclass(frozen=True)
class QuasiEigenBasis:
    """A quasi-eigen basis with what its construction found.

    Attributes
    ----------
    shapes : ndarray of shape (n_shapes + n_appended, n_dims)
        Quasi-eigen faces (displacements), then any appended eigenfaces.
    names : tuple of str
        Hand-shape names, then ``pca_<j>`` for appended axes (1-based ``j`` as in the paper).
    weights : ndarray of shape (n_shapes, m)
        ``W^{PCA-to-QE}`` (eq. 3).
    projection : str
    empty_axes : tuple of int
        0-based indices of the eigenface axes the quasi-eigen faces leave empty.
    appended_axes : tuple of int
        The empty axes whose eigenfaces were appended to the basis.
    axis_sums : ndarray of shape (m,)
        ``sum_i |w_ij|`` per axis.
    thresholds : ndarray of shape (m,)
        ``epsilon`` per axis in data units.
    hand_residual : float
        The largest distance of a quasi-eigen face from its hand shape, relative to the hand shape's norm: the part
        of a hand shape outside the eigenface hyperplane (``mu + span(eigenfaces)``, affine; ``span(eigenfaces)``,
        linear). 0 when every hand shape lies in it (m large enough): then QE is H
        (:func:`workbench.stats.identities.run_identities`). NaN: not measured.
    """

    shapes: np.ndarray
    names: tuple[str, ...]
    weights: np.ndarray
    projection: str
    empty_axes: tuple[int, ...]
    appended_axes: tuple[int, ...]
    axis_sums: np.ndarray
    thresholds: np.ndarray
    hand_residual: float = float("nan")


def build_quasi_eigen_basis(
    hand,
    names,
    eigenfaces: Eigenfaces,
    *,
    projection: str = "affine",
    empty_axis_eps: float = 0.05,
    empty_axis_scale: str = "axis_std",
    append_empty_axes: bool = False,
) -> QuasiEigenBasis:
    """Project the hand basis onto the eigenface hyperplane (eq. 3-4) and apply the post-treatment.

    Parameters
    ----------
    hand : array-like of shape (n_shapes, n_dims)
        Hand-made shapes as displacements from neutral.
    names : sequence of str
        One name per hand shape.
    eigenfaces : Eigenfaces
        Fitted on the training capture.
    projection : {"affine", "linear"}
    empty_axis_eps : float
        ``epsilon`` of the post-treatment. With ``empty_axis_scale="axis_std"`` it is a fraction of each axis's
        standard deviation in the capture (``sqrt(lambda_j)``), so the test does not depend on units; with
        ``"absolute"`` it is in data units, as the paper writes it.
    empty_axis_scale : {"axis_std", "absolute"}
    append_empty_axes : bool
        Append the eigenface of every empty axis to the basis (the paper's simplest remedy).

    Returns
    -------
    QuasiEigenBasis

    Raises
    ------
    WorkbenchError
        Unfitted ``eigenfaces``; a hand basis that is not finite, has the wrong number of columns or names, or
        breaks a rule of :func:`check_hand_basis` (all-zero, duplicate or linearly dependent shapes); an unknown
        ``projection`` or ``empty_axis_scale``, a negative or non-finite ``empty_axis_eps``.
    """
    eigenfaces._check_fitted()
    hand = check_matrix("hand basis", hand, CAPTURE, n_columns=eigenfaces.mean_.shape[0])
    names = tuple(str(name) for name in names)
    if len(names) != hand.shape[0]:
        raise WorkbenchError(f"hand basis has {hand.shape[0]} shapes but {len(names)} names")
    if len(set(names)) != len(names):
        raise WorkbenchError(f"hand basis names must be distinct, got {list(names)}")
    if projection not in PROJECTIONS:
        raise WorkbenchError(f"projection must be one of {PROJECTIONS}, got {projection!r}")
    if empty_axis_scale not in EMPTY_AXIS_SCALES:
        raise WorkbenchError(f"empty_axis_scale must be one of {EMPTY_AXIS_SCALES}, got {empty_axis_scale!r}")
    if not _is_number(empty_axis_eps) or not 0 <= empty_axis_eps < np.inf:
        raise WorkbenchError(f"empty_axis_eps must be a finite number >= 0, got {_shown(empty_axis_eps)}")
    if not isinstance(append_empty_axes, (bool, np.bool_)):
        raise WorkbenchError(f"append_empty_axes must be true or false, got {_shown(append_empty_axes)}")
    check_hand_basis(hand, names, tol=eigenfaces.tol)
    components, mean = eigenfaces.components_, eigenfaces.mean_
    weights = pca_to_qe_weights(hand, components, mean, projection)
    shapes = quasi_eigen_faces(weights, components, mean, projection)
    residual = float(np.max(np.linalg.norm(shapes - hand, axis=1) / np.linalg.norm(hand, axis=1)))
    m = components.shape[0]
    if empty_axis_scale == "axis_std":
        thresholds = empty_axis_eps * np.sqrt(eigenfaces.explained_variance_[:m])
    else:
        thresholds = np.full(m, float(empty_axis_eps))
    empty = empty_axes(weights, thresholds)
    appended = empty if append_empty_axes else np.array([], dtype=int)
    if appended.size:
        shapes = np.vstack([shapes, components[appended]])
        names = names + tuple(f"pca_{j + 1}" for j in appended)
    return QuasiEigenBasis(
        shapes=shapes,
        names=names,
        weights=weights,
        projection=projection,
        empty_axes=tuple(int(j) for j in empty),
        appended_axes=tuple(int(j) for j in appended),
        axis_sums=np.abs(weights).sum(axis=0),
        thresholds=thresholds,
        hand_residual=residual,
    )
