"""``workbench export RUN_DIR``: the command's arguments, and the lines it prints for what :func:`export_run` wrote."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from workbench.core.files import FORCE_FLAG, check_output_folder, inside
from workbench.reporting.export.run import OBJ_UNITS, WRITER, export_run


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
    parser.add_argument(
        FORCE_FLAG,
        action="store_true",
        help="replace files of an earlier output that were changed since it was written",
    )
    args = parser.parse_args(list(argv))
    if args.out is not None:  # refused before the run is rebuilt
        check_output_folder(args.out, "--out", writer=WRITER, force=args.force)
    out = Path(args.out) if args.out is not None else inside(args.run, "export")
    bases = None if args.bases is None else [label for label in args.bases.split(",") if label]
    manifest = export_run(
        args.run, out, data=args.data, bases=bases, solver=args.solver, obj_unit=args.obj_unit, force=args.force
    )
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
