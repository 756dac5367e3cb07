"""The alpha table of a run: its columns and its rows, one home for what the record writes, the run prints, and
the export and the report read."""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import pandas as pd

ALPHA_COLUMNS = ("alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled", "rms_mm")
"""The alpha-table columns every row of a record must have (numbers)."""
FRAME_COLUMNS = ("err_mm_median", "err_mm_p95", "err_mm_max", "w_max_abs", "w_outside_01", "w_sparsity", "w_roughness")
"""The alpha-table columns of the per-frame error over the face region (median, 95th percentile and maximum over
frames, mm) and of the weights' statistics (:class:`workbench.numerics.metrics.WeightStatistics`: largest ``|w|``, share of
frames with a weight outside [0, 1], Hoyer sparsity, mean squared second time derivative in 1/s^4); empty (NaN)
for PCA's weights, and absent from records made before they were measured."""
CLEAN_COLUMNS = tuple(f"clean_{column}" for column in ALPHA_COLUMNS)
"""The alpha-table columns of the same reconstructions scored against the clean frames (``metric.score_clean``):
present only in runs that did so, empty (NaN) in rows that have no clean frames."""

ROW_NAME_COLUMNS = ("data", "basis", "projection", "solver")
ALPHA_TABLE_COLUMNS = (
    "n",
    "m",
    "coverage",
    "alpha_abs_mean",
    "alpha_abs_pooled",
    "alpha_disp_mean",
    "alpha_disp_pooled",
    "rms_mm",
    "paper_alpha",
)
TABLE_COLUMNS = (*ROW_NAME_COLUMNS, *ALPHA_TABLE_COLUMNS, *FRAME_COLUMNS)


def alpha_columns(summary, prefix: str = "") -> dict:
    """The alpha-table columns of an :class:`workbench.numerics.metrics.AlphaSummary` (with ``prefix`` before each name)."""
    return {f"{prefix}{name}": value for name, value in summary.table_values().items()}


def alpha_table(
    rows: Sequence, *, data: str, m: int, coverage: float, paper_alpha: Mapping[str, float]
) -> pd.DataFrame:
    """One row per (basis, solver) with every alpha variant and the paper's value beside it.

    Parameters
    ----------
    rows : sequence of workbench.study.results.Row
    data : str
        The data variant the rows were computed on (``markers``, ``mesh``, ...).
    m : int
        Number of eigenfaces.
    coverage : float
        Explained variance the ``m`` eigenfaces reach.
    paper_alpha : mapping
        The paper's alpha per basis label (``H``, ``QE``, ``PCA``); other labels get NaN.

    Returns
    -------
    pandas.DataFrame
        Columns ``TABLE_COLUMNS``, then :data:`CLEAN_COLUMNS` when a row was scored against the clean frames.
    """
    clean = any(getattr(row, "clean_alpha", None) is not None for row in rows)
    records = [
        {
            "data": data,
            "basis": row.basis,
            "projection": row.projection,
            "solver": row.solver,
            "n": row.n_shapes,
            "m": m,
            "coverage": coverage,
            **alpha_columns(row.alpha),
            "paper_alpha": paper_alpha.get(row.basis, math.nan),
            **frame_values(row),
            **(alpha_columns(row.clean_alpha, "clean_") if clean and row.clean_alpha is not None else {}),
        }
        for row in rows
    ]
    return pd.DataFrame.from_records(records, columns=list(TABLE_COLUMNS) + (list(CLEAN_COLUMNS) if clean else []))


def frame_values(row) -> dict:
    """The :data:`FRAME_COLUMNS` of one row (NaN where it has no such measure)."""
    error, weights = getattr(row, "error_mm", None), getattr(row, "weight_statistics", None)
    nan = math.nan
    return {
        "err_mm_median": error.median if error else nan,
        "err_mm_p95": error.p95 if error else nan,
        "err_mm_max": error.max if error else nan,
        "w_max_abs": weights.max_abs if weights else nan,
        "w_outside_01": weights.outside_unit_share if weights else nan,
        "w_sparsity": weights.sparsity if weights else nan,
        "w_roughness": weights.roughness if weights else nan,
    }
