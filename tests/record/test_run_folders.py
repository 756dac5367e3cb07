"""A run folder belongs to the workbench, with real processes: a run writes only into a new or empty folder or a
record of its own; any other folder is refused in one line (exit 2) with nothing in it touched; the current
directory is never a run folder; a failed run removes only what it wrote; names that become paths stay plain."""

import hashlib
import importlib
import os
import shutil
import subprocess
import sys
import types
from pathlib import Path

import pytest

from workbench.core.errors import WorkbenchError
from workbench.core.interrupt import MESSAGE
from workbench.record.record import DONE
from workbench.record.tracking import LOCK_FILE, check_run_dir, clear_partial, discard_failed_run
from workbench.settings.config import REPO_ROOT

SMALL = ["dataset.n_frames=300", "solver=lstsq"]


def workbench_of_copy(*arguments, cwd, pythonpath):
    """The command in a child process that imports the workbench from ``pythonpath`` (a copy of the checkout)."""
    env = dict(os.environ, PYTHONPATH=str(pythonpath), OPENBLAS_NUM_THREADS="1", PYTHONDONTWRITEBYTECODE="1")
    return subprocess.run(
        [sys.executable, "-m", "workbench", *arguments], cwd=cwd, env=env, capture_output=True, text=True, timeout=300
    )


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` with its content hash and modification time, and every folder (Python's and
    numba's byte-code caches, ``__pycache__``, left out)."""
    found = {}
    for path in sorted(folder.rglob("*")):
        if "__pycache__" in path.parts:
            continue
        is_file = path.is_file()
        found[str(path.relative_to(folder))] = (
            (hashlib.sha256(path.read_bytes()).hexdigest(), path.lstat().st_mtime_ns) if is_file else "folder"
        )
    return found


def user_folder(folder: Path) -> Path:
    folder.mkdir(parents=True)
    (folder / "notes.txt").write_text("my notes\n")
    (folder / "thesis.tex").write_text("\\documentclass{article}\n")
    (folder / "config.yaml").write_text("mine: true\n")  # a name a record uses, but the user's file
    return folder


def one_error_line(result) -> str:
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr
    assert len(lines) == 1 and lines[0].startswith("workbench: error: "), result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    return lines[0]


def test_a_run_into_a_folder_of_the_users_is_refused_and_touches_nothing(tmp_path, cli):
    folder = user_folder(tmp_path / "DIR")
    before = snapshot(folder)
    result = cli(*SMALL, f"hydra.run.dir={folder}", cwd=tmp_path)
    line = one_error_line(result)
    assert f"{folder} is not empty and holds no run record (notes.txt, thesis.tex)" in line
    assert snapshot(folder) == before


@pytest.mark.slow
@pytest.mark.process
def test_the_current_directory_is_never_a_run_folder_even_in_a_copy_of_the_checkout(tmp_path):
    checkout = tmp_path / "checkout"
    tracked = subprocess.run(["git", "-C", str(REPO_ROOT), "ls-files", "-z"], capture_output=True, check=True)
    for name in tracked.stdout.decode().split("\0"):
        if name and not name.startswith("reports/") and (REPO_ROOT / name).is_file():
            (checkout / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(REPO_ROOT / name, checkout / name)
    before = snapshot(checkout)
    assert {"README.md", "pyproject.toml", ".gitignore", "workbench/cli/main.py"} <= set(before)
    for run_dir in ("hydra.run.dir=", "hydra.run.dir=.", f"hydra.run.dir={checkout}", "hydra.run.dir=.."):
        line = one_error_line(workbench_of_copy(*SMALL, run_dir, cwd=checkout, pythonpath=checkout))
        assert "a run writes into a folder of its own" in line, line
    # the output root itself, whatever it holds (here: the checkout's files)
    line = one_error_line(
        workbench_of_copy(
            *SMALL, "paths.output_root=.", "hydra.run.dir=${paths.output_root}", cwd=checkout, pythonpath=checkout
        )
    )
    assert "a run writes into a folder of its own" in line
    line = one_error_line(
        workbench_of_copy(*SMALL, "hydra.sweep.dir=", "dataset.seed=0,1", "-m", cwd=checkout, pythonpath=checkout)
    )
    assert line.startswith("workbench: error: hydra.sweep.dir is empty")
    assert snapshot(checkout) == before, "a file of the checkout was touched"


def test_the_output_root_as_run_folder_is_refused_and_kept(tmp_path, cli):
    root = tmp_path / "outputs"
    first = cli(*SMALL, f"hydra.run.dir={root / 'paper' / 'one'}", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    (root / "notes.txt").write_text("mine\n")
    before = snapshot(root)
    line = one_error_line(cli(*SMALL, f"paths.output_root={root}", "hydra.run.dir=${paths.output_root}", cwd=tmp_path))
    assert f"{root} is not empty and holds no run record (notes.txt, paper)" in line
    assert snapshot(root) == before


def test_a_sweep_never_deletes_a_users_file_in_a_run_folder(tmp_path, cli):
    sweep = tmp_path / "sweep"
    arguments = [*SMALL, "dataset.seed=0,1", f"hydra.sweep.dir={sweep}", "-m"]
    first = cli(*arguments, cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    complete, redo = sorted(path.parent for path in sweep.glob(f"*/{DONE}"))
    assert not list(sweep.glob(f"*/{LOCK_FILE}")), "a complete record keeps no lock file"
    # a note beside a complete record: the resumed sweep skips the record and leaves the note
    (complete / "notes.txt").write_text("beside my record\n")
    # a record made partial (as a kill leaves it) that also holds the user's file: refused, nothing deleted
    (redo / DONE).unlink()
    (redo / LOCK_FILE).touch()  # a killed run's folder keeps its lock file (a complete record has none)
    (redo / "notes.txt").write_text("inside a killed run's folder\n")
    before = {folder: snapshot(folder) for folder in (complete, redo)}
    line = one_error_line(cli(*arguments, cwd=tmp_path))
    assert f"{redo} holds a killed run's files and others no run writes (notes.txt)" in line
    assert {folder: snapshot(folder) for folder in (complete, redo)} == before
    # with the note moved away, the sweep resumes and redoes that run
    (redo / "notes.txt").unlink()
    again = cli(*arguments, cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert (redo / DONE).is_file() and (complete / "notes.txt").read_text() == "beside my record\n"


def test_a_failed_run_removes_only_what_it_wrote(tmp_path, cli):
    # m above the capture's rank fails inside the run, after the run folder was claimed
    failing = [*SMALL, "basis.n_components=500"]
    empty = tmp_path / "empty"
    empty.mkdir()
    assert cli(*failing, f"hydra.run.dir={empty}", cwd=tmp_path).returncode == 2
    assert empty.is_dir() and list(empty.iterdir()) == [], "the user's empty folder stays, empty"
    new = tmp_path / "new"
    assert cli(*failing, f"hydra.run.dir={new}", cwd=tmp_path).returncode == 2
    assert not new.exists(), "a folder the run made is removed"
    # the default folder, outputs/paper/<date and time>: the parents the run made go too, a parent it found stays
    assert cli(*failing, cwd=tmp_path).returncode == 2
    assert not (tmp_path / "outputs").exists(), "a failed run leaves no empty outputs/paper/"
    (tmp_path / "outputs").mkdir()
    assert cli(*failing, cwd=tmp_path).returncode == 2
    assert list((tmp_path / "outputs").iterdir()) == []


def test_a_run_failing_before_it_claims_its_folder_leaves_no_empty_folder(tmp_path, monkeypatch, cli):
    api = importlib.import_module("workbench.api")

    def broken(*args, **kwargs):
        raise RuntimeError("broken before the run")

    monkeypatch.setattr(api, "run_owned", broken)
    result = cli(*SMALL, cwd=tmp_path)
    assert result.returncode == 3 and "broken before the run" in result.stderr, result.stderr
    assert not (tmp_path / "outputs").exists(), "Hydra made outputs/paper/<date and time>; the failed run removes it"


def test_ctrl_c_while_the_study_loads_leaves_no_empty_folder(tmp_path, monkeypatch, cli):
    """Ctrl-C after Hydra made the run folder, while the run imports the study's modules (about a second at start):
    exit 130 in one line, and the folder and the parents made for it are gone."""

    def interrupted(name):
        raise KeyboardInterrupt

    loading = types.ModuleType("workbench.api")
    loading.__getattr__ = interrupted  # the import of run_owned is where the Ctrl-C lands
    monkeypatch.setitem(sys.modules, "workbench.api", loading)
    result = cli(*SMALL, cwd=tmp_path)
    assert result.returncode == 130 and result.stderr.strip() == MESSAGE, result.stderr
    assert not (tmp_path / "outputs").exists(), "the run removes the outputs/paper/<date-time> Hydra made"


def test_clean_up_removes_record_files_only(tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    for name in (
        LOCK_FILE,
        "config.yaml",
        ".metrics.json.ab12cd.tmp",
        "inputs_markers.npz",
        "workbench.log",
        "notes.txt",
        "figure.png",
    ):
        (folder / name).write_text("x")
    assert clear_partial(folder) == [".metrics.json.ab12cd.tmp", "config.yaml", "inputs_markers.npz"]
    assert sorted(path.name for path in folder.iterdir()) == [LOCK_FILE, "figure.png", "notes.txt", "workbench.log"]
    assert discard_failed_run(folder, frozenset({LOCK_FILE, "notes.txt", "figure.png"}), created=True) is False
    assert sorted(path.name for path in folder.iterdir()) == [LOCK_FILE, "figure.png", "notes.txt"]


@pytest.mark.parametrize(
    "names, accepted",
    [
        ((), True),
        ((LOCK_FILE, "config.yaml", "workbench.log"), True),
        ((DONE, "notes.txt"), True),
        (("config.yaml",), False),
        ((LOCK_FILE, "notes.txt"), False),
        (("notes.txt",), False),
    ],
)
def test_which_folders_a_run_may_write_into(tmp_path, names, accepted):
    folder = tmp_path / "run"
    folder.mkdir()
    for name in names:
        (folder / name).write_text("x")
    if accepted:
        assert check_run_dir(folder) == frozenset(names)
    else:
        with pytest.raises(WorkbenchError, match="touches nothing else"):
            check_run_dir(folder)
    assert sorted(path.name for path in folder.iterdir()) == sorted(names)


@pytest.mark.parametrize("override", ["study=../../../../elsewhere", "study=a/b", "study=", "study=.hidden"])
def test_study_names_that_would_leave_the_output_root_are_refused_before_anything_is_made(tmp_path, override, cli):
    work = tmp_path / "a" / "b" / "c" / "d"
    work.mkdir(parents=True)
    line = one_error_line(cli(*SMALL, override, "paths.output_root=out", cwd=work))
    assert line.startswith("workbench: error: study must be a plain name")
    assert [path for path in tmp_path.rglob("*") if path.is_file() or not any(path.iterdir())] == [work]
    sweep = one_error_line(cli(*SMALL, override, "paths.output_root=out", "dataset.seed=0,1", "-m", cwd=work))
    assert sweep == line
    assert [path for path in tmp_path.rglob("*") if path.is_file() or not any(path.iterdir())] == [work]
