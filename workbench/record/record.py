"""The run record, both ways: writing it (every file atomically, the ``done`` marker last) and reading it back.

A run record is a folder holding

- ``config.yaml``: the resolved config (without Hydra's own node);
- ``alpha_table.csv`` / ``alpha_table.md``: the alpha table and the full text the run printed (``--wide``);
- ``metrics.json``: its layout's version (``format``, :data:`METRICS_FORMAT`), study, config hash, overrides,
  dataset facts, per-data-variant metrics, every table row with its solver diagnostics, the paper's two claims at
  m = n (``claims``), versions, git state and times;
- ``timings.json``: seconds per stage;
- optionally ``inputs.npz`` (``save_inputs=true``) and ``alpha_per_frame.npz``;
- ``done``: written last, holding the SHA-256 of every other file of the record; a folder without it is not a
  record (a run still going, or one that was killed), and a file that no longer matches its checksum makes the
  record untrusted: :func:`load_record` refuses it, so every reader (report, collect, mlflow, export) does.

This module is the only place that knows these names; everything that reads records (``workbench collect``,
``workbench report``, the tracking export) reads them through :class:`RunRecord`.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import platform
import re
import subprocess
import sys
import zipfile
from dataclasses import dataclass, field
from functools import cached_property
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Iterable, Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.files import (
    TEMPORARY_SUFFIX,
    json_text,
    mapped_npz,
    npz_bytes,
    plain_name,
    sha256_of_file,
    write_atomic,
)
from workbench.record.meaning import check_meaning
from workbench.study.claims import CLAIMS_FORMAT
from workbench.study.table import ALPHA_COLUMNS, CLEAN_COLUMNS, FRAME_COLUMNS

if TYPE_CHECKING:
    import pandas as pd

RECORD_PACKAGES = (
    "numpy",
    "scipy",
    "pandas",
    "matplotlib",
    "hydra-core",
    "omegaconf",
    "fast-simplification",
    "scikit-learn",
)


def config_hash(resolved_yaml: str) -> str:
    """Short content hash of a resolved config's settings: the same settings give the same hash in whatever order
    the YAML lists them (a record written before the dataset kinds shared their frames settings lists those in
    another place; its ``config.yaml`` hashes as a new run's does)."""
    import yaml

    settings = yaml.safe_load(resolved_yaml)
    return hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode()).hexdigest()[:16]


def git_state(repository: Path | None) -> dict:
    """Commit of the workbench's checkout and whether its code had uncommitted changes (changes under
    ``reports/``, the rendered reports that ``workbench report --reference`` rewrites, do not count). None for
    an installed package (``repository`` None): its version, in :func:`versions`, says what ran."""
    if repository is None:
        return {"commit": None, "dirty": None}

    def git(*args):
        return subprocess.run(["git", "-C", str(repository), *args], capture_output=True, text=True, timeout=10)

    try:
        commit = git("rev-parse", "HEAD")
        status = git("status", "--porcelain", "--untracked-files=no", "--", ".", ":(exclude)reports")
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}
    if commit.returncode != 0:
        return {"commit": None, "dirty": None}
    return {"commit": commit.stdout.strip(), "dirty": bool(status.stdout.strip())}


def package_versions(packages: Sequence[str]) -> dict:
    """The installed version of each package (None for one not installed), in the order given."""
    found = {}
    for package in packages:
        try:
            found[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            found[package] = None
    return found


def versions() -> dict:
    """The workbench's version, Python, platform and the versions of the packages that decide the numbers."""
    from workbench.version import __version__

    return {
        "workbench": __version__,
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        **package_versions(RECORD_PACKAGES),
    }


# ---------------------------------------------------------------------------------------------------------------
# The record's files
# ---------------------------------------------------------------------------------------------------------------

DONE = "done"
"""The completion marker, written last into a run folder: the checksums of the record's other files (JSON)."""
CONFIG_FILE = "config.yaml"
TABLE_FILE = "alpha_table.csv"
TEXT_FILE = "alpha_table.md"
METRICS_FILE = "metrics.json"
TIMINGS_FILE = "timings.json"
ALPHA_PER_FRAME_FILE = "alpha_per_frame.npz"
INPUTS_FILE = "inputs.npz"
RECORD_FILES = (CONFIG_FILE, TABLE_FILE, TEXT_FILE, METRICS_FILE, TIMINGS_FILE, ALPHA_PER_FRAME_FILE, INPUTS_FILE, DONE)
"""The names of a record's files (besides ``inputs_<data>.npz``, one per data variant)."""
METRICS_FORMAT = 1
"""The layout of ``metrics.json`` (its field ``format``): 1 states every variant's ``protocol``, ``notes`` and
``face_region``, the dataset's ``provenance``, the ``versions`` and each row's ``train_on`` and ``eval_on``. A record
without the field is of the layout before (0), read through :func:`current_metrics`; readers take every field of
the current layout as given."""
MEANING_NAMES = {"config": CONFIG_FILE, "metrics": METRICS_FILE, "table": TABLE_FILE, "per_frame": ALPHA_PER_FRAME_FILE}
"""The files :func:`workbench.record.meaning.check_meaning` names."""
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.[A-Za-z0-9_]+" + re.escape(TEMPORARY_SUFFIX))
_VARIANT_INPUTS = re.compile(r"inputs_[^/]+\.npz")


def record_state(folder: Path) -> str:
    """``complete`` (has ``done``), ``partial`` (exists without it) or ``absent``."""
    folder = Path(folder)
    if (folder / DONE).is_file():
        return "complete"
    return "partial" if folder.exists() else "absent"


def is_complete(folder: Path) -> bool:
    """Whether ``folder`` holds a complete record (its ``done`` marker exists)."""
    return record_state(folder) == "complete"


def is_record_file(name: str) -> bool:
    """Whether a file name is one a run writes into its record (or a temporary file of one being written)."""
    match = _TEMPORARY.fullmatch(name)
    name = match.group("name") if match else name
    return name in RECORD_FILES or bool(_VARIANT_INPUTS.fullmatch(name))


# ---------------------------------------------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------------------------------------------


def run_metrics(
    results_metrics: Mapping,
    *,
    study: str,
    resolved_yaml: str,
    overrides: Sequence[str],
    job_num: int | None,
    started_at: str,
    repository: Path,
) -> dict:
    """The content of ``metrics.json`` for a finished run.

    Parameters
    ----------
    results_metrics : mapping
        What the run found: ``dataset``, ``data``, ``rows`` and the paper's ``claims`` (format
        :data:`CLAIMS_FORMAT`; :func:`workbench.study.summary.results_metrics`).
    study : str
    resolved_yaml : str
        The resolved config as written to ``config.yaml`` (its hash identifies the run).
    overrides : sequence of str
        The command-line and sweep overrides that made the config.
    job_num : int or None
        The run's position in its sweep.
    started_at : str
        ISO time the run started.
    repository : pathlib.Path
        The workbench's checkout, for the git commit.

    Returns
    -------
    dict
    """
    from datetime import datetime, timezone

    return {
        "format": METRICS_FORMAT,
        "study": study,
        "config_hash": config_hash(resolved_yaml),
        "overrides": list(overrides),
        "job_num": job_num,
        "dataset": results_metrics["dataset"],
        "data": results_metrics["data"],
        "rows": results_metrics["rows"],
        **({"claims": results_metrics["claims"]} if "claims" in results_metrics else {}),
        "versions": versions(),
        "git": git_state(repository),
        "started_at": started_at,
        "finished_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }


def write_record(
    folder: Path,
    *,
    resolved_yaml: str,
    table,
    text: str,
    metrics: Mapping,
    timings: Mapping,
    inputs: Mapping[str, Mapping[str, np.ndarray]] | None = None,
    alpha_per_frame: Mapping[str, np.ndarray] | None = None,
) -> None:
    """Write a run record into ``folder``, every file atomically and ``done`` last.

    Parameters
    ----------
    folder : pathlib.Path
    resolved_yaml : str
        ``config.yaml``.
    table : pandas.DataFrame
        ``alpha_table.csv``.
    text : str
        ``alpha_table.md``: what the run printed.
    metrics, timings : mapping
        ``metrics.json`` (:func:`run_metrics`) and ``timings.json``.
    inputs : mapping, optional
        Data variant -> the arrays of its inputs file (``save_inputs``): ``inputs.npz`` when the run has one data
        variant, ``inputs_<variant>.npz`` otherwise (:func:`workbench.study.summary.saved_inputs`).
    alpha_per_frame : mapping, optional
        The arrays of ``alpha_per_frame.npz`` (:func:`workbench.study.summary.alpha_per_frame_arrays`).
    """
    folder = Path(folder)
    checksums = {}

    def write(name: str, data: bytes | str) -> None:
        payload = data.encode() if isinstance(data, str) else data
        write_atomic(folder / name, payload)
        checksums[name] = hashlib.sha256(payload).hexdigest()

    write(CONFIG_FILE, resolved_yaml)
    write(TABLE_FILE, table.to_csv(index=False))
    write(TEXT_FILE, text)
    write(METRICS_FILE, json_text(dict(metrics)))
    write(TIMINGS_FILE, json_text(dict(timings)))
    # Inputs are stored, not deflated: float frames shrink by about 5 % (ICT mesh, every 4th frame: 441.5 MB against
    # 462.5 MB) and deflating took 13 s a file. Readers map stored arrays and read deflated ones whole (mapped_npz).
    for data, arrays in (inputs or {}).items():
        name = INPUTS_FILE if len(metrics["data"]) == 1 else f"inputs_{data.replace('->', '_to_')}.npz"
        write(name, npz_bytes(arrays, compressed=False))
    if alpha_per_frame is not None:
        write(ALPHA_PER_FRAME_FILE, npz_bytes(alpha_per_frame))
    write_atomic(folder / DONE, json_text({"sha256": checksums}))


# ---------------------------------------------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunRecord:
    """A complete run record, read back.

    Attributes
    ----------
    folder : pathlib.Path
    config : dict
        The resolved config (``config.yaml``).
    table : pandas.DataFrame
        The alpha table (``alpha_table.csv``), one row per data variant, basis and solver.
    metrics : dict
        ``metrics.json``.
    timings : dict
        ``timings.json``: seconds per stage (empty when the record has none).
    checksums : dict or None
        File name -> SHA-256 the run wrote into ``done`` (:func:`load_record` refuses a record without them).
    """

    folder: Path
    config: dict
    table: "pd.DataFrame"
    metrics: dict
    timings: dict = field(default_factory=dict)
    checksums: dict | None = None

    @property
    def study(self) -> str:
        return str(self.metrics.get("study") or self.config.get("study"))

    @cached_property
    def settings(self):
        """The run's settings, checked and typed as the run had them (:func:`workbench.settings.typed.study_settings`
        of ``config``; the retired settings an earlier version's record holds left out)."""
        from workbench.settings.typed import study_settings

        return study_settings(self.config)

    @property
    def config_hash(self) -> str | None:
        return self.metrics.get("config_hash")

    @property
    def overrides(self) -> list[str]:
        return list(self.metrics.get("overrides") or [])

    @property
    def job_num(self) -> int | None:
        return self.metrics.get("job_num")

    @property
    def git(self) -> dict:
        return dict(self.metrics.get("git") or {})

    @property
    def data_variants(self) -> list[str]:
        return list(self.metrics["data"])

    @property
    def claims(self) -> dict | None:
        """The paper's two claims as the run computed them (``metrics.json``'s ``claims``,
        :func:`workbench.study.claims.claims_at_m_equals_n`), or None for a record written before they were kept."""
        found = self.metrics.get("claims")
        return dict(found) if isinstance(found, dict) else None

    def rows(self) -> list[dict]:
        """Every row of the alpha table with its solver diagnostics (``metrics.json``'s ``rows``)."""
        return [dict(row) for row in self.metrics["rows"]]

    def inputs_path(self, data: str) -> Path:
        single = self.folder / INPUTS_FILE
        return single if len(self.data_variants) == 1 else self.folder / f"inputs_{data}.npz"

    def load_inputs(self, data: str) -> dict | None:
        """The arrays of ``inputs[_<data>].npz`` (``save_inputs=true``), or None when the run did not save them.
        They are read-only, mapped from the file (:func:`~workbench.core.files.mapped_npz`): copy one to change it."""
        return self._load_arrays(self.inputs_path(data))

    def load_alpha_per_frame(self) -> dict | None:
        """The arrays of ``alpha_per_frame.npz``, or None when the run did not save them."""
        return self._load_arrays(self.folder / ALPHA_PER_FRAME_FILE)

    def _load_arrays(self, path: Path) -> dict | None:
        """The arrays of one of the record's archives, checked against its checksum first (archives can be large,
        so they are checked when read, not when the record is loaded)."""
        if self.checksums is not None and (path.name in self.checksums or path.is_file()):
            check_file(self.folder, path.name, self.checksums)
        return _load_arrays(path)


def _load_arrays(path: Path) -> dict | None:
    if not path.is_file():
        return None
    try:
        return mapped_npz(path)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as error:
        raise WorkbenchError(f"{path}: not a readable NumPy archive ({error})") from None


def _read_text(path: Path) -> str:
    try:
        return path.read_text()
    except FileNotFoundError:
        raise WorkbenchError(f"run record {path.parent}: {path.name} is missing") from None
    except (OSError, UnicodeDecodeError) as error:
        raise WorkbenchError(f"run record {path.parent}: {path.name} cannot be read ({error})") from None


def _read_json(path: Path) -> dict:
    try:
        value = json.loads(_read_text(path))
    except ValueError as error:
        raise WorkbenchError(f"{path}: not valid JSON ({error})") from None
    if not isinstance(value, dict):
        raise WorkbenchError(f"{path}: must hold a JSON object, got {type(value).__name__}")
    return value


def read_checksums(folder: Path) -> dict:
    """The checksums a run wrote into its ``done`` marker (file name -> SHA-256).

    Raises
    ------
    WorkbenchError
        When ``done`` holds anything but the checksums a run writes (an emptied marker included: without them no
        file of the record can be checked).
    """
    text = _read_text(Path(folder) / DONE)
    if not text.strip():
        raise WorkbenchError(
            f"run record {folder}: '{DONE}' is empty (it must hold the checksums of the record's "
            "files, as a run writes them); the record cannot be trusted"
        )
    try:
        checksums = json.loads(text)["sha256"]
    except (ValueError, KeyError, TypeError):
        checksums = None
    if not isinstance(checksums, dict) or not all(
        isinstance(name, str) and is_record_file(name) and isinstance(value, str) for name, value in checksums.items()
    ):
        raise WorkbenchError(
            f"run record {folder}: '{DONE}' is damaged (it must hold the checksums of the record's "
            "files, as a run writes them); the record cannot be trusted"
        )
    return checksums


def check_file(folder: Path, name: str, checksums: Mapping[str, str]) -> None:
    """Refuse a record file that the run did not write (not among ``checksums``) or that changed since.

    Raises
    ------
    WorkbenchError
    """
    path = Path(folder) / name
    if name not in checksums:
        raise WorkbenchError(
            f"run record {folder}: {name} is not one of the files the run wrote (its '{DONE}' lists "
            f"{sorted(checksums)}); the record cannot be trusted: move the file away"
        )
    try:
        found = sha256_of_file(path)
    except FileNotFoundError:
        raise WorkbenchError(f"run record {folder}: {name} is missing") from None
    except OSError as error:
        raise WorkbenchError(f"run record {folder}: {name} cannot be read ({error.strerror})") from None
    if found != checksums[name]:
        raise WorkbenchError(
            f"run record {folder}: {name} was changed after the run (its SHA-256 no longer matches "
            f"the one in '{DONE}'); the record cannot be trusted: restore the file or run again"
        )


def check_record_files(folder: Path, checksums: Mapping[str, str], *, archives: bool = False) -> None:
    """Every file the run wrote is there and unchanged, and no record file was added; archives (``.npz``, which
    can be large) only with ``archives``, else when read (:meth:`RunRecord.load_inputs`).

    Raises
    ------
    WorkbenchError
    """
    folder = Path(folder)
    for name in checksums:
        if archives or not name.endswith(".npz"):
            check_file(folder, name, checksums)
    added = sorted(
        path.name
        for path in folder.iterdir()
        if path.name != DONE
        and (archives or not path.name.endswith(".npz"))
        and is_record_file(path.name)
        and not _TEMPORARY.fullmatch(path.name)
        and path.name not in checksums
    )
    if added:
        check_file(folder, added[0], checksums)


def verify_record(folder: Path, *, archives: bool = True) -> dict:
    """Check a complete record before anything of it is used: its ``done`` holds the checksums the run wrote,
    every file the run wrote is there and unchanged, and no record file was added since (every reader, report,
    collect, export and mlflow, loads records through :func:`load_record`, which calls this).

    Parameters
    ----------
    folder : pathlib.Path
    archives : bool
        Check the ``.npz`` archives too (the default); else each is checked when read.

    Returns
    -------
    dict
        File name -> SHA-256, from ``done``.

    Raises
    ------
    WorkbenchError
        Naming the record and the file at fault.
    """
    folder = Path(folder)
    if not is_complete(folder):
        raise WorkbenchError(f"{folder} is not a complete run record (no '{DONE}' file)")
    checksums = read_checksums(folder)
    check_record_files(folder, checksums, archives=archives)
    return checksums


def _check_field(path: Path, where: str, value, kinds: tuple, rule: str) -> None:
    """Refuse ``value`` unless it is one of ``kinds`` (a bool is not a number here)."""
    if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
        raise WorkbenchError(f"{path}: field '{where}' must be {rule}, got {value!r:.60}")


def current_metrics(path: Path, metrics: dict) -> dict:
    """``metrics.json`` in the current layout (:data:`METRICS_FORMAT`): a record of an earlier version (no field
    ``format``) is still read, given here, in one place, what its writer left unsaid (a variant scored on its
    training frames, without notes or face region; a dataset without provenance; no versions; each row trained and
    evaluated on its own data variant).

    Raises
    ------
    WorkbenchError
        Naming the file, for a format this version does not know (a record of a later workbench).
    """
    found = metrics.get("format", 0)
    if found == METRICS_FORMAT:
        return metrics
    if isinstance(found, bool) or not isinstance(found, int) or not 0 <= found < METRICS_FORMAT:
        raise WorkbenchError(
            f"{path}: field 'format' must be an integer from 0 to {METRICS_FORMAT} (this workbench's layout), got "
            f"{found!r:.60}: a record of a later version of the workbench; read it with that version or rerun the run"
        )
    upgraded = dict(metrics, format=METRICS_FORMAT, versions=metrics.get("versions") or {})
    if isinstance(metrics.get("dataset"), dict):
        upgraded["dataset"] = dict(metrics["dataset"], provenance=metrics["dataset"].get("provenance") or {})
    if isinstance(metrics.get("data"), dict):
        upgraded["data"] = {
            variant: {"protocol": "training frames", "notes": [], "face_region": "", **facts}
            if isinstance(facts, dict)
            else facts
            for variant, facts in metrics["data"].items()
        }
    if isinstance(metrics.get("rows"), list):
        upgraded["rows"] = [
            {"train_on": row.get("data"), "eval_on": row.get("data"), **row} if isinstance(row, dict) else row
            for row in metrics["rows"]
        ]
    return upgraded


def _check_metrics(path: Path, metrics: Mapping) -> None:
    """The fields of ``metrics.json`` that readers rely on, with their types."""
    for key, kind in (("study", str), ("config_hash", str), ("rows", list), ("data", dict), ("dataset", dict)):
        if not isinstance(metrics.get(key), kind):
            raise WorkbenchError(
                f"{path}: field '{key}' must be a {kind.__name__}, got "
                f"{type(metrics.get(key)).__name__ if key in metrics else 'nothing'}"
            )
    if not plain_name(metrics["study"]):
        raise WorkbenchError(f"{path}: field 'study' must be a plain name, got {metrics['study']!r:.60}")
    _check_field(path, "overrides", metrics.get("overrides", []), (list,), "a list of strings")
    _check_field(path, "job_num", metrics.get("job_num"), (int, type(None)), "an integer or null")
    _check_field(path, "git", metrics.get("git") or {}, (dict,), "an object")
    for variant, facts in metrics["data"].items():
        _check_field(path, f"data.{variant}", facts, (dict,), "an object")
    if "claims" in metrics:
        claims = metrics["claims"]
        _check_field(path, "claims", claims, (dict,), "an object")
        if claims.get("format") != CLAIMS_FORMAT:
            raise WorkbenchError(
                f"{path}: field 'claims.format' must be {CLAIMS_FORMAT}, got {claims.get('format')!r:.60}"
            )
        _check_field(path, "claims.entries", claims.get("entries"), (list,), "a list of objects")
    for i, row in enumerate(metrics["rows"]):
        if not isinstance(row, dict):
            raise WorkbenchError(f"{path}: rows[{i}] must be an object")
        for key in ("data", "basis", "solver", *ALPHA_COLUMNS):
            if key not in row:
                raise WorkbenchError(f"{path}: rows[{i}] has no '{key}'")
        for key in ("data", "basis", "solver"):
            _check_field(path, f"rows[{i}].{key}", row[key], (str,), "a string")
        for key in ALPHA_COLUMNS:
            _check_field(path, f"rows[{i}].{key}", row[key], (int, float, type(None)), "a number or null")
        if row["data"] not in metrics["data"]:
            raise WorkbenchError(
                f"{path}: rows[{i}].data {row['data']!r} is not one of the field 'data' ({sorted(metrics['data'])})"
            )


def _check_values(folder: Path, rows: Sequence[Mapping], table) -> None:
    """Every alpha value of ``metrics.json``'s rows is finite and its alpha table cell's (to rounding), or, where
    the cell is empty (no value: alpha undefined), null or NaN: a record re-signed after its values were changed
    is refused by what it says, not only by its checksums."""
    for i, row in enumerate(rows):
        for key in ALPHA_COLUMNS:
            value, cell = row[key], float(table[key].iloc[i])
            stated = math.nan if value is None else float(value)
            if math.isnan(cell) and math.isnan(stated):
                continue
            if not math.isfinite(stated) or not math.isclose(stated, cell, rel_tol=1e-9, abs_tol=1e-12):
                raise WorkbenchError(
                    f"{folder / METRICS_FILE}: field 'rows[{i}].{key}' must be a finite number equal to {TABLE_FILE} "
                    f"row {i + 1}'s ({cell:.6g}), got {value}"
                )


def load_record(folder: Path, *, check_archives: bool = True) -> RunRecord:
    """Read and check a complete run record: every file against the checksum the run wrote into ``done``
    (:func:`verify_record`), then the fields readers rely on, then what the values mean (an alpha below zero, a
    setting that breaks its rule, rows the per-frame arrays contradict: :mod:`workbench.record.meaning`).

    Parameters
    ----------
    folder : pathlib.Path
    check_archives : bool
        Check the record's ``.npz`` archives now too (the default: every reader refuses a damaged record before it
        writes anything); otherwise each is checked when read.

    Returns
    -------
    RunRecord

    Raises
    ------
    WorkbenchError
        Naming the file and field when the folder is not a complete record or a file of it is damaged.
    """
    import pandas as pd
    import yaml

    folder = Path(folder)
    checksums = verify_record(folder, archives=check_archives)
    try:
        config = yaml.safe_load(_read_text(folder / CONFIG_FILE))
    except yaml.YAMLError as error:
        raise WorkbenchError(f"{folder / CONFIG_FILE}: not valid YAML ({str(error).splitlines()[0]})") from None
    if not isinstance(config, dict) or not isinstance(config.get("study"), str) or not plain_name(config["study"]):
        raise WorkbenchError(
            f"{folder / CONFIG_FILE}: must be a mapping whose field 'study' is a plain name "
            f"(no path), got {config.get('study') if isinstance(config, dict) else config!r:.60}"
        )
    if not isinstance(config.get("dataset", {}), dict):
        raise WorkbenchError(f"{folder / CONFIG_FILE}: field 'dataset' must be a mapping")
    metrics = current_metrics(folder / METRICS_FILE, _read_json(folder / METRICS_FILE))
    _check_metrics(folder / METRICS_FILE, metrics)
    timings = _read_json(folder / TIMINGS_FILE) if (folder / TIMINGS_FILE).exists() else {}
    for stage, seconds in timings.items():
        _check_field(folder / TIMINGS_FILE, stage, seconds, (int, float), "a number of seconds")
    try:
        table = pd.read_csv(
            io.StringIO(_read_text(folder / TABLE_FILE)),
            keep_default_na=False,
            na_values={c: ["", "NaN", "nan"] for c in ("paper_alpha", *ALPHA_COLUMNS, *FRAME_COLUMNS, *CLEAN_COLUMNS)},
        )
    except (ValueError, pd.errors.ParserError) as error:
        raise WorkbenchError(f"{folder / TABLE_FILE}: not a readable CSV ({error})") from None
    missing = [
        column
        for column in ("data", "basis", "projection", "solver", "n", "m", *ALPHA_COLUMNS)
        if column not in table.columns
    ]
    if missing:
        raise WorkbenchError(f"{folder / TABLE_FILE}: missing column(s) {missing}")
    bad = [column for column in ALPHA_COLUMNS if not pd.api.types.is_numeric_dtype(table[column])]
    if bad:
        raise WorkbenchError(f"{folder / TABLE_FILE}: column(s) {bad} must hold numbers")
    if len(table) != len(metrics["rows"]):
        raise WorkbenchError(
            f"{folder}: {TABLE_FILE} has {len(table)} rows but {METRICS_FILE} lists {len(metrics['rows'])}"
        )
    _check_values(folder, metrics["rows"], table)
    record = RunRecord(folder=folder, config=config, table=table, metrics=metrics, timings=timings, checksums=checksums)
    check_meaning(folder, config, metrics, table, record.load_alpha_per_frame(), MEANING_NAMES)
    return record


def find_records(paths: Iterable[Path]) -> tuple[list[Path], list[Path]]:
    """Run folders under the given paths (each a run folder, a sweep folder or any folder above them).

    Returns
    -------
    complete : list of pathlib.Path
        Folders with a ``done`` marker, in natural order of their paths.
    incomplete : list of pathlib.Path
        Folders that look like runs (they hold a ``config.yaml`` or ``metrics.json``) but have no marker.
    """
    complete, candidates = set(), set()
    for path in map(Path, paths):
        if not path.exists():
            raise WorkbenchError(f"{path} does not exist")
        complete.update(marker.parent for marker in path.rglob(DONE) if marker.is_file())
        for name in (CONFIG_FILE, METRICS_FILE):
            # Hydra's own .hydra/config.yaml is not a run; a folder inside a complete record is part of it
            candidates.update(
                found.parent
                for found in path.rglob(name)
                if not any(part.startswith(".") for part in found.relative_to(path).parts)
            )
    incomplete = {
        folder
        for folder in candidates
        if folder not in complete and not any(parent in complete for parent in folder.parents)
    }
    return sorted(complete, key=_natural_path), sorted(incomplete, key=_natural_path)


def _natural_path(path: Path) -> list:
    return [(0, int(part), "") if part.isdigit() else (1, 0, part) for part in path.parts]
