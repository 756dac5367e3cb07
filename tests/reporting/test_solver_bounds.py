"""Every caller of the identities passes the run's own solver bounds (its config's ``solver``), never the kinds'
defaults: a run with ``solver.box.upper=2`` says its box is [0, 2] wherever an ordering holds by construction."""

import dataclasses

import pytest

from workbench.reporting.findings.comparisons import adjusted_comparisons, comparison_table, multiplicity_text
from workbench.reporting.findings.run import run_findings
from workbench.reporting.findings.run_summary import run_summary
from workbench.reporting.report.run import comparison_sections
from workbench.reporting.tables.runs import never_worse_than
from workbench.study.summary import headline_column

WIDE = "box's weights [0, 2]"
DEFAULT = "box's weights [0, 1]"


@pytest.fixture(scope="module")
def wide_box_run(tmp_path_factory):
    from in_process import run_workbench

    from workbench.record.record import load_record

    folder = tmp_path_factory.mktemp("bounds") / "run"
    done = run_workbench(
        "dataset.n_frames=300", "solver=all", "solver.box.upper=2", f"hydra.run.dir={folder}", cwd=folder.parent
    )
    assert done.returncode == 0, done.stderr
    return load_record(folder)


def test_the_report_states_the_runs_own_box(wide_box_run):
    record = wide_box_run
    assert record.config["solver"]["box"]["upper"] == 2.0
    sections = comparison_sections(record)
    table = sections[0].blocks[1]
    verdicts = " ".join(table["verdict"])
    assert WIDE in verdicts and DEFAULT not in verdicts
    findings = " ".join(
        run_findings(
            record.table,
            headline_column(record.config),
            {},
            {data: values["intuitiveness"] for data, values in record.metrics["data"].items()},
            record.metrics,
            record.config,
        )
    )
    assert DEFAULT not in findings
    # the callers left to themselves would fall back to the kinds' defaults: the record's metrics keep no bounds
    assert DEFAULT in " ".join(comparison_table(record.metrics)["verdict"])
    solvers = record.config["solver"]
    assert WIDE in " ".join(comparison_table(record.metrics, solvers=solvers)["verdict"])
    assert adjusted_comparisons(record.metrics, solvers) and multiplicity_text(record.metrics, solvers)
    assert run_summary(record.table, headline_column(record.config), record.metrics, solvers)


def test_the_runs_table_nests_the_solvers_by_the_runs_bounds(wide_box_run):
    record = wide_box_run
    found = never_worse_than(record)
    assert "H/box" in found[("markers", "H", "nnls")].split(";")  # [0, 2] lies inside the non-negative weights
    # a box reaching below 0 would not: the same record with its config's box from -1 nests nnls above nothing
    below = dict(record.config, solver=dict(record.config["solver"], box={"kind": "box", "lower": -1.0, "upper": 2.0}))
    moved = never_worse_than(dataclasses.replace(record, config=below))
    assert "H/box" not in moved.get(("markers", "H", "nnls"), "").split(";")
