"""Finished run records in an MLflow store: one MLflow run per record, the right params, metrics, tags and
artifacts, and no duplicates when a sweep is resumed or imported again (needs the mlflow extra; CI installs it)."""

import dataclasses
import os
import subprocess
import sys

import pandas as pd
import pytest

from workbench.config import REPO_ROOT
from workbench.errors import WorkbenchError
from workbench.record import find_records, load_record

mlflow = pytest.importorskip("mlflow", reason="the mlflow extra is not installed (pip install -e '.[mlflow]')")

from workbench.reporting.mlflow_store import (log_records, metric_key, record_metrics,  # noqa: E402
                                              store_uris)

SWEEP = ["--config-name", "coverage_small", "dataset.n_frames=500", "paths.output_root=out",
         "hydra.sweep.dir=out/coverage_small/default", "hydra.callbacks.mlflow.enabled=true"]


def sweep(cwd):
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT), OPENBLAS_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-m", "workbench", *SWEEP], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


def search(tmp_path):
    mlflow.set_tracking_uri(f"sqlite:///{tmp_path / 'out' / '.mlflow' / 'mlflow.db'}")
    return mlflow.search_runs(experiment_names=["coverage_small"])


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    """A small study swept with the MLflow callback on: its store under the output root."""
    tmp_path = tmp_path_factory.mktemp("mlflow")
    result = sweep(tmp_path)
    assert result.returncode == 0, result.stderr
    assert "mlflow: 4 runs added, 0 already in the store" in result.stdout
    return tmp_path


def test_one_mlflow_run_per_record_with_params_metrics_and_tags(swept):
    runs = search(swept)
    complete, _ = find_records([swept / "out" / "coverage_small" / "default"])
    assert len(runs) == len(complete) == 4
    assert set(runs["status"]) == {"FINISHED"}
    assert sorted(zip(runs["params.basis.coverage"], runs["params.dataset.seed"])) == [
        ("0.95", "0"), ("0.95", "1"), ("0.995", "0"), ("0.995", "1")]
    assert set(runs["params.dataset.n_frames"]) == {"500"} and set(runs["params.solver.lstsq.kind"]) == {"lstsq"}
    filtered = mlflow.search_runs(experiment_names=["coverage_small"],
                                  filter_string="params.`basis.coverage` = '0.95' and tags.study = 'coverage_small'")
    assert len(filtered) == 2
    for folder in complete:
        record = load_record(folder)
        [run] = runs[runs["tags.record"] == str(folder.resolve())].to_dict("records")
        assert run["tags.config_hash"] == record.config_hash and run["tags.data"] == "markers"
        assert run["tags.git_commit"] == str(record.git.get("commit")) and run["tags.study"] == "coverage_small"
        assert run["tags.sweep"] == str(folder.resolve().parent) and run["tags.mlflow.runName"] == folder.name
        for row in record.table.to_dict("records"):
            for column in ("alpha_abs_mean", "alpha_disp_pooled", "rms_mm"):
                key = f"metrics.{column}.markers.{row['basis']}.{row['solver']}"
                assert run[key] == pytest.approx(row[column], rel=1e-15, abs=0)
        assert run["metrics.m.markers"] == record.table["m"].iloc[0]
        artifacts = {item.path for item in mlflow.MlflowClient().list_artifacts(run["run_id"])}
        assert {"alpha_table.csv", "alpha_table.md", "config.yaml", "metrics.json", "workbench.log"} <= artifacts
        stored = mlflow.artifacts.download_artifacts(run_id=run["run_id"], artifact_path="alpha_table.csv")
        pd.testing.assert_frame_equal(pd.read_csv(stored), record.table)
    metric_names = [name for name in runs.columns if name.startswith("metrics.alpha_abs_mean.")]
    assert sorted(metric_names) == ["metrics.alpha_abs_mean.markers.H.lstsq", "metrics.alpha_abs_mean.markers.PCA.projection",
                                    "metrics.alpha_abs_mean.markers.QE-linear.lstsq", "metrics.alpha_abs_mean.markers.QE.lstsq"]


def test_resumed_sweep_and_second_import_add_nothing(swept):
    before = search(swept)
    again = sweep(swept)
    assert again.returncode == 0, again.stderr
    assert again.stdout.count("skip ") == 4 and "mlflow: 0 runs added, 4 already in the store" in again.stdout
    result = log_records([swept / "out"], store=swept / "out" / ".mlflow")
    assert (result["added"], result["skipped"], result["incomplete"]) == (0, 4, [])
    after = search(swept)
    assert sorted(after["run_id"]) == sorted(before["run_id"])


def test_an_interrupted_import_is_redone(swept, tmp_path):
    folders, _ = find_records([swept / "out" / "coverage_small" / "default"])
    store = tmp_path / "store"
    log_records(folders[:1], store=store)
    uri, _ = store_uris(store)
    client = mlflow.MlflowClient(tracking_uri=uri)
    [run] = client.search_runs([client.get_experiment_by_name("coverage_small").experiment_id])
    client.set_terminated(run.info.run_id, status="RUNNING")  # as an import killed before it finished leaves it
    result = log_records(folders[:2], store=store)
    assert (result["added"], result["skipped"]) == (2, 0)
    runs = client.search_runs([client.get_experiment_by_name("coverage_small").experiment_id])
    assert len(runs) == 2 and {run.info.status for run in runs} == {"FINISHED"}


def test_store_never_in_the_source_tree_and_metric_names():
    with pytest.raises(WorkbenchError, match="inside the source tree"):
        store_uris(REPO_ROOT / "reports" / ".mlflow")
    uri, artifacts = store_uris(REPO_ROOT.parent / "elsewhere")
    assert uri == f"sqlite:///{REPO_ROOT.parent / 'elsewhere' / 'mlflow.db'}"
    assert artifacts == (REPO_ROOT.parent / "elsewhere" / "artifacts").as_uri()
    assert metric_key("alpha_abs_mean", "markers->mesh", "QE", "lstsq") == "alpha_abs_mean.markers-_mesh.QE.lstsq"


def test_two_rows_of_one_name_are_refused(swept):
    folders, _ = find_records([swept / "out" / "coverage_small" / "default"])
    record = load_record(folders[0])
    record = dataclasses.replace(record, table=pd.concat([record.table, record.table.iloc[:1]], ignore_index=True))
    with pytest.raises(WorkbenchError, match="two rows are named alpha_abs_mean.markers.H.lstsq"):
        record_metrics(record)
