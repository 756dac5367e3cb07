"""Marker-to-mesh interpolation with radial basis functions, by Euclidean or geodesic distance.

The interpolant is linear in the marker values, so it is computed once as a matrix ``A`` of shape
``(n_targets, n_markers)``: the displacement field of a frame at the targets is ``A @ marker_displacements``, and
every frame of a take is one matrix product. With the Euclidean metric ``A`` is SciPy's ``RBFInterpolator``
evaluated on the identity (one displacement field per marker); with the geodesic metric, distances along the mesh
(Dijkstra on its edges) replace Euclidean ones in the same kernels, so that, e.g., upper-lip markers do not drag
the lower lip across the mouth opening.
"""

from __future__ import annotations

from itertools import combinations_with_replacement

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.numerics.mesh_graph import mesh_edge_graph
from workbench.settings.rules import RBF_KERNELS, RBF_METRICS, RBF_SCALE_INVARIANT, checked, integer, interval, one_of

KERNELS = {
    "linear": lambda r: -r,
    "thin_plate_spline": lambda r: np.where(r > 0, r**2 * np.log(np.where(r > 0, r, 1.0)), 0.0),
    "cubic": lambda r: r**3,
    "quintic": lambda r: -(r**5),
    "multiquadric": lambda r: -np.sqrt(r**2 + 1.0),
    "inverse_multiquadric": lambda r: 1.0 / np.sqrt(r**2 + 1.0),
    "inverse_quadratic": lambda r: 1.0 / (r**2 + 1.0),
    "gaussian": lambda r: np.exp(-(r**2)),
}
"""SciPy ``RBFInterpolator``'s kernels of ``r = epsilon * distance``, with its signs (named by
:data:`workbench.settings.rules.RBF_KERNELS`)."""


def rbf_epsilon(epsilon: float | None) -> float:
    """The shape parameter an interpolation uses: ``epsilon``, or 1 when not given (a scale-invariant kernel,
    :data:`workbench.settings.rules.RBF_SCALE_INVARIANT`, which needs none)."""
    return 1.0 if epsilon is None else float(epsilon)


def check_rbf_settings(kernel: str, epsilon: float | None, degree: int, smoothing: float, metric: str) -> float:
    """Validate RBF settings and return the epsilon to use (:func:`rbf_epsilon`)."""
    checked(kernel, "rbf.kernel", one_of(*RBF_KERNELS))
    checked(metric, "rbf.metric", one_of(*RBF_METRICS))
    if epsilon is None and kernel not in RBF_SCALE_INVARIANT:
        raise WorkbenchError(f"rbf.epsilon must be set for the {kernel} kernel (a shape parameter in 1/mm)")
    epsilon = rbf_epsilon(epsilon)
    checked(epsilon, "rbf.epsilon", interval(0, low_open=True))
    checked(smoothing, "rbf.smoothing", interval(0))
    checked(degree, "rbf.degree", integer(-1, 2, whole_floats=True))
    return float(epsilon)


def monomials(points: np.ndarray, degree: int, shift: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Monomials of degree <= ``degree`` of the shifted and scaled coordinates (SciPy's polynomial tail).

    Returns
    -------
    ndarray of shape (n_points, n_monomials)
    """
    if degree < 0:
        return np.empty((len(points), 0))
    scaled = (points - shift) / scale
    columns = [np.ones(len(points))]
    for order in range(1, degree + 1):
        for axes in combinations_with_replacement(range(points.shape[1]), order):
            columns.append(np.prod(scaled[:, list(axes)], axis=1))
    return np.stack(columns, axis=1)


def rbf_operator(
    centres: np.ndarray,
    targets: np.ndarray,
    *,
    kernel: str = "thin_plate_spline",
    smoothing: float = 0.0,
    epsilon: float | None = None,
    degree: int = 1,
    centre_distances: np.ndarray | None = None,
    target_distances: np.ndarray | None = None,
) -> np.ndarray:
    """The linear map from values at the centres to the RBF interpolant's values at the targets.

    Parameters
    ----------
    centres : ndarray of shape (n_centres, 3)
        Where the values are known (marker positions on the mesh).
    targets : ndarray of shape (n_targets, 3)
        Where the interpolant is evaluated (mesh vertices).
    kernel, smoothing, epsilon, degree
        As SciPy's ``RBFInterpolator`` (``smoothing`` 0 interpolates exactly).
    centre_distances : ndarray of shape (n_centres, n_centres), optional
        Distances between centres by another metric (geodesic); Euclidean (SciPy) when None.
    target_distances : ndarray of shape (n_targets, n_centres), optional
        Distances from each target to each centre by the same metric; required with ``centre_distances``.

    Returns
    -------
    ndarray of shape (n_targets, n_centres)
        ``values_at_targets = operator @ values_at_centres`` for any number of value columns.
    """
    metric = "euclidean" if centre_distances is None else "geodesic"
    epsilon = check_rbf_settings(kernel, epsilon, degree, smoothing, metric)
    return _rbf_matrix(
        centres,
        targets,
        kernel=kernel,
        smoothing=smoothing,
        epsilon=epsilon,
        degree=degree,
        centre_distances=centre_distances,
        target_distances=target_distances,
    )


def _rbf_matrix(
    centres: np.ndarray,
    targets: np.ndarray,
    *,
    kernel: str,
    smoothing: float,
    epsilon: float,
    degree: int,
    centre_distances: np.ndarray | None = None,
    target_distances: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`rbf_operator` of settings already checked (:func:`check_rbf_settings`; ``epsilon`` as it returns)."""
    centres, targets = np.asarray(centres, dtype=np.float64), np.asarray(targets, dtype=np.float64)
    n_centres = len(centres)
    if centre_distances is None:
        from scipy.interpolate import RBFInterpolator

        try:
            interpolator = RBFInterpolator(
                centres, np.eye(n_centres), kernel=kernel, smoothing=smoothing, epsilon=epsilon, degree=degree
            )
        except (ValueError, np.linalg.LinAlgError) as error:
            raise WorkbenchError(f"RBF interpolation is not solvable for these markers ({error})") from None
        return interpolator(targets)
    if target_distances is None or target_distances.shape != (len(targets), n_centres):
        raise WorkbenchError(f"target_distances must have shape ({len(targets)}, {n_centres})")
    phi = KERNELS[kernel]
    low, high = centres.min(axis=0), centres.max(axis=0)
    shift, scale = (low + high) / 2, np.where(high > low, (high - low) / 2, 1.0)
    poly_centres = monomials(centres, degree, shift, scale)
    n_poly = poly_centres.shape[1]
    system = np.zeros((n_centres + n_poly, n_centres + n_poly))
    system[:n_centres, :n_centres] = phi(epsilon * centre_distances) + smoothing * np.eye(n_centres)
    system[:n_centres, n_centres:] = poly_centres
    system[n_centres:, :n_centres] = poly_centres.T
    right = np.zeros((n_centres + n_poly, n_centres))
    right[:n_centres] = np.eye(n_centres)
    try:
        coefficients = np.linalg.solve(system, right)
    except np.linalg.LinAlgError:
        raise WorkbenchError(
            f"geodesic RBF system is singular: markers share vertices or are too few for the degree-{degree} polynomial"
        ) from None
    evaluation = np.concatenate([phi(epsilon * target_distances), monomials(targets, degree, shift, scale)], axis=1)
    return evaluation @ coefficients


def geodesic_distances(vertices: np.ndarray, triangles: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """Shortest-path distances along the mesh's edges from source vertices to every vertex (Dijkstra).

    Edge paths overestimate the true surface geodesic by a few percent on a regular mesh; the RBF only needs
    distances that do not cut across openings such as the mouth.

    Parameters
    ----------
    vertices : ndarray of shape (n_vertices, 3)
    triangles : ndarray of shape (n_triangles, 3) of int
    sources : ndarray of shape (n_sources,) of int

    Returns
    -------
    ndarray of shape (n_sources, n_vertices)
        ``inf`` where a vertex is not connected to the source.
    """
    from scipy.sparse.csgraph import dijkstra

    return dijkstra(mesh_edge_graph(vertices, triangles), directed=False, indices=np.asarray(sources))


def mesh_rbf_operator(
    vertices: np.ndarray,
    triangles: np.ndarray | None,
    centre_vertices: np.ndarray,
    target_vertices: np.ndarray,
    *,
    metric: str = "euclidean",
    kernel: str = "thin_plate_spline",
    smoothing: float = 0.0,
    epsilon: float | None = None,
    degree: int = 1,
) -> np.ndarray:
    """RBF map from values at some mesh vertices (the markers) to values at others (the targets).

    Parameters
    ----------
    vertices : ndarray of shape (n_vertices, 3)
    triangles : ndarray of shape (n_triangles, 3) of int, or None
        Needed for ``metric="geodesic"``.
    centre_vertices : ndarray of shape (n_centres,) of int
        Distinct vertices carrying the known values.
    target_vertices : ndarray of shape (n_targets,) of int
    metric : {"euclidean", "geodesic"}
    kernel, smoothing, epsilon, degree
        See :func:`rbf_operator`.

    Returns
    -------
    ndarray of shape (n_targets, n_centres)
    """
    epsilon = check_rbf_settings(kernel, epsilon, degree, smoothing, metric)
    return mesh_rbf_matrix(
        vertices,
        triangles,
        centre_vertices,
        target_vertices,
        metric=metric,
        kernel=kernel,
        smoothing=smoothing,
        epsilon=epsilon,
        degree=degree,
    )


def mesh_rbf_matrix(
    vertices: np.ndarray,
    triangles: np.ndarray | None,
    centre_vertices: np.ndarray,
    target_vertices: np.ndarray,
    *,
    metric: str,
    kernel: str,
    smoothing: float,
    epsilon: float,
    degree: int,
) -> np.ndarray:
    """:func:`mesh_rbf_operator` of settings already checked (:func:`check_rbf_settings`, whose ``epsilon`` it
    takes): what the workbench's own interpolations call with settings it states itself."""
    centre_vertices, target_vertices = np.asarray(centre_vertices), np.asarray(target_vertices)
    if len(np.unique(centre_vertices)) != len(centre_vertices):
        values, counts = np.unique(centre_vertices, return_counts=True)
        raise WorkbenchError(
            f"RBF centres must be distinct vertices; vertex(es) {values[counts > 1].tolist()} "
            "carry more than one marker"
        )
    centres, targets = vertices[centre_vertices], vertices[target_vertices]
    options = dict(kernel=kernel, smoothing=smoothing, epsilon=epsilon, degree=degree)
    if metric == "euclidean":
        return _rbf_matrix(centres, targets, **options)
    if triangles is None or len(triangles) == 0:
        raise WorkbenchError("rbf.metric geodesic needs the mesh's polygons, and this mesh has none")
    distances = geodesic_distances(vertices, triangles, centre_vertices)
    unreachable = ~np.isfinite(distances[:, target_vertices])
    if unreachable.any():
        centre, target = np.argwhere(unreachable)[0]
        raise WorkbenchError(
            f"geodesic RBF: vertex {int(target_vertices[target])} is not connected to marker vertex "
            f"{int(centre_vertices[centre])} on the mesh ({int(unreachable.any(axis=0).sum())} "
            "such vertices); use rbf.metric=euclidean or a connected region"
        )
    return _rbf_matrix(
        centres,
        targets,
        centre_distances=distances[:, centre_vertices],
        target_distances=distances[:, target_vertices].T,
        **options,
    )


def interpolate_frames(operator: np.ndarray, marker_displacements: np.ndarray) -> np.ndarray:
    """Apply an RBF operator to every frame at once.

    Parameters
    ----------
    operator : ndarray of shape (n_targets, n_markers)
    marker_displacements : ndarray of shape (n_frames, n_markers, 3)

    Returns
    -------
    ndarray of shape (n_frames, n_targets, 3)
    """
    n_frames, n_markers, _ = marker_displacements.shape
    # One matrix product over all frames and coordinates (a batched product per frame is many times slower).
    stacked = np.ascontiguousarray(marker_displacements.transpose(1, 0, 2)).reshape(n_markers, -1)
    fields = (operator @ stacked).reshape(len(operator), n_frames, 3)
    return np.ascontiguousarray(fields.transpose(1, 0, 2))
