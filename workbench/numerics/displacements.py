"""Whether frames are displacements from the neutral face, as the method takes them, or positions given by mistake.

A capture's frames are ``v* - v0``: each frame's points move by millimetres around a mean face that is itself
small. Positions ``v*`` carry the face's shape: the mean frame's points spread over the whole face (tens of
millimetres) while they move by a few. The rule compares the two (:func:`shape_over_motion`): the spread of the
mean frame's points about their centroid (so it does not depend on where the coordinate origin is) over the RMS
motion of a point, and refuses above :data:`POSITIONS_ABOVE`.
"""

from __future__ import annotations

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.numerics.frames import frame_chunks

POSITIONS_ABOVE = 5.0
"""Frames whose :func:`shape_over_motion` exceeds this look like positions. Measured on the workbench's captures
(``docs/api.md``): as displacements 0.20 to 0.96 (a single frame against the capture's motion: at most 2.8), as
positions 12.0 to 67.2 (a single frame: at least 11.5)."""


def motion_rms(total_variance: float, n_points: int) -> float:
    """The RMS motion of a point: ``sqrt(total_variance / n_points)``, the frames' covariance trace shared out.

    Parameters
    ----------
    total_variance : float
        The trace of the frames' covariance, the sum of the variances of all ``3 * n_points`` columns.
    n_points : int
    """
    return float(np.sqrt(total_variance / n_points))


def frames_mean_and_motion(frames) -> tuple[np.ndarray, float]:
    """The mean frame and :func:`motion_rms` of ``frames``, a chunk of frames at a time
    (:func:`workbench.numerics.frames.frame_chunks`: frames on disk stay there, and memory stays within a chunk).

    Parameters
    ----------
    frames : ndarray of shape (n_frames, 3 * n_points) or FramesOnDisk

    Returns
    -------
    mean_frame : ndarray of shape (3 * n_points,)
    motion : float
    """
    n_frames = frames.shape[0]
    mean = sum(chunk.sum(axis=0) for _, chunk in frame_chunks(frames)) / n_frames
    total = sum(float(np.sum((chunk - mean) ** 2)) for _, chunk in frame_chunks(frames))
    return mean, motion_rms(total / n_frames, frames.shape[1] // 3)


def shape_over_motion(mean_frame: np.ndarray, motion: float) -> float:
    """The spread of the mean frame's points about their centroid (RMS distance) over ``motion``.

    Parameters
    ----------
    mean_frame : ndarray of shape (3 * n_points,)
        The frames' mean.
    motion : float
        The RMS motion of a point (:func:`motion_rms`); 0 gives 0 (constant frames are refused elsewhere).

    Returns
    -------
    float
        Below 1 for a capture's displacements, tens for positions.
    """
    points = np.asarray(mean_frame, dtype=np.float64).reshape(-1, 3)
    spread = float(np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1))))
    return spread / motion if motion > 0 else 0.0


def positions_problem(name: str, mean_frame: np.ndarray, motion: float, remedy: str) -> str | None:
    """What :func:`check_displacements` refuses, as one line naming ``name``, or None when the frames pass.

    Parameters
    ----------
    name : str
        The frames as the line names them.
    mean_frame : ndarray of shape (3 * n_points,)
    motion : float
        The RMS motion of a point in the frames (or in the capture a fit was made on).
    remedy : str
        How the caller's user says what the frames are, or makes them displacements.
    """
    ratio = shape_over_motion(mean_frame, motion)
    if ratio <= POSITIONS_ABOVE:
        return None
    return (
        f"{name} look like positions, not displacements from the neutral face: their mean face spreads "
        f"{ratio:.1f} times their motion (displacements stay below {POSITIONS_ABOVE:g}); {remedy}"
    )


def check_displacements(name: str, mean_frame: np.ndarray, motion: float, remedy: str) -> None:
    """A one-line :class:`WorkbenchError` (:func:`positions_problem`'s line) when frames with this mean and motion
    look like positions; the arguments are :func:`positions_problem`'s."""
    problem = positions_problem(name, mean_frame, motion, remedy)
    if problem:
        raise WorkbenchError(problem)
