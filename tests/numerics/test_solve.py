"""Tests of workbench.numerics.solve: eq. 5 weights for every frame, checked against NumPy/SciPy per frame."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import lsq_linear, nnls

import workbench.numerics.solve
from workbench.core.errors import WorkbenchError
from workbench.core.tolerances import TOL
from workbench.numerics.solve import WeightSolution, kkt_violation, reconstruct, solve_weights

N_FRAMES = 200


# ----------------------------------------------------------------------------------------------------------
# Helpers (independent of the module under test)
# ----------------------------------------------------------------------------------------------------------


def random_problem(seed, n_shapes, n_dims, n_frames=N_FRAMES, scale=1.0):
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((n_shapes, n_dims)) * scale
    weights = rng.uniform(-0.5, 1.5, (n_frames, n_shapes))
    targets = weights @ basis + 0.5 * scale * rng.standard_normal((n_frames, n_dims))
    return basis, targets


def objective(basis, targets, weights):
    """0.5 |d - B^T w|^2 per frame, shape (n_frames,)."""
    return 0.5 * ((targets - weights @ basis) ** 2).sum(axis=1)


def scipy_nnls(basis, targets):
    return np.array([nnls(basis.T, d)[0] for d in targets])


def scipy_bvls(basis, targets, lower, upper):
    """Per-frame lsq_linear(method="bvls"); shapes with lower == upper are fixed (SciPy needs lower < upper)."""
    n = basis.shape[0]
    lo = np.broadcast_to(-np.inf if lower is None else np.asarray(lower, float), (n,))
    hi = np.broadcast_to(np.inf if upper is None else np.asarray(upper, float), (n,))
    fixed = lo == hi
    weights = np.tile(np.where(fixed, lo, 0.0), (len(targets), 1))
    rest = targets - lo[fixed] @ basis[fixed]
    bounds = (lo[~fixed], hi[~fixed])
    weights[:, ~fixed] = [lsq_linear(basis[~fixed].T, d, bounds=bounds, method="bvls", tol=1e-12).x for d in rest]
    return weights


def assert_kkt(basis, targets, weights, lower, upper, rtol=1e-8, atol_w=1e-10):
    """KKT of min 0.5|d - B^T w|^2 s.t. lower <= w <= upper, checked from the definition."""
    n = basis.shape[0]
    lo = np.broadcast_to(-np.inf if lower is None else np.asarray(lower, float), (n,))
    hi = np.broadcast_to(np.inf if upper is None else np.asarray(upper, float), (n,))
    grad = (weights @ basis - targets) @ basis.T
    size = np.abs(targets @ basis.T).max(axis=1) + np.abs(basis @ basis.T).max() * np.abs(weights).max(axis=1)
    scaled = grad / size[:, None]
    assert np.all(weights >= lo - atol_w), "weights below lower"
    assert np.all(weights <= hi + atol_w), "weights above upper"
    at_lo = weights <= lo + atol_w
    at_hi = weights >= hi - atol_w
    free = ~at_lo & ~at_hi
    assert np.all(np.abs(scaled[free]) <= rtol), "gradient not zero on free weights"
    assert np.all(scaled[at_lo & ~at_hi] >= -rtol), "gradient points below a lower bound"
    assert np.all(scaled[at_hi & ~at_lo] <= rtol), "gradient points above an upper bound"


def planted_box_problem(seed, n_shapes=12, n_dims=60, n_frames=N_FRAMES, frac_active=0.6):
    """Targets whose box solution is known exactly, with many active bounds (per-shape bounds)."""
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((n_shapes, n_dims))
    lower = rng.uniform(-1.0, 0.0, n_shapes)
    upper = lower + rng.uniform(0.2, 2.0, n_shapes)
    solution = rng.uniform(lower, upper, (n_frames, n_shapes))
    state = rng.random((n_frames, n_shapes))
    at_lo = state < frac_active / 2
    at_hi = (state >= frac_active / 2) & (state < frac_active)
    solution = np.where(at_lo, lower, np.where(at_hi, upper, solution))
    gram = basis @ basis.T
    push = rng.uniform(0.1, 1.0, (n_frames, n_shapes)) * np.abs(gram).max()
    grad = np.where(at_lo, push, 0.0) - np.where(at_hi, push, 0.0)
    rhs = solution @ gram - grad
    noise = rng.standard_normal((n_frames, n_dims))
    noise -= np.linalg.solve(gram, basis @ noise.T).T @ basis
    targets = np.linalg.solve(gram, rhs.T).T @ basis + noise
    return basis, targets, lower, upper, solution, at_lo | at_hi


# ----------------------------------------------------------------------------------------------------------
# lstsq
# ----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("n_shapes, n_dims", [(3, 30), (18, 198), (10, 6)])
def test_lstsq_equals_numpy_per_frame(seed, n_shapes, n_dims):
    basis, targets = random_problem(seed, n_shapes, n_dims)
    sol = solve_weights(basis, targets)
    expected = np.array([np.linalg.lstsq(basis.T, d, rcond=None)[0] for d in targets])
    np.testing.assert_allclose(sol.weights, expected, rtol=1e-10, atol=1e-10)
    assert sol.kind == "lstsq" and sol.n_iterations == 0 and sol.n_fallback_frames == 0
    assert sol.max_kkt_violation == 0.0 and sol.lower is None and sol.upper is None


def test_lstsq_recovers_planted_weights():
    rng = np.random.default_rng(7)
    basis = rng.standard_normal((18, 198))
    planted = rng.standard_normal((500, 18))
    sol = solve_weights(basis, planted @ basis, kind="lstsq")
    np.testing.assert_allclose(sol.weights, planted, rtol=0, atol=1e-12)


def test_lstsq_minimum_norm_for_duplicate_shapes():
    basis, targets = random_problem(3, 5, 40)
    basis = np.vstack([basis, basis[2]])
    sol = solve_weights(basis, targets)
    expected = np.array([np.linalg.lstsq(basis.T, d, rcond=None)[0] for d in targets])
    np.testing.assert_allclose(sol.weights, expected, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(sol.weights[:, 2], sol.weights[:, 5], rtol=1e-9, atol=1e-9)


# ----------------------------------------------------------------------------------------------------------
# nnls
# ----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("n_shapes", [3, 10, 18])
@pytest.mark.parametrize("n_dims", [30, 198])
def test_nnls_agrees_with_scipy_per_frame(seed, n_shapes, n_dims):
    basis, targets = random_problem(seed, n_shapes, n_dims)
    sol = solve_weights(basis, targets, kind="nnls")
    expected = scipy_nnls(basis, targets)
    np.testing.assert_allclose(sol.weights, expected, rtol=0, atol=1e-6)
    np.testing.assert_allclose(
        objective(basis, targets, sol.weights), objective(basis, targets, expected), rtol=1e-10, atol=1e-12
    )
    assert sol.lower == 0.0 and sol.upper is None
    assert np.all(sol.weights >= 0.0)
    assert sol.max_kkt_violation <= TOL.kkt


@pytest.mark.parametrize("kind, lower, upper", [("nnls", None, None), ("box", 0.0, 1.0)])
def test_more_than_62_shapes(kind, lower, upper):
    # Free sets of more than 62 shapes do not fit one integer key; frames are grouped by their rows instead.
    basis, targets = random_problem(18, 70, 120, n_frames=60)
    sol = solve_weights(basis, targets, kind=kind, lower=lower, upper=upper)
    expected = scipy_reference(basis, targets, lower, upper)
    np.testing.assert_allclose(
        objective(basis, targets, sol.weights), objective(basis, targets, expected), rtol=1e-8, atol=0
    )
    assert sol.n_fallback_frames == 0 and sol.max_kkt_violation <= TOL.kkt


def test_nnls_keeps_feasible_frames_unconstrained_and_zero_targets_at_zero():
    rng = np.random.default_rng(11)
    basis = rng.standard_normal((6, 50))
    positive = rng.uniform(0.1, 1.0, (20, 6))
    targets = np.vstack([positive @ basis, np.zeros((3, 50))])
    sol = solve_weights(basis, targets, kind="nnls")
    np.testing.assert_allclose(sol.weights[:20], positive, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(sol.weights[20:], 0.0)
    assert sol.n_iterations == 0


# ----------------------------------------------------------------------------------------------------------
# box
# ----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("n_shapes, n_dims", [(3, 30), (10, 198), (18, 198), (18, 30)])
def test_box_agrees_with_bvls_scalar_bounds(seed, n_shapes, n_dims):
    basis, targets = random_problem(seed, n_shapes, n_dims)
    sol = solve_weights(basis, targets, kind="box", lower=0.0, upper=1.0)
    expected = scipy_bvls(basis, targets, 0.0, 1.0)
    np.testing.assert_allclose(sol.weights, expected, rtol=0, atol=1e-6)
    np.testing.assert_allclose(
        objective(basis, targets, sol.weights), objective(basis, targets, expected), rtol=1e-10, atol=1e-12
    )
    assert sol.lower == 0.0 and sol.upper == 1.0 and sol.kind == "box"
    assert_kkt(basis, targets, sol.weights, 0.0, 1.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_box_agrees_with_bvls_per_shape_and_infinite_bounds(seed):
    rng = np.random.default_rng(100 + seed)
    basis, targets = random_problem(seed, 10, 80)
    lower = rng.uniform(-0.5, 0.5, 10)
    upper = lower + rng.uniform(0.0, 1.0, 10)
    lower[[1, 4]] = -np.inf
    upper[[2, 4, 7]] = np.inf
    upper[5] = lower[5]  # a pinned shape
    sol = solve_weights(basis, targets, kind="box", lower=lower, upper=upper)
    expected = scipy_bvls(basis, targets, lower, upper)
    np.testing.assert_allclose(sol.weights, expected, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(sol.weights[:, 5], lower[5])
    np.testing.assert_array_equal(sol.lower, lower)
    np.testing.assert_array_equal(sol.upper, upper)
    assert_kkt(basis, targets, sol.weights, lower, upper)


@pytest.mark.parametrize(
    "lower, upper",
    [(None, 0.5), (-0.25, None), (-np.inf, 0.3), (np.full(8, -np.inf), np.linspace(0.0, 1.0, 8))],
)
def test_box_one_sided_bounds(lower, upper):
    basis, targets = random_problem(4, 8, 50)
    sol = solve_weights(basis, targets, kind="box", lower=lower, upper=upper)
    expected = scipy_bvls(basis, targets, lower, upper)
    np.testing.assert_allclose(sol.weights, expected, rtol=0, atol=1e-6)
    assert_kkt(basis, targets, sol.weights, lower, upper)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_box_recovers_planted_solution_with_many_active_bounds(seed):
    basis, targets, lower, upper, planted, active = planted_box_problem(seed)
    assert active.mean() > 0.5
    sol = solve_weights(basis, targets, kind="box", lower=lower, upper=upper)
    np.testing.assert_allclose(sol.weights, planted, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.weights, scipy_bvls(basis, targets, lower, upper), rtol=0, atol=1e-6)
    assert sol.max_kkt_violation <= TOL.kkt


def test_box_is_unit_invariant():
    basis, targets = random_problem(5, 12, 90)
    small = solve_weights(basis, targets, kind="box", lower=0.0, upper=1.0)
    large = solve_weights(basis * 1e3, targets * 1e3, kind="box", lower=0.0, upper=1.0)
    np.testing.assert_allclose(large.weights, small.weights, rtol=0, atol=1e-10)


# ----------------------------------------------------------------------------------------------------------
# KKT
# ----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind, lower, upper", [("nnls", None, None), ("box", 0.0, 1.0), ("box", -0.2, 0.4)])
def test_kkt_conditions_hold(kind, lower, upper):
    basis, targets = random_problem(8, 18, 198)
    sol = solve_weights(basis, targets, kind=kind, lower=lower, upper=upper)
    assert_kkt(basis, targets, sol.weights, 0.0 if kind == "nnls" else lower, upper)
    violation = kkt_violation(basis @ basis.T, targets @ basis.T, sol.weights, sol.lower, sol.upper)
    assert violation.shape == (N_FRAMES,)
    assert np.all(violation <= TOL.kkt)
    assert sol.max_kkt_violation == pytest.approx(violation.max(), rel=1e-6, abs=1e-15)


def test_kkt_violation_detects_wrong_weights():
    basis, targets = random_problem(9, 6, 40)
    gram, rhs = basis @ basis.T, targets @ basis.T
    sol = solve_weights(basis, targets, kind="box", lower=0.0, upper=1.0)
    moved = np.clip(sol.weights + 1e-3, 0.0, 1.0)
    assert np.all(kkt_violation(gram, rhs, moved, 0.0, 1.0) > 1e-6)
    infeasible = sol.weights.copy()
    infeasible[:, 0] = -0.1
    assert np.all(kkt_violation(gram, rhs, infeasible, 0.0, 1.0) >= 0.1 / 1.1)
    unconstrained = solve_weights(basis, targets).weights
    assert np.all(kkt_violation(gram, rhs, unconstrained, None, None) <= 1e-12)
    nan_weights = sol.weights.copy()
    nan_weights[3, 2] = np.nan
    assert np.isinf(kkt_violation(gram, rhs, nan_weights, 0.0, 1.0)[3])
    with pytest.raises(WorkbenchError, match="gram"):
        kkt_violation(gram[:, :3], rhs, sol.weights, 0.0, 1.0)


# ----------------------------------------------------------------------------------------------------------
# Ill-conditioned and rank-deficient bases
# ----------------------------------------------------------------------------------------------------------


def ill_conditioned_basis(seed, gap):
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((6, 40))
    basis[1] = basis[0] + gap * rng.standard_normal(40)
    targets = rng.uniform(0.0, 1.0, (N_FRAMES, 6)) @ basis + rng.standard_normal((N_FRAMES, 40))
    return basis, targets


@pytest.mark.parametrize("gap", [0.0, 1e-12, 1e-9, 1e-6])
@pytest.mark.parametrize("kind, lower, upper", [("nnls", None, None), ("box", 0.0, 1.0)])
def test_rank_deficient_basis_attains_minimal_objective(gap, kind, lower, upper):
    basis, targets = ill_conditioned_basis(int(gap == 0.0), gap)
    sol = solve_weights(basis, targets, kind=kind, lower=lower, upper=upper)
    assert np.all(np.isfinite(sol.weights))
    expected = scipy_nnls(basis, targets) if kind == "nnls" else scipy_bvls(basis, targets, lower, upper)
    ours, theirs = objective(basis, targets, sol.weights), objective(basis, targets, expected)
    floor = 1e-8 * 0.5 * (targets**2).sum(axis=1)
    assert np.all(ours <= theirs * (1 + 1e-8) + floor)
    np.testing.assert_allclose(ours, theirs, rtol=1e-8, atol=0)
    assert np.all(sol.weights >= (0.0 if lower is None else lower))
    if upper is not None:
        assert np.all(sol.weights <= upper)
    assert sol.max_kkt_violation <= TOL.kkt


def test_duplicate_shapes_share_weight():
    basis, targets = ill_conditioned_basis(2, 0.0)
    sol = solve_weights(basis, targets, kind="box", lower=0.0, upper=1.0)
    summed = sol.weights[:, 0] + sol.weights[:, 1]
    expected = scipy_bvls(np.delete(basis, 1, axis=0), targets, 0.0, [2.0, 1.0, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(summed, expected[:, 0], rtol=0, atol=1e-6)


def test_more_shapes_than_dims_and_zero_shape():
    rng = np.random.default_rng(12)
    basis = rng.standard_normal((12, 9))
    basis[4] = 0.0
    targets = rng.standard_normal((N_FRAMES, 9)) * 3.0
    sol = solve_weights(basis, targets, kind="nnls")
    expected = scipy_nnls(basis, targets)
    np.testing.assert_allclose(
        objective(basis, targets, sol.weights), objective(basis, targets, expected), rtol=1e-8, atol=1e-10
    )
    np.testing.assert_allclose(sol.weights[:, 4], 0.0, rtol=0, atol=1e-9)


# ----------------------------------------------------------------------------------------------------------
# Rank-deficient bases: known answers, all frames solved in batch
# ----------------------------------------------------------------------------------------------------------

N_MANY = 2000

STRUCTURES = ["duplicates", "combinations", "projected", "affine_projected", "nearly_projected"]


def rank_deficient_problem(structure, seed, n_shapes=18, n_dims=198, rank=13, n_frames=N_MANY):
    """A basis of ``n_shapes`` shapes spanning (about) ``rank`` dimensions, and targets off its span.

    ``duplicates``: ``rank`` random shapes and copies of some of them; ``combinations``: ``rank`` random
    shapes and random linear combinations of them; ``projected``: random shapes projected onto a random
    ``rank``-dimensional subspace, as the quasi-eigen faces are with the linear projection;
    ``affine_projected``: projected onto an affine subspace through a random offset instead (``rank + 1``
    dimensions, like the affine projection); ``nearly_projected``: ``projected`` plus a 1e-9 perturbation
    (full rank, singular values down to ~1e-10 of the largest).  Rows are shuffled.  Targets mix the
    original shapes with weights in [-0.3, 1.2] (so both bounds of [0, 1] are often active) plus noise.
    """
    rng = np.random.default_rng(seed)
    shapes = rng.standard_normal((n_shapes, n_dims)) * rng.uniform(0.5, 2.0, (n_shapes, 1))
    if structure == "duplicates":
        basis = shapes[np.concatenate([np.arange(rank), rng.integers(0, rank, n_shapes - rank)])]
    elif structure == "combinations":
        basis = np.vstack([shapes[:rank], rng.standard_normal((n_shapes - rank, rank)) @ shapes[:rank]])
    else:
        axes = np.linalg.qr(rng.standard_normal((n_dims, rank)))[0]
        offset = rng.standard_normal(n_dims) if structure == "affine_projected" else np.zeros(n_dims)
        basis = offset + (shapes - offset) @ axes @ axes.T
        if structure == "nearly_projected":
            basis += 1e-9 * rng.standard_normal(basis.shape)
    basis = basis[rng.permutation(n_shapes)]
    mix = rng.uniform(-0.3, 1.2, (n_frames, n_shapes))
    targets = mix @ shapes + 0.3 * rng.standard_normal((n_frames, n_dims))
    return basis, targets


def scipy_reference(basis, targets, lower, upper):
    """Per-frame SciPy NNLS (``lower=None``) or BVLS, with a generous iteration cap.

    With its default cap (the number of variables) SciPy's BVLS stops early on rank-deficient bases, at
    weights that fail the KKT conditions; with 1000 iterations it converges.
    """
    if lower is None:
        return np.array([nnls(basis.T, d, maxiter=1000)[0] for d in targets])
    bounds = (lower, upper)
    return np.array([lsq_linear(basis.T, d, bounds=bounds, method="bvls", tol=1e-12, max_iter=1000).x for d in targets])


@pytest.mark.parametrize("structure", STRUCTURES)
@pytest.mark.parametrize("kind, lower, upper", [("nnls", None, None), ("box", 0.0, 1.0)])
def test_rank_deficient_basis_matches_scipy_without_fallback(structure, kind, lower, upper):
    basis, targets = rank_deficient_problem(structure, STRUCTURES.index(structure))
    singular = np.linalg.svd(basis, compute_uv=False)
    assert singular[13 if structure == "affine_projected" else 12] > 1e-3 * singular[0]
    assert singular[-1] < 1e-8 * singular[0]
    sol = solve_weights(basis, targets, kind=kind, lower=lower, upper=upper)
    assert sol.n_fallback_frames == 0
    assert sol.max_kkt_violation <= TOL.kkt
    assert_kkt(basis, targets, sol.weights, 0.0 if kind == "nnls" else lower, upper)
    some = slice(None, None, 20)
    expected = scipy_reference(basis, targets[some], lower, upper)
    gram, rhs = basis @ basis.T, targets[some] @ basis.T
    assert np.all(kkt_violation(gram, rhs, expected, sol.lower, sol.upper) <= 1e-8)  # a trustworthy reference
    np.testing.assert_allclose(
        objective(basis, targets[some], sol.weights[some]),
        objective(basis, targets[some], expected),
        rtol=1e-8,
        atol=0,
    )


@pytest.mark.parametrize("kind, lower, upper", [("nnls", None, None), ("box", 0.0, 1.0)])
def test_rank_deficient_basis_without_warm_start(monkeypatch, kind, lower, upper):
    # The ADMM warm start only saves iterations: from the clipped unconstrained weights alone, the active-set
    # method reaches the same objective, still without SciPy.
    basis, targets = rank_deficient_problem("affine_projected", 5, n_frames=500)
    warm = solve_weights(basis, targets, kind=kind, lower=lower, upper=upper)
    monkeypatch.setattr(workbench.numerics.solve, "_ADMM_STEPS", 0)
    cold = solve_weights(basis, targets, kind=kind, lower=lower, upper=upper)
    assert cold.n_fallback_frames == 0 and cold.max_kkt_violation <= TOL.kkt
    np.testing.assert_allclose(
        objective(basis, targets, cold.weights), objective(basis, targets, warm.weights), rtol=1e-10, atol=0
    )


@pytest.mark.parametrize("kind, lower, upper", [("nnls", None, None), ("box", 0.0, 1.0)])
def test_rank_deficient_basis_falls_back_to_exact_scipy(kind, lower, upper):
    basis, targets = rank_deficient_problem("projected", 6, n_frames=100)
    sol = solve_weights(basis, targets, kind=kind, lower=lower, upper=upper, tol=replace(TOL, active_set_max_iter=0))
    assert sol.n_fallback_frames >= 90
    assert sol.max_kkt_violation <= TOL.kkt
    expected = scipy_reference(basis, targets, lower, upper)
    np.testing.assert_allclose(
        objective(basis, targets, sol.weights), objective(basis, targets, expected), rtol=1e-8, atol=0
    )


def test_kkt_violation_accepts_every_optimum_of_a_singular_gram():
    # With duplicate shapes the optimal weights are not unique: moving weight between two copies keeps the
    # reconstruction, so the moved weights are optimal too and must pass; weights that change the
    # reconstruction must not.
    basis, targets = rank_deficient_problem("duplicates", 7, n_frames=300)
    same = (basis[:, None] == basis[None]).all(axis=2) & ~np.eye(len(basis), dtype=bool)
    i, j = np.argwhere(same)[0]
    gram, rhs = basis @ basis.T, targets @ basis.T
    assert np.linalg.matrix_rank(gram) == 13
    sol = solve_weights(basis, targets, kind="box", lower=0.0, upper=1.0)
    moved = sol.weights.copy()
    shift = 0.5 * np.minimum(1.0 - moved[:, i], moved[:, j])
    moved[:, i] += shift
    moved[:, j] -= shift
    assert np.count_nonzero(shift > 0.05) > 20
    np.testing.assert_allclose(reconstruct(basis, moved), reconstruct(basis, sol.weights), rtol=0, atol=1e-12)
    assert np.all(kkt_violation(gram, rhs, moved, 0.0, 1.0) <= TOL.kkt)
    assert np.all(kkt_violation(gram, rhs, np.clip(sol.weights + 1e-3, 0.0, 1.0), 0.0, 1.0) > 1e-6)


# ----------------------------------------------------------------------------------------------------------
# Fallback to SciPy: iteration cap, failed KKT check (and a frame that made the old method cycle)
# ----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("max_iter", [0, 1])
@pytest.mark.parametrize("kind, lower, upper", [("nnls", None, None), ("box", 0.0, 0.5)])
def test_iteration_cap_falls_back_to_scipy(max_iter, kind, lower, upper):
    basis, targets = random_problem(13, 18, 30, n_frames=300)
    tol = replace(TOL, active_set_max_iter=max_iter)
    sol = solve_weights(basis, targets, kind=kind, lower=lower, upper=upper, tol=tol)
    assert sol.n_fallback_frames > 0
    assert sol.n_iterations <= max_iter
    expected = scipy_nnls(basis, targets) if kind == "nnls" else scipy_bvls(basis, targets, lower, upper)
    np.testing.assert_allclose(sol.weights, expected, rtol=0, atol=1e-6)
    assert_kkt(basis, targets, sol.weights, 0.0 if kind == "nnls" else lower, upper)


def test_frame_on_which_primal_dual_active_set_cycles_is_solved_in_batch():
    # G = B B^T is positive definite but not an M-matrix; from this frame's first guess a primal-dual
    # active-set iteration visits four active sets and returns to the first one.  The batched primal
    # active-set method lowers the objective at every step, so it cannot cycle and needs no SciPy.
    basis = np.array(
        [
            [5.42132742, 0.99506762, 1.68317221],
            [4.58862157, -1.00065418, 3.33810755],
            [5.39613845, -1.50217202, 3.51836179],
        ]
    )
    targets = np.array([[-4.43382301, -4.43059603, -0.84204664]])
    lower, upper = -0.9965387373771148, 0.385709670364331
    sol = solve_weights(basis, targets, kind="box", lower=lower, upper=upper)
    assert sol.n_fallback_frames == 0
    assert sol.n_iterations < TOL.active_set_max_iter
    np.testing.assert_allclose(sol.weights, scipy_bvls(basis, targets, lower, upper), rtol=0, atol=1e-9)
    assert_kkt(basis, targets, sol.weights, lower, upper)


def test_fallback_handles_equal_bounds():
    basis, targets = random_problem(17, 6, 30)
    lower = np.array([0.0, 0.3, -1.0, 0.0, 0.2, 0.0])
    upper = np.array([1.0, 0.3, 1.0, 0.5, 0.2, np.inf])
    tol = replace(TOL, active_set_max_iter=0)
    sol = solve_weights(basis, targets, kind="box", lower=lower, upper=upper, tol=tol)
    assert sol.n_fallback_frames > 0
    np.testing.assert_array_equal(sol.weights[:, [1, 4]], np.broadcast_to([0.3, 0.2], (N_FRAMES, 2)))
    np.testing.assert_allclose(sol.weights, scipy_bvls(basis, targets, lower, upper), rtol=0, atol=1e-6)
    everything_fixed = solve_weights(basis, targets, kind="box", lower=0.25, upper=0.25, tol=tol)
    np.testing.assert_array_equal(everything_fixed.weights, 0.25)


def test_failed_kkt_check_resolves_with_scipy():
    basis, targets = random_problem(14, 10, 60)
    sol = solve_weights(basis, targets, kind="box", lower=0.0, upper=1.0, tol=replace(TOL, kkt=0.0))
    assert sol.n_fallback_frames > 0
    np.testing.assert_allclose(sol.weights, scipy_bvls(basis, targets, 0.0, 1.0), rtol=0, atol=1e-6)
    assert_kkt(basis, targets, sol.weights, 0.0, 1.0)


# ----------------------------------------------------------------------------------------------------------
# reconstruct and the result record
# ----------------------------------------------------------------------------------------------------------


def test_reconstruct_is_weights_times_basis():
    basis, targets = random_problem(15, 5, 21)
    sol = solve_weights(basis, targets, kind="nnls")
    np.testing.assert_allclose(reconstruct(basis, sol.weights), sol.weights @ basis, rtol=1e-15, atol=0)
    assert reconstruct(basis, sol.weights).shape == targets.shape
    with pytest.raises(WorkbenchError, match="weights"):
        reconstruct(basis, sol.weights[:, :3])


def test_solution_is_frozen_record():
    basis, targets = random_problem(16, 4, 12, n_frames=10)
    sol = solve_weights(basis, targets, kind="box", lower=0.0, upper=1.0)
    assert isinstance(sol, WeightSolution)
    assert sol.weights.shape == (10, 4)
    with pytest.raises(AttributeError):
        sol.kind = "nnls"


# ----------------------------------------------------------------------------------------------------------
# Bad inputs
# ----------------------------------------------------------------------------------------------------------

GOOD_BASIS = np.eye(3, 6)
GOOD_TARGETS = np.ones((4, 6))


def with_nan(array, value=np.nan):
    array = array.copy()
    array[0, 0] = value
    return array


@pytest.mark.parametrize(
    "basis, targets, kwargs, pattern",
    [
        (np.ones(6), GOOD_TARGETS, {}, r"basis must be 2-dimensional"),
        (GOOD_BASIS, np.ones((2, 4, 6)), {}, r"targets must be 2-dimensional"),
        (GOOD_BASIS, np.ones((4, 5)), {}, r"targets has 5 columns but basis has 6"),
        (with_nan(GOOD_BASIS), GOOD_TARGETS, {}, r"basis must be finite"),
        (GOOD_BASIS, with_nan(GOOD_TARGETS, np.inf), {}, r"targets must be finite"),
        (np.empty((0, 6)), GOOD_TARGETS, {}, r"basis must not be empty"),
        (GOOD_BASIS, np.empty((0, 6)), {}, r"targets must not be empty"),
        (GOOD_BASIS, [["a"] * 6], {}, r"targets must be a numeric array"),
        (GOOD_BASIS, GOOD_TARGETS, {"kind": "qp"}, r"kind must be one of lstsq, nnls, box"),
        (
            GOOD_BASIS,
            GOOD_TARGETS,
            {"kind": "box", "lower": 0.5, "upper": 0.2},
            r"lower \(0\.5\) must not exceed upper \(0\.2\)",
        ),
        (
            GOOD_BASIS,
            GOOD_TARGETS,
            {"kind": "box", "lower": [0.0, 0.9, 0.0], "upper": 0.5},
            r"lower\[1\] \(0\.9\) must not exceed upper\[1\] \(0\.5\)",
        ),
        (GOOD_BASIS, GOOD_TARGETS, {"kind": "box"}, r"kind 'box' needs lower or upper"),
        (
            GOOD_BASIS,
            GOOD_TARGETS,
            {"kind": "box", "lower": [0.0, 0.0]},
            r"lower must be a scalar or have shape \(3,\)",
        ),
        (GOOD_BASIS, GOOD_TARGETS, {"kind": "box", "upper": np.nan}, r"upper must not contain NaN"),
        (GOOD_BASIS, GOOD_TARGETS, {"kind": "box", "lower": np.inf}, r"lower must not be inf"),
        (GOOD_BASIS, GOOD_TARGETS, {"kind": "box", "upper": -np.inf}, r"upper must not be -inf"),
        (GOOD_BASIS, GOOD_TARGETS, {"kind": "nnls", "upper": 1.0}, r"kind 'nnls' fixes lower=0 and upper=None"),
        (GOOD_BASIS, GOOD_TARGETS, {"kind": "nnls", "lower": 0.1}, r"kind 'nnls' fixes lower=0"),
        (GOOD_BASIS, GOOD_TARGETS, {"lower": 0.0}, r"lower and upper must be None for kind 'lstsq'"),
    ],
)
def test_bad_inputs_raise_workbench_error(basis, targets, kwargs, pattern):
    with pytest.raises(WorkbenchError, match=pattern):
        solve_weights(basis, targets, **kwargs)


def test_nnls_accepts_explicit_zero_lower():
    sol = solve_weights(GOOD_BASIS, GOOD_TARGETS, kind="nnls", lower=0)
    np.testing.assert_allclose(sol.weights, 1.0, rtol=0, atol=1e-12)
