"""Write the studies' collected tables and findings into docs/studies.md, from the run records of their sweeps.

Each block of the page between ``<!-- collected: STUDY [metric=M] -->`` and ``<!-- end collected: STUDY -->`` is
replaced by what ``workbench collect`` makes of ``OUTPUT_ROOT/STUDY/default`` with the study's own layout (its
``hydra.callbacks.collect``; ``metric=M`` replaces its metric): the command, the alpha table and the findings.
Nothing in a block is typed by hand.

    .venv/bin/workbench --config-name coverage          # ... each study whose block is to be refreshed
    .venv/bin/python docs/study_tables.py [OUTPUT_ROOT]  # default: outputs
"""

from __future__ import annotations

import re
import sys
import tempfile
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

from workbench.core.errors import WorkbenchError
from workbench.reporting.collect.sweep import collect_and_write
from workbench.settings.config import compose

PAGE = Path(__file__).with_name("studies.md")
BLOCK = re.compile(r"(<!-- collected: (\S+)((?: \w+=\S+)*) -->\n).*?(<!-- end collected: \2 -->)", re.DOTALL)


def collect_options(layout: dict) -> str:
    """The ``workbench collect`` options of a study's layout, as typed on the command line."""
    options = [f"--metric {layout['metric']}"] if "metric" in layout else []
    options += [f"--where {key}={value}" for key, value in (layout.get("where") or {}).items()]
    options += [f"--columns {layout['columns']}"] if "columns" in layout else []
    options += [f"--extra {','.join(layout['extra'])}"] if layout.get("extra") else []
    return " ".join(options)


def sweep_overrides(sweep: Path) -> str:
    """The overrides the sweep was started with (Hydra's ``multirun.yaml`` in the sweep folder), as typed."""
    multirun = sweep / "multirun.yaml"
    task = OmegaConf.load(multirun).hydra.overrides.task if multirun.is_file() else []
    return "".join(f" {override}" for override in task)


def block(study: str, root: Path, metric: str | None = None) -> str:
    """The text of one study's block: the commands, the alpha table and the findings of its sweep (of ``metric``
    instead of the study's own when given)."""
    layout = OmegaConf.to_container(compose(study).hydra.callbacks.collect)
    layout.pop("_target_")
    if metric is not None:
        layout["metric"] = metric
    sweep = root / study / "default"
    with tempfile.TemporaryDirectory() as scratch:
        written = collect_and_write([sweep], Path(scratch), **layout)
        runs = pd.read_parquet(Path(scratch) / "runs.parquet").drop_duplicates("run")
    seconds = runs["time_total"].sum() if "time_total" in runs.columns else float("nan")
    findings = "".join(f"- {line}\n" for line in written["findings"])
    return (
        f"`.venv/bin/workbench --config-name {study}{sweep_overrides(sweep)}`, then `.venv/bin/workbench collect "
        f"outputs/{study}/default {collect_options(layout)}`: {written['n_runs']} runs "
        f"({seconds:,.0f} s of run time, the sum of the runs' own).\n\n{written['markdown']}\n"
        f"<details><summary>Findings ({len(written['findings'])}, generated from the alpha table and the paired "
        f"comparisons)</summary>\n\n{findings}\n</details>\n"
    )


def main(argv: list[str]) -> int:
    root = Path(argv[0]) if argv else Path("outputs")
    page = PAGE.read_text()

    def refresh(match: re.Match) -> str:
        options = dict(item.split("=", 1) for item in match.group(3).split())
        try:
            text = block(match.group(2), root, options.get("metric"))
        except WorkbenchError as error:  # a study not run: its block stays as it was
            print(f"{match.group(2)}: kept ({error})")
            return match.group(0)
        print(f"{match.group(2)}{match.group(3)}: written")
        return f"{match.group(1)}{text}{match.group(4)}"

    PAGE.write_text(BLOCK.sub(refresh, page))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
