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

import io
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from workbench.core.errors import WorkbenchError
from workbench.core.files import (
    output_folder,
    plain_name,
    write_atomic,
    write_json,
    write_npz,
)
from workbench.record.replay import replay
from workbench.reporting.export.bases import (
    AXES,
    TARGETS_TEXT,
    ExportedBasis,
    exported_bases,
)
from workbench.reporting.export.takes import (
    LIVELINK_TIMECODE_RATE,
    ExportTake,
    csv_text,
    export_takes,
    livelink_channels,
    livelink_csv,
    livelink_source,
    take_facts,
    weights_csv,
)

OBJ_UNITS = {"m": 1000.0, "mm": 1.0}
"""OBJ unit -> millimetres per unit."""


REPLAY_REFUSED = "rerun the study and export the new record"
"""How an export refused by :func:`workbench.record.replay.replay` ends its line."""


def read_run_record(folder: Path):
    """The run record to export (:func:`workbench.record.record.load_record`: config, alpha table, metrics)."""
    from workbench.record.record import load_record

    return load_record(folder)


# --- morph targets an animation tool plays back exactly ---


# --- takes and their times ---


# --- files ---


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
    from workbench.reporting.export.rig import GENERATOR, RigTake, rig_mesh, target_rows

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
    force: bool = False,
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
    force : bool
        Replace files of an earlier export in ``out`` that were changed since (``--force``).

    Returns
    -------
    dict
        The manifest.
    """
    if obj_unit not in OBJ_UNITS:
        raise WorkbenchError(f"export --obj-unit {obj_unit}: must be one of {sorted(OBJ_UNITS)}")
    out = Path(out)
    record = read_run_record(folder)
    settings = record.settings
    solvers = list(settings.solvers)
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
    dataset = settings.dataset
    rate = dataset.timecode_rate if dataset.kind == "ict_livelink" else LIVELINK_TIMECODE_RATE
    takes = export_takes(capture, livelink_source(dataset), float(rate))
    mesh = capture.faces is not None
    check_plan(
        out,
        [
            file_plan(basis, takes, mesh=mesh, arkit=livelink_channels(basis.names, basis.weights) is not None)
            for basis in chosen
        ],
    )
    with output_folder(out, "--out", writer=WRITER, force=force) as staging:
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
