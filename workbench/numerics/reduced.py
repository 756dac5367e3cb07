"""One streamed pass over the evaluated frames that gives every basis what its weights (eq. 5) and alpha (eq. 6)
need, so that no basis reads the frames again and no reconstruction is ever formed.

Each basis is an affine subspace ``offset + span(U)`` with orthonormal columns ``U`` (the left singular vectors of
a hand or quasi-eigen basis, offset 0; the eigenfaces with the capture mean as offset). For a frame ``y`` the pass
keeps the coordinates ``q = U^T (y - offset)`` and the squared distance to the subspace,
``|y - offset - U q|^2``. The weights of eq. 5 are a function of ``q`` alone, and the error of any reconstruction
``offset + U a`` is ``|y - offset - U q|^2 + |q - a|^2``. The squared distance is taken as
``|y - offset|^2 - |q|^2`` from the pass's dot products, and recomputed from the explicit residual for the
frames where that difference cancels (distance below ``EXPLICIT_BELOW`` of the terms' size), so it is accurate
to rounding for every frame.

Given a part of the points (the face region, coordinates ``R``), the same pass also keeps, per subspace, the region's
part of the distance, ``|d_R|^2`` with ``d = y - offset - U q``, and ``U_R^T d_R``. The region's error of any
reconstruction ``offset + U a`` is then ``|U_R e + d_R|^2 = e^T U_R^T U_R e + 2 e.(U_R^T d_R) + |d_R|^2`` with
``e = q - a`` (:func:`region_error_sq`), so scoring the region reads the frames no second time.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from workbench.numerics.frames import frame_chunks

EXPLICIT_BELOW = 1e-4
"""Frames whose squared distance is below this fraction of ``|y|^2 + |offset|^2`` get the explicit residual."""


@dataclass(frozen=True)
class Subspace:
    """An affine subspace ``offset + span(columns)`` of frame space.

    Attributes
    ----------
    columns : ndarray of shape (n_dims, k)
        Orthonormal.
    offset : ndarray of shape (n_dims,) or None
        None for a linear subspace.
    """

    columns: np.ndarray
    offset: np.ndarray | None = None


@dataclass(frozen=True)
class FrameProjections:
    """What one pass over the frames keeps.

    Attributes
    ----------
    coordinates : dict
        Subspace label -> ndarray of shape (n_frames, k), ``U^T (y - offset)``.
    distance_sq : dict
        Subspace label -> ndarray of shape (n_frames,), ``|y - offset - U U^T (y - offset)|^2``.
    displacement_sq, position_sq : ndarray of shape (n_frames,)
        ``|y|^2`` and ``|v0 + y|^2`` (the references of eq. 6, as
        :func:`workbench.numerics.metrics.reference_squares`).
    n_explicit : int
        Frame-subspace pairs whose distance was recomputed from the explicit residual.
    region : RegionProjections or None
        The part of the points ``project_frames`` was given (None when it was given none).
    """

    coordinates: dict
    distance_sq: dict
    displacement_sq: np.ndarray
    position_sq: np.ndarray
    n_explicit: int
    region: "RegionProjections | None" = None


@dataclass(frozen=True)
class RegionProjections:
    """What the pass keeps of a part of the points, coordinates ``R``, per subspace ``offset + span(U)``.

    Attributes
    ----------
    distance_sq : dict
        Label -> ndarray of shape (n_frames,), ``|d_R|^2`` with ``d = y - offset - U q``.
    cross : dict
        Label -> ndarray of shape (n_frames, k), ``U_R^T d_R``.
    gram : dict
        Label -> ndarray of shape (k, k), ``U_R^T U_R``.
    """

    distance_sq: dict
    cross: dict
    gram: dict


def region_error_sq(region: RegionProjections, label: str, difference: np.ndarray | None = None) -> np.ndarray:
    """Squared error over the region of each frame's reconstruction ``offset + U a`` in subspace ``label``:
    ``e^T U_R^T U_R e + 2 e.(U_R^T d_R) + |d_R|^2`` with ``e = q - a``.

    Parameters
    ----------
    region : RegionProjections
    label : str
    difference : ndarray of shape (n_frames, k), optional
        ``q - a``, the coordinates' difference within the span (``None``: the orthogonal projection, ``a = q``).

    Returns
    -------
    ndarray of shape (n_frames,)
    """
    if difference is None:
        return region.distance_sq[label]
    inside = np.einsum("ij,ij->i", difference @ region.gram[label], difference)
    return np.maximum(
        inside + 2.0 * np.einsum("ij,ij->i", difference, region.cross[label]) + region.distance_sq[label], 0.0
    )


def project_frames(
    frames,
    subspaces: Mapping[str, Subspace],
    neutral: np.ndarray,
    *,
    chunk_size: int | None = None,
    region: np.ndarray | None = None,
) -> FrameProjections:
    """Coordinates of every frame in every subspace, and its squared distance to each, in one pass.

    Parameters
    ----------
    frames : ndarray of shape (n_frames, n_dims) or FramesOnDisk
        Float64 or float32 in memory, or on disk; read a chunk at a time as float64.
    subspaces : mapping
        Label -> :class:`Subspace`, all with ``n_dims`` rows.
    neutral : ndarray of shape (n_dims,)
        Neutral positions ``v0`` (for the absolute reference ``|v0 + y|^2``).
    chunk_size : int, optional
        Frames per chunk (:func:`workbench.numerics.frames.chunk_frames` when None).
    region : ndarray of shape (n_dims,) of bool, optional
        Coordinates of a part of the points: the pass then also keeps :class:`RegionProjections` of them.

    Returns
    -------
    FrameProjections
    """
    n_frames, n_dims = frames.shape
    labels = list(subspaces)
    columns = [subspaces[label].columns for label in labels]
    offsets = [
        np.zeros(n_dims) if subspaces[label].offset is None else np.asarray(subspaces[label].offset, float)
        for label in labels
    ]
    # One matrix product per chunk: every subspace's columns, then every offset and the neutral positions (then the
    # same columns and offsets zero outside the region).
    widths = [basis.shape[1] for basis in columns]
    stops = np.cumsum(widths)
    blocks = columns + [np.column_stack(offsets + [neutral])]
    if region is not None:
        inside = np.asarray(region, dtype=bool)
        masked = [np.where(inside[:, None], basis, 0.0) for basis in columns]
        masked_offsets = [np.where(inside, offset, 0.0) for offset in offsets]
        blocks += masked + [np.column_stack(masked_offsets)]
        first_masked = int(stops[-1]) + len(labels) + 1
        region_columns = [basis[inside] for basis in columns]
        region_gram = [basis.T @ basis for basis in region_columns]
        region_offset_coordinates = [offset @ basis for offset, basis in zip(masked_offsets, masked)]
        region_offset_sq = [float(offset @ offset) for offset in masked_offsets]
        inside_weight = inside.astype(float)
        region_distance = {label: np.empty(n_frames) for label in labels}
        region_cross = {label: np.empty((n_frames, width)) for label, width in zip(labels, widths)}
    together = np.hstack(blocks)
    offset_coordinates = [offset @ basis for offset, basis in zip(offsets, columns)]
    offset_sq = [float(offset @ offset) for offset in offsets]
    coordinates = {label: np.empty((n_frames, width)) for label, width in zip(labels, widths)}
    distance_sq = {label: np.empty(n_frames) for label in labels}
    displacement_sq, neutral_dot = np.empty(n_frames), np.empty(n_frames)
    n_explicit = 0
    for rows, chunk in frame_chunks(frames, chunk_size):
        products = chunk @ together
        squares = np.einsum("ij,ij->i", chunk, chunk)
        if region is not None:
            region_squares = np.einsum("ij,ij,j->i", chunk, chunk, inside_weight)
        displacement_sq[rows], neutral_dot[rows] = squares, products[:, stops[-1] + len(labels)]
        for index, label in enumerate(labels):
            q = products[:, stops[index] - widths[index] : stops[index]] - offset_coordinates[index]
            scale = squares + offset_sq[index]
            distance = squares - 2.0 * products[:, stops[-1] + index] + offset_sq[index] - np.einsum("ij,ij->i", q, q)
            close = distance <= EXPLICIT_BELOW * scale
            if region is not None:
                start = first_masked + int(stops[index]) - widths[index]
                along = products[:, start : start + widths[index]] - region_offset_coordinates[index]  # U_R^T (y-o)_R
                region_scale = region_squares + region_offset_sq[index]
                part = (
                    region_squares
                    - 2.0 * products[:, first_masked + int(stops[-1]) + index]
                    + region_offset_sq[index]
                    - 2.0 * np.einsum("ij,ij->i", q, along)
                    + np.einsum("ij,ij->i", q @ region_gram[index], q)
                )
                cross = along - q @ region_gram[index]
                explicit = np.flatnonzero(close | (part <= EXPLICIT_BELOW * region_scale))
            else:
                explicit = np.flatnonzero(close)
            if explicit.size:
                residual = chunk[explicit] - offsets[index] - q[explicit] @ columns[index].T
                exact = np.einsum("ij,ij->i", residual, residual)
                distance[close] = exact[close[explicit]]
                n_explicit += int(close.sum())
                if region is not None:
                    residual = residual[:, inside]
                    part[explicit] = np.einsum("ij,ij->i", residual, residual)
                    cross[explicit] = residual @ region_columns[index]
            coordinates[label][rows], distance_sq[label][rows] = q, np.maximum(distance, 0.0)
            if region is not None:
                region_distance[label][rows], region_cross[label][rows] = np.maximum(part, 0.0), cross
    position_sq = np.maximum(displacement_sq + 2.0 * neutral_dot + neutral @ neutral, 0.0)
    return FrameProjections(
        coordinates=coordinates,
        distance_sq=distance_sq,
        displacement_sq=displacement_sq,
        position_sq=position_sq,
        n_explicit=n_explicit,
        region=(
            None if region is None else RegionProjections(region_distance, region_cross, dict(zip(labels, region_gram)))
        ),
    )
