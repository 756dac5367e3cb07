"""The run record, both ways: writing it (every file atomically, the ``done`` marker last) and reading it back.

A run record is a folder holding

- ``config.yaml``: the resolved config (without Hydra's own node);
- ``alpha_table.csv`` / ``alpha_table.md``: the alpha table and the text the run printed;
- ``metrics.json``: study, config hash, overrides, dataset facts, per-data-variant metrics, every table row with
  its solver diagnostics, versions, git state and times;
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
import os
import platform
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Iterable, Mapping, Sequence

import numpy as np

from workbench.errors import WorkbenchError

if TYPE_CHECKING:
    import pandas as pd

RECORD_PACKAGES = ("numpy", "scipy", "pandas", "matplotlib", "hydra-core", "omegaconf", "fast-simplification",
                   "scikit-learn")
TEMPORARY_SUFFIX = ".tmp"
"""A file being written is ``.<name>.<random>.tmp`` beside its final name; a kill can leave one behind, never a
part of a final file. Readers look only at final names; a rerun clears a killed run's folder."""


def _file_mode() -> int:
    """Permissions of a new file under the process's umask (the temporary file is created private)."""
    umask = os.umask(0o022)
    os.umask(umask)
    return 0o666 & ~umask


FILE_MODE = _file_mode()


def write_atomic(path: Path, data: bytes | str) -> None:
    """Write a file so that a reader sees either the old content or the whole new content, never a part."""
    path = Path(path)
    payload = data.encode() if isinstance(data, str) else data
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX)
    except OSError as error:
        raise _naming(error, path) from None
    try:
        os.fchmod(handle, FILE_MODE)
        with os.fdopen(handle, "wb") as stream:
            stream.write(payload)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, path)
    except BaseException as error:
        Path(temporary).unlink(missing_ok=True)
        if isinstance(error, OSError):
            raise _naming(error, path) from None
        raise


def _naming(error: OSError, path: Path) -> OSError:
    """``error`` naming the file being written (a full disk fails a write on an open file, which names none)."""
    return type(error)(error.errno, f"cannot write ({error.strerror})", str(path))


def json_text(value) -> str:
    return json.dumps(value, indent=2, sort_keys=False, allow_nan=True) + "\n"


def npz_bytes(arrays: Mapping[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return buffer.getvalue()


def write_json(path: Path, value) -> None:
    write_atomic(path, json_text(value))


def write_npz(path: Path, arrays: Mapping[str, np.ndarray]) -> None:
    write_atomic(path, npz_bytes(arrays))


def config_hash(resolved_yaml: str) -> str:
    """Short content hash of a resolved config: the same settings give the same hash."""
    return hashlib.sha256(resolved_yaml.encode()).hexdigest()[:16]


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


def versions() -> dict:
    """The workbench's version, Python, platform and the versions of the packages that decide the numbers."""
    from workbench import __version__

    found = {"workbench": __version__, "python": sys.version.split()[0], "platform": platform.platform()}
    for package in RECORD_PACKAGES:
        try:
            found[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            found[package] = None
    return found


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
RECORD_FILES = (CONFIG_FILE, TABLE_FILE, TEXT_FILE, METRICS_FILE, TIMINGS_FILE, ALPHA_PER_FRAME_FILE, INPUTS_FILE,
                DONE)
"""The names of a record's files (besides ``inputs_<data>.npz``, one per data variant)."""
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.[A-Za-z0-9_]+" + re.escape(TEMPORARY_SUFFIX))
_VARIANT_INPUTS = re.compile(r"inputs_[^/]+\.npz")
ALPHA_COLUMNS = ("alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled", "rms_mm")
"""The alpha-table columns every row of a record must have (numbers)."""
FRAME_COLUMNS = ("err_mm_median", "err_mm_p95", "err_mm_max", "w_max_abs", "w_outside_01", "w_sparsity",
                 "w_roughness")
"""The alpha-table columns of the per-frame error over the face region (median, 95th percentile and maximum over
frames, mm) and of the weights' statistics (:class:`workbench.metrics.WeightStatistics`: largest ``|w|``, share of
frames with a weight outside [0, 1], Hoyer sparsity, mean squared second time derivative in 1/s^4); empty (NaN)
for PCA's weights, and absent from records made before they were measured."""
CLEAN_COLUMNS = tuple(f"clean_{column}" for column in ALPHA_COLUMNS)
"""The alpha-table columns of the same reconstructions scored against the clean frames (``metric.score_clean``):
present only in runs that did so, empty (NaN) in rows that have no clean frames."""


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


def file_checksum(path: Path) -> str:
    """SHA-256 of a file's bytes (hex), read in blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


# ---------------------------------------------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------------------------------------------


def alpha_per_frame_arrays(results) -> dict:
    """Per-frame alpha of every table row, for plots over time: ``<data>.absolute`` and ``<data>.displacement``
    of shape (n_rows, n_eval_frames), ``<data>.error_mm`` (RMS point error over the face region, NaN where a row
    has none), ``<data>.basis`` / ``<data>.solver`` naming the rows in table order, and the evaluated frames'
    take, frame number in the file and time (``<data>.take``, ``.frame``, ``.seconds``)."""
    arrays = {}
    for result in results:
        n_frames = len(result.capture.eval)
        arrays[f"{result.data}.basis"] = np.array([row.basis for row in result.rows])
        arrays[f"{result.data}.solver"] = np.array([row.solver for row in result.rows])
        arrays[f"{result.data}.absolute"] = np.array([row.alpha.absolute_per_frame for row in result.rows])
        arrays[f"{result.data}.displacement"] = np.array([row.alpha.displacement_per_frame for row in result.rows])
        arrays[f"{result.data}.error_mm"] = np.array([np.full(n_frames, np.nan) if row.frame_error_mm is None
                                                      else row.frame_error_mm for row in result.rows])
        arrays.update(result.capture.timeline().as_arrays(f"{result.data}."))
    return arrays


def comparison_pairs(rows: Sequence) -> list[tuple[int, int]]:
    """The pairs of table rows a run compares frame by frame: every two bases under the same solver (PCA, whose
    row has no solver, under each), and every basis under two solvers.

    Parameters
    ----------
    rows : sequence of workbench.pipeline.Row

    Returns
    -------
    list of (int, int)
        Indices into ``rows``.
    """
    solvers = list(dict.fromkeys(row.solver for row in rows if row.solver != "projection"))
    pairs = []
    for solver in solvers:
        members = [i for i, row in enumerate(rows) if row.solver in (solver, "projection")]
        pairs += [(a, b) for k, a in enumerate(members) for b in members[k + 1:]]
    for basis in dict.fromkeys(row.basis for row in rows if row.solver != "projection"):
        members = [i for i, row in enumerate(rows) if row.basis == basis and row.solver != "projection"]
        pairs += [(a, b) for k, a in enumerate(members) for b in members[k + 1:]]
    return list(dict.fromkeys(pairs))


def frame_comparisons(result, metric: Mapping) -> list[dict]:
    """Paired comparisons of a result's rows on the evaluated frames, in the run's headline alpha: for every pair
    of :func:`comparison_pairs`, the difference ``a - b`` with its block-bootstrap interval over time
    (:mod:`workbench.reporting.statistics`).

    Parameters
    ----------
    result : workbench.pipeline.StudyResult
    metric : mapping
        The ``metric`` config group: the headline's normalisation and aggregate, the bootstrap's resamples and
        seed.

    Returns
    -------
    list of dict
        ``a`` and ``b`` as ``[basis, solver]``, ``column``, and the :class:`Interval`'s fields.
    """
    from workbench.reporting.statistics import paired_mean_difference, paired_pooled_difference

    normalisation, aggregate = metric["headline_normalisation"], metric["headline_aggregate"]
    column = f"alpha_{'abs' if normalisation == 'absolute' else 'disp'}_{aggregate}"
    options = {"n_resamples": int(metric.get("bootstrap_resamples", 2000)),
               "seed": int(metric.get("bootstrap_seed", 0))}
    timeline = result.capture.timeline()
    takes = np.unique(timeline.take, return_inverse=True)[1]  # compared once here, not per comparison
    found = []
    for a, b in comparison_pairs(result.rows):
        first, second = result.rows[a].alpha, result.rows[b].alpha
        if aggregate == "mean":
            values = [getattr(alpha, f"{normalisation}_per_frame") for alpha in (first, second)]
            interval = paired_mean_difference(*values, takes=takes, seconds=timeline.seconds, **options)
        else:
            reference = first.position_sq if normalisation == "absolute" else first.displacement_sq
            interval = paired_pooled_difference(first.error_sq, second.error_sq, reference, takes=takes,
                                                seconds=timeline.seconds, **options)
        found.append({"a": [result.rows[a].basis, result.rows[a].solver],
                      "b": [result.rows[b].basis, result.rows[b].solver], "column": column, **interval.as_dict()})
    return found


def data_metrics(result) -> dict:
    """The part of ``metrics.json`` about one data variant: frames, points, spectrum, empty axes, intuitiveness."""
    from workbench.pipeline import intuitiveness_table

    capture, eigenfaces = result.capture, result.eigenfaces
    return {
        "n_points": capture.n_points, "n_train_frames": len(capture.train), "n_eval_frames": len(capture.eval),
        "notes": list(capture.notes), "face_region": result.face_region, "offset": dict(result.offset),
        "protocol": result.protocol,
        "pca": {"m": eigenfaces.n_components_, "coverage_reached": eigenfaces.coverage_,
                "method": eigenfaces.method_, "rank": int(eigenfaces.explained_variance_.size),
                "explained_variance_ratio": eigenfaces.explained_variance_ratio_[:60].tolist()},
        "quasi_eigen": {projection: {"empty_axes": [j + 1 for j in qe.empty_axes],
                                     "appended_axes": [j + 1 for j in qe.appended_axes],
                                     "axis_sums": qe.axis_sums.tolist(), "thresholds": qe.thresholds.tolist()}
                        for projection, qe in result.quasi_eigen.items()},
        "intuitiveness": intuitiveness_table(result),
        **({"basis_intuitiveness": result.basis_intuitiveness} if result.basis_intuitiveness else {}),
    }


def run_metrics(results, table, *, study: str, resolved_yaml: str, overrides: Sequence[str],
                job_num: int | None, started_at: str, repository: Path,
                comparisons: Mapping[str, list] | None = None) -> dict:
    """The content of ``metrics.json`` for a finished run.

    Parameters
    ----------
    results : sequence of workbench.pipeline.StudyResult
        One per data variant.
    table : pandas.DataFrame
        The run's alpha table (``workbench.run_text.alpha_table`` of every result, concatenated).
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
    comparisons : mapping, optional
        Data variant -> its :func:`frame_comparisons`, kept as ``data.<variant>.comparisons``.

    Returns
    -------
    dict
    """
    from datetime import datetime, timezone

    capture = results[0].capture
    rows = [(result, result_row) for result in results for result_row in result.rows]
    return {
        "study": study,
        "config_hash": config_hash(resolved_yaml),
        "overrides": list(overrides),
        "job_num": job_num,
        "dataset": {"name": capture.name, "units": capture.units, "origin": capture.origin,
                    "frame_rate": capture.frame_rate, "hand_names": list(capture.hand_names),
                    "provenance": capture.provenance},
        "data": {result.data: dict(data_metrics(result), comparisons=(comparisons or {}).get(result.data, []))
                 for result in results},
        "rows": [dict(table.iloc[i].to_dict(), train_on=result.train_on or result.data,
                      eval_on=result.eval_on or result.data, solver_iterations=row.n_iterations,
                      solver_fallback_frames=row.n_fallback_frames,
                      solver_max_kkt_violation=row.max_kkt_violation,
                      max_abs_weight=row.max_abs_weight,
                      basis_conditioning=row.conditioning.as_dict() if row.conditioning else None,
                      undefined_displacement_frames=row.alpha.n_undefined_displacement_frames,
                      weights=row.weight_statistics.as_dict() if row.weight_statistics else None,
                      error_mm_quantiles=row.error_mm.quantiles.tolist() if row.error_mm else None,
                      offset_error_share=row.offset_error_share)
                 for i, (result, row) in enumerate(rows)],
        "versions": versions(),
        "git": git_state(repository),
        "started_at": started_at,
        "finished_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }


def input_arrays(result) -> dict:
    """The arrays of ``inputs.npz``: what figures 2-4 need to recompute a few frames with the core."""
    capture = result.capture
    return {"train": capture.train, "eval": capture.eval, "neutral": capture.neutral, "hand": capture.hand,
            "hand_names": np.array(capture.hand_names), "mean": result.eigenfaces.mean_,
            "components": result.eigenfaces.components_,
            **({"faces": capture.faces} if capture.faces is not None else {}),
            **({"eval_visible": capture.eval_visible} if capture.eval_visible is not None else {}),
            **({"point_support": capture.point_support} if capture.point_support is not None
               else {}),
            **capture.timeline().as_arrays("eval_")}


def write_record(folder: Path, *, resolved_yaml: str, table, text: str, metrics: Mapping, timings: Mapping,
                 results=(), save_inputs: bool = False) -> None:
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
    results : sequence of workbench.pipeline.StudyResult
        Needed with ``save_inputs``: the arrays of ``inputs.npz`` and ``alpha_per_frame.npz``.
    save_inputs : bool
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
    if save_inputs:
        # bases carried onto other points (dataset.eval_on) live in two point sets: no single inputs file; the
        # figures show the paper's protocol, so held-out frames (dataset.held_out) are not saved either
        for result in [result for result in results
                       if result.transfer == "identity" and result.protocol == "training frames"]:
            name = INPUTS_FILE if len(results) == 1 else f"inputs_{result.data.replace('->', '_to_')}.npz"
            write(name, npz_bytes(input_arrays(result)))
        write(ALPHA_PER_FRAME_FILE, npz_bytes(alpha_per_frame_arrays(results)))
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

    def rows(self) -> list[dict]:
        """Every row of the alpha table with its solver diagnostics (``metrics.json``'s ``rows``)."""
        return [dict(row) for row in self.metrics["rows"]]

    def inputs_path(self, data: str) -> Path:
        single = self.folder / INPUTS_FILE
        return single if len(self.data_variants) == 1 else self.folder / f"inputs_{data}.npz"

    def load_inputs(self, data: str) -> dict | None:
        """The arrays of ``inputs[_<data>].npz`` (``save_inputs=true``), or None when the run did not save them."""
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
        with np.load(path, allow_pickle=False) as arrays:
            return {key: arrays[key] for key in arrays.files}
    except (OSError, ValueError, EOFError) as error:
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
        raise WorkbenchError(f"run record {folder}: '{DONE}' is empty (it must hold the checksums of the record's "
                             "files, as a run writes them); the record cannot be trusted")
    try:
        checksums = json.loads(text)["sha256"]
    except (ValueError, KeyError, TypeError):
        checksums = None
    if not isinstance(checksums, dict) or not all(isinstance(name, str) and is_record_file(name)
                                                  and isinstance(value, str) for name, value in checksums.items()):
        raise WorkbenchError(f"run record {folder}: '{DONE}' is damaged (it must hold the checksums of the record's "
                             "files, as a run writes them); the record cannot be trusted")
    return checksums


def check_file(folder: Path, name: str, checksums: Mapping[str, str]) -> None:
    """Refuse a record file that the run did not write (not among ``checksums``) or that changed since.

    Raises
    ------
    WorkbenchError
    """
    path = Path(folder) / name
    if name not in checksums:
        raise WorkbenchError(f"run record {folder}: {name} is not one of the files the run wrote (its '{DONE}' lists "
                             f"{sorted(checksums)}); the record cannot be trusted: move the file away")
    try:
        found = file_checksum(path)
    except FileNotFoundError:
        raise WorkbenchError(f"run record {folder}: {name} is missing") from None
    except OSError as error:
        raise WorkbenchError(f"run record {folder}: {name} cannot be read ({error.strerror})") from None
    if found != checksums[name]:
        raise WorkbenchError(f"run record {folder}: {name} was changed after the run (its SHA-256 no longer matches "
                             f"the one in '{DONE}'); the record cannot be trusted: restore the file or run again")


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
    added = sorted(path.name for path in folder.iterdir()
                   if path.name != DONE and (archives or not path.name.endswith(".npz")) and is_record_file(path.name)
                   and not _TEMPORARY.fullmatch(path.name) and path.name not in checksums)
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


def _check_metrics(path: Path, metrics: Mapping) -> None:
    """The fields of ``metrics.json`` that readers rely on, with their types."""
    for key, kind in (("study", str), ("config_hash", str), ("rows", list), ("data", dict), ("dataset", dict)):
        if not isinstance(metrics.get(key), kind):
            raise WorkbenchError(f"{path}: field '{key}' must be a {kind.__name__}, got "
                                 f"{type(metrics.get(key)).__name__ if key in metrics else 'nothing'}")
    if not plain_name(metrics["study"]):
        raise WorkbenchError(f"{path}: field 'study' must be a plain name, got {metrics['study']!r:.60}")
    _check_field(path, "overrides", metrics.get("overrides", []), (list,), "a list of strings")
    _check_field(path, "job_num", metrics.get("job_num"), (int, type(None)), "an integer or null")
    _check_field(path, "git", metrics.get("git") or {}, (dict,), "an object")
    for variant, facts in metrics["data"].items():
        _check_field(path, f"data.{variant}", facts, (dict,), "an object")
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
            raise WorkbenchError(f"{path}: rows[{i}].data {row['data']!r} is not one of the field 'data' "
                                 f"({sorted(metrics['data'])})")


def plain_name(name: str) -> bool:
    """Whether ``name`` can name a file or folder without leaving its parent (no separator, not '.' or '..')."""
    return bool(name) and name not in (".", "..") and "/" not in name and "\\" not in name and "\0" not in name


def inside(root: Path, *parts: str) -> Path:
    """``root / parts``, refused when it would leave ``root``, by its name or through a symbolic link (a report or
    collect writes only into its output folder, whatever names a record holds and whatever links it contains).

    Raises
    ------
    WorkbenchError
    """
    root = Path(root)
    path = root.joinpath(*parts)
    for resolved, base, target in ((False, os.path.abspath(root), os.path.abspath(path)),
                                   (True, os.path.realpath(root), os.path.realpath(path))):
        if os.path.commonpath([base, target]) != base:
            link = f" (a symbolic link leads to {target})" if resolved else ""
            raise WorkbenchError(f"refusing to write {path}: it is not inside the output folder {root}{link}")
    return path


def load_record(folder: Path, *, check_archives: bool = True) -> RunRecord:
    """Read and check a complete run record: every file against the checksum the run wrote into ``done``
    (:func:`verify_record`), then the fields readers rely on.

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
        raise WorkbenchError(f"{folder / CONFIG_FILE}: must be a mapping whose field 'study' is a plain name "
                             f"(no path), got {config.get('study') if isinstance(config, dict) else config!r:.60}")
    if not isinstance(config.get("dataset", {}), dict):
        raise WorkbenchError(f"{folder / CONFIG_FILE}: field 'dataset' must be a mapping")
    metrics = _read_json(folder / METRICS_FILE)
    _check_metrics(folder / METRICS_FILE, metrics)
    timings = _read_json(folder / TIMINGS_FILE) if (folder / TIMINGS_FILE).exists() else {}
    for stage, seconds in timings.items():
        _check_field(folder / TIMINGS_FILE, stage, seconds, (int, float), "a number of seconds")
    try:
        table = pd.read_csv(io.StringIO(_read_text(folder / TABLE_FILE)), keep_default_na=False,
                            na_values={c: ["", "NaN", "nan"]
                                       for c in ("paper_alpha", *ALPHA_COLUMNS, *FRAME_COLUMNS, *CLEAN_COLUMNS)})
    except (ValueError, pd.errors.ParserError) as error:
        raise WorkbenchError(f"{folder / TABLE_FILE}: not a readable CSV ({error})") from None
    missing = [column for column in ("data", "basis", "projection", "solver", "n", "m", *ALPHA_COLUMNS)
               if column not in table.columns]
    if missing:
        raise WorkbenchError(f"{folder / TABLE_FILE}: missing column(s) {missing}")
    bad = [column for column in ALPHA_COLUMNS if not pd.api.types.is_numeric_dtype(table[column])]
    if bad:
        raise WorkbenchError(f"{folder / TABLE_FILE}: column(s) {bad} must hold numbers")
    if len(table) != len(metrics["rows"]):
        raise WorkbenchError(f"{folder}: {TABLE_FILE} has {len(table)} rows but {METRICS_FILE} lists "
                             f"{len(metrics['rows'])}")
    return RunRecord(folder=folder, config=config, table=table, metrics=metrics, timings=timings, checksums=checksums)


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
            candidates.update(found.parent for found in path.rglob(name)
                              if not any(part.startswith(".") for part in found.relative_to(path).parts))
    incomplete = {folder for folder in candidates
                  if folder not in complete and not any(parent in complete for parent in folder.parents)}
    return sorted(complete, key=_natural_path), sorted(incomplete, key=_natural_path)


def _natural_path(path: Path) -> list:
    return [(0, int(part), "") if part.isdigit() else (1, 0, part) for part in path.parts]
