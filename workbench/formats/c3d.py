"""Labelled optical markers from C3D files (read with the ``c3d`` package from PyPI).

Positions are converted to millimetres from the file's ``POINT:UNITS``; samples the file marks invalid (a
negative residual, the C3D convention for a gap), and samples holding NaN or Inf (some exporters' gaps), become NaN.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.files import input_path

MM_PER_UNIT = {
    "mm": 1.0,
    "millimeter": 1.0,
    "millimetre": 1.0,
    "cm": 10.0,
    "m": 1000.0,
    "meter": 1000.0,
    "metre": 1000.0,
    "in": 25.4,
    "inch": 25.4,
}


@dataclass(frozen=True)
class MarkerTake:
    """One C3D take.

    Attributes
    ----------
    labels : tuple of str
        Marker labels, in the file's order (surrounding blanks removed).
    positions : ndarray of shape (n_frames, n_markers, 3)
        Positions in millimetres; NaN where the file marks a sample invalid.
    frame_rate : float
        ``POINT:RATE`` in frames per second.
    units : str
        The file's ``POINT:UNITS`` (converted to mm in ``positions``).
    first_frame : int
        Number of the first frame in the file.
    path : pathlib.Path
    """

    labels: tuple[str, ...]
    positions: np.ndarray
    frame_rate: float
    units: str
    first_frame: int
    path: Path

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def n_missing(self) -> int:
        """Samples (marker, frame) with no position."""
        return int(np.isnan(self.positions[..., 0]).sum())

    def index_of(self, labels: Sequence[str], *, named_in: str) -> np.ndarray:
        """Positions of ``labels`` in :attr:`labels`, with a clear error for a label the file does not have.

        Parameters
        ----------
        labels : sequence of str
        named_in : str
            Where the labels come from (for the error message), e.g. ``"dataset.rigid_markers"``.

        Returns
        -------
        ndarray of shape (len(labels),) of int
        """
        position = {label: i for i, label in enumerate(self.labels)}
        unknown = [label for label in labels if label not in position]
        if unknown:
            raise WorkbenchError(
                f"{self.path}: unknown marker label(s) {unknown} named in {named_in}; the file's "
                f"{len(self.labels)} labels are {', '.join(self.labels)}"
            )
        index = np.array([position[label] for label in labels], dtype=np.int64)
        never = [label for label, seen in zip(labels, np.isfinite(self.positions[:, index, 0]).any(axis=0)) if not seen]
        if never:
            raise WorkbenchError(
                f"{self.path}: marker(s) {never} named in {named_in} have no sample in any of the "
                f"take's {self.n_frames} frames; a marker never seen cannot be used: leave it out of "
                f"{named_in}"
            )
        return index


def units_to_mm(units: str, path: Path) -> float:
    """Millimetres per unit of a C3D ``POINT:UNITS`` string."""
    key = units.strip().lower()
    if key not in MM_PER_UNIT:
        raise WorkbenchError(f"{path}: POINT:UNITS {units.strip()!r} is not one of {sorted(set(MM_PER_UNIT))}")
    return MM_PER_UNIT[key]


def point_labels(reader) -> tuple[str, ...]:
    """Every marker label of a C3D file, surrounding blanks removed.

    A parameter holds at most 255 entries, so files with more markers (Vicon's, among others) continue the list in
    ``POINT:LABELS2``, ``POINT:LABELS3``, ...; they are read in that order until one is missing.
    """
    labels, group = [], 1
    while (parameter := reader.get("POINT:LABELS" + (str(group) if group > 1 else ""))) is not None:
        labels += [str(label).strip() for label in parameter.string_array]
        group += 1
    return tuple(labels)


HEADER_FRAME_LIMIT = 65535
"""The header stores its first and last frame numbers in 16 bits; longer takes give theirs in the TRIAL
parameters, and the header's last frame may then wrap."""


def check_frame_range(reader, path: Path) -> None:
    """The frame numbers of a C3D's header (and of its ``TRIAL`` parameters, which the reader prefers) run
    forwards: a last frame before the first is a damaged header, not an empty take."""
    for where, first, last in (
        ("header", reader.header.first_frame, reader.header.last_frame),
        ("TRIAL:ACTUAL_START_FIELD/END_FIELD", reader.first_frame, reader.last_frame),
    ):
        wrapped = where == "header" and reader.last_frame > HEADER_FRAME_LIMIT
        if int(last) < int(first) and not wrapped:
            raise WorkbenchError(
                f"{path}: its {where} says the last frame ({int(last)}) precedes the first "
                f"({int(first)}); a damaged header (frame numbers must run forwards)"
            )


def read_c3d_markers(path: str | os.PathLike) -> MarkerTake:
    """Read the labelled 3-D marker trajectories of a C3D file, in millimetres.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    MarkerTake
        ``labels`` (one per marker), ``positions`` of shape (n_frames, n_markers, 3) in mm with NaN at gaps,
        ``frame_rate`` in Hz.

    Raises
    ------
    WorkbenchError
        If the file is missing, not a C3D file, truncated (fewer frames than its header declares), has no
        markers, a label count other than its marker count, duplicate labels or unknown units.
    """
    import c3d

    path = input_path(path, "C3D file")
    with open(path, "rb") as handle, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the reader warns (rather than fails) on a short file: checked below
        try:
            reader = c3d.Reader(handle)
            check_frame_range(reader, path)
            declared = reader.last_frame - reader.first_frame + 1
            labels = point_labels(reader)
            n_markers = int(reader.point_used)
            units_parameter = reader.get("POINT:UNITS")
            units = units_parameter.string_value if units_parameter is not None else "mm"
            frame_rate = float(reader.point_rate)
            if not frame_rate > 0:  # before the frames: the reader divides by it
                raise WorkbenchError(f"{path}: POINT:RATE (the frame rate) must be positive, got {frame_rate}")
            frames = [points[:, :4].astype(np.float64) for _, points, _ in reader.read_frames(copy=True)]
        except WorkbenchError:
            raise
        except Exception as error:  # the reader raises many kinds of error on a damaged file
            raise WorkbenchError(f"{path}: not a readable C3D file ({type(error).__name__}: {error})") from None
    if len(labels) != n_markers:
        raise WorkbenchError(
            f"{path}: {len(labels)} labels in POINT:LABELS, LABELS2, ... for {n_markers} markers "
            "(POINT:USED); every marker needs one label"
        )
    if len(frames) < declared:
        raise WorkbenchError(
            f"{path}: truncated: its header declares {declared} frames but the data ends after {len(frames)}"
        )
    if not labels or not frames:
        raise WorkbenchError(f"{path}: holds no marker trajectories ({len(labels)} labels, {len(frames)} frames)")
    if len(frames) < 2:
        raise WorkbenchError(
            f"{path}: holds {len(frames)} frame; a take needs at least 2 (its motion is what is measured)"
        )
    if len(set(labels)) != len(labels):
        duplicates = sorted({label for label in labels if labels.count(label) > 1})
        raise WorkbenchError(f"{path}: duplicate marker labels {duplicates}")
    data = np.stack(frames)
    positions = data[:, :, :3] * units_to_mm(units, path)
    # A sample is missing when the file marks it invalid, or when it holds NaN or Inf where a position should be.
    positions[(data[:, :, 3] < 0) | ~np.all(np.isfinite(positions), axis=2)] = np.nan
    return MarkerTake(
        labels=labels,
        positions=positions,
        frame_rate=frame_rate,
        units=units.strip(),
        first_frame=int(reader.first_frame),
        path=path,
    )
