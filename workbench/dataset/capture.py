"""The contract between the dataset stage and the numerical core."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np


@dataclass(frozen=True)
class Timeline:
    """Where each frame of a capture comes from: its take, its frame number in that take's file and its time.

    Attributes
    ----------
    take : ndarray of shape (n_frames,) of str
        Name of the take (file stem, or the synthetic take's seed).
    frame : ndarray of shape (n_frames,) of int
        Frame number in the take's file (0-based), before any sub-sampling.
    seconds : ndarray of shape (n_frames,) of float
        Time of the frame from the start of its take, from the file's frame rate or timecodes.
    """

    take: np.ndarray
    frame: np.ndarray
    seconds: np.ndarray

    def __post_init__(self):
        if not len(self.take) == len(self.frame) == len(self.seconds):
            raise ValueError("Timeline: take, frame and seconds must have one entry per frame")

    def __len__(self) -> int:
        return len(self.frame)

    def __getitem__(self, index) -> "Timeline":
        return Timeline(take=self.take[index], frame=self.frame[index], seconds=self.seconds[index])

    def label(self, i: int) -> str:
        """``<take> frame <n> (t = <s> s)`` of frame ``i``."""
        return f"{self.take[i]} frame {int(self.frame[i])} (t = {float(self.seconds[i]):.2f} s)"

    def elapsed(self) -> np.ndarray:
        """Time of each frame on one axis through the takes in order, each take after the previous one ends.

        Returns
        -------
        ndarray of shape (n_frames,)
        """
        elapsed = np.asarray(self.seconds, dtype=float).copy()
        offset = 0.0
        for start, stop in self.take_spans():
            elapsed[start:stop] += offset - self.seconds[start]
            step = np.median(np.diff(self.seconds[start:stop])) if stop - start > 1 else 0.0
            offset = elapsed[stop - 1] + step
        return elapsed

    def take_spans(self) -> list[tuple[int, int]]:
        """(start, stop) of each run of consecutive frames of one take."""
        changes = np.flatnonzero(self.take[1:] != self.take[:-1]) + 1
        edges = [0, *changes.tolist(), len(self)]
        return list(zip(edges[:-1], edges[1:]))

    def as_arrays(self, prefix: str = "") -> dict:
        return {
            f"{prefix}take": np.asarray(self.take, dtype=str),
            f"{prefix}frame": np.asarray(self.frame),
            f"{prefix}seconds": np.asarray(self.seconds, dtype=float),
        }

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "") -> "Timeline | None":
        """The timeline stored by :meth:`as_arrays`, or None when ``arrays`` has none."""
        if f"{prefix}frame" not in arrays:
            return None
        return cls(
            take=np.asarray(arrays[f"{prefix}take"]).astype(str),
            frame=np.asarray(arrays[f"{prefix}frame"]),
            seconds=np.asarray(arrays[f"{prefix}seconds"], dtype=float),
        )

    @classmethod
    def uniform(cls, take: str, frames: Sequence[int], frame_rate: float) -> "Timeline":
        """Frames of one take recorded at a constant ``frame_rate`` (frames per second of the file)."""
        frames = np.asarray(frames, dtype=int)
        return cls(take=np.full(len(frames), take), frame=frames, seconds=frames / float(frame_rate))

    @classmethod
    def concatenate(cls, parts: Sequence["Timeline"]) -> "Timeline":
        return cls(
            take=np.concatenate([p.take for p in parts]).astype(str),
            frame=np.concatenate([p.frame for p in parts]),
            seconds=np.concatenate([p.seconds for p in parts]),
        )


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
        Frames per second of the frames used (the file's rate over any frame step).
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
        space and lifted (:meth:`workbench.numerics.bases.Eigenfaces.fit_mapped`).
    point_support : ndarray of shape (n_points,) of bool, or None
        False at points whose motion is extrapolated far from any measured point (a mesh moved by an interpolation
        of markers: neck, back of the head); figures draw them plain, out of the colour scales. None: every point
        is measured or interpolated.
    eval_timeline : Timeline or None
        Take, frame number in the file and time of every evaluated frame; None: frame ``i`` of one take at
        ``i / frame_rate`` (see :meth:`timeline`).
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
    point_support: np.ndarray | None = None
    eval_timeline: Timeline | None = None

    def __post_init__(self):
        if (self.train_source is None) != (self.train_operator is None):
            raise ValueError("Capture: train_source and train_operator are given together or not at all")
        if self.eval_timeline is not None and len(self.eval_timeline) != len(self.eval):
            raise ValueError("Capture: eval_timeline needs one entry per evaluated frame")

    def timeline(self) -> Timeline:
        """The evaluated frames' timeline (:attr:`eval_timeline`, or frames of one take at ``frame_rate``)."""
        if self.eval_timeline is not None:
            return self.eval_timeline
        return Timeline.uniform("take", np.arange(len(self.eval)), self.frame_rate)

    @property
    def n_points(self) -> int:
        return self.neutral.shape[0] // 3
