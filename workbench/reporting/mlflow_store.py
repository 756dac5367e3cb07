"""``workbench mlflow <folder>...``: log finished run records into an MLflow tracking store (extra: mlflow).

Runs are logged from their records after the fact (at the end of a sweep, or by ``workbench mlflow <folder>``),
so the machines that compute need no access to the store. The default store needs no server: a SQLite file and
an artifact folder in ``<paths.output_root>/.mlflow/``. Each study is an MLflow experiment and each complete record
one MLflow run:

- params: the flattened resolved config (``dataset.n_frames``, ``basis.coverage``, ...);
- metrics: every alpha of every row of the alpha table as ``<alpha column>.<data>.<basis>.<solver>`` (for example
  ``alpha_abs_mean.markers.QE.lstsq``), the number of eigenfaces and their coverage per data variant
  (``m.<data>``, ``coverage.<data>``) and the stage timings (``time.<stage>``, seconds);
- tags: ``study``, ``sweep``, ``config_hash``, ``git_commit``, ``data`` (the data variants), ``record`` (the run
  folder), and MLflow's run name (the run folder's name);
- artifacts: the record's files (config, alpha table as CSV and Markdown, metrics, timings, log) and the run's
  report (``report/``, its figures) when one was built.

A record already in the store (same ``record`` and ``config_hash`` tags, finished) is not logged again; a run an
interrupted import left unfinished is deleted and logged anew.
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import time
from datetime import datetime
from pathlib import Path
from typing import Iterable, Mapping, Sequence

from workbench.config import REPO_ROOT
from workbench.errors import WorkbenchError
from workbench.record import (ALPHA_COLUMNS, CONFIG_FILE, METRICS_FILE, TABLE_FILE, TEXT_FILE, TIMINGS_FILE,
                              RunRecord, find_records, load_record)
from workbench.reporting.runs import flatten

log = logging.getLogger(__name__)

STORE_FOLDER = ".mlflow"
"""Hidden, so that the copies of records among its artifacts are never taken for runs by collect, report or this."""
DATABASE_FILE = "mlflow.db"
ARTIFACTS_FOLDER = "artifacts"
ARTIFACT_FILES = (CONFIG_FILE, TABLE_FILE, TEXT_FILE, METRICS_FILE, TIMINGS_FILE, "workbench.log")
REPORT_FOLDER = "report"
RECORD_TAG = "record"
KEEP_OUT = ("workbench", "conf", "studies", "tests", "reports", "benchmarks")
"""Folders of the source tree a store must never be written into."""


def import_mlflow():
    """The ``mlflow`` module, or a one-line error saying how to install it."""
    try:
        import mlflow
    except ImportError as error:
        from workbench.extras import install_hint

        raise WorkbenchError(f"the MLflow store needs the mlflow extra: {install_hint('mlflow')} ({error})") from None
    return mlflow


def default_store(output_root: Path) -> Path:
    """The folder of the embedded store: ``<output_root>/.mlflow`` (holding ``mlflow.db`` and ``artifacts/``)."""
    return Path(output_root) / STORE_FOLDER


def store_uris(store: Path) -> tuple[str, str]:
    """The tracking URI (SQLite) and artifact location of the embedded store in ``store``.

    Raises
    ------
    WorkbenchError
        When ``store`` lies in a folder of the source tree (the package, configs, tests or committed reports).
    """
    store = Path(store).expanduser().resolve()
    for name in KEEP_OUT:
        if store.is_relative_to(REPO_ROOT / name):
            raise WorkbenchError(f"MLflow store {store} is inside the source tree ({REPO_ROOT / name}); "
                                 "put it under the output root (--store)")
    return f"sqlite:///{store / DATABASE_FILE}", (store / ARTIFACTS_FOLDER).as_uri()


def metric_key(*parts) -> str:
    """An MLflow metric or param name from its parts joined by dots; characters MLflow refuses become ``_``."""
    return ".".join(re.sub(r"[^A-Za-z0-9_\-. /]", "_", str(part)) for part in parts)


def record_metrics(record: RunRecord) -> dict[str, float]:
    """Every alpha of every table row, ``m`` and coverage per data variant and the stage timings, by stable name.

    Raises
    ------
    WorkbenchError
        When two rows of the table would share a name (the table has no such rows).
    """
    metrics = {}
    for row in record.table.to_dict("records"):
        for column in ALPHA_COLUMNS:
            key = metric_key(column, row["data"], row["basis"], row["solver"])
            if key in metrics:
                raise WorkbenchError(f"{record.folder / TABLE_FILE}: two rows are named {key}")
            metrics[key] = float(row[column])
        metrics[metric_key("m", row["data"])] = float(row["m"])
        metrics[metric_key("coverage", row["data"])] = float(row["coverage"])
    metrics.update({metric_key("time", stage): float(seconds) for stage, seconds in record.timings.items()})
    return metrics


def record_params(record: RunRecord) -> dict[str, str]:
    """The flattened resolved config as MLflow params (text, as MLflow keeps them)."""
    return {metric_key(key): str(value) for key, value in flatten(record.config).items()}


def record_tags(record: RunRecord) -> dict[str, str]:
    """The tags that find a run: study, sweep, config hash, git commit, data variants and the record's folder."""
    folder = record.folder.resolve()
    return {"study": record.study, "sweep": str(folder.parent), "config_hash": str(record.config_hash),
            "git_commit": str(record.git.get("commit")), "data": ",".join(record.data_variants),
            RECORD_TAG: str(folder), "mlflow.runName": folder.name}


def experiment_id(client, study: str, artifact_root: str | None) -> str:
    """The id of the study's experiment, created if new (its artifacts in ``<artifact_root>/<study>``, or where
    the store puts them when ``artifact_root`` is None)."""
    experiment = client.get_experiment_by_name(study)
    if experiment is not None:
        return experiment.experiment_id
    return client.create_experiment(study, artifact_location=None if artifact_root is None
                                    else f"{artifact_root}/{study}")


def logged_records(client, experiment: str) -> dict[tuple[str, str], list]:
    """The runs of an experiment by (record folder, config hash)."""
    from mlflow.entities import ViewType

    runs, token = {}, None
    while True:
        page = client.search_runs([experiment], run_view_type=ViewType.ACTIVE_ONLY, max_results=1000,
                                  page_token=token)
        for run in page:
            key = (run.data.tags.get(RECORD_TAG), run.data.tags.get("config_hash"))
            runs.setdefault(key, []).append(run)
        token = page.token
        if not token:
            return runs


def started_ms(record: RunRecord) -> int:
    """The run's start (``metrics.json``'s ``started_at``) in milliseconds since the epoch; now if unknown."""
    started = record.metrics.get("started_at")
    try:
        return int(datetime.fromisoformat(str(started)).timestamp() * 1000)
    except ValueError:
        return int(time.time() * 1000)


def log_record(client, experiment: str, record: RunRecord) -> str:
    """Log one record as a finished MLflow run and return the run's id."""
    from mlflow.entities import Metric, Param, RunTag

    start = started_ms(record)
    run = client.create_run(experiment, start_time=start,
                            tags={key: value for key, value in record_tags(record).items()})
    run_id = run.info.run_id
    client.log_batch(run_id, metrics=[Metric(key, value, start, 0) for key, value in record_metrics(record).items()],
                     params=[Param(key, value[:6000]) for key, value in record_params(record).items()],
                     tags=[RunTag("workbench.version", str(record.metrics.get("versions", {}).get("workbench")))])
    for name in ARTIFACT_FILES:
        if (record.folder / name).is_file():
            client.log_artifact(run_id, str(record.folder / name))
    if (record.folder / REPORT_FOLDER).is_dir():
        client.log_artifacts(run_id, str(record.folder / REPORT_FOLDER), artifact_path=REPORT_FOLDER)
    end = start + int(1000 * float(record.timings.get("total", 0.0)))
    client.set_terminated(run_id, status="FINISHED", end_time=end)
    return run_id


def log_records(paths: Iterable[Path], *, store: Path | None = None, tracking_uri: str | None = None) -> dict:
    """Log every complete record under ``paths`` that the store does not hold yet.

    Parameters
    ----------
    paths : iterable of pathlib.Path
        Run folders, sweep folders or folders above them.
    store : pathlib.Path, optional
        Folder of the embedded SQLite store; default ``<paths.output_root of the records>/.mlflow``.
    tracking_uri : str, optional
        Any MLflow tracking URI instead of the embedded store (a server, another database); artifacts then go
        where that store puts them.

    Returns
    -------
    dict
        ``tracking_uri``, ``added`` and ``skipped`` (numbers of records) and ``incomplete`` (run folders without
        a completion marker, left out).
    """
    mlflow = import_mlflow()
    complete, incomplete = find_records([Path(path) for path in paths])
    if not complete:
        raise WorkbenchError(f"no complete run record under {', '.join(map(str, paths))}")
    records = [load_record(folder) for folder in complete]
    if tracking_uri is None:
        store = default_store(records[0].config.get("paths", {}).get("output_root", "outputs")) \
            if store is None else Path(store)
        tracking_uri, artifact_root = store_uris(store)
        Path(store).mkdir(parents=True, exist_ok=True)
    else:
        artifact_root = None
    client = mlflow.MlflowClient(tracking_uri=tracking_uri)
    added = skipped = 0
    experiments = {}
    for record in records:
        if record.study not in experiments:
            experiment = experiment_id(client, record.study, artifact_root)
            experiments[record.study] = (experiment, logged_records(client, experiment))
        experiment, logged = experiments[record.study]
        previous = logged.get((str(record.folder.resolve()), str(record.config_hash)), [])
        if any(run.info.status == "FINISHED" for run in previous):
            skipped += 1
            continue
        for run in previous:  # an import that was interrupted: start that record again
            client.delete_run(run.info.run_id)
        log_record(client, experiment, record)
        added += 1
    return {"tracking_uri": tracking_uri, "added": added, "skipped": skipped, "incomplete": incomplete}


def summary_line(result: Mapping) -> str:
    note = f", {len(result['incomplete'])} incomplete run folders left out" if result["incomplete"] else ""
    return (f"mlflow: {result['added']} runs added, {result['skipped']} already in the store{note}; "
            f"browse with: mlflow ui --backend-store-uri {result['tracking_uri']}")


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="workbench mlflow",
        description="Log finished run records into an MLflow tracking store (each record once).")
    parser.add_argument("paths", nargs="+", type=Path, help="run folders, sweep folders or folders above them")
    target = parser.add_mutually_exclusive_group()
    target.add_argument("--store", type=Path, default=None,
                        help="folder of the embedded SQLite store (default: <paths.output_root>/.mlflow of the "
                             "records)")
    target.add_argument("--tracking-uri", default=os.environ.get("MLFLOW_TRACKING_URI"),
                        help="an MLflow tracking URI instead (default: $MLFLOW_TRACKING_URI, else the embedded "
                             "store)")
    return parser.parse_args(list(argv))


def main(argv: Sequence[str]) -> int:
    """``workbench mlflow <folder>... [--store DIR | --tracking-uri URI]``."""
    args = parse_args(argv)
    print(summary_line(log_records(args.paths, store=args.store, tracking_uri=args.tracking_uri)))
    return 0


try:
    from hydra.experimental.callback import Callback
except ImportError:  # pragma: no cover - Hydra is a dependency; this keeps the module importable without it
    Callback = object


class MlflowSweep(Callback):
    """Hydra callback: when a sweep ends, log its finished records into the MLflow store.

    Every study carries it off (``hydra.callbacks.mlflow.enabled: false``); a study config or the command line
    turns it on (``hydra.callbacks.mlflow.enabled=true``). ``store`` or ``tracking_uri`` choose the store as the
    ``workbench mlflow`` options do.
    """

    def __init__(self, enabled: bool = False, store: str | None = None, tracking_uri: str | None = None):
        self.enabled, self.store, self.tracking_uri = bool(enabled), store, tracking_uri

    def on_multirun_end(self, config, **kwargs) -> None:
        if not self.enabled:
            return
        sweep_dir = Path(str(config.hydra.sweep.dir))
        try:
            result = log_records([sweep_dir], store=None if self.store is None else Path(self.store),
                                 tracking_uri=self.tracking_uri)
        except WorkbenchError as error:  # the records are complete; say why the store is not, and how to retry
            log.error(f"workbench mlflow: error: {error} (records kept; rerun 'workbench mlflow {sweep_dir}')")
            return
        log.info(summary_line(result))
