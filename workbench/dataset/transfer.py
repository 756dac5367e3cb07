"""Move displacement fields (bases, frames) from one point set to another of the same face.

Bases fitted on one data variant (markers, say) are scored on another (the mesh) by carrying their shapes over.
The map is linear, a matrix ``T`` of shape (n_target, n_source) applied to each coordinate, chosen from the rest
positions alone:

- ``identity``: the two point sets are the same;
- ``coincident``: every target point is one of the source points (markers on mesh vertices), so ``T`` selects;
- ``rbf``: few source points (markers), so a thin-plate-spline RBF with a linear polynomial interpolates them
  onto the targets, as the markers of a capture are carried onto its mesh;
- ``nearest``: many source points that do not include every target (a decimated mesh and the markers), so each
  target takes its nearest source point; the largest distance is reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.dataset.rbf import rbf_operator

RBF_MAX_CENTRES = 500
"""Above this many source points the RBF system gets large and ``nearest`` is used instead."""
COINCIDENT_TOL_MM = 1e-6


@dataclass(frozen=True)
class PointTransfer:
    """A linear map of per-point values from a source point set to a target point set.

    Attributes
    ----------
    method : str
        ``identity``, ``coincident``, ``rbf`` or ``nearest``.
    operator : ndarray of shape (n_target, n_source) or None
        None for ``identity``.
    max_distance : float
        Largest distance from a target point to the source point it copies (``coincident`` and ``nearest``;
        0 otherwise), in data units.
    """

    method: str
    operator: np.ndarray | None
    max_distance: float = 0.0

    def apply(self, fields: np.ndarray) -> np.ndarray:
        """Carry fields over.

        Parameters
        ----------
        fields : ndarray of shape (n_fields, 3 * n_source)

        Returns
        -------
        ndarray of shape (n_fields, 3 * n_target)
        """
        if self.operator is None:
            return fields
        return apply_point_operator(self.operator, fields.reshape(len(fields), -1, 3)).reshape(len(fields), -1)

    def apply_one(self, field: np.ndarray) -> np.ndarray:
        """Carry one field of shape (3 * n_source,) over; returns shape (3 * n_target,)."""
        return self.apply(field[None, :])[0]

    def describe(self) -> str:
        extra = f", largest distance {self.max_distance:.2f} mm" if self.method == "nearest" else ""
        return f"{self.method}{extra}"


def apply_point_operator(operator: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``operator @ points[f]`` for every field ``f``, as one matrix product (a batched product of small
    matrices is many times slower for thousands of frames).

    Parameters
    ----------
    operator : ndarray of shape (n_target, n_source)
    points : ndarray of shape (n_fields, n_source, 3)

    Returns
    -------
    ndarray of shape (n_fields, n_target, 3)
    """
    n_fields, n_source, n_coordinates = points.shape
    stacked = np.transpose(points, (1, 0, 2)).reshape(n_source, n_fields * n_coordinates)
    return np.transpose((operator @ stacked).reshape(len(operator), n_fields, n_coordinates), (1, 0, 2))


def point_transfer(source: np.ndarray, target: np.ndarray, *, rbf_max_centres: int = RBF_MAX_CENTRES) -> PointTransfer:
    """Choose and build the map from values at ``source`` points to values at ``target`` points.

    Parameters
    ----------
    source : ndarray of shape (n_source, 3)
        Rest positions of the points the values are known at.
    target : ndarray of shape (n_target, 3)
        Rest positions of the points the values are wanted at, in the same coordinate frame.
    rbf_max_centres : int
        Use RBF interpolation only up to this many source points.

    Returns
    -------
    PointTransfer
    """
    from scipy.spatial import cKDTree

    source, target = np.asarray(source, dtype=np.float64), np.asarray(target, dtype=np.float64)
    if source.shape == target.shape and np.allclose(source, target, rtol=0.0, atol=COINCIDENT_TOL_MM):
        return PointTransfer(method="identity", operator=None)
    distance, nearest = cKDTree(source).query(target)
    selection = np.zeros((len(target), len(source)))
    selection[np.arange(len(target)), nearest] = 1.0
    if np.all(distance <= COINCIDENT_TOL_MM):
        return PointTransfer(method="coincident", operator=selection, max_distance=float(distance.max()))
    if len(source) <= rbf_max_centres:
        return PointTransfer(method="rbf", operator=rbf_operator(source, target, kernel="thin_plate_spline", degree=1))
    return PointTransfer(method="nearest", operator=selection, max_distance=float(distance.max()))
