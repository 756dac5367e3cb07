"""Helpers every dataset builder shares: the train/eval split, the ``train_on`` list, interpolated and masked
frames, content hashes of arrays, the markers' jitter."""

from __future__ import annotations

import hashlib
from typing import Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.cache import code_fingerprint
from workbench.dataset.storage import FrameStorage
from workbench.dataset.transfer import apply_point_operator
from workbench.numerics.frames import FramesOnDisk, frame_chunks
from workbench.numerics.metrics import point_norms


def split_frames(frames: np.ndarray, split: str, eval_fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """Choose training and evaluation frames.

    Parameters
    ----------
    frames : ndarray of shape (n_frames, n_dims) or FramesOnDisk
    split : {"same", "tail"}
        ``same`` trains and evaluates on every frame, as the paper does; ``tail`` holds out the last
        ``eval_fraction`` of the take for evaluation (checked with the settings).
    eval_fraction : float
        In (0, 1), used by ``tail``.

    Returns
    -------
    train, eval : ndarray
    """
    if split == "same":
        return frames, frames
    take = frames.rows if isinstance(frames, FramesOnDisk) else lambda start, stop: frames[start:stop]
    n_eval = int(round(eval_fraction * len(frames)))
    if n_eval < 1 or n_eval > len(frames) - 2:
        raise WorkbenchError(
            f"dataset.eval_fraction {eval_fraction} leaves {n_eval} of {len(frames)} frames "
            "for evaluation; need at least 1 and at least 2 for training"
        )
    return take(0, len(frames) - n_eval), take(len(frames) - n_eval, len(frames))


def name_list(value) -> list[str]:
    """A checked setting that takes one name or a list of them (``dataset.train_on``) as a list."""
    return [value] if isinstance(value, str) else list(value)


def interpolated_frames(operator: np.ndarray, points: np.ndarray, storage: FrameStorage):
    """Values at target points interpolated from source points, ``operator @ points[f]`` for every frame, written
    chunk by chunk into ``storage`` (so a dense interpolated mesh never exists whole in float64).

    Parameters
    ----------
    operator : ndarray of shape (n_target, n_source)
    points : ndarray of shape (n_frames, n_source, 3)
    storage : FrameStorage

    Returns
    -------
    ndarray of shape (n_frames, 3 * n_target), read-only, or FramesOnDisk
    """
    key = (array_digest(points), array_digest(operator), code_fingerprint())
    return storage.build(
        "interpolated",
        key,
        len(points),
        3 * len(operator),
        lambda rows: apply_point_operator(operator, points[rows]).reshape(rows.stop - rows.start, -1),
    )


def array_digest(array: np.ndarray) -> str:
    """Content hash of an array: its values, type and shape (for the keys of frames stored on disk)."""
    array = np.ascontiguousarray(array)
    digest = hashlib.sha256(f"{array.dtype.str} {array.shape}".encode())
    digest.update(array.tobytes())
    return digest.hexdigest()


def largest_point_norm(frames) -> float:
    """The largest displacement of any point in any frame, read a chunk of frames at a time.

    Parameters
    ----------
    frames : ndarray of shape (n_frames, 3 * n_points) or FramesOnDisk

    Returns
    -------
    float
    """
    largest = 0.0
    for _, chunk in frame_chunks(frames):
        largest = max(largest, float(point_norms(chunk).max(initial=0.0)))
    return largest


def point_operator_matrix(operator: np.ndarray) -> np.ndarray:
    """A map of per-point values, shape (n_target, n_source), as the matrix acting on flattened frames
    ``[x0, y0, z0, x1, ...]``: ``kron(operator, I_3)``, shape (3 * n_target, 3 * n_source)."""
    return np.kron(operator, np.eye(3))


def masked_training_frames(train: np.ndarray, visible: np.ndarray, fit_on: str) -> tuple[np.ndarray, str]:
    """The frames the bases are fitted on under the ``masked`` gap policy, and a note saying which.

    Parameters
    ----------
    train : ndarray of shape (n_train, 3 * n_points)
        Training frames with their gaps filled linearly.
    visible : ndarray of shape (n_train, n_points) of bool
        Which markers each training frame saw.
    fit_on : {"complete", "filled"}
        ``complete``: only the frames that saw every marker (the fill's errors stay out of the PCA, whose coverage
        rule would otherwise keep axes for them); ``filled``: every frame, gaps filled.

    Returns
    -------
    train : ndarray of shape (n_fit, 3 * n_points)
    note : str
    """
    if fit_on == "filled":
        return train, f"the bases are fitted on all {len(train)} training frames, their gaps filled linearly"
    complete = visible.all(axis=1)
    if complete.sum() < 2:
        raise WorkbenchError(
            f"dataset.gap_fit_on 'complete': only {int(complete.sum())} of {len(train)} training "
            "frames saw every marker; need at least 2 (use gap_fit_on filled)"
        )
    return train[complete], (
        f"the bases are fitted on the {int(complete.sum())} of {len(train)} training frames that saw every marker"
    )


def masked_frames(frames: np.ndarray, visible: np.ndarray) -> np.ndarray:
    """``frames`` (n_frames, 3 * n_points) with NaN at the points ``visible`` (n_frames, n_points) marks unseen."""
    return np.where(np.repeat(visible, 3, axis=1), frames, np.nan)


def marker_jitter_rms(trajectories: Sequence[np.ndarray]) -> float:
    """RMS length (mm) of the markers' jitter: the high-frequency part of their trajectories.

    The estimator is the second difference over consecutive frames, ``d_t = x_{t-1} - 2 x_t + x_{t+1}`` of every
    coordinate of every marker. White jitter of variance ``s^2`` per coordinate gives ``d_t`` the variance
    ``(1 + 4 + 1) s^2 = 6 s^2``, while a smooth trajectory adds only its acceleration times the squared frame
    interval; so ``J = sqrt(mean |d_t|^2 / 6)`` (``|.|`` the 3-D length, the mean over frames and markers) is the
    RMS length of the 3-D jitter vector, ``sqrt(3) s``. The motion's own acceleration adds to it, so ``J`` is an
    upper bound of the jitter, tight when the face moves slowly against the frame rate. Samples next to a missing
    one (NaN) are left out.

    Parameters
    ----------
    trajectories : sequence of ndarray of shape (n_frames, n_markers, 3)
        One per take, consecutive frames (a second difference never spans two takes).

    Returns
    -------
    float
        NaN when no three consecutive samples of a marker are present.
    """
    total, count = 0.0, 0
    for positions in trajectories:
        second = positions[:-2] - 2.0 * positions[1:-1] + positions[2:]
        squared = np.sum(second**2, axis=2)
        seen = np.isfinite(squared)
        total, count = total + float(squared[seen].sum()), count + int(seen.sum())
    return float(np.sqrt(total / count / 6.0)) if count else float("nan")
