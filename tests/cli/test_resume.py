"""Resumable sweeps: a sweep killed part-way (SIGKILL) resumes, redoes nothing finished and loses nothing."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml

from workbench.api import run
from workbench.core.errors import WorkbenchError
from workbench.record.record import DONE, config_hash
from workbench.record.tracking import LOCK_FILE, clear_partial, prepare_run_dir, record_state
from workbench.settings.config import REPO_ROOT, compose, resolved_yaml_text, run_dir_name

SWEEP = ["--config-name", "coverage", "dataset.n_frames=500", "dataset.seed=0,1", "basis.coverage=0.9,0.95,0.99"]
N_RUNS = 6


def sweep_command(sweep_dir: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "workbench", *SWEEP, f"hydra.sweep.dir={sweep_dir}", *extra]


def cli_env() -> dict:
    # one BLAS thread in every process, so that sums are added in the same order in parallel and sequential runs
    return dict(os.environ, PYTHONPATH=str(REPO_ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")


def run_sweep(sweep_dir: Path, cwd: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        sweep_command(sweep_dir, *extra), capture_output=True, text=True, cwd=cwd, timeout=600, env=cli_env()
    )


def snapshot(folder: Path) -> dict:
    """Every file of a run folder: inode, modification time (ns) and content."""
    return {
        path.name: (path.stat().st_ino, path.stat().st_mtime_ns, path.read_bytes()) for path in sorted(folder.iterdir())
    }


def record_snapshot(folder: Path) -> dict:
    """:func:`snapshot` of a run folder without its lock file (not part of the record)."""
    return {name: state for name, state in snapshot(folder).items() if name != LOCK_FILE}


def comparable(table: pd.DataFrame) -> pd.DataFrame:
    """A collected table without what differs between two sweeps of the same runs (folders, timings)."""
    if "metric" in table.columns:
        table = table[~table["metric"].str.startswith("time_")].reset_index(drop=True)
    return table.drop(columns=[column for column in table.columns if column == "sweep" or column.startswith("time_")])


@pytest.mark.process
@pytest.mark.slow
def test_killed_sweep_resumes_without_redoing_or_losing_runs(tmp_path):
    sweep = tmp_path / "killed"
    process = subprocess.Popen(
        sweep_command(sweep),
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=cli_env(),
        start_new_session=True,
    )
    deadline = time.monotonic() + 300
    while not list(sweep.glob("*/done")):
        assert process.poll() is None, "the sweep ended before any run finished"
        assert time.monotonic() < deadline, "no run finished in time"
        time.sleep(0.005)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()

    # a run's record, without its lock file: a kill between writing 'done' and removing the lock leaves the lock,
    # which the resume removes from a complete record (tracking.release_run_dir), the record itself untouched
    finished = {path.parent.name: record_snapshot(path.parent) for path in sweep.glob("*/done")}
    assert 1 <= len(finished) < N_RUNS, "the kill came too late to test a resume"
    # a run killed while writing its record: a folder without 'done' holding a stale file
    unfinished = run_dir_name("basis.coverage=0.99,dataset.n_frames=500,dataset.seed=1")
    assert unfinished not in finished
    (sweep / unfinished).mkdir(exist_ok=True)
    (sweep / unfinished / LOCK_FILE).touch()  # the first file a run writes into its folder
    (sweep / unfinished / "alpha_table.csv").write_text("stale")

    resumed = run_sweep(sweep, tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    skipped = [line for line in resumed.stdout.splitlines() if line.startswith("skip ")]
    assert len(skipped) == len(finished)
    for name, files in finished.items():
        assert record_snapshot(sweep / name) == files, f"finished run {name} was touched"
        assert not (sweep / name / LOCK_FILE).exists(), f"finished run {name} kept a lock file"
    assert sum(1 for _ in sweep.glob("*/done")) == N_RUNS
    assert (sweep / unfinished / "alpha_table.csv").read_text() != "stale"

    uninterrupted = tmp_path / "uninterrupted"
    complete = run_sweep(uninterrupted, tmp_path)
    assert complete.returncode == 0, complete.stderr
    for name in ("runs", "summary"):
        pd.testing.assert_frame_equal(
            comparable(pd.read_parquet(sweep / "collected" / f"{name}.parquet")),
            comparable(pd.read_parquet(uninterrupted / "collected" / f"{name}.parquet")),
        )
    assert (sweep / "collected" / "alpha_table.md").read_text() == (
        uninterrupted / "collected" / "alpha_table.md"
    ).read_text()
    assert sorted(path.name for path in sweep.iterdir()) == sorted(path.name for path in uninterrupted.iterdir())


@pytest.mark.process
@pytest.mark.slow
def test_parallel_sweep_with_joblib_launcher(tmp_path):
    """The sweep through Hydra's joblib launcher (two worker processes) names and records its runs the same way."""
    sweep = tmp_path / "parallel"
    result = run_sweep(
        sweep, tmp_path, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", "dataset.seed=0", "basis.coverage=0.9,0.99"
    )
    assert result.returncode == 0, result.stderr
    assert sorted(path.parent.name for path in sweep.glob("*/done")) == [
        "basis.coverage=0.9,dataset.n_frames=500,dataset.seed=0",
        "basis.coverage=0.99,dataset.n_frames=500,dataset.seed=0",
    ]
    assert "collected 2 runs" in result.stdout
    # determinism: the same runs in one sequential process give byte-identical tables (same BLAS thread count)
    sequential = tmp_path / "sequential"
    result = run_sweep(sequential, tmp_path, "dataset.seed=0", "basis.coverage=0.9,0.99")
    assert result.returncode == 0, result.stderr
    for done in sorted(sweep.glob("*/done")):
        table = done.parent.name + "/alpha_table.csv"
        assert (sweep / table).read_bytes() == (sequential / table).read_bytes(), table


def test_run_ids_are_stable_readable_and_distinct():
    assert run_dir_name("basis.coverage=0.99,dataset.seed=1") == "basis.coverage=0.99,dataset.seed=1"
    assert run_dir_name("") == "default"
    unsafe = run_dir_name("dataset.train_on=[markers,mesh]")
    assert unsafe.startswith("dataset.train_on=_markers,mesh_-") and "/" not in unsafe
    assert unsafe != run_dir_name("dataset.train_on=(markers,mesh)")
    long = run_dir_name("x=" + "1" * 300)
    assert len(long) <= 120 and long == run_dir_name("x=" + "1" * 300) != run_dir_name("x=" + "1" * 299)


def test_complete_record_is_skipped_refused_or_never_cleared(tmp_path):
    folder = tmp_path / "run"
    assert record_state(folder) == "absent" and prepare_run_dir(folder, "abc")
    folder.mkdir()
    (folder / "config.yaml").write_text("partial")
    (folder / ".metrics.json.x.tmp").write_text("")
    assert record_state(folder) == "partial"
    assert prepare_run_dir(folder, "abc") and list(folder.iterdir()) == []
    settings = "dataset:\n  kind: synthetic\n"
    (folder / "config.yaml").write_text(settings)
    (folder / "metrics.json").write_text(json.dumps({"config_hash": config_hash(settings)}))
    (folder / DONE).write_text("")
    assert record_state(folder) == "complete"
    assert prepare_run_dir(folder, config_hash(settings)) is False
    with pytest.raises(WorkbenchError, match="another config .*never overwritten"):
        prepare_run_dir(folder, "def")
    with pytest.raises(WorkbenchError, match="never cleared"):
        clear_partial(folder)
    assert sorted(path.name for path in folder.iterdir()) == ["config.yaml", DONE, "metrics.json"]


def test_a_record_listing_its_settings_in_another_order_is_a_record_of_the_same_config(tmp_path):
    """A record written before the dataset kinds shared their frames settings lists ``split`` ... ``dtype`` after
    the kind's own settings, and its metrics.json holds a hash of that text: a run of the same settings skips it,
    and a run of other settings is refused."""
    import hashlib

    new_text = resolved_yaml_text(compose("paper", ["dataset.n_frames=300"]))
    settings = yaml.safe_load(new_text)
    frames = ("split", "eval_fraction", "held_out", "folds", "fold_gap_s", "storage", "dtype")
    own = {key: value for key, value in settings["dataset"].items() if key not in frames}
    old_order = {**settings, "dataset": {**own, **{key: settings["dataset"][key] for key in frames}}}
    old_text = yaml.safe_dump(old_order, sort_keys=False)
    assert old_text != new_text and list(yaml.safe_load(old_text)["dataset"])[-1] == "dtype"
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "config.yaml").write_text(old_text)
    text_hash = hashlib.sha256(old_text.encode()).hexdigest()[:16]  # what the record's metrics.json held
    (folder / "metrics.json").write_text(json.dumps({"config_hash": text_hash}))
    (folder / DONE).write_text("")
    assert prepare_run_dir(folder, config_hash(new_text)) is False
    other = resolved_yaml_text(compose("paper", ["dataset.n_frames=400"]))
    with pytest.raises(WorkbenchError, match="another config .*never overwritten"):
        prepare_run_dir(folder, config_hash(other))


def test_run_refuses_to_overwrite_a_complete_record(tmp_path):
    cfg = compose("paper", ["dataset.n_frames=300", "solver=lstsq"])
    run(cfg, tmp_path, overrides=["dataset.n_frames=300"], job_num=3)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["overrides"] == ["dataset.n_frames=300"] and metrics["job_num"] == 3
    assert metrics["config_hash"] == config_hash((tmp_path / "config.yaml").read_text())
    assert metrics["started_at"] <= metrics["finished_at"]
    before = snapshot(tmp_path)
    with pytest.raises(WorkbenchError, match="never overwritten"):
        run(cfg, tmp_path)
    assert snapshot(tmp_path) == before


def test_a_sweep_composes_each_run_once_and_the_runs_get_the_config_they_would_have_alone(tmp_path, monkeypatch):
    # The sweep's check, Hydra's basic sweeper and its basic launcher each ask for every run's config: one
    # composition per run serves all three (record.tracking.compose_each_run_once), each a copy of its own.
    from hydra._internal.config_loader_impl import ConfigLoaderImpl

    from tests.in_process import run_workbench
    from workbench.settings.config import compose

    composed = []
    load_sweep_config = ConfigLoaderImpl.load_sweep_config

    def counted(self, master_config, sweep_overrides):
        composed.append(tuple(sweep_overrides))
        return load_sweep_config(self, master_config, sweep_overrides)

    monkeypatch.setattr(ConfigLoaderImpl, "load_sweep_config", counted)
    sweep = ["dataset.n_frames=400", "solver=lstsq", "dataset.seed=0,1,2", "paths.output_root=out", "-m"]
    done = run_workbench(*sweep, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert len(composed) == 3 and len(set(composed)) == 3
    folder = tmp_path / "out" / "paper-multirun" / "default"
    for seed in (0, 1, 2):
        run_folder = folder / f"dataset.n_frames=400,dataset.seed={seed},solver=lstsq"
        alone = tmp_path / f"alone{seed}"
        run(compose("paper", ["dataset.n_frames=400", "solver=lstsq", f"dataset.seed={seed}"]), alone)
        assert (run_folder / "alpha_table.csv").read_text() == (alone / "alpha_table.csv").read_text()
        assert f"  seed: {seed}\n" in (run_folder / "config.yaml").read_text()
