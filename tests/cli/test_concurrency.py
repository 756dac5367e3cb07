"""Concurrent runs and interruptions, with real processes: a run folder belongs to one live process."""

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from workbench.record.record import DONE, load_record
from workbench.record.tracking import LOCK_FILE, lock_run_dir, unlock_run_dir
from workbench.settings.config import REPO_ROOT

pytestmark = pytest.mark.process  # every test here starts the command as a child process

SMALL = ["dataset.n_frames=300", "dataset.mesh_rows=20", "dataset.mesh_cols=20", "solver=lstsq"]


def command(*arguments: str) -> list[str]:
    return [sys.executable, "-m", "workbench", *arguments]


def cli_env() -> dict:
    return dict(os.environ, PYTHONPATH=str(REPO_ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")


def default_sigint():
    """The child's Ctrl-C as a user's, even when this test runner was started with SIGINT ignored (nohup)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(arguments, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen(
        command(*arguments),
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=cli_env(),
        preexec_fn=default_sigint,
    )


@pytest.mark.slow
def test_identical_sweeps_into_one_folder_do_every_run_exactly_once(tmp_path):
    sweep = tmp_path / "sweep"
    arguments = [
        "--config-name",
        "coverage_small",
        *SMALL,
        "dataset.seed=0,1",
        "basis.coverage=0.9,0.95,0.99",
        f"hydra.sweep.dir={sweep}",
    ]
    processes = [start(arguments, tmp_path) for _ in range(2)]
    outputs = [process.communicate(timeout=300) for process in processes]
    for process, (out, err) in zip(processes, outputs):
        assert process.returncode == 0, err
    done = [re.findall(r"^done\s+(\S+):", out, flags=re.MULTILINE) for out, _ in outputs]  # a long name wraps
    runs = sorted(path.parent for path in sweep.glob(f"*/{DONE}"))
    assert len(runs) == 6
    named = sorted(str(tmp_path / folder) for folders in done for folder in folders)  # relative to the cwd
    assert named == sorted(map(str, runs)), outputs
    for run in runs:
        load_record(run)


def test_a_plain_run_into_a_locked_folder_stops_with_one_line_and_touches_nothing(tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "alpha_table.csv").write_text("a live run's file")
    lock = lock_run_dir(folder)  # this test process is the live run
    try:
        result = subprocess.run(
            command(*SMALL, f"hydra.run.dir={folder}"),
            cwd=tmp_path,
            capture_output=True,
            text=True,
            env=cli_env(),
            timeout=300,
        )
    finally:
        unlock_run_dir(lock)
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().splitlines() == [
        f"workbench: error: {folder} is in use by another workbench process (its lock file {LOCK_FILE} is held); "
        "wait for it to end or write this run elsewhere"
    ]
    assert (folder / "alpha_table.csv").read_text() == "a live run's file"


@pytest.mark.slow
def test_two_identical_plain_runs_leave_one_complete_record(tmp_path):
    folder = tmp_path / "run"
    processes = [start([*SMALL, f"hydra.run.dir={folder}"], tmp_path)]
    time.sleep(1.0)
    processes.append(start([*SMALL, f"hydra.run.dir={folder}"], tmp_path))
    results = [(process.wait(timeout=300), *process.communicate()) for process in processes]
    codes = sorted(code for code, _, _ in results)
    assert codes in ([0, 0], [0, 2]), results
    if codes == [0, 2]:
        assert any("in use by another workbench process" in err for _, _, err in results)
    load_record(folder)


def test_ctrl_c_ends_with_one_line_exit_130_and_no_stub_folder(tmp_path):
    folder = tmp_path / "run"
    process = start(["dataset.n_frames=20000", "solver=lstsq", f"hydra.run.dir={folder}"], tmp_path)
    deadline = time.monotonic() + 120
    while not (folder / LOCK_FILE).exists():
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.01)
    time.sleep(0.5)
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == "workbench: interrupted; rerun the same command to resume"
    assert len([line for line in err.splitlines() if line.strip()]) == 1, err
    assert not folder.exists()


def test_a_failed_plain_run_leaves_no_stub_folder(tmp_path):
    folder = tmp_path / "run"
    result = subprocess.run(
        command("dataset.n_frames=-5", f"hydra.run.dir={folder}"),
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=cli_env(),
        timeout=300,
    )
    assert result.returncode == 2, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not folder.exists()
