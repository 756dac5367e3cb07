"""``workbench export``: a run's bases and weight curves in files Blender, Maya and game engines read.

A run record holds the resolved config and the alpha table, not the bases or weights (they are mesh-sized), so the
export runs the recorded config again (the pipeline is deterministic; built datasets come from the cache) and
refuses to write anything unless the recomputed alpha table matches the recorded one.

For mesh data (points that are mesh vertices), each basis gives:

- ``<basis>.glb``: glTF 2.0 binary, the neutral mesh (triangles) with one morph target per basis shape, named as
  the shape (``jawOpen``, ... for H and QE; ``pca_mean``, ``pca_01``, ... for PCA), and the solved weights of
  every evaluated frame as a morph-weight animation at the capture's frame rate; metres, +Y up;
- ``<basis>_obj/``: ``neutral.obj`` and one OBJ per shape in millimetres, a blendshape folder the workbench
  reads back as a hand basis (``dataset.hand_basis``);
- ``<basis>_weights.csv``: ``frame``, ``time`` and one column per shape;
- ``<basis>_livelink.csv``: when shapes carry ARKit-derived names, the weights in the Live Link Face CSV layout.

For marker data, each basis gives ``<basis>_basis.npz`` and ``<basis>_basis.csv`` (neutral marker positions and
every shape's marker displacements, mm) and the weight curves. ``manifest.json`` lists every file with its units,
axes, frame rate and the alpha of the exported reconstruction.
"""

from __future__ import annotations

import argparse
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from workbench.errors import WorkbenchError
from workbench.record import inside, write_atomic, write_json, write_npz

TABLE_CHECK_RTOL = 1e-6
"""Recomputed alpha must match the recorded table to this relative tolerance before anything is exported."""
ALPHA_COLUMNS = ("alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled")
PCA_MEAN = "pca_mean"
LIVELINK_TIMECODE_RATE = 60.0
AXES = "+Y up, the face looking along +Z (glTF's convention), coordinates as the data's"


def read_run_record(folder: Path):
    """The run record to export (:func:`workbench.record.load_record`: config, alpha table, metrics)."""
    from workbench.record import load_record

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
    """

    label: str
    names: tuple[str, ...]
    shapes: np.ndarray
    weights: np.ndarray
    solver: str
    alpha: dict


def pca_weights(result) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """PCA as a morph basis: ``pca_mean`` (weight 1 in every frame) then the eigenfaces with their coefficients.

    Returns
    -------
    names : tuple of str
    shapes : ndarray of shape (1 + m, n_dims)
    weights : ndarray of shape (n_eval_frames, 1 + m)
    """
    from workbench.solve import solve_weights

    eigenfaces, capture = result.eigenfaces, result.capture
    if capture.eval_visible is None:
        coefficients = (capture.eval - eigenfaces.mean_) @ eigenfaces.components_.T
    else:  # with gaps, the projection becomes least squares over the seen points (as the alpha table does)
        coefficients = solve_weights(eigenfaces.components_, capture.eval - eigenfaces.mean_,
                                     visible=capture.eval_visible).weights
    names = (PCA_MEAN,) + tuple(f"pca_{j + 1:02d}" for j in range(eigenfaces.n_components_))
    weights = np.hstack([np.ones((len(coefficients), 1)), coefficients])
    return names, np.vstack([eigenfaces.mean_, eigenfaces.components_]), weights


def exported_bases(result, labels: Sequence[str] | None, solver: str, table: pd.DataFrame) -> list[ExportedBasis]:
    """The bases of one data variant's result to export, each with its weights under ``solver``.

    Parameters
    ----------
    result : workbench.pipeline.StudyResult
    labels : sequence of str or None
        Basis labels; None: H, every quasi-eigen basis and PCA (PCA only where the bases were not carried onto
        other points; the alternative bases of ``basis.alternatives`` are not kept by the pipeline).
    solver : str
    table : pandas.DataFrame
        The recorded alpha table (for each basis's alpha).
    """
    from workbench.pipeline import QE_LABELS

    shapes = {"H": (result.capture.hand_names, result.capture.hand)}
    shapes.update({QE_LABELS[projection]: (qe.names, qe.shapes) for projection, qe in result.quasi_eigen.items()})
    pca_available = result.transfer == "identity"
    available = [label for label in shapes if (label, solver) in result.weights] + (["PCA"] if pca_available else [])
    chosen = available if labels is None else list(labels)
    unknown = [label for label in chosen if label not in available]
    if unknown or not chosen:
        raise WorkbenchError(f"export --bases {','.join(chosen)}: data '{result.data}' with solver '{solver}' has "
                             f"bases {available}" + ("" if pca_available else " (PCA is not exported where the bases "
                                                     "were carried onto other points)"))
    rows = table[table["data"] == result.data]
    exported = []
    for label in chosen:
        if label == "PCA":
            names, basis, weights = pca_weights(result)
            row = rows[rows["basis"] == "PCA"]
            used = "projection"
        else:
            names, basis = shapes[label]
            weights = result.weights[(label, solver)]
            row = rows[(rows["basis"] == label) & (rows["solver"] == solver)]
            used = solver
        exported.append(ExportedBasis(label=label, names=tuple(names), shapes=np.asarray(basis), weights=weights,
                                      solver=used, alpha={c: float(row[c].iloc[0]) for c in ALPHA_COLUMNS}))
    return exported


def check_recomputed(results, table: pd.DataFrame, folder: Path) -> None:
    """Refuse an export whose recomputed alpha differs from the record (data or code changed since the run)."""
    from workbench.run_text import alpha_table

    for result in results:
        fresh = alpha_table(result.rows, data=result.data, m=result.eigenfaces.n_components_,
                            coverage=result.eigenfaces.coverage_, paper_alpha={})
        recorded = table[table["data"] == result.data].reset_index(drop=True)
        keys = ["basis", "projection", "solver"]
        if len(recorded) != len(fresh) or not (recorded[keys].astype(str) == fresh[keys].astype(str)).all().all():
            raise WorkbenchError(f"{folder}: the recomputed alpha table of data '{result.data}' has other rows than "
                                 "the recorded one; rerun the study and export the new record")
        a, b = recorded[list(ALPHA_COLUMNS)].to_numpy(float), fresh[list(ALPHA_COLUMNS)].to_numpy(float)
        if not np.allclose(a, b, rtol=TABLE_CHECK_RTOL, atol=0.0, equal_nan=True):
            worst = np.nanmax(np.abs(a - b) / np.maximum(np.abs(a), 1e-300))
            raise WorkbenchError(f"{folder}: recomputing the run gives alpha {worst:.2e} (relative) away from the "
                                 f"recorded table for data '{result.data}' (allowed {TABLE_CHECK_RTOL:g}): the data or "
                                 "the code changed since the run; rerun the study and export the new record")


def rebuild_results(record):
    """Run the recorded config again and check it against the record; returns the study results."""
    from workbench.pipeline import run_study

    results = run_study(record.config)
    check_recomputed(results, record.table, record.folder)
    return results


def csv_text(table: pd.DataFrame, float_format: str) -> str:
    """A table as CSV text (no index column), numbers in ``float_format``; written by the atomic writer."""
    buffer = io.StringIO()
    table.to_csv(buffer, index=False, float_format=float_format)
    return buffer.getvalue()


def frame_seconds(n_frames: int, frame_rate: float) -> np.ndarray:
    """Time of each evaluated frame from the first, at the capture's rate."""
    return np.arange(n_frames) / float(frame_rate)


def weights_csv(names: Sequence[str], weights: np.ndarray, seconds: np.ndarray) -> str:
    """Weight curves as CSV: ``frame``, ``time`` (s), then one column per shape."""
    table = pd.DataFrame(weights, columns=list(names))
    table.insert(0, "time", seconds)
    table.insert(0, "frame", np.arange(len(weights)))
    return csv_text(table, "%.9g")


def livelink_csv(names: Sequence[str], weights: np.ndarray, seconds: np.ndarray) -> tuple[str, int] | None:
    """The weight curves in the Live Link Face CSV layout, when shapes carry ARKit-derived names.

    Each ARKit channel gets the mean weight of the shapes it maps onto by the workbench's naming rule
    (``JawOpen -> jawOpen``, ``BrowInnerUp -> browInnerUp_L, browInnerUp_R``); channels with none stay 0.
    ARKit weights are fractions, so values are clipped into [0, 1].

    Returns
    -------
    (str, int) or None
        The CSV text and how many values were clipped; None when no shape has an ARKit-derived name.
    """
    from workbench.dataset.livelink import ARKIT_NAMES, map_arkit_channels

    mapping = map_arkit_channels(ARKIT_NAMES, names)
    counts = mapping.matrix.sum(axis=1)
    if not counts.any():
        return None
    channels = (weights @ mapping.matrix.T) / np.maximum(counts, 1.0)
    clipped = int(((channels < 0.0) | (channels > 1.0)).sum())
    table = pd.DataFrame(np.clip(channels, 0.0, 1.0), columns=list(ARKIT_NAMES))
    table.insert(0, "BlendShapeCount", len(ARKIT_NAMES))
    table.insert(0, "Timecode", [timecode(second) for second in seconds])
    return csv_text(table, "%.6g"), clipped


def timecode(seconds: float, rate: float = LIVELINK_TIMECODE_RATE) -> str:
    """``HH:MM:SS:FF.fff`` with ``FF`` frames at ``rate`` (Live Link Face's timecode)."""
    whole = int(np.floor(seconds))
    frames = (seconds - whole) * rate
    return f"{whole // 3600:02d}:{whole // 60 % 60:02d}:{whole % 60:02d}:{frames:06.3f}"


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


def export_basis(out: Path, result, basis: ExportedBasis, *, run_name: str) -> dict:
    """Write one basis's files into ``out`` and return their manifest entry."""
    from workbench.gltf import MM_PER_METRE, MorphAnimation, MorphMesh, glb_bytes

    capture = result.capture
    seconds = frame_seconds(len(basis.weights), capture.frame_rate)
    n_points = capture.n_points
    neutral = capture.neutral.reshape(n_points, 3)
    shapes = basis.shapes.reshape(len(basis.names), n_points, 3)
    files = {}
    write_atomic(out / f"{basis.label}_weights.csv", weights_csv(basis.names, basis.weights, seconds))
    files[f"{basis.label}_weights.csv"] = "weight curves: frame, time (s), one column per shape"
    livelink = livelink_csv(basis.names, basis.weights, seconds)
    if livelink is not None:
        write_atomic(out / f"{basis.label}_livelink.csv", livelink[0])
        files[f"{basis.label}_livelink.csv"] = (f"weight curves in the Live Link Face CSV layout (ARKit channels, "
                                                f"{livelink[1]} values clipped into [0, 1])")
    if capture.faces is not None:
        mesh = MorphMesh(neutral=neutral, triangles=capture.faces, names=basis.names, deltas=shapes,
                         animations=(MorphAnimation(name=f"{basis.label}_{basis.solver}", seconds=seconds,
                                                    weights=basis.weights),),
                         extras={"units": "metres", "axes": AXES, "frame_rate": capture.frame_rate,
                                 "basis": basis.label, "solver": basis.solver, "run": run_name,
                                 "data": result.data, "source": capture.name,
                                 "credits": capture.provenance.get("credits", [])})
        write_atomic(out / f"{basis.label}.glb", glb_bytes(mesh, mesh_name="face"))
        files[f"{basis.label}.glb"] = (f"glTF 2.0: neutral mesh, {len(basis.names)} morph targets, animation "
                                       f"'{basis.label}_{basis.solver}' of {len(seconds)} frames at "
                                       f"{capture.frame_rate:g} fps; metres ({MM_PER_METRE:g} mm), {AXES}")
        folder = f"{basis.label}_obj"
        write_atomic(out / folder / "neutral.obj", obj_text(neutral, capture.faces))
        for name, shape in zip(basis.names, shapes):
            write_atomic(out / folder / f"{name}.obj", obj_text(neutral + shape, capture.faces))
        files[folder + "/"] = ("blendshape folder: neutral.obj and one OBJ per shape, mm (read back with "
                               f"dataset.hand_basis.path={folder}, unit_mm 1)")
    else:
        arrays = {"neutral": neutral, "shapes": shapes, "names": np.array(basis.names),
                  "labels": np.array(capture.point_labels)}
        write_npz(out / f"{basis.label}_basis.npz", arrays)
        write_atomic(out / f"{basis.label}_basis.csv",
                     marker_basis_csv(capture.point_labels, capture.neutral, basis.names, basis.shapes))
        files[f"{basis.label}_basis.npz"] = ("neutral (n_markers, 3), shapes (n_shapes, n_markers, 3), names, "
                                             "labels; mm")
        files[f"{basis.label}_basis.csv"] = "row 'neutral' then one row per shape; <marker>_x|y|z columns, mm"
    return {"basis": basis.label, "solver": basis.solver, "shapes": list(basis.names), "alpha": basis.alpha,
            "files": files}


def export_run(folder: Path, out: Path, *, data: str | None = None, bases: Sequence[str] | None = None,
               solver: str | None = None) -> dict:
    """Export one data variant of a run: every chosen basis's files and ``manifest.json``.

    Parameters
    ----------
    folder : pathlib.Path
        A complete run record.
    out : pathlib.Path
        Output folder (created).
    data : str, optional
        Data variant (a row's ``data`` in the alpha table); default the run's first.
    bases : sequence of str, optional
        Basis labels; default every basis the run scored.
    solver : str, optional
        Solver whose weights are exported; default the run's first.

    Returns
    -------
    dict
        The manifest.
    """
    record = read_run_record(folder)
    solvers = list(record.config.get("solver") or {})
    solver = solver or (solvers[0] if solvers else None)
    if solver not in solvers:
        raise WorkbenchError(f"export --solver {solver}: the run's solvers are {solvers}")
    variants = list(dict.fromkeys(record.table["data"].astype(str)))
    data = data or variants[0]
    if data not in variants:
        raise WorkbenchError(f"export --data {data}: the run's data variants are {variants}")
    results = {result.data: result for result in rebuild_results(record)}
    result = results[data]
    entries = [export_basis(Path(out), result, basis, run_name=folder.name)
               for basis in exported_bases(result, bases, solver, record.table)]
    capture = result.capture
    manifest = {
        "run": str(Path(folder).resolve()), "config_hash": record.config_hash, "data": data,
        "dataset": capture.name, "credits": capture.provenance.get("credits", []),
        "n_points": capture.n_points, "points": ("mesh vertices" if capture.faces is not None
                                          else "points without triangles (markers, or a thinned mesh)"),
        "n_triangles": None if capture.faces is None else int(len(capture.faces)),
        "n_frames": int(len(capture.eval)), "frame_rate": capture.frame_rate,
        "frames": "the run's evaluated frames in order; time = frame / frame_rate",
        "units": {"glb": "metres", "obj": "mm", "npz_csv": "mm", "weights": "dimensionless"},
        "axes": AXES, "bases": entries,
    }
    write_json(Path(out) / "manifest.json", manifest)
    return manifest


def main(argv: Sequence[str]) -> int:
    """``workbench export RUN_DIR [--out DIR] [--data NAME] [--bases H,QE,PCA] [--solver NAME]``."""
    parser = argparse.ArgumentParser(
        prog="workbench export",
        description="Export a run's bases and weight curves: glTF 2.0 (.glb) with morph targets and a weight "
                    "animation, an OBJ blendshape folder and CSV weight curves for mesh data; NPZ/CSV marker "
                    "bases and weight curves for marker data.")
    parser.add_argument("run", type=Path, help="a complete run record (folder with a 'done' marker)")
    parser.add_argument("--out", type=Path, help="output folder (default: <run>/export)")
    parser.add_argument("--data", help="data variant (default: the run's first, e.g. mesh)")
    parser.add_argument("--bases", help="comma-separated basis labels, e.g. H,QE,PCA (default: all)")
    parser.add_argument("--solver", help="solver whose weights are exported (default: the run's first)")
    args = parser.parse_args(list(argv))
    out = args.out or inside(args.run, "export")
    bases = None if args.bases is None else [label for label in args.bases.split(",") if label]
    manifest = export_run(args.run, out, data=args.data, bases=bases, solver=args.solver)
    for entry in manifest["bases"]:
        alpha = entry["alpha"]["alpha_abs_mean"]
        print(f"{entry['basis']} ({entry['solver']}, {len(entry['shapes'])} shapes, alpha {alpha:.3f}%): "
              + ", ".join(entry["files"]))
    print(f"exported data '{manifest['data']}' of {args.run} ({manifest['n_frames']} frames at "
          f"{manifest['frame_rate']:g} fps) into {out}")
    return 0
