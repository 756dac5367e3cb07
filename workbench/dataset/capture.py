"""The contract between the dataset stage and the numerical core."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Capture:
    """A capture prepared for the quasi-eigen study: everything in displacement form, one set of points.

    Attributes
    ----------
    name : str
        Human-readable name of the data (a synthetic dataset says so in its name).
    neutral : ndarray of shape (3 * n_points,)
        Neutral positions ``v0`` of the points, flattened ``[x0, y0, z0, x1, ...]``, in ``units``.
    train : ndarray of shape (n_train_frames, 3 * n_points)
        Displacements from neutral of the frames the bases are fitted on.
    eval : ndarray of shape (n_eval_frames, 3 * n_points)
        Displacements from neutral of the frames that are reconstructed and scored.
    hand : ndarray of shape (n_shapes, 3 * n_points)
        Hand-made basis ``E^H`` as displacements from neutral at the same points.
    hand_names : tuple of str
        One name per hand shape.
    point_labels : tuple of str
        One label per point (marker label or ``v<index>`` for mesh vertices).
    units : str
        Length unit of every array (``"mm"``).
    origin : str
        Where the coordinate origin of ``neutral`` is; the absolute alpha of eq. 6 depends on it.
    frame_rate : float
        Frames per second of the capture.
    provenance : dict
        Where the data came from (kind, seed, files, licence), written into every run record.
    notes : tuple of str
        Facts about the preparation worth reporting (stabilisation residual, split, ...).
    faces : ndarray of shape (n_faces, 3) of int, or None
        Triangles over the points when they are the vertices of a mesh (for figures); None for markers.
    eval_visible : ndarray of shape (n_eval_frames, n_points) of bool, or None
        Which points each evaluated frame saw, under the ``masked`` gap policy: ``eval`` is NaN at the others,
        and weights and alpha use the visible points only. None: every point of every frame was seen.
    train_source, train_operator : ndarray of shape (n_train_frames, k) and (3 * n_points, k), or None
        Set when the training frames are a fixed linear map of smaller data, ``train = train_source @
        train_operator.T`` (mesh frames interpolated from markers by RBF): the PCA is then computed in the small
        space and lifted (:meth:`workbench.bases.Eigenfaces.fit_mapped`).
    """

    name: str
    neutral: np.ndarray
    train: np.ndarray
    eval: np.ndarray
    hand: np.ndarray
    hand_names: tuple[str, ...]
    point_labels: tuple[str, ...]
    units: str
    origin: str
    frame_rate: float
    provenance: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    faces: np.ndarray | None = None
    eval_visible: np.ndarray | None = None
    train_source: np.ndarray | None = None
    train_operator: np.ndarray | None = None

    def __post_init__(self):
        if (self.train_source is None) != (self.train_operator is None):
            raise ValueError("Capture: train_source and train_operator are given together or not at all")

    @property
    def n_points(self) -> int:
        return self.neutral.shape[0] // 3
