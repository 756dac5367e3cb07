"""The takes of an export and the weight curves written per take: each take's frames, times and frame rate
(:class:`ExportTake`), the raw weights CSV, and the weights in the Live Link Face layout with the take's timecodes."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from workbench.core.errors import WorkbenchError

LIVELINK_DECIMALS = "%.10f"
"""Live Link Face writes every weight and rotation with 10 decimals."""


@dataclass(frozen=True)
class ExportTake:
    """The evaluated frames of one take: one animation, one weights file and one Live Link file of their own.

    Attributes
    ----------
    name : str
        The take's name (its file's stem).
    rows : slice
        Its frames among the evaluated frames.
    frames : ndarray of shape (n,) of int
        Frame numbers in the take's file.
    seconds : ndarray of shape (n,)
        Time of each frame from the take's first frame in its file (a dropped frame leaves a gap).
    frame_rate : float
        Frames per second of the frames used (the file's rate over any frame step).
    timecodes : tuple of str
        Live Link Face timecode of each frame (:func:`take_timecodes`).
    rotations : ndarray of shape (n, 9) or None
        Head and eye rotations of each frame from the source take, where it has them.
    timecode_source : str
        Where the timecodes and rotations come from, in words.
    """

    name: str
    rows: slice
    frames: np.ndarray
    seconds: np.ndarray
    frame_rate: float
    timecodes: tuple[str, ...]
    rotations: np.ndarray | None
    timecode_source: str

    def missing_frames(self) -> int:
        """Frames absent between the first and last (dropped by the capture or by a gap policy)."""
        steps = np.rint(np.diff(self.seconds) * self.frame_rate)
        return int(np.sum(np.maximum(steps - 1.0, 0.0)))


def export_takes(capture, source: "LiveLinkSource | None", timecode_rate: float) -> list[ExportTake]:
    """The takes of a capture's evaluated frames, in order (a take split in two runs gets ``_2``).

    Parameters
    ----------
    capture : workbench.dataset.capture.Capture
    source : LiveLinkSource or None
        The Live Link Face take the capture was driven by (:func:`livelink_source`).
    timecode_rate : float
        Frames per second of the timecodes' frame field.
    """
    timeline = capture.timeline()
    takes, seen = [], {}
    for start, stop in timeline.take_spans():
        name = str(timeline.take[start])
        seen[name] = seen.get(name, 0) + 1
        frames = np.asarray(timeline.frame[start:stop], dtype=int)
        seconds = np.asarray(timeline.seconds[start:stop], dtype=float)
        timecodes, rotations, said = take_timecodes(frames, seconds, source, timecode_rate)
        takes.append(
            ExportTake(
                name=name if seen[name] == 1 else f"{name}_{seen[name]}",
                rows=slice(start, stop),
                frames=frames,
                seconds=seconds,
                frame_rate=float(capture.frame_rate),
                timecodes=tuple(timecodes),
                rotations=rotations,
                timecode_source=said,
            )
        )
    return takes


def blender_frame_rate(rate: float) -> tuple[int, float]:
    """Blender's ``render.fps`` (an integer) and ``render.fps_base`` for a frame rate: ``fps / fps_base = rate``.

    The smallest whole ``fps_base`` up to 10 that makes ``fps`` whole (7.5 -> 15 / 2); else ``fps`` the nearest
    integer and ``fps_base = fps / rate`` (29.97 -> 30 / 1.001, as Blender's NTSC preset).
    """
    for base in range(1, 11):
        fps = round(rate * base)
        if fps >= 1 and abs(fps - rate * base) <= 1e-6 * rate * base:
            return int(fps), float(base)
    fps = max(1, round(rate))
    return int(fps), fps / rate


def take_facts(take: ExportTake) -> dict:
    """A take's entry in the manifest and in ``asset.extras``: frames, times, rate and Blender's settings."""
    fps, fps_base = blender_frame_rate(take.frame_rate)
    first, last = float(take.seconds[0]) * fps / fps_base, float(take.seconds[-1]) * fps / fps_base
    return {
        "take": take.name,
        "n_frames": len(take.frames),
        "rows": [take.rows.start, take.rows.stop],
        "first_frame": int(take.frames[0]),
        "last_frame": int(take.frames[-1]),
        "start_seconds": float(take.seconds[0]),
        "end_seconds": float(take.seconds[-1]),
        "frame_rate": take.frame_rate,
        "missing_frames": take.missing_frames(),
        "blender": {
            "fps": fps,
            "fps_base": fps_base,
            "frame_start": int(np.floor(first + 1e-6)),
            "frame_end": int(np.ceil(last - 1e-6)),
        },
        "livelink_timecodes": take.timecode_source,
    }


def csv_text(table: pd.DataFrame, float_format: str) -> str:
    """A table as CSV text (no index column), numbers in ``float_format``; written by the atomic writer."""
    buffer = io.StringIO()
    table.to_csv(buffer, index=False, float_format=float_format, lineterminator="\n")
    return buffer.getvalue()


def weights_csv(names: Sequence[str], weights: np.ndarray, frames: np.ndarray, seconds: np.ndarray) -> str:
    """Weight curves as CSV: ``frame`` (in the take's file), ``time`` (s in the take), one column per shape."""
    table = pd.DataFrame(weights, columns=list(names))
    table.insert(0, "time", seconds)
    table.insert(0, "frame", np.asarray(frames, dtype=int))
    return csv_text(table, "%.9g")


def livelink_channels(names: Sequence[str], weights: np.ndarray) -> np.ndarray | None:
    """The 52 ARKit channels of weights over shapes with ARKit-derived names, unclipped, or None when no shape has
    such a name.

    Each channel gets the mean weight of the shapes it maps onto by the workbench's naming rule
    (``JawOpen -> jawOpen``, ``BrowInnerUp -> browInnerUp_L, browInnerUp_R``); channels with none stay 0.

    Returns
    -------
    ndarray of shape (n_frames, 52) or None
    """
    from workbench.formats.livelink import ARKIT_NAMES, map_arkit_channels

    mapping = map_arkit_channels(ARKIT_NAMES, names)
    counts = mapping.matrix.sum(axis=1)
    if not counts.any():
        return None
    return (weights @ mapping.matrix.T) / np.maximum(counts, 1.0)


def livelink_csv(
    channels: np.ndarray, timecodes: Sequence[str], rotations: np.ndarray | None = None
) -> tuple[str, int]:
    """A take in the Live Link Face CSV layout, as the app writes it.

    ``Timecode``, ``BlendShapeCount`` (61), the 52 ARKit weights clipped into [0, 1] (ARKit weights are fractions)
    and the 9 head and eye rotations, every number with 10 decimals.

    Parameters
    ----------
    channels : ndarray of shape (n_frames, 52)
        :func:`livelink_channels`.
    timecodes : sequence of str
        ``HH:MM:SS:FF.fff`` of each frame (the source take's, or :func:`timecode` of its time).
    rotations : ndarray of shape (n_frames, 9), optional
        ``HeadYaw`` ... ``RightEyeRoll`` (radians); zeros when None.

    Returns
    -------
    text : str
    clipped : int
        How many weights lay outside [0, 1].
    """
    from workbench.formats.livelink import ARKIT_NAMES, ROTATION_NAMES

    clipped = int(((channels < 0.0) | (channels > 1.0)).sum())
    rotations = np.zeros((len(channels), len(ROTATION_NAMES))) if rotations is None else rotations
    table = pd.DataFrame(
        np.hstack([np.clip(channels, 0.0, 1.0), rotations]) + 0.0, columns=[*ARKIT_NAMES, *ROTATION_NAMES]
    )
    table.insert(0, "BlendShapeCount", len(ARKIT_NAMES) + len(ROTATION_NAMES))
    table.insert(0, "Timecode", list(timecodes))
    return csv_text(table, LIVELINK_DECIMALS), clipped


LIVELINK_TIMECODE_RATE = 60.0
"""The timecode rate of the takes exported from data without one of their own (every kind but ``ict_livelink``,
whose ``dataset.timecode_rate`` the source take states): Live Link Face's 60 frames per second."""


def timecode(seconds: float, rate: float = LIVELINK_TIMECODE_RATE) -> str:
    """``HH:MM:SS:FF.fff``: whole seconds, then ``FF.fff`` frames at ``rate`` (Live Link Face's timecode).

    The frame field is rounded to the thousandth it is printed with, carrying into the seconds, so it stays below
    ``rate``.
    """
    whole = int(np.floor(seconds))
    frames = round((seconds - whole) * rate, 3)
    if frames >= rate:
        whole, frames = whole + 1, 0.0
    return f"{whole // 3600:02d}:{whole // 60 % 60:02d}:{whole % 60:02d}:{frames:06.3f}"


@dataclass(frozen=True)
class LiveLinkSource:
    """The Live Link Face take a capture was driven by, row by row as the file holds it.

    Attributes
    ----------
    timecodes : ndarray of shape (n_rows,) of str
        As written.
    rotations : ndarray of shape (n_rows, 9) or None
        The head and eye rotations, where the file has them.
    """

    timecodes: np.ndarray
    rotations: np.ndarray | None


def livelink_source(dataset) -> LiveLinkSource | None:
    """The source Live Link Face take of a run's typed dataset settings (``dataset=ict_livelink`` driven by a Live
    Link CSV), or None for other data."""
    from workbench.dataset.real import data_path
    from workbench.formats.livelink import read_livelink_csv

    if dataset.kind != "ict_livelink" or dataset.weight_curves or not dataset.livelink_csv:
        return None
    path = data_path(dataset.data_root, dataset.livelink_csv, "livelink_csv")
    take = read_livelink_csv(path, timecode_rate=dataset.timecode_rate)
    column = pd.read_csv(path, usecols=["Timecode"], dtype=str, skipinitialspace=True)["Timecode"]
    return LiveLinkSource(timecodes=column.str.strip().to_numpy(), rotations=take.rotations)


def take_timecodes(
    frames: np.ndarray, seconds: np.ndarray, source: LiveLinkSource | None, timecode_rate: float
) -> tuple[list[str], np.ndarray | None, str]:
    """Timecodes and rotations of a take's frames: the source take's rows where there is one, else timecodes of
    the frames' times (from 00:00:00:00.000) and no rotations; and a phrase saying which.

    Parameters
    ----------
    frames : ndarray of shape (n,) of int
        Rows of the source take.
    seconds : ndarray of shape (n,)
        Their times from the take's first row.
    """
    from workbench.formats.livelink import parse_timecodes

    if source is None:
        return (
            [timecode(second, timecode_rate) for second in seconds],
            None,
            f"from the frames' times (00:00:00:00.000 at the take's start, {timecode_rate:g} frames a second)",
        )
    timecodes = source.timecodes[frames]
    where = Path("the source take")
    start = parse_timecodes([source.timecodes[0]], timecode_rate, where)[0]
    if not np.allclose(parse_timecodes(list(timecodes), timecode_rate, where) - start, seconds, rtol=0.0, atol=1e-9):
        raise WorkbenchError(
            "export: the source Live Link take's timecodes do not give the run's frame times; the "
            "take changed since the run: rerun the study and export the new record"
        )
    rotations = None if source.rotations is None else source.rotations[frames]
    return (
        list(timecodes),
        rotations,
        "the source take's own" + ("" if rotations is not None else " (rotations: zeros, the source has none)"),
    )
