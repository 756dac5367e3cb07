"""Which MLflow store records are logged into, and opening it (extra: mlflow): a team's server (``--tracking-uri`` or
``MLFLOW_TRACKING_URI``) or, by default, an embedded SQLite database with its artifact folder in
``<paths.output_root>/.mlflow/`` (:func:`resolve_store`), set up in a temporary file so that a failure leaves none
(:func:`create_database`), and ``mlflow`` imported with its telemetry off and its INFO lines quiet.
What a record becomes in the store, and the ``workbench mlflow`` command, are in :mod:`workbench.record.mlflow`."""

from __future__ import annotations

import glob
import logging
import os
import re
import shlex
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence

from workbench.core.errors import WorkbenchError
from workbench.core.files import TEMPORARY_SUFFIX, disk_full, free_bytes, lock_file, unlock_file
from workbench.core.interrupt import interrupts_deferred
from workbench.settings.config import REPO_ROOT

STORE_FOLDER = ".mlflow"
"""Hidden, so that the copies of records among its artifacts are never taken for runs by collect, report or this."""


DATABASE_FILE = "mlflow.db"


ARTIFACTS_FOLDER = "artifacts"


KEEP_OUT = ("workbench", "conf", "studies", "tests", "reports", "benchmarks")
"""Folders of the source tree a store must never be written into."""


def import_mlflow():
    """The ``mlflow`` module (its usage telemetry off, its own INFO lines quiet: :func:`quiet_mlflow`), or a
    one-line error saying how to install it."""
    # MLflow's usage telemetry writes an id into the user's configuration folder and sends events out: a run writes
    # only into the folders its user named (MLFLOW_DISABLE_TELEMETRY=false in the environment turns it back on)
    os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")
    try:
        import mlflow
    except ImportError as error:
        from workbench.core.extras import install_hint

        raise WorkbenchError(f"the MLflow store needs the mlflow extra: {install_hint('mlflow')} ({error})") from None
    quiet_mlflow()
    return mlflow


QUIET_LOGGERS = ("mlflow", "alembic")
"""MLflow's loggers (its own and its database migrations'), whose INFO lines (``Creating initial MLflow database
tables...``) stay off the console."""


def quiet_mlflow() -> None:
    """Keep MLflow's own INFO lines off the console: its loggers at WARNING, unless ``MLFLOW_LOGGING_LEVEL`` is set
    (``--verbose`` sets it to INFO; a level the user set is kept)."""
    if os.environ.get("MLFLOW_LOGGING_LEVEL"):
        return
    for name in QUIET_LOGGERS:
        logger = logging.getLogger(name)
        if logger.getEffectiveLevel() < logging.WARNING:
            logger.setLevel(logging.WARNING)
    # it logs a database error with its whole traceback before raising it, which the command reports in one line
    logging.getLogger("mlflow.store.db.utils").setLevel(logging.CRITICAL)


@dataclass(frozen=True)
class Store:
    """Where runs are logged.

    Attributes
    ----------
    tracking_uri : str
    artifact_root : str or None
        The embedded store's artifact folder (a file URI); None: the store decides (a server's own root).
    lock_file : pathlib.Path or None
        For a SQLite store: the file its writers lock in turn (the first of them also creates the tables).
    """

    tracking_uri: str
    artifact_root: str | None = None
    lock_file: Path | None = None

    def browse_hint(self, experiment_ids: Sequence[str] = ()) -> str:
        """How to look at the runs: the server's page, or the ``mlflow ui`` command of a database."""
        uri = self.tracking_uri
        if uri.startswith(("http://", "https://")):
            page = f"/#/experiments/{experiment_ids[0]}" if len(experiment_ids) == 1 else ""
            return f"browse: {uri.rstrip('/')}{page}"
        if uri.startswith("databricks"):
            return "browse in your Databricks workspace"
        return f"browse with: mlflow ui --backend-store-uri {shlex.quote(uri)}"


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
            raise WorkbenchError(
                f"MLflow store {store} is inside the source tree ({REPO_ROOT / name}); "
                "put it under the output root (--store)"
            )
    return f"sqlite:///{store / DATABASE_FILE}", (store / ARTIFACTS_FOLDER).as_uri()


def resolve_store(
    *,
    store: Path | None = None,
    tracking_uri: str | None = None,
    output_root: Path | str = "outputs",
    artifact_location: str | None = None,
) -> Store:
    """The store to log into: ``tracking_uri`` if given, else the embedded store in ``store`` if given, else
    ``$MLFLOW_TRACKING_URI`` if set, else the embedded store of ``output_root``.

    A new experiment keeps its artifacts under the store named: the embedded store's ``artifacts/``; beside the
    database of a SQLite URI (``sqlite:///<folder>/t.db``: ``<folder>/t.artifacts``), never in MLflow's default
    ``./mlruns`` of the current folder; where a server puts them. ``artifact_location`` (a folder or URI) names
    another place.
    """
    tracking_uri = tracking_uri or (None if store is not None else os.environ.get("MLFLOW_TRACKING_URI") or None)
    chosen = None if not artifact_location else artifact_uri(artifact_location)
    if tracking_uri is None:
        folder = default_store(output_root) if store is None else Path(store)
        uri, artifacts = store_uris(folder)
        return Store(uri, chosen or artifacts, folder.expanduser().resolve() / f"{DATABASE_FILE}.lock")
    database_file = sqlite_database(tracking_uri)
    if database_file is None:
        return Store(tracking_uri, chosen, None)
    lock = database_file.with_name(database_file.name + ".lock")
    database_file = database_file.expanduser().resolve()
    beside = (
        database_file.parent / ARTIFACTS_FOLDER
        if database_file.name == DATABASE_FILE  # the embedded layout
        else database_file.with_suffix(ARTIFACTS_SUFFIX)
    )
    return Store(tracking_uri, chosen or beside.as_uri(), lock)


def sqlite_database(tracking_uri: str) -> Path | None:
    """The database file of a SQLite tracking URI (``sqlite:///<path>[?options]``), or None for any other store."""
    database = re.match(r"sqlite:///(.+)$", tracking_uri)
    return Path(database.group(1).split("?")[0]) if database else None


def create_database(target: Store) -> None:
    """Set up a new SQLite store whole or not at all: its schema is made in a temporary file beside the database
    (MLflow's migrations take seconds) and the file is moved into place once complete, so a kill leaves no store
    that every later command refuses (tables half made), only a temporary file, which the next set-up removes.
    Ctrl-C is held back until the schema is set up (:func:`workbench.core.interrupt.interrupts_deferred`), then
    acted on. Call it with the store's lock held; a store that exists, or any other kind of store, is left as it
    is."""
    from mlflow.store.tracking.sqlalchemy_store import SqlAlchemyStore

    database = sqlite_database(target.tracking_uri)
    if database is None or database.expanduser().exists():
        return
    database = Path(os.path.abspath(database.expanduser()))
    database.parent.mkdir(parents=True, exist_ok=True)
    for leftover in database.parent.glob(f".{glob.escape(database.name)}.*{TEMPORARY_SUFFIX}*"):  # a killed set-up's
        leftover.unlink(missing_ok=True)
    handle, temporary = tempfile.mkstemp(dir=database.parent, prefix=f".{database.name}.", suffix=TEMPORARY_SUFFIX)
    os.close(handle)
    options = target.tracking_uri.partition("?")[2]
    try:
        with interrupts_deferred():
            made = SqlAlchemyStore(f"sqlite:///{temporary}" + (f"?{options}" if options else ""), target.artifact_root)
            made.engine.dispose()  # every connection closed: the file is complete
            os.replace(temporary, database)
    finally:
        for leftover in ("", "-journal", "-wal", "-shm"):
            Path(temporary + leftover).unlink(missing_ok=True)


ARTIFACTS_SUFFIX = ".artifacts"
"""The artifact folder of a SQLite store named by a URI sits beside its database: ``t.db`` -> ``t.artifacts``
(``mlflow.db`` -> ``artifacts``, as in the embedded store)."""


def artifact_uri(location: str) -> str:
    """An artifact location as MLflow takes it: a URI as is, a folder as its absolute ``file://`` URI."""
    if re.match(r"^[A-Za-z][A-Za-z0-9+.\-]*://", str(location)):
        return str(location).rstrip("/")
    return Path(location).expanduser().resolve().as_uri()


@contextmanager
def open_store(target: Store) -> Iterator:
    """An ``MlflowClient`` of the store, with the store's lock held (SQLite); errors of the store as one line.

    Raises
    ------
    WorkbenchError
        When the store refuses a request or cannot be reached, naming the store.
    """
    mlflow = import_mlflow()
    from mlflow.exceptions import MlflowException

    check_reachable(target)
    handle = None
    if target.lock_file is not None:
        target.lock_file.parent.mkdir(parents=True, exist_ok=True)
        handle = lock_file(target.lock_file)
    try:
        create_database(target)
        yield mlflow.MlflowClient(tracking_uri=target.tracking_uri)
    except MlflowException as error:
        raise WorkbenchError(store_error(target, error)) from None
    except Exception as error:  # noqa: BLE001 - the database driver's own errors (a full disk, a locked file)
        if type(error).__module__.split(".")[0] not in ("sqlalchemy", "sqlite3", "alembic") and not disk_full(error):
            raise
        raise WorkbenchError(store_error(target, error)) from None
    finally:
        if handle is not None:
            unlock_file(handle)


def check_reachable(target: Store, timeout: float = 10.0) -> None:
    """Refuse a server that does not answer at all, at once (MLflow's client would retry each request for minutes).

    Raises
    ------
    WorkbenchError
    """
    import urllib.error
    import urllib.request

    if not target.tracking_uri.startswith(("http://", "https://")):
        return
    try:
        urllib.request.urlopen(f"{target.tracking_uri.rstrip('/')}/health", timeout=timeout).close()
    except urllib.error.HTTPError:
        return  # it answers (a proxy asking for credentials, say): the client's requests will tell
    except (OSError, ValueError) as error:
        reason = getattr(error, "reason", error)
        raise WorkbenchError(f"MLflow server {target.tracking_uri} cannot be reached ({reason})") from None


def store_error(target: Store, error: Exception) -> str:
    """One line for an error of the store: the first line of its message that says what happened (not SQLAlchemy's
    notes on how it happened), a full disk named as such with the space left."""
    lines = [" ".join(line.split()) for line in str(error).splitlines()]
    said = [
        line
        for line in lines
        if line and not line.startswith(("(raised as a result of", "[SQL", "[parameters", "(Background"))
    ]
    text = (said or lines or [""])[0] or type(error).__name__
    if disk_full(error):
        database = sqlite_database(target.tracking_uri)
        free = free_bytes(database.parent) if database is not None else None
        left = f", {free // 1024:,} KB left on {database.parent}" if free is not None else ""
        text = f"the disk is full ({text}{left}); free some space"
    return (
        f"MLflow store {target.tracking_uri}: {text[:300]}; records already logged are kept: rerun the same "
        "command to log the rest"
    )
