"""Run folders and resumable sweeps: a stable identity for every run, skip what is complete, never overwrite a
record, never touch a file the workbench did not write.

A run folder belongs to the workbench. A run writes only into a folder that is new, empty, or holds a record of
its own; any other folder is refused before anything is written into it (:func:`check_run_dir`), and the current
directory (``hydra.run.dir=`` or ``.``) is never a run folder. A study's sweep writes each run into
``<sweep dir>/<run id>``, the run id made from the run's overrides (not a job number or a time), so re-running the
same sweep finds the same folders. A folder whose ``done`` marker exists holds a complete record: the run is
skipped if its config hash matches and refused if it does not (the record is never overwritten). A folder without
``done`` holding only what a killed run wrote (its lock file and record files) is cleared of its record files and
run again; clearing removes only record files, never anything else.

A run folder belongs to one live process at a time: the run holds an advisory lock (``fcntl.flock``) on
``<folder>/.lock`` from before it decides anything about the folder until it ends. The operating system releases
the lock when the process ends, however it ends, so a killed run never leaves a folder locked. A second process
finding the folder locked skips it (sweeps) or stops with one line (plain runs); it never clears the files of a
live run. A run that ends with a complete record removes the lock file (:func:`release_run_dir`): a complete record
is never written again, so it needs no lock, and only a killed run's folder keeps one, marking its files as a run's.
"""

from __future__ import annotations

import json
import logging
import os
import sys
from contextlib import contextmanager
from pathlib import Path

import yaml

from workbench.core.errors import WorkbenchError, exit_on_error
from workbench.core.files import check_folder_setting, lock_file, shown_names, unlock_file
from workbench.record.record import CONFIG_FILE, DONE, METRICS_FILE, config_hash, is_record_file, record_state


def recorded_config_hash(folder: Path) -> str | None:
    """The config hash of the settings a complete record was made with, or None when its ``metrics.json`` is
    unreadable or names no hash. Made from its ``config.yaml`` (:func:`config_hash`), so a record whose
    ``metrics.json`` holds a hash of the YAML's text (written before the hash was of the settings) still matches
    a run of the same settings."""
    try:
        stored = json.loads((Path(folder) / METRICS_FILE).read_text())["config_hash"]
        return config_hash((Path(folder) / CONFIG_FILE).read_text()) if stored else None
    except (OSError, ValueError, KeyError, TypeError, yaml.YAMLError):
        return None


def clear_partial(folder: Path) -> list[str]:
    """Remove the record files a killed run left in its folder (and their temporary files), so none of them mixes
    into the new record; refuses a complete record. Nothing else is removed: the lock file, the job log and any
    file that is not a record file stay.

    Returns
    -------
    list of str
        Names of the removed files.
    """
    folder = Path(folder)
    if record_state(folder) == "complete":
        raise WorkbenchError(f"{folder} holds a complete record ('{DONE}' exists); a record is never cleared")
    removed = []
    for path in sorted(folder.iterdir()):
        if is_record_file(path.name) and (path.is_file() or path.is_symlink()):
            path.unlink()
            removed.append(path.name)
    return removed


def prepare_run_dir(folder: Path, config_hash: str) -> bool:
    """Decide whether a run goes ahead in ``folder``.

    Parameters
    ----------
    folder : pathlib.Path
        The run's record folder.
    config_hash : str
        Hash of the run's resolved config (:func:`workbench.record.record.config_hash`).

    Returns
    -------
    bool
        False when a complete record of the same config is there (skip the run); True when the run should go
        ahead (the folder is absent, or partial and now cleared).

    Raises
    ------
    WorkbenchError
        When a complete record of a different config is there: it is never overwritten.
    """
    state = record_state(folder)
    if state == "complete":
        recorded = recorded_config_hash(folder)
        if recorded is None:
            raise WorkbenchError(
                f"{folder} holds a complete record ('{DONE}' exists) whose metrics.json or config.yaml is missing "
                "or unreadable, or whose metrics.json has no config_hash; records are never overwritten: move that "
                "record away or use another sweep folder (hydra.sweep.dir=...)"
            )
        if recorded != config_hash:
            raise WorkbenchError(
                f"{folder} holds a complete record of another config (config hash {recorded}, this run "
                f"{config_hash}); records are never overwritten: use another sweep folder "
                "(hydra.sweep.dir=...) or move that record away"
            )
        return False
    if state == "partial":
        clear_partial(folder)
    return True


LOCK_FILE = ".lock"
"""The lock file of a run folder, created before anything else a run writes there; it marks the folder of a run
that did not end as a run's. Removed only once the record is complete (:func:`release_run_dir`): a process that
opened the old file meanwhile then only finds the complete record, which it skips or refuses."""
LOG_FILE = "workbench.log"
"""The job log Hydra writes into a run folder (``hydra.job.name`` is ``workbench``)."""
HYDRA_FOLDER = ".hydra"
"""Hydra's copy of the config, which runs of earlier versions kept in their folder."""


class RunLog(logging.FileHandler):
    """The job log of a run folder (``workbench.log``, ``conf/hydra/job_logging/workbench.yaml``). It is written
    after the record is complete; a write that fails (a full disk) is one warning line naming the file, once,
    instead of the logging module's traceback of every message."""

    reported = False

    def emit(self, record) -> None:
        try:
            super().emit(record)
        except OSError:  # opening the file (on the first message) is outside the handler's own error handling
            self.handleError(record)

    def handleError(self, record) -> None:
        if not self.reported:
            self.reported = True
            error = sys.exc_info()[1]
            reason = getattr(error, "strerror", None) or error
            print(
                f"workbench: warning: cannot write {self.baseFilename} ({reason}); the record is complete, only "
                "the copy of what the run printed is missing",
                file=sys.stderr,
            )


def run_entry(name: str) -> bool:
    """Whether a name in a folder is one a workbench run writes there: a record file, the lock, the job log."""
    return is_record_file(name) or name in (LOCK_FILE, LOG_FILE, HYDRA_FOLDER)


def check_run_dir(folder: Path, setting: str = "hydra.run.dir") -> frozenset:
    """Refuse a run folder the workbench does not own, before anything is written into it.

    A run writes into a folder that does not exist yet, an empty one, one holding a complete record (skipped or
    refused by :func:`prepare_run_dir`), or one holding only what a run writes (its lock file, record files, job
    log: a killed run's, resumed). Any other folder holds someone's files, and nothing in it is touched.

    Parameters
    ----------
    folder : pathlib.Path
    setting : str
        The setting that named the folder, for the message.

    Returns
    -------
    frozenset of str
        The names the folder held (empty for a new folder): what a failed run must leave in place.

    Raises
    ------
    WorkbenchError
    """
    folder = check_folder_setting(folder, setting)
    if not os.path.lexists(folder):
        return frozenset()
    if not folder.is_dir():
        raise WorkbenchError(f"{setting}={folder} is a file, not a folder; name a new or empty folder")
    names = frozenset(os.listdir(folder))
    if not names or DONE in names:
        return names
    foreign = sorted(name for name in names if not run_entry(name))
    if LOCK_FILE in names and not foreign:
        return names
    shown = shown_names(foreign or names)
    if LOCK_FILE in names:
        what = f"holds a killed run's files and others no run writes ({shown})"
    elif foreign:
        what = f"is not empty and holds no run record ({shown})"
    else:
        what = (
            f"holds files named as a run record's ({shown}) but no run's lock file ({LOCK_FILE}), so no run wrote them"
        )
    raise WorkbenchError(
        f"{folder} {what}; a run writes only into a new or empty folder or its own record, and "
        f"touches nothing else: name another folder ({setting}=...)"
    )


class FolderBusy(WorkbenchError):
    """Another live process holds the run folder's lock."""


def lock_run_dir(folder: Path) -> int:
    """Take the run folder's lock without waiting, for the rest of the process or until :func:`unlock_run_dir`.

    Parameters
    ----------
    folder : pathlib.Path
        The run folder (created if absent).

    Returns
    -------
    int
        The lock file's descriptor.

    Raises
    ------
    FolderBusy
        When another live process holds the lock.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    handle = lock_file(folder / LOCK_FILE, wait=False)
    if handle is None:
        raise FolderBusy(
            f"{folder} is in use by another workbench process (its lock file {LOCK_FILE} is "
            "held); wait for it to end or write this run elsewhere"
        )
    return handle


def unlock_run_dir(handle: int) -> None:
    """Release a lock taken by :func:`lock_run_dir`."""
    unlock_file(handle)


def release_run_dir(folder: Path, handle: int) -> None:
    """Release a lock taken by :func:`lock_run_dir`; a folder holding a complete record keeps no lock file.

    Parameters
    ----------
    folder : pathlib.Path
        The run folder locked.
    handle : int
        The lock file's descriptor (:func:`lock_run_dir`).
    """
    try:
        if record_state(folder) == "complete":
            (Path(folder) / LOCK_FILE).unlink(missing_ok=True)
    finally:
        unlock_file(handle)


def discard_failed_run(folder: Path, found: frozenset = frozenset(), created: bool = False) -> bool:
    """After a plain run failed or was interrupted: remove what it wrote (the run files that were not in the
    folder when it started), and the folder itself when the run created it and it is left empty. A complete record
    is never touched, nor any file the run did not write. Call it only while holding the folder's lock.

    Parameters
    ----------
    folder : pathlib.Path
    found : frozenset of str
        The names the folder held before the run (:func:`check_run_dir`).
    created : bool
        Whether the run created the folder.

    Returns
    -------
    bool
        Whether the folder was removed.
    """
    folder = Path(folder)
    if not folder.is_dir() or record_state(folder) == "complete":
        return False
    for path in folder.iterdir():
        if path.name not in found and run_entry(path.name) and (path.is_file() or path.is_symlink()):
            path.unlink()
    if not created or any(folder.iterdir()):
        return False
    folder.rmdir()
    return True


_NEW_RUN_DIRS: dict[str, str] = {}
"""Run folders that did not exist when this process started its run (:func:`note_new_run_dir`, before Hydra or
the run creates them) -> the outermost of the folder and its parents that did not exist either, so that a failed
run removes only folders it created, its parents (``outputs/paper/``) included."""


def note_new_run_dir(folder: Path) -> None:
    """Note ``folder`` as made by this process's run if it does not exist yet, with its missing parents."""
    folder = os.path.abspath(Path(str(folder)).expanduser())
    if os.path.lexists(folder):
        _NEW_RUN_DIRS.pop(folder, None)  # made by an earlier run of this process, not by this one
        return
    outermost = folder
    while not os.path.lexists(os.path.dirname(outermost)) and os.path.dirname(outermost) != outermost:
        outermost = os.path.dirname(outermost)
    _NEW_RUN_DIRS[folder] = outermost


def created_by_this_run(folder: Path) -> bool:
    """Whether this process's run created ``folder`` (:func:`note_new_run_dir`)."""
    return os.path.abspath(folder) in _NEW_RUN_DIRS


def remove_made_folders(folder: Path) -> None:
    """After a plain run failed (and :func:`discard_failed_run` removed its files): remove ``folder`` and the parents
    this run made for it (:func:`note_new_run_dir`), innermost first, each only while it is empty (another run may
    be writing beside it). Nothing when the run did not make ``folder``."""
    path = os.path.abspath(folder)
    outermost = _NEW_RUN_DIRS.get(path)
    if outermost is None:
        return
    while True:
        try:
            os.rmdir(path)
        except FileNotFoundError:  # removed already (discard_failed_run)
            pass
        except OSError:  # not empty: what is left is not only this run's
            return
        if path == outermost:
            return
        path = os.path.dirname(path)


try:
    from hydra.experimental.callback import Callback
except ImportError:  # pragma: no cover - Hydra is a dependency; this keeps the module importable without it
    Callback = object


class RunFolders(Callback):
    """Hydra callback: check the config and the run or sweep folder before Hydra creates or writes anything.

    Hydra makes the run folder (and its parents) before the run starts; this looks first, so a study name leading
    out of the output root, a bad setting, the current directory or a folder holding someone's files is refused
    in one line with nothing written. Each run of a sweep checks its own folder and config when it starts.
    Hydra turns an exception in a callback into a warning and goes on, so a refusal ends the process here.
    """

    def on_run_start(self, config, **kwargs) -> None:
        from workbench.settings.schema import check_hydra_settings, check_study_config

        with _refusal_ends_the_process():
            check_hydra_settings(config.hydra)
            check_study_config(config, as_typed(config.hydra.overrides.task), refuse_ineffective=True)
            folder = config.hydra.run.dir
            check_run_dir(folder)
            note_new_run_dir(folder)

    def on_multirun_start(self, config, **kwargs) -> None:
        from workbench.settings.schema import check_hydra_settings, check_study_config

        with _refusal_ends_the_process():
            check_hydra_settings(config.hydra)
            check_study_config(config, as_typed(config.hydra.overrides.task), refuse_ineffective=False)
            check_folder_setting(config.hydra.sweep.dir, "hydra.sweep.dir")
        check_sweep_values(config)


def check_sweep_values(config) -> None:
    """Before a sweep starts, compose and check the config of each of its runs: a value Hydra cannot parse or
    compose and a value that breaks a setting's rule alike refuse the whole sweep in one line naming the run's
    values, before any run starts or any folder is made. Only Hydra's basic sweeper (the workbench's) is expanded
    here; another sweeper chooses its values as it goes."""
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from workbench.settings.config import config_error_line
    from workbench.settings.typed import study_settings

    if not str(config.hydra.sweeper.get("_target_", "")).endswith(".BasicSweeper"):
        return
    params = config.hydra.sweeper.get("params") or {}
    arguments = [f"{key}={value}" for key, value in params.items()] + as_typed(config.hydra.overrides.task)
    loader = GlobalHydra.instance().config_loader()
    if str(config.hydra.launcher.get("_target_", "")).endswith(".BasicLauncher"):
        compose_each_run_once(loader, config)
    try:
        parsed = OverridesParser.create(config_loader=loader).parse_overrides(arguments)
        swept = {override.get_key_element() for override in parsed if override.is_sweep_override()}
        jobs = [job for batch in BasicSweeper.split_arguments(parsed, None) for job in batch]
    except Exception as error:  # noqa: BLE001 - Hydra's own refusal, as one line
        _refuse_sweep(config_error_line(error))
    for job in jobs:
        values = " ".join(override for override in job if override.split("=", 1)[0] in swept) or " ".join(job)
        try:
            study_settings(loader.load_sweep_config(master_config=config, sweep_overrides=list(job)), job)
        except Exception as error:  # noqa: BLE001 - one line for any refusal
            message = str(error) if isinstance(error, WorkbenchError) else config_error_line(error)
            _refuse_sweep(f"the sweep's run {values} is refused: {message}")


def compose_each_run_once(loader, master_config) -> None:
    """Let Hydra's config ``loader`` compose each run of this sweep once: the check above, Hydra's basic sweeper
    (which composes every run to validate the batch) and its basic launcher (which composes it again to run it) ask
    for the same config three times, and composing is most of a small run's time (0.26 s per run of the noise
    study). Each asks for the same overrides of the same sweep config and gets a copy of the first composition.
    Only for the basic launcher, which runs in this process: other launchers send the loader to other processes."""
    import copy

    compose = loader.load_sweep_config
    composed = {}

    def load_sweep_config(master_config, sweep_overrides):
        key = (id(master_config), tuple(sweep_overrides))
        if key not in composed:  # the master config is kept with it, so its id is not reused by another
            composed[key] = (master_config, compose(master_config=master_config, sweep_overrides=list(sweep_overrides)))
        return copy.deepcopy(composed[key][1])

    loader.load_sweep_config = load_sweep_config


def _refuse_sweep(message: str) -> None:
    """End the process with a sweep's refusal (exit 2): no run of it started."""
    exit_on_error(
        "workbench", WorkbenchError(f"{message}; no run of the sweep started: fix the value and run it again")
    )


def as_typed(overrides) -> list[str]:
    """Hydra's list of overrides as typed (``key=${...}`` kept as text: iterating the config would resolve it)."""
    from omegaconf import OmegaConf

    return [str(override) for override in OmegaConf.to_container(overrides, resolve=False)]


@contextmanager
def _refusal_ends_the_process():
    """A refusal (any error) ends the process with the command line's one line (exit 2), not Hydra's warning."""
    try:
        yield
    except Exception as error:  # noqa: BLE001 - Hydra would only warn about it
        exit_on_error("workbench", error if isinstance(error, WorkbenchError) else WorkbenchError(str(error)))
