"""Intuitiveness, the one home of it: how far each quasi-eigen face moved from its hand shape
(:func:`intuitiveness`), and for any basis, measured rather than asserted, how close its elements stay to the hand
shapes, how local each element is on the face, and how many elements a typical frame uses.

Pure numerical code: arrays in, arrays out. Shapes are rows of arrays of shape ``(n_elements, 3 * n_points)``.
"""

from __future__ import annotations

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.numerics.validation import FRAMES, check_matrix

LOCALITY_ENERGY = 0.9
"""Locality is the fraction of the face's area that holds this fraction of an element's squared displacement."""
USAGE_THRESHOLD = 0.1
"""An element is used in a frame when its contribution exceeds this fraction of the frame's largest one."""


def matched_closeness(basis: np.ndarray, hand: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Optimal one-to-one matching of basis elements to hand shapes by ``|cosine|`` (Hungarian method).

    ``|cosine|`` ignores each element's sign and scale, which several bases leave arbitrary (PCA, ICA); the
    relative distance after the optimal scale, ``min_s |s e - h| / |h| = sqrt(1 - cos^2)``, is a function of it
    and adds nothing.

    Parameters
    ----------
    basis : ndarray of shape (n_elements, n_dims)
    hand : ndarray of shape (n_shapes, n_dims)

    Returns
    -------
    element_index, hand_index : ndarray of int, shape (n_matched,)
        Matched pairs, ``n_matched = min(n_elements, n_shapes)``, sorted by ``hand_index``.
    abs_cosine : ndarray of shape (n_matched,)
        ``|cos|`` of each pair (1: the same shape up to scale and sign; 0: orthogonal).
    """
    from scipy.optimize import linear_sum_assignment

    def unit(rows):
        norms = np.linalg.norm(rows, axis=1, keepdims=True)
        return np.divide(rows, norms, out=np.zeros_like(rows), where=norms > 0)

    similarity = np.abs(unit(np.asarray(basis, float)) @ unit(np.asarray(hand, float)).T)
    element_index, hand_index = linear_sum_assignment(similarity, maximize=True)
    order = np.argsort(hand_index)
    element_index, hand_index = element_index[order], hand_index[order]
    return element_index, hand_index, similarity[element_index, hand_index]


def point_areas(neutral: np.ndarray, faces: np.ndarray | None = None) -> np.ndarray:
    """Area each point stands for: a third of each adjacent triangle's area on a mesh, equal for markers.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_points,)
    faces : ndarray of shape (n_faces, 3) of int, or None

    Returns
    -------
    ndarray of shape (n_points,)
        Sums to 1.
    """
    points = np.asarray(neutral, dtype=np.float64).reshape(-1, 3)
    if faces is None:
        return np.full(len(points), 1.0 / len(points))
    faces = np.asarray(faces)
    corners = points[faces]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    areas = np.bincount(faces.ravel(), weights=np.repeat(area / 3.0, 3), minlength=len(points))
    return areas / areas.sum()


def locality(basis: np.ndarray, areas: np.ndarray, energy: float = LOCALITY_ENERGY) -> np.ndarray:
    """Fraction of the face's area holding ``energy`` of each element's squared displacement.

    The element's energy is ``sum_j a_j |e_j|^2`` (``a_j`` the area of point ``j``, ``e_j`` its 3-D
    displacement), the discrete ``integral |e|^2 dA``; the smallest area holding a fraction ``energy`` of it is
    taken by adding points in order of decreasing ``|e_j|^2`` until the fraction is reached (the point that
    reaches it counted whole). Small is local: an element moving one marker of 66 equally has 1/66.

    Parameters
    ----------
    basis : ndarray of shape (n_elements, 3 * n_points)
    areas : ndarray of shape (n_points,)
        From :func:`point_areas`.
    energy : float
        In (0, 1].

    Returns
    -------
    ndarray of shape (n_elements,)
        In (0, 1]; NaN for an all-zero element.
    """
    if not 0.0 < energy <= 1.0:
        raise WorkbenchError(f"energy must be in (0, 1], got {energy}")
    areas = np.asarray(areas, dtype=np.float64)
    squared = (np.asarray(basis, dtype=np.float64).reshape(len(basis), -1, 3) ** 2).sum(axis=2)
    order = np.argsort(-squared, axis=1, kind="stable")
    density = np.take_along_axis(squared, order, axis=1)
    cumulative = np.cumsum(density * areas[order], axis=1)
    total = cumulative[:, -1]
    result = np.full(len(basis), np.nan)
    for i in np.flatnonzero(total > 0):
        # first point whose cumulative energy reaches the fraction (a relative slack for round-off)
        count = int(np.searchsorted(cumulative[i], energy * total[i] * (1 - 1e-12))) + 1
        result[i] = areas[order[i, :count]].sum() / areas.sum()
    return result


def usage(weights: np.ndarray, basis: np.ndarray, threshold: float = USAGE_THRESHOLD) -> np.ndarray:
    """Number of elements each frame uses: those whose contribution ``|w_i| |e_i|`` exceeds ``threshold``
    times the frame's largest contribution.

    The contribution is the length of the displacement an element adds (``|w_i e_i|``), so the count does not
    depend on how each element is scaled. Frames with no contribution at all use 0 elements.

    Parameters
    ----------
    weights : ndarray of shape (n_frames, n_elements)
    basis : ndarray of shape (n_elements, n_dims)
    threshold : float
        In [0, 1).

    Returns
    -------
    ndarray of shape (n_frames,) of int
    """
    if not 0.0 <= threshold < 1.0:
        raise WorkbenchError(f"threshold must be in [0, 1), got {threshold}")
    contribution = np.abs(np.asarray(weights, dtype=np.float64)) * np.linalg.norm(basis, axis=1)
    largest = contribution.max(axis=1, keepdims=True)
    return np.where(largest[:, 0] > 0, (contribution > threshold * largest).sum(axis=1), 0)


def intuitiveness(hand: np.ndarray, quasi_eigen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far each quasi-eigen face moved from its hand shape.

    Parameters
    ----------
    hand : ndarray of shape (n_shapes, n_dims)
        Hand-made shapes ``e_i^H`` (displacements).
    quasi_eigen : ndarray of shape (n_shapes, n_dims)
        Their quasi-eigen faces ``e_i^QE``, in the same order.

    Returns
    -------
    relative_distance : ndarray of shape (n_shapes,)
        ``|e_i^QE - e_i^H| / |e_i^H|`` (0 = unchanged).
    cosine : ndarray of shape (n_shapes,)
        ``e_i^QE . e_i^H / (|e_i^QE| |e_i^H|)`` (1 = same direction).
    """
    hand = check_matrix("hand", hand, FRAMES, finite=False)
    quasi_eigen = check_matrix("quasi_eigen", quasi_eigen, FRAMES, finite=False)
    if quasi_eigen.shape != hand.shape:
        raise WorkbenchError(
            f"quasi_eigen has shape {quasi_eigen.shape}, but hand has {hand.shape}; one quasi-eigen face per hand shape"
        )
    hand_norm = np.linalg.norm(hand, axis=1)
    if not np.all(hand_norm > 0):
        raise WorkbenchError(
            f"hand shape(s) {np.flatnonzero(~(hand_norm > 0)).tolist()} are all zero or not finite; "
            "their distance to a quasi-eigen face is undefined"
        )
    qe_norm = np.linalg.norm(quasi_eigen, axis=1)
    relative_distance = np.linalg.norm(quasi_eigen - hand, axis=1) / hand_norm
    cosine = np.einsum("ij,ij->i", hand, quasi_eigen) / (hand_norm * qe_norm)
    return relative_distance, cosine
