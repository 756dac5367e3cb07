"""The documentation runs as written: every command of every shell block of README.md and docs/ (how they are read,
filled in and run: tests/doc_blocks.py and docs/commands.md)."""

import re

import pytest
from doc_blocks import (
    LONG_SECONDS,
    REPO_ROOT,
    TIMES_DOC,
    Scratch,
    all_commands,
    documents,
    measured_times,
    prerequisites,
    reads,
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


@pytest.fixture(scope="session")
def compiled_solvers():
    """A small run in this process first: numba compiles the solvers and the synthetic actor into its cache beside
    the sources, which every scratch copy takes along (tests/doc_blocks.py)."""
    from workbench.api import run_study
    from workbench.settings.config import compose

    run_study(compose("paper", ["dataset.n_frames=300", "dataset.mesh_rows=20", "dataset.mesh_cols=20", "solver=all"]))


def check_documented_commands(doc: str, tmp_path) -> None:
    """Every command of ``doc`` runs in a scratch copy of the checkout, none unmeasured takes a CPU-minute, and
    none leaves a file in the checkout."""
    scratch = Scratch(tmp_path)
    times = measured_times()
    lines = []
    outcomes = run_document(doc, scratch, report=lines.append)
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
    class TestDocumentedCommands:
        def test_commands_run(self, shared_data, tmp_path, compiled_solvers):
            check_documented_commands(doc, tmp_path)

    name = "TestCommandsOf_" + re.sub(r"\W", "_", doc)
    TestDocumentedCommands.__name__ = TestDocumentedCommands.__qualname__ = name
    return TestDocumentedCommands


for _doc in documents():
    _class = commands_test_class(_doc)
    globals()[_class.__name__] = _class
