"""``workbench report <run or sweep folder>``: an HTML page and a README.md with the alpha tables, the paper's
figures and the study plots, rebuilt from run records only.

A *run* folder holds a complete record (``done`` written last, see :mod:`workbench.record.record`); a *sweep* folder
holds run folders at any depth. The report of a run has the alpha tables beside the paper's values, figures 1-4
(from the inputs a run writes with ``save_inputs=true``, or rebuilt from its config when it wrote none), the
coverage curve, alpha per frame over time and marker versus mesh; the report of a sweep has the tidy table of means and 95 % confidence intervals over
seeds and alpha against every swept setting. Both state the dataset's provenance and licence, the choices the run
made, and the versions and commit that made it.

This module is the command: its arguments, where the report goes, and which report it builds. The report of a run
is :mod:`workbench.reporting.report.run`, of a sweep :mod:`workbench.reporting.report.sweep`; their figures
:mod:`workbench.reporting.report.run_figures` and :mod:`workbench.reporting.report.faces`, the arrays recomputed for
them :mod:`workbench.reporting.report.data`, and the documents :mod:`workbench.reporting.report.page` renders from the
templates in ``workbench/reporting/report/templates``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Sequence

from workbench.core.errors import WorkbenchError
from workbench.core.files import FORCE_FLAG, check_output_folder, inside, output_folder, plain_name
from workbench.record.record import DONE, RunRecord, is_complete, load_record
from workbench.reporting.report.run import build_run_report
from workbench.reporting.report.run_figures import FIGURE_FORMATS
from workbench.reporting.report.sweep import build_sweep_report, sweep_records


def default_report_name(study: str, kind: str) -> str:
    """``<study>`` for the synthetic actor, ``<study>-<dataset kind>`` for other data."""
    return study if kind == "synthetic" else f"{study}-{kind}"


REPORT_FOLDER = "report"
"""Default report folder, inside the run or sweep folder it reports on."""
SHARED_FOLDER = "shared"
"""Folder of the figures the reference reports share, beside them (``reports/shared``)."""
REPORT_FILES = ("index.html", "README.md", "figures", "alpha_table.csv", "run_config.yaml")
SWEEP_REPORT_FILES = ("index.html", "README.md", "figures", "summary.csv", "comparisons.csv", "runs.csv")
"""What a report of a run, or of a sweep, writes: accepted without the output marker in a folder the workbench
chose itself (``<folder>/report``, ``reports/<name>``), as reports written before folders were marked hold them."""
WRITER = "a report"


def check_report_name(name: str) -> None:
    """``--name``: a plain folder name that is not blank and not :data:`SHARED_FOLDER`; an empty one is refused,
    never taken as the default (it would rewrite the default reference report)."""
    if not plain_name(name) or not name.strip():
        raise WorkbenchError(
            f"--name must be a plain folder name (not empty or blank, no path, not '.' or '..'), got {name!r}"
        )
    if name == SHARED_FOLDER:
        raise WorkbenchError(
            f"--name {SHARED_FOLDER} is reserved: reports/{SHARED_FOLDER} holds the figures the reference reports "
            "share; choose another name"
        )


def report_folder(folder: Path, study: str, kind: str, *, out: Path | None, reference: bool, name: str | None) -> Path:
    """Where a report goes: ``--out`` as given, the checkout's ``reports/<name>`` with ``--reference`` (by default
    named by the run's ``study`` and ``dataset.kind``: :func:`default_report_name`), else ``<folder>/report`` beside
    the runs."""
    from workbench.settings.config import CHECKOUT

    if out is not None and reference:
        raise WorkbenchError("give either --out or --reference, not both")
    if name is not None and not reference:
        raise WorkbenchError("--name names a reference report; it goes with --reference")
    if name is not None:
        check_report_name(name)
    if reference:
        name = default_report_name(study, kind) if name is None else name
        check_report_name(name)
        if CHECKOUT is None:
            raise WorkbenchError(
                "--reference rewrites the committed reports of the workbench's checkout, and this "
                "workbench is an installed package: use --out DIR, or run from a checkout"
            )
        return inside(CHECKOUT / "reports", name)
    return Path(out) if out is not None else inside(folder, REPORT_FOLDER)


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="workbench report",
        description="Build the report of a run record or of a sweep folder, from its "
        "records only. It goes into <folder>/report unless --out or --reference says otherwise.",
    )
    parser.add_argument("folder", type=Path, help=f"a run record (holds '{DONE}') or a folder of run records")
    parser.add_argument(
        "--out",
        help="the report folder: new, empty, or one a report wrote before (default: <folder>/report)",
    )
    parser.add_argument(
        "--reference",
        action="store_true",
        help="(re)write the workbench's committed reference report reports/<name> of the checkout",
    )
    parser.add_argument(
        "--name",
        help="with --reference: the report's folder name (default: the study, plus the dataset unless synthetic)",
    )
    parser.add_argument(
        "--formats",
        default=",".join(FIGURE_FORMATS),
        help="copies of each figure besides the one the report shows (faces as WebP, line plots as "
        "SVG), comma-separated: png, svg, pdf (default: none)",
    )
    parser.add_argument("--shapes", help="figure 2: four hand-shape names, comma-separated")
    parser.add_argument(
        FORCE_FLAG,
        action="store_true",
        help="replace files of an earlier output that were changed since it was written",
    )
    return parser.parse_args(list(argv))


FIGURE_2_SHAPES = 4
"""Hand shapes figure 2 shows (the paper's figure 2)."""


def figure_2_shapes(text: str, record: RunRecord) -> list[str]:
    """``--shapes``: four distinct hand shapes of the run, checked before the report is written."""
    names = [name.strip() for name in text.split(",") if name.strip()]
    if len(names) != FIGURE_2_SHAPES or len(set(names)) != len(names):
        raise WorkbenchError(
            f"--shapes takes {FIGURE_2_SHAPES} distinct hand-shape names (figure 2 shows "
            f"{FIGURE_2_SHAPES}), got {names}"
        )
    known = list(record.metrics["dataset"].get("hand_names") or [])
    unknown = [name for name in names if known and name not in known]
    if unknown:
        raise WorkbenchError(f"--shapes names unknown hand shapes {unknown}; the run has {known}")
    return names


def main(argv: Sequence[str]) -> int:
    """``workbench report <folder> [--out DIR | --reference [--name NAME]] [--formats png,pdf] [--shapes a,b,c,d]``."""
    args = parse_args(argv)
    if args.name is not None:
        check_report_name(args.name)
    formats = [fmt.strip() for fmt in args.formats.split(",") if fmt.strip()]
    unknown = sorted(set(formats) - {"png", "svg", "pdf"})
    if unknown:
        raise WorkbenchError(f"--formats takes png, svg, pdf; got {unknown}")
    if args.out is not None:  # refused before any record is read
        check_output_folder(args.out, "--out", writer=WRITER, force=args.force)
    folder = args.folder
    if not folder.is_dir():
        raise WorkbenchError(f"{folder} is not a folder")
    command = "workbench report " + " ".join(argv)
    setting = "--name" if args.reference else "--out"
    if is_complete(folder):
        record = load_record(folder, check_archives=True)
        settings = record.settings
        out = report_folder(
            folder, settings.study, settings.dataset.kind, out=args.out, reference=args.reference, name=args.name
        )
        options = {
            "shapes": figure_2_shapes(args.shapes, record) if args.shapes is not None else None,
            "shared": out.parent / SHARED_FOLDER if args.reference else None,
        }
        known = REPORT_FILES if args.out is None else ()
        with output_folder(out, setting, writer=WRITER, known=known, force=args.force) as staging:
            build_run_report(record, staging, formats=formats, options=options, command=command)
    else:
        first = sweep_records(folder)[0]
        settings = first.settings
        out = report_folder(
            folder, settings.study, settings.dataset.kind, out=args.out, reference=args.reference, name=args.name
        )
        known = SWEEP_REPORT_FILES if args.out is None else ()
        with output_folder(out, setting, writer=WRITER, known=known, force=args.force) as staging:
            build_sweep_report(folder, staging, formats=formats, command=command)
    print(f"report: {out / 'index.html'}")
    return 0
