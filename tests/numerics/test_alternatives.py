"""Other bases beside the quasi-eigen faces, each on data with a known answer, and the intuitiveness measures on
hand-computed cases."""

import numpy as np
import pytest

from workbench.core.errors import WorkbenchError
from workbench.numerics.alternatives import (
    SurfaceDistance,
    fitted_hand_basis,
    ica_basis,
    leading_svd,
    nmf_basis,
    sparse_pca_basis,
    splocs_basis,
    support_map,
    unit_activation,
)
from workbench.numerics.intuitiveness import locality, matched_closeness, point_areas, usage


def best_abs_cosines(found, planted):
    """|cosine| of each planted shape with the found shape matched to it (Hungarian)."""
    element, hand, cosine = matched_closeness(found, planted)
    assert hand.tolist() == list(range(len(planted)))
    return cosine


def block_shapes(rng, n_shapes, n_points, width):
    """Shapes each moving its own block of ``width`` points (disjoint supports), random signed directions."""
    shapes = np.zeros((n_shapes, n_points, 3))
    for k in range(n_shapes):
        shapes[k, k * width : (k + 1) * width] = rng.normal(size=(width, 3))
    return shapes.reshape(n_shapes, -1)


# --- known answers ------------------------------------------------------------------------------------------


def test_sparse_pca_recovers_planted_sparse_components():
    rng = np.random.default_rng(0)
    planted = block_shapes(rng, 4, 40, 6)  # 4 shapes, each non-zero on 18 of 120 coordinates
    planted /= np.linalg.norm(planted, axis=1, keepdims=True)
    frames = rng.normal(size=(400, 4)) @ planted  # equal variances: PCA's axes are any rotation of the shapes
    found = sparse_pca_basis(frames, n_components=4, alpha=0.05)
    assert np.all(best_abs_cosines(found, planted) > 0.99)
    # off their planted blocks the found shapes are (almost) exactly zero
    element, _, _ = matched_closeness(found, planted)
    outside = planted == 0
    assert np.all(np.abs(found[element][outside]) < 1e-6 * np.abs(found).max())
    # plain PCA of the same data mixes the blocks: the test can fail
    _, _, vt = leading_svd(frames, 4)
    assert best_abs_cosines(vt, planted).min() < 0.9


def test_ica_recovers_planted_independent_sources():
    rng = np.random.default_rng(1)
    planted = rng.normal(size=(4, 60)) + 1.5 * rng.normal(size=60)  # dense shapes sharing a common part
    sources = np.column_stack(
        [rng.laplace(size=2000), rng.uniform(-1, 1, 2000), rng.laplace(size=2000) ** 3, np.sign(rng.normal(size=2000))]
    )
    sources /= sources.std(axis=0)
    found = ica_basis(sources @ planted, n_components=4, seed=0)
    assert np.all(best_abs_cosines(found, planted) > 0.99)
    _, _, vt = leading_svd(sources @ planted, 4)
    assert best_abs_cosines(vt, planted).min() < 0.9


def test_nmf_recovers_planted_signed_parts_with_non_negative_weights():
    rng = np.random.default_rng(2)
    planted = block_shapes(rng, 5, 50, 8)  # signed displacements, each part on its own points
    weights = rng.exponential(size=(600, 5)) * (rng.uniform(size=(600, 5)) < 0.5)
    found = nmf_basis(weights @ planted, n_components=5, seed=0)
    assert np.all(best_abs_cosines(found, planted) > 0.99)
    # oriented so that the parts are switched on by non-negative weights
    element, _, _ = matched_closeness(found, planted)
    assert np.all(np.einsum("ij,ij->i", found[element], planted) > 0)


def grid_face(rows=14, cols=14, spacing=10.0):
    """A flat triangulated grid as a face: neutral positions (3 * n_points,) and triangles."""
    y, x = np.mgrid[0:rows, 0:cols] * spacing
    points = np.column_stack([x.ravel(), y.ravel(), np.zeros(rows * cols)])
    index = np.arange(rows * cols).reshape(rows, cols)
    a, b, c, d = index[:-1, :-1].ravel(), index[:-1, 1:].ravel(), index[1:, :-1].ravel(), index[1:, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    return points.reshape(-1), faces


@pytest.mark.parametrize("on_mesh", [True, False])
def test_splocs_recovers_planted_local_components(on_mesh):
    rng = np.random.default_rng(3)
    neutral, faces = grid_face()
    points = neutral.reshape(-1, 3)
    centres = points[[15, 95, 180]]  # near three corners and the middle of the grid
    planted = []
    for centre, direction in zip(centres, ([0, 0, 1.0], [1.0, 0, 0.5], [0, -1.0, 0])):
        bump = np.exp(-np.sum((points - centre) ** 2, axis=1) / (2 * 12.0**2))
        planted.append((bump[:, None] * direction).reshape(-1))
    planted = np.array(planted)
    weights = rng.uniform(size=(300, 3)) * (rng.uniform(size=(300, 3)) < 0.6)
    distance = SurfaceDistance(neutral, faces if on_mesh else None)
    found = splocs_basis(weights @ planted, distance, n_components=3, sparsity_lambda=2.0)
    assert np.all(best_abs_cosines(found, planted) > 0.98)
    areas = point_areas(neutral, faces if on_mesh else None)
    assert np.nanmax(locality(found, areas)) < 0.12  # as local as the planted bumps
    # weights of the recovered components stay in [0, 1], the paper's constraint
    solved = np.linalg.lstsq(found.T, (weights @ planted).T, rcond=None)[0]
    assert solved.min() > -1e-3 and solved.max() < 1 + 1e-3


def test_support_map_and_distances():
    np.testing.assert_allclose(support_map(np.array([0.0, 0.1, 0.4, 0.7, 2.0]), 0.1, 0.7), [0, 0, 0.5, 1, 1])
    neutral, faces = grid_face(rows=3, cols=4, spacing=1.0)  # largest side 3
    on_mesh = SurfaceDistance(neutral, faces).from_point(0)
    euclidean = SurfaceDistance(neutral).from_point(0)
    assert on_mesh[3] == pytest.approx(1.0) and euclidean[3] == pytest.approx(1.0)  # 3 edges along the side
    # to the far corner the edge path runs along diagonals and sides, longer than the straight line
    assert euclidean[11] == pytest.approx(np.hypot(3, 2) / 3)
    assert on_mesh[11] == pytest.approx((2 * np.sqrt(2) + 1) / 3)


def test_fitted_hand_basis_recovers_a_basis_that_generated_the_data():
    rng = np.random.default_rng(4)
    generating = rng.normal(size=(6, 90))
    frames = rng.uniform(size=(500, 6)) @ generating
    # the shapes that generated the frames are a fixed point: returned exactly
    np.testing.assert_allclose(fitted_hand_basis(frames, generating), generating, rtol=0, atol=1e-9)
    # hand shapes sculpted with an error off the frames' span: the refit removes it to second order
    off = rng.normal(size=(6, 90))
    off -= off @ np.linalg.pinv(generating) @ generating  # orthogonal to the span of the generating shapes
    hand = generating + 1e-3 * off / np.linalg.norm(off, axis=1, keepdims=True) * np.linalg.norm(
        generating, axis=1, keepdims=True
    )
    refit = fitted_hand_basis(frames, hand, n_iterations=3)
    before = np.linalg.norm(hand - generating) / np.linalg.norm(generating)
    after = np.linalg.norm(refit - generating) / np.linalg.norm(generating)
    assert before == pytest.approx(1e-3, rel=1e-6) and after < 1e-5
    np.testing.assert_allclose(np.linalg.lstsq(refit.T, frames.T, rcond=None)[0].T @ refit, frames, atol=1e-9)


def test_unit_activation_orients_and_scales():
    rng = np.random.default_rng(5)
    shapes = rng.normal(size=(3, 30))
    weights = rng.uniform(0.1, 2.0, size=(200, 3))
    scaled = unit_activation(shapes * [[-2.0], [0.5], [3.0]], weights @ shapes)
    solved = np.linalg.lstsq(scaled.T, (weights @ shapes).T, rcond=None)[0].T
    np.testing.assert_allclose(solved.max(axis=0), 1.0)
    np.testing.assert_allclose(scaled, shapes * weights.max(axis=0)[:, None])


def test_alternatives_are_deterministic_and_check_their_input():
    rng = np.random.default_rng(6)
    frames = rng.normal(size=(80, 30)) @ rng.normal(size=(30, 30))
    np.testing.assert_array_equal(ica_basis(frames, n_components=5, seed=3), ica_basis(frames, n_components=5, seed=3))
    np.testing.assert_array_equal(sparse_pca_basis(frames, n_components=5), sparse_pca_basis(frames, n_components=5))
    with pytest.raises(WorkbenchError, match="n_components must be between 1 and"):
        nmf_basis(frames, n_components=31)
    with pytest.raises(WorkbenchError, match="d_min < d_max"):
        splocs_basis(frames, SurfaceDistance(np.zeros(30)), n_components=2, d_min=0.5, d_max=0.5)
    with pytest.raises(WorkbenchError, match="hand basis must have shape"):
        fitted_hand_basis(frames, np.zeros((3, 29)))


# --- intuitiveness measures, hand-computed ------------------------------------------------------------------


def test_matched_closeness_is_the_optimal_one_to_one_matching():
    hand = np.eye(3)[:2]  # h0 = e0, h1 = e1
    # |cos|: b0 -> (0.6, 0.5), b1 -> (0.5, 0.1); greedy takes (b0, h0) then (b1, h1), 0.7 in all; optimal is 1.0
    basis = np.array([[0.6, 0.5, np.sqrt(0.39)], [-0.5, 0.1, np.sqrt(0.74)]]) * [[2.0], [0.3]]
    element, hand_index, cosine = matched_closeness(basis, hand)
    assert element.tolist() == [1, 0] and hand_index.tolist() == [0, 1]
    np.testing.assert_allclose(cosine, [0.5, 0.5])
    # a permuted, rescaled, sign-flipped copy of the hand shapes matches back with |cos| 1
    shapes = np.random.default_rng(7).normal(size=(4, 12))
    element, hand_index, cosine = matched_closeness(-3.0 * shapes[[2, 0, 3, 1]], shapes)
    assert element.tolist() == [1, 3, 0, 2]
    np.testing.assert_allclose(cosine, 1.0)


def test_point_areas_of_a_square_and_of_markers():
    square = np.array([0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0], dtype=float)
    np.testing.assert_allclose(point_areas(square, np.array([[0, 1, 2], [0, 2, 3]])), [1 / 3, 1 / 6, 1 / 3, 1 / 6])
    np.testing.assert_allclose(point_areas(np.zeros(15)), 0.2)


def test_locality_hand_computed():
    areas = np.full(10, 0.1)
    one = np.zeros((10, 3))
    one[2] = [3.0, 0, 0]
    one[7] = [0, 1.0, 0]  # energies 9 and 1: the first point alone holds 90 %
    four = np.zeros((10, 3))
    four[:4, 2] = 1.0  # four equal points: three hold 75 %, so all four are needed
    np.testing.assert_allclose(locality(np.stack([one, four]).reshape(2, -1), areas), [0.1, 0.4])
    assert locality(np.stack([one, four]).reshape(2, -1), areas, energy=0.75)[1] == pytest.approx(0.3)
    # with areas the energy is area-weighted: a small patch moving strongly is local
    weighted = np.array([0.05, 0.05, 0.9])
    shape = np.array([[0, 0, 2.0, 0, 0, 2.0, 0, 0, 0.1]])  # energies 0.2, 0.2, 0.009
    assert locality(shape, weighted)[0] == pytest.approx(0.1)
    assert np.isnan(locality(np.zeros((1, 9)), weighted)[0])


def test_usage_hand_computed():
    basis = np.diag([1.0, 0.1, 10.0])
    weights = np.array(
        [
            [1.0, 0.5, 0.05],  # contributions 1, 0.05, 0.5: two above 0.1 x 1
            [0.0, 0.0, 0.0],  # nothing moves: no element used
            [0.2, -30.0, 0.02],
        ]
    )  # contributions 0.2, 3, 0.2: only the second above 0.3
    assert usage(weights, basis).tolist() == [2, 0, 1]
    assert usage(weights, basis, threshold=0.0).tolist() == [3, 0, 3]


def test_every_basis_of_the_table_has_its_fit_its_settings_and_their_defaults():
    """A basis is its fit and one entry of workbench.settings.bases: the settings' schema, the names
    basis.alternatives takes and the report's colours follow the table; conf/basis/default.yaml states the same
    option defaults as the entry's schema."""
    from dataclasses import asdict, fields

    import yaml

    from workbench.numerics.alternatives import FITS
    from workbench.reporting.figures.bases import BASIS_MARKERS, OTHER_BASIS_COLOURS
    from workbench.settings.bases import ALTERNATIVE_BASES
    from workbench.settings.config import CONF_DIR
    from workbench.settings.schema import ALTERNATIVE_NAMES, BasisSchema

    defaults = yaml.safe_load((CONF_DIR / "basis" / "default.yaml").read_text())
    schema_fields = {spec.name: spec for spec in fields(BasisSchema)}
    assert list(FITS) == list(ALTERNATIVE_BASES) == list(ALTERNATIVE_NAMES)
    for label, basis in ALTERNATIVE_BASES.items():
        assert schema_fields[basis.options_key].default_factory is basis.options
        assert defaults[basis.options_key] == asdict(basis.options()), label
        assert OTHER_BASIS_COLOURS[label] == basis.colour and BASIS_MARKERS[label] == basis.marker
