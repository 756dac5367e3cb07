"""Resumable sweeps: a stable identity for every run, skip what is complete, never overwrite a record.

A study's sweep writes each run into ``<sweep dir>/<run id>``, the run id made from the run's overrides (not a
job number or a time), so re-running the same sweep finds the same folders. A folder whose ``done`` marker
exists holds a complete record: the run is skipped if its config hash matches and refused if it does not (the
record is never overwritten). A folder without ``done`` is what a killed run left: it is cleared and run again.

A run folder belongs to one live process at a time: the run holds an advisory lock (``fcntl.flock``) on
``<folder>/.lock`` from before it decides anything about the folder until it ends. The operating system releases
the lock when the process ends, however it ends, so a killed run never leaves a folder locked. A second process
finding the folder locked skips it (sweeps) or stops with one line (plain runs); it never clears the files of a
live run.
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import re
import shutil
from pathlib import Path

from workbench.errors import WorkbenchError
from workbench.record import DONE, METRICS_FILE, record_state

RUN_ID_MAX = 120
"""Longest run folder name made from the overrides alone; longer ones are cut and get a hash."""


def run_dir_name(override_dirname: str) -> str:
    """The folder name of a run, from Hydra's ``hydra.job.override_dirname`` (its sorted overrides).

    Readable when it can be (``basis.coverage=0.99,dataset.seed=1``); characters unsafe in a file name are
    replaced, and a name that had to be changed or cut gets a hash of the full text so that two runs never
    share a folder.

    Parameters
    ----------
    override_dirname : str

    Returns
    -------
    str
    """
    text = str(override_dirname)
    if not text:
        return "default"
    safe = re.sub(r"[^A-Za-z0-9._=,+\-]", "_", text)
    if safe == text and len(text) <= RUN_ID_MAX:
        return text
    return f"{safe[:RUN_ID_MAX - 9]}-{hashlib.sha256(text.encode()).hexdigest()[:8]}"


def register_resolvers() -> None:
    """Register ``${run_id:...}`` with OmegaConf (studies name their run folders with it)."""
    from omegaconf import OmegaConf

    if not OmegaConf.has_resolver("run_id"):
        OmegaConf.register_new_resolver("run_id", run_dir_name)


def recorded_config_hash(folder: Path) -> str | None:
    """The config hash a complete record was made with (from its ``metrics.json``), or None if unreadable."""
    try:
        return json.loads((Path(folder) / METRICS_FILE).read_text())["config_hash"]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def clear_partial(folder: Path) -> list[str]:
    """Remove the files a killed run left in its folder, so none of them mixes into the new record; refuses a
    complete record. Sub-folders and ``*.log`` files are kept: Hydra creates its ``.hydra`` folder and opens the
    job's log before the run starts (the studies turn both off; a plain ``workbench`` run keeps them).

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
        if (path.is_file() or path.is_symlink()) and path.suffix != ".log" and path.name != LOCK_FILE:
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
        Hash of the run's resolved config (:func:`workbench.record.config_hash`).

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
                f"{folder} holds a complete record ('{DONE}' exists) whose metrics.json is missing, unreadable or "
                "has no config_hash; records are never overwritten: move that record away or use another sweep "
                "folder (hydra.sweep.dir=...)")
        if recorded != config_hash:
            raise WorkbenchError(
                f"{folder} holds a complete record of another config (config hash {recorded}, this run "
                f"{config_hash}); records are never overwritten: use another sweep folder "
                "(hydra.sweep.dir=...) or move that record away")
        return False
    if state == "partial":
        clear_partial(folder)
    return True


LOCK_FILE = ".lock"
"""The lock file of a run folder (kept: removing it while another process waits on it would split the lock)."""


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
    handle = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as error:
        os.close(handle)
        if error.errno in (errno.EWOULDBLOCK, errno.EACCES):
            raise FolderBusy(f"{folder} is in use by another workbench process (its lock file {LOCK_FILE} is "
                             "held); wait for it to end or write this run elsewhere") from None
        raise
    return handle


def unlock_run_dir(handle: int) -> None:
    """Release a lock taken by :func:`lock_run_dir`."""
    fcntl.flock(handle, fcntl.LOCK_UN)
    os.close(handle)


STUB_NAMES = (".hydra", LOCK_FILE)
"""What a plain run's folder holds before its run writes anything: Hydra's config copy, the job log, the lock."""


def discard_failed_run(folder: Path) -> bool:
    """After a plain run failed or was interrupted: remove what it wrote of its record, and the folder itself when
    nothing but Hydra's stub is left (``.hydra/``, ``*.log``, the lock file). A complete record is never touched.
    Call it only while holding the folder's lock.

    Returns
    -------
    bool
        Whether the folder was removed.
    """
    folder = Path(folder)
    if not folder.is_dir() or record_state(folder) == "complete":
        return False
    clear_partial(folder)
    if any(path.name not in STUB_NAMES and path.suffix != ".log" for path in folder.iterdir()):
        return False
    shutil.rmtree(folder, ignore_errors=True)
    return True
