"""Known-answer tests of eq. 6 in both normalisations, the RMS error, the intuitiveness measure, the error as a
distribution over frames and the statistics of the weights."""

import numpy as np
import pytest

from workbench.core.errors import WorkbenchError
from workbench.numerics.intuitiveness import intuitiveness
from workbench.numerics.metrics import alpha_per_frame, alpha_pooled, point_norms, rms_point_error, summarise_alpha


def test_perfect_reconstruction_has_zero_alpha():
    rng = np.random.default_rng(0)
    neutral = rng.standard_normal(12) * 50
    captured = rng.standard_normal((7, 12))
    summary = summarise_alpha(neutral, captured, captured.copy())
    assert summary.absolute_mean == 0.0 and summary.absolute_pooled == 0.0
    assert summary.displacement_mean == 0.0 and summary.displacement_pooled == 0.0
    assert summary.rms_mm == 0.0


def test_alpha_known_values():
    reference = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 2.0]])
    reconstruction = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(alpha_per_frame(reference, reconstruction), [100.0, 50.0])
    # Pooled: sqrt(25 + 1) / sqrt(25 + 4), not the mean of 100 and 50.
    assert alpha_pooled(reference, reconstruction) == pytest.approx(100 * np.sqrt(26 / 29), rel=1e-12)


def test_absolute_alpha_depends_on_origin_and_displacement_alpha_does_not():
    captured = np.array([[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]])
    reconstructed = np.array([[0.5, 0.0, 0.0, 0.0, 1.0, 0.0]])
    near = summarise_alpha(np.zeros(6) + 1.0, captured, reconstructed)
    far = summarise_alpha(np.zeros(6) + 100.0, captured, reconstructed)
    assert far.absolute_mean < near.absolute_mean
    assert far.displacement_mean == near.displacement_mean == pytest.approx(100 * 0.5 / np.sqrt(2))


def test_zero_displacement_frames_are_undefined_not_infinite():
    captured = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    reconstructed = np.array([[0.1, 0.0, 0.0], [1.0, 0.0, 0.0]])
    summary = summarise_alpha(np.array([0.0, 0.0, 10.0]), captured, reconstructed)
    assert np.isnan(summary.displacement_per_frame[0])
    assert summary.n_undefined_displacement_frames == 1
    assert summary.displacement_mean == 0.0
    assert summary.displacement_pooled == pytest.approx(10.0)


def test_rms_point_error_is_per_3d_point():
    reference = np.zeros((2, 6))
    reconstruction = np.array([[3.0, 4.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    # One point off by 5 mm among 4 point-frames.
    assert rms_point_error(reference, reconstruction) == pytest.approx(np.sqrt(25 / 4))


def test_intuitiveness_known_values():
    hand = np.array([[1.0, 0.0], [0.0, 2.0], [3.0, 0.0]])
    qe = np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 3.0]])
    distance, cosine = intuitiveness(hand, qe)
    np.testing.assert_allclose(distance, [0.0, np.sqrt(8) / 2, 1.0])
    np.testing.assert_allclose(cosine, [1.0, 0.0, 1 / np.sqrt(2)])


def test_summary_equals_the_equation_functions_on_random_frames():
    rng = np.random.default_rng(7)
    neutral = rng.normal(50.0, 20.0, 3 * 40)
    captured = rng.normal(0.0, 2.0, (500, 3 * 40))
    captured[3] = 0.0  # a frame at rest: displacement alpha undefined
    reconstructed = captured + rng.normal(0.0, 0.3, captured.shape)
    summary = summarise_alpha(neutral, captured, reconstructed)
    np.testing.assert_allclose(
        summary.absolute_per_frame, alpha_per_frame(neutral + captured, neutral + reconstructed), rtol=1e-10
    )
    np.testing.assert_allclose(summary.displacement_per_frame, alpha_per_frame(captured, reconstructed), rtol=1e-10)
    assert np.isnan(summary.displacement_per_frame[3]) and summary.n_undefined_displacement_frames == 1
    np.testing.assert_allclose(
        summary.absolute_pooled, alpha_pooled(neutral + captured, neutral + reconstructed), rtol=1e-10
    )
    np.testing.assert_allclose(summary.displacement_pooled, alpha_pooled(captured, reconstructed), rtol=1e-10)
    np.testing.assert_allclose(summary.rms_mm, rms_point_error(captured, reconstructed), rtol=1e-10)


def test_summary_from_a_chunked_reconstruction_equals_the_whole_one():
    rng = np.random.default_rng(8)
    neutral = rng.normal(50.0, 20.0, 30)
    captured = rng.normal(0.0, 2.0, (1000, 30))
    reconstructed = captured + rng.normal(0.0, 0.3, captured.shape)
    whole = summarise_alpha(neutral, captured, reconstructed)
    chunked = summarise_alpha(neutral, captured, lambda rows: reconstructed[rows], chunk_frames=77)
    np.testing.assert_array_equal(whole.absolute_per_frame, chunked.absolute_per_frame)
    assert (whole.absolute_pooled, whole.displacement_mean, whole.rms_mm) == (
        chunked.absolute_pooled,
        chunked.displacement_mean,
        chunked.rms_mm,
    )


# ---------------------------------------------------------------------------------------------------------------
# The weights an animator would get, and the error as a distribution
# ---------------------------------------------------------------------------------------------------------------


def test_weight_statistics_of_a_known_weight_matrix():
    from workbench.numerics.metrics import weight_statistics

    # one second apart; shape 0 is w = t^2 (second derivative 2 everywhere), shape 1 jumps about
    seconds = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    weights = np.array([[0.0, 0.0], [1.0, 0.5], [4.0, 1.0], [9.0, -1.5], [16.0, 2.0]])
    stats = weight_statistics(weights, seconds)
    assert stats.max_abs == 16.0
    assert stats.outside_unit_share == 3 / 5  # frames 2 (4 > 1), 3 (9 and -1.5) and 4 (16 and 2)
    assert stats.negative_share == 1 / 5  # frame 3
    # second differences: shape 0: 2, 2, 2; shape 1: 1 - 1 + 0 = 0, -1.5 - 2 + 0.5 = -3, 2 + 3 + 1 = 6
    assert stats.roughness == (4.0 + 4.0 + 4.0 + 0.0 + 9.0 + 36.0) / 6
    # Hoyer (n = 2): (sqrt(2) - |w|_1 / |w|_2) / (sqrt(2) - 1) of frames 1-4; frame 0 (all zero) left out
    hoyer = [(np.sqrt(2) - np.abs(w).sum() / np.linalg.norm(w)) / (np.sqrt(2) - 1) for w in weights[1:]]
    np.testing.assert_allclose(stats.sparsity, np.mean(hoyer), rtol=1e-15)
    np.testing.assert_allclose(hoyer[1], (np.sqrt(2) - 5 / np.sqrt(17)) / (np.sqrt(2) - 1), rtol=1e-15)
    assert stats.sum_median == 5.0  # sums 0, 1.5, 5, 7.5, 18
    # the same weights with frame 3 in another take: no second difference spans the two takes
    split = weight_statistics(weights, np.array([0.0, 1.0, 2.0, 0.0, 1.0]), np.array(list("aaabb")))
    assert split.roughness == (4.0 + 0.0) / 2


def test_hoyer_sparsity_ends():
    from workbench.numerics.metrics import hoyer_sparsity

    values = hoyer_sparsity(np.array([[0.0, 3.0, 0.0], [1.0, -1.0, 1.0], [0.0, 0.0, 0.0]]))
    np.testing.assert_allclose(values[:2], [1.0, 0.0], atol=1e-15)
    assert np.isnan(values[2])


def test_hoyer_sparsity_leaves_out_a_frame_still_but_for_round_off():
    from workbench.numerics.metrics import STILL_WEIGHTS, hoyer_sparsity

    rng = np.random.default_rng(0)
    moving = rng.normal(size=(3, 4))
    still = 1e-15 * rng.normal(size=(1, 4))  # a neutral frame's weights: round-off of no motion
    slight = 1e3 * STILL_WEIGHTS * moving[:1]  # a frame moving 1.5e-5 as far as the first one: kept
    values = hoyer_sparsity(np.vstack([moving, still, slight, np.full((1, 4), np.nan)]))
    np.testing.assert_array_equal(values[:3], hoyer_sparsity(moving))
    assert np.isnan(values[3]) and np.isnan(values[5])
    assert values[4] == pytest.approx(values[0], rel=1e-12)


def test_second_derivative_uses_the_frame_times_and_never_spans_two_takes():
    from workbench.numerics.metrics import second_derivative

    # w = t^2 on uneven times: the three-point formula is exact for a parabola
    seconds = np.array([0.0, 0.5, 2.0, 2.25, 0.0, 1.0, 3.0])
    takes = np.array(["a", "a", "a", "a", "b", "b", "b"])
    values = (seconds**2)[:, None]
    result = second_derivative(values, seconds, takes)
    np.testing.assert_allclose(result, [[2.0], [2.0], [2.0]], rtol=1e-13)  # a: frames 1, 2; b: frame 5
    with pytest.raises(WorkbenchError, match="increase within each take"):
        second_derivative(values, seconds)  # one take: the time goes back


def test_error_distribution_and_rms_per_frame():
    from workbench.numerics.metrics import error_distribution, rms_error

    per_frame = rms_error(np.array([4.0, 16.0, 0.0, 1.0]), np.array([1, 4, 0, 1]))
    np.testing.assert_allclose(per_frame[[0, 1, 3]], [2.0, 2.0, 1.0])
    assert np.isnan(per_frame[2])
    found = error_distribution(np.arange(101.0))
    assert (found.median, found.p95, found.max) == (50.0, 95.0, 100.0)
    np.testing.assert_allclose(found.quantiles, np.arange(101.0))


def test_a_rank_deficient_basis_whose_nnls_equals_lstsq_needs_no_negative_weights():
    from workbench.numerics.metrics import needs_negative_share, weight_statistics
    from workbench.numerics.solve import solve_weights

    # e1, e2 and e1 + e2: rank 2 of 3. A frame 2 e1 (+ a part outside the span) has the least-squares minimum-norm
    # weights (4/3, -2/3, 2/3), negative, yet (2, 0, 0) reaches the same error without a negative weight
    rng = np.random.default_rng(0)
    e1, e2, outside = np.eye(6)[0], np.eye(6)[1], np.eye(6)[5]
    basis = np.vstack([e1, e2, e1 + e2])
    scale = rng.uniform(0.5, 2.0, 50)
    frames = scale[:, None] * (2.0 * e1) + rng.uniform(0.0, 0.1, 50)[:, None] * outside
    frames[::2] = scale[::2, None] * (2.0 * e1)  # half of them exactly in the span (errors of rounding size)
    lstsq, nnls = (solve_weights(basis, frames, kind=kind) for kind in ("lstsq", "nnls"))
    np.testing.assert_allclose(lstsq.weights[1], scale[1] * np.array([4, -2, 2]) / 3, rtol=1e-9)
    errors = [np.sum((frames - solution.weights @ basis) ** 2, axis=1) for solution in (lstsq, nnls)]
    assert weight_statistics(lstsq.weights, np.arange(50) / 120.0).negative_share == 1.0
    assert needs_negative_share(*errors, np.sum(frames**2, axis=1)) == 0.0
    # a frame that does need one: -e1 is reached by least squares only
    target = np.vstack([frames, -e1])
    lstsq, nnls = (solve_weights(basis, target, kind=kind) for kind in ("lstsq", "nnls"))
    errors = [np.sum((target - solution.weights @ basis) ** 2, axis=1) for solution in (lstsq, nnls)]
    assert needs_negative_share(*errors, np.sum(target**2, axis=1)) == 1 / 51


def test_point_norms_are_numpys_norms_bit_for_bit():
    """The lengths written out over the three coordinates add the squares in NumPy's order: the same numbers, for one
    point set, a stack of frames, and a strided view."""
    rng = np.random.default_rng(7)
    for flat in (rng.standard_normal(3 * 11), rng.standard_normal((40, 3 * 25)) * 1e3, rng.standard_normal((5, 8, 60))):
        expected = np.linalg.norm(flat.reshape(*flat.shape[:-1], -1, 3), axis=-1)
        assert np.array_equal(point_norms(flat), expected)
    frames = rng.standard_normal((30, 3 * 20))[::2]
    assert np.array_equal(point_norms(frames), np.linalg.norm(frames.reshape(15, 20, 3), axis=-1))
    assert point_norms(np.array([3.0, 4.0, 12.0, 0.0, 0.0, 0.0])).tolist() == [13.0, 0.0]
