"""How far Blender's playback of exported .glb files lies from the workbench's reconstruction.

Exports a run (``workbench.reporting.export.run.export_run``) under each solver, plays every .glb back in Blender (background
mode, the stock glTF importer, the recipe of docs/export.md: ``blender_playback.py``) at keys spread over each take,
and compares every vertex of Blender's evaluated mesh with the reconstruction the workbench computes from the same
weights (float64, mm).

Usage (from the repository root; the run record's data must be where the run found them)::

    .venv/bin/python tests/tools/playback_check.py RUN [--solvers lstsq,nnls,box] [--data mesh] [--keys 12]

prints one line per basis and solver: the max abs difference (mm) over every vertex of every evaluated key.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def chosen_keys(weights: np.ndarray, spans: list[tuple[int, int]], per_take: int) -> list[list[int]]:
    """Key indices within each take: ``per_take`` spread evenly from first to last, plus the frame whose weights
    reach furthest from [0, 1] (where a clamped slider would show)."""
    chosen = []
    for start, stop in spans:
        spread = np.linspace(0, stop - start - 1, min(per_take, stop - start)).round().astype(int)
        outside = np.maximum(weights[start:stop] - 1.0, -weights[start:stop]).max(axis=1)
        chosen.append(sorted(set(spread.tolist()) | {int(np.argmax(outside))}))
    return chosen


def blender_play(files: list[dict], timeout: float = 1200.0) -> list[dict]:
    """Run ``blender_playback.py`` on ``files`` (its REQUEST's entries) in one Blender process; the IMPORTED
    summaries, one per file."""
    with tempfile.TemporaryDirectory(prefix="playback-") as scratch:
        request = Path(scratch) / "request.json"
        request.write_text(json.dumps({"files": files}))
        result = subprocess.run(
            [
                "blender",
                "--background",
                "--factory-startup",
                "--python",
                str(HERE / "blender_playback.py"),
                "--",
                str(request),
            ],
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    summaries = [
        json.loads(line[len("IMPORTED ") :]) for line in result.stdout.splitlines() if line.startswith("IMPORTED ")
    ]
    if result.returncode != 0 or len(summaries) != len(files):
        raise RuntimeError(
            f"blender exited {result.returncode} after {len(summaries)} of {len(files)} files:\n"
            + result.stdout[-3000:]
            + result.stderr[-3000:]
        )
    return summaries


def gltf_axes_mm(blender_positions: np.ndarray) -> np.ndarray:
    """Blender's coordinates (+Z up, metres) back to glTF's (+Y up), in mm: the importer maps (x, y, z) to
    (x, -z, y)."""
    x, y, z = np.moveaxis(np.asarray(blender_positions, dtype=np.float64), -1, 0)
    return np.stack([x, z, -y], axis=-1) * 1000.0


def playback_differences(
    out: Path, manifest: dict, bases: list, neutral: np.ndarray, per_take: int = 12, scratch: Path | None = None
) -> dict:
    """Play every basis's .glb of an export back in Blender and compare it with the workbench's reconstruction.

    Parameters
    ----------
    out : pathlib.Path
        The export folder.
    manifest : dict
        Its manifest.
    bases : list of workbench.reporting.export.bases.ExportedBasis
        The exported bases, raw shapes (mm) and weights.
    neutral : ndarray of shape (n_vertices, 3)
        The capture's neutral, mm.
    per_take : int
        Keys evaluated per take, spread evenly (plus the one furthest outside [0, 1]).

    Returns
    -------
    dict
        Basis label -> ``{"max_abs_mm", "keys", "imported"}`` (the Blender summary).
    """
    ((_, found),) = exports_played_back([(None, out, manifest, bases)], neutral, per_take, scratch).items()
    return found


def exports_played_back(exports: list[tuple], neutral: np.ndarray, per_take: int = 12, scratch: Path | None = None):
    """:func:`playback_differences` of several exports of one capture, every .glb in one Blender process.

    ``exports`` holds ``(key, out, manifest, bases)`` per export (``scratch`` is then required if two keys share
    it: each export's played-back frames go to ``scratch / key``); returns key -> what
    :func:`playback_differences` returns for that export."""
    plans = []
    for key, out, manifest, bases in exports:
        folder = Path(scratch or out) / (key or "")
        folder.mkdir(parents=True, exist_ok=True)
        takes = manifest.get("takes") or [{"rows": [0, manifest["n_frames"]]}]
        spans = [tuple(take["rows"]) for take in takes]
        files, rows = [], []
        for basis in bases:
            entry = next(entry for entry in manifest["bases"] if entry["basis"] == basis.label)
            names = entry.get("animations") or [""]
            keys = chosen_keys(basis.weights, spans, per_take)
            files.append(
                {
                    "glb": str(out / f"{basis.label}.glb"),
                    "out": str(folder / f"{basis.label}.playback.npz"),
                    "keys": dict(zip(names, keys)),
                }
            )
            rows.append(np.concatenate([np.asarray(k) + start for k, (start, _) in zip(keys, spans)]))
        plans.append((key, bases, files, rows))
    summaries = iter(blender_play([file for _, _, files, _ in plans for file in files]))
    played_back = {}
    for key, bases, files, rows in plans:
        found = {}
        for basis, file, frame_rows, summary in zip(bases, files, rows, summaries):
            with np.load(file["out"]) as played:
                blender = gltf_axes_mm(played["positions"])
            expected = neutral[None] + (basis.weights[frame_rows] @ basis.shapes).reshape(len(frame_rows), -1, 3)
            found[basis.label] = {
                "max_abs_mm": float(np.abs(blender - expected).max()),
                "keys": len(frame_rows),
                "imported": summary,
            }
        played_back[key] = found
    return played_back


def measure(run: Path, solvers: list[str] | None, data: str | None, per_take: int) -> list[tuple]:
    """(basis, solver, max abs mm, keys) for every basis of a run exported under each solver (PCA once)."""
    from workbench.record.replay import replay
    from workbench.reporting.export.bases import exported_bases
    from workbench.reporting.export.run import export_run, read_run_record

    record = read_run_record(run)
    solvers = solvers or list(record.config.get("solver") or {})
    results = {result.data: result for result in replay(record, "rerun the study and check the new record")}
    data = data or next(iter(results))
    result = results[data]
    neutral = result.capture.neutral.reshape(-1, 3)
    measured = []
    with tempfile.TemporaryDirectory(prefix="playback-check-") as scratch:
        for solver in solvers:
            out = Path(scratch) / solver
            labels = (
                None
                if solver == solvers[0]
                else [label for label in ("H", "QE", "QE-linear") if (label, solver) in result.weights]
            )
            manifest = export_run(run, out, data=data, solver=solver, bases=labels)
            bases = exported_bases(result, labels, solver, record.table)
            for label, found in playback_differences(out, manifest, bases, neutral, per_take).items():
                measured.append((label, "projection" if label == "PCA" else solver, found["max_abs_mm"], found["keys"]))
    return measured


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--solvers", help="comma-separated (default: the run's)")
    parser.add_argument("--data", help="data variant (default: the run's first)")
    parser.add_argument("--keys", type=int, default=12, help="keys evaluated per take (default 12)")
    args = parser.parse_args(argv)
    rows = measure(args.run, args.solvers.split(",") if args.solvers else None, args.data, args.keys)
    print(f"{'basis':<10} {'solver':<11} {'max_abs_mm':>11} {'keys':>5}")
    for label, solver, difference, keys in rows:
        print(f"{label:<10} {solver:<11} {difference:>11.3g} {keys:>5}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
