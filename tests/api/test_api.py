"""The public Python API: the estimator's manners, known answers, and the same alpha as the command line's run."""

import importlib.util
import os
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest
import scipy.sparse

import workbench
from workbench import NotFittedError, QuasiEigenFaces, WorkbenchError
from workbench.numerics import bases
from workbench.numerics.bases import Eigenfaces
from workbench.numerics.estimator_manners import ScikitLearnManners
from workbench.numerics.metrics import alpha_per_frame
from workbench.settings.config import REPO_ROOT
from workbench.settings.typed import study_settings

PARAMETERS = {
    "hand_shapes": None,
    "neutral": None,
    "names": None,
    "coverage": 0.995,
    "n_components": None,
    "svd_solver": "auto",
    "random_state": None,
    "through": "mean",
    "solver": "lstsq",
    "bounds": (0.0, 1.0),
    "empty_axis_eps": 0.05,
    "empty_axis_scale": "axis_std",
    "append_empty_axes": False,
    "frames_as": "auto",
}


def low_rank(variances=(9.0, 4.0, 1.0), n_frames=40, n_dims=12, seed=0):
    """Frames ``mean + scores @ directions`` whose PCA is known: orthonormal ``directions`` (rows), zero-mean
    scores with orthogonal columns of population variances ``variances``."""
    rng = np.random.default_rng(seed)
    directions = np.linalg.qr(rng.standard_normal((n_dims, len(variances))))[0].T
    centred = rng.standard_normal((n_frames, len(variances)))
    centred -= centred.mean(axis=0)
    unit = np.linalg.qr(centred)[0]  # orthonormal columns in the span of zero-mean columns: zero mean
    scores = unit * np.sqrt(n_frames * np.asarray(variances))
    mean = rng.standard_normal(n_dims)
    return mean + scores @ directions, mean, directions


@pytest.fixture
def fitted():
    frames, _, directions = low_rank()
    hand = np.random.default_rng(1).standard_normal((4, frames.shape[1]))
    return QuasiEigenFaces(hand_shapes=hand, neutral=np.full(frames.shape[1], 50.0), n_components=3).fit(frames), frames


# --- manners ------------------------------------------------------------------------------------------------------


def test_parameters_are_keyword_only_and_stored_untouched():
    assert QuasiEigenFaces().get_params() == PARAMETERS
    odd = {
        "hand_shapes": "shapes",
        "neutral": 0,
        "names": "abc",
        "coverage": 7,
        "n_components": "many",
        "svd_solver": "arpack",
        "random_state": "seed",
        "through": "sideways",
        "solver": "qp",
        "bounds": [1, 0],
        "empty_axis_eps": -1.0,
        "empty_axis_scale": None,
        "append_empty_axes": "yes",
        "frames_as": "both",
    }
    estimator = QuasiEigenFaces(**odd)  # checked by fit, not by __init__
    assert vars(estimator) == odd and estimator.get_params() == odd
    with pytest.raises(TypeError):
        QuasiEigenFaces(0.9)
    assert (
        repr(QuasiEigenFaces(n_components=18, through="neutral"))
        == "QuasiEigenFaces(n_components=18, through='neutral')"
    )
    assert QuasiEigenFaces().set_params(solver="nnls").solver == "nnls"
    with pytest.raises(WorkbenchError, match="no parameter 'alpha'"):
        QuasiEigenFaces().set_params(alpha=1)


def test_fit_returns_self_and_fitted_attributes_end_with_an_underscore(fitted):
    estimator, frames = fitted
    assert estimator.fit(frames) is estimator
    fitted_names = set(vars(estimator)) - set(PARAMETERS)
    assert fitted_names and all(name.endswith("_") and not name.startswith("_") for name in fitted_names)
    assert {
        "mean_",
        "eigenfaces_",
        "explained_variance_ratio_",
        "m_",
        "shapes_",
        "pca_to_qe_weights_",
        "empty_axes_",
        "n_features_in_",
        "hand_shapes_",
        "neutral_",
    } <= fitted_names
    params = estimator.get_params()
    assert params.pop("hand_shapes") is estimator.hand_shapes and params.pop("neutral") is estimator.neutral
    assert params == {name: value for name, value in PARAMETERS.items() if name not in ("hand_shapes", "neutral")} | {
        "n_components": 3
    }


@pytest.mark.parametrize(
    "use",
    [
        lambda e, x: e.transform(x),
        lambda e, x: e.inverse_transform(np.ones((1, 4))),
        lambda e, x: e.alpha(x),
        lambda e, x: e.alpha_summary(x, basis="PCA"),
    ],
)
def test_a_clear_error_before_fit(use):
    frames, _, _ = low_rank()
    with pytest.raises(NotFittedError, match=r"QuasiEigenFaces instance is not fitted yet: call fit\(frames\) before"):
        use(QuasiEigenFaces(), frames)
    assert issubclass(NotFittedError, ValueError) and issubclass(NotFittedError, AttributeError)


def test_the_estimator_needs_no_scikit_learn(monkeypatch):
    """The core without the bases extra: the same estimator, its own NotFittedError (scikit-learn's when installed,
    tests/numerics/test_sklearn.py)."""
    for name in [name for name in sys.modules if name == "sklearn" or name.startswith("sklearn.")] + ["sklearn"]:
        monkeypatch.setitem(sys.modules, name, None)  # import sklearn... raises ImportError
    path = REPO_ROOT / "workbench" / "numerics" / "estimator.py"
    spec = importlib.util.spec_from_file_location("estimator_without_scikit_learn", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.ESTIMATOR_BASES == () and module.QuasiEigenFaces.__mro__[1:] == (ScikitLearnManners, object)
    assert issubclass(module.NotFittedError, WorkbenchError) and issubclass(module.NotFittedError, AttributeError)
    frames, _, _ = low_rank()
    hand = np.random.default_rng(1).standard_normal((3, frames.shape[1]))
    estimator = module.QuasiEigenFaces(hand_shapes=hand, n_components=3)
    with pytest.raises(module.NotFittedError, match="not fitted yet"):
        estimator.transform(frames)
    fitted = QuasiEigenFaces(hand_shapes=hand, n_components=3).fit(frames)
    np.testing.assert_array_equal(estimator.fit(frames).transform(frames), fitted.transform(frames))
    assert estimator.score(frames) == fitted.score(frames) and repr(estimator) == repr(fitted)
    assert estimator.set_params(solver="nnls").get_params()["solver"] == "nnls"


def test_eigenface_signs_are_deterministic():
    frames, _, _ = low_rank(seed=3)
    hand = np.random.default_rng(2).standard_normal((3, frames.shape[1]))
    first = QuasiEigenFaces(hand_shapes=hand, n_components=3).fit(frames)
    flipped = QuasiEigenFaces(hand_shapes=hand, n_components=3).fit(
        -frames
    )  # same covariance, eigenvectors of either sign
    rows = np.arange(3)
    pivots = np.argmax(np.abs(first.eigenfaces_), axis=1)
    assert np.all(first.eigenfaces_[rows, pivots] > 0)
    np.testing.assert_allclose(flipped.eigenfaces_, first.eigenfaces_, rtol=0, atol=1e-12)


# --- known answers ------------------------------------------------------------------------------------------------


def test_low_rank_frames_give_their_known_principal_components():
    frames, mean, directions = low_rank(variances=(9.0, 4.0, 1.0))
    hand = np.random.default_rng(4).standard_normal((3, frames.shape[1]))
    estimator = QuasiEigenFaces(hand_shapes=hand, coverage=0.9).fit(frames)
    # 9/14 = 0.643 < 0.9 <= 13/14 = 0.929: two eigenfaces
    assert estimator.m_ == 2 and estimator.coverage_ == pytest.approx(13 / 14, abs=1e-12)
    np.testing.assert_allclose(estimator.mean_, mean, rtol=0, atol=1e-12)
    np.testing.assert_allclose(estimator.explained_variance_, [9.0, 4.0], rtol=1e-12)  # one per eigenface kept
    np.testing.assert_allclose(estimator.explained_variance_ratio_, [9 / 14, 4 / 14], rtol=1e-12)
    np.testing.assert_allclose(np.abs(estimator.eigenfaces_ @ directions[:2].T), np.eye(2), rtol=0, atol=1e-12)
    every = QuasiEigenFaces(hand_shapes=hand, n_components=3).fit(frames)
    np.testing.assert_allclose(
        every.inverse_transform(every.transform(frames, basis="PCA"), basis="PCA"), frames, rtol=0, atol=1e-12
    )


def test_both_svd_solvers_give_the_same_fit_with_the_same_attributes(monkeypatch):
    frames, _, directions = low_rank(variances=(9.0, 4.0, 1.0, 0.01), n_frames=300, n_dims=60, seed=3)
    hand = np.random.default_rng(5).standard_normal((5, frames.shape[1]))
    fits = {
        solver: QuasiEigenFaces(hand_shapes=hand, coverage=0.99, svd_solver=solver, random_state=7).fit(frames)
        for solver in ("full", "randomized")
    }
    full, randomized = fits["full"], fits["randomized"]
    assert full.m_ == randomized.m_ == 3 and full.explained_variance_.shape == randomized.explained_variance_.shape
    np.testing.assert_allclose(randomized.explained_variance_, [9.0, 4.0, 1.0], rtol=1e-9)
    np.testing.assert_allclose(full.explained_variance_, [9.0, 4.0, 1.0], rtol=1e-12)
    np.testing.assert_allclose(randomized.explained_variance_ratio_, full.explained_variance_ratio_, rtol=1e-9)
    np.testing.assert_allclose(randomized.eigenfaces_, full.eigenfaces_, rtol=0, atol=1e-9)  # signs fixed alike
    np.testing.assert_allclose(randomized.shapes_, full.shapes_, rtol=0, atol=1e-8)
    assert {name for name in vars(full) if name.endswith("_")} == {
        name for name in vars(randomized) if name.endswith("_")
    }
    # the same random_state, the same fit; "auto" takes the randomised path where its cost model says so
    again = QuasiEigenFaces(hand_shapes=hand, coverage=0.99, svd_solver="randomized", random_state=7).fit(frames)
    assert np.array_equal(again.eigenfaces_, randomized.eigenfaces_)
    auto = QuasiEigenFaces(hand_shapes=hand, coverage=0.99, random_state=7)
    assert np.array_equal(auto.fit(frames).eigenfaces_, full.eigenfaces_)
    monkeypatch.setattr(bases, "auto_solver", lambda *shape_and_floor: "randomized")
    assert np.array_equal(auto.fit(frames).eigenfaces_, randomized.eigenfaces_)
    assert auto.explained_variance_.shape == full.explained_variance_.shape == (3,)
    # a Generator is used as given
    generated = QuasiEigenFaces(hand_shapes=hand, svd_solver="randomized", random_state=np.random.default_rng(7))
    np.testing.assert_allclose(generated.fit(frames).eigenfaces_, full.eigenfaces_, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    "params, message",
    [
        ({"svd_solver": "arpack"}, "^svd_solver must be one of 'auto', 'full', 'randomized'; got 'arpack'$"),
        ({"svd_solver": "exact"}, "^svd_solver must be one of 'auto', 'full', 'randomized'; got 'exact'$"),
        (
            {"random_state": -1},
            "^random_state must be None, a non-negative integer or a numpy.random.Generator; got -1$",
        ),
        ({"random_state": 1.5}, "^random_state must be None, a non-negative integer or a numpy.random.Generator"),
        ({"random_state": True}, "^random_state must be None, a non-negative integer or a numpy.random.Generator"),
    ],
)
def test_bad_svd_solver_or_random_state_is_refused_naming_it(params, message):
    frames, _, _ = low_rank()
    with pytest.raises(WorkbenchError, match=message):
        QuasiEigenFaces(hand_shapes=frames[:2], **params).fit(frames)


@pytest.mark.parametrize("through", ["mean", "neutral"])
def test_a_hand_shape_on_the_hyperplane_comes_back_unchanged(through):
    frames, mean, directions = low_rank()
    offset = mean if through == "mean" else 0.0
    on_plane = offset + np.array([2.0, -1.0, 0.5]) @ directions
    off_plane = np.random.default_rng(5).standard_normal(frames.shape[1]) * 3.0
    hand = np.vstack([on_plane, off_plane])
    estimator = QuasiEigenFaces(hand_shapes=hand, names=["on", "off"], n_components=3, through=through).fit(frames)
    np.testing.assert_allclose(estimator.shapes_[0], on_plane, rtol=0, atol=1e-12)
    signs = np.diag(estimator.eigenfaces_ @ directions.T)  # each eigenface is +-1 times its direction
    np.testing.assert_allclose(np.abs(signs), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(estimator.pca_to_qe_weights_[0], signs * [2.0, -1.0, 0.5], rtol=0, atol=1e-12)
    # the other moves by the least distance: straight onto the hyperplane, its move orthogonal to the eigenfaces
    np.testing.assert_allclose(directions @ (off_plane - estimator.shapes_[1]), 0.0, rtol=0, atol=1e-12)
    assert estimator.shape_names_ == ("on", "off")


def test_alpha_of_a_frame_with_a_known_residual():
    """A frame ``2 h_1 + r`` with ``r`` orthogonal to the hand shapes: alpha in H is ``100 |r| / |d|``, and
    ``100 |r| / |v0 + d|`` over positions."""
    rng = np.random.default_rng(6)
    frames, _, _ = low_rank(n_dims=12)
    hand = rng.standard_normal((2, 12))
    residual = rng.standard_normal(12)
    residual -= hand.T @ np.linalg.lstsq(hand.T, residual, rcond=None)[0]
    frame = 2.0 * hand[0] + residual
    neutral = np.full(12, 10.0)
    estimator = QuasiEigenFaces(hand_shapes=hand, neutral=neutral, n_components=2).fit(frames)
    expected_disp = 100 * np.linalg.norm(residual) / np.linalg.norm(frame)
    expected_abs = 100 * np.linalg.norm(residual) / np.linalg.norm(neutral + frame)
    assert estimator.alpha(frame[None], basis="H", normalisation="displacement") == pytest.approx(
        expected_disp, rel=1e-12
    )
    assert estimator.alpha(frame[None], basis="H") == pytest.approx(expected_abs, rel=1e-12)
    np.testing.assert_allclose(estimator.transform(frame[None], basis="H"), [[2.0, 0.0]], rtol=0, atol=1e-12)


def test_solvers_keep_their_constraints_and_alpha_orders_them(fitted):
    estimator, frames = fitted
    nnls = estimator.transform(frames, solver="nnls")
    box = estimator.transform(frames, solver="box")
    assert nnls.min() >= 0 and box.min() >= 0 and box.max() <= 1
    alphas = [estimator.alpha(frames, solver=solver, aggregate="per_frame") for solver in ("lstsq", "nnls", "box")]
    assert np.all(alphas[0] <= alphas[1] + 1e-9) and np.all(alphas[1] <= alphas[2] + 1e-9)  # per frame, always
    reconstruction = estimator.inverse_transform(nnls)
    np.testing.assert_allclose(
        estimator.alpha(frames, solver="nnls", aggregate="per_frame"),
        alpha_per_frame(estimator.neutral_ + frames, estimator.neutral_ + reconstruction),
        rtol=1e-9,
    )


def test_alpha_summary_is_a_small_table_of_every_basis(fitted):
    estimator, frames = fitted
    table = estimator.alpha_summary(frames, solver="nnls")
    assert list(table["basis"]) == ["QE", "H", "PCA"] and list(table["solver"]) == ["nnls", "nnls", "projection"]
    assert list(table.columns) == [
        "basis",
        "solver",
        "n_frames",
        "alpha_abs_mean",
        "alpha_abs_pooled",
        "alpha_disp_mean",
        "alpha_disp_pooled",
        "rms_mm",
    ]
    assert (table["n_frames"] == len(frames)).all() and table.shape == (3, 8)
    for row in table.itertuples():
        solver = None if row.basis == "PCA" else "nnls"
        for normalisation, short in (("absolute", "abs"), ("displacement", "disp")):
            for aggregate in ("mean", "pooled"):
                value = estimator.alpha(
                    frames, solver=solver, basis=row.basis, normalisation=normalisation, aggregate=aggregate
                )
                assert getattr(row, f"alpha_{short}_{aggregate}") == value, (row.basis, normalisation, aggregate)
    one = estimator.alpha_summary(frames, basis="H")  # one basis, the estimator's solver
    assert one.shape == (1, 8) and one.loc[0, "solver"] == "lstsq"
    assert one.loc[0, "alpha_abs_mean"] == estimator.alpha(frames, basis="H")
    with pytest.raises(WorkbenchError, match="^solver must be None for basis 'PCA'"):
        estimator.alpha_summary(frames, basis="PCA", solver="nnls")
    with pytest.raises(WorkbenchError, match="^basis must be one of 'QE', 'H', 'PCA' or a list of them; got \\[\\]$"):
        estimator.alpha_summary(frames, basis=[])


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda e, x, h: e.fit(x[0]), "frames must be a 2-D array"),
        (lambda e, x, h: e.set_params(hand_shapes=h[:, :-1]).fit(x[:, :-1]), "frames must have 3 \\* n_points columns"),
        (lambda e, x, h: e.set_params(hand_shapes=None).fit(x), r"hand_shapes must be given: QuasiEigenFaces\(hand_"),
        (
            lambda e, x, h: e.set_params(hand_shapes=None).fit(x, h),
            r"fit takes the frames alone: give the hand shapes as QuasiEigenFaces\(hand_",
        ),
        (lambda e, x, h: e.set_params(hand_shapes=h[:, :-3]).fit(x), "hand_shapes must have 12 columns"),
        (lambda e, x, h: e.set_params(neutral=np.zeros(5)).fit(x), r"neutral must have shape \(12,\)"),
        (lambda e, x, h: e.set_params(names=["a"]).fit(x), "names must be a sequence of one name per hand shape"),
        (lambda e, x, h: e.set_params(through="origin").fit(x), "through must be one of 'mean', 'neutral'"),
        (lambda e, x, h: e.set_params(solver="qp").fit(x), "solver must be one of 'lstsq', 'nnls', 'box'"),
        (lambda e, x, h: e.set_params(coverage=1.5).fit(x), r"coverage must be in \(0, 1\], got 1.5"),
        (lambda e, x, h: e.set_params(n_components=0).fit(x), "n_components must be a positive integer"),
        (lambda e, x, h: e.fit(x).transform(x[:, :6]), "frames must have 12 columns"),
        (lambda e, x, h: e.fit(x).transform(x, basis="ICA"), "basis must be one of 'QE', 'H', 'PCA'"),
        (lambda e, x, h: e.fit(x).alpha(x), "normalisation='absolute' needs the neutral positions"),
        (lambda e, x, h: e.fit(x).alpha(x, normalisation="disp"), "normalisation must be one of"),
        (
            lambda e, x, h: e.fit(x).alpha(x, basis="PCA", solver="nnls", normalisation="displacement"),
            "solver must be None for basis 'PCA'",
        ),
        # bounds are checked at fit whatever the solver (transform may ask for "box")
        (lambda e, x, h: e.set_params(bounds=(1, 0)).fit(x), r"^bounds must have lower <= upper, got \(1, 0\)$"),
        (lambda e, x, h: e.set_params(solver="box", bounds=(None, None)).fit(x), "^bounds must be a pair"),
        (lambda e, x, h: e.set_params(bounds=0.5).fit(x), r"^bounds must be a pair \(lower, upper\)"),
        (lambda e, x, h: e.set_params(bounds=(0, float("nan"))).fit(x), "^bounds must be a pair"),
        # what a conversion to floats would silently change
        (lambda e, x, h: e.fit(x + 1j * x), r"^frames must be real: Complex data not supported \(dtype complex128\)"),
        (lambda e, x, h: e.set_params(hand_shapes=h * (1 + 0j)).fit(x), "^hand_shapes must be real"),
        (lambda e, x, h: e.fit(np.ma.masked_less(x, 0.0)), "^frames must not be a NumPy masked array"),
        (lambda e, x, h: e.fit(x).transform(np.ma.masked_array(x)), "^frames must not be a NumPy masked array"),
        (lambda e, x, h: e.fit(scipy.sparse.csr_matrix(x)), "^frames must be a dense array: sparse input"),
        (
            lambda e, x, h: e.set_params(hand_shapes=h * 1e-140, neutral=np.full(12, 1e200)).fit(x * 1e-140),
            r"^neutral is too large against the frames' scale [0-9.e+-]+: rescale both$",
        ),
    ],
)
def test_bad_input_is_refused_naming_the_argument_and_the_rule(call, message):
    frames, _, _ = low_rank()
    hand = np.random.default_rng(7).standard_normal((3, 12))
    with pytest.raises(WorkbenchError, match=message) as refused:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # refused, not converted with a warning
            call(QuasiEigenFaces(hand_shapes=hand), frames, hand)
    assert "\n" not in str(refused.value)


def test_identical_or_numerically_constant_frames_are_refused():
    """50 copies of one frame have a round-off variance (about 1e-29), which must not make an eigenface; frames
    that differ only at round-off of their scale are as constant; a small motion far from neutral is not."""
    frames, _, _ = low_rank()
    hand = np.random.default_rng(8).standard_normal((1, 12))
    estimator = QuasiEigenFaces(hand_shapes=hand, n_components=1)
    copies = np.tile(frames[0] + 10.0, (50, 1))
    assert 0 < Eigenfaces(n_components=1).fit(copies).explained_variance_[0] < 1e-25  # what the rule is for
    for same in (copies, np.zeros((50, 12))):
        with pytest.raises(WorkbenchError, match=r"^frames are numerically constant: all 50 frames are the same$"):
            estimator.fit(same)
    jitter = copies * (1 + 1e-15 * np.random.default_rng(9).standard_normal(copies.shape))  # round-off apart
    with pytest.raises(WorkbenchError, match=r"^frames are numerically constant: their spread [0-9.e+-]+ is at most"):
        estimator.fit(jitter)
    moving = frames[0] * 1e3 + 1e-6 * frames  # a relative spread of about 1e-9: a capture, fitted ...
    with pytest.raises(WorkbenchError, match="^frames look like positions"):  # ... once said to be displacements
        estimator.fit(moving)
    assert estimator.set_params(frames_as="displacements").fit(moving).m_ == 1


@pytest.mark.parametrize("scale", [1e100, 1e-100, 2.0**-60])
def test_the_fit_is_relative_to_the_frames_scale(scale):
    """Frames and hand shapes scaled together give the same eigenfaces, basis weights and alpha."""
    frames, _, _ = low_rank(seed=4)
    hand = np.random.default_rng(10).standard_normal((3, 12))
    neutral = np.full(12, 50.0)
    one = QuasiEigenFaces(hand_shapes=hand, neutral=neutral, n_components=3).fit(frames)
    scaled = QuasiEigenFaces(hand_shapes=hand * scale, neutral=neutral * scale, n_components=3).fit(frames * scale)
    np.testing.assert_allclose(scaled.eigenfaces_, one.eigenfaces_, rtol=0, atol=1e-10)
    np.testing.assert_allclose(scaled.explained_variance_ratio_, one.explained_variance_ratio_, rtol=1e-10)
    np.testing.assert_allclose(scaled.explained_variance_, one.explained_variance_ * scale**2, rtol=1e-10)
    np.testing.assert_allclose(scaled.shapes_, one.shapes_ * scale, rtol=1e-10, atol=0)
    np.testing.assert_allclose(scaled.transform(frames * scale), one.transform(frames), rtol=0, atol=1e-9)
    for solver in ("lstsq", "nnls", "box"):
        assert scaled.alpha(frames * scale, solver=solver) == pytest.approx(one.alpha(frames, solver=solver), rel=1e-9)


@pytest.mark.parametrize("scale", [1e300, 1e-200])
def test_frames_beyond_float64_squares_are_refused_naming_their_scaling(scale):
    frames, _, _ = low_rank()
    hand = np.random.default_rng(11).standard_normal((3, 12))
    with pytest.raises(WorkbenchError, match=r"^frames are scaled beyond float64's squares: largest \|value\| "):
        QuasiEigenFaces(hand_shapes=hand * scale).fit(frames * scale)


def test_a_rank_deficient_basis_is_warned_about_as_the_command_line_notes_it():
    frames, _, _ = low_rank(variances=(9.0, 4.0, 1.0))
    hand = np.random.default_rng(12).standard_normal((4, 12))
    # through the mean the quasi-eigen faces span the mean too (rank m + 1); through the neutral face, m
    for through, rank in (("mean", 3), ("neutral", 2)):
        with pytest.warns(UserWarning, match=rf"quasi-eigen basis is rank-deficient, rank {rank} of 4 shapes on 2 e"):
            QuasiEigenFaces(hand_shapes=hand, n_components=2, through=through).fit(frames)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        QuasiEigenFaces(hand_shapes=hand[:2], n_components=2).fit(frames)  # as many eigenfaces as shapes: none


# --- the package's namespace --------------------------------------------------------------------------------------


@pytest.mark.process
def test_the_public_names_are_listed_and_load_lazily():
    expected = {
        "QuasiEigenFaces",
        "read_c3d",
        "read_livelink",
        "read_obj",
        "read_gltf",
        "read_mesh_sequence",
        "read_obj_sequence",
        "read_blendshapes",
        "build_captures",
        "compose_config",
        "run_study",
        "record_study",
        "read_record",
        "arkit_mapping",
        "rest_frame",
        "stabilise_markers",
        "read_marker_table",
        "place_markers",
        "rbf_carry",
    }
    assert expected <= set(workbench.__all__) <= set(dir(workbench))
    assert all(callable(getattr(workbench, name)) for name in workbench.__all__)
    with pytest.raises(AttributeError, match="has no attribute 'nothing'"):
        workbench.nothing  # noqa: B018
    code = (
        "import sys, workbench, workbench.cli.main; dir(workbench); "
        "heavy = {'numpy', 'pandas', 'hydra', 'omegaconf'} & set(sys.modules); assert not heavy, heavy; "
        "workbench.QuasiEigenFaces; assert 'numpy' in sys.modules"
    )
    result = subprocess.run(
        [sys.executable, "-c", code],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=str(REPO_ROOT)),
        timeout=120,
    )
    assert result.returncode == 0, result.stderr


def test_the_readers_are_the_registered_formats_with_their_own_docstrings():
    """Each reader of workbench.formats.registry is public under its name, as the function itself (its docstring
    says what it returns, with shapes), and a dataset finds a reader by what the file holds and its suffix."""
    from workbench.formats.registry import FORMATS, format_for

    public = {entry.public_name for entry in FORMATS.values()}
    assert public <= set(workbench.__all__)
    # read_record reads a run record, read_marker_table a correspondence table of conf/: neither is a data format
    others = ("read_record", "read_marker_table")
    assert {name for name in workbench.__all__ if name.startswith("read_") and name not in others} == public
    for entry in FORMATS.values():
        assert getattr(workbench, entry.public_name) is entry.read
        assert "Returns" in entry.read.__doc__, entry.name
    assert format_for("take.C3D", "marker take", "dataset.takes").name == "c3d"
    assert format_for("curves.csv", "weight curves", "dataset.weight_curves").name == "weight_curves"
    with pytest.raises(WorkbenchError, match=r"dataset\.takes take\.trc: no reader of a marker take reads '\.trc'"):
        format_for("take.trc", "marker take", "dataset.takes")


# --- the same alpha as the command line's run ---------------------------------------------------------------------

COLUMNS = {
    "alpha_abs_mean": ("absolute", "mean"),
    "alpha_abs_pooled": ("absolute", "pooled"),
    "alpha_disp_mean": ("displacement", "mean"),
    "alpha_disp_pooled": ("displacement", "pooled"),
}


def check_estimator_against_record(record, captures):
    """Every alpha of every row of the record (H, QE, QE-linear and PCA; every solver; every variant) from
    estimators fitted on the capture's arrays, to 1e-12."""
    from workbench.study.regime import paper_regime_name

    checked = 0
    variants = [(data, capture, None) for data, capture in captures.items()]
    variants += [
        (paper_regime_name(data), capture, len(capture.hand))
        for data, capture in captures.items()
        if paper_regime_name(data) in record.metrics["data"]
    ]  # the paper's regime: m = n
    for data, capture, n_components in variants:
        rows = [row for row in record.metrics["rows"] if row["data"] == data]
        for through, label in (("mean", "QE"), ("neutral", "QE-linear")):
            estimator = QuasiEigenFaces(
                hand_shapes=capture.hand,
                neutral=capture.neutral,
                names=capture.hand_names,
                through=through,
                n_components=n_components,
            ).fit(capture.train)
            for row in (row for row in rows if row["basis"] in (label, "H", "PCA")):
                basis = "QE" if row["basis"] == label else row["basis"]
                solver = None if basis == "PCA" else row["solver"]
                assert estimator.m_ == row["m"] and (basis != "QE" or len(estimator.shapes_) == row["n"])
                for column, (normalisation, aggregate) in COLUMNS.items():
                    alpha = estimator.alpha(
                        capture.eval, solver=solver, basis=basis, normalisation=normalisation, aggregate=aggregate
                    )
                    assert alpha == pytest.approx(row[column], rel=0, abs=1e-12), (
                        data,
                        row["basis"],
                        row["solver"],
                        column,
                    )
                    checked += 1
    return checked


def test_the_estimator_gives_the_alpha_of_a_run_on_the_synthetic_actor(tmp_path):
    overrides = ["dataset.n_frames=300"]
    config = workbench.compose_config("paper", overrides)
    record = workbench.record_study(config, tmp_path / "run", overrides=overrides)
    assert record.overrides == overrides and (tmp_path / "run" / "done").is_file()
    assert record.settings == study_settings(config)  # a record read back gives the run's typed settings
    assert not (tmp_path / "run" / ".lock").exists(), "a complete record keeps no lock file"
    captures = workbench.build_captures(config)
    # markers at the coverage rule's m and markers m=n (the paper's regime), 4 alpha variants, 2 projections
    assert check_estimator_against_record(record, captures) == 2 * 4 * 2 * (3 + 3 + 1)
    # a folder holding the complete record of the same config is not run again; the dataset group alone builds too
    assert workbench.record_study(config, tmp_path / "run", overrides=overrides).metrics == record.metrics
    assert not (tmp_path / "run" / ".lock").exists()
    assert workbench.build_captures(config.dataset)["markers"].train.shape == captures["markers"].train.shape
    # the headline is the default: the record's alpha_abs_mean of QE with the estimator's solver
    capture = captures["markers"]
    estimator = QuasiEigenFaces(hand_shapes=capture.hand, neutral=capture.neutral, solver="nnls").fit(capture.train)
    row = next(
        row
        for row in record.metrics["rows"]
        if row["data"] == "markers" and row["basis"] == "QE" and row["solver"] == "nnls"
    )
    assert estimator.alpha(capture.eval) == pytest.approx(row["alpha_abs_mean"], rel=0, abs=1e-12)
    # and from the weights, reconstructed explicitly
    reconstruction = estimator.inverse_transform(estimator.transform(capture.eval))
    explicit = alpha_per_frame(capture.neutral + capture.eval, capture.neutral + reconstruction)
    assert np.mean(explicit) == pytest.approx(row["alpha_abs_mean"], rel=0, abs=1e-10)
    # the same study in memory, from the record's resolved config
    results = workbench.run_study(record.config)
    # the paper's regime gives two results of one capture: their names tell them apart, and say which is which
    assert [result.data for result in results] == ["markers m=n", "markers"]
    assert len({result.capture.name for result in results}) == 1
    assert [result.name for result in results] == [
        f"{results[0].capture.name} [{data}]" for data in ("markers m=n", "markers")
    ]
    result = results[1]  # every field its repr prints is an attribute of that name
    assert (result.m, result.n_frames, result.n_rows) == (
        result.eigenfaces.n_components_,
        len(result.capture.eval),
        len(result.rows),
    )
    assert repr(result) == (
        f"StudyResult(name={result.name!r}, m={result.m}, n_frames={result.n_frames}, n_rows={result.n_rows})"
    )
    assert results[0].m == len(results[0].capture.hand_names)  # the paper's regime: m = n
    markers = next(result for result in results if result.data == "markers")
    qe = next(r for r in markers.rows if r.basis == "QE" and r.solver == "nnls")
    assert qe.alpha.absolute_mean == row["alpha_abs_mean"]


def test_the_estimator_gives_the_alpha_of_a_run_on_a_real_take(shared_data, tmp_path):
    overrides = [
        "dataset=animface",
        "dataset.train_on=markers",
        "dataset.frame_step=20",
        f"paths.data_root={shared_data}",
    ]
    config = workbench.compose_config("paper", overrides)
    record = workbench.record_study(config, tmp_path / "run", overrides=overrides)
    assert record.metrics["dataset"]["provenance"]["kind"] == "animface"
    # markers at the coverage rule's m and at the paper's regime m = n: every alpha of every row, to 1e-12
    assert check_estimator_against_record(record, workbench.build_captures(config)) == 2 * 4 * 2 * (3 + 3 + 1)


def test_the_readers_read_the_shared_takes(shared_data):
    take = workbench.read_c3d(shared_data / "animface" / "animface_jaw.c3d")
    assert take.positions.shape == (take.positions.shape[0], len(take.labels), 3) and take.frame_rate > 0
    curves = workbench.read_livelink(shared_data / "livelinkface" / "alex_rom_3.csv")
    assert curves.weights.shape == (len(curves.seconds), len(curves.names)) and len(curves.names) >= 52
    neutral = workbench.read_obj(shared_data / "ict-facekit" / "FaceXModel" / "generic_neutral_mesh.obj")
    assert neutral.vertices.shape[1] == 3 and neutral.n_vertices > 9409


RETIRED_LINE = (
    "setting metric.bootstrap_{} was retired: the within-run intervals are batch means over time and draw nothing at "
    "random (docs/statistics.md); leave it out"
)


@pytest.mark.parametrize(
    "study, overrides, message",
    [
        ("paper", ["dataset.n_frames=abc"], "^Error merging override dataset.n_frames=abc; Value 'abc' of type 'str'"),
        ("paper", ["solver=bogus"], "^In 'paper': Could not find 'solver/bogus'; Available options in 'solver': all,"),
        ("paper", ["dataset=nope"], "^In 'paper': Could not find 'dataset/nope'; Available options in 'dataset'"),
        ("paper", ["basis.nope=1"], "^Could not override 'basis.nope'; To append to your config use"),
        ("paper", ["basis.coverage=[1,"], r"^override 'basis.coverage=\[1,' cannot be parsed: no viable alternative"),
        ("nope", [], r"^study must be one of .*paper .*\(studies/\), got 'nope'$"),
        ("../../../etc/passwd", [], r"^study must be one of .*, got '../../../etc/passwd'$"),
        (None, [], "^study must be one of .*, got None$"),
        ("paper", None, "^overrides must be a list of 'key=value' strings, got None$"),
        ("paper", [1], r"^overrides must be a list of 'key=value' strings, got \[1\]$"),
        (
            "paper",
            "dataset.n_frames=300",
            r"^overrides must be a list .* got the string 'dataset.n_frames=300'; give \[",
        ),
        ("paper", ["+metric.bootstrap_resamples=5"], re.escape(RETIRED_LINE.format("resamples"))),
        ("paper", ["++metric.bootstrap_seed=5"], re.escape(RETIRED_LINE.format("seed"))),
        ("paper", ["metric.bootstrap_seed=1"], re.escape(RETIRED_LINE.format("seed"))),
        ("paper", ["=1"], r"^overrides: the override '=1' names no setting before its '=': write key=value"),
        ("paper", ["solver=nnls", "+=x"], r"^overrides: the override '\+=x' names no setting before its '='"),
        ("paper", ["~"], r"^overrides: the override '~' names no setting"),
    ],
)
def test_compose_config_refuses_in_one_line_as_the_command_line(study, overrides, message):
    with pytest.raises(WorkbenchError, match=message) as refused:
        workbench.compose_config(study, overrides)
    assert "\n" not in str(refused.value) and type(refused.value) is WorkbenchError


def test_the_command_line_refuses_the_same_overrides_in_the_same_words(tmp_path):
    from in_process import run_workbench

    for override in ("+metric.bootstrap_resamples=5", "metric.bootstrap_seed=1", "basis.coverage=[1,"):
        with pytest.raises(WorkbenchError) as refused:
            workbench.compose_config("paper", [override])
        done = run_workbench(override, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
        assert done.returncode == 2 and done.stderr.strip() == f"workbench: error: {refused.value}"
        assert "+metric" not in done.stderr  # no advice to add a retired setting with '+'
    done = run_workbench("--config-name", "nope", cwd=tmp_path)
    assert done.returncode == 2 and "Cannot find primary config 'nope'; the studies are bases," in done.stderr


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda cfg, tmp: workbench.record_study(cfg, None), "^output_dir is empty"),
        (
            lambda cfg, tmp: workbench.record_study(cfg, tmp / "run", overrides="dataset.n_frames=300"),
            "^overrides must be a list of 'key=value' strings, got the string 'dataset.n_frames=300'",
        ),
        (lambda cfg, tmp: workbench.read_record(None), "^folder must be the path of a run record, got None$"),
        (lambda cfg, tmp: workbench.read_c3d(None), r"^path must be a path \(C3D file\), got None$"),
        (lambda cfg, tmp: workbench.read_obj(3), r"^path must be a path \(OBJ file\), got 3$"),
        (lambda cfg, tmp: workbench.read_gltf(""), r"^path must be a path \(glTF file\), got ''$"),
        (lambda cfg, tmp: workbench.read_livelink(None), r"^path must be a path \(Live Link Face CSV\), got None$"),
        (lambda cfg, tmp: workbench.read_weight_curves([]), r"^path must be a path \(weight-curve file\), got \[\]$"),
        (lambda cfg, tmp: workbench.read_mesh_sequence(None), r"^path must be a path \(mesh sequence file\)"),
        (lambda cfg, tmp: workbench.read_blendshapes(None, neutral="n.obj"), r"^folder must be a path \(blendshape"),
        (lambda cfg, tmp: workbench.read_c3d("/dev/zero"), r"^/dev/zero: is a device, pipe or socket, not a file"),
        (lambda cfg, tmp: workbench.read_c3d(tmp), r": is a folder, not a file \(C3D file expected\)$"),
        (lambda cfg, tmp: workbench.read_mesh_sequence(tmp), r": is a folder, not a file \(mesh sequence file"),
        (
            lambda cfg, tmp: workbench.read_blendshapes(__file__, neutral="n.obj"),
            r"test_api.py: is a file, not a folder \(blendshape folder expected\)$",
        ),
    ],
)
def test_the_api_refuses_a_wrong_argument_naming_it(tmp_path, call, message):
    config = workbench.compose_config("paper", ["dataset.n_frames=300"])
    with pytest.raises(WorkbenchError, match=message) as refused:
        call(config, tmp_path)
    assert "\n" not in str(refused.value)
    assert not (tmp_path / "run").exists()


# --- the estimator as strict as scikit-learn: frames as positions, columns, pickles, parameters set after fit ---------


def face_capture(n_frames=300, n_points=30, seed=3):
    """A face-like capture in mm: neutral positions spread over a face (about 60 mm), hand shapes moving a few points
    by a few mm, frames they drive with noise off their span, as displacements."""
    rng = np.random.default_rng(seed)
    neutral = rng.uniform(-60, 60, (n_points, 3)).ravel() + 400.0  # the origin far from the face, as a camera's
    hand = rng.standard_normal((5, 3 * n_points)) * rng.uniform(0, 4, 3 * n_points)
    frames = rng.uniform(0, 1, (n_frames, 5)) @ hand + 0.1 * rng.standard_normal((n_frames, 3 * n_points))
    return hand, neutral, frames


def test_frames_given_as_positions_are_refused_in_one_line_naming_neutral():
    hand, neutral, frames = face_capture()
    positions = neutral + frames
    with pytest.raises(WorkbenchError, match=r"^frames look like positions, .* spreads [0-9.]+ times") as refused:
        QuasiEigenFaces(hand_shapes=hand, neutral=neutral).fit(positions)
    assert "\n" not in str(refused.value) and "neutral=v0, frames_as='positions'" in str(refused.value)
    fitted = QuasiEigenFaces(hand_shapes=hand, neutral=neutral).fit(frames)  # displacements pass
    for use in (fitted.transform, fitted.alpha, fitted.score, fitted.alpha_summary):
        with pytest.raises(WorkbenchError, match="^frames look like positions"):
            use(positions)
    with pytest.raises(WorkbenchError, match="^frames look like positions"):
        fitted.transform(positions[:1])  # one frame, against the motion fitted on
    fitted.transform(frames[np.argmax(np.abs(frames).sum(axis=1))][None])  # the most extreme frame passes


def test_frames_said_to_be_positions_are_fitted_as_their_displacements():
    hand, neutral, frames = face_capture()
    positions = neutral + frames
    given = QuasiEigenFaces(hand_shapes=hand, neutral=neutral, frames_as="positions").fit(positions)
    direct = QuasiEigenFaces(hand_shapes=hand, neutral=neutral).fit(frames)
    np.testing.assert_allclose(given.shapes_, direct.shapes_, rtol=0, atol=1e-9)
    np.testing.assert_allclose(given.transform(positions), direct.transform(frames), rtol=0, atol=1e-9)
    assert given.alpha(positions) == pytest.approx(direct.alpha(frames), rel=1e-9)
    weights = given.transform(positions)
    np.testing.assert_allclose(given.inverse_transform(weights), direct.inverse_transform(weights) + neutral, atol=1e-9)
    assert given.point_motion_ == pytest.approx(direct.point_motion_, rel=1e-12) and direct.point_motion_ > 0
    with pytest.raises(WorkbenchError, match=r"^frames_as='positions' needs neutral=v0"):
        QuasiEigenFaces(hand_shapes=hand, frames_as="positions").fit(positions)
    # said to be displacements: fitted as given, unchecked (a capture whose mean face is large on purpose)
    as_given = QuasiEigenFaces(hand_shapes=hand, frames_as="displacements").fit(positions)
    np.testing.assert_allclose(as_given.mean_, positions.mean(axis=0), rtol=1e-12)
    with pytest.raises(WorkbenchError, match=r"^frames_as must be one of 'auto', 'displacements', 'positions'"):
        QuasiEigenFaces(hand_shapes=hand, frames_as="absolute").fit(frames)


def test_parameters_set_after_fit_are_refused_in_their_own_words(fitted):
    estimator, frames = fitted
    estimator.set_params(bounds=(float("nan"), 1.0))
    for use in (
        lambda: estimator.transform(frames, solver="box"),
        lambda: estimator.alpha(frames, solver="box"),
        lambda: estimator.set_params(solver="box").score(frames),
    ):
        with pytest.raises(WorkbenchError, match=r"^bounds must be a pair \(lower, upper\) of numbers or None"):
            use()
    estimator.set_params(bounds=(1.0, 0.0))
    with pytest.raises(WorkbenchError, match=r"^bounds must have lower <= upper, got \(1.0, 0.0\)"):
        estimator.transform(frames)
    estimator.set_params(solver="qp", bounds=(0.0, 1.0))
    with pytest.raises(WorkbenchError, match="^solver must be one of 'lstsq', 'nnls', 'box'; got 'qp'"):
        estimator.transform(frames)
    estimator.set_params(solver="lstsq", frames_as="position")
    with pytest.raises(WorkbenchError, match="^frames_as must be one of"):
        estimator.alpha(frames)


def test_dataframe_columns_are_remembered_and_must_come_back_the_same():
    import pandas as pd

    hand, neutral, frames = face_capture()
    columns = [f"{axis}{point}" for point in range(frames.shape[1] // 3) for axis in "xyz"]
    table = pd.DataFrame(frames, columns=columns)
    estimator = QuasiEigenFaces(hand_shapes=hand, neutral=neutral).fit(table)
    assert list(estimator.feature_names_in_) == columns and estimator.feature_names_in_.dtype == object
    reordered = table[columns[3:] + columns[:3]]
    with pytest.raises(WorkbenchError, match=r"^frames' columns must be those .* reordered: column 0 is 'x1'"):
        estimator.transform(reordered)
    with pytest.raises(WorkbenchError, match=r"but column 'X0' was not among the columns fitted on; select them as"):
        estimator.alpha(table.rename(columns={"x0": "X0"}))
    with pytest.raises(WorkbenchError, match=r"column 'z29' fitted on is missing"):
        estimator.transform(table.iloc[:, :-1])
    np.testing.assert_array_equal(
        estimator.transform(reordered[estimator.feature_names_in_]), estimator.transform(table)
    )
    with pytest.warns(
        UserWarning, match="frames do not have column names, but QuasiEigenFaces was fitted with them"
    ) as warned:
        assert estimator.alpha(frames) == pytest.approx(estimator.alpha(table), rel=1e-12)  # taken by position
    assert warned[0].filename == __file__  # the warning points at the caller, not the estimator
    assert not hasattr(estimator.fit(frames), "feature_names_in_")  # an array forgets them
    with pytest.warns(UserWarning, match="frames have column names, but QuasiEigenFaces was fitted without them"):
        estimator.transform(table)
    with pytest.raises(WorkbenchError, match="^frames' columns must all be named by strings or none of them"):
        estimator.fit(pd.DataFrame(frames, columns=columns[:-1] + [7]))


def test_a_pickle_carries_the_version_and_an_older_one_is_refused_with_refit(fitted):
    import copyreg
    import pickle

    estimator, frames = fitted
    copy = pickle.loads(pickle.dumps(estimator))
    np.testing.assert_array_equal(copy.transform(frames), estimator.transform(frames))
    assert repr(copy) == repr(estimator) and "_workbench_version" not in vars(copy)

    class Pickled:
        """Pickles as the estimator with the given state, as an older workbench wrote it."""

        def __init__(self, state):
            self.state = state

        def __reduce__(self):
            return copyreg._reconstructor, (QuasiEigenFaces, object, None), self.state

    current = estimator.__getstate__()
    older = {key: value for key, value in current.items() if key not in ("_workbench_version", "frames_as")}
    for state, written in [
        (older, "an older workbench"),
        ({**current, "_workbench_version": "0.0.9"}, "workbench 0.0.9"),
        ({**older, "_workbench_version": workbench.__version__}, f"workbench {workbench.__version__}, without para"),
    ]:
        with pytest.raises(WorkbenchError, match=f"^This pickled QuasiEigenFaces was written by {written}") as refused:
            pickle.loads(pickle.dumps(Pickled(state)))
        assert "refit the estimator" in str(refused.value) and "\n" not in str(refused.value)


def test_feature_names_out_are_the_shape_names_and_set_output_gives_them(fitted):
    import pandas as pd

    estimator, frames = fitted
    assert list(estimator.get_feature_names_out()) == list(estimator.shape_names_)
    with pytest.raises(WorkbenchError, match="^input_features must hold 12 names"):
        estimator.get_feature_names_out(["a", "b"])
    with pytest.raises(NotFittedError):
        QuasiEigenFaces().get_feature_names_out()
    table = pd.DataFrame(frames, index=pd.RangeIndex(100, 100 + len(frames)))
    weights = estimator.set_output(transform="pandas").transform(table)
    assert isinstance(weights, pd.DataFrame) and list(weights.columns) == list(estimator.shape_names_)
    assert list(weights.index) == list(table.index)
    np.testing.assert_array_equal(weights.to_numpy(), estimator.set_output(transform="default").transform(frames))
    hand = estimator.set_output(transform="pandas").transform(frames, basis="H")
    assert list(hand.columns) == list(estimator.shape_names_[:4])
    assert list(estimator.transform(frames, basis="PCA").columns) == ["pca_1", "pca_2", "pca_3"]
    with pytest.raises(WorkbenchError, match="^set_output's transform must be one of 'default', 'pandas', 'polars'"):
        estimator.set_output(transform="arrow")
