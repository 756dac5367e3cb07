"""``workbench export``: a run's bases and weight curves in files Blender, Maya and game engines play back exactly.

A run record holds the resolved config and the alpha table, not the bases or weights (they are mesh-sized), so the
export runs the recorded config again (the pipeline is deterministic; built datasets come from the cache) and
refuses to write anything unless the recomputed alpha table matches the recorded one.

For mesh data (points that are mesh vertices), each basis gives:

- ``<basis>.glb``: glTF 2.0 binary, the neutral mesh (triangles), morph targets whose weights all stay in [0, 1]
  (the slider range Blender's importer gives a shape key, which Blender clamps to: :func:`playback_targets`) and
  one morph-weight animation per take, keyed at the source frames' own times; metres, +Y up;
- ``<basis>_obj/``: ``neutral.obj`` and one OBJ per shape (metres by default), with a ``manifest.json`` naming the
  unit, a blendshape folder the workbench reads back as a hand basis (``dataset.hand_basis``);
- ``<basis>_weights.csv``: the raw weights, ``frame`` (in the take's file), ``time`` and one column per shape;
- ``<basis>_livelink.csv``: when shapes carry ARKit-derived names, the weights as the Live Link Face app writes a
  take (its timecodes where the capture came from one).

A capture of several takes gets one weights and one Live Link file per take (``<basis>_<take>_weights.csv``). For
marker data, each basis gives ``<basis>_basis.npz`` and ``<basis>_basis.csv`` (neutral marker positions and every
shape's marker displacements, mm) and the weight curves. ``manifest.json`` lists every file with its units, axes,
takes and frame rates, the alpha of the exported reconstruction and how to recover the raw weights from the
glTF targets.
"""

from __future__ import annotations

import argparse
import io
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from workbench.core.errors import WorkbenchError
from workbench.core.files import (
    check_output_folder,
    inside,
    output_folder,
    plain_name,
    write_atomic,
    write_json,
    write_npz,
)
from workbench.record.replay import replay

ALPHA_COLUMNS = ("alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled")
PCA_MEAN = "pca_mean"
AXES = "+Y up, the face looking along +Z (glTF's convention), coordinates as the data's"
WEIGHT_TOLERANCE = 1e-9
"""Weights this close outside [0, 1] are clipped into it instead of getting a target of their own (a solver's
rounding: the shape moves a vertex by this fraction of its size, far below float32's resolution)."""
OVER, NEGATIVE, POSITIVE = "_over", "_neg", "_pos"
"""Suffixes of the targets a shape is split into (:func:`playback_targets`)."""
OBJ_UNITS = {"m": 1000.0, "mm": 1.0}
"""OBJ unit -> millimetres per unit."""
LIVELINK_DECIMALS = "%.10f"
"""Live Link Face writes every weight and rotation with 10 decimals."""
TARGETS_TEXT = (
    "the glTF file's morph-target weights all stay in [0, 1] (the shape-key slider range Blender's "
    "importer sets, which Blender clamps to). A hand-made or quasi-eigen shape '<s>' keeps its own "
    "target '<s>' (weight clipped into [0, 1]); weights above 1 go to '<s>_over' (the shape times "
    "max weight - 1), weights below 0 to '<s>_neg' (the shape times the min weight); a PCA eigenface "
    "'<e>' becomes '<e>_pos' and '<e>_neg', scaled by the largest positive and negative coefficient. "
    "Raw weight of a shape = sum over its targets of scale x target weight (each target's 'scale'); the "
    "raw weights are also in the weights CSV files"
)


REPLAY_REFUSED = "rerun the study and export the new record"
"""How an export refused by :func:`workbench.record.replay.replay` ends its line."""


def read_run_record(folder: Path):
    """The run record to export (:func:`workbench.record.record.load_record`: config, alpha table, metrics)."""
    from workbench.record.record import load_record

    return load_record(folder)


@dataclass(frozen=True)
class ExportedBasis:
    """One basis as it is exported: shapes and the weights of every evaluated frame.

    Attributes
    ----------
    label : str
        ``H``, ``QE``, ``QE-linear``, ``PCA`` or an alternative basis's label.
    names : tuple of str
        One per shape.
    shapes : ndarray of shape (n_shapes, 3 * n_points)
        Displacements from neutral, mm.
    weights : ndarray of shape (n_eval_frames, n_shapes)
    solver : str
        The solver the weights come from (``projection`` for PCA).
    alpha : dict
        The run's alpha of this reconstruction (:data:`ALPHA_COLUMNS`).
    sculpted : tuple of bool
        Per shape: True where weight 1 means the shape as made (a hand shape, its quasi-eigen projection, PCA's
        mean), False for eigenfaces (unit length, no meaning at weight 1).
    """

    label: str
    names: tuple[str, ...]
    shapes: np.ndarray
    weights: np.ndarray
    solver: str
    alpha: dict
    sculpted: tuple[bool, ...] = ()


def pca_weights(result) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """PCA as a morph basis: ``pca_mean`` (weight 1 in every frame) then the eigenfaces with their coefficients.

    Returns
    -------
    names : tuple of str
    shapes : ndarray of shape (1 + m, n_dims)
    weights : ndarray of shape (n_eval_frames, 1 + m)
    """
    from workbench.numerics.solve import solve_weights

    eigenfaces, capture = result.eigenfaces, result.capture
    if capture.eval_visible is None:
        coefficients = (capture.eval - eigenfaces.mean_) @ eigenfaces.components_.T
    else:  # with gaps, the projection becomes least squares over the seen points (as the alpha table does)
        coefficients = solve_weights(
            eigenfaces.components_, capture.eval - eigenfaces.mean_, visible=capture.eval_visible
        ).weights
    names = (PCA_MEAN,) + tuple(f"pca_{j + 1:02d}" for j in range(eigenfaces.n_components_))
    weights = np.hstack([np.ones((len(coefficients), 1)), coefficients])
    return names, np.vstack([eigenfaces.mean_, eigenfaces.components_]), weights


def exported_bases(result, labels: Sequence[str] | None, solver: str, table: pd.DataFrame) -> list[ExportedBasis]:
    """The bases of one data variant's result to export, each with its weights under ``solver``.

    Parameters
    ----------
    result : workbench.study.results.StudyResult
    labels : sequence of str or None
        Basis labels; None: H, every quasi-eigen basis and PCA (PCA only where the bases were not carried onto
        other points; the alternative bases of ``basis.alternatives`` are not kept by the pipeline).
    solver : str
    table : pandas.DataFrame
        The recorded alpha table (for each basis's alpha).
    """
    from workbench.study.results import QE_LABELS

    n_hand = len(result.capture.hand_names)
    shapes = {"H": (result.capture.hand_names, result.capture.hand)}
    shapes.update({QE_LABELS[projection]: (qe.names, qe.shapes) for projection, qe in result.quasi_eigen.items()})
    pca_available = result.transfer == "identity"
    available = [label for label in shapes if (label, solver) in result.weights] + (["PCA"] if pca_available else [])
    chosen = available if labels is None else list(labels)
    unknown = [label for label in chosen if label not in available]
    if unknown or not chosen:
        raise WorkbenchError(
            f"export --bases {','.join(chosen)}: data '{result.data}' with solver '{solver}' has "
            f"bases {available}"
            + ("" if pca_available else " (PCA is not exported where the bases were carried onto other points)")
        )
    rows = table[table["data"] == result.data]
    exported = []
    for label in chosen:
        if label == "PCA":
            names, basis, weights = pca_weights(result)
            row = rows[rows["basis"] == "PCA"]
            used = "projection"
            sculpted = (True,) + (False,) * (len(names) - 1)
        else:
            names, basis = shapes[label]
            weights = result.weights[(label, solver)]
            row = rows[(rows["basis"] == label) & (rows["solver"] == solver)]
            used = solver
            sculpted = tuple(i < n_hand for i in range(len(names)))  # a QE basis's appended eigenfaces are not
        exported.append(
            ExportedBasis(
                label=label,
                names=tuple(names),
                shapes=np.asarray(basis),
                weights=weights,
                solver=used,
                alpha={c: float(row[c].iloc[0]) for c in ALPHA_COLUMNS},
                sculpted=sculpted,
            )
        )
    return exported


# --- morph targets an animation tool plays back exactly ---


@dataclass(frozen=True)
class PlaybackTargets:
    """A basis as morph targets whose weights all lie in [0, 1].

    Attributes
    ----------
    names : tuple of str
        One per target.
    shapes : ndarray of shape (n_targets,) of int
        The basis shape each target is a multiple of.
    scales : ndarray of shape (n_targets,)
        Target = ``scales[k]`` x basis shape ``shapes[k]``.
    weights : ndarray of shape (n_frames, n_targets)
        In [0, 1]; the raw weight of shape ``i`` is the sum of ``scales[k] * weights[:, k]`` over its targets.
    """

    names: tuple[str, ...]
    shapes: np.ndarray
    scales: np.ndarray
    weights: np.ndarray

    def deltas(self, basis_shapes: np.ndarray) -> np.ndarray:
        """Each target's displacements, shape (n_targets, n_dims), from the basis's (n_shapes, n_dims)."""
        return self.scales[:, None] * basis_shapes[self.shapes]

    def raw_weights(self, n_shapes: int) -> np.ndarray:
        """The basis's weights, shape (n_frames, n_shapes), recovered from the targets'."""
        raw = np.zeros((len(self.weights), n_shapes))
        np.add.at(raw.T, self.shapes, (self.weights * self.scales).T)
        return raw


def playback_targets(names: Sequence[str], weights: np.ndarray, sculpted: Sequence[bool]) -> PlaybackTargets:
    """Split a basis into morph targets whose weights stay in [0, 1], reproducing every frame exactly.

    Blender's glTF importer gives each shape key the slider range [0, 1] (widened only to the first key's value)
    and Blender clamps a shape key's value to that range, so weights outside it do not play back. A sculpted
    shape ``s`` keeps its own target at scale 1 (weights clipped into [0, 1]: the slider an animator knows), plus
    ``s_over`` = (max weight - 1) x ``s`` carrying the part above 1 and ``s_neg`` = (min weight) x ``s`` carrying
    the part below 0, each only when the weights need it. An eigenface ``e`` (no meaning at weight 1) becomes
    ``e_pos`` and ``e_neg``, scaled by its largest positive and negative coefficient.

    Parameters
    ----------
    names : sequence of str
        One per shape.
    weights : ndarray of shape (n_frames, n_shapes)
    sculpted : sequence of bool
        Per shape (:attr:`ExportedBasis.sculpted`).

    Returns
    -------
    PlaybackTargets

    Raises
    ------
    WorkbenchError
        When a target's name would repeat another's (a shape named like another's ``_over`` target).
    """
    target_names, sources, scales, columns = [], [], [], []

    def add(name: str, source: int, scale: float, column: np.ndarray) -> None:
        target_names.append(name)
        sources.append(source)
        scales.append(scale)
        columns.append(np.clip(column, 0.0, 1.0) + 0.0)  # + 0.0: no -0.0 in the files

    for i, (name, is_sculpted) in enumerate(zip(names, sculpted)):
        w = weights[:, i]
        high, low = float(np.max(w)), float(np.min(w))
        if is_sculpted:
            add(name, i, 1.0, w)
            if high > 1.0 + WEIGHT_TOLERANCE:
                add(name + OVER, i, high - 1.0, (w - 1.0) / (high - 1.0))
        elif high > WEIGHT_TOLERANCE:
            add(name + POSITIVE, i, high, w / high)
        elif low >= -WEIGHT_TOLERANCE:  # an eigenface no frame uses still gets a target
            add(name + POSITIVE, i, 1.0, np.zeros_like(w))
        if low < -WEIGHT_TOLERANCE:
            add(name + NEGATIVE, i, low, w / low)
    repeated = sorted({name for name in target_names if target_names.count(name) > 1})
    if repeated:
        raise WorkbenchError(
            f"export: morph target name(s) {repeated} would repeat: a shape is named like another "
            f"shape's {OVER!r}/{NEGATIVE!r}/{POSITIVE!r} target; rename the shape"
        )
    return PlaybackTargets(
        names=tuple(target_names),
        shapes=np.asarray(sources, dtype=int),
        scales=np.asarray(scales, dtype=float),
        weights=np.column_stack(columns) if columns else np.zeros((len(weights), 0)),
    )


# --- takes and their times ---


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


# --- files ---


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


def timecode(seconds: float, rate: float = 60.0) -> str:
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


def livelink_source(dataset_cfg: Mapping) -> LiveLinkSource | None:
    """The source Live Link Face take of a dataset config (``dataset=ict_livelink`` driven by a Live Link CSV), or
    None for other data."""
    from workbench.dataset.real import data_path
    from workbench.formats.livelink import read_livelink_csv
    from workbench.settings.typed import dataset_settings

    if (
        dataset_cfg.get("kind") != "ict_livelink"
        or dataset_cfg.get("weight_curves")
        or not dataset_cfg.get("livelink_csv")
    ):
        return None
    path = data_path(dataset_settings(dataset_cfg), dataset_cfg["livelink_csv"], "livelink_csv")
    take = read_livelink_csv(path, timecode_rate=dataset_cfg.get("timecode_rate", 60.0))
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


def obj_text(vertices: np.ndarray, triangles: np.ndarray) -> str:
    """A Wavefront OBJ of vertices (n, 3) and 0-based triangles (t, 3)."""
    buffer = io.StringIO()
    np.savetxt(buffer, vertices, fmt="v %.9g %.9g %.9g")
    np.savetxt(buffer, np.asarray(triangles) + 1, fmt="f %d %d %d")
    return buffer.getvalue()


def marker_basis_csv(labels: Sequence[str], neutral: np.ndarray, names: Sequence[str], shapes: np.ndarray) -> str:
    """Neutral marker positions then every shape's displacements: one row each, ``<label>_x|y|z`` columns (mm)."""
    columns = [f"{label}_{axis}" for label in labels for axis in "xyz"]
    table = pd.DataFrame(np.vstack([neutral, shapes]), columns=columns)
    table.insert(0, "shape", ["neutral", *names])
    return csv_text(table, "%.9g")


# --- where files go ---


def plain_part(name: str, out: Path) -> str:
    """``name`` if it can name a file inside ``out`` without leaving it, else a :class:`WorkbenchError`."""
    if not plain_name(name):
        raise WorkbenchError(
            f"export: {name!r} cannot name a file inside {out}: a shape, take or basis name must be "
            "a plain name (not empty, '.' or '..', no '/' or '\\')"
        )
    return name


def export_path(out: Path, *parts: str) -> Path:
    """``out / parts`` for a file the export writes, each part a plain name and none a symbolic link.

    Raises
    ------
    WorkbenchError
        When a part is empty, ``.``, ``..`` or holds a path separator (a shape or take name such as ``../../x``
        or ``sub/dir/name``), or a file or folder on the way already is a symbolic link (which could lead out of
        the folder).
    """
    path = Path(out)
    for part in parts:
        path = path / plain_part(part, out)
        if path.is_symlink():
            raise WorkbenchError(
                f"export: refusing to write {Path(out).joinpath(*parts)}: {path} is a symbolic link "
                f"(the export writes only plain files and folders inside {out})"
            )
    return path


def file_plan(basis: ExportedBasis, takes: Sequence[ExportTake], *, mesh: bool, arkit: bool) -> dict:
    """Every file one basis's export writes: ``weights`` and ``livelink`` (take name -> file name), ``glb``,
    ``obj`` (a folder) and ``obj_files`` in it, or ``npz`` and ``csv``; and ``names``, the basis, take and shape
    names that file names are made of."""
    several = len(takes) > 1
    prefix = {take.name: f"{basis.label}_{take.name}_" if several else f"{basis.label}_" for take in takes}
    plan = {
        "weights": {take: start + "weights.csv" for take, start in prefix.items()},
        "livelink": {take: start + "livelink.csv" for take, start in prefix.items()} if arkit else {},
        "names": [basis.label, *(prefix if several else [])],
    }
    if mesh:
        plan.update(
            glb=f"{basis.label}.glb",
            obj=f"{basis.label}_obj",
            obj_files=["neutral.obj", "manifest.json", *[f"{name}.obj" for name in basis.names]],
        )
        plan["names"] += list(basis.names)
    else:
        plan.update(npz=f"{basis.label}_basis.npz", csv=f"{basis.label}_basis.csv")
    return plan


def check_plan(out: Path, plans: Sequence[dict]) -> None:
    """Refuse an export before anything is written when a name is not plain, a file or folder on the way is a
    symbolic link or two files would be one (a shape called ``neutral``; names equal but for case)."""
    for plan in plans:
        for name in plan["names"]:
            plain_part(name, out)
    top = [
        name
        for plan in plans
        for name in [
            *plan["weights"].values(),
            *plan["livelink"].values(),
            *[plan[kind] for kind in ("glb", "obj", "npz", "csv") if kind in plan],
        ]
    ]
    folders = [(plan["obj"], plan["obj_files"]) for plan in plans if "obj" in plan]
    for name in top:
        export_path(out, name)
    for folder, names in folders:
        for name in names:
            export_path(out, folder, name)
    for where, names in [(Path(out), top)] + [(Path(out) / folder, names) for folder, names in folders]:
        folded = [name.casefold() for name in names]
        twice = sorted({name for name, key in zip(names, folded) if folded.count(key) > 1})
        if twice:
            raise WorkbenchError(
                f"export: {twice} would be written twice into {where} (a shape named 'neutral', or "
                "names equal but for case); rename the shape or take"
            )


# --- writing ---


def export_basis(
    out: Path, result, basis: ExportedBasis, takes: Sequence[ExportTake], *, run_name: str, obj_unit: str
) -> dict:
    """Write one basis's files into ``out`` and return their manifest entry."""
    from workbench.formats.gltf import MM_PER_METRE

    capture = result.capture
    n_points = capture.n_points
    neutral = capture.neutral.reshape(n_points, 3)
    shapes = basis.shapes.reshape(len(basis.names), n_points, 3)
    channels = livelink_channels(basis.names, basis.weights)
    plan = file_plan(basis, takes, mesh=capture.faces is not None, arkit=channels is not None)
    files = {}
    entry = {
        "basis": basis.label,
        "solver": basis.solver,
        "shapes": list(basis.names),
        "alpha": basis.alpha,
        "files": files,
    }
    for take in takes:
        name = plan["weights"][take.name]
        write_atomic(
            export_path(out, name), weights_csv(basis.names, basis.weights[take.rows], take.frames, take.seconds)
        )
        files[name] = (
            f"take {take.name}: raw weights; frame (in the take's file), time (s in the take), one column per shape"
        )
    if channels is not None:
        clipped = 0
        for take in takes:
            name = plan["livelink"][take.name]
            text, count = livelink_csv(channels[take.rows], take.timecodes, take.rotations)
            write_atomic(export_path(out, name), text)
            clipped += count
            files[name] = (
                f"take {take.name} in the Live Link Face CSV layout: timecodes {take.timecode_source}; "
                f"52 ARKit channels ({count} values clipped into [0, 1]) and 9 rotations"
            )
        entry["livelink_clipped"] = {"values": clipped, "of": int(channels.size)}
    if capture.faces is None:
        write_npz(
            export_path(out, plan["npz"]),
            {
                "neutral": neutral,
                "shapes": shapes,
                "names": np.array(basis.names),
                "labels": np.array(capture.point_labels),
            },
        )
        write_atomic(
            export_path(out, plan["csv"]),
            marker_basis_csv(capture.point_labels, capture.neutral, basis.names, basis.shapes),
        )
        files[plan["npz"]] = "neutral (n_markers, 3), shapes (n_shapes, n_markers, 3), names, labels; mm"
        files[plan["csv"]] = "row 'neutral' then one row per shape; <marker>_x|y|z columns, mm"
        return entry
    from workbench.formats.gltf import glb_bytes
    from workbench.reporting.rig import GENERATOR, RigTake, rig_mesh, target_rows

    rig_takes = [
        RigTake(
            name=take.name,
            rows=take.rows,
            seconds=take.seconds,
            extras={
                "take": take.name,
                "frame_rate": take.frame_rate,
                "frames": [int(take.frames[0]), int(take.frames[-1])],
            },
        )
        for take in takes
    ]
    animation_names = [f"{basis.label}_{basis.solver}_{take.name}" for take in takes]
    facts = [dict(take_facts(take), animation=name) for take, name in zip(takes, animation_names)]
    extras = {
        "units": "metres",
        "axes": AXES,
        "frame_rate": capture.frame_rate,
        "takes": facts,
        "run": run_name,
        "data": result.data,
        "source": capture.name,
        "credits": capture.provenance.get("credits", []),
    }
    mesh, targets = rig_mesh(basis, neutral, capture.faces, rig_takes, extras)
    write_atomic(export_path(out, plan["glb"]), glb_bytes(mesh, mesh_name="face", generator=GENERATOR))
    files[plan["glb"]] = (
        f"glTF 2.0: neutral mesh, {len(targets.names)} morph targets (weights in [0, 1]) for "
        f"{len(basis.names)} shapes, one animation per take keyed at the frames' own times "
        f"({capture.frame_rate:g} fps); metres ({MM_PER_METRE:g} mm), {AXES}"
    )
    entry["animations"] = animation_names
    entry["targets"] = target_rows(targets, basis.names)
    folder, per_unit = plan["obj"], OBJ_UNITS[obj_unit]
    write_atomic(export_path(out, folder, "neutral.obj"), obj_text(neutral / per_unit, capture.faces))
    for name, shape in zip(basis.names, shapes):
        write_atomic(export_path(out, folder, f"{name}.obj"), obj_text((neutral + shape) / per_unit, capture.faces))
    write_json(
        export_path(out, folder, "manifest.json"),
        {
            "unit": obj_unit,
            "unit_mm": per_unit,
            "neutral": "neutral.obj",
            "shapes": list(basis.names),
            "axes": AXES,
            "basis": basis.label,
            "run": run_name,
            "data": result.data,
        },
    )
    files[folder + "/"] = (
        f"blendshape folder: neutral.obj and one OBJ per shape (neutral plus the shape) in "
        f"{obj_unit}, manifest.json with the unit (read back with "
        f"dataset.hand_basis.path={folder})"
    )
    return entry


WRITER = "an export"


def export_run(
    folder: Path,
    out: Path,
    *,
    data: str | None = None,
    bases: Sequence[str] | None = None,
    solver: str | None = None,
    obj_unit: str = "m",
) -> dict:
    """Export one data variant of a run: every chosen basis's files and ``manifest.json``.

    Parameters
    ----------
    folder : pathlib.Path
        A complete run record.
    out : pathlib.Path
        Output folder: new, empty or an earlier export's (replaced as a whole); written in a temporary folder beside
        it and moved into place when complete (:func:`workbench.core.files.output_folder`).
    data : str, optional
        Data variant (a row's ``data`` in the alpha table); default the run's first.
    bases : sequence of str, optional
        Basis labels; default every basis the run scored.
    solver : str, optional
        Solver whose weights are exported; default the run's first.
    obj_unit : {"m", "mm"}
        Unit of the OBJ files.

    Returns
    -------
    dict
        The manifest.
    """
    if obj_unit not in OBJ_UNITS:
        raise WorkbenchError(f"export --obj-unit {obj_unit}: must be one of {sorted(OBJ_UNITS)}")
    out = Path(out)
    record = read_run_record(folder)
    solvers = list(record.config.get("solver") or {})
    solver = solver or (solvers[0] if solvers else None)
    if solver not in solvers:
        raise WorkbenchError(f"export --solver {solver}: the run's solvers are {solvers}")
    variants = list(dict.fromkeys(record.table["data"].astype(str)))
    data = data or variants[0]
    if data not in variants:
        raise WorkbenchError(f"export --data {data}: the run's data variants are {variants}")
    results = {result.data: result for result in replay(record, REPLAY_REFUSED)}
    result = results[data]
    capture = result.capture
    chosen = exported_bases(result, bases, solver, record.table)
    dataset_cfg = record.config.get("dataset") or {}
    takes = export_takes(capture, livelink_source(dataset_cfg), float(dataset_cfg.get("timecode_rate") or 60.0))
    mesh = capture.faces is not None
    check_plan(
        out,
        [
            file_plan(basis, takes, mesh=mesh, arkit=livelink_channels(basis.names, basis.weights) is not None)
            for basis in chosen
        ],
    )
    with output_folder(out, "--out", writer=WRITER) as staging:
        manifest = export_manifest(
            [export_basis(staging, result, basis, takes, run_name=folder.name, obj_unit=obj_unit) for basis in chosen],
            folder,
            record,
            capture,
            data=data,
            takes=takes,
            obj_unit=obj_unit,
        )
        write_json(export_path(staging, "manifest.json"), manifest)
    return manifest


def export_manifest(entries, folder, record, capture, *, data, takes, obj_unit) -> dict:
    """``manifest.json`` of an export: the run, the data and its units, and every basis's files (``entries``)."""
    mesh = capture.faces is not None
    return {
        "run": str(Path(folder).resolve()),
        "config_hash": record.config_hash,
        "data": data,
        "dataset": capture.name,
        "credits": capture.provenance.get("credits", []),
        "n_points": capture.n_points,
        "points": ("mesh vertices" if mesh else "points without triangles (markers, or a thinned mesh)"),
        "n_triangles": None if capture.faces is None else int(len(capture.faces)),
        "n_frames": int(len(capture.eval)),
        "frame_rate": capture.frame_rate,
        "frames": (
            "the run's evaluated frames in order, take by take; each is keyed at its own time in its take "
            "(seconds from the take's first frame in its file), so a frame the capture lacks (dropped, or "
            "removed by a gap policy) is a gap between keys"
        ),
        "takes": [take_facts(take) for take in takes],
        "units": {"glb": "metres", "obj": obj_unit, "npz_csv": "mm", "weights": "dimensionless"},
        "axes": AXES,
        "targets": TARGETS_TEXT if mesh else None,
        "bases": entries,
    }


def main(argv: Sequence[str]) -> int:
    """``workbench export RUN_DIR [--out DIR] [--data NAME] [--bases H,QE,PCA] [--solver NAME] [--obj-unit m|mm]``."""
    parser = argparse.ArgumentParser(
        prog="workbench export",
        description="Export a run's bases and weight curves: glTF 2.0 (.glb) with morph targets and one weight "
        "animation per take, an OBJ blendshape folder and CSV weight curves (raw, and in the Live Link "
        "Face layout) for mesh data; NPZ/CSV marker bases and weight curves for marker data.",
    )
    parser.add_argument("run", type=Path, help="a complete run record (folder with a 'done' marker)")
    parser.add_argument(
        "--out", help="output folder: new, empty, or one an export wrote before (default: <run>/export)"
    )
    parser.add_argument("--data", help="data variant (default: the run's first, e.g. mesh)")
    parser.add_argument("--bases", help="comma-separated basis labels, e.g. H,QE,PCA (default: all)")
    parser.add_argument("--solver", help="solver whose weights are exported (default: the run's first)")
    parser.add_argument(
        "--obj-unit",
        choices=sorted(OBJ_UNITS),
        default="m",
        help="unit of the OBJ files (default: m, as animation tools expect)",
    )
    args = parser.parse_args(list(argv))
    if args.out is not None:  # refused before the run is rebuilt
        check_output_folder(args.out, "--out", writer=WRITER)
    out = Path(args.out) if args.out is not None else inside(args.run, "export")
    bases = None if args.bases is None else [label for label in args.bases.split(",") if label]
    manifest = export_run(args.run, out, data=args.data, bases=bases, solver=args.solver, obj_unit=args.obj_unit)
    for entry in manifest["bases"]:
        alpha = entry["alpha"]["alpha_abs_mean"]
        print(
            f"{entry['basis']} ({entry['solver']}, {len(entry['shapes'])} shapes, alpha {alpha:.3f}%): "
            + ", ".join(entry["files"])
        )
        clipped = entry.get("livelink_clipped", {})
        if clipped.get("values"):
            print(
                f"warning: {entry['basis']}: {clipped['values']:,} of {clipped['of']:,} ARKit values "
                f"({100.0 * clipped['values'] / clipped['of']:.1f}%) lay outside [0, 1] and were clipped in the Live "
                f"Link file(s); the raw weights are in the weights CSV",
                file=sys.stderr,
            )
    takes = manifest["takes"]
    print(
        f"exported data '{manifest['data']}' of {args.run} ({manifest['n_frames']} frames at "
        f"{manifest['frame_rate']:g} fps, {len(takes)} take{'s' if len(takes) != 1 else ''}) into {out}"
    )
    return 0
