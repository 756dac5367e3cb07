"""A study's sweep on a real single-node SLURM cluster (``.ci/slurm-cluster start``), logging to a real MLflow
server as its jobs end: every record complete and the collected table equal to the same sweep run locally; a
sweep cut by ``scancel`` of a running task and a restart of ``slurmd``, resubmitted with the same command, runs
only what is missing; the runs are found on the server through its REST API with the records' numbers.

Skipped without the test cluster (``SLURM_CONF`` from the helper); CI starts it and sets
``WORKBENCH_REQUIRE_CLUSTER=1``. The evidence (times, interruption, REST query and answer) is printed to the
terminal even when the tests pass, so that CI's log shows it.
"""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from mlflow_rest import rest

from workbench.record.record import find_records, load_record
from workbench.settings.config import REPO_ROOT
from workbench.study.table import ALPHA_COLUMNS

pytestmark = pytest.mark.slow  # a SLURM cluster and an MLflow server, both real (CI starts them)

# A small sweep whatever the preset's size: 2 seeds x 2 coverages of 500 frames, named on the command line.
STUDY = [
    "--config-name",
    "coverage_small",
    "dataset.n_frames=500",
    "dataset.seed=0,1",
    "basis.coverage=0.95,0.995",
    "paths.output_root=out",
]
ON_SLURM = [
    "hydra/launcher=slurm",
    "hydra.launcher.partition=debug",
    "hydra.launcher.cpus_per_task=1",
    "hydra.launcher.mem_gb=2",
    "hydra.callbacks.mlflow.enabled=true",
]
ENV = dict(os.environ, PYTHONPATH=str(REPO_ROOT))


def command(sweep_dir, *extra):
    return [sys.executable, "-m", "workbench", *STUDY, f"hydra.sweep.dir={sweep_dir}", *extra]


def shown(text: str) -> str:
    return "\n".join(f"    {line}" for line in text.strip().splitlines())


def comparable(sweep: Path) -> pd.DataFrame:
    """A sweep's collected runs table without what differs between two sweeps of the same runs (their folder,
    timings)."""
    runs = pd.read_csv(sweep / "collected" / "runs.csv")
    return runs.drop(columns=["sweep", *[column for column in runs.columns if column.startswith("time_")]])


def sweep_runs(server, sweep: Path) -> tuple[dict, list]:
    """The REST query for a sweep's runs and the runs it returns."""
    experiment = rest(server, "GET", "experiments/get-by-name?experiment_name=coverage_small")["experiment"]
    query = {
        "experiment_ids": [experiment["experiment_id"]],
        "filter": f"tags.sweep = '{sweep.resolve()}'",
        "max_results": 100,
    }
    return query, rest(server, "POST", "runs/search", query).get("runs", [])


def tags_of(run) -> dict:
    return {tag["key"]: tag["value"] for tag in run["data"].get("tags", [])}


def check_runs_against_records(runs: list) -> list[str]:
    """Every nested run's metrics equal its record's alpha table; one line per run for the log."""
    [parent] = [run for run in runs if tags_of(run)["kind"] == "sweep"]
    lines = [f"{tags_of(parent)['mlflow.runName']}: sweep run, {parent['info']['status']}"]
    for run in sorted(
        (run for run in runs if tags_of(run)["kind"] == "run"), key=lambda run: tags_of(run)["mlflow.runName"]
    ):
        tags = tags_of(run)
        assert tags["mlflow.parentRunId"] == parent["info"]["run_id"] and run["info"]["status"] == "FINISHED"
        record = load_record(Path(tags["record"]))
        metrics = {metric["key"]: metric["value"] for metric in run["data"]["metrics"]}
        checked = 0
        for row in record.table.to_dict("records"):
            for column in ALPHA_COLUMNS:
                assert metrics[f"{column}.{row['data']}.{row['basis']}.{row['solver']}"] == pytest.approx(
                    row[column], rel=1e-15
                ), (tags["record"], column, row["basis"])
                checked += 1
        qe = record.table[record.table["basis"] == "QE"].iloc[0]
        lines.append(
            f"  {tags['mlflow.runName']}: {run['info']['status']}, {checked} alpha metrics equal to "
            f"alpha_table.csv (alpha_abs_mean.markers.QE.lstsq = "
            f"{metrics['alpha_abs_mean.markers.QE.lstsq']!r}, record {float(qe['alpha_abs_mean'])!r})"
        )
    return lines


def running_tasks() -> list[str]:
    out = subprocess.run(
        ["squeue", "--noheader", "--array", "--states=RUNNING", "--format=%i"],
        capture_output=True,
        text=True,
        timeout=30,
    ).stdout
    return out.split()


def wait_for(condition, timeout=180, every=0.1):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = condition()
        if found:
            return found
        time.sleep(every)
    raise AssertionError(f"timed out after {timeout} s")


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory, mlflow_server):
    """The same sweep run locally (Hydra's default launcher, logging to the server too), timed."""
    root = tmp_path_factory.mktemp("local")
    start = time.monotonic()
    result = subprocess.run(
        command("out/local", "hydra.callbacks.mlflow.enabled=true"),
        cwd=root,
        env=dict(ENV, MLFLOW_TRACKING_URI=mlflow_server),
        capture_output=True,
        text=True,
        timeout=900,
    )
    seconds = time.monotonic() - start
    assert result.returncode == 0, result.stderr[-3000:]
    return root / "out" / "local", seconds


@pytest.mark.process
def test_a_sweep_on_slurm_equals_the_local_sweep_and_its_runs_are_on_the_server(
    slurm_cluster, mlflow_server, local_sweep, tmp_path, capsys
):
    local, local_seconds = local_sweep
    sweep = tmp_path / "out" / "slurm"
    env = dict(ENV, MLFLOW_TRACKING_URI=mlflow_server)
    start = time.monotonic()
    process = subprocess.Popen(
        command("out/slurm", *ON_SLURM),
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    first_visible = None
    while process.poll() is None:  # the runs appear on the server while the sweep runs, as their jobs end
        if first_visible is None:
            try:
                _, runs = sweep_runs(mlflow_server, sweep)
            except (OSError, KeyError):
                runs = []
            if any(tags_of(run).get("kind") == "run" for run in runs):
                first_visible = time.monotonic() - start
        time.sleep(0.5)
    out, err = process.communicate()
    seconds = time.monotonic() - start
    assert process.returncode == 0, err[-3000:]
    complete, incomplete = find_records([sweep])
    assert len(complete) == 4 and incomplete == []
    pd.testing.assert_frame_equal(comparable(sweep), comparable(local))
    assert (sweep / "collected" / "alpha_table.md").read_text() == (local / "collected" / "alpha_table.md").read_text()
    assert "job states are read from squeue" in err + out and "sacct" not in (err + out).replace(
        "(sacct: Slurm accounting storage is disabled)", ""
    )
    assert first_visible is not None and first_visible < seconds
    query, runs = sweep_runs(mlflow_server, sweep)
    assert len(runs) == 5
    lines = check_runs_against_records(runs)
    with capsys.disabled():
        print(
            f"\n=== SLURM sweep ({len(complete)} runs, {os.cpu_count()} CPUs, cpus_per_task=1) ===\n"
            f"{shown(' '.join(command('out/slurm', *ON_SLURM)[3:]))}\n"
            f"{shown(chr(10).join(line for line in (out + err).splitlines() if 'HYDRA' in line or 'mlflow' in line))}\n"
            f"time: SLURM sweep {seconds:.1f} s, the same sweep locally (default launcher) {local_seconds:.1f} s; "
            f"first run on the server {first_visible:.1f} s after submission; uptime: "
            f"{subprocess.run(['uptime'], capture_output=True, text=True).stdout.strip()}\n"
            f"collected table equal to the local sweep's:\n{shown((sweep / 'collected' / 'alpha_table.md').read_text())}\n"
            f"=== REST: POST {mlflow_server}/api/2.0/mlflow/runs/search {json.dumps(query)} ===\n"
            f"{shown(chr(10).join(lines))}"
        )


@pytest.mark.process
def test_an_interrupted_slurm_sweep_resumes_with_only_the_missing_runs(
    slurm_cluster, mlflow_server, local_sweep, tmp_path, capsys
):
    local, _ = local_sweep
    sweep = tmp_path / "out" / "cut"
    env = dict(ENV, MLFLOW_TRACKING_URI=mlflow_server, WORKBENCH_SLURM_DIR=str(slurm_cluster))
    evidence = []
    process = subprocess.Popen(
        command("out/cut", *ON_SLURM), cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    cancelled = wait_for(running_tasks)[0]
    queue = subprocess.run(["squeue", "--array"], capture_output=True, text=True).stdout
    subprocess.run(["scancel", cancelled], check=True)
    evidence += [f"queue:\n{shown(queue)}", f"scancel {cancelled} (running)"]
    other = wait_for(lambda: [task for task in running_tasks() if task != cancelled])[0]
    restart = subprocess.run(
        [str(REPO_ROOT / ".ci" / "slurm-cluster"), "restart-slurmd"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert restart.returncode == 0, restart.stderr
    evidence.append(f"restart of slurmd while {other} runs:\n{shown(restart.stdout)}")
    out, err = process.communicate(timeout=900)
    assert process.returncode == 2, err[-3000:]
    [error] = [line for line in err.splitlines() if line.startswith("workbench")]
    assert (
        error.startswith("workbench: error: 1 of 4 submitted runs ended without a result: ")
        and f"{cancelled} (" in error
        and "CANCELLED" in error
        and "submit the same command again" in error
    )
    evidence.append(f"the sweep command (exit {process.returncode}):\n{shown(error)}")
    complete, incomplete = find_records([sweep])
    assert len(complete) == 3 and len(incomplete) <= 1
    before = {folder: (folder / "done").stat() for folder in complete}
    evidence.append(
        "records after the interruption: "
        + ", ".join(
            f"{folder.name} {'complete' if folder in complete else 'incomplete'}"
            for folder in sorted(sweep.iterdir())
            if folder.is_dir() and not folder.name.startswith(".")
        )
    )

    again = subprocess.run(
        command("out/cut", *ON_SLURM), cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900
    )
    assert again.returncode == 0, again.stderr[-3000:]
    log = again.stdout + again.stderr
    assert log.count("complete record, not submitted") == 3 and "1 of 4 runs" in log
    complete_after, _ = find_records([sweep])
    assert len(complete_after) == 4
    for folder, stat in before.items():  # the finished runs were not redone
        now = (folder / "done").stat()
        assert (now.st_ino, now.st_mtime_ns) == (stat.st_ino, stat.st_mtime_ns), folder
    pd.testing.assert_frame_equal(comparable(sweep), comparable(local))
    query, runs = sweep_runs(mlflow_server, sweep)
    assert len(runs) == 5  # one sweep run and one run per record: the resumed sweep duplicated nothing
    lines = check_runs_against_records(runs)
    evidence.append(
        f"the same command again (exit 0):\n{shown(chr(10).join(line for line in log.splitlines() if 'HYDRA' in line or 'mlflow' in line))}"
    )
    with capsys.disabled():
        print(
            "\n=== SLURM sweep interrupted and resumed ===\n"
            + "\n".join(evidence)
            + f"\ncollected table equal to the local sweep's; REST: POST {mlflow_server}/api/2.0/mlflow/runs/search "
            f"{json.dumps(query)}\n{shown(chr(10).join(lines))}"
        )


def test_job_states_from_squeue_cover_pending_ranges_and_single_jobs():
    """What the launcher reads on a cluster without accounting (runs without a cluster)."""
    pytest.importorskip("submitit", reason="the cluster extra is not installed")
    from workbench.cli.cluster import accounting_disabled, squeue_states

    states = squeue_states("17_0|CANCELLED|vm\n17_1|RUNNING|vm\n17_[2-3%4]|PENDING|\n21|COMPLETED|vm\n")
    assert {job: info["State"] for job, info in states.items()} == {
        "17_0": "CANCELLED",
        "17_1": "RUNNING",
        "17_2": "PENDING",
        "17_3": "PENDING",
        "21": "COMPLETED",
    }
    assert accounting_disabled("Slurm accounting storage is disabled\n")
