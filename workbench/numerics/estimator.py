"""The paper's method as a scikit-learn style estimator on plain NumPy arrays: :class:`QuasiEigenFaces`.

No config and no files: frames, hand shapes and (for the paper's absolute alpha) the neutral face in, fitted
arrays out. Every number comes from the functions the command line runs (:mod:`workbench.numerics.bases`,
:mod:`workbench.numerics.solve`, :mod:`workbench.numerics.reduced`, :mod:`workbench.numerics.metrics`), composed as a run composes them, so
that an estimator fitted on a capture's arrays gives the alpha of that run's record.

scikit-learn (the ``bases`` extra) is optional: when it is installed the estimator is one of its estimators
(``BaseEstimator``, ``TransformerMixin``: tags, cloning, the HTML display) and :class:`NotFittedError` is its
``sklearn.exceptions.NotFittedError``; without it the estimator keeps the same parameters and methods.
"""

from __future__ import annotations

import dataclasses
import inspect
import warnings
from typing import Mapping

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.numerics.bases import Eigenfaces, build_quasi_eigen_basis
from workbench.numerics.displacements import check_displacements, frames_mean_and_motion
from workbench.numerics.estimator_manners import ScikitLearnManners
from workbench.numerics.metrics import AlphaSummary, basis_conditioning, summarise_squares
from workbench.numerics.reduced import Subspace, project_frames
from workbench.numerics.solve import KINDS, in_span_error_sq, reconstruct, reduce_basis, solve_projected, solve_weights
from workbench.numerics.validation import CAPTURE, check_matrix

SVD_SOLVERS = {"auto": "auto", "full": "exact", "randomized": "randomized"}
"""``svd_solver`` as scikit-learn names it -> :class:`workbench.numerics.bases.Eigenfaces`' own name."""
THROUGH = {"mean": "affine", "neutral": "linear"}
"""``through`` -> the projection of :func:`workbench.numerics.bases.build_quasi_eigen_basis` (the run's ``QE`` and
``QE-linear`` rows)."""
BASES = ("QE", "H", "PCA")
NORMALISATIONS = ("absolute", "displacement")
AGGREGATES = ("mean", "pooled", "per_frame")
FRAMES_AS = ("auto", "displacements", "positions")
"""``frames_as``: displacements refused when they look like positions, displacements as given, or positions."""
POSITIONS_REMEDY = (
    "if they are positions, give the neutral face and say so, QuasiEigenFaces(neutral=v0, frames_as='positions'), "
    "which subtracts it; if they are displacements, frames_as='displacements'"
)
CONSTANT_REL = 1e-10
"""Frames whose spread ``sqrt(total variance)`` is at most this times their root-mean-square norm are numerically
constant (round-off of the mean, not motion)."""
SCALE_RANGE = (1e-150, 1e150)
"""The largest ``|value|`` of frames and hand shapes must lie in this range: the fit sums squares of the values,
which overflow (``inf``) above it and underflow to zero below it in float64."""
WORKING_SCALE_BELOW = 1e-3
"""Frames whose largest ``|value|`` is below this are divided by the power of two nearest it for the computation
(``scale_``), so that the tolerances the workbench states in data units (``TOL.zero_displacement``: 1e-9) stay
small against them; at or above it (millimetres, metres) they are computed as given, as a run computes them."""

try:
    from sklearn.base import BaseEstimator, TransformerMixin
    from sklearn.exceptions import NotFittedError
except ImportError:  # the core without the bases extra

    class NotFittedError(WorkbenchError, AttributeError):
        """A fitted attribute or method of an estimator used before ``fit`` (a ``ValueError`` and an
        ``AttributeError``, as scikit-learn's ``NotFittedError``, which takes its place when scikit-learn is
        installed)."""

    ESTIMATOR_BASES: tuple = ()
    ESTIMATOR_OPTIONS: dict = {}
else:
    ESTIMATOR_BASES = (TransformerMixin, BaseEstimator)
    ESTIMATOR_OPTIONS = {"auto_wrap_output_keys": None}  # set_output is ScikitLearnManners', for every basis=


class QuasiEigenFaces(ScikitLearnManners, *ESTIMATOR_BASES, **ESTIMATOR_OPTIONS):
    """Quasi-eigen faces (Kim & Ko, eq. 2-6): eigenfaces of a capture, the hand shapes projected onto their
    hyperplane, weights of frames in that basis and the reconstruction error alpha.

    Frames and shapes are rows of displacements from the neutral face, ``n_dims = 3 * n_points`` columns
    ``[x0, y0, z0, x1, ...]`` (the paper's ``3N x L`` matrix, transposed), as a run's capture holds them.

    Parameters
    ----------
    hand_shapes : array-like of shape (n_shapes, n_dims)
        ``E^H``: the hand-made shapes as displacements from neutral; none all zero, none a copy of another,
        linearly independent. Required by :meth:`fit`; a parameter (not an argument of ``fit``) so that a
        ``Pipeline``, ``GridSearchCV`` or ``cross_validate`` fits every clone with them.
    neutral : array-like of shape (n_dims,) or None, default None
        Neutral positions ``v0``, for the paper's absolute alpha (:meth:`alpha`, :meth:`score`); not used by the
        fit.
    names : sequence of str or None, default None
        One distinct name per hand shape (default ``shape_1``, ``shape_2``, ...).
    coverage : float, default 0.995
        Keep the smallest ``m`` eigenfaces whose cumulative explained variance reaches this (the paper: 99.5 %);
        ignored when ``n_components`` is given.
    n_components : int or None, default None
        A fixed ``m`` instead of the coverage rule (at most the rank of the frames).
    svd_solver : {"auto", "full", "randomized"}, default "auto"
        How the eigenfaces are found, as scikit-learn's ``PCA`` names it: ``"full"`` decomposes the covariance (or
        the frames' Gram matrix, whichever is smaller) and finds every eigenvalue; ``"randomized"`` finds the
        leading ones in a randomised block Krylov space, as many as the coverage needs; ``"auto"`` takes the one
        the cost model puts cheaper (:func:`workbench.numerics.randomized_pca.auto_solver`), as a run does.
    random_state : int, numpy.random.Generator or None, default None
        Seed of the randomised solver's test matrix; None is the seed a run uses (0), so that the default
        reproduces a run (unlike scikit-learn, where None draws a new seed). Unused by ``"full"``.
    through : {"mean", "neutral"}, default "mean"
        Where the hand shapes are projected through: ``"mean"`` is eq. 3-4 as written (affine, through the capture
        mean ``mu``: the run's ``QE`` rows); ``"neutral"`` projects through the neutral face, the origin of
        displacement space (linear: the run's ``QE-linear`` rows).
    solver : {"lstsq", "nnls", "box"}, default "lstsq"
        The weights of eq. 5: unconstrained least squares, ``w >= 0``, or ``lower <= w <= upper`` with
        ``bounds``; :meth:`transform` and :meth:`alpha` may override it per call.
    bounds : tuple of (float or None, float or None), default (0.0, 1.0)
        ``(lower, upper)`` of the ``"box"`` solver (the run's ``solver=box``: blendshape sliders in [0, 1]).
    empty_axis_eps : float, default 0.05
        Post-treatment ``epsilon``: an eigenface axis with ``sum_i |w_ij|`` below it is left empty by the
        quasi-eigen faces (``empty_axes_``).
    empty_axis_scale : {"axis_std", "absolute"}, default "axis_std"
        ``epsilon`` as a fraction of each axis's standard deviation in the frames, or in data units.
    append_empty_axes : bool, default False
        Append the eigenface of each empty axis to ``shapes_`` (the paper's simplest remedy).
    frames_as : {"auto", "displacements", "positions"}, default "auto"
        What every method's ``frames`` are. ``"auto"``: displacements, refused in one line when they look like
        positions (:mod:`workbench.numerics.displacements`: the spread of their mean face over their motion above
        5); ``"displacements"``: displacements, not checked; ``"positions"``: positions ``v*``, from which
        ``neutral`` (then required) is subtracted (and :meth:`inverse_transform` gives positions back).

    The defaults are the run's (``conf/basis/default.yaml``, ``conf/solver``).

    Attributes
    ----------
    n_features_in_ : int
        ``n_dims`` of the frames fitted on.
    feature_names_in_ : ndarray of shape (n_dims,)
        The column names of a DataFrame fitted on (absent for an array); every later use of frames with names
        requires the same columns in the same order.
    point_motion_ : float
        The RMS motion of a point in the frames fitted on (``sqrt`` of their covariance trace over ``n_points``):
        the scale that ``frames_as="auto"`` measures later frames' mean face against.
    mean_ : ndarray of shape (n_dims,)
        The mean ``mu`` of the frames (a mean displacement from neutral).
    eigenfaces_ : ndarray of shape (m, n_dims)
        ``E^PCA``: orthonormal eigenfaces as rows, largest variance first, each with its largest-magnitude entry
        positive (deterministic signs, as scikit-learn's ``svd_flip``).
    explained_variance_ : ndarray of shape (m,)
        The eigenvalues of the frames' covariance (eq. 2) of the ``m`` eigenfaces kept, descending, whichever
        ``svd_solver`` found them (as scikit-learn's ``PCA``, one per component). The covariance divides by
        ``n_frames`` (the paper's ``C = D~ D~^T / L``, as a run computes it), where scikit-learn's ``PCA`` divides
        by ``n_frames - 1``: multiply by ``n_frames / (n_frames - 1)`` to compare. The ratios are the same.
    explained_variance_ratio_ : ndarray of shape (m,)
        Each over the total variance (the trace of the covariance); they sum to ``coverage_``.
    m_ : int
        Number of eigenfaces kept.
    coverage_ : float
        Explained variance the ``m_`` eigenfaces reach.
    hand_shapes_ : ndarray of shape (n_shapes, n_dims)
        ``E^H``, the hand shapes fitted with (a copy).
    shape_names_ : tuple of str
        One name per row of ``shapes_``: the hand shapes' names, then ``pca_<j>`` for appended axes.
    pca_to_qe_weights_ : ndarray of shape (n_shapes, m)
        ``W^{PCA-to-QE}`` of eq. 3: ``shapes_[:n_shapes] = mu + pca_to_qe_weights_ @ eigenfaces_`` (without ``mu``
        for ``through="neutral"``).
    shapes_ : ndarray of shape (n_shapes + n_appended, n_dims)
        ``E^QE``, the quasi-eigen faces (eq. 4) as displacements from neutral, then any appended eigenfaces.
    empty_axes_ : tuple of int
        0-based indices of the eigenface axes the quasi-eigen faces leave empty (post-treatment).
    neutral_ : ndarray of shape (n_dims,) or None
        Neutral positions ``v0`` given to :meth:`fit` (the absolute alpha of eq. 6 needs them).
    scale_ : float
        1.0, or for frames whose largest ``|value|`` is below ``WORKING_SCALE_BELOW`` (1e-3) the power of two they
        are divided by inside the computation (every attribute and result is in the frames' own units).

    Examples
    --------
    >>> qe = QuasiEigenFaces(hand_shapes=hand, neutral=neutral, n_components=18).fit(frames)  # doctest: +SKIP
    >>> weights = qe.transform(frames, solver="nnls")  # doctest: +SKIP
    >>> qe.alpha(frames)  # doctest: +SKIP
    """

    def __init__(
        self,
        *,
        hand_shapes=None,
        neutral=None,
        names=None,
        coverage: float = 0.995,
        n_components: int | None = None,
        svd_solver: str = "auto",
        random_state=None,
        through: str = "mean",
        solver: str = "lstsq",
        bounds: tuple = (0.0, 1.0),
        empty_axis_eps: float = 0.05,
        empty_axis_scale: str = "axis_std",
        append_empty_axes: bool = False,
        frames_as: str = "auto",
    ):
        self.hand_shapes = hand_shapes
        self.neutral = neutral
        self.names = names
        self.coverage = coverage
        self.n_components = n_components
        self.svd_solver = svd_solver
        self.random_state = random_state
        self.through = through
        self.solver = solver
        self.bounds = bounds
        self.empty_axis_eps = empty_axis_eps
        self.empty_axis_scale = empty_axis_scale
        self.append_empty_axes = append_empty_axes
        self.frames_as = frames_as

    # -- scikit-learn's parameter protocol -------------------------------------------------------------------

    @classmethod
    def _parameter_names(cls) -> list[str]:
        return [name for name in inspect.signature(cls.__init__).parameters if name != "self"]

    def get_params(self, deep: bool = True) -> dict:
        """The parameters as given to ``__init__`` (``deep`` is accepted for scikit-learn's ``clone``)."""
        return {name: getattr(self, name) for name in self._parameter_names()}

    def set_params(self, **params) -> "QuasiEigenFaces":
        """Set parameters by name; returns ``self``. Fitted attributes are left as they are until the next fit."""
        unknown = sorted(set(params) - set(self._parameter_names()))
        if unknown:
            raise WorkbenchError(
                f"QuasiEigenFaces has no parameter {unknown[0]!r}; its parameters are {self._parameter_names()}"
            )
        for name, value in params.items():
            setattr(self, name, value)
        return self

    def __repr__(self) -> str:
        defaults = {
            name: parameter.default for name, parameter in inspect.signature(type(self).__init__).parameters.items()
        }
        changed = [
            f"{name}={_shown(value)}" for name, value in self.get_params().items() if not _same(value, defaults[name])
        ]
        return f"{type(self).__name__}({', '.join(changed)})"

    def __sklearn_is_fitted__(self) -> bool:
        """Whether :meth:`fit` has run (scikit-learn's ``check_is_fitted`` asks this)."""
        return hasattr(self, "shapes_")

    # -- fitting ---------------------------------------------------------------------------------------------

    def fit(self, frames, y=None) -> "QuasiEigenFaces":
        """Fit the eigenfaces on ``frames`` (eq. 2) and project ``hand_shapes`` onto their hyperplane (eq. 3-4).

        Parameters
        ----------
        frames : array-like of shape (n_frames, n_dims)
            Training frames as displacements from the neutral face, ``n_dims = 3 * n_points``; at least 2, not all
            the same. Real numbers only: complex values and NumPy masked arrays are refused (the estimator has no
            gap policy; drop or fill masked frames first). Positions instead for ``frames_as="positions"``;
            a DataFrame's column names become ``feature_names_in_``.
        y : None
            Ignored (scikit-learn's convention); the hand shapes are the parameter ``hand_shapes`` (without it, a 2-D
            ``y``, the hand shapes given here as earlier versions took them, is refused saying so).

        Returns
        -------
        self

        Raises
        ------
        WorkbenchError
            Naming the argument or parameter and the rule it broke; for ``frames_as="auto"``, frames that look like
            positions (:mod:`workbench.numerics.displacements`), naming ``neutral`` and ``frames_as``.

        Warns
        -----
        UserWarning
            When the quasi-eigen basis is rank-deficient (more hand shapes than eigenfaces): its weights are not
            unique, as the command line's table notes.
        """
        through, _ = self._checked_parameters()
        if self.hand_shapes is None and y is not None and np.ndim(y) == 2:  # as earlier versions took them
            raise WorkbenchError(
                "fit takes the frames alone: give the hand shapes as QuasiEigenFaces(hand_shapes=...), not as y"
            )
        svd_solver = SVD_SOLVERS[_check_choice("svd_solver", self.svd_solver, tuple(SVD_SOLVERS))]
        seed = _check_random_state(self.random_state)
        frames_as = _check_choice("frames_as", self.frames_as, FRAMES_AS)
        self._remember_columns(frames)
        frames = check_matrix("frames", frames, CAPTURE)
        if frames.shape[1] % 3:
            raise WorkbenchError(f"frames must have 3 * n_points columns (x, y, z per point), got {frames.shape[1]}")
        _check_scale("frames", frames)
        if self.hand_shapes is None:
            raise WorkbenchError(
                "hand_shapes must be given: QuasiEigenFaces(hand_shapes=<array of shape (n_shapes, n_dims)>)"
            )
        hand = check_matrix("hand_shapes", self.hand_shapes, CAPTURE, n_columns=frames.shape[1])
        _check_scale("hand_shapes", hand)
        neutral = None if self.neutral is None else _check_vector("neutral", self.neutral, frames.shape[1])
        frames = _training_displacements(frames, frames_as, neutral)
        largest = _largest(frames)
        scale = float(2.0 ** np.round(np.log2(largest))) if 0 < largest < WORKING_SCALE_BELOW else 1.0
        if scale != 1.0:  # a power of two: exact
            frames, hand = frames / scale, hand / scale
            with np.errstate(over="ignore"):  # an overflow is refused here, in one line
                overflows = neutral is not None and not np.all(np.isfinite(neutral / scale))
            if overflows:
                raise WorkbenchError(f"neutral is too large against the frames' scale {largest:.3g}: rescale both")
        names = tuple(f"shape_{i + 1}" for i in range(hand.shape[0])) if self.names is None else self.names
        if isinstance(names, str) or len(names) != hand.shape[0]:
            raise WorkbenchError(
                f"names must be a sequence of one name per hand shape ({hand.shape[0]}), got {names!r:.80}"
            )
        if not np.ptp(frames, axis=0).any():
            raise WorkbenchError(f"frames are numerically constant: all {frames.shape[0]} frames are the same")
        eigenfaces = Eigenfaces(
            coverage=self.coverage, n_components=self.n_components, svd_solver=svd_solver, seed=seed
        ).fit(frames)
        _check_not_constant(eigenfaces)
        mean, motion = frames_mean_and_motion(frames)
        if frames_as == "auto":  # after the constant frames' own refusal: their motion is round-off
            check_displacements("frames", mean, motion, POSITIONS_REMEDY)
        epsilon = self.empty_axis_eps
        if self.empty_axis_scale == "absolute" and _is_number(epsilon):  # in data units
            epsilon = epsilon / scale
        basis = build_quasi_eigen_basis(
            hand,
            names,
            eigenfaces,
            projection=THROUGH[through],
            empty_axis_eps=epsilon,
            empty_axis_scale=self.empty_axis_scale,
            append_empty_axes=self.append_empty_axes,
        )
        self.n_features_in_ = frames.shape[1]
        self.point_motion_ = motion * scale
        self.scale_ = scale
        self.mean_ = eigenfaces.mean_ * scale
        self.eigenfaces_ = eigenfaces.components_
        self.m_ = int(eigenfaces.n_components_)
        self.explained_variance_ = eigenfaces.explained_variance_[: self.m_] * scale**2
        self.explained_variance_ratio_ = eigenfaces.explained_variance_ratio_[: self.m_]
        self.coverage_ = float(eigenfaces.coverage_)
        self.hand_shapes_ = hand * scale
        self.shape_names_ = basis.names
        self.pca_to_qe_weights_ = basis.weights * scale
        self.shapes_ = basis.shapes * scale
        self.empty_axes_ = basis.empty_axes
        self.neutral_ = neutral
        conditioning = basis_conditioning(self.shapes_)
        if conditioning.rank < conditioning.n_shapes:
            warnings.warn(
                f"QuasiEigenFaces: the quasi-eigen basis is rank-deficient, rank {conditioning.rank} of "
                f"{conditioning.n_shapes} shapes on {self.m_} eigenfaces (weights not unique; minimum-norm for "
                "lstsq); n_components >= the number of hand shapes gives a full-rank basis",
                UserWarning,
                stacklevel=2,
            )
        return self

    def fit_transform(self, frames, y=None) -> np.ndarray:
        """:meth:`fit`, then :meth:`transform` of the same frames; ``y`` is ignored."""
        return self.fit(frames).transform(frames)

    # -- using the fit ---------------------------------------------------------------------------------------

    def transform(self, frames, *, solver: str | None = None, basis: str = "QE") -> np.ndarray:
        """Weights of every frame (eq. 5): ``min_w |d* - sum_i w_i e_i|^2`` under the solver's constraints.

        Parameters
        ----------
        frames : array-like of shape (n_frames, n_dims)
            Displacements from neutral (positions for ``frames_as="positions"``), in the columns fitted on.
        solver : {"lstsq", "nnls", "box"}, optional
            Overrides the estimator's ``solver`` for this call (``"box"`` uses ``bounds``). With a rank-deficient
            basis (more quasi-eigen faces than eigenfaces) the weights are not unique: ``lstsq`` gives the
            minimum-norm ones.
        basis : {"QE", "H", "PCA"}, default "QE"
            ``QE``: the quasi-eigen faces ``shapes_``; ``H``: the hand shapes; ``PCA``: the coordinates of
            ``frames - mean_`` along ``eigenfaces_`` (an orthogonal projection: no solver).

        Returns
        -------
        ndarray of shape (n_frames, n_shapes)
            ``n_shapes`` is ``len(shapes_)``, ``len(hand_shapes_)`` or ``m_``; a DataFrame whose columns are the
            shape names (``pca_<j>`` for PCA) after ``set_output(transform="pandas")``.
        """
        self._check_fitted()
        given, frames = frames, self._displacements(frames)
        basis = _check_choice("basis", basis, BASES)
        if basis == "PCA":
            _no_solver_for_pca(solver)
            names = [f"pca_{j + 1}" for j in range(self.m_)]
            return self._in_container((frames - self.mean_) @ self.eigenfaces_.T, given, names)
        shapes, frames = self._working(self._shapes(basis)), self._working(frames)
        weights = solve_weights(shapes, frames, **self._solver_arguments(solver)).weights
        names = self.shape_names_ if basis == "QE" else self.shape_names_[: len(self.hand_shapes_)]
        return self._in_container(weights, given, names)

    def inverse_transform(self, weights, *, basis: str = "QE") -> np.ndarray:
        """Reconstructed displacements from weights: ``weights @ shapes`` (eq. 1 without ``v0``), for PCA
        ``mean_ + weights @ eigenfaces_``.

        Parameters
        ----------
        weights : array-like of shape (n_frames, n_shapes)
        basis : {"QE", "H", "PCA"}, default "QE"
            The basis the weights belong to (as :meth:`transform`).

        Returns
        -------
        ndarray of shape (n_frames, n_dims)
            Displacements, or positions (``neutral_`` added) for ``frames_as="positions"``.
        """
        self._check_fitted()
        basis = _check_choice("basis", basis, BASES)
        if basis == "PCA":
            displacements = self.mean_ + reconstruct(self.eigenfaces_, weights)
        else:
            displacements = reconstruct(self._shapes(basis), weights)
        if _check_choice("frames_as", self.frames_as, FRAMES_AS) == "positions":
            return displacements + self._neutral_for_positions()
        return displacements

    def alpha(
        self,
        frames,
        *,
        solver: str | None = None,
        basis: str = "QE",
        normalisation: str = "absolute",
        aggregate: str = "mean",
    ):
        """Reconstruction error alpha in percent (eq. 6) of ``frames`` reconstructed in a basis.

        Computed as a run computes the alpha table (:mod:`workbench.numerics.reduced`: each frame's coordinates in the
        basis's span and its distance to it, the weights from the coordinates, the error from both), so the value
        equals the run's record to rounding; it equals the alpha of ``inverse_transform(transform(frames))`` to
        rounding as well.

        Parameters
        ----------
        frames : array-like of shape (n_frames, n_dims)
            Displacements from neutral ``d*`` (positions ``v*`` for ``frames_as="positions"``).
        solver : {"lstsq", "nnls", "box"}, optional
            Overrides ``solver``; must be None for ``basis="PCA"``, whose reconstruction is the mean plus the
            orthogonal projection onto the eigenfaces.
        basis : {"QE", "H", "PCA"}, default "QE"
        normalisation : {"absolute", "displacement"}, default "absolute"
            ``absolute``: the paper's literal ``100 |v* - v| / |v*|`` over positions ``v* = v0 + d*`` (needs
            ``neutral`` given to :meth:`fit`; its value depends on where the coordinate origin is);
            ``displacement``: ``100 |d* - d| / |d*|``.
        aggregate : {"mean", "pooled", "per_frame"}, default "mean"
            Mean of the per-frame values (frames with a zero reference left out), pooled over all frames
            (``100 sqrt(sum |error|^2 / sum |reference|^2)``), or the per-frame values (NaN where undefined).

        The defaults are the run's headline (``metric.headline_normalisation: absolute``,
        ``metric.headline_aggregate: mean``): the record's ``alpha_abs_mean``.

        Returns
        -------
        float, or ndarray of shape (n_frames,) for ``aggregate="per_frame"``
        """
        normalisation = _check_choice("normalisation", normalisation, NORMALISATIONS)
        aggregate = _check_choice("aggregate", aggregate, AGGREGATES)
        self._check_fitted()
        if normalisation == "absolute" and self.neutral_ is None:
            raise WorkbenchError(
                "alpha with normalisation='absolute' needs the neutral positions: pass neutral= to "
                "fit, or use normalisation='displacement'"
            )
        summary = self._summary(frames, solver=solver, basis=basis)
        if aggregate == "per_frame":
            return summary.absolute_per_frame if normalisation == "absolute" else summary.displacement_per_frame
        return getattr(summary, f"{normalisation}_{aggregate}")

    def score(self, frames, y=None) -> float:
        """Minus the headline alpha of ``frames`` in percent, for a search that maximises its score.

        The headline is a run's (``metric.headline_*``): the quasi-eigen basis with the estimator's ``solver``,
        absolute alpha (eq. 6 over positions ``neutral + frames``), mean of the per-frame values, i.e. the record's
        ``alpha_abs_mean`` of the ``QE`` row. Without ``neutral`` the positions are measured from the neutral face,
        so it is the mean displacement alpha (``alpha_disp_mean``).

        Parameters
        ----------
        frames : array-like of shape (n_frames, n_dims)
            Displacements from neutral (positions for ``frames_as="positions"``).
        y : None
            Ignored (scikit-learn's convention).

        Returns
        -------
        float
            ``-alpha``: higher is better.
        """
        return -float(self._summary(frames).absolute_mean)

    def alpha_summary(self, frames, *, solver: str | None = None, basis=BASES):
        """Every variant of eq. 6 and the RMS point error, one row per basis, as a run's alpha table holds them.

        Parameters
        ----------
        frames : array-like of shape (n_frames, n_dims)
            Displacements from neutral (positions for ``frames_as="positions"``).
        solver : {"lstsq", "nnls", "box"}, optional
            The solver of eq. 5 for ``QE`` and ``H`` (the estimator's ``solver`` when None); PCA takes none.
        basis : str or sequence of str, default ("QE", "H", "PCA")
            The bases compared, as in :meth:`alpha`.

        Returns
        -------
        pandas.DataFrame
            One row per basis, columns ``basis``, ``solver`` (``projection`` for PCA, as in a run's table),
            ``n_frames``, ``alpha_abs_mean``, ``alpha_abs_pooled``, ``alpha_disp_mean``, ``alpha_disp_pooled`` (in
            percent) and ``rms_mm`` (the RMS point error, in the frames' units): the record's column names. Without
            ``neutral`` given to :meth:`fit`, the absolute variants are those of the origin at the neutral face
            (equal to the displacement ones). The per-frame values are :meth:`alpha`'s ``aggregate="per_frame"``.
        """
        import pandas as pd

        names = [basis] if isinstance(basis, str) else list(basis) if isinstance(basis, (list, tuple)) else None
        if not names:
            raise WorkbenchError(f"basis must be one of {', '.join(map(repr, BASES))} or a list of them; got {basis!r}")
        rows = []
        for name in names:
            given = solver if isinstance(basis, str) or name != "PCA" else None  # a list: PCA without the solver
            summary = self._summary(frames, solver=given, basis=name)
            rows.append(
                {
                    "basis": name,
                    "solver": "projection" if name == "PCA" else solver or self.solver,
                    "n_frames": len(summary.absolute_per_frame),
                    **summary.table_values(),
                }
            )
        return pd.DataFrame(rows)

    def pose(self, weights, basis: str = "QE", *, positions: bool = False) -> np.ndarray:
        """The face a rig shows at slider values ``weights``: ``sum_i w_i e_i`` (eq. 1), plus ``v0`` for positions.

        Parameters
        ----------
        weights : array-like of shape (n_shapes,) or (n_poses, n_shapes), or mapping of str to float
            One value per shape of the basis, in the order of its names (``shape_names_`` for ``QE``, the hand
            shapes' names for ``H``, the eigenfaces' order for ``PCA``); or a mapping from shape name to value,
            shapes it leaves out at 0 (``{"jawOpen": 1.0}``: the paper's figure 2, one shape alone).
        basis : {"QE", "H", "PCA"}, default "QE"
            ``PCA`` poses ``mean_ + sum_j w_j eigenfaces_j`` (its sliders are the eigenface coordinates).
        positions : bool, default False
            False: displacements from neutral; True: vertex positions ``neutral + displacement`` (needs ``neutral``
            given to :meth:`fit`).

        Returns
        -------
        ndarray of shape (n_dims,) or (n_poses, n_dims)
            One row per pose, 1-D for 1-D weights or a mapping; ``[x0, y0, z0, x1, ...]`` in the frames' units.
        """
        self._check_fitted()
        basis = _check_choice("basis", basis, BASES)
        shapes = self.eigenfaces_ if basis == "PCA" else self._shapes(basis)
        names = (
            tuple(f"pca_{j + 1}" for j in range(self.m_)) if basis == "PCA" else tuple(self.shape_names_[: len(shapes)])
        )
        if isinstance(weights, Mapping):
            unknown = sorted(set(weights) - set(names))
            if unknown:
                raise WorkbenchError(f"pose: basis {basis!r} has no shape {unknown[0]!r}; its shapes are {list(names)}")
            weights = [weights.get(name, 0.0) for name in names]
        try:
            one_pose = np.ndim(weights) == 1
        except ValueError:  # ragged rows: check_matrix words it
            one_pose = False
        values = check_matrix("weights", [weights] if one_pose else weights, CAPTURE)
        if values.shape[1] != len(names):
            raise WorkbenchError(
                f"pose: weights must hold one value per shape of basis {basis!r} ({len(names)}), got {values.shape[1]}"
            )
        if positions and self.neutral_ is None:
            raise WorkbenchError("pose(positions=True) needs the neutral positions: pass neutral= to fit")
        posed = values @ shapes + (self.mean_ if basis == "PCA" else 0.0)
        if positions:
            posed = posed + self.neutral_
        return posed[0] if one_pose else posed

    def _summary(self, frames, *, solver: str | None = None, basis: str = "QE") -> AlphaSummary:
        """Every variant of eq. 6, per frame too, and the RMS point error of one basis's reconstruction
        (:class:`workbench.numerics.metrics.AlphaSummary`, what a run's table row holds)."""
        self._check_fitted()
        frames = self._displacements(frames)
        basis = _check_choice("basis", basis, BASES)
        neutral = self.neutral_ if self.neutral_ is not None else np.zeros(self.n_features_in_)
        frames, neutral = self._working(frames), self._working(neutral)
        n_compared = frames.shape[0] * (frames.shape[1] // 3)
        if basis == "PCA":
            _no_solver_for_pca(solver)
            subspace = Subspace(self.eigenfaces_.T, self._working(self.mean_))
            projections = project_frames(frames, {"PCA": subspace}, neutral)
            error_sq = projections.distance_sq["PCA"]
        else:
            reduction = reduce_basis(self._working(self._shapes(basis)))
            projections = project_frames(frames, {basis: Subspace(reduction.u)}, neutral)
            coordinates = projections.coordinates[basis]
            solution = solve_projected(reduction, coordinates, **self._solver_arguments(solver))
            error_sq = projections.distance_sq[basis] + in_span_error_sq(reduction, coordinates, solution.weights)
        summary = summarise_squares(error_sq, projections.displacement_sq, projections.position_sq, n_compared)
        if self.scale_ == 1.0:
            return summary
        squared = self.scale_**2  # back to data units: alpha is a ratio, the RMS and the squares are not
        return dataclasses.replace(
            summary,
            rms_mm=summary.rms_mm * self.scale_,
            error_sq=summary.error_sq * squared,
            displacement_sq=summary.displacement_sq * squared,
            position_sq=summary.position_sq * squared,
        )

    # -- checks ----------------------------------------------------------------------------------------------

    def _check_fitted(self) -> None:
        if not hasattr(self, "shapes_"):
            raise NotFittedError(
                f"This {type(self).__name__} instance is not fitted yet: call fit(frames) before using it"
            )

    def _checked_parameters(self) -> tuple[str, dict]:
        """``through``, ``bounds`` and the solver's arguments, checked (the other parameters are checked by the
        functions they go to: coverage and n_components by the eigenfaces, the post-treatment's by the quasi-eigen
        basis). ``bounds`` is checked whatever the solver, since :meth:`transform` may ask for ``"box"``."""
        _check_bounds(self.bounds)
        return _check_choice("through", self.through, tuple(THROUGH)), self._solver_arguments(None)

    def _shapes(self, basis: str) -> np.ndarray:
        return self.shapes_ if basis == "QE" else self.hand_shapes_

    def _working(self, array: np.ndarray) -> np.ndarray:
        """``array`` in the units the fit computed in: divided by ``scale_`` (a power of two, so exactly)."""
        return array if self.scale_ == 1.0 else array / self.scale_

    def _solver_arguments(self, solver: str | None) -> dict:
        """Keyword arguments of :func:`workbench.numerics.solve.solve_weights` for a solver (the estimator's by default), as
        a run's ``solver`` group gives them."""
        kind = _check_choice("solver", self.solver if solver is None else solver, KINDS)
        if kind == "lstsq":
            return {"kind": kind}
        if kind == "nnls":
            return {"kind": kind, "lower": 0.0}
        _check_bounds(self.bounds)  # set_params after fit: named in its own words, not the solver's
        return {"kind": kind, "lower": self.bounds[0], "upper": self.bounds[1]}

    def _displacements(self, frames) -> np.ndarray:
        """Frames given to a method after :meth:`fit`, checked (their columns, shape and values) and as
        displacements: ``neutral_`` subtracted for ``frames_as="positions"``, refused for ``"auto"`` when they look
        like positions against the fitted motion ``point_motion_``.

        Returns
        -------
        ndarray of shape (n_frames, n_dims)
        """
        self._check_columns(frames)
        frames = check_matrix("frames", frames, CAPTURE, n_columns=self.n_features_in_)
        frames_as = _check_choice("frames_as", self.frames_as, FRAMES_AS)
        if frames_as == "positions":
            return frames - self._neutral_for_positions()
        if frames_as == "auto":
            check_displacements("frames", frames.mean(axis=0), self.point_motion_, POSITIONS_REMEDY)
        return frames

    def _neutral_for_positions(self) -> np.ndarray:
        if self.neutral_ is None:
            raise WorkbenchError(
                "frames_as='positions' needs the neutral face the estimator was fitted with: refit with neutral=v0"
            )
        return self.neutral_


def _training_displacements(frames: np.ndarray, frames_as: str, neutral: np.ndarray | None) -> np.ndarray:
    """The frames :meth:`QuasiEigenFaces.fit` is given as displacements: ``frames - neutral`` for
    ``frames_as="positions"`` (a one-line error without ``neutral``), else ``frames``, shape (n_frames, n_dims)."""
    if frames_as != "positions":
        return frames
    if neutral is None:
        raise WorkbenchError("frames_as='positions' needs neutral=v0, the neutral positions subtracted from them")
    return frames - neutral


def _check_bounds(bounds) -> None:
    """A :class:`WorkbenchError` naming ``bounds`` unless it is ``(lower, upper)``, each a number or None (not both
    None), with ``lower <= upper``."""
    pair = not isinstance(bounds, (str, bytes)) and hasattr(bounds, "__len__") and len(bounds) == 2
    numbers = pair and all(value is None or _is_number(value) for value in bounds)
    if not numbers or all(value is None for value in bounds) or any(value != value for value in bounds):
        raise WorkbenchError(f"bounds must be a pair (lower, upper) of numbers or None, not both None; got {bounds!r}")
    lower, upper = bounds
    if lower is not None and upper is not None and lower > upper:
        raise WorkbenchError(f"bounds must have lower <= upper, got {tuple(bounds)!r}")


def _largest(array: np.ndarray) -> float:
    """The largest ``|value|`` of a finite array, without an absolute copy of it (a mesh capture is gigabytes)."""
    return max(float(array.max()), -float(array.min()))


def _check_scale(name: str, array: np.ndarray) -> None:
    """A :class:`WorkbenchError` naming ``name`` when its largest ``|value|`` lies outside :data:`SCALE_RANGE` (but
    for all zeros, which the fit's own rules refuse)."""
    largest = _largest(array)
    low, high = SCALE_RANGE
    if largest and not low <= largest <= high:
        raise WorkbenchError(
            f"{name} are scaled beyond float64's squares: largest |value| {largest:.3g} is outside [{low:g}, "
            f"{high:g}], where their squares {'overflow to inf' if largest > high else 'underflow to zero'}; "
            "rescale them (e.g. to millimetres)"
        )


def _check_not_constant(eigenfaces: Eigenfaces) -> None:
    """A :class:`WorkbenchError` naming ``frames`` when their variance is round-off against their scale
    (:data:`CONSTANT_REL`): identical frames give a round-off eigenvalue that would otherwise make an eigenface."""
    total = float(eigenfaces.explained_variance_[0] / eigenfaces.explained_variance_ratio_[0])
    mean_square = total + float(eigenfaces.mean_ @ eigenfaces.mean_)
    if total <= CONSTANT_REL**2 * mean_square:
        raise WorkbenchError(
            f"frames are numerically constant: their spread {np.sqrt(total):.3g} is at most {CONSTANT_REL:g} of "
            f"their root-mean-square norm {np.sqrt(mean_square):.3g}; frames must vary to have eigenfaces"
        )


def _check_random_state(value):
    """``random_state`` as the seed :class:`workbench.numerics.bases.Eigenfaces` takes (None: a run's seed, 0), or a
    :class:`WorkbenchError` naming it."""
    if value is None:
        return 0
    if isinstance(value, np.random.Generator):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 0:
        return int(value)
    raise WorkbenchError(
        f"random_state must be None, a non-negative integer or a numpy.random.Generator; got {value!r:.80}"
    )


def _check_choice(name: str, value, choices: tuple) -> str:
    if not isinstance(value, str) or value not in choices:
        raise WorkbenchError(f"{name} must be one of {', '.join(map(repr, choices))}; got {value!r}")
    return value


def _check_vector(name: str, value, n_dims: int) -> np.ndarray:
    """``value`` as a finite float vector of length ``n_dims``, or a :class:`WorkbenchError` naming ``name``."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise WorkbenchError(f"{name} must be a numeric array of shape ({n_dims},): {error}") from None
    if array.shape != (n_dims,):
        raise WorkbenchError(f"{name} must have shape ({n_dims},) to match the frames' columns, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise WorkbenchError(f"{name} holds NaN or Inf values ({int(np.sum(~np.isfinite(array)))} entries)")
    return array.copy()


def _no_solver_for_pca(solver) -> None:
    if solver is not None:
        raise WorkbenchError(
            f"solver must be None for basis 'PCA' (its reconstruction is the orthogonal projection "
            f"onto the eigenfaces), got {solver!r}"
        )


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def _shown(value) -> str:
    """A parameter as the repr shows it: arrays by shape and dtype, anything else by its repr."""
    if isinstance(value, np.ndarray):
        return f"<array of shape {value.shape}, {value.dtype}>"
    return repr(value)


def _same(a, b) -> bool:
    try:
        return bool(a == b) and type(a) is type(b)
    except (TypeError, ValueError):
        return False
