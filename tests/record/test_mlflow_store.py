"""Finished run records in an MLflow store: one parent run per sweep with one nested run per record, params as
the config writes them, readable metric names, tags, artifacts; no duplicates when a sweep is resumed, imported
again, imported twice at once or interrupted by Ctrl-C; a full disk and a damaged name end in one line. Real
processes throughout (needs the mlflow extra; CI installs it)."""

import dataclasses
import json
import os
import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
import time

import pandas as pd
import pytest
from in_process import run_workbench
from mlflow_rest import rest
from servers import sigint_at_default

from workbench.core.errors import WorkbenchError
from workbench.record.record import find_records, load_record
from workbench.settings.config import REPO_ROOT
from workbench.study.table import ALPHA_COLUMNS, CLEAN_COLUMNS, FRAME_COLUMNS

mlflow = pytest.importorskip("mlflow", reason="the mlflow extra is not installed (pip install -e '.[mlflow]')")

from workbench.record.mlflow import finished_ms, log_records, metric_key, param_text, record_metrics, started_ms  # noqa: E402
from workbench.record.mlflow_store import Store, create_database, open_store, resolve_store, store_uris  # noqa: E402

SWEEP = [
    "--config-name",
    "coverage_small",
    "dataset.n_frames=500",
    "dataset.seed=0,1",
    "basis.coverage=0.95,0.995",
    "metric.score_clean=true",
    "paths.output_root=out",
    "hydra.sweep.dir=out/coverage_small/default",
    "hydra.callbacks.mlflow.enabled=true",
]
ENV = dict(os.environ, PYTHONPATH=str(REPO_ROOT), OPENBLAS_NUM_THREADS="1")
ENV.pop("MLFLOW_TRACKING_URI", None)


def workbench(*args, cwd, env=None):
    """The command in this process, with ``env`` (default :data:`ENV`) as its environment's variables."""
    return run_workbench(*args, cwd=cwd, env={"MLFLOW_TRACKING_URI": None, **(env or ENV)})


def search(store_folder, experiment="coverage_small"):
    mlflow.set_tracking_uri(f"sqlite:///{store_folder / 'mlflow.db'}")
    return mlflow.search_runs(experiment_names=[experiment])


def children(runs):
    return runs[runs["tags.kind"] == "run"]


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    """A small study swept with the MLflow callback on: its store under the output root."""
    tmp_path = tmp_path_factory.mktemp("mlflow")
    result = workbench(*SWEEP, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("mlflow: logged ") == 4  # each job logged its run as it ended
    assert (
        "mlflow: sweep coverage_small/default: 4 runs in the store (0 added at the end of the sweep)" in result.stdout
    )
    assert (
        f"browse with: mlflow ui --backend-store-uri sqlite:///{tmp_path / 'out' / '.mlflow' / 'mlflow.db'}"
        in result.stdout
    )
    return tmp_path


def test_one_nested_run_per_record_with_params_metrics_tags_and_artifacts(swept):
    runs = search(swept / "out" / ".mlflow")
    complete, _ = find_records([swept / "out" / "coverage_small" / "default"])
    [parent] = runs[runs["tags.kind"] == "sweep"].to_dict("records")
    assert parent["tags.mlflow.runName"] == "coverage_small/default" and parent["status"] == "FINISHED"
    assert parent["tags.sweep"] == str((swept / "out" / "coverage_small" / "default").resolve())
    runs = children(runs)
    assert len(runs) == len(complete) == 4
    assert set(runs["status"]) == {"FINISHED"} and set(runs["tags.mlflow.parentRunId"]) == {parent["run_id"]}
    assert sorted(zip(runs["params.basis.coverage"], runs["params.dataset.seed"])) == [
        ("0.95", "0"),
        ("0.95", "1"),
        ("0.995", "0"),
        ("0.995", "1"),
    ]
    # params as the config writes them: null and true, not Python's None and True
    assert set(runs["params.dataset.eval_on"]) == {"null"} and set(runs["params.dataset.stabilise"]) == {"true"}
    assert set(runs["params.basis.projections"]) == {"[affine, linear]"}
    assert set(runs["params.dataset.n_frames"]) == {"500"} and set(runs["params.solver.lstsq.kind"]) == {"lstsq"}
    filtered = mlflow.search_runs(
        experiment_names=["coverage_small"],
        filter_string="params.`basis.coverage` = '0.95' and tags.study = 'coverage_small'",
    )
    assert len(filtered) == 2
    for folder in complete:
        record = load_record(folder)
        [run] = runs[runs["tags.record"] == str(folder.resolve())].to_dict("records")
        assert run["tags.config_hash"] == record.config_hash and run["tags.data"] == "markers"
        assert run["tags.git_commit"] == run["tags.mlflow.source.git.commit"] == record.git["commit"]
        assert run["tags.workbench.version"] == record.metrics["versions"]["workbench"] == "0.1.0"
        assert run["tags.study"] == "coverage_small" and run["tags.mlflow.runName"] == folder.name
        for row in record.table.to_dict("records"):
            for column in ALPHA_COLUMNS:
                assert run[f"metrics.{column}.markers.{row['basis']}.{row['solver']}"] == row[column]
            # error in mm, weights (PCA has none) and scores against the clean frames, where the row has them
            for column in (*FRAME_COLUMNS, *CLEAN_COLUMNS):
                logged = run.get(f"metrics.{column}.markers.{row['basis']}.{row['solver']}")
                assert logged == row[column] if pd.notna(row[column]) else pd.isna(logged)
        assert pd.notna(run["metrics.w_max_abs.markers.QE.lstsq"])
        assert pd.notna(run["metrics.err_mm_p95.markers.PCA.projection"])
        assert (
            run["metrics.clean_alpha_abs_mean.markers.QE.lstsq"]
            == record.table.loc[
                (record.table["basis"] == "QE") & (record.table["solver"] == "lstsq"), "clean_alpha_abs_mean"
            ].item()
        )
        assert run["metrics.m.markers"] == record.table["m"].iloc[0]
        artifacts = {item.path for item in mlflow.MlflowClient().list_artifacts(run["run_id"])}
        assert {"alpha_table.csv", "alpha_table.md", "config.yaml", "metrics.json", "workbench.log"} <= artifacts
        stored = mlflow.artifacts.download_artifacts(run_id=run["run_id"], artifact_path="alpha_table.csv")
        pd.testing.assert_frame_equal(pd.read_csv(stored), record.table)
    metric_names = [name for name in runs.columns if name.startswith("metrics.alpha_abs_mean.")]
    assert sorted(metric_names) == [
        "metrics.alpha_abs_mean.markers.H.lstsq",
        "metrics.alpha_abs_mean.markers.PCA.projection",
        "metrics.alpha_abs_mean.markers.QE-linear.lstsq",
        "metrics.alpha_abs_mean.markers.QE.lstsq",
    ]
    collected = {item.path for item in mlflow.MlflowClient().list_artifacts(parent["run_id"], "collected")}
    assert {"collected/runs.csv", "collected/alpha_table.md", "collected/summary.csv"} <= collected


def test_resumed_sweep_and_second_import_add_nothing(swept):
    before = search(swept / "out" / ".mlflow")
    again = workbench(*SWEEP, cwd=swept)
    assert again.returncode == 0, again.stderr
    assert again.stdout.count("skip ") == 4 and "mlflow: sweep run coverage_small/default (resumed)" in again.stdout
    assert "4 runs in the store (0 added at the end of the sweep)" in again.stdout
    result = log_records([swept / "out"], store=swept / "out" / ".mlflow")
    assert (result["added"], result["resumed"], result["skipped"], result["incomplete"]) == (0, 0, 4, [])
    after = search(swept / "out" / ".mlflow")
    assert sorted(after["run_id"]) == sorted(before["run_id"])


def test_an_interrupted_import_is_completed_not_duplicated(swept, tmp_path):
    folders, _ = find_records([swept / "out" / "coverage_small" / "default"])
    store = tmp_path / "store"
    log_records(folders[:1], store=store)
    uri, _ = store_uris(store)
    client = mlflow.MlflowClient(tracking_uri=uri)
    experiment = client.get_experiment_by_name("coverage_small").experiment_id
    [run] = [run for run in client.search_runs([experiment]) if run.data.tags["kind"] == "run"]
    # the sweep's run an import made: its settings, summary and the span of its records (not the import's time)
    [sweep] = [run for run in client.search_runs([experiment]) if run.data.tags["kind"] == "sweep"]
    record = load_record(folders[0])
    assert sweep.data.params["study"] == "coverage_small" and sweep.data.metrics["runs"] == 1
    # the geometric mean of one run's value: exp(log(x)), equal to x up to rounding
    assert sweep.data.metrics["alpha_abs_mean.markers.QE.lstsq"] == pytest.approx(
        run.data.metrics["alpha_abs_mean.markers.QE.lstsq"], rel=1e-14
    )
    assert (sweep.info.start_time, sweep.info.end_time) == (started_ms(record), finished_ms(record))
    client.set_terminated(run.info.run_id, status="RUNNING")  # as an import killed before it finished leaves it
    result = log_records(folders[:2], store=store)
    assert (result["added"], result["resumed"], result["skipped"]) == (1, 1, 0)
    runs = [run for run in client.search_runs([experiment]) if run.data.tags["kind"] == "run"]
    assert len(runs) == 2 and {run.info.status for run in runs} == {"FINISHED"}
    assert run.info.run_id in {run.info.run_id for run in runs}


def test_names_params_and_where_to_browse():
    with pytest.raises(WorkbenchError, match="inside the source tree"):
        store_uris(REPO_ROOT / "reports" / ".mlflow")
    uri, artifacts = store_uris(REPO_ROOT.parent / "elsewhere")
    assert uri == f"sqlite:///{REPO_ROOT.parent / 'elsewhere' / 'mlflow.db'}"
    assert artifacts == (REPO_ROOT.parent / "elsewhere" / "artifacts").as_uri()
    assert metric_key("alpha_abs_mean", "markers->mesh", "QE", "lstsq") == "alpha_abs_mean.markers_to_mesh.QE.lstsq"
    assert metric_key("alpha_abs_mean", "../../x", "QE", "lstsq") == "alpha_abs_mean.______x.QE.lstsq"
    assert [param_text(value) for value in (None, True, False, 0.995, 1e-6, 12, "a b", ["markers", None], {})] == [
        "null",
        "true",
        "false",
        "0.995",
        "1.0e-06",
        "12",
        "a b",
        "[markers, null]",
        "{}",
    ]
    assert Store("http://lab:5000/").browse_hint(["7"]) == "browse: http://lab:5000/#/experiments/7"
    assert (
        Store("sqlite:////a b/mlflow.db").browse_hint()
        == "browse with: mlflow ui --backend-store-uri 'sqlite:////a b/mlflow.db'"
    )


def test_the_store_named_wins_then_the_environment_then_the_default(tmp_path, monkeypatch):
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    assert resolve_store(output_root=tmp_path).tracking_uri == f"sqlite:///{tmp_path.resolve()}/.mlflow/mlflow.db"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", "http://lab:5000")
    assert resolve_store(output_root=tmp_path) == Store("http://lab:5000")
    assert resolve_store(store=tmp_path / "s").tracking_uri == f"sqlite:///{tmp_path.resolve()}/s/mlflow.db"
    assert resolve_store(tracking_uri="http://other:5000", output_root=tmp_path).tracking_uri == "http://other:5000"
    assert resolve_store(tracking_uri=f"sqlite:///{tmp_path}/x.db").lock_file == tmp_path / "x.db.lock"
    # artifacts beside the database named (never MLflow's ./mlruns of the current folder), unless named elsewhere
    assert resolve_store(tracking_uri=f"sqlite:///{tmp_path}/x.db").artifact_root == (tmp_path / "x.artifacts").as_uri()
    assert (
        resolve_store(tracking_uri=f"sqlite:///{tmp_path}/s/mlflow.db").artifact_root
        == (tmp_path / "s" / "artifacts").as_uri()
        == resolve_store(store=tmp_path / "s").artifact_root
    )
    assert (
        resolve_store(tracking_uri=f"sqlite:///{tmp_path}/x.db", artifact_location=str(tmp_path / "a")).artifact_root
        == (tmp_path / "a").as_uri()
    )
    assert resolve_store(tracking_uri="http://lab:5000", artifact_location="s3://b/x/").artifact_root == "s3://b/x"
    assert resolve_store(tracking_uri="http://lab:5000").artifact_root is None  # the server decides


def test_scores_against_the_clean_frames_are_logged_where_a_row_has_them(swept):
    folders, _ = find_records([swept / "out" / "coverage_small" / "default"])
    record = load_record(folders[0])
    clean = record.table["alpha_abs_mean"].where(record.table["basis"] != "PCA") * 2
    metrics = record_metrics(dataclasses.replace(record, table=record.table.assign(clean_alpha_abs_mean=clean)))
    assert metrics["clean_alpha_abs_mean.markers.QE.lstsq"] == 2 * metrics["alpha_abs_mean.markers.QE.lstsq"]
    assert "clean_alpha_abs_mean.markers.PCA.projection" not in metrics  # an empty cell is no measurement
    assert "w_max_abs.markers.PCA.projection" not in metrics and "w_max_abs.markers.H.lstsq" in metrics


def test_two_rows_of_one_name_are_refused(swept):
    folders, _ = find_records([swept / "out" / "coverage_small" / "default"])
    record = load_record(folders[0])
    record = dataclasses.replace(record, table=pd.concat([record.table, record.table.iloc[:1]], ignore_index=True))
    with pytest.raises(WorkbenchError, match="two rows are named alpha_abs_mean.markers.H.lstsq"):
        record_metrics(record)


# --- real processes: concurrent imports, Ctrl-C, a full disk, names from a record, report figures -------------


@pytest.mark.slow
@pytest.mark.process
def test_a_sweep_into_a_sqlite_uri_writes_only_where_named_and_its_run_says_what_the_sweep_was(tmp_path):
    """MLFLOW_TRACKING_URI=sqlite:///<folder>/t.db, run from another folder: the artifacts go beside the database
    (not into ./mlruns), nothing is written anywhere else (the home folder included: no telemetry id), MLflow's own
    INFO lines stay off the console, and the sweep's run holds its settings, summary metrics and true duration."""
    store, out, cwd, home = (tmp_path / name for name in ("store", "out", "cwd", "home"))
    for folder in (store, cwd, home):
        folder.mkdir()
    env = dict(ENV, MLFLOW_TRACKING_URI=f"sqlite:///{store / 't.db'}", HOME=str(home))
    for name in ("XDG_CONFIG_HOME", "XDG_CACHE_HOME", "XDG_DATA_HOME", "MLFLOW_DISABLE_TELEMETRY"):
        env.pop(name, None)
    command = [
        sys.executable,
        "-m",
        "workbench",
        "--config-name",
        "coverage_small",
        "dataset.n_frames=500",
        "dataset.seed=0",
        "basis.coverage=0.95,0.995",
        f"paths.output_root={out}",
        "hydra.callbacks.mlflow.enabled=true",
    ]
    started, ended, lines = time.time(), None, []
    process = subprocess.Popen(command, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in process.stdout:  # the sweep ends with its last line (the interpreter's own teardown is not the sweep's)
        lines.append(line)
        if line.startswith("mlflow: sweep coverage_small/default: 2 runs in the store"):
            ended = time.time()
    error = process.stderr.read()
    assert process.wait(timeout=600) == 0, error
    assert ended is not None, "".join(lines)
    assert sorted(os.listdir(tmp_path)) == ["cwd", "home", "out", "store"]
    assert not list(cwd.iterdir()) and not list(home.iterdir())
    assert sorted(os.listdir(store)) == ["t.artifacts", "t.db", "t.db.lock"]
    # one format: no Hydra date prefix, no MLflow INFO line
    assert not [line for line in lines if line.startswith("[") or " INFO " in line], lines
    assert "INFO" not in error and "alembic" not in error, error
    client = mlflow.MlflowClient(tracking_uri=f"sqlite:///{store / 't.db'}")
    runs = client.search_runs([client.get_experiment_by_name("coverage_small").experiment_id])
    [parent] = [run for run in runs if run.data.tags["kind"] == "sweep"]
    children_ = [run for run in runs if run.data.tags["kind"] == "run"]
    assert len(children_) == 2
    assert all(run.info.artifact_uri.startswith((store / "t.artifacts").as_uri()) for run in runs)
    assert parent.data.params["study"] == "coverage_small" and parent.data.params["swept"] == "basis.coverage"
    assert parent.data.params["basis.coverage"] == "0.95,0.995" and parent.data.params["dataset.seed"] == "0"
    assert parent.data.params["dataset.n_frames"] == "500"
    values = [run.data.metrics["alpha_abs_mean.markers.QE.lstsq"] for run in children_]
    assert parent.data.metrics["alpha_abs_mean.markers.QE.lstsq"] == pytest.approx(
        (values[0] * values[1]) ** 0.5, rel=1e-12
    )
    assert parent.data.metrics["runs"] == 2
    duration = (parent.info.end_time - parent.info.start_time) / 1000
    assert duration == pytest.approx(ended - started, abs=1.0), (duration, ended - started)
    assert parent.data.metrics["time.sweep"] == pytest.approx(duration, abs=1.0)


def records_copy(swept, tmp_path):
    """The sweep's records copied (without the store), so that each test logs them into a store of its own."""
    target = tmp_path / "out" / "coverage_small" / "default"
    shutil.copytree(
        swept / "out" / "coverage_small" / "default", target, ignore=shutil.ignore_patterns("collected", ".submitit")
    )
    return target


def interruptible(command: list[str], cwd) -> subprocess.Popen:
    """``command`` started with SIGINT at its default action, whatever the test process has it set to."""
    return subprocess.Popen(
        command,
        cwd=cwd,
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=sigint_at_default,
    )


def stored_runs(database):
    """Every run row of a SQLite store, deleted ones too: (record tag, '' for a sweep run; status; stage)."""
    with sqlite3.connect(database) as connection:
        return connection.execute(
            "select coalesce((select value from tags where tags.run_uuid = runs.run_uuid and key = 'record'), ''), "
            "status, lifecycle_stage from runs"
        ).fetchall()


@pytest.mark.process
@pytest.mark.slow
def test_two_imports_started_together_into_a_new_store_both_succeed(swept, tmp_path):
    sweep = records_copy(swept, tmp_path)
    for trial in range(2):
        store = tmp_path / f"store{trial}"
        command = [sys.executable, "-m", "workbench", "mlflow", str(sweep), "--store", str(store)]
        processes = [
            subprocess.Popen(command, cwd=tmp_path, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            for _ in range(2)
        ]
        outputs = [process.communicate(timeout=600) for process in processes]
        assert [process.returncode for process in processes] == [0, 0], [err for _, err in outputs]
        lines = sorted(out.strip().split(";")[0] for out, _ in outputs)
        assert lines == ["mlflow: 0 runs added, 4 already in the store", "mlflow: 4 runs added, 0 already in the store"]
        rows = stored_runs(store / "mlflow.db")
        assert sorted(rows) == sorted(
            [("", "FINISHED", "active")]
            + [(str(folder.resolve()), "FINISHED", "active") for folder in find_records([sweep])[0]]
        )


@pytest.mark.process
@pytest.mark.slow
def test_ctrl_c_during_an_import_then_the_same_command_leaves_one_run_per_record(swept, tmp_path):
    """SIGINT (as Ctrl-C sends) while the runs are being written, at several moments; the same command again
    finishes the job: every record once, in the store's own rows too (deleted runs counted)."""
    sweep = records_copy(swept, tmp_path)
    records = sorted(str(folder.resolve()) for folder in find_records([sweep])[0])
    with open_store(resolve_store(store=tmp_path / "empty")) as client:  # a store with its tables, no runs yet
        client.search_experiments()
    outcomes = []
    # the import of four records ends within 0.1-0.3 s of its first run row (here), and on a fast moment of a
    # machine before even the first moment's Ctrl-C comes (an outcome 0, checked as well): the moments are tried in
    # turn, both at least once, until one interrupted the import, at most six trials
    for trial, extra_delay in enumerate((0.0, 0.1) * 3):
        if trial >= 2 and 130 in outcomes:
            break
        store = tmp_path / f"store{trial}"
        store.mkdir()
        shutil.copy(tmp_path / "empty" / "mlflow.db", store / "mlflow.db")
        command = [sys.executable, "-m", "workbench", "mlflow", str(sweep), "--store", str(store)]
        process = interruptible(command, tmp_path)
        deadline = time.monotonic() + 300
        while process.poll() is None and time.monotonic() < deadline:  # until the first run row exists
            if (store / "mlflow.db").is_file():
                try:
                    if stored_runs(store / "mlflow.db"):
                        break
                except sqlite3.Error:
                    pass
            time.sleep(0.01)
        time.sleep(extra_delay)
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=120)
        outcomes.append(process.returncode)
        if process.returncode == 130:
            assert err.strip().splitlines()[-1] == "workbench mlflow: interrupted; rerun the same command to resume"
        elif process.returncode == -signal.SIGINT:
            # the signal came as the finished import's process exited (Python no longer handles it then): the
            # import had printed its summary
            assert out.strip() and not err.strip(), (out, err)
        else:
            assert process.returncode == 0, err
        again = workbench("mlflow", sweep, "--store", store, cwd=tmp_path)  # the store it left: no process needed
        assert again.returncode == 0, again.stderr
        rows = stored_runs(store / "mlflow.db")
        assert sorted(record for record, _, _ in rows if record) == records
        assert {(status, stage) for _, status, stage in rows} == {("FINISHED", "active")}
    assert 130 in outcomes, outcomes


@pytest.mark.slow
@pytest.mark.process
def test_a_store_on_a_full_disk_ends_in_one_line(swept, tmp_path):
    """The store on a 3 MB file system: full before the store exists, and full while artifacts are written."""
    if shutil.which("unshare") is None:
        pytest.skip("unshare (util-linux) is needed to mount a small file system for this test")
    probe = subprocess.run(["unshare", "--user", "--map-root-user", "--mount", "true"], capture_output=True)
    if probe.returncode != 0:
        pytest.skip(f"user namespaces are not available here: {probe.stderr.decode().strip()}")
    sweep = records_copy(swept, tmp_path)
    report = find_records([sweep])[0][0] / "report"  # a report larger than the space left
    report.mkdir()
    (report / "figure.png").write_bytes(os.urandom(4_000_000))
    disk = tmp_path / "disk"
    disk.mkdir()
    for fill in ("full", "space for the database"):
        leave = "0" if fill == "full" else "1500"  # kilobytes left free
        script = (
            f"mount -t tmpfs -o size=3m tmpfs {disk} && "
            f"(head -c $((3072 - {leave}))k /dev/zero > {disk}/filler 2>/dev/null; true) && "
            f"exec {sys.executable} -m workbench mlflow {sweep} --store {disk}/store"
        )
        result = subprocess.run(
            ["unshare", "--user", "--map-root-user", "--mount", "sh", "-c", script],
            cwd=tmp_path,
            env=ENV,
            capture_output=True,
            text=True,
            timeout=600,
        )
        errors = [line for line in result.stderr.splitlines() if line.startswith("workbench")]
        assert result.returncode == 2, (fill, result.stderr[-3000:])
        assert len(errors) == 1 and "Traceback" not in result.stderr, (fill, result.stderr[-3000:])
        assert "No space left on device" in errors[0] or "disk is full" in errors[0], errors[0]


@pytest.mark.slow
@pytest.mark.process
def test_a_store_whose_disk_fills_while_logging_ends_in_one_line_that_says_so(swept, tmp_path):
    """A store that exists, on a disk with 30 KB left: MLflow logged SQLAlchemy's traceback, and the line after it
    named the autoflush, not the full disk. A child process: what the process prints is the point."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(disk)], capture_output=True).returncode:
        pytest.skip("cannot mount a file system here")
    try:
        sweep = records_copy(swept, tmp_path)
        records = find_records([sweep])[0]
        assert workbench("mlflow", records[0], "--store", disk / "store", cwd=tmp_path).returncode == 0
        free = shutil.disk_usage(disk).free
        with open(disk / "filler", "wb") as filler:
            filler.write(bytes(free - 30 * 1024))
        result = subprocess.run(
            [sys.executable, "-m", "workbench", "mlflow", str(sweep), "--store", str(disk / "store")],
            cwd=tmp_path,
            env=ENV,
            capture_output=True,
            text=True,
            timeout=600,
        )
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2 and len(lines) == 1, result.stderr[-3000:]
        assert lines[0].startswith(f"workbench mlflow: error: MLflow store sqlite:///{disk / 'store'}"), lines
        assert "the disk is full (" in lines[0] and "KB left on" in lines[0], lines
        (disk / "filler").unlink()
        again = workbench("mlflow", sweep, "--store", disk / "store", cwd=tmp_path)
        assert again.returncode == 0, again.stderr
        rows = stored_runs(disk / "store" / "mlflow.db")
        assert sorted(record for record, status, _ in rows if record and status == "FINISHED") == sorted(
            str(folder.resolve()) for folder in records
        )
    finally:
        subprocess.run(["umount", "--lazy", str(disk)], check=True)  # the in-process store may hold the file open


def test_metric_names_from_a_record_never_leave_their_place(swept, tmp_path):
    """A record whose data variant reads '../../x' (edited by hand): its metrics are logged under a plain name."""
    sweep = records_copy(swept, tmp_path)
    folder = find_records([sweep])[0][0]
    table = pd.read_csv(folder / "alpha_table.csv")
    table["data"] = "../../x"
    table.to_csv(folder / "alpha_table.csv", index=False)
    metrics = json.loads((folder / "metrics.json").read_text())
    metrics["data"] = {"../../x": metrics["data"]["markers"]}
    for row in metrics["rows"]:
        row["data"] = "../../x"
    (folder / "metrics.json").write_text(json.dumps(metrics))
    # as a record written so by another tool: checksums matching its files (a hand edit alone is refused)
    from workbench.core.files import sha256_of_file as file_checksum
    from workbench.record.record import DONE

    done = json.loads((folder / DONE).read_text())
    done["sha256"].update({name: file_checksum(folder / name) for name in ("alpha_table.csv", "metrics.json")})
    (folder / DONE).write_text(json.dumps(done))
    result = workbench("mlflow", folder, "--store", tmp_path / "store", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    [run] = children(search(tmp_path / "store")).to_dict("records")
    assert run["metrics.alpha_abs_mean.______x.QE.lstsq"] == table.loc[table["basis"] == "QE", "alpha_abs_mean"].iloc[0]
    assert not any(".." in name for name in run if name.startswith("metrics."))


@pytest.mark.slow
def test_per_frame_alpha_and_report_figures_are_logged(tmp_path):
    """A run with its per-frame alpha (save_inputs=true) logged at once; its report's figures once it has one."""
    run_dir = tmp_path / "out" / "run"
    result = workbench(
        "dataset.n_frames=500",
        "solver=lstsq",
        "save_inputs=true",
        f"hydra.run.dir={run_dir}",
        "paths.output_root=out",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    first = workbench("mlflow", run_dir, cwd=tmp_path)
    assert first.returncode == 0 and "mlflow: 1 runs added" in first.stdout, first.stderr
    report = workbench("report", run_dir, "--formats", "png", cwd=tmp_path)
    assert report.returncode == 0, report.stderr
    again = workbench("mlflow", run_dir, cwd=tmp_path)
    assert again.returncode == 0 and "mlflow: 0 runs added, 1 already in the store" in again.stdout, again.stderr
    client = mlflow.MlflowClient(tracking_uri=f"sqlite:///{tmp_path / 'out' / '.mlflow' / 'mlflow.db'}")
    [run] = client.search_runs([client.get_experiment_by_name("paper").experiment_id])
    assert "mlflow.parentRunId" not in run.data.tags  # a single run belongs to no sweep
    artifacts = {item.path for item in client.list_artifacts(run.info.run_id)}
    assert "alpha_per_frame.npz" in artifacts and "report" in artifacts
    figures = {item.path for item in client.list_artifacts(run.info.run_id, "report/figures")}
    expected = {f"report/figures/{path.name}" for path in (run_dir / "report" / "figures").glob("*.png")}
    assert expected and expected <= figures


# --- a tracking server ----------------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.process
def test_a_sweep_logs_to_the_server_named_by_the_environment(mlflow_server, tmp_path):
    """MLFLOW_TRACKING_URI alone sends the sweep to the server; the runs are found there through the REST API."""
    args = [arg.replace("coverage_small/default", "coverage_small/server") for arg in SWEEP]
    result = workbench(*args, cwd=tmp_path, env=dict(ENV, MLFLOW_TRACKING_URI=mlflow_server))
    assert result.returncode == 0, result.stderr
    experiment = rest(mlflow_server, "GET", "experiments/get-by-name?experiment_name=coverage_small")
    experiment_id = experiment["experiment"]["experiment_id"]
    assert f"browse: {mlflow_server}/#/experiments/{experiment_id}" in result.stdout
    sweep = (tmp_path / "out" / "coverage_small" / "server").resolve()
    found = rest(
        mlflow_server,
        "POST",
        "runs/search",
        {"experiment_ids": [experiment_id], "filter": f"tags.sweep = '{sweep}'", "max_results": 100},
    )["runs"]
    tags = [{tag["key"]: tag["value"] for tag in run["data"]["tags"]} for run in found]
    assert sorted(tag["kind"] for tag in tags) == ["run"] * 4 + ["sweep"]
    for run, tag in zip(found, tags):
        if tag["kind"] == "sweep":
            continue
        record = load_record(tag["record"])
        metrics = {metric["key"]: metric["value"] for metric in run["data"]["metrics"]}
        for row in record.table.to_dict("records"):
            for column in ALPHA_COLUMNS:
                assert metrics[f"{column}.markers.{row['basis']}.{row['solver']}"] == pytest.approx(
                    row[column], rel=1e-15
                )
        params = {param["key"]: param["value"] for param in run["data"]["params"]}
        assert params["dataset.eval_on"] == "null" and params["dataset.stabilise"] == "true"
    # the same records logged again by the command, with the server named on the command line: nothing added
    again = workbench("mlflow", sweep, "--tracking-uri", mlflow_server, cwd=tmp_path)
    assert again.returncode == 0 and "mlflow: 0 runs added, 4 already in the store" in again.stdout, again.stderr


def test_a_server_out_of_reach_stops_no_run_and_the_command_says_so_in_one_line(tmp_path):
    with socket.socket() as probe:  # a port nothing listens on
        probe.bind(("127.0.0.1", 0))
        nowhere = f"http://127.0.0.1:{probe.getsockname()[1]}"
    result = workbench(
        "--config-name",
        "coverage_small",
        "dataset.n_frames=500",
        "dataset.seed=0",
        "basis.coverage=0.95",
        "paths.output_root=out",
        "hydra.callbacks.mlflow.enabled=true",
        f"hydra.callbacks.mlflow.tracking_uri={nowhere}",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    assert len(find_records([tmp_path / "out" / "coverage_small" / "default"])[0]) == 1
    assert result.stdout.count(f"MLflow server {nowhere} cannot be reached") == 2  # at the start and at the end
    late = workbench("mlflow", tmp_path / "out", "--tracking-uri", nowhere, cwd=tmp_path)
    assert late.returncode == 2 and late.stderr.strip() == (
        f"workbench mlflow: error: MLflow server {nowhere} cannot be reached ([Errno 111] Connection refused)"
    )


STORE_FILES = {"artifacts", "mlflow.db", "mlflow.db.lock"}
"""What a store folder holds after an import: no temporary file of its set-up."""


def test_a_new_store_is_set_up_in_a_temporary_file_and_a_failure_leaves_none(tmp_path, monkeypatch):
    from mlflow.store.tracking import sqlalchemy_store

    target = resolve_store(store=tmp_path / "store")
    seen = []

    class Failing(sqlalchemy_store.SqlAlchemyStore):
        def __init__(self, db_uri, default_artifact_root):
            seen.append(sorted(os.listdir(tmp_path / "store")))
            raise KeyboardInterrupt

    monkeypatch.setattr(sqlalchemy_store, "SqlAlchemyStore", Failing)
    with pytest.raises(KeyboardInterrupt):
        create_database(target)
    assert len(seen[0]) == 1 and seen[0][0].startswith(".mlflow.db.") and seen[0][0].endswith(".tmp"), seen
    assert os.listdir(tmp_path / "store") == []  # no database, no temporary file
    monkeypatch.undo()
    (tmp_path / "store" / ".mlflow.db.abc123.tmp").write_bytes(b"a killed set-up's")
    create_database(target)
    assert os.listdir(tmp_path / "store") == ["mlflow.db"]
    with sqlite3.connect(tmp_path / "store" / "mlflow.db") as connection:
        tables = {row[0] for row in connection.execute("select name from sqlite_master where type = 'table'")}
    assert {"experiments", "runs", "metrics", "params", "tags", "alembic_version"} <= tables
    before = (tmp_path / "store" / "mlflow.db").read_bytes()
    create_database(target)  # an existing store is left as it is
    assert (tmp_path / "store" / "mlflow.db").read_bytes() == before


@pytest.mark.process
@pytest.mark.slow
def test_ctrl_c_while_a_new_store_is_set_up_leaves_one_the_same_command_completes(swept, tmp_path):
    """SIGINT at several moments from when the import takes a new store's lock, over the seconds MLflow's schema
    migrations take: the command ends with the one line (or ends its work first), never swallows the interrupt,
    and the same command again makes the store and logs every record once."""
    sweep = records_copy(swept, tmp_path)
    records = sorted(str(folder.resolve()) for folder in find_records([sweep])[0])
    outcomes = []
    for trial, delay in enumerate((0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.3, 1.6)):
        store = tmp_path / f"store{trial}"
        command = [sys.executable, "-m", "workbench", "mlflow", str(sweep), "--store", str(store)]
        process = interruptible(command, tmp_path)
        deadline = time.monotonic() + 300
        while process.poll() is None and not (store / "mlflow.db.lock").exists() and time.monotonic() < deadline:
            time.sleep(0.005)
        time.sleep(delay)
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=120)
        assert "Exception ignored" not in err and "Traceback" not in err, err
        interrupted = "interrupted" in err
        outcomes.append(130 if interrupted else process.returncode)
        if interrupted:
            assert err.strip().splitlines() == ["workbench mlflow: interrupted; rerun the same command to resume"]
            assert process.returncode == 130, process.returncode
        else:  # the import ended first (its last steps ignore Ctrl-C, or Python no longer handles it)
            assert process.returncode in (0, -signal.SIGINT) and out.startswith("mlflow: 4 runs added"), (out, err)
        again = workbench("mlflow", sweep, "--store", store, cwd=tmp_path)  # the store it left: no process needed
        assert again.returncode == 0, again.stderr
        rows = stored_runs(store / "mlflow.db")
        assert sorted(record for record, _, _ in rows if record) == records
        assert {(status, stage) for _, status, stage in rows} == {("FINISHED", "active")}
        assert set(os.listdir(store)) == STORE_FILES
    assert outcomes.count(130) >= 4, outcomes
