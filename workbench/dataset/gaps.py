"""Marker dropout (gaps) and the policies that handle it.

An optical system loses a marker when it is occluded, for a run of frames at a time. :func:`make_gap_mask` draws
such runs; :func:`apply_gap_policy` handles trajectories with missing (NaN) samples by one of
:data:`workbench.settings.rules.GAP_POLICIES`:

``drop``
    keep only the frames that saw every marker;
``linear``
    fill each gap by linear interpolation in time (holding the nearest sample before the first or after the last
    one), gaps longer than ``max_fill_frames`` excepted: frames still missing a marker are dropped;
``masked``
    keep every frame that saw at least one marker; the bases are fitted on the linearly filled frames (PCA needs
    complete data), while each evaluated frame's weights and alpha use only the markers it saw, so no filled value
    is ever scored.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.core.errors import WorkbenchError


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
    n_filled_samples : int
        Samples given a value by interpolation (for ``masked``: in the training frames only).
    n_dropped_frames : int
        Frames left out.
    """

    policy: str
    n_missing_samples: int
    missing_fraction: float
    longest_gap_frames: int
    n_filled_samples: int = 0
    n_dropped_frames: int = 0

    def as_dict(self) -> dict:
        return {
            "policy": self.policy,
            "n_missing_samples": self.n_missing_samples,
            "missing_fraction": self.missing_fraction,
            "longest_gap_frames": self.longest_gap_frames,
            "n_filled_samples": self.n_filled_samples,
            "n_dropped_frames": self.n_dropped_frames,
        }

    def describe(self) -> str:
        """One line for the run's notes."""
        text = (
            f"{self.n_missing_samples} missing marker samples ({100 * self.missing_fraction:.2f} %, longest "
            f"gap {self.longest_gap_frames} frames), gap policy '{self.policy}'"
        )
        if self.n_filled_samples:
            text += f": {self.n_filled_samples} samples filled by linear interpolation"
        if self.n_dropped_frames:
            text += f"; {self.n_dropped_frames} frames dropped"
        return text


def make_gap_mask(
    n_frames: int, n_markers: int, rate: float, mean_length: float, rng: np.random.Generator
) -> np.ndarray:
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
    return gap_mask(n_frames, n_markers, rate, mean_length, rng)


def gap_mask(n_frames: int, n_markers: int, rate: float, mean_length: float, rng: np.random.Generator) -> np.ndarray:
    """:func:`make_gap_mask` of a rate and a mean length already checked (``dataset.gap_rate`` and
    ``dataset.gap_mean_frames``, as the builders take them)."""
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
            for start, length in zip(starts[int(not missing) :: 2], runs[int(not missing) :: 2]):
                if start >= n_frames:
                    break
                mask[start : start + length, marker] = True
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


@dataclass(frozen=True)
class GapOutcome:
    """Trajectories after a gap policy.

    Attributes
    ----------
    positions : ndarray of shape (n_kept, n_markers, 3)
        Complete trajectories of the kept frames (filled where the policy fills), for training.
    visible : ndarray of shape (n_kept, n_markers) of bool, or None
        ``masked``: which markers each kept frame saw; None for the other policies (every kept frame is complete
        as it was captured, or filled).
    kept : ndarray of shape (n_frames,) of bool
        Frames kept.
    report : GapReport
    """

    positions: np.ndarray
    visible: np.ndarray | None
    kept: np.ndarray
    report: GapReport


def apply_gap_policy(positions: np.ndarray, policy: str, max_fill_frames: int | None = None) -> GapOutcome:
    """Handle missing (NaN) samples of marker trajectories by one of :data:`workbench.settings.rules.GAP_POLICIES`.

    Parameters
    ----------
    positions : ndarray of shape (n_frames, n_markers, 3)
        NaN where a marker is missing.
    policy : {"drop", "linear", "masked"}
        ``dataset.gap_policy``, checked with the settings.
    max_fill_frames : int, optional
        ``linear``: gaps longer than this are not filled (their frames are dropped). None: no limit.

    Returns
    -------
    GapOutcome
    """
    missing = np.isnan(positions).any(axis=2)
    if policy == "drop":
        filled, kept = positions, ~missing.any(axis=1)
    else:
        filled = _interpolate(positions, missing, max_fill_frames if policy == "linear" else None)
        kept = (~np.isnan(filled).any(axis=(1, 2))) if policy == "linear" else (~missing).any(axis=1)
    if not kept.any():
        raise WorkbenchError(f"gap policy {policy!r} keeps no frame: every frame misses a marker")
    report = GapReport(
        policy=policy,
        n_missing_samples=int(missing.sum()),
        missing_fraction=float(missing.mean()) if missing.size else 0.0,
        longest_gap_frames=longest_run(missing),
        n_filled_samples=int((missing[kept] & ~np.isnan(filled[kept]).any(axis=2)).sum()) if policy != "drop" else 0,
        n_dropped_frames=int((~kept).sum()),
    )
    return GapOutcome(
        positions=filled[kept], visible=~missing[kept] if policy == "masked" else None, kept=kept, report=report
    )


def _interpolate(positions: np.ndarray, missing: np.ndarray, max_fill_frames: int | None) -> np.ndarray:
    """Each coordinate of each missing sample interpolated linearly in time between the samples around its gap,
    the nearest sample held before the first or after the last one; gaps longer than ``max_fill_frames`` stay NaN.
    A copy."""
    filled = np.array(positions, dtype=np.float64)
    if not missing.any():
        return filled
    frames = np.arange(positions.shape[0])
    for marker in np.flatnonzero(missing.any(axis=0)):
        seen = ~missing[:, marker]
        if not seen.any():
            raise WorkbenchError(f"marker {marker} is missing in every frame: no gap policy can fill it")
        fill = ~seen
        if max_fill_frames is not None:
            fill &= _run_lengths(missing[:, marker]) <= max_fill_frames
        for axis in range(3):
            filled[fill, marker, axis] = np.interp(frames[fill], frames[seen], positions[seen, marker, axis])
    return filled


def _run_lengths(column: np.ndarray) -> np.ndarray:
    """For each frame, the length of the run of True values it belongs to (0 where False); shape (n_frames,)."""
    padded = np.concatenate([[False], column, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    lengths = np.zeros(column.shape[0], dtype=int)
    for start, stop in zip(edges[::2], edges[1::2]):
        lengths[start:stop] = stop - start
    return lengths
