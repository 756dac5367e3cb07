"""Known-answer tests of eq. 6 in both normalisations, the RMS error and the intuitiveness measure."""

import numpy as np
import pytest

from workbench.metrics import alpha_per_frame, alpha_pooled, intuitiveness, rms_point_error, summarise_alpha


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
    np.testing.assert_allclose(summary.absolute_per_frame,
                               alpha_per_frame(neutral + captured, neutral + reconstructed), rtol=1e-10)
    np.testing.assert_allclose(summary.displacement_per_frame, alpha_per_frame(captured, reconstructed),
                               rtol=1e-10)
    assert np.isnan(summary.displacement_per_frame[3]) and summary.n_undefined_displacement_frames == 1
    np.testing.assert_allclose(summary.absolute_pooled,
                               alpha_pooled(neutral + captured, neutral + reconstructed), rtol=1e-10)
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
    assert (whole.absolute_pooled, whole.displacement_mean, whole.rms_mm) == \
           (chunked.absolute_pooled, chunked.displacement_mean, chunked.rms_mm)
