"""Named blendshape weight curves beyond Live Link Face: MediaPipe face blendshapes and generic CSV/JSON files.

Every reader returns a :class:`~workbench.formats.livelink.LiveLinkTake` (names, weights per frame, times, frame
rate), so the curves drive a blendshape folder by name through the same ARKit naming rule and override table
(``dataset.arkit_overrides``). MediaPipe's names are ARKit's in camelCase (``jawOpen``, ``mouthSmileLeft``), which
the rule maps as it maps Live Link Face's; its ``_neutral`` score is not a shape and is dropped.

Layouts read (:func:`read_weight_curves`):

- Live Link Face CSV (``Timecode``, ``BlendShapeCount``, ...): :func:`~workbench.formats.livelink.read_livelink_csv`;
- CSV with a time column (``time`` in seconds or ``timestamp_ms``) or a ``frame`` column (then ``frame_rate`` is
  needed), and one column per named weight;
- JSON object ``{"names": [...], "weights": [[...], ...], "time": [...]}`` (or ``"frame_rate"`` instead of
  ``"time"``);
- JSON list of MediaPipe face-landmarker results, one per frame: ``{"timestamp_ms": t, "face_blendshapes":
  [[{"category_name": n, "score": s}, ...]]}`` (the camelCase keys ``timestampMs``, ``faceBlendshapes``,
  ``categoryName`` and a ``{"categories": [...]}`` wrapper are read too).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError, single_line
from workbench.core.files import input_path
from workbench.formats.livelink import (
    LiveLinkTake,
    _numeric_block,
    check_weight_range,
    frame_rate_of,
    read_livelink_csv,
)
from workbench.settings.rules import positive_setting

MEDIAPIPE_NEUTRAL = "_neutral"
TIME_COLUMNS = {"time": 1.0, "timestamp_ms": 1e-3}
"""Time column -> seconds per unit."""


def read_weight_curves(
    path: str | os.PathLike, *, frame_rate: float | None = None, timecode_rate: float = 60.0
) -> LiveLinkTake:
    """Read named weight curves from a CSV or JSON file in any layout of this module: Live Link Face, MediaPipe face
    blendshapes, or a generic table.

    Parameters
    ----------
    path : path-like
    frame_rate : float, optional
        Frames per second, for files that number frames instead of timing them.
    timecode_rate : float
        For Live Link Face CSV files (see :func:`~workbench.formats.livelink.read_livelink_csv`).

    Returns
    -------
    LiveLinkTake
        ``rotations`` is None for every layout but Live Link Face's.

    Raises
    ------
    WorkbenchError
        Naming the file, row and column: a missing file, an unknown layout, no time or frame column (or a frame
        column without ``frame_rate``), repeated names, a value that is not a finite number or a weight outside
        [0, 1], times that do not increase, fewer than 2 frames.
    """
    path = input_path(path, "weight-curve file")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        from workbench.formats.livelink import _header

        if "Timecode" in _header(path):
            return read_livelink_csv(path, timecode_rate=timecode_rate)
        return _read_csv_curves(path, frame_rate)
    if suffix == ".json":
        try:
            document = json.loads(path.read_text())
        except (ValueError, UnicodeDecodeError) as error:
            raise WorkbenchError(f"{path}: not valid JSON ({error})") from None
        except RecursionError:
            raise WorkbenchError(
                f"{path}: JSON nested too deeply to be weight curves (an object of names, weights "
                "and times, or a list of MediaPipe results, is nested a few levels)"
            ) from None
        if isinstance(document, list):
            return _mediapipe_curves(document, path, frame_rate)
        if isinstance(document, dict):
            return _json_curves(document, path, frame_rate)
        raise WorkbenchError(f"{path}: JSON must be an object (names, weights, time) or a list of MediaPipe results")
    raise WorkbenchError(f"{path}: weight curves must be a .csv or .json file")


def _take(names: Sequence[str], weights: np.ndarray, seconds: np.ndarray, path: Path, first_row: int) -> LiveLinkTake:
    """Check and assemble curves: distinct names, at least 2 frames, weights in [0, 1], increasing times;
    MediaPipe's ``_neutral`` dropped."""
    names = [str(name) for name in names]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise WorkbenchError(f"{path}: weight name(s) {repeated} appear more than once")
    keep = [i for i, name in enumerate(names) if name != MEDIAPIPE_NEUTRAL]
    if not keep:
        raise WorkbenchError(f"{path}: no named weight columns")
    if len(weights) < 2:
        raise WorkbenchError(f"{path}: {len(weights)} frame(s); a take needs at least 2")
    names, weights = [names[i] for i in keep], weights[:, keep]
    check_weight_range(weights, names, path, first_row)
    rate = frame_rate_of(seconds, path, "frame times", first_row)
    return LiveLinkTake(
        names=tuple(names), weights=weights, seconds=seconds - seconds[0], frame_rate=rate, rotations=None, path=path
    )


def _frame_seconds(frames: np.ndarray, frame_rate: float | None, path: Path) -> np.ndarray:
    if frame_rate is None:
        raise WorkbenchError(f"{path}: frames are numbered, not timed: set the frame rate (dataset.weight_frame_rate)")
    return frames / positive_setting(frame_rate, f"{path}: frame rate")


def _read_csv_curves(path: Path, frame_rate: float | None) -> LiveLinkTake:
    import pandas as pd

    from workbench.formats.livelink import _header

    try:
        table = pd.read_csv(path, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as error:
        raise WorkbenchError(f"{path}: not a readable CSV ({single_line(error)})") from None
    header = _header(path)
    table.columns = header if len(header) == len(table.columns) else [str(c).strip() for c in table.columns]
    timing = [column for column in (*TIME_COLUMNS, "frame") if column in table.columns]
    if not timing:
        raise WorkbenchError(
            f"{path}: no time column ({', '.join(TIME_COLUMNS)}) or frame column ('frame'); "
            "the first columns must say when each row was captured"
        )
    names = [column for column in table.columns if column not in (*TIME_COLUMNS, "frame")]
    if len(set(table.columns)) != len(table.columns):
        repeated = sorted({name for name in table.columns if list(table.columns).count(name) > 1})
        raise WorkbenchError(f"{path}: column(s) {repeated} appear more than once")
    weights = _numeric_block(table, names, path)
    clock = _numeric_block(table, [timing[0]], path)[:, 0]
    seconds = clock * TIME_COLUMNS[timing[0]] if timing[0] in TIME_COLUMNS else _frame_seconds(clock, frame_rate, path)
    return _take(names, weights, seconds, path, first_row=2)


def _json_curves(document: Mapping, path: Path, frame_rate: float | None) -> LiveLinkTake:
    names, weights = document.get("names"), document.get("weights")
    if not isinstance(names, list) or not isinstance(weights, list):
        raise WorkbenchError(
            f"{path}: a JSON object of weight curves needs 'names' (list) and 'weights' (one list of numbers per frame)"
        )
    try:
        matrix = np.array(weights, dtype=np.float64)
    except (TypeError, ValueError):
        raise WorkbenchError(f"{path}: 'weights' must be a list of equally long lists of numbers") from None
    if matrix.ndim != 2 or matrix.shape[1] != len(names):
        raise WorkbenchError(
            f"{path}: 'weights' must have one row per frame of {len(names)} numbers (one per "
            f"name), got shape {matrix.shape}"
        )
    _check_finite(matrix, names, path, first_row=0)
    rate = document.get("frame_rate", frame_rate)
    if "time" in document:
        times = document["time"]
        if (
            not isinstance(times, list)
            or len(times) != len(matrix)
            or not all(_is_number(time) and np.isfinite(time) for time in times)
        ):
            raise WorkbenchError(f"{path}: 'time' must hold {len(matrix)} finite numbers (seconds), one per frame")
        seconds = np.array(times, dtype=np.float64)
    else:
        seconds = _frame_seconds(np.arange(len(matrix), dtype=np.float64), rate, path)
    return _take(names, matrix, seconds, path, first_row=0)


def _check_finite(matrix: np.ndarray, names: Sequence[str], path: Path, first_row: int) -> None:
    bad = ~np.isfinite(matrix)
    if bad.any():
        row, column = np.argwhere(bad)[0]
        raise WorkbenchError(
            f"{path}: frame {row + first_row}, weight {names[column]}: not a finite number "
            f"({int(bad.sum())} such values)"
        )


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _first(item: Mapping, *keys):
    return next((item[key] for key in keys if key in item), None)


def _mediapipe_curves(results: list, path: Path, frame_rate: float | None) -> LiveLinkTake:
    """Curves from a list of MediaPipe face-landmarker results (one per frame, the first face's blendshapes)."""
    names, rows, times = None, [], []
    for number, result in enumerate(results):
        faces = _first(result, "face_blendshapes", "faceBlendshapes") if isinstance(result, Mapping) else None
        if not isinstance(faces, list) or not faces:
            raise WorkbenchError(
                f"{path}: frame {number}: no face_blendshapes (a MediaPipe result per frame, with at least one face)"
            )
        face = faces[0]
        categories = face.get("categories") if isinstance(face, Mapping) else face
        try:
            pairs = [(str(_first(c, "category_name", "categoryName")), float(c["score"])) for c in categories]
        except (TypeError, KeyError, ValueError):
            raise WorkbenchError(f"{path}: frame {number}: categories need category_name and a numeric score") from None
        frame_names = [name for name, _ in pairs]
        if names is None:
            names = frame_names
        elif frame_names != names:
            raise WorkbenchError(
                f"{path}: frame {number}: its blendshape names differ from frame 0's; every frame "
                "needs the same categories in the same order"
            )
        rows.append([score for _, score in pairs])
        times.append(_first(result, "timestamp_ms", "timestampMs"))
    if names is None:
        raise WorkbenchError(f"{path}: no frames")
    matrix = np.array(rows, dtype=np.float64)
    _check_finite(matrix, names, path, first_row=0)
    timed = [time is not None for time in times]
    if any(timed) and not all(timed):
        raise WorkbenchError(
            f"{path}: frame {timed.index(False)} has no timestamp_ms but frame {timed.index(True)} "
            "has one; every frame needs one, or none (then the frame rate numbers them)"
        )
    bad = next((number for number, time in enumerate(times) if time is not None and not _is_number(time)), None)
    if bad is not None:
        raise WorkbenchError(f"{path}: frame {bad}: timestamp_ms {times[bad]!r} is not a number (milliseconds)")
    if all(timed):
        seconds = np.array(times, dtype=np.float64) * 1e-3
    else:
        seconds = _frame_seconds(np.arange(len(matrix), dtype=np.float64), frame_rate, path)
    return _take(names, matrix, seconds, path, first_row=0)
