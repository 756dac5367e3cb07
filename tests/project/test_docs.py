"""The documentation runs as written: every command of every shell block of README.md and docs/ (how they are read,
filled in and run: tests/doc_blocks.py and docs/commands.md)."""

import json
import os
import re

import pytest
from doc_blocks import (
    LONG_SECONDS,
    REPO_ROOT,
    TIMES_DOC,
    Command,
    Reuse,
    Scratch,
    all_commands,
    documents,
    identity,
    measured_times,
    naming,
    prerequisites,
    reads,
    repeated_commands,
    run_document,
    runnable,
    table_rows,
    writes,
)

DOCUMENTED = all_commands()
PLACEHOLDER = re.compile(r"<[A-Za-z][\w-]*>")
FILLED = {"<date-time>", "<TAB>", "<partition>"}


def test_every_document_has_its_commands_read():
    assert {"README.md", "docs/studies.md", "docs/tracking.md"} <= set(DOCUMENTED)
    readme = DOCUMENTED["README.md"]
    assert readme[0].summary == "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/workbench"
    heredoc = next(command for command in DOCUMENTED["docs/formats.md"] if "<<'PY'" in command.text)
    assert heredoc.text.splitlines()[-1] == "PY" and "outputs/take_mediapipe.json" in writes(heredoc)


@pytest.mark.parametrize("doc", documents())
def test_placeholders_are_ones_the_test_fills(doc):
    for command in DOCUMENTED[doc]:
        unknown = set(PLACEHOLDER.findall(command.code)) - FILLED
        assert not unknown, f"{doc}:{command.line} uses {unknown}: fill it in tests/doc_blocks.py"


def test_the_readme_test_command_is_what_ci_runs():
    test_command = next(command.text for command in DOCUMENTED["README.md"] if "pytest" in command.text)
    assert test_command.endswith("&& .venv/bin/pytest") and ".[test,mlflow]" in test_command
    assert test_command in (REPO_ROOT / ".ci" / "run").read_text().splitlines()


def test_prerequisites_come_from_the_pages_that_write_what_a_page_reads():
    found = prerequisites("docs/reports.md", DOCUMENTED)
    assert [command.summary for command in found] == [".venv/bin/workbench --config-name coverage"]
    assert "outputs/coverage/default" in reads(DOCUMENTED["docs/reports.md"][3])
    assert prerequisites("docs/export.md", DOCUMENTED) == []  # export.md makes its own runs first
    # the only outputs/coverage/default of tracking.md is in a command the test does not run (a lab's server)
    assert prerequisites("docs/tracking.md", DOCUMENTED) == []


def test_commands_are_made_runnable_without_installing_anything(tmp_path):
    readme = DOCUMENTED["README.md"][0]
    assert runnable(readme, tmp_path) == "true && doc_has_extras '' && .venv/bin/workbench"
    tab = next(command for command in DOCUMENTED["docs/tracking.md"] if "<TAB>" in command.text)
    assert runnable(tab, tmp_path).startswith("doc_complete 'workbench ")
    report = next(command for command in DOCUMENTED["README.md"] if "<date-time>" in command.text)
    assert '"$(ls outputs/paper | tail -n 1)"' in runnable(report, tmp_path)


def test_measured_rows_are_documented_commands():
    """docs/commands.md lists only commands the docs still hold (measure rewrites it when they change)."""
    documented = {command.key: command for listed in DOCUMENTED.values() for command in listed}
    rows = table_rows()
    assert rows, f"{TIMES_DOC} has no measured rows"
    for key, cells in rows.items():
        assert key in documented, f"{TIMES_DOC}: {cells[0]} {cells[1]} is no longer documented: measure its page"
        assert cells[5] == ("long: not run" if float(cells[3].removesuffix(" s")) >= LONG_SECONDS else "run")


def test_the_same_command_is_its_text_without_comments_and_unset_variables_the_environment_lacks():
    assert identity("env -u A_B -u C .venv/bin/x  run  # a note", {}) == ".venv/bin/x run"
    assert identity("env -u A_B -u C .venv/bin/x run", {"C": "1"}) == "env -u A_B -u C .venv/bin/x run"
    repeated = repeated_commands(DOCUMENTED, {})
    assert ".venv/bin/workbench --config-name coverage" in repeated  # README, reports.md (prerequisite), studies.md
    assert ".venv/bin/python benchmarks/run.py markers" in repeated  # twice in performance.md, once with env -u


@pytest.mark.process
def test_a_command_run_again_has_its_output_copied_into_the_new_scratch_copy(tmp_path):
    text = (
        ".venv/bin/python - <<'PY'\nimport os, pathlib\npathlib.Path('outputs').mkdir()\n"
        "pathlib.Path('outputs/where.txt').write_text(os.getcwd())\nPY"
    )
    command = Command("docs/x.md", 1, 1, text)
    reuse = Reuse(tmp_path / "kept")
    reuse.repeated = {identity(command.text, {}, heredoc=True)}
    first, second = Scratch(tmp_path / "first"), Scratch(tmp_path / "second")
    ran = reuse.run(first, command, runnable(command, first.tmp), [], 60)
    copied = reuse.run(second, command, runnable(command, second.tmp), [], 60)
    assert ran.status == copied.status == "ok" and ran.cpu_seconds > 0, ran.output
    assert "not run again" not in ran.note and copied.note.startswith("not run again: ran for docs/x.md:1")
    assert (second.root / "outputs" / "where.txt").read_text() == str(second.root)  # its path, not the first's
    again = reuse.run(second, command, runnable(command, second.tmp), [], 60)  # its folder is there: it runs
    assert again.status == "failed" and "FileExistsError" in again.output


def test_a_file_that_names_the_scratch_folder_is_rewritten_unless_its_record_checks_it(tmp_path):
    run = tmp_path / "checkout" / "outputs" / "run"
    run.mkdir(parents=True)
    (run / "metrics.json").write_text(json.dumps({"data": f"{tmp_path}/shared/data"}))
    (run / "workbench.log").write_text(f"ran in {tmp_path}/checkout")
    (run / "alpha_table.csv").write_text("alpha\n0.1\n")
    (run / "done").write_text(json.dumps({"sha256": {"metrics.json": "0", "alpha_table.csv": "1"}}))
    assert naming(tmp_path, tmp_path / "checkout", ["outputs/run"]) == {
        "outputs/run/metrics.json": (True, True),  # Reuse keeps no copy of this run
        "outputs/run/workbench.log": (True, False),
    }


@pytest.fixture(scope="session")
def compiled_solvers():
    """A small run in this process first: numba compiles the solvers and the synthetic actor into its cache beside
    the sources, which every scratch copy takes along (tests/doc_blocks.py)."""
    from workbench.api import run_study
    from workbench.settings.config import compose

    run_study(compose("paper", ["dataset.n_frames=300", "dataset.mesh_rows=20", "dataset.mesh_cols=20", "solver=all"]))


@pytest.fixture(scope="session")
def reused_outputs(tmp_path_factory):
    """The outputs of commands that several documents run, kept from their first run in this test run
    (tests/doc_blocks.py, Reuse): in a folder every test process sees, beside the processes' own temporary folders
    under pytest-xdist."""
    base = tmp_path_factory.getbasetemp()
    return Reuse((base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "doc-command-outputs")


def check_documented_commands(doc: str, tmp_path, reuse: Reuse) -> None:
    """Every command of ``doc`` runs in a scratch copy of the checkout (or, run by another document's test before,
    has its output copied there), none unmeasured takes a CPU-minute, and none leaves a file in the checkout."""
    scratch = Scratch(tmp_path)
    times = measured_times()
    lines = []
    outcomes = run_document(doc, scratch, report=lines.append, reuse=reuse)
    print("\n".join(lines))
    failed = [outcome for outcome in outcomes if outcome.status == "failed"]
    assert not failed, (
        f"{failed[0].command.doc}:{failed[0].command.line} failed ({failed[0].note}): "
        f"{failed[0].command.summary}\n{failed[0].output[-4000:]}"
    )
    slow = [
        outcome
        for outcome in outcomes
        if outcome.status == "ok" and outcome.command.key not in times and outcome.cpu_seconds >= LONG_SECONDS
    ]
    assert not slow, (
        f"{slow[0].command.doc}:{slow[0].command.line} took {slow[0].cpu_seconds:.0f} CPU s and is "
        f"not in {TIMES_DOC}: run 'tests/doc_blocks.py measure {slow[0].command.doc}'"
    )
    assert scratch.changes() == [], f"the commands of {doc} left files in the checkout"


def commands_test_class(doc: str) -> type:
    """A test class of its own for one document's commands: pytest-xdist (``--dist loadscope``) sends each class
    to whichever worker is free, so the documents' commands run on both workers while every test file keeps its
    tests, and its module fixtures, on one."""

    @pytest.mark.slow
    @pytest.mark.process
    class TestDocumentedCommands:
        def test_commands_run(self, shared_data, tmp_path, compiled_solvers, reused_outputs):
            check_documented_commands(doc, tmp_path, reused_outputs)

    name = "TestCommandsOf_" + re.sub(r"\W", "_", doc)
    TestDocumentedCommands.__name__ = TestDocumentedCommands.__qualname__ = name
    return TestDocumentedCommands


for _doc in documents():
    _class = commands_test_class(_doc)
    globals()[_class.__name__] = _class
