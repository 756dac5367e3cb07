"""``workbench collect SWEEP_DIR ...``: the command's arguments (the ``--where`` filters among them), and what it prints
of the tables :func:`~workbench.reporting.collect.sweep.collect_and_write` wrote."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Sequence

from workbench.core.errors import WorkbenchError
from workbench.core.files import FORCE_FLAG, check_output_folder, inside
from workbench.record.record import DONE
from workbench.reporting.collect.sweep import COLLECTED, COLLECTED_FILES, WRITER, collect_and_write, findings_text
from workbench.reporting.tables.width import PRINT_WIDTH, fit_width


def parse_where(items: Sequence[str]) -> dict:
    where = {}
    for item in items:
        key, separator, value = item.partition("=")
        if not separator or not key:
            raise WorkbenchError(f"collect --where must be KEY=VALUE, got {item!r}")
        where[key] = value
    return where


def main(argv: Sequence[str]) -> int:
    """``workbench collect SWEEP_DIR [SWEEP_DIR ...] [--out DIR] [--metric M] [--where K=V] ...``."""
    parser = argparse.ArgumentParser(
        prog="workbench collect",
        description=f"Gather run records (folders with a '{DONE}' marker) of one or many sweeps into runs.csv/"
        ".parquet, summary.csv/.parquet (geometric mean and 95%% interval over seeds), comparisons.csv/.md "
        "(paired comparisons of the bases), alpha_table.md/.tex and findings.md.",
    )
    parser.add_argument("paths", nargs="+", type=Path, help="sweep folders, run folders or folders above them")
    parser.add_argument(
        "--out", help="output folder: new, empty, or one collect wrote before (default: <the one path>/collected)"
    )
    parser.add_argument("--metric", default="alpha_abs_mean", help="metric of the alpha table")
    parser.add_argument(
        "--where",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="keep only rows with this value, e.g. solver=lstsq (repeatable)",
    )
    parser.add_argument("--columns", default="basis", help="key whose values become the table's columns")
    parser.add_argument("--extra", default="m", help="comma-separated metrics shown beside the row keys")
    parser.add_argument("--over", help="comma-separated replicate columns (default: the config keys naming a seed)")
    parser.add_argument(
        FORCE_FLAG,
        action="store_true",
        help="replace files of an earlier output that were changed since it was written",
    )
    parser.add_argument(
        "--wide", action="store_true", help=f"print long lines whole (default: within {PRINT_WIDTH} columns)"
    )
    args = parser.parse_args(list(argv))
    fit = (lambda text: text) if args.wide else fit_width
    if args.out is None and len(args.paths) != 1:
        raise WorkbenchError("collect: give --out when collecting more than one path")
    if args.out is not None:  # refused before any record is read
        check_output_folder(args.out, "--out", writer=WRITER, force=args.force)
    out = Path(args.out) if args.out is not None else inside(args.paths[0], COLLECTED)
    written = collect_and_write(
        args.paths,
        out,
        metric=args.metric,
        where=parse_where(args.where),
        columns=args.columns,
        extra=[name for name in args.extra.split(",") if name],
        over=None if args.over is None else [name for name in args.over.split(",") if name],
        known=COLLECTED_FILES if args.out is None else (),
        force=args.force,
    )
    print(fit(written["markdown"] + findings_text(written["findings"])), end="")
    note = f"; {written['n_incomplete']} incomplete run folders left out" if written["n_incomplete"] else ""
    print(fit(f"collected {written['n_runs']} runs into {out}{note}"))
    return 0
