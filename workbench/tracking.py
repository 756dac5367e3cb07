"""Resumable sweeps: a stable identity for every run, skip what is complete, never overwrite a record.

A study's sweep writes each run into ``<sweep dir>/<run id>``, the run id made from the run's overrides (not a
job number or a time), so re-running the same sweep finds the same folders. A folder whose ``done`` marker
exists holds a complete record: the run is skipped if its config hash matches and refused if it does not (the
record is never overwritten). A folder without ``done`` is what a killed run left: it is cleared and run again.
"""

from __future__ import annotations

import hashlib
import json
import re
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
        if (path.is_file() or path.is_symlink()) and path.suffix != ".log":
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
