"""A run record's values checked for meaning when it is read back, not only against its checksums.

The checksums in ``done`` catch a file changed after the run; a record changed and signed again (its checksums
recomputed) passes them. What no run can write is refused here, naming the file and the field: an alpha below zero
or not finite, a setting that breaks the rule every study is checked against (``dataset.n_frames: -5``), a count
below zero, rows that contradict the record's own per-frame arrays (``alpha_per_frame.npz``: which rows they are,
and the mean of each row's frames) or its paired comparisons (the difference of two rows' mean alpha). Every
reader (report, collect, export, mlflow) loads records through :func:`workbench.record.record.load_record`, which
calls :func:`check_meaning`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.study.table import ALPHA_COLUMNS

if TYPE_CHECKING:
    import pandas as pd

UNTRUSTED = "no run writes that: the record cannot be trusted"
NON_NEGATIVE_COLUMNS = (*ALPHA_COLUMNS, "rms_mm")
"""Columns of the alpha table that are sizes of an error: at or above zero, or empty where undefined."""
COUNT_COLUMNS = ("n", "m")
"""Columns of the alpha table that count shapes."""
COUNTS = ("n_points", "n_train_frames", "n_eval_frames", "n_eval_takes")
"""Facts of a data variant in ``metrics.json`` that count."""
PER_FRAME_MEANS = {"absolute": "alpha_abs_mean", "displacement": "alpha_disp_mean"}
"""The per-frame arrays of ``alpha_per_frame.npz`` and the table column that is the mean of each row's frames."""
RELATIVE = 1e-6
"""Agreement asked of two ways of computing one value (a mean over frames summed in another order)."""


def check_meaning(
    folder: Path, config: Mapping, metrics: Mapping, table: pd.DataFrame, per_frame: Mapping | None, names: Mapping
) -> None:
    """Refuse a record whose values no run could have written.

    Parameters
    ----------
    folder : pathlib.Path
        The record.
    config : mapping
        ``config.yaml``.
    metrics : mapping
        ``metrics.json`` (its types checked already).
    table : pandas.DataFrame
        ``alpha_table.csv``, one row per data variant, basis and solver (equal to ``metrics.json``'s rows).
    per_frame : mapping or None
        The arrays of ``alpha_per_frame.npz`` (``<data>.basis``, ``<data>.solver``, ``<data>.absolute`` of shape
        (n_rows, n_eval_frames), ...), None when the run saved none.
    names : mapping
        The record's file names: ``config``, ``metrics``, ``table``, ``per_frame``.

    Raises
    ------
    WorkbenchError
        Naming the file and the field.
    """
    folder = Path(folder)
    check_settings(folder / names["config"], config)
    check_table(folder / names["table"], table)
    check_counts(folder / names["metrics"], metrics)
    if per_frame is not None:
        check_per_frame(folder / names["per_frame"], per_frame, table, metrics)
    check_comparisons(folder / names["metrics"], metrics, table)


def check_settings(path: Path, config: Mapping) -> None:
    """Every setting of the recorded config that the current schema knows meets its rule (settings it does not
    know, from another version, are left alone)."""
    from workbench.settings.schema import DATASET_SCHEMAS, SolverSchema, StudySchema

    _apply_rules(path, config, StudySchema, "")
    dataset = config.get("dataset")
    if isinstance(dataset, Mapping) and dataset.get("kind") in DATASET_SCHEMAS:
        _apply_rules(path, dataset, DATASET_SCHEMAS[dataset["kind"]], "dataset.")
    solvers = config.get("solver")
    for name, solver in solvers.items() if isinstance(solvers, Mapping) else ():
        if isinstance(solver, Mapping):
            _apply_rules(path, solver, SolverSchema, f"solver.{name}.")


def _apply_rules(path: Path, values: Mapping, schema, prefix: str) -> None:
    """The rules of ``schema``'s fields applied to ``values``, recursing into nested schemas."""
    from dataclasses import fields

    from workbench.settings.schema import nested_schema

    for spec in fields(schema):
        if spec.name not in values or spec.name in ("dataset", "solver") and not prefix:
            continue
        value, nested = values[spec.name], nested_schema(spec)
        if nested is not None:
            if isinstance(value, Mapping):
                _apply_rules(path, value, nested, f"{prefix}{spec.name}.")
        elif "check" in spec.metadata and not spec.metadata["check"](value):
            raise WorkbenchError(
                f"{path}: field '{prefix}{spec.name}' must be {spec.metadata['rule']}, got {value!r:.60}; {UNTRUSTED}"
            )


def check_table(path: Path, table: pd.DataFrame) -> None:
    """Every alpha (and RMS error) is at or above zero, or empty where undefined; every shape count a whole number
    at or above zero."""
    for column in NON_NEGATIVE_COLUMNS:
        if column not in table.columns:
            continue
        for i, value in enumerate(table[column].astype(float)):
            if value < 0 or math.isinf(value):
                raise WorkbenchError(
                    f"{path}: field '{column}' of row {i + 1} ({_row_name(table, i)}) must be a finite number >= 0 "
                    f"(an error relative to the face's size), got {value:g}; {UNTRUSTED}"
                )
    for column in COUNT_COLUMNS:
        for i, value in enumerate(table[column] if column in table.columns else ()):
            if not _count(value):
                raise WorkbenchError(
                    f"{path}: field '{column}' of row {i + 1} ({_row_name(table, i)}) must be a whole number >= 0, "
                    f"got {value!r}; {UNTRUSTED}"
                )


def check_counts(path: Path, metrics: Mapping) -> None:
    """The counts of each data variant (points, frames, takes) are whole numbers at or above zero."""
    for variant, facts in metrics["data"].items():
        for key in COUNTS:
            if key in facts and facts[key] is not None and not _count(facts[key]):
                raise WorkbenchError(
                    f"{path}: field 'data.{variant}.{key}' must be a whole number >= 0, got {facts[key]!r:.60}; "
                    f"{UNTRUSTED}"
                )


def check_comparisons(path: Path, metrics: Mapping, table: pd.DataFrame) -> None:
    """Each paired comparison of two rows in the absolute mean alpha states their difference (the mean over the
    same frames of ``a - b``, which is ``alpha_a - alpha_b``: absolute alpha is defined on every frame)."""
    for variant, facts in metrics["data"].items():
        comparisons = facts.get("comparisons")
        for i, comparison in enumerate(comparisons if isinstance(comparisons, list) else ()):
            if not isinstance(comparison, Mapping) or comparison.get("column") != "alpha_abs_mean":
                continue
            a, b = (_row_value(table, variant, comparison.get(key), "alpha_abs_mean") for key in ("a", "b"))
            estimate = comparison.get("estimate")
            if a is None or b is None or not isinstance(estimate, (int, float)) or not math.isfinite(estimate):
                continue
            if not math.isclose(estimate, a - b, rel_tol=RELATIVE, abs_tol=RELATIVE * max(abs(a), abs(b))):
                raise WorkbenchError(
                    f"{path}: field 'data.{variant}.comparisons[{i}].estimate' ({estimate:.6g}) is not the "
                    f"difference of the rows it compares, {comparison['a']} - {comparison['b']} = {a - b:.6g} in the "
                    f"alpha table; {UNTRUSTED}"
                )


def check_per_frame(path: Path, arrays: Mapping, table: pd.DataFrame, metrics: Mapping) -> None:
    """The per-frame arrays name the table's rows in its order, and each row's mean alpha is the mean of its
    frames."""
    data = table["data"].astype(str)
    for variant in dict.fromkeys(data):
        rows = table[data == variant]
        labels = arrays.get(f"{variant}.basis"), arrays.get(f"{variant}.solver")
        if labels[0] is None or labels[1] is None:
            continue
        stated = list(zip(rows["basis"].astype(str), rows["solver"].astype(str)))
        saved = list(zip(map(str, labels[0]), map(str, labels[1])))
        if stated != saved:
            raise WorkbenchError(
                f"{path}: fields '{variant}.basis' / '{variant}.solver' name the rows {saved}, but the alpha table "
                f"lists {stated}; {UNTRUSTED}"
            )
        for kind, column in PER_FRAME_MEANS.items():
            frames = arrays.get(f"{variant}.{kind}")
            if frames is None:
                continue
            n_frames = metrics["data"].get(variant, {}).get("n_eval_frames")
            if frames.ndim != 2 or len(frames) != len(rows) or n_frames is not None and frames.shape[1] != n_frames:
                raise WorkbenchError(
                    f"{path}: field '{variant}.{kind}' has shape {frames.shape}, not ({len(rows)}, {n_frames}) (rows, "
                    f"evaluated frames); {UNTRUSTED}"
                )
            for i, value in enumerate(rows[column].astype(float)):
                _check_mean(path, f"{variant}.{kind}", i, frames[i], value, column)


def _check_mean(path: Path, field: str, i: int, frames: np.ndarray, value: float, column: str) -> None:
    if math.isnan(value):  # undefined, shown as such: no number to contradict
        return
    defined = frames[np.isfinite(frames)]
    mean = float(defined.mean()) if defined.size else math.nan
    if not math.isclose(mean, value, rel_tol=RELATIVE, abs_tol=1e-12) or np.any(defined < 0):
        raise WorkbenchError(
            f"{path}: field '{field}' row {i} (frames at or above zero, mean {mean:.6g}) contradicts the alpha "
            f"table's {column} of that row ({value:.6g}); {UNTRUSTED}"
        )


def _row_value(table: pd.DataFrame, variant: str, label, column: str) -> float | None:
    """The ``column`` value of the one row of ``variant`` whose basis and solver are ``label``, or None."""
    if not isinstance(label, (list, tuple)) or len(label) != 2:
        return None
    found = table[
        (table["data"].astype(str) == variant)
        & (table["basis"].astype(str) == str(label[0]))
        & (table["solver"].astype(str) == str(label[1]))
    ]
    value = float(found[column].iloc[0]) if len(found) == 1 else math.nan
    return value if math.isfinite(value) else None


def _row_name(table: pd.DataFrame, i: int) -> str:
    return ", ".join(str(table[key].iloc[i]) for key in ("data", "basis", "solver") if key in table.columns)


def _count(value) -> bool:
    """A whole number at or above zero (an int, or a float with no fraction: a CSV column with a gap reads as
    floats)."""
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, str) and not value.strip():  # an empty cell: no count (a row without one)
        return True
    try:
        number = float(value)
    except (TypeError, ValueError):
        return False
    return math.isnan(number) or (math.isfinite(number) and number >= 0 and number.is_integer())
