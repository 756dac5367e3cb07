"""Marker dropout (gaps) and how a capture fills them.

An optical system loses a marker when it is occluded, for a run of frames at a time. :func:`make_gap_mask` draws
such runs; :func:`fill_gaps` applies a gap policy to trajectories with missing (NaN) samples. Only ``linear``
(interpolate each coordinate linearly in time, hold the nearest sample before the first or after the last one)
is implemented; dropping frames or a masked solve would be further policies of :data:`GAP_POLICIES`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import WorkbenchError

GAP_POLICIES = ("linear",)


@dataclass(frozen=True)
class GapReport:
    """What a gap policy met and did, for the run record.

    Attributes
    ----------
    policy : str
    n_missing_samples : int
        Marker samples (one marker in one frame) that were missing.
    missing_fraction : float
        ``n_missing_samples`` over all marker samples.
    longest_gap_frames : int
        Longest run of consecutive missing frames of one marker.
    """

    policy: str
    n_missing_samples: int
    missing_fraction: float
    longest_gap_frames: int

    def as_dict(self) -> dict:
        return {"policy": self.policy, "n_missing_samples": self.n_missing_samples,
                "missing_fraction": self.missing_fraction, "longest_gap_frames": self.longest_gap_frames}


def make_gap_mask(n_frames: int, n_markers: int, rate: float, mean_length: float,
                  rng: np.random.Generator) -> np.ndarray:
    """Draw occlusion gaps: for each marker, visible and missing runs alternate.

    Run lengths are geometric, missing runs with mean ``mean_length`` frames and visible runs with mean
    ``mean_length * (1 - rate) / rate``, so that on average a fraction ``rate`` of the samples is missing. Each
    marker starts missing with probability ``rate``.

    Parameters
    ----------
    n_frames, n_markers : int
    rate : float
        Expected fraction of missing samples, in [0, 1).
    mean_length : float
        Mean gap length in frames, >= 1.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray of shape (n_frames, n_markers) of bool
        True where a sample is missing.
    """
    if not 0.0 <= rate < 1.0:
        raise WorkbenchError(f"dataset.gap_rate must be in [0, 1), got {rate}")
    if not mean_length >= 1.0:
        raise WorkbenchError(f"dataset.gap_mean_frames must be >= 1, got {mean_length}")
    mask = np.zeros((n_frames, n_markers), dtype=bool)
    if rate == 0.0:
        return mask
    mean_visible = mean_length * (1.0 - rate) / rate
    # Enough alternating runs to cover the take with a wide margin (each pair spans a mean of mean_length /
    # rate frames); the margin is topped up below in the rare case it does not suffice.
    n_pairs = int(np.ceil(n_frames * rate / mean_length)) * 2 + 8
    for marker in range(n_markers):
        frame, missing = 0, bool(rng.random() < rate)
        while frame < n_frames:
            gaps = rng.geometric(1.0 / mean_length, n_pairs)
            visible = rng.geometric(min(1.0, 1.0 / mean_visible), n_pairs)
            runs = np.stack([gaps, visible] if missing else [visible, gaps], axis=1).reshape(-1)
            starts = frame + np.concatenate([[0], np.cumsum(runs)[:-1]])
            for start, length in zip(starts[int(not missing)::2], runs[int(not missing)::2]):
                if start >= n_frames:
                    break
                mask[start:start + length, marker] = True
            frame = int(starts[-1] + runs[-1])
    return mask


def longest_run(mask: np.ndarray) -> int:
    """Longest run of consecutive True values down any column of a boolean array of shape (n_frames, n_cols)."""
    longest = 0
    for column in mask.T:
        padded = np.concatenate([[False], column, [False]]).astype(np.int8)
        edges = np.flatnonzero(np.diff(padded))
        if edges.size:
            longest = max(longest, int(np.max(edges[1::2] - edges[::2])))
    return longest


def fill_gaps(positions: np.ndarray, policy: str = "linear") -> tuple[np.ndarray, GapReport]:
    """Fill missing (NaN) samples of marker trajectories by a gap policy.

    Parameters
    ----------
    positions : ndarray of shape (n_frames, n_markers, 3)
        Marker positions with NaN where a marker is missing (all three coordinates together).
    policy : {"linear"}
        ``linear``: each coordinate is interpolated linearly in time between the samples around a gap; before
        the first and after the last sample the nearest sample is held.

    Returns
    -------
    filled : ndarray of shape (n_frames, n_markers, 3)
    report : GapReport
    """
    if policy not in GAP_POLICIES:
        raise WorkbenchError(f"dataset.gap_policy must be one of {GAP_POLICIES}, got {policy!r}")
    missing = np.isnan(positions).any(axis=2)
    report = GapReport(policy=policy, n_missing_samples=int(missing.sum()),
                       missing_fraction=float(missing.mean()) if missing.size else 0.0,
                       longest_gap_frames=longest_run(missing))
    if not missing.any():
        return positions, report
    filled = np.array(positions, dtype=np.float64)
    frames = np.arange(positions.shape[0])
    for marker in np.flatnonzero(missing.any(axis=0)):
        seen = ~missing[:, marker]
        if not seen.any():
            raise WorkbenchError(f"marker {marker} is missing in every frame: no gap policy can fill it")
        for axis in range(3):
            filled[~seen, marker, axis] = np.interp(frames[~seen], frames[seen], positions[seen, marker, axis])
    return filled, report
