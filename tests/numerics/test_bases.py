"""Known-answer tests of eigenfaces (eq. 2), quasi-eigen projection (eq. 3-4) and the post-treatment."""

import numpy as np
import pytest

from workbench.core.errors import WorkbenchError
from workbench.numerics.bases import (
    Eigenfaces,
    build_quasi_eigen_basis,
    covariance_eigen,
    empty_axes,
    flip_signs,
    n_components_for_coverage,
    pca_to_qe_weights,
    quasi_eigen_faces,
)


def low_rank_capture(n_frames, n_dims, stds, seed=0):
    """A capture whose PCA is known exactly: mean + orthogonal centred scores x orthonormal axes."""
    rng = np.random.default_rng(seed)
    k = len(stds)
    axes = np.linalg.qr(rng.standard_normal((n_dims, k)))[0].T  # (k, n_dims), orthonormal rows
    raw = rng.standard_normal((n_frames, k))
    scores = np.linalg.qr(raw - raw.mean(axis=0))[0]  # orthonormal, centred columns
    scores *= np.sqrt(n_frames) * np.asarray(stds)  # sample variance of column i is stds[i]**2
    mean = rng.standard_normal(n_dims) * 10
    return mean + scores @ axes, mean, axes, np.asarray(stds) ** 2


@pytest.mark.parametrize("n_frames,n_dims,expected_method", [(400, 30, "covariance"), (25, 120, "gram")])
def test_pca_recovers_known_eigenvalues_and_axes(n_frames, n_dims, expected_method):
    stds = [5.0, 3.0, 2.0, 1.0, 0.5]
    capture, mean, axes, variances = low_rank_capture(n_frames, n_dims, stds)
    pca = Eigenfaces(n_components=5).fit(capture)
    assert pca.method_ == expected_method
    np.testing.assert_allclose(pca.mean_, mean, rtol=0, atol=1e-10)
    np.testing.assert_allclose(pca.explained_variance_, variances, rtol=1e-9)
    np.testing.assert_allclose(np.abs(pca.components_ @ axes.T), np.eye(5), atol=1e-9)
    np.testing.assert_allclose(pca.components_ @ pca.components_.T, np.eye(5), atol=1e-10)
    np.testing.assert_allclose(pca.explained_variance_ratio_, variances / variances.sum(), rtol=1e-9)


def test_covariance_and_gram_routes_agree():
    capture, *_ = low_rank_capture(60, 59, [4.0, 2.0, 1.0], seed=3)
    centred = capture - capture.mean(axis=0)
    values_cov, vectors_cov, method_cov = covariance_eigen(centred)
    # One zero column more than there are frames sends the same data down the Gram route.
    values_gram, vectors_gram, method_gram = covariance_eigen(np.hstack([centred, np.zeros((60, 2))]))
    assert (method_cov, method_gram) == ("covariance", "gram")
    np.testing.assert_allclose(values_gram, values_cov, rtol=1e-10)
    np.testing.assert_allclose(vectors_gram[:, :-2], vectors_cov, atol=1e-9)
    np.testing.assert_allclose(vectors_gram[:, -2:], 0.0, atol=1e-12)


def test_coverage_picks_smallest_m():
    ratio = np.array([0.6, 0.3, 0.05, 0.04, 0.01])
    assert n_components_for_coverage(ratio, 0.6) == 1
    assert n_components_for_coverage(ratio, 0.9) == 2
    assert n_components_for_coverage(ratio, 0.95) == 3
    assert n_components_for_coverage(ratio, 0.96) == 4
    assert n_components_for_coverage(ratio, 1.0) == 5


def test_coverage_threshold_on_fit():
    capture, *_ = low_rank_capture(300, 40, [10.0, 5.0, 1.0, 0.1])
    variances = np.array([100.0, 25.0, 1.0, 0.01])
    cumulative = np.cumsum(variances) / variances.sum()
    pca = Eigenfaces(coverage=0.995).fit(capture)
    assert pca.n_components_ == 3
    assert pca.coverage_ == pytest.approx(cumulative[2], rel=1e-9)
    assert Eigenfaces(coverage=0.99).fit(capture).n_components_ == 2  # cumulative[1] = 0.99207


@pytest.mark.parametrize("coverage", [0.0, -0.1, 1.5])
def test_coverage_outside_unit_interval_is_refused(coverage):
    capture, *_ = low_rank_capture(50, 10, [1.0, 0.5])
    with pytest.raises(WorkbenchError, match="coverage"):
        Eigenfaces(coverage=coverage).fit(capture)


def test_fixed_m_larger_than_rank_is_refused():
    capture, *_ = low_rank_capture(50, 10, [1.0, 0.5])
    with pytest.raises(WorkbenchError, match="n_components.*rank 2"):
        Eigenfaces(n_components=3).fit(capture)


def test_unfitted_and_bad_capture_errors():
    with pytest.raises(WorkbenchError, match="not fitted"):
        Eigenfaces().reconstruct(np.zeros((2, 3)))
    with pytest.raises(WorkbenchError, match="NaN or Inf"):
        Eigenfaces().fit(np.array([[0.0, np.nan], [1.0, 2.0]]))
    with pytest.raises(WorkbenchError, match="no variance"):
        Eigenfaces().fit(np.ones((5, 3)))


def test_signs_are_deterministic():
    capture, *_ = low_rank_capture(200, 20, [3.0, 2.0, 1.0])
    components = Eigenfaces(n_components=3).fit(capture).components_
    np.testing.assert_array_equal(flip_signs(-components), components)
    assert np.all(components[np.arange(3), np.argmax(np.abs(components), axis=1)] > 0)


def test_pca_reconstruction_is_exact_inside_the_span():
    capture, *_ = low_rank_capture(100, 30, [3.0, 2.0, 1.0])
    pca = Eigenfaces(coverage=1.0).fit(capture)
    np.testing.assert_allclose(pca.reconstruct(capture), capture, atol=1e-9)


@pytest.fixture
def fitted():
    capture, mean, axes, _ = low_rank_capture(500, 24, [6.0, 4.0, 2.0, 1.0], seed=7)
    return Eigenfaces(coverage=1.0).fit(capture), mean, axes


@pytest.mark.parametrize("projection", ["affine", "linear"])
def test_hand_shape_on_hyperplane_comes_back_unchanged(fitted, projection):
    pca, mean, axes = fitted
    rng = np.random.default_rng(1)
    on_plane = rng.standard_normal((5, 4)) @ axes
    if projection == "affine":
        on_plane = on_plane + mean
    weights = pca_to_qe_weights(on_plane, pca.components_, pca.mean_, projection)
    np.testing.assert_allclose(quasi_eigen_faces(weights, pca.components_, pca.mean_, projection), on_plane, atol=1e-9)


@pytest.mark.parametrize("projection", ["affine", "linear"])
def test_projection_is_idempotent_and_moves_by_least_distance(fitted, projection):
    pca, _, _ = fitted
    rng = np.random.default_rng(2)
    hand = rng.standard_normal((6, 24)) * 5
    once = quasi_eigen_faces(
        pca_to_qe_weights(hand, pca.components_, pca.mean_, projection), pca.components_, pca.mean_, projection
    )
    twice = quasi_eigen_faces(
        pca_to_qe_weights(once, pca.components_, pca.mean_, projection), pca.components_, pca.mean_, projection
    )
    np.testing.assert_allclose(twice, once, atol=1e-9)
    # The move is orthogonal to the hyperplane, so it is the least Euclidean distance onto it.
    np.testing.assert_allclose((hand - once) @ pca.components_.T, 0.0, atol=1e-9)


def test_eq3_weights_match_the_formula(fitted):
    pca, _, _ = fitted
    hand = np.random.default_rng(4).standard_normal((3, 24))
    weights = pca_to_qe_weights(hand, pca.components_, pca.mean_, "affine")
    for i in range(3):
        for j in range(4):
            assert weights[i, j] == pytest.approx(pca.components_[j] @ (hand[i] - pca.mean_), abs=1e-12)
    linear = pca_to_qe_weights(hand, pca.components_, pca.mean_, "linear")
    np.testing.assert_allclose(linear, hand @ pca.components_.T, atol=1e-12)


def test_post_treatment_finds_and_appends_the_empty_axis(fitted):
    pca, _, _ = fitted
    rng = np.random.default_rng(5)
    # Hand shapes with nothing along eigenface 3 (index 2), plus some off-plane noise.
    coefficients = rng.standard_normal((5, 4)) * 10
    coefficients[:, 2] = 0.0
    off_plane = rng.standard_normal((5, 24))
    off_plane -= (off_plane @ pca.components_.T) @ pca.components_
    hand = coefficients @ pca.components_ + off_plane
    result = build_quasi_eigen_basis(
        hand, [f"h{i}" for i in range(5)], pca, projection="linear", empty_axis_eps=0.01, append_empty_axes=True
    )
    assert result.empty_axes == (2,)
    assert result.appended_axes == (2,)
    assert result.names[-1] == "pca_3"
    np.testing.assert_allclose(result.shapes[-1], pca.components_[2])
    assert result.shapes.shape == (6, 24)
    np.testing.assert_array_equal(empty_axes(result.weights, result.thresholds), [2])
    kept = build_quasi_eigen_basis(hand, [f"h{i}" for i in range(5)], pca, projection="linear", empty_axis_eps=0.01)
    assert kept.empty_axes == (2,) and kept.appended_axes == () and kept.shapes.shape == (5, 24)


def test_quasi_eigen_basis_validates_its_inputs(fitted):
    pca, _, _ = fitted
    with pytest.raises(WorkbenchError, match="24 columns"):
        build_quasi_eigen_basis(np.ones((2, 23)), ["a", "b"], pca)
    with pytest.raises(WorkbenchError, match="2 shapes but 1 names"):
        build_quasi_eigen_basis(np.ones((2, 24)), ["a"], pca)
    with pytest.raises(WorkbenchError, match="projection"):
        build_quasi_eigen_basis(np.ones((2, 24)), ["a", "b"], pca, projection="oblique")


def decaying_capture(rng, n_frames=600, n_dims=300, rank=12, noise=1e-3):
    """Frames on a rank-``rank`` affine subspace with decaying variances, plus a little isotropic noise."""
    axes = np.linalg.qr(rng.standard_normal((n_dims, rank)))[0].T
    scores = rng.standard_normal((n_frames, rank)) * np.geomspace(10.0, 0.3, rank)
    return 5.0 + scores @ axes + noise * rng.standard_normal((n_frames, n_dims))


@pytest.mark.parametrize("coverage", [0.9, 0.99, 0.999])
def test_randomized_solver_matches_exact(coverage):
    capture = decaying_capture(np.random.default_rng(3))
    exact = Eigenfaces(coverage=coverage, svd_solver="exact").fit(capture)
    fast = Eigenfaces(coverage=coverage, svd_solver="randomized").fit(capture)
    assert fast.method_ == "randomized" and fast.n_components_ == exact.n_components_
    m = exact.n_components_
    np.testing.assert_allclose(fast.explained_variance_[:m], exact.explained_variance_[:m], rtol=1e-9)
    np.testing.assert_allclose(fast.explained_variance_ratio_[:m], exact.explained_variance_ratio_[:m], rtol=1e-9)
    np.testing.assert_allclose(fast.components_, exact.components_, atol=1e-7)
    assert fast.coverage_ == pytest.approx(exact.coverage_, rel=1e-9)


def test_randomized_solver_grows_until_coverage_is_reached():
    """More than the first 32 eigenpairs are needed: the solver doubles until the coverage is reached."""
    rng = np.random.default_rng(4)
    capture = rng.standard_normal((500, 120)) * np.linspace(1.0, 0.9, 120)  # nearly flat spectrum
    exact = Eigenfaces(coverage=0.9, svd_solver="exact").fit(capture)
    fast = Eigenfaces(coverage=0.9, svd_solver="randomized").fit(capture)
    assert exact.n_components_ > 32
    assert fast.n_components_ == exact.n_components_
    np.testing.assert_allclose(fast.explained_variance_[:10], exact.explained_variance_[:10], rtol=1e-6)


def test_randomized_solver_is_deterministic_and_rejects_unknown_solver():
    capture = decaying_capture(np.random.default_rng(5))
    first = Eigenfaces(n_components=5, svd_solver="randomized", seed=7).fit(capture).components_
    second = Eigenfaces(n_components=5, svd_solver="randomized", seed=7).fit(capture).components_
    assert np.array_equal(first, second)
    with pytest.raises(WorkbenchError, match="svd_solver must be"):
        Eigenfaces(svd_solver="arpack").fit(capture)


@pytest.mark.parametrize("solver", ["exact", "randomized"])
def test_with_n_components_equals_a_fresh_fit_at_that_m(solver):
    """The paper's m = n from the coverage rule's decomposition: the same eigenfaces as decomposing again."""
    capture = decaying_capture(np.random.default_rng(6), rank=24)  # 24 separated axes above the noise
    rule = Eigenfaces(coverage=0.9, svd_solver=solver, n_reusable=18).fit(capture)
    assert rule.n_components_ < 18
    truncated, fresh = rule.with_n_components(18), Eigenfaces(n_components=18, svd_solver=solver).fit(capture)
    assert truncated.n_components_ == fresh.n_components_ == 18 and truncated.method_ == fresh.method_
    assert truncated.explained_variance_.shape == fresh.explained_variance_.shape
    if solver == "exact":  # every eigenpair was found: the very same arrays
        np.testing.assert_array_equal(truncated.components_, fresh.components_)
        np.testing.assert_array_equal(truncated.explained_variance_ratio_, fresh.explained_variance_ratio_)
    # the randomised-vs-exact tolerances of test_randomized_solver_matches_exact
    np.testing.assert_allclose(truncated.components_, fresh.components_, atol=1e-7)
    np.testing.assert_allclose(truncated.explained_variance_, fresh.explained_variance_, rtol=1e-9)
    assert truncated.coverage_ == pytest.approx(fresh.coverage_, rel=1e-9)
    np.testing.assert_array_equal(truncated.mean_, rule.mean_)
    assert rule.n_components_ < 18 and rule.components_.shape[0] == rule.n_components_  # the fit is unchanged
    with pytest.raises(WorkbenchError, match="n_components must be between 1 and the"):
        Eigenfaces(n_components=3, svd_solver="randomized").fit(capture).with_n_components(4)
    if solver == "randomized":  # beyond its m, only the n_reusable pairs it brought to convergence
        with pytest.raises(WorkbenchError, match=f"the {rule.n_components_} eigenpairs this fit can give"):
            Eigenfaces(coverage=0.9, svd_solver=solver).fit(capture).with_n_components(18)


def test_auto_takes_the_path_the_cost_model_puts_cheaper():
    from workbench.numerics.randomized_pca import EIGH_COST, SKINNY_COST, auto_solver, solver_costs

    # ICT mesh columns: exact n^2 d + EIGH_COST n^3 against 2 * 4 products of n d (24 + 8) weighed multiply-adds
    d = 28227
    assert solver_costs(1000, d, 24) == (1000**2 * d + EIGH_COST * 1000**3, SKINNY_COST * 8 * 1000 * d * 32)
    crossover = next(n for n in range(501, 5000) if auto_solver(n, d, None, 500) == "randomized")
    exact, randomized = solver_costs(crossover, d, 24)
    assert randomized < exact and np.greater_equal(*solver_costs(crossover - 1, d, 24)[::-1])
    assert 950 < crossover < 1000
    assert all(auto_solver(n, d, None, 500) == "randomized" for n in (3000, 3999, 4001, 5000))
    assert auto_solver(35000, 198, None, 500) == "exact"  # markers: the 198 x 198 covariance
    assert auto_solver(1000, 1000, 400, 500) == "exact"  # 420 columns per product: the eigen-decomposition wins
    assert auto_solver(2000, 2000, None, 2000) == "exact"  # the floor
    capture = decaying_capture(np.random.default_rng(3), n_frames=900, n_dims=600)
    assert auto_solver(900, 600, None, 500) == "randomized"
    assert Eigenfaces(coverage=0.99).fit(capture).method_ == "randomized"
    assert Eigenfaces(coverage=0.99).fit(capture[:, :500]).method_ == "covariance"


def test_randomized_solver_stops_once_converged_or_once_the_space_holds_every_direction():
    from workbench.numerics.bases import randomized_covariance_eigen

    capture = decaying_capture(np.random.default_rng(3), noise=0.0)  # rank 12: converged once C times the start
    mean, total, values, _, n_passes = randomized_covariance_eigen(capture, 12, np.random.default_rng(0))
    assert n_passes == 4  # the first pass (with the mean and total variance) and one more
    exact = Eigenfaces(n_components=12, svd_solver="exact").fit(capture)
    np.testing.assert_allclose(values, exact.explained_variance_[:12], rtol=1e-9)
    np.testing.assert_allclose(mean, capture.mean(axis=0), rtol=1e-12)
    assert total == pytest.approx(capture.var(axis=0).sum(), rel=1e-12)
    flat = np.random.default_rng(4).standard_normal((500, 120)) * np.linspace(1.0, 0.9, 120)
    _, _, values, _, n_passes = randomized_covariance_eigen(flat, 32, np.random.default_rng(0))
    assert n_passes == 6  # blocks of 40: the third holds the last of the 120 directions, exactly
    exact = Eigenfaces(n_components=32, svd_solver="exact").fit(flat)
    np.testing.assert_allclose(values, exact.explained_variance_[:32], rtol=1e-9)


def test_randomized_solver_far_from_the_origin_and_its_refusal_of_nan():
    """A capture whose mean is far larger than its spread starts the Krylov space one pass later (the first pass's
    uncentred product would cancel), with the same eigenpairs; NaN is found by the first pass and located."""
    from workbench.numerics.bases import randomized_covariance_eigen

    capture = decaying_capture(np.random.default_rng(3))
    exact = Eigenfaces(n_components=12, svd_solver="exact").fit(capture)
    near = randomized_covariance_eigen(capture, 12, np.random.default_rng(0))
    far = randomized_covariance_eigen(capture + 1e4, 12, np.random.default_rng(0))
    assert near[4] <= far[4] <= near[4] + 2
    for _, _, values, vectors, _ in (near, far):
        np.testing.assert_allclose(values, exact.explained_variance_[:12], rtol=1e-9)
        np.testing.assert_allclose(vectors, exact.components_, atol=1e-7)
    broken = capture.copy()
    broken[321, 7] = np.nan
    with pytest.raises(WorkbenchError, match=r"capture holds NaN or Inf values \(in frames 0-599\)"):
        Eigenfaces(n_components=3, svd_solver="randomized").fit(broken)


def test_randomized_solver_on_a_large_capture_reads_larger_chunks_to_the_same_eigenpairs(monkeypatch):
    """From LARGE_FRAMES values on, each pass reads chunks of LARGE_CHUNK_BYTES (the threshold lowered here so that
    a small capture crosses it): fewer, longer chunks, and the eigenpairs of the smaller chunks to round-off."""
    from workbench.numerics import randomized_pca

    capture = decaying_capture(np.random.default_rng(3), n_frames=2000, n_dims=600)
    monkeypatch.setattr(randomized_pca, "CHUNK_BYTES", 8 * 600 * 50)
    monkeypatch.setattr(randomized_pca, "LARGE_CHUNK_BYTES", 8 * 600 * 400)
    small = randomized_pca.randomized_covariance_eigen(capture, 12, np.random.default_rng(0))
    assert [rows.stop - rows.start for rows, _ in randomized_pca.product_chunks(capture)][:2] == [50, 50]
    monkeypatch.setattr(randomized_pca, "LARGE_FRAMES", capture.size)
    large = randomized_pca.randomized_covariance_eigen(capture, 12, np.random.default_rng(0))
    assert [rows.stop - rows.start for rows, _ in randomized_pca.product_chunks(capture)] == [400] * 5
    assert large[4] == small[4]
    np.testing.assert_allclose(large[0], small[0], rtol=1e-13)
    np.testing.assert_allclose(large[2], small[2], rtol=1e-12)
    np.testing.assert_allclose(np.abs(large[3] @ small[3].T), np.eye(12), atol=1e-9)
