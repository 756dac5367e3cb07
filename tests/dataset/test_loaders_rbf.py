"""Marker-to-mesh RBF interpolation: SciPy agreement, exact reproduction at the markers, geodesic distances."""

from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import RBFInterpolator
from scipy.spatial.distance import cdist

from workbench.core.errors import WorkbenchError
from workbench.dataset.rbf import geodesic_distances, interpolate_frames, mesh_rbf_operator, rbf_operator


def sheet(n=20, spacing=5.0, gap_rows=()):
    """A flat n x n grid of vertices (mm) and its triangles; rows in ``gap_rows`` are not joined to the next row
    (a slit, like the mouth opening between the lips)."""
    x, y = np.meshgrid(np.arange(n) * spacing, np.arange(n) * spacing)
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    triangles = []
    for row in range(n - 1):
        if row in gap_rows:
            continue
        for col in range(n - 1):
            a, b, c, d = row * n + col, row * n + col + 1, (row + 1) * n + col, (row + 1) * n + col + 1
            triangles += [[a, b, d], [a, d, c]]
    return vertices, np.array(triangles)


def slit_sheet(n=20):
    """A sheet whose rows 9 and 10 are joined only at the right end: a slit from the left edge to near the right."""
    vertices, triangles = sheet(n, gap_rows=(9,))
    a, b, c, d = 9 * n + n - 2, 9 * n + n - 1, 10 * n + n - 2, 10 * n + n - 1
    return vertices, np.concatenate([triangles, [[a, b, d], [a, d, c]]])


@pytest.mark.parametrize(
    "kernel,epsilon,degree",
    [("thin_plate_spline", None, 1), ("gaussian", 0.05, 1), ("inverse_multiquadric", 0.05, 0), ("linear", None, 0)],
)
def test_operator_is_scipy_rbf_and_the_distance_route_agrees(kernel, epsilon, degree):
    rng = np.random.default_rng(0)
    centres, targets = rng.normal(size=(25, 3)) * 40, rng.normal(size=(300, 3)) * 40
    values = rng.normal(size=(25, 6))  # six displacement fields at once
    expected = RBFInterpolator(centres, values, kernel=kernel, epsilon=epsilon or 1.0, degree=degree)(targets)
    operator = rbf_operator(centres, targets, kernel=kernel, epsilon=epsilon, degree=degree)
    np.testing.assert_allclose(operator @ values, expected, atol=1e-8)
    by_distance = rbf_operator(
        centres,
        targets,
        kernel=kernel,
        epsilon=epsilon,
        degree=degree,
        centre_distances=cdist(centres, centres),
        target_distances=cdist(targets, centres),
    )
    np.testing.assert_allclose(by_distance @ values, expected, atol=1e-8)


@pytest.mark.parametrize("metric", ["euclidean", "geodesic"])
def test_rbf_reproduces_marker_displacements_at_the_markers(metric):
    vertices, triangles = sheet()
    markers = np.array([0, 19, 380, 399, 105, 210, 250, 333, 66, 144])
    displacements = np.random.default_rng(1).normal(size=(7, len(markers), 3))
    operator = mesh_rbf_operator(
        vertices,
        triangles,
        markers,
        np.arange(len(vertices)),
        metric=metric,
        kernel="inverse_multiquadric",
        epsilon=0.05,
        degree=0,
    )
    field = interpolate_frames(operator, displacements)
    assert field.shape == (7, 400, 3)
    np.testing.assert_allclose(field[:, markers], displacements, atol=1e-9)


def test_geodesic_distance_goes_around_a_slit():
    vertices, triangles = slit_sheet()
    n = 20
    below, above = 9 * n + 2, 10 * n + 2
    distance = geodesic_distances(vertices, triangles, np.array([below]))[0]
    assert np.linalg.norm(vertices[below] - vertices[above]) == pytest.approx(5.0)
    assert distance[above] > 150.0  # around the end of the slit and back
    assert distance[below + 1] == pytest.approx(5.0)


def test_geodesic_rbf_keeps_the_two_sides_of_a_slit_apart():
    """A marker above the slit moving up must not drag the vertices just below it (as Euclidean RBF does)."""
    n = 20
    vertices, triangles = slit_sheet(n)
    above, below = 11 * n + 8, 8 * n + 8
    markers = np.array([above, below, 0, 19, 380, 399])
    displacement = np.zeros((1, len(markers), 3))
    displacement[0, 0, 1] = 10.0  # the marker above the slit moves up 10 mm, the others stay
    just_below = 9 * n + 8
    moved = {}
    for metric in ("euclidean", "geodesic"):
        operator = mesh_rbf_operator(
            vertices,
            triangles,
            markers,
            np.array([just_below]),
            metric=metric,
            kernel="inverse_multiquadric",
            epsilon=0.05,
            degree=0,
        )
        moved[metric] = np.linalg.norm(interpolate_frames(operator, displacement)[0, 0])
    assert moved["geodesic"] < 0.5 * moved["euclidean"]


def test_rbf_setting_errors():
    vertices, triangles = sheet(n=5)
    with pytest.raises(WorkbenchError, match="rbf.kernel must be one of"):
        mesh_rbf_operator(vertices, triangles, np.array([0, 4, 20]), np.arange(25), kernel="spline")
    with pytest.raises(WorkbenchError, match="rbf.epsilon must be set for the gaussian kernel"):
        mesh_rbf_operator(vertices, triangles, np.array([0, 4, 20]), np.arange(25), kernel="gaussian")
    with pytest.raises(WorkbenchError, match=r"vertex\(es\) \[4\] carry more than one marker"):
        mesh_rbf_operator(vertices, triangles, np.array([0, 4, 4]), np.arange(25))
    with pytest.raises(WorkbenchError, match="rbf.metric must be one of"):
        mesh_rbf_operator(vertices, triangles, np.array([0, 4, 20]), np.arange(25), metric="manhattan")
    apart = np.concatenate([triangles, [[25, 26, 27]]])
    far = np.concatenate([vertices, [[100, 100, 0], [101, 100, 0], [100, 101, 0]]])
    with pytest.raises(WorkbenchError, match="geodesic RBF: vertex 25 is not connected to marker vertex 0"):
        mesh_rbf_operator(
            far,
            apart,
            np.array([0, 4, 20]),
            np.arange(28),
            metric="geodesic",
            kernel="inverse_multiquadric",
            epsilon=0.05,
        )


def test_the_rbf_settings_have_one_set_of_defaults():
    """The settings name every kernel the interpolation has; an AnimFace dataset group without ``rbf`` takes the
    schema's defaults, and the shipped config's choice (a constant tail) is what its group says."""
    from omegaconf import OmegaConf

    from workbench.dataset.rbf import KERNELS
    from workbench.settings.rules import RBF_KERNELS, RBF_SCALE_INVARIANT
    from workbench.settings.schema import RbfSchema, check_dataset_group
    from workbench.settings.typed import DATASET_SETTINGS, typed

    assert sorted(KERNELS) == list(RBF_KERNELS) and set(RBF_SCALE_INVARIANT) <= set(KERNELS)
    assert typed(DATASET_SETTINGS["animface"], {"kind": "animface"}).rbf == RbfSchema()
    shipped = OmegaConf.to_container(OmegaConf.load(Path(__file__).parents[2] / "conf" / "dataset" / "animface.yaml"))[
        "rbf"
    ]
    rbf = typed(RbfSchema, shipped)
    assert (rbf.metric, rbf.kernel, rbf.epsilon, rbf.smoothing, rbf.degree) == (
        "geodesic",
        "inverse_multiquadric",
        0.05,
        0.0,
        0,
    )
    with pytest.raises(WorkbenchError, match="dataset.rbf.epsilon must be set for the gaussian kernel"):
        check_dataset_group({"kind": "animface", "rbf": {"kernel": "gaussian"}})
