"""``workbench mlflow <folder>...``: log finished run records into an MLflow tracking store (extra: mlflow).

The store is a team's MLflow server (``--tracking-uri http://...`` or ``MLFLOW_TRACKING_URI``) or, by default, an
embedded one that needs no server: a SQLite file and an artifact folder in ``<paths.output_root>/.mlflow/``.
Records are logged after the fact by this command, or by a sweep's callback as each job ends. Each study is an
MLflow experiment; each sweep one parent run with a nested run per complete record:

- params: the resolved config flattened to dotted keys, each value as the config writes it (``null``, ``true``,
  ``0.995``, ``[markers, mesh]``);
- metrics (:func:`metric_key`): every alpha column of every table row as ``<column>.<data>.<basis>.<solver>``
  (``alpha_abs_mean.markers.QE.lstsq``; a data variant ``markers->mesh`` reads ``markers_to_mesh``), and so the
  per-frame error and weight columns (``err_mm_*``, ``w_*``) and the scores against the clean frames
  (``clean_*``) where the row has them (PCA has no weights: no ``w_*`` of PCA), the number
  of eigenfaces and their coverage per data variant (``m.<data>``, ``coverage.<data>``) and the stage timings
  (``time.<stage>``, seconds);
- tags: ``kind`` (``run`` or ``sweep``), ``study``, ``sweep``, ``record``, ``config_hash``, ``data``,
  ``workbench.version``, ``git_commit`` (also as MLflow's ``mlflow.source.git.commit``), ``git_dirty``;
- artifacts: the record's files (config, alpha table as CSV and Markdown, per-frame alpha, metrics, timings, log)
  and its report's files (``report/``) when one was built; the sweep's run holds its collected tables;
- the sweep's run: its settings and summary metrics (:func:`sweep_params`, :func:`sweep_metrics`) and the sweep's
  span, from the command's start to the end of its logging (an import's: from its first record's start to its last
  record's end).

A new experiment keeps its files with the store named (:func:`resolve_store`: a SQLite database's beside it, never
MLflow's ``./mlruns`` of the current folder); MLflow's telemetry is off and its INFO lines stay off the console
unless ``--verbose``.

Each record goes in once (found again by its ``record`` and ``config_hash`` tags); a run an interrupted import
left unfinished is completed, not duplicated. Writers of a SQLite store take turns (a lock file beside the
database), so concurrent imports and concurrent jobs are safe.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import re
import time
from datetime import datetime
from pathlib import Path
from typing import Iterable, Iterator, Mapping, Sequence

from workbench.core.errors import WorkbenchError
from workbench.record.mlflow_store import (
    Store,
    open_store,
    resolve_store,
)
from workbench.record.record import (
    ALPHA_PER_FRAME_FILE,
    CONFIG_FILE,
    METRICS_FILE,
    TABLE_FILE,
    TEXT_FILE,
    TIMINGS_FILE,
    RunRecord,
    find_records,
    is_complete,
    load_record,
)
from workbench.study.table import ALPHA_COLUMNS, CLEAN_COLUMNS, FRAME_COLUMNS

log = logging.getLogger("workbench.sweep")
"""The callback's lines: to the console only (``conf/hydra/job_logging/workbench.yaml``), never into a record's
``workbench.log`` (the job that wrote it has ended)."""

ARTIFACT_FILES = (CONFIG_FILE, TABLE_FILE, TEXT_FILE, ALPHA_PER_FRAME_FILE, METRICS_FILE, TIMINGS_FILE, "workbench.log")
REPORT_FOLDER = "report"
COLLECTED_FOLDER = "collected"
KIND_TAG, RUN_KIND, SWEEP_KIND = "kind", "run", "sweep"
RECORD_TAG, SWEEP_TAG, LOGGED_BY_TAG = "record", "sweep", "logged_by"
BATCH_LIMITS = {"metrics": 1000, "params": 100}
"""The most metrics and params one MLflow ``log-batch`` request takes."""


# ---------------------------------------------------------------------------------------------------------------
# What a record becomes
# ---------------------------------------------------------------------------------------------------------------


def name_part(text) -> str:
    """One part of a metric or param name: ``->`` reads ``_to_`` and anything but letters, digits, ``_`` and
    ``-`` becomes ``_``, so parts never hold the dots that join them nor a path (``../x`` becomes ``___x``)."""
    return re.sub(r"[^A-Za-z0-9_\-]", "_", str(text).replace("->", "_to_")) or "_"


def metric_key(*parts) -> str:
    """An MLflow metric or param name: its parts (:func:`name_part`) joined by dots."""
    return ".".join(name_part(part) for part in parts)


def param_text(value) -> str:
    """A config value as the config writes it: ``null``, ``true``, ``0.995``, ``[markers, mesh]``, text as is."""
    import yaml

    if isinstance(value, str):
        return value
    text = yaml.safe_dump(value, default_flow_style=True, width=math.inf).strip()
    return text[:-3].strip() if text.endswith("\n...") or text.endswith("...") else text


def config_params(config: Mapping, prefix: tuple = ()) -> dict[str, str]:
    """The config flattened to ``{dotted.key: text}`` (lists kept whole, as the config writes them)."""
    params = {}
    for key, value in config.items():
        if isinstance(value, Mapping) and value:
            params.update(config_params(value, (*prefix, key)))
        else:
            params[metric_key(*prefix, key)] = param_text(value)
    return params


def record_metrics(record: RunRecord) -> dict[str, float]:
    """Every alpha of every table row, its error and weight measures and scores against the clean frames where it
    has them, ``m`` and coverage per data variant and the stage timings, by name.

    Raises
    ------
    WorkbenchError
        When two rows of the table would share a name.
    """
    metrics = {}
    measured = [column for column in (*FRAME_COLUMNS, *CLEAN_COLUMNS) if column in record.table.columns]
    for row in record.table.to_dict("records"):
        for column in ALPHA_COLUMNS:
            key = metric_key(column, row["data"], row["basis"], row["solver"])
            if key in metrics:
                raise WorkbenchError(f"{record.folder / TABLE_FILE}: two rows are named {key}")
            metrics[key] = float(row[column])
        for column in measured:  # empty cells (PCA's weights, rows without clean frames) are no measurement
            if math.isfinite(float(row[column])):
                metrics[metric_key(column, row["data"], row["basis"], row["solver"])] = float(row[column])
        metrics[metric_key("m", row["data"])] = float(row["m"])
        metrics[metric_key("coverage", row["data"])] = float(row["coverage"])
    metrics.update({metric_key("time", stage): float(seconds) for stage, seconds in record.timings.items()})
    return metrics


def record_params(record: RunRecord) -> dict[str, str]:
    """The resolved config as MLflow params (text, at most MLflow's 6,000 characters a value)."""
    return {key: value[:6000] for key, value in config_params(record.config).items()}


def sweep_folder(record: RunRecord) -> Path | None:
    """The sweep a record belongs to (its parent folder), or None for a single run."""
    return None if record.job_num is None else record.folder.resolve().parent


def version_tags(record: RunRecord) -> dict[str, str]:
    """The workbench version and git commit that made the record, as far as it says."""
    tags = {}
    version = (record.metrics.get("versions") or {}).get("workbench")
    if version:
        tags["workbench.version"] = str(version)
    if record.git.get("commit"):
        tags.update(
            {
                "git_commit": str(record.git["commit"]),
                "mlflow.source.git.commit": str(record.git["commit"]),
                "git_dirty": str(record.git.get("dirty")).lower(),
            }
        )
    return tags


def record_tags(record: RunRecord, parent_id: str | None) -> dict[str, str]:
    """The tags that find a run: kind, study, sweep, record folder, config hash, data variants, version, commit."""
    folder = record.folder.resolve()
    tags = {
        KIND_TAG: RUN_KIND,
        "study": record.study,
        SWEEP_TAG: str(folder.parent),
        RECORD_TAG: str(folder),
        "config_hash": str(record.config_hash),
        "data": ",".join(record.data_variants),
        "mlflow.runName": folder.name,
        **version_tags(record),
    }
    if parent_id is not None:
        tags["mlflow.parentRunId"] = parent_id
    return tags


def sweep_name(folder: Path) -> str:
    """A sweep run's name: its folder and the folder above (``coverage/default``)."""
    return "/".join(Path(folder).resolve().parts[-2:])


def started_ms(record: RunRecord) -> int:
    """The run's start (``metrics.json``'s ``started_at``) in milliseconds since the epoch; now if unknown."""
    try:
        return int(datetime.fromisoformat(str(record.metrics.get("started_at"))).timestamp() * 1000)
    except ValueError:
        return int(time.time() * 1000)


def finished_ms(record: RunRecord) -> int:
    """The run's end (``metrics.json``'s ``finished_at``, else its start and total time) in milliseconds."""
    try:
        return int(datetime.fromisoformat(str(record.metrics.get("finished_at"))).timestamp() * 1000)
    except ValueError:
        return started_ms(record) + int(1000 * float(record.timings.get("total", 0)))


def process_start_ms() -> int:
    """When this process started, in milliseconds since the epoch (Linux's ``/proc``); now where it cannot say."""
    now = time.time()
    try:
        fields = Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        started = now - (uptime - int(fields[19]) / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError, AttributeError):
        return int(now * 1000)
    return int(min(started, now) * 1000)


SWEPT_PARAM = "swept"
"""The sweep run's param naming the settings that take several values (comma-separated)."""
HEADLINE = "alpha_abs_mean"
"""The metric a sweep run summarises (:func:`sweep_metrics`)."""


def sweep_params(study: str, records: Sequence[RunRecord]) -> dict[str, str]:
    """A sweep run's params: ``study``; each setting its runs were given on the command line or by the study, with
    its values in Hydra's sweep syntax (``basis.coverage`` -> ``0.95,0.995``; one value as is); and ``swept``, the
    settings with several values (comma-separated, empty when none)."""
    values: dict[str, list[str]] = {}
    for record in sorted(records, key=lambda record: (record.job_num is None, record.job_num or 0)):
        for override in record.metrics.get("overrides") or []:
            key, _, value = str(override).partition("=")
            key = key.lstrip("+~")
            if key.startswith("hydra.") or not key:
                continue
            if value not in values.setdefault(key, []):
                values[key].append(value)
    params = {metric_key(*key.split(".")): ",".join(found)[:6000] for key, found in values.items()}
    params["study"] = study
    params[SWEPT_PARAM] = ",".join(key for key, found in values.items() if len(found) > 1)
    return params


def sweep_metrics(records: Sequence[RunRecord]) -> dict[str, float]:
    """A sweep run's metrics: the headline ``alpha_abs_mean.<data>.<basis>.<solver>`` as the geometric mean over
    the sweep's runs (as ``workbench collect`` summarises a cell; the arithmetic mean where a value is not
    positive), and ``runs``, the number of complete runs."""
    gathered: dict[str, list[float]] = {}
    for record in records:
        for row in record.table.to_dict("records"):
            value = float(row[HEADLINE])
            if math.isfinite(value):
                gathered.setdefault(metric_key(HEADLINE, row["data"], row["basis"], row["solver"]), []).append(value)
    metrics = {}
    for key, found in gathered.items():
        metrics[key] = math.exp(sum(map(math.log, found)) / len(found)) if min(found) > 0 else sum(found) / len(found)
    metrics["runs"] = float(len(records))
    return metrics


def finish_sweep_run(
    client, run_id: str, study: str, records: Sequence[RunRecord], end_ms: int | None, wall_seconds: float | None = None
) -> None:
    """Log a sweep run's params (those it does not hold yet: MLflow keeps a param's first value) and metrics, and
    finish it at ``end_ms`` (now when None).

    Parameters
    ----------
    wall_seconds : float, optional
        The time the command running the sweep took, logged as ``time.sweep``.
    """
    from mlflow.entities import Metric, Param

    held = client.get_run(run_id).data.params
    params = [Param(key, value) for key, value in sweep_params(study, records).items() if key not in held]
    for batch in chunks(params, BATCH_LIMITS["params"]):
        client.log_batch(run_id, params=batch)
    now = int(time.time() * 1000)
    metrics = dict(sweep_metrics(records))
    if wall_seconds is not None:
        metrics[metric_key("time", "sweep")] = float(wall_seconds)
    for batch in chunks([Metric(key, value, now, 0) for key, value in metrics.items()], BATCH_LIMITS["metrics"]):
        client.log_batch(run_id, metrics=batch)
    client.set_terminated(run_id, status="FINISHED", end_time=end_ms)


# ---------------------------------------------------------------------------------------------------------------
# Logging
# ---------------------------------------------------------------------------------------------------------------


def experiment_id(client, study: str, artifact_root: str | None) -> str:
    """The id of the study's experiment, created if new (its artifacts in ``<artifact_root>/<study>``, or where
    the store puts them when ``artifact_root`` is None)."""
    from mlflow.exceptions import MlflowException

    experiment = client.get_experiment_by_name(study)
    if experiment is not None:
        return experiment.experiment_id
    try:
        return client.create_experiment(
            study, artifact_location=None if artifact_root is None else f"{artifact_root}/{study}"
        )
    except MlflowException:  # another process created it meanwhile
        experiment = client.get_experiment_by_name(study)
        if experiment is None:
            raise
        return experiment.experiment_id


def quoted(value: str) -> str | None:
    """``value`` quoted for an MLflow search filter, or None when it holds both kinds of quote."""
    for quote in ("'", '"'):
        if quote not in value:
            return f"{quote}{value}{quote}"
    return None


def find_runs(client, experiment: str, **tags: str) -> list:
    """The active runs of an experiment whose tags have these values."""
    from mlflow.entities import ViewType

    terms = [f"tags.`{key}` = {quoted(value)}" for key, value in tags.items() if quoted(value)]
    runs, token = [], None
    while True:
        page = client.search_runs(
            [experiment],
            filter_string=" and ".join(terms),
            run_view_type=ViewType.ACTIVE_ONLY,
            max_results=1000,
            page_token=token,
        )
        runs.extend(run for run in page if all(run.data.tags.get(key) == value for key, value in tags.items()))
        token = page.token
        if not token:
            return runs


def sweep_run(
    client,
    experiment: str,
    folder: Path,
    study: str,
    runs: Sequence,
    *,
    logged_by: str,
    start_ms: int | None = None,
    version: Mapping[str, str] | None = None,
) -> tuple[str, bool]:
    """A sweep's parent run: its id, created (running) if the store has none, and whether this caller is to finish
    it (it made it, or an interrupted import made it and left it running).

    Parameters
    ----------
    logged_by : str
        ``sweep`` (the sweep's callback, which finishes the run when the sweep ends) or ``import``.
    """
    found = sorted(
        (run for run in runs if run.data.tags.get(KIND_TAG) == SWEEP_KIND), key=lambda run: run.info.start_time
    )
    if found:
        run = found[0]
        return run.info.run_id, run.info.status != "FINISHED" and run.data.tags.get(LOGGED_BY_TAG) == "import"
    folder = Path(folder).resolve()
    tags = {
        KIND_TAG: SWEEP_KIND,
        "study": study,
        SWEEP_TAG: str(folder),
        "mlflow.runName": sweep_name(folder),
        LOGGED_BY_TAG: logged_by,
        **(version or {}),
    }
    run = client.create_run(experiment, start_time=start_ms or int(time.time() * 1000), tags=tags)
    return run.info.run_id, True


def chunks(items: list, size: int) -> Iterator[list]:
    for start in range(0, len(items), size):
        yield items[start : start + size]


def log_folders(client, run_id: str, folder: Path, names: Sequence[str], again: bool = False) -> None:
    """Log the sub-folders of ``folder`` named ``names`` that exist as the run's artifacts of the same names: only
    those the run does not hold yet, or all of them again (``again``)."""
    present = [name for name in names if (Path(folder) / name).is_dir()]
    held = set() if again or not present else {item.path for item in client.list_artifacts(run_id)}
    for name in present:
        if name not in held:
            client.log_artifacts(run_id, str(Path(folder) / name), artifact_path=name)


def log_record(client, experiment: str, record: RunRecord, previous: Sequence, parent_id: str | None) -> str:
    """Log one record as a finished MLflow run, or finish the run an interrupted import left.

    Parameters
    ----------
    previous : sequence of mlflow.entities.Run
        The store's runs of this record (same folder and config hash).
    parent_id : str or None
        The sweep's run.

    Returns
    -------
    str
        ``added``, ``resumed`` (an unfinished run of the record completed) or ``skipped`` (already logged).
    """
    from mlflow.entities import Metric, Param

    finished = [run for run in previous if run.info.status == "FINISHED"]
    if finished:  # a report built since it was logged: its figures go in too
        log_folders(client, finished[0].info.run_id, record.folder, [REPORT_FOLDER])
        return "skipped"
    start = started_ms(record)
    if previous:
        run, outcome = previous[0], "resumed"
        for extra in previous[1:]:
            client.delete_run(extra.info.run_id)
    else:
        run, outcome = client.create_run(experiment, start_time=start, tags=record_tags(record, parent_id)), "added"
    run_id, logged = run.info.run_id, set(run.data.metrics)
    metrics = [Metric(key, value, start, 0) for key, value in record_metrics(record).items() if key not in logged]
    for batch in chunks(metrics, BATCH_LIMITS["metrics"]):
        client.log_batch(run_id, metrics=batch)
    # a param logged again with the same value is accepted, so an interrupted run is completed the same way
    for batch in chunks([Param(key, value) for key, value in record_params(record).items()], BATCH_LIMITS["params"]):
        client.log_batch(run_id, params=batch)
    for name in ARTIFACT_FILES:
        if (record.folder / name).is_file():
            client.log_artifact(run_id, str(record.folder / name))
    log_folders(client, run_id, record.folder, [REPORT_FOLDER], again=outcome == "added")
    client.set_terminated(run_id, status="FINISHED", end_time=start + int(1000 * float(record.timings.get("total", 0))))
    return outcome


def log_records(
    paths: Iterable[Path],
    *,
    store: Path | None = None,
    tracking_uri: str | None = None,
    sweep_run_id: str | None = None,
    finish_sweeps: bool = False,
    artifact_location: str | None = None,
    wall_seconds: float | None = None,
) -> dict:
    """Log every complete record under ``paths`` that the store does not hold yet, nested in its sweep's run.

    Parameters
    ----------
    paths : iterable of pathlib.Path
        Run folders, sweep folders or folders above them.
    store : pathlib.Path, optional
        Folder of the embedded SQLite store.
    tracking_uri : str, optional
        Any MLflow tracking URI (a server, another database). Without it or ``store``: ``$MLFLOW_TRACKING_URI``,
        else the embedded store ``<paths.output_root of the records>/.mlflow``.
    sweep_run_id : str, optional
        The parent run of the records' sweep, when the caller knows it (a sweep's callback).
    finish_sweeps : bool
        Mark the sweeps' runs finished now (the end of a sweep); otherwise only sweep runs made here are, at the
        end of their last record. A sweep run is given its params and summary metrics as it is finished
        (:func:`finish_sweep_run`).
    artifact_location : str, optional
        Where a new experiment keeps its artifacts (:func:`resolve_store`).
    wall_seconds : float, optional
        The time the command running the sweep took (the sweep's callback), logged as the sweep run's
        ``time.sweep``.

    Returns
    -------
    dict
        ``store`` (:class:`Store`), ``experiments`` (ids), ``sweeps`` (their run ids), numbers of records
        ``added``, ``resumed`` and ``skipped``, and ``incomplete`` (run folders without a completion marker).
    """
    complete, incomplete = find_records([Path(path) for path in paths])
    if not complete:
        raise WorkbenchError(f"no complete run record under {', '.join(map(str, paths))}")
    records = [load_record(folder) for folder in complete]
    target = resolve_store(
        store=store,
        tracking_uri=tracking_uri,
        artifact_location=artifact_location,
        output_root=records[0].settings.paths.output_root,
    )
    groups: dict[tuple, list[RunRecord]] = {}
    for record in records:
        groups.setdefault((record.study, sweep_folder(record) or record.folder.resolve().parent), []).append(record)
    counts = {"added": 0, "resumed": 0, "skipped": 0}
    experiments, sweeps = {}, {}
    with open_store(target) as client:
        for (study, folder), group in groups.items():
            if study not in experiments:
                experiments[study] = experiment_id(client, study, target.artifact_root)
            experiment = experiments[study]
            runs = find_runs(client, experiment, **{SWEEP_TAG: str(folder)})
            parent, finish = None, False
            if sweep_folder(group[0]) is not None:
                parent, finish = (
                    (sweep_run_id, False)
                    if sweep_run_id
                    else sweep_run(
                        client,
                        experiment,
                        folder,
                        study,
                        runs,
                        logged_by="sweep" if finish_sweeps else "import",
                        start_ms=min(map(started_ms, group)),
                        version=version_tags(group[0]),
                    )
                )
                sweeps[str(folder)] = parent
            by_record = {}
            for run in runs:
                by_record.setdefault((run.data.tags.get(RECORD_TAG), run.data.tags.get("config_hash")), []).append(run)
            for record in group:
                key = (str(record.folder.resolve()), str(record.config_hash))
                counts[log_record(client, experiment, record, by_record.get(key, []), parent)] += 1
            if parent is not None:
                # the collected tables change as a sweep is resumed: the end of a sweep logs them again
                log_folders(client, parent, folder, [COLLECTED_FOLDER, REPORT_FOLDER], again=finish or finish_sweeps)
                if finish or finish_sweeps:  # the sweep's end (now), or the end of its last record imported
                    finish_sweep_run(
                        client,
                        parent,
                        study,
                        group,
                        None if finish_sweeps else max(map(finished_ms, group)),
                        wall_seconds,
                    )
    return {
        "store": target,
        "tracking_uri": target.tracking_uri,
        "experiments": list(experiments.values()),
        "sweeps": sweeps,
        **counts,
        "incomplete": incomplete,
    }


def summary_line(result: Mapping) -> str:
    resumed = f", {result['resumed']} left unfinished by an interrupted import completed" if result["resumed"] else ""
    note = f", {len(result['incomplete'])} incomplete run folders left out" if result["incomplete"] else ""
    return (
        f"mlflow: {result['added']} runs added, {result['skipped']} already in the store{resumed}{note}; "
        f"{result['store'].browse_hint(result['experiments'])}"
    )


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="workbench mlflow",
        description="Log finished run records into an MLflow tracking store (each record once, nested in its "
        "sweep's run).",
    )
    parser.add_argument("paths", nargs="+", type=Path, help="run folders, sweep folders or folders above them")
    target = parser.add_mutually_exclusive_group()
    target.add_argument(
        "--store",
        type=Path,
        default=None,
        help="folder of the embedded SQLite store (default: <paths.output_root>/.mlflow of the records)",
    )
    target.add_argument(
        "--tracking-uri",
        default=None,
        help="an MLflow tracking URI instead, e.g. a server http://host:5000 (default: "
        "$MLFLOW_TRACKING_URI, else the embedded store)",
    )
    parser.add_argument(
        "--artifact-location",
        default=None,
        help="where a new experiment keeps the runs' files (a folder or URI; default: beside the "
        "store's database, or where the server puts them)",
    )
    return parser.parse_args(list(argv))


def main(argv: Sequence[str]) -> int:
    """``workbench mlflow <folder>... [--store DIR | --tracking-uri URI] [--artifact-location DIR]``."""
    args = parse_args(argv)
    print(
        summary_line(
            log_records(
                args.paths, store=args.store, tracking_uri=args.tracking_uri, artifact_location=args.artifact_location
            )
        )
    )
    return 0


# ---------------------------------------------------------------------------------------------------------------
# The sweep's callback
# ---------------------------------------------------------------------------------------------------------------

try:
    from hydra.experimental.callback import Callback
except ImportError:  # pragma: no cover - Hydra is a dependency; this keeps the module importable without it
    Callback = object


class MlflowSweep(Callback):
    """Hydra callback: log a sweep's runs into an MLflow store while it runs.

    Every study carries it off (``hydra.callbacks.mlflow.enabled: false``); a study config or the command line
    turns it on (``hydra.callbacks.mlflow.enabled=true``). ``tracking_uri`` (default ``$MLFLOW_TRACKING_URI``) or
    ``store`` choose the store as the ``workbench mlflow`` options do. When the sweep starts, its parent run is
    made (or found, when a sweep is resumed); each job logs its record as it ends, wherever it runs (a cluster
    node too); when the sweep ends, whatever a job could not log is logged and the parent run is finished. A store
    that cannot be reached stops no run: one line says so, and ``workbench mlflow <sweep folder>`` logs later.
    """

    def __init__(
        self,
        enabled: bool = False,
        store: str | None = None,
        tracking_uri: str | None = None,
        artifact_location: str | None = None,
    ):
        self.enabled, self.store, self.tracking_uri = bool(enabled), store, tracking_uri
        self.artifact_location = artifact_location
        self.started_ms = process_start_ms()  # the sweep's run starts with the command
        self.sweep_run_id = None
        self.jobs_log = True  # off when the store failed as the sweep started: the end of the sweep tries again

    def target(self, config) -> Store:
        return resolve_store(
            store=None if self.store is None else Path(self.store),
            tracking_uri=self.tracking_uri,
            output_root=config.paths.output_root,
            artifact_location=self.artifact_location,
        )

    def log(self, folder: Path, **options) -> dict:
        """:func:`log_records` into this callback's store."""
        return log_records(
            [folder],
            store=None if self.store is None else Path(self.store),
            tracking_uri=self.tracking_uri,
            sweep_run_id=self.sweep_run_id,
            artifact_location=self.artifact_location,
            **options,
        )

    def on_multirun_start(self, config, **kwargs) -> None:
        if not self.enabled:
            return
        sweep_dir, study = Path(str(config.hydra.sweep.dir)), str(config.study)
        try:
            target = self.target(config)
            with open_store(target) as client:
                experiment = experiment_id(client, study, target.artifact_root)
                runs = find_runs(client, experiment, **{SWEEP_TAG: str(sweep_dir.resolve())})
                resumed = any(run.data.tags.get(KIND_TAG) == SWEEP_KIND for run in runs)
                self.sweep_run_id, _ = sweep_run(
                    client, experiment, sweep_dir, study, runs, logged_by="sweep", start_ms=self.started_ms
                )
                if resumed:  # running again until this sweep ends
                    client.update_run(self.sweep_run_id, status="RUNNING")
        except (WorkbenchError, OSError) as error:
            self.jobs_log = False
            log.error(
                f"workbench mlflow: error: {error} (the sweep goes on; its end tries again, or log it later "
                f"with 'workbench mlflow {sweep_dir}')"
            )
            return
        log.info(
            f"mlflow: sweep run {sweep_name(sweep_dir)} ({'resumed' if resumed else 'new'}) in experiment "
            f"{study} of {target.tracking_uri}; each run is logged as its job ends"
        )

    def on_job_end(self, config, job_return=None, **kwargs) -> None:
        if not self.enabled or not self.jobs_log:
            return
        folder = Path(str(config.hydra.runtime.output_dir))
        if not is_complete(folder):
            return
        try:
            result = self.log(folder)
        except (WorkbenchError, OSError) as error:
            log.error(
                f"workbench mlflow: error: {error} (record kept; the end of the sweep or 'workbench mlflow "
                f"{folder}' logs it)"
            )
            return
        if result["added"] or result["resumed"]:
            log.info(f"mlflow: logged {folder.name}")

    def on_multirun_end(self, config, **kwargs) -> None:
        if not self.enabled:
            return
        sweep_dir = Path(str(config.hydra.sweep.dir))
        try:
            result = self.log(
                sweep_dir, finish_sweeps=True, wall_seconds=round(time.time() - self.started_ms / 1000, 3)
            )
        except (WorkbenchError, OSError) as error:  # the records are complete; say why the store is not
            log.error(f"workbench mlflow: error: {error} (records kept; rerun 'workbench mlflow {sweep_dir}')")
            return
        total = result["added"] + result["resumed"] + result["skipped"]
        log.info(
            f"mlflow: sweep {sweep_name(sweep_dir)}: {total} runs in the store ({result['added']} added at "
            f"the end of the sweep); {result['store'].browse_hint(result['experiments'])}"
        )
