"""Head-motion removal recovers known rigid transforms."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.core.errors import WorkbenchError
from workbench.dataset.rigid import kabsch, stabilise


def moved_markers(n_frames=50, seed=0):
    rng = np.random.default_rng(seed)
    reference = rng.standard_normal((7, 3)) * 80
    face = rng.standard_normal((20, 3)) * 60
    rotations = Rotation.from_rotvec(rng.standard_normal((n_frames, 3)) * 0.3).as_matrix()
    translations = rng.standard_normal((n_frames, 3)) * 10
    points = np.concatenate([face, reference])
    moved = np.einsum("fij,mj->fmi", rotations, points) + translations[:, None]
    return moved, reference, face, rotations, translations


def test_kabsch_recovers_the_inverse_motion():
    moved, reference, _, rotations, translations = moved_markers()
    found_r, found_t = kabsch(moved[:, 20:], reference)
    np.testing.assert_allclose(found_r, np.transpose(rotations, (0, 2, 1)), atol=1e-10)
    np.testing.assert_allclose(np.linalg.det(found_r), 1.0, atol=1e-12)
    np.testing.assert_allclose(found_t, -np.einsum("fji,fj->fi", rotations, translations), atol=1e-9)


def test_stabilise_puts_every_marker_back_with_zero_residual():
    moved, reference, face, _, _ = moved_markers()
    result = stabilise(moved, np.arange(20, 27), reference)
    np.testing.assert_allclose(result.markers[:, :20], np.broadcast_to(face, (50, 20, 3)), atol=1e-9)
    np.testing.assert_allclose(result.residual_rms, 0.0, atol=1e-9)


def test_stabilise_residual_reports_noise():
    moved, reference, _, _, _ = moved_markers(n_frames=400)
    noisy = moved + np.random.default_rng(1).normal(0, 0.5, moved.shape)
    residual = stabilise(noisy, np.arange(20, 27), reference).residual_rms
    # Fitting 6 rigid parameters to 21 noisy coordinates leaves sqrt(15/21) of the noise per coordinate.
    assert np.mean(residual**2) == pytest.approx(3 * 0.25 * 15 / 21, rel=0.1)


def test_stabilise_needs_three_rigid_markers():
    moved, reference, *_ = moved_markers()
    with pytest.raises(WorkbenchError, match="at least 3 rigid markers"):
        stabilise(moved, [20, 21], reference[:2])
