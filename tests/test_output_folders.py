"""Where ``report``, ``export`` and ``collect`` write: a folder of their own (new, empty, or one the workbench
wrote before), never the current folder by an empty name and never a folder holding someone's files; written
whole into a temporary folder beside it and moved into place."""

import hashlib
import os
from pathlib import Path

import pytest
from in_process import run_workbench

from workbench.core.errors import WorkbenchError
from workbench.core.files import OUTPUT_MARKER, check_output_folder, output_folder, write_atomic
from workbench.reporting.pages import REPORT_FILES

USER_FILES = {
    "README.md": "# my project\n",
    "index.html": "<p>my page</p>\n",
    "manifest.json": '{"mine": true}\n',
    "runs.csv": "run,value\n1,2\n",
    "summary.csv": "a,b\n",
}


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    from workbench.api import run
    from workbench.settings.config import compose

    folder = tmp_path_factory.mktemp("output_folders") / "run"
    run(compose("paper", ["dataset.n_frames=300", "basis.paper_regime=false"]), folder)
    return folder


def user_folder(path: Path) -> Path:
    path.mkdir()
    for name, text in USER_FILES.items():
        (path / name).write_text(text)
    return path


def digests(folder: Path) -> dict:
    return {path.name: hashlib.sha256(path.read_bytes()).hexdigest() for path in sorted(folder.iterdir())}


def one_line_refusal(result) -> str:
    assert result.returncode == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


@pytest.mark.parametrize("command", ["report", "export", "collect"])
@pytest.mark.parametrize("out", ["", "."])
def test_an_empty_or_current_out_leaves_a_users_files_as_they_were(record, tmp_path, command, out):
    here = user_folder(tmp_path / "project")
    before = digests(here)
    line = one_line_refusal(run_workbench(command, record, "--out", out, cwd=here))
    assert "--out" in line and "current directory" in line and "name one" in line, line
    assert digests(here) == before


@pytest.mark.parametrize("command", ["report", "export", "collect"])
def test_a_folder_holding_a_users_files_is_refused_by_name(record, tmp_path, command):
    user = user_folder(tmp_path / "mine")
    before = digests(user)
    line = one_line_refusal(run_workbench(command, record, "--out", user, cwd=tmp_path))
    assert line.startswith(f"workbench {command}: error: {user} holds files the workbench did not write"), line
    assert "README.md" in line and "name another folder (--out=...)" in line, line
    assert digests(user) == before
    assert sorted(os.listdir(tmp_path)) == ["mine"]  # no temporary folder left beside it


def test_a_users_file_among_the_workbenchs_own_is_refused(record, tmp_path):
    out = tmp_path / "tables"
    assert run_workbench("collect", record, "--out", out, cwd=tmp_path).returncode == 0
    (out / "notes.txt").write_text("mine\n")
    line = one_line_refusal(run_workbench("collect", record, "--out", out, cwd=tmp_path))
    assert "(notes.txt)" in line, line
    assert (out / "notes.txt").read_text() == "mine\n"


@pytest.mark.parametrize("command", ["export", "collect"])
def test_a_rerun_into_the_workbenchs_own_folder_replaces_it(record, tmp_path, command):
    out = tmp_path / "out"
    first = run_workbench(command, record, "--out", out, cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    assert (out / OUTPUT_MARKER).is_file()
    names = sorted(os.listdir(out))
    table = out / ("manifest.json" if command == "export" else "runs.csv")
    table.write_text("stale\n")  # the earlier output, changed since
    again = run_workbench(command, record, "--out", out, cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert sorted(os.listdir(out)) == names and table.read_text() != "stale\n"
    assert sorted(os.listdir(tmp_path)) == ["out"]  # the earlier output removed, no temporary folder left


@pytest.mark.slow
def test_a_report_rerun_into_its_own_folder_and_its_default_folder(record, tmp_path):
    out = tmp_path / "report"
    for _ in range(2):
        result = run_workbench("report", record, "--out", out, cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert result.stdout.strip() == f"report: {out / 'index.html'}"
    assert set(os.listdir(out)) == {OUTPUT_MARKER, *REPORT_FILES}
    assert sorted(os.listdir(tmp_path)) == ["report"]


def test_a_default_folder_from_before_folders_were_marked_is_still_the_workbenchs(tmp_path):
    old = tmp_path / "report"
    old.mkdir()
    for name in ("index.html", "README.md", "alpha_table.csv"):
        (old / name).write_text("from an earlier version\n")
    # where the workbench chose the folder (<run>/report, reports/<name>), a report's own names are accepted
    assert check_output_folder(old, "--out", writer="a report", known=REPORT_FILES) == old
    # named with --out, the same names may be anyone's
    with pytest.raises(WorkbenchError, match="holds files the workbench did not write there"):
        check_output_folder(old, "--out", writer="a report")


def test_a_failure_while_writing_leaves_the_earlier_output_and_nothing_else(tmp_path):
    out = tmp_path / "out"
    with output_folder(out, "--out", writer="collect") as staging:
        write_atomic(staging / "runs.csv", "first\n")
    before = digests(out)

    class Stop(Exception):
        pass

    for stop in (Stop, KeyboardInterrupt):
        with pytest.raises(stop):
            with output_folder(out, "--out", writer="collect") as staging:
                write_atomic(staging / "runs.csv", "second, half-written\n")
                raise stop()
        assert digests(out) == before
        assert sorted(os.listdir(tmp_path)) == ["out"]
    # a new folder that fails is not made at all
    with pytest.raises(Stop):
        with output_folder(tmp_path / "new", "--out", writer="collect") as staging:
            write_atomic(staging / "runs.csv", "x\n")
            raise Stop()
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_a_symbolic_link_or_a_file_as_the_output_folder_is_refused(tmp_path):
    target = user_folder(tmp_path / "elsewhere")
    (tmp_path / "link").symlink_to(target)
    (tmp_path / "file").write_text("mine\n")
    with pytest.raises(WorkbenchError, match="is a symbolic link"):
        check_output_folder(tmp_path / "link", "--out", writer="a report")
    with pytest.raises(WorkbenchError, match="is a file, not a folder"):
        check_output_folder(tmp_path / "file", "--out", writer="a report")


def replace_many_times(out: Path, writer: int) -> int:
    """Replace ``out`` 100 times; the number of failures."""
    failures = 0
    for time in range(100):
        try:
            with output_folder(out, "--out", writer="collect") as staging:
                write_atomic(staging / "runs.csv", f"{writer} {time}\n")
        except Exception:  # noqa: BLE001 - counted, whatever it is
            failures += 1
    return failures


@pytest.mark.process
def test_two_processes_replacing_one_output_folder_take_turns(tmp_path):
    """As two identical sweeps ending together both collect their tables into <sweep>/collected."""
    import multiprocessing

    with multiprocessing.get_context("fork").Pool(2) as pool:
        assert pool.starmap(replace_many_times, [(tmp_path / "collected", 0), (tmp_path / "collected", 1)]) == [0, 0]
    assert sorted(os.listdir(tmp_path)) == ["collected"]
    assert sorted(os.listdir(tmp_path / "collected")) == [OUTPUT_MARKER, "runs.csv"]


def test_the_committed_reference_reports_can_be_rebuilt_in_place():
    """``report --reference`` rewrites reports/<name>, made before folders were marked: each holds only what a
    report of a run (or of a sweep, reports/bases) writes."""
    from workbench.reporting.pages import SWEEP_REPORT_FILES
    from workbench.settings.config import REPO_ROOT

    reports = sorted(path.parent for path in (REPO_ROOT / "reports").glob("*/index.html"))
    if not reports:
        pytest.skip("no committed reference reports")
    for report in reports:
        known = SWEEP_REPORT_FILES if (report / "runs.csv").exists() else REPORT_FILES
        assert check_output_folder(report, "--name", writer="a report", known=known) == report
