"""Where ``report``, ``export`` and ``collect`` write: a folder of their own (new, empty, or one the workbench
wrote before), never the current folder by an empty name and never a folder holding someone's files; written
whole into a temporary folder beside it and moved into place."""

import hashlib
import os
from pathlib import Path

import pytest
from in_process import run_workbench

from workbench.core.errors import WorkbenchError
from workbench.core.files import (
    OUTPUT_MARKER,
    TEMPORARY_SUFFIX,
    check_output_folder,
    output_folder,
    temporary_prefix,
    write_atomic,
)
from workbench.reporting.report.command import REPORT_FILES

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
    again = run_workbench(command, record, "--out", out, cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert sorted(os.listdir(out)) == names
    assert sorted(os.listdir(tmp_path)) == ["out"]  # the earlier output removed, no temporary folder left


@pytest.mark.parametrize("command", ["export", "collect"])
def test_a_file_the_user_edited_in_the_workbenchs_folder_is_replaced_only_with_force(record, tmp_path, command):
    out = tmp_path / "out"
    assert run_workbench(command, record, "--out", out, cwd=tmp_path).returncode == 0
    edited = out / ("manifest.json" if command == "export" else "findings.md")
    edited.write_text("my notes\n")
    before = digests(out)
    line = one_line_refusal(run_workbench(command, record, "--out", out, cwd=tmp_path))
    assert f"{edited.name} changed since" in line and "--force" in line, line
    assert digests(out) == before
    forced = run_workbench(command, record, "--out", out, "--force", cwd=tmp_path)
    assert forced.returncode == 0, forced.stderr
    assert edited.read_text() != "my notes\n"
    assert sorted(os.listdir(tmp_path)) == ["out"]


@pytest.mark.slow
def test_a_report_rerun_into_its_own_folder_and_its_default_folder(record, tmp_path):
    out = tmp_path / "report"
    for _ in range(2):
        result = run_workbench("report", record, "--out", out, cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert result.stdout.strip() == f"report: {out / 'index.html'}"
    assert set(os.listdir(out)) == {OUTPUT_MARKER, *REPORT_FILES}
    assert sorted(os.listdir(tmp_path)) == ["report"]
    (out / "figures" / "my_plot.png").write_bytes(b"a plot of mine")
    line = one_line_refusal(run_workbench("report", record, "--out", out, cwd=tmp_path))
    assert "(figures/my_plot.png)" in line, line
    assert (out / "figures" / "my_plot.png").read_bytes() == b"a plot of mine"


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
    from workbench.reporting.report.command import SWEEP_REPORT_FILES
    from workbench.settings.config import REPO_ROOT

    reports = sorted(path.parent for path in (REPO_ROOT / "reports").glob("*/index.html"))
    if not reports:
        pytest.skip("no committed reference reports")
    for report in reports:
        known = SWEEP_REPORT_FILES if (report / "runs.csv").exists() else REPORT_FILES
        assert check_output_folder(report, "--name", writer="a report", known=known) == report


def written(out: Path, writer: str, files: dict, **options) -> None:
    """An output folder as ``writer`` writes it: ``files`` (path -> text, at any depth)."""
    with output_folder(out, "--out", writer=writer, **options) as staging:
        for name, text in files.items():
            write_atomic(staging / name, text)


def test_a_file_the_user_added_in_a_subfolder_of_the_output_survives_a_rerun(tmp_path):
    """A report rerun into an earlier report folder deleted a plot the user had saved in its figures/: only
    top-level names were compared."""
    out = tmp_path / "report"
    written(out, "a report", {"index.html": "1", "figures/fig1.png": "1"})
    (out / "figures" / "my_plot.png").write_text("mine")
    with pytest.raises(WorkbenchError, match=r"did not write there \(figures/my_plot\.png\)"):
        written(out, "a report", {"index.html": "2", "figures/fig1.png": "2"})
    assert (out / "figures" / "my_plot.png").read_text() == "mine"
    assert (out / "index.html").read_text() == "1"
    assert sorted(os.listdir(tmp_path)) == ["report"]


@pytest.mark.parametrize(
    ("first", "second"),
    [("a report", "export"), ("an export", "report"), ("an export", "collect"), ("collect", "export")],
)
def test_another_commands_output_is_refused_naming_what_is_there(record, tmp_path, first, second):
    out = tmp_path / "out"
    written(out, first, {"index.html": "1", "runs.csv": "1"})
    before = digests(out)
    line = one_line_refusal(run_workbench(second, record, "--out", out, cwd=tmp_path))
    assert f"{out} holds the output of {first}" in line and "name another folder (--out=...)" in line, line
    assert digests(out) == before


def test_two_commands_writing_one_new_folder_at_once_do_not_both_succeed(tmp_path):
    """An export and a collect into one new folder both said they succeeded, and one output vanished: the one to
    finish second is refused, and the first's output stays whole."""
    out = tmp_path / "out"
    with pytest.raises(WorkbenchError, match="holds the output of an export"):
        with output_folder(out, "--out", writer="collect") as staging:
            write_atomic(staging / "runs.csv", "collected\n")
            written(out, "an export", {"manifest.json": "{}\n"})  # started later, finished first
    assert sorted(os.listdir(out)) == [OUTPUT_MARKER, "manifest.json"]
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_a_copy_a_killed_command_left_is_removed_by_the_next_command_on_that_folder(tmp_path):
    """``kill -9`` (or SIGKILL after a SIGTERM that was not heeded) leaves the temporary copy; a copy a running
    command holds is left alone, and an earlier output moved aside when the kill came is moved back."""
    import fcntl

    out = tmp_path / "out"
    written(out, "collect", {"runs.csv": "1\n"})
    killed = tmp_path / ".out.k1ll3d_x.tmp"
    (killed / "figures").mkdir(parents=True)
    (killed / "figures" / "big.png").write_text("half a report")
    running = tmp_path / ".out.running1.tmp"
    running.mkdir()
    handle = os.open(running, os.O_RDONLY)
    fcntl.flock(handle, fcntl.LOCK_EX)
    try:
        written(out, "collect", {"runs.csv": "2\n"})
        assert sorted(os.listdir(tmp_path)) == [".out.running1.tmp", "out"]
    finally:
        os.close(handle)
    # killed between moving the earlier output aside and moving the new one in
    os.replace(out, tmp_path / ".out.aside123.old.tmp")
    written(tmp_path / "other", "collect", {"runs.csv": "x\n"})  # another folder's command leaves it be
    assert (tmp_path / ".out.aside123.old.tmp").is_dir()
    with pytest.raises(WorkbenchError, match="holds the output of collect"):  # the restored output is checked
        written(out, "an export", {"manifest.json": "{}\n"})
    assert (out / "runs.csv").read_text() == "2\n"
    assert sorted(os.listdir(tmp_path)) == ["other", "out"]


def test_temporary_names_fit_wherever_the_final_name_fits(tmp_path):
    """A 255-byte folder name (legal) failed: its temporary name was longer than a name may be."""
    long_name = "r" * 250 + "é" * 2 + "x"  # 255 bytes in UTF-8
    assert len(long_name.encode()) == 255
    written(tmp_path / long_name, "collect", {"runs.csv": "1\n", long_name: "2\n"})
    written(tmp_path / long_name, "collect", {"runs.csv": "3\n", long_name: "4\n"})
    assert (tmp_path / long_name / long_name).read_text() == "4\n"
    assert sorted(os.listdir(tmp_path)) == [long_name]
    other = "r" * 250 + "é" * 2 + "y"  # the same name cut short: a copy of its own
    assert temporary_prefix(other) != temporary_prefix(long_name)
    assert temporary_prefix("report") == ".report."


@pytest.mark.parametrize("name", ["new\nline", "tab\there", "bell\x07"])
def test_a_control_character_in_the_out_name_is_refused(tmp_path, name):
    with pytest.raises(WorkbenchError, match="control character"):
        check_output_folder(tmp_path / name, "--out", writer="collect")
    assert os.listdir(tmp_path) == []


@pytest.fixture
def mount_point(tmp_path):
    """An empty file system mounted on a folder (root may mount one; elsewhere the test is skipped)."""
    import subprocess

    point = tmp_path / "mounted"
    point.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(point)], capture_output=True).returncode:
        pytest.skip("cannot mount a file system here")
    yield point
    subprocess.run(["umount", str(point)], check=True)


@pytest.mark.process
def test_an_empty_mount_point_as_out_is_refused_naming_it(record, tmp_path, mount_point):
    """It was refused naming the workbench's temporary folder, after the work was done."""
    line = one_line_refusal(run_workbench("collect", record, "--out", mount_point, cwd=tmp_path))
    assert f"{mount_point} is a mount point" in line and f"--out={mount_point / 'out'}" in line, line
    assert TEMPORARY_SUFFIX not in line
    assert sorted(os.listdir(tmp_path)) == ["mounted"] and os.listdir(mount_point) == []


def test_an_earlier_output_made_read_only_is_replaced_and_nothing_is_left(tmp_path):
    out = tmp_path / "out"
    written(out, "a report", {"index.html": "1", "figures/fig1.png": "1"})
    for path in (out / "figures" / "fig1.png", out / "figures"):
        path.chmod(0o500 if path.is_dir() else 0o400)
    written(out, "a report", {"index.html": "2", "figures/fig1.png": "2"})
    assert (out / "figures" / "fig1.png").read_text() == "2"
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_the_marker_lists_every_file_at_any_depth_with_its_digest(tmp_path):
    import json

    out = tmp_path / "out"
    written(out, "a report", {"index.html": "page", "figures/faces/fig2.webp": "face"})
    marker = json.loads((out / OUTPUT_MARKER).read_text())
    assert marker["written_by"] == "a report"
    assert marker["files"] == {
        "index.html": hashlib.sha256(b"page").hexdigest(),
        "figures/faces/fig2.webp": hashlib.sha256(b"face").hexdigest(),
    }


def test_a_move_into_place_that_fails_leaves_the_earlier_output_and_no_temporary_folder(tmp_path, monkeypatch):
    out = tmp_path / "out"
    written(out, "collect", {"runs.csv": "1\n"})
    before = digests(out)
    real_replace = os.replace

    def refused_for_the_output(source, target):
        if Path(target) == out and Path(source).name.endswith(TEMPORARY_SUFFIX) and ".old." not in Path(source).name:
            raise OSError(28, "No space left on device")
        return real_replace(source, target)

    monkeypatch.setattr(os, "replace", refused_for_the_output)
    with pytest.raises(OSError, match="No space left on device"):
        written(out, "collect", {"runs.csv": "2\n"})
    monkeypatch.undo()
    assert digests(out) == before
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_an_earlier_output_that_cannot_be_moved_back_is_kept_and_moved_back_by_the_next_command(tmp_path, monkeypatch):
    out = tmp_path / "out"
    written(out, "collect", {"runs.csv": "1\n"})
    before = digests(out)
    real_replace = os.replace

    def refused_for_the_output(source, target):
        if Path(target) == out and Path(source).name.endswith(TEMPORARY_SUFFIX):
            raise OSError(5, "Input/output error")
        return real_replace(source, target)

    monkeypatch.setattr(os, "replace", refused_for_the_output)
    with pytest.raises(OSError, match="Input/output error"):
        written(out, "collect", {"runs.csv": "2\n"})
    monkeypatch.undo()
    [kept] = [name for name in os.listdir(tmp_path) if name != "out"]
    assert kept.startswith(".out.") and kept.endswith(".old.tmp")
    assert check_output_folder(out, "--out", writer="collect") == out  # the next command on the folder
    assert digests(out) == before and sorted(os.listdir(tmp_path)) == ["out"]
