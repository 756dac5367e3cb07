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
    """

    coordinates: dict
    distance_sq: dict
    displacement_sq: np.ndarray
    position_sq: np.ndarray
    n_explicit: int


def project_frames(
    frames, subspaces: Mapping[str, Subspace], neutral: np.ndarray, *, chunk_size: int | None = None
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

    Returns
    -------
    FrameProjections
    """
    n_frames, n_dims = frames.shape
    labels = list(subspaces)
    offsets = [
        np.zeros(n_dims) if subspaces[label].offset is None else np.asarray(subspaces[label].offset, float)
        for label in labels
    ]
    # One matrix product per chunk: every subspace's columns, then every offset and the neutral positions.
    widths = [subspaces[label].columns.shape[1] for label in labels]
    stops = np.cumsum(widths)
    together = np.hstack([subspaces[label].columns for label in labels] + [np.column_stack(offsets + [neutral])])
    offset_coordinates = [offset @ subspaces[label].columns for label, offset in zip(labels, offsets)]
    offset_sq = [float(offset @ offset) for offset in offsets]
    coordinates = {label: np.empty((n_frames, width)) for label, width in zip(labels, widths)}
    distance_sq = {label: np.empty(n_frames) for label in labels}
    displacement_sq, neutral_dot = np.empty(n_frames), np.empty(n_frames)
    n_explicit = 0
    for rows, chunk in frame_chunks(frames, chunk_size):
        products = chunk @ together
        squares = np.einsum("ij,ij->i", chunk, chunk)
        displacement_sq[rows], neutral_dot[rows] = squares, products[:, -1]
        for index, label in enumerate(labels):
            q = products[:, stops[index] - widths[index] : stops[index]] - offset_coordinates[index]
            scale = squares + offset_sq[index]
            distance = squares - 2.0 * products[:, stops[-1] + index] + offset_sq[index] - np.einsum("ij,ij->i", q, q)
            close = np.flatnonzero(distance <= EXPLICIT_BELOW * scale)
            if close.size:
                residual = chunk[close] - offsets[index] - q[close] @ subspaces[label].columns.T
                distance[close] = np.einsum("ij,ij->i", residual, residual)
                n_explicit += close.size
            coordinates[label][rows], distance_sq[label][rows] = q, np.maximum(distance, 0.0)
    position_sq = np.maximum(displacement_sq + 2.0 * neutral_dot + neutral @ neutral, 0.0)
    return FrameProjections(
        coordinates=coordinates,
        distance_sq=distance_sq,
        displacement_sq=displacement_sq,
        position_sq=position_sq,
        n_explicit=n_explicit,
    )
