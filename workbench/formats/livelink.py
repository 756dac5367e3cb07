"""ARKit blendshape weight curves from Live Link Face CSV exports, and driving a blendshape basis with them.

A Live Link Face CSV has a ``Timecode`` column (``HH:MM:SS:FF.fff``, frames counted at the timecode rate), a
``BlendShapeCount`` column, the 52 ARKit weights (``EyeBlinkLeft`` ... ``TongueOut``, in [0, 1]) and, in most
exports, head and eye rotations (``HeadYaw`` ... ``RightEyeRoll``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError, single_line
from workbench.core.files import input_path
from workbench.settings.rules import positive_setting

ARKIT_NAMES = (
    "EyeBlinkLeft",
    "EyeLookDownLeft",
    "EyeLookInLeft",
    "EyeLookOutLeft",
    "EyeLookUpLeft",
    "EyeSquintLeft",
    "EyeWideLeft",
    "EyeBlinkRight",
    "EyeLookDownRight",
    "EyeLookInRight",
    "EyeLookOutRight",
    "EyeLookUpRight",
    "EyeSquintRight",
    "EyeWideRight",
    "JawForward",
    "JawRight",
    "JawLeft",
    "JawOpen",
    "MouthClose",
    "MouthFunnel",
    "MouthPucker",
    "MouthRight",
    "MouthLeft",
    "MouthSmileLeft",
    "MouthSmileRight",
    "MouthFrownLeft",
    "MouthFrownRight",
    "MouthDimpleLeft",
    "MouthDimpleRight",
    "MouthStretchLeft",
    "MouthStretchRight",
    "MouthRollLower",
    "MouthRollUpper",
    "MouthShrugLower",
    "MouthShrugUpper",
    "MouthPressLeft",
    "MouthPressRight",
    "MouthLowerDownLeft",
    "MouthLowerDownRight",
    "MouthUpperUpLeft",
    "MouthUpperUpRight",
    "BrowDownLeft",
    "BrowDownRight",
    "BrowInnerUp",
    "BrowOuterUpLeft",
    "BrowOuterUpRight",
    "CheekPuff",
    "CheekSquintLeft",
    "CheekSquintRight",
    "NoseSneerLeft",
    "NoseSneerRight",
    "TongueOut",
)
"""The 52 ARKit blendshape channels, in Live Link Face's column order."""

WEIGHT_SLACK = 0.1
"""ARKit weights are fractions in [0, 1]; exports overshoot by a little (up to about 1.004 seen), so a weight is
refused only outside ``[-WEIGHT_SLACK, 1 + WEIGHT_SLACK]``: such values are in other units (percent)."""

ROTATION_NAMES = (
    "HeadYaw",
    "HeadPitch",
    "HeadRoll",
    "LeftEyeYaw",
    "LeftEyePitch",
    "LeftEyeRoll",
    "RightEyeYaw",
    "RightEyePitch",
    "RightEyeRoll",
)


@dataclass(frozen=True)
class LiveLinkTake:
    """A Live Link Face take.

    Attributes
    ----------
    names : tuple of str
        The 52 ARKit channel names (:data:`ARKIT_NAMES`).
    weights : ndarray of shape (n_frames, 52)
        Weight of each channel in each frame.
    seconds : ndarray of shape (n_frames,)
        Time of each frame from the first, from the timecodes.
    frame_rate : float
        Frames per second: the inverse of the median frame interval.
    rotations : ndarray of shape (n_frames, 9) or None
        ``ROTATION_NAMES`` columns when the file has all of them (radians as exported).
    path : pathlib.Path
    """

    names: tuple[str, ...]
    weights: np.ndarray
    seconds: np.ndarray
    frame_rate: float
    rotations: np.ndarray | None
    path: Path

    @property
    def n_frames(self) -> int:
        return self.weights.shape[0]


def parse_timecodes(timecodes: Sequence[str], timecode_rate: float, path: Path) -> np.ndarray:
    """Seconds since the first frame of ``HH:MM:SS:FF[.fff]`` timecodes (``FF`` frames at ``timecode_rate``).

    Returns
    -------
    ndarray of shape (n_frames,)
    """
    seconds = np.empty(len(timecodes))
    for i, text in enumerate(timecodes):
        parts = str(text).strip().split(":")
        try:
            if len(parts) != 4:
                raise ValueError
            hours, minutes, secs, frames = (float(part) for part in parts)
        except ValueError:
            raise WorkbenchError(f"{path}: row {i + 2}: Timecode {text!r} is not HH:MM:SS:FF[.fff]") from None
        seconds[i] = hours * 3600.0 + minutes * 60.0 + secs + frames / timecode_rate
    steps = np.diff(seconds)
    steps[steps < -43200.0] += 86400.0  # a take that runs past midnight restarts the clock
    return np.concatenate([[0.0], np.cumsum(steps)])


def read_livelink_csv(path: str | os.PathLike, *, timecode_rate: float = 60.0) -> LiveLinkTake:
    """Read the 52 ARKit weight curves of a Live Link Face CSV export.

    Parameters
    ----------
    path : path-like
    timecode_rate : float, default 60.0
        Frames per second the timecode's frame field counts (Live Link Face: 60, whatever the capture rate).

    Returns
    -------
    LiveLinkTake
        ``names`` (ARKit channels), ``weights`` of shape (n_frames, n_channels) in [0, 1], ``seconds`` of shape
        (n_frames,), ``frame_rate``, ``rotations`` (head and eyes) or None.

    Raises
    ------
    WorkbenchError
        If the file is missing or not a readable CSV, has no ``Timecode`` column, lacks any of the 52 ARKit weight
        columns or repeats one, holds a value that is not a finite number or a weight outside [0, 1] (beyond
        :data:`WEIGHT_SLACK`), or has fewer than 2 frames.
    """
    import pandas as pd

    path = input_path(path, "Live Link Face CSV")
    positive_setting(timecode_rate, "timecode_rate")
    try:
        table = pd.read_csv(path, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as error:
        raise WorkbenchError(f"{path}: not a readable CSV ({single_line(error)})") from None
    table.columns = [str(column).strip() for column in table.columns]
    header = _header(path)
    repeated = sorted({name for name in header if header.count(name) > 1 and name in ARKIT_NAMES + ("Timecode",)})
    if repeated:
        raise WorkbenchError(f"{path}: column(s) {repeated} appear more than once; each ARKit channel needs one column")
    if "Timecode" not in table.columns:
        raise WorkbenchError(
            f"{path}: no 'Timecode' column; a Live Link Face CSV starts with Timecode, "
            "BlendShapeCount and the 52 ARKit weights"
        )
    missing = [name for name in ARKIT_NAMES if name not in table.columns]
    if missing:
        raise WorkbenchError(f"{path}: missing {len(missing)} of the 52 ARKit weight columns: {', '.join(missing)}")
    if len(table) < 2:
        raise WorkbenchError(f"{path}: {len(table)} frame(s); a take needs at least 2")
    weights = check_weight_range(_numeric_block(table, ARKIT_NAMES, path), ARKIT_NAMES, path)
    rotations = (
        _numeric_block(table, ROTATION_NAMES, path) if all(name in table.columns for name in ROTATION_NAMES) else None
    )
    seconds = parse_timecodes(table["Timecode"].tolist(), timecode_rate, path)
    return LiveLinkTake(
        names=ARKIT_NAMES,
        weights=weights,
        seconds=seconds,
        frame_rate=frame_rate_of(seconds, path, "timecodes"),
        rotations=rotations,
        path=path,
    )


def check_weight_range(weights: np.ndarray, names: Sequence[str], path: Path, first_row: int = 2) -> np.ndarray:
    """``weights`` (n_frames, n_channels) if every one is a fraction in [0, 1] (within :data:`WEIGHT_SLACK`),
    else a :class:`WorkbenchError` naming the row (``first_row`` is the first frame's) and the channel."""
    outside = (weights < -WEIGHT_SLACK) | (weights > 1.0 + WEIGHT_SLACK)
    if outside.any():
        row, column = np.argwhere(outside)[0]
        raise WorkbenchError(
            f"{path}: row {row + first_row}, column {names[column]}: weight {weights[row, column]:g} "
            f"is outside [0, 1] ({int(outside.sum())} such cells); ARKit weights are fractions, not "
            "percent"
        )
    return weights


def frame_rate_of(seconds: np.ndarray, path: Path, what: str, first_row: int = 2) -> float:
    """Frames per second of increasing frame times (the inverse of the median interval), or a
    :class:`WorkbenchError` naming the first row (``first_row`` is the first frame's) whose time does not increase."""
    steps = np.diff(seconds)
    if steps.size == 0 or np.any(~(steps > 0)):
        bad = int(np.argmax(~(steps > 0))) + first_row + 1 if steps.size else first_row
        raise WorkbenchError(f"{path}: {what} must increase from row to row (row {bad} does not)")
    return 1.0 / float(np.median(steps))


def _header(path: Path) -> list[str]:
    """The column names of a CSV's first line, as written (pandas renames repeated ones)."""
    import csv

    with open(path, newline="", encoding="utf-8", errors="replace") as handle:
        return [name.strip() for name in next(csv.reader(handle), [])]


def _numeric_block(table, columns: Sequence[str], path: Path) -> np.ndarray:
    import pandas as pd

    block = table[list(columns)].apply(pd.to_numeric, errors="coerce").to_numpy(dtype=np.float64)
    bad = ~np.isfinite(block)
    if bad.any():
        row, column = np.argwhere(bad)[0]
        raise WorkbenchError(
            f"{path}: row {row + 2}, column {columns[column]}: {table[columns[column]].iloc[row]!r} "
            f"is not a finite number ({int(bad.sum())} such cells)"
        )
    return block


@dataclass(frozen=True)
class ArkitMapping:
    """How ARKit channels drive the shapes of a blendshape basis.

    Attributes
    ----------
    channels : tuple of str
        ARKit channel names (rows of ``matrix``).
    shapes : tuple of str
        Basis shape names (columns of ``matrix``), in the basis order.
    matrix : ndarray of shape (n_channels, n_shapes)
        1 where a channel drives a shape: ``shape weights = channel weights @ matrix``.
    targets : dict
        Channel -> tuple of the shapes it drives (empty for an unmapped channel).
    unmapped : tuple of str
        Channels that drive no shape.
    undriven : tuple of str
        Basis shapes no channel drives.
    """

    channels: tuple[str, ...]
    shapes: tuple[str, ...]
    matrix: np.ndarray
    targets: dict
    unmapped: tuple[str, ...]
    undriven: tuple[str, ...]

    def describe(self) -> list[str]:
        """One line per fact worth reporting once: unmapped channels and undriven shapes."""
        lines = []
        if self.unmapped:
            lines.append(f"ARKit channels with no basis shape, ignored: {', '.join(self.unmapped)}")
        if self.undriven:
            lines.append(f"basis shapes no ARKit channel drives (left at 0): {', '.join(self.undriven)}")
        return lines


def arkit_target_names(channel: str, basis_names: Sequence[str]) -> tuple[str, ...]:
    """The basis shapes an ARKit channel drives under the naming rules.

    In order: the channel's name with a lower-case first letter (``JawOpen -> jawOpen``, ``MouthLeft ->
    mouthLeft``); ``...Left``/``...Right`` onto ``..._L``/``..._R`` (``MouthSmileLeft -> mouthSmile_L``); a
    channel without a side onto the basis's left/right pair (``BrowInnerUp -> browInnerUp_L, browInnerUp_R``).
    Empty when none of these names is in the basis.
    """
    available = set(basis_names)
    camel = channel[:1].lower() + channel[1:]
    if camel in available:
        return (camel,)
    for suffix, side in (("Left", "_L"), ("Right", "_R")):
        if camel.endswith(suffix) and camel[: -len(suffix)] + side in available:
            return (camel[: -len(suffix)] + side,)
    pair = (camel + "_L", camel + "_R")
    if all(name in available for name in pair):
        return pair
    return ()


def map_arkit_channels(
    channels: Sequence[str], basis_names: Sequence[str], overrides: Mapping[str, Sequence[str]] | None = None
) -> ArkitMapping:
    """Map ARKit channels onto the shapes of a blendshape basis by name (see :func:`arkit_target_names`).

    Parameters
    ----------
    channels : sequence of str
        ARKit channel names (usually :data:`ARKIT_NAMES`).
    basis_names : sequence of str
        The basis's shape names.
    overrides : mapping, optional
        Channel -> list of shape names, replacing the rule for that channel (an empty list leaves it unmapped);
        a channel's first letter may be of either case.

    Returns
    -------
    ArkitMapping

    Raises
    ------
    WorkbenchError
        If an override names an unknown channel or a shape the basis does not have.
    """
    # the same override table serves Live Link (TongueOut) and MediaPipe (tongueOut) channel names
    same_channel = {channel[:1].lower() + channel[1:]: channel for channel in channels}
    overrides = {same_channel.get(key[:1].lower() + key[1:], key): value for key, value in (overrides or {}).items()}
    unknown = [channel for channel in overrides if channel not in channels]
    if unknown:
        raise WorkbenchError(f"arkit_overrides names channel(s) {unknown} that are not ARKit channels {list(channels)}")
    matrix = np.zeros((len(channels), len(basis_names)))
    column = {name: j for j, name in enumerate(basis_names)}
    targets = {}
    for i, channel in enumerate(channels):
        if channel in overrides:
            chosen = tuple(overrides[channel] or ())
            bad = [name for name in chosen if name not in column]
            if bad:
                raise WorkbenchError(f"arkit_overrides.{channel} names shape(s) {bad} the basis does not have")
        else:
            chosen = arkit_target_names(channel, basis_names)
        targets[channel] = chosen
        for name in chosen:
            matrix[i, column[name]] = 1.0
    unmapped = tuple(channel for channel in channels if not targets[channel])
    undriven = tuple(name for j, name in enumerate(basis_names) if not matrix[:, j].any())
    return ArkitMapping(
        channels=tuple(channels),
        shapes=tuple(basis_names),
        matrix=matrix,
        targets=targets,
        unmapped=unmapped,
        undriven=undriven,
    )


def drive_blendshapes(channel_weights: np.ndarray, mapping: ArkitMapping, deltas: np.ndarray) -> np.ndarray:
    """Displacements of a linear blendshape face driven by channel weights (eq. 1 without ``v0``).

    Parameters
    ----------
    channel_weights : ndarray of shape (n_frames, n_channels)
    mapping : ArkitMapping
        Its ``shapes`` are the rows of ``deltas``.
    deltas : ndarray of shape (n_shapes, n_dims)
        Shape displacements, flattened.

    Returns
    -------
    ndarray of shape (n_frames, n_dims)
    """
    return (channel_weights @ mapping.matrix) @ deltas
