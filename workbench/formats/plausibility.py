"""Plausibility checks on captures and shapes, for every loader to call at its boundary.

Each check returns the problems it found, one sentence each naming the file, take, marker or vertex and the rule
broken; :func:`settle` turns them into a one-line error (``dataset.plausibility: error``, the default) or keeps
them as warnings (``warn``: printed above the alpha table as notes and listed in ``metrics.json`` under the
dataset's ``provenance.plausibility_warnings``), for a researcher who wants the data as it is. Settings that
cannot be meant (a rigid-marker set with a repeated or collinear marker) are always errors.
"""

from __future__ import annotations

import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError


@dataclass(frozen=True)
class Limits:
    """What a face capture can plausibly hold.

    Attributes
    ----------
    face_spread_mm : tuple of float
        Range of a take's face size: the median, over frames, of the markers' median distance from their centroid
        (a human face: about 40-90 mm). Outside it the take's units are not what the file says.
    take_spread_ratio : float
        Largest ratio of face sizes between two takes of one capture (one performer, one marker set).
    outlier_factor : float
        A sample is an outlier when its distance from its marker's median position exceeds this many times the
        larger of the marker's own 90th-percentile distance and the median of that over all markers.
    mesh_outlier_factor : float
        A mesh vertex is an outlier when its distance (along its worst axis) from the neutral's median vertex
        exceeds this many times the neutral's 90th-percentile distance.
    used_weight : float
        A blendshape channel is used by a take when its weight exceeds this in some frame.
    rigid_flatness : float
        A rigid-marker set is degenerate (collinear) when its second singular value is below this fraction of its
        first.
    jump_factor : float
        A vertex of a mesh sequence jumps when it moves farther than this many times the face's extent (as in
        ``mesh_outlier_factor``) from one frame to the next: a face moves a few millimetres a frame. The markers of
        a take jump when their median move from one frame to the next is farther than this many times the take's
        face size (:func:`face_spread`).
    static_fraction : float
        A mesh sequence is static when no vertex ever moves farther than this fraction of the face's extent from
        the first frame; a take of markers, when no marker moves farther than this fraction of its face size.
    static_weight : float
        A take of blendshape weights is static when no channel's weight ever changes by more than this.
    frame_rate_hz : tuple of float
        Range of frame rates of a face capture: optical systems and phones record at 24-1000 Hz, high-speed
        cameras at a few thousand; outside it the rate (or the time stamps) are in other units.
    face_extent_mm : tuple of float
        Range of the neutral face's extent in mm (the longest side of its bounding box): a human face, or a head
        with its face, spans about 100-300 mm; outside the range the mesh's unit (``unit_mm``) is wrong by a factor
        such as 10 or 1000.
    """

    face_spread_mm: tuple = (20.0, 500.0)
    take_spread_ratio: float = 3.0
    outlier_factor: float = 20.0
    mesh_outlier_factor: float = 20.0
    used_weight: float = 0.05
    rigid_flatness: float = 0.02
    jump_factor: float = 1.0
    static_fraction: float = 1e-4
    static_weight: float = 1e-3
    frame_rate_hz: tuple = (1.0, 10_000.0)
    face_extent_mm: tuple = (40.0, 1000.0)


LIMITS = Limits()


def settle(problems: Sequence[str], policy: str) -> list[str]:
    """Raise the first problem as a one-line error under ``error``; return them all as warnings under ``warn``."""
    if problems and policy == "error":
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise WorkbenchError(f"{problems[0]}{more}; set dataset.plausibility=warn to use the data anyway")
    return list(problems)


def with_warnings(notes: Sequence[str], provenance: Mapping, warnings: Sequence[str]) -> dict:
    """A capture's ``notes`` and ``provenance`` with the plausibility warnings added: ``WARNING:`` notes are
    printed above the alpha table, ``provenance.plausibility_warnings`` goes into ``metrics.json``."""
    return {
        "notes": tuple(notes) + tuple(f"WARNING: {warning}" for warning in warnings),
        "provenance": dict(provenance, **({"plausibility_warnings": list(warnings)} if warnings else {})),
    }


def face_spread(positions: np.ndarray) -> float:
    """A take's face size in its units: the median over frames of the markers' median distance from their centroid.

    Parameters
    ----------
    positions : ndarray of shape (n_frames, n_markers, 3)
        NaN where a sample is missing.
    """
    with _quiet_nan():
        centred = positions - np.nanmean(positions, axis=1, keepdims=True)
        return float(np.nanmedian(np.nanmedian(np.linalg.norm(centred, axis=2), axis=1)))


@contextmanager
def _quiet_nan():
    """Silence NumPy's warnings about all-NaN slices (a frame or marker with no sample has no statistic; NaN
    compares false, so it breaks no rule)."""
    with warnings.catch_warnings(), np.errstate(invalid="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


def take_units_problems(spreads: Mapping[str, float], units: Mapping[str, str]) -> list[str]:
    """Per-take unit consistency: every take's face size (:func:`face_spread`, in mm) within
    :attr:`Limits.face_spread_mm` and within :attr:`Limits.take_spread_ratio` of the other takes'.

    Parameters
    ----------
    spreads : mapping
        Take (file) -> face size in mm.
    units : mapping
        Take -> the units its file declares.
    """
    low, high = LIMITS.face_spread_mm
    problems = [
        f"{take}: markers spread {spread:.3g} mm from their centroid (file units {units[take]!r}); a face "
        f"spans {low:g}-{high:g} mm, so the take's units are not what the file says"
        for take, spread in spreads.items()
        if not low <= spread <= high
    ]
    plausible = {take: spread for take, spread in spreads.items() if low <= spread <= high}
    if len(plausible) > 1:  # the smallest and largest face, not each against the median (two takes: their mean)
        smallest, largest = min(plausible, key=plausible.get), max(plausible, key=plausible.get)
        if plausible[largest] > LIMITS.take_spread_ratio * plausible[smallest]:
            problems.append(
                f"{largest}: markers spread {plausible[largest]:.3g} mm from their centroid against "
                f"{plausible[smallest]:.3g} mm in {smallest} (more than {LIMITS.take_spread_ratio:g} x "
                "apart, one performer and one marker set); the takes' units or scales differ"
            )
    return problems


def parked_marker_problems(positions: np.ndarray, labels: Sequence[str], source: str) -> list[str]:
    """Markers parked at the origin: samples exactly at (0, 0, 0), which exporters write for a gap.

    Parameters
    ----------
    positions : ndarray of shape (n_frames, n_markers, 3)
    labels : sequence of str
    source : str
        The file, for the message.
    """
    parked = np.all(positions == 0.0, axis=2)
    return [
        f"{source}: marker {labels[j]} is at the origin (0, 0, 0) in {int(parked[:, j].sum())} frame(s) (first: "
        f"frame {int(np.argmax(parked[:, j]))}); a marker on a face is never exactly there (an exporter's gap "
        "written as zeros)"
        for j in np.flatnonzero(parked.any(axis=0))
    ]


def take_motion_problems(positions: np.ndarray, source: str, units: str) -> list[str]:
    """The markers of a take jumping together from one frame to the next (their median move beyond
    :attr:`Limits.jump_factor` x the take's face size: a head moves a few millimetres a frame, so such a take
    joins two recordings or changes units part way), or a take that never moves (no marker farther than
    :attr:`Limits.static_fraction` x the face size from the first frame). Single markers far from their place are
    :func:`outlier_problems`'.

    Parameters
    ----------
    positions : ndarray of shape (n_frames, n_markers, 3)
        As read (head motion included); NaN where missing.
    source : str
    units : str
        The take's units, for the message.
    """
    if len(positions) < 2:
        return []
    spread = face_spread(positions)
    with _quiet_nan():
        step = np.nanmedian(np.linalg.norm(np.diff(positions, axis=0), axis=2), axis=1)
        beyond = np.flatnonzero(step > LIMITS.jump_factor * spread)
        largest = float(np.nanmax(np.linalg.norm(positions - positions[:1], axis=2), initial=0.0))
    problems = []
    if beyond.size:
        frame = int(beyond[0])
        problems.append(
            f"{source}: the markers jump {step[frame]:.3g} {units} together (median over markers) from frame "
            f"{frame} to frame {frame + 1} ({beyond.size} such frame(s)), more than {LIMITS.jump_factor:g} x the "
            f"face's size ({spread:.3g} {units}); a head moves a few millimetres a frame"
        )
    if largest <= LIMITS.static_fraction * spread:
        problems.append(
            f"{source}: the take is static: no marker moves more than {largest:.3g} {units} from the first frame "
            "(a face that does not move has no motion to fit)"
        )
    return problems


def outlier_problems(
    positions: np.ndarray, labels: Sequence[str], source: str, frames: np.ndarray | None = None
) -> list[str]:
    """Samples far beyond the capture's own spread, per marker (robust: medians and percentiles, not means).

    Parameters
    ----------
    positions : ndarray of shape (n_frames, n_markers, 3)
        In the head's frame (head motion removed); NaN where missing.
    labels : sequence of str
    source : str
    frames : ndarray of shape (n_frames,), optional
        Frame numbers in the file, for the message (0-based positions when None).
    """
    if len(positions) < 3:
        return []
    with _quiet_nan():
        distance = np.linalg.norm(positions - np.nanmedian(positions, axis=0), axis=2)
        own = np.nanpercentile(distance, 90, axis=0)
        scale = np.maximum(own, np.nanmedian(own))
        limit = LIMITS.outlier_factor * scale
        far = distance > limit
    problems = []
    for j in np.flatnonzero(far.any(axis=0)):
        worst = int(np.nanargmax(np.where(far[:, j], distance[:, j], -np.inf)))
        frame = int(frames[worst]) if frames is not None else worst
        problems.append(
            f"{source}: marker {labels[j]} is {distance[worst, j]:.3g} mm from its median position in "
            f"frame {frame} ({int(far[:, j].sum())} such sample(s)), more than {LIMITS.outlier_factor:g} x "
            f"the capture's spread ({scale[j]:.3g} mm)"
        )
    return problems


def mesh_outlier_problems(vertices: np.ndarray, neutral: np.ndarray, source: str, unit: str = "units") -> list[str]:
    """Vertices of a mesh far from the neutral face (a coordinate typed wrong, a vertex at 1e6).

    Parameters
    ----------
    vertices : ndarray of shape (n_vertices, 3)
        The mesh (the neutral itself or an expression of the same topology).
    neutral : ndarray of shape (n_vertices, 3)
    source : str
    unit : str
        The coordinates' unit, for the message.
    """
    # distances along the worst axis (not Euclidean): a coordinate of 1e300 must not overflow to inf
    centre = np.median(neutral, axis=0)
    scale = float(np.percentile(np.abs(neutral - centre).max(axis=1), 90))
    distance = np.abs(vertices - centre).max(axis=1)
    far = ~(distance <= LIMITS.mesh_outlier_factor * scale)
    if not far.any():
        return []
    worst = int(np.argmax(np.where(far, np.nan_to_num(distance, nan=np.inf), -np.inf)))
    return [
        f"{source}: vertex {worst} lies {distance[worst]:.3g} {unit} from the face's centre along an axis "
        f"({int(far.sum())} such vertices), more than {LIMITS.mesh_outlier_factor:g} x the neutral face's extent "
        f"({scale:.3g} {unit})"
    ]


def face_size_problems(neutral: np.ndarray, source: str, setting: str, unit_mm: float) -> list[str]:
    """The neutral face's extent (the longest side of its bounding box, in mm) outside
    :attr:`Limits.face_extent_mm`: its unit setting is off by a factor.

    Parameters
    ----------
    neutral : ndarray of shape (n_vertices, 3)
        The neutral face in mm (file units times ``unit_mm``).
    source : str
        The file (or folder) the face was read from.
    setting : str
        The setting that scales it to mm, named in the message (``dataset.blendshapes.unit_mm``).
    unit_mm : float
        Its value: millimetres per file unit.
    """
    low, high = LIMITS.face_extent_mm
    with np.errstate(over="ignore", invalid="ignore"):
        extent = float(np.max(np.ptp(np.asarray(neutral, dtype=np.float64), axis=0))) if len(neutral) else 0.0
    if low <= extent <= high:
        return []
    return [
        f"{source}: with {setting}={unit_mm:g} the neutral face spans {extent:.3g} mm, not a human face's size "
        f"({low:g}-{high:g} mm); {setting} (mm per file unit) is off by a factor"
    ]


def frame_rate_problems(rate: float, source: str, what: str = "frame rate") -> list[str]:
    """A capture's frame rate outside :attr:`Limits.frame_rate_hz`."""
    low, high = LIMITS.frame_rate_hz
    if low <= rate <= high:
        return []
    return [
        f"{source}: {what} {rate:.6g} frames per second is not a face capture's ({low:g}-{high:g}); the rate or "
        "the time stamps are in other units"
    ]


def static_weights_problems(weights: np.ndarray, source: str) -> list[str]:
    """A take of blendshape weights in which no channel moves (a frozen export, one frame repeated).

    Parameters
    ----------
    weights : ndarray of shape (n_frames, n_channels)
    source : str
    """
    change = float(np.max(np.ptp(weights, axis=0), initial=0.0))
    if change > LIMITS.static_weight:
        return []
    return [
        f"{source}: the take is static: no weight changes by more than {change:.3g} over its {len(weights)} "
        "frames (a face that does not move has no motion to fit)"
    ]


def _first_beyond(values: np.ndarray, limit: float, start: int) -> tuple[tuple | None, int]:
    """The first frame with a value above ``limit`` as (frame + ``start``, vertex, value) at its largest value, or
    None, and how many frames have one.

    Parameters
    ----------
    values : ndarray of shape (n_frames, n_vertices)
    """
    beyond = (values > limit).any(axis=1)
    if not beyond.any():
        return None, 0
    frame = int(np.argmax(beyond))
    vertex = int(np.argmax(values[frame]))
    return (start + frame, vertex, float(values[frame, vertex])), int(beyond.sum())


class SequenceMotion:
    """Plausibility of a mesh sequence, gathered a chunk of frames at a time: vertices far outside the face,
    vertices jumping between consecutive frames, and a sequence that never moves.

    Parameters
    ----------
    source : str
        The file, for the messages.
    unit : str
        The coordinates' unit, for the messages.
    """

    def __init__(self, source: str, unit: str = "file units"):
        self.source, self.unit = source, unit
        self.reference = self.centre = self.last = None
        self.scale = 0.0
        self.outlier = self.jump = None  # (frame, vertex, distance) of the first one
        self.n_outlier_frames = self.n_jumps = 0
        self.largest_motion = 0.0

    def add(self, start: int, chunk: np.ndarray) -> None:
        """Frames ``start:start + len(chunk)``, shape (n, n_vertices, 3), finite."""
        if self.reference is None:
            self.reference = chunk[0].astype(np.float64)
            self.centre = np.median(self.reference, axis=0)
            self.scale = float(np.percentile(np.abs(self.reference - self.centre).max(axis=1), 90))
        distance = np.abs(chunk - self.centre).max(axis=2)
        first, count = _first_beyond(distance, LIMITS.mesh_outlier_factor * self.scale, start)
        self.outlier, self.n_outlier_frames = self.outlier or first, self.n_outlier_frames + count
        previous = chunk[:1] if self.last is None else self.last[None]
        step = np.linalg.norm(np.diff(np.concatenate([previous, chunk]), axis=0), axis=2)
        first, count = _first_beyond(step, LIMITS.jump_factor * self.scale, start)
        self.jump, self.n_jumps = self.jump or first, self.n_jumps + count
        self.last = chunk[-1].astype(np.float64)
        self.largest_motion = max(
            self.largest_motion, float(np.linalg.norm(chunk - self.reference, axis=2).max(initial=0.0))
        )

    def problems(self) -> list[str]:
        found = []
        if self.outlier is not None:
            frame, vertex, distance = self.outlier
            found.append(
                f"{self.source}: frame {frame}, vertex {vertex} lies {distance:.3g} {self.unit} from the "
                f"face's centre along an axis ({self.n_outlier_frames} such frame(s)), more than "
                f"{LIMITS.mesh_outlier_factor:g} x the face's extent ({self.scale:.3g} {self.unit})"
            )
        if self.jump is not None:
            frame, vertex, distance = self.jump
            found.append(
                f"{self.source}: vertex {vertex} jumps {distance:.3g} {self.unit} from frame {frame - 1} to "
                f"frame {frame} ({self.n_jumps} such frame(s)), more than {LIMITS.jump_factor:g} x the face's "
                f"extent ({self.scale:.3g} {self.unit}); a face moves a few millimetres a frame"
            )
        if self.reference is not None and self.largest_motion <= LIMITS.static_fraction * self.scale:
            found.append(
                f"{self.source}: the sequence is static: no vertex moves more than {self.largest_motion:.3g} "
                f"{self.unit} from the first frame (a face that does not move has no motion to fit)"
            )
        return found


def unused_channel_problems(
    unmapped: Sequence[str], channels: Sequence[str], weights: np.ndarray, source: str
) -> list[str]:
    """Channels a take uses that no basis shape stands for (their shapes missing from the folder).

    Parameters
    ----------
    unmapped : sequence of str
        Channels with no basis shape (leave out those the config drops on purpose).
    channels : sequence of str
        The take's channels, the columns of ``weights``.
    weights : ndarray of shape (n_frames, n_channels)
    source : str
    """
    peak = {channel: float(np.nanmax(np.abs(weights[:, channels.index(channel)]))) for channel in unmapped}
    used = {channel: value for channel, value in peak.items() if value > LIMITS.used_weight}
    if not used:
        return []
    listed = ", ".join(f"{channel} (max weight {value:.2f})" for channel, value in used.items())
    return [
        f"{source}: the take uses channel(s) {listed} but the blendshape folder has no shape for them (their "
        "OBJ files are missing), so that motion would be left out; to leave a channel out on purpose, map it to "
        "no shape (dataset.arkit_overrides: {CHANNEL: []})"
    ]


def check_rigid_set(labels: Sequence[str], reference: np.ndarray, source: str) -> None:
    """A rigid-marker set that can fix a head pose: distinct markers, at least 3, not collinear.

    Parameters
    ----------
    labels : sequence of str
        ``dataset.rigid_markers``.
    reference : ndarray of shape (len(labels), 3)
        Their positions in the reference frame.
    source : str
        Where the reference comes from (file and frame), for the message.

    Raises
    ------
    WorkbenchError
    """
    repeated = sorted({label for label in labels if list(labels).count(label) > 1})
    if repeated:
        raise WorkbenchError(
            f"dataset.rigid_markers lists {repeated} more than once; the markers must be distinct "
            "(a repeated marker makes the head-motion residual look smaller than it is)"
        )
    if len(labels) < 3:
        raise WorkbenchError(f"dataset.rigid_markers has {len(labels)} marker(s); a head pose needs at least 3")
    singular = np.linalg.svd(reference - reference.mean(axis=0), compute_uv=False)
    if not singular[1] > LIMITS.rigid_flatness * singular[0]:
        raise WorkbenchError(
            f"dataset.rigid_markers {list(labels)} are (nearly) collinear in {source} (singular "
            f"values {np.round(singular, 3).tolist()} mm); they cannot fix the head's rotation"
        )
