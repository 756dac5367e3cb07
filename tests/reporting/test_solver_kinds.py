"""The table of solver kinds: the settings, the solve, the findings and the figures read one entry per kind, so a new
kind is its solve and one entry; the findings name a solver by the bounds the run gave it."""

import re

import numpy as np
import pytest
from test_findings import PAPER, known_table

from workbench.api import read_record, run
from workbench.core.errors import WorkbenchError
from workbench.core.solvers import SOLVER_KINDS, SolverKind, solver_text
from workbench.numerics import solve
from workbench.reporting.findings.run import run_findings
from workbench.reporting.report.run_figures import draw_alpha_per_solver
from workbench.settings.config import compose
from workbench.settings.typed import study_settings

TOY = SolverKind((), -0.5, 0.5, "weights clipped to [{lower}, {upper}]", line_style="-.", hatch="++")


def clipped(problem):
    """The toy kind's solve: the unconstrained weights clipped to its bounds."""
    return np.clip(problem.start, problem.lo, problem.hi), 0, 0, 0.0


@pytest.fixture
def toy_kind(monkeypatch):
    monkeypatch.setitem(SOLVER_KINDS, "clip", TOY)
    monkeypatch.setitem(solve.SOLVES, "clip", clipped)


def test_a_new_kind_is_its_solve_and_one_entry(toy_kind, tmp_path):
    with pytest.raises(WorkbenchError, match=re.escape("must be one of ('lstsq', 'nnls', 'box', 'clip'), got 'qp'")):
        study_settings(compose("paper", ["dataset.n_frames=200", "solver=lstsq", "solver.lstsq.kind=qp"]))
    # a solver named box of the toy kind: every part reads its kind from the settings, not its name
    overrides = ["solver=[lstsq,box]", "solver.box.kind=clip", "solver.box.lower=null", "solver.box.upper=null"]
    cfg = compose("paper", ["dataset.n_frames=200", *overrides])
    run(cfg, tmp_path / "run")
    record = read_record(tmp_path / "run")
    table = record.table
    assert {"lstsq", "box"} <= set(table["solver"])
    toy_rows = [row for row in record.metrics["rows"] if row["solver"] == "box" and row.get("weights")]
    assert toy_rows and all(row["weights"]["max_abs"] <= 0.5 + 1e-12 for row in toy_rows)
    lstsq_rows = [row for row in record.metrics["rows"] if row["solver"] == "lstsq" and row.get("weights")]
    assert max(row["weights"]["max_abs"] for row in lstsq_rows) > 0.5  # the bounds changed the weights

    lines = run_findings(table, "alpha_abs_mean", PAPER, {}, record.metrics, record.config)
    assert any("with weights clipped to [-0.5, 0.5] QE's alpha" in line for line in lines)

    figure = draw_alpha_per_solver(record, {})
    bars = {container.get_label(): container for container in figure.axes[0].containers}
    assert {patch.get_hatch() for patch in bars["box"]} == {"++"}  # the toy kind's, not box weights'
    assert {patch.get_hatch() or "" for patch in bars["lstsq"]} == {""}
    assert [text.get_text() for text in figure.legends[0].get_texts()] == ["lstsq", "box"]
    assert [patch.get_hatch() or "" for patch in figure.legends[0].get_patches()] == ["", "++"]


def test_the_findings_name_a_solver_by_the_bounds_the_run_gave_it():
    table = known_table()
    table = table[table["solver"] != "nnls"].replace({"solver": {"box": "wide"}})
    settings = {"lstsq": {"kind": "lstsq"}, "wide": {"kind": "box", "lower": 0.0, "upper": 2.0}}
    lines = run_findings(table, "alpha_abs_mean", PAPER, {}, config={"solver": settings})
    assert any(line.startswith("**mesh**: with box [0, 2] weights QE's alpha x") for line in lines)
    # without the settings a solver named other than its kind has no known kind: no constraint is said
    assert not any("weights QE's alpha x" in line for line in run_findings(table, "alpha_abs_mean", PAPER, {}))


def test_the_description_is_made_from_the_bounds():
    assert solver_text("box") == "box [0, 1] weights"  # the kind's defaults, conf/solver/box.yaml's
    assert solver_text("b", {"b": {"kind": "box", "lower": None, "upper": 3}}) == "box [-inf, 3] weights"
    assert solver_text("nnls", {"nnls": {"kind": "nnls", "lower": 0.0}}) == "non-negative weights"
    assert solver_text("mine") == "mine"  # no known kind: its name


def test_the_conf_files_give_each_kind_the_table_s_defaults():
    solvers = compose("paper", ["solver=all"]).solver
    assert list(solvers) == list(SOLVER_KINDS)
    for kind, entry in SOLVER_KINDS.items():
        assert (solvers[kind].kind, solvers[kind].lower, solvers[kind].upper) == (kind, entry.lower, entry.upper)


def test_the_solve_keeps_the_bounds_a_kind_fixes(toy_kind):
    rng = np.random.default_rng(3)
    basis, targets = rng.standard_normal((4, 30)), rng.standard_normal((20, 30)) * 3
    solution = solve.solve_weights(basis, targets, kind="clip")
    assert (solution.lower, solution.upper) == (-0.5, 0.5)
    free = solve.solve_weights(basis, targets).weights
    np.testing.assert_array_equal(solution.weights, np.clip(free, -0.5, 0.5))
    with pytest.raises(WorkbenchError, match=re.escape("kind 'clip' fixes lower=-0.5 and upper=0.5")):
        solve.solve_weights(basis, targets, kind="clip", upper=1.0)
    with pytest.raises(WorkbenchError, match=re.escape("kind 'nnls' fixes lower=0 and upper=None")):
        solve.solve_weights(basis, targets, kind="nnls", lower=1.0)
