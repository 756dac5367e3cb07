"""The one check of an array argument: a non-empty 2-D float array (rows x dims), or a one-line error naming it.

Pure numerical code. Each caller keeps its own wording of the faults (:class:`MatrixWording`): the frames of the
metrics (:data:`FRAMES`), the captures and bases (:data:`CAPTURE`) and the solvers' inputs (:data:`SOLVER`).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from workbench.core.errors import WorkbenchError


@dataclass(frozen=True)
class MatrixWording:
    """How :func:`check_matrix` words each fault: format strings over ``name`` (the argument), ``error`` (why the
    conversion to floats failed), ``shape`` (the array's), ``n_columns`` and ``got`` (the columns needed and
    found) and ``bad`` (the count of NaN or Inf entries). ``empty`` None: worded as ``not_2d``."""

    not_numeric: str
    not_2d: str
    columns: str
    empty: str | None = None
    not_points: str = "{name} must have 3 * n_points columns (x, y, z per point), got {got}"
    not_finite: str = "{name} holds NaN or Inf values ({bad} entries)"
    not_real: str = "{name} must be real: Complex data not supported (dtype {dtype}); pass the real part if meant"
    sparse: str = "{name} must be a dense array: sparse input is not supported; pass {name}.toarray()"
    masked: str = (
        "{name} must not be a NumPy masked array (its mask would be ignored): drop the masked rows or fill them "
        "(e.g. {name}.filled(...)) first"
    )


# The metrics' frames (workbench.numerics.metrics): NaN and Inf are found per frame there.
FRAMES = MatrixWording(
    "{name} must be a numeric array of shape (n_frames, n_dims): {error}",
    "{name} must be a non-empty array of shape (n_frames, n_dims), got shape {shape}",
    "{name} has {got} columns, but the captured frames have {n_columns}",
)

# Captures and bases (workbench.numerics.bases, workbench.numerics.estimator).
CAPTURE = MatrixWording(
    "{name} must be a numeric 2-D array (rows x dims): {error}",
    "{name} must be a 2-D array (rows x dims), got shape {shape}",
    "{name} must have {n_columns} columns to match the capture, got {got}",
    empty="{name} must not be empty, got shape {shape}",
)

# The solvers' bases, targets and weights (workbench.numerics.solve); they never check columns here.
SOLVER = MatrixWording(
    "{name} must be a numeric array ({error})",
    "{name} must be 2-dimensional, got shape {shape}",
    "",
    empty="{name} must not be empty, got shape {shape}",
    not_finite="{name} must be finite, found {bad} NaN/Inf",
)


def check_matrix(
    name: str, value, wording: MatrixWording, *, n_columns: int | None = None, points: bool = False, finite: bool = True
) -> np.ndarray:
    """``value`` as a non-empty 2-D float64 array, or a :class:`WorkbenchError` naming ``name``.

    Complex values, NumPy masked arrays and SciPy sparse matrices are refused, never converted (a conversion
    would drop the imaginary part or the mask, or make an array of objects).

    Parameters
    ----------
    name : str
        The argument as the error names it.
    value : array_like of shape (n_rows, n_dims)
    wording : MatrixWording
        How the caller words each fault.
    n_columns : int, optional
        The columns ``value`` must have.
    points : bool
        Whether the columns must be ``3 * n_points`` (x, y, z per point).
    finite : bool
        Whether NaN and Inf are refused.

    Returns
    -------
    ndarray of shape (n_rows, n_dims)
        float64.
    """
    if np.ma.isMaskedArray(value):
        raise WorkbenchError(wording.masked.format(name=name))
    sparse = sys.modules.get("scipy.sparse")  # a sparse matrix means SciPy's sparse module is loaded already
    if sparse is not None and sparse.issparse(value):
        raise WorkbenchError(wording.sparse.format(name=name))
    try:
        given = np.asarray(value)
        complex_values = np.iscomplexobj(given)
        array = None if complex_values else np.asarray(given, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise WorkbenchError(wording.not_numeric.format(name=name, error=error)) from None
    if complex_values:
        raise WorkbenchError(wording.not_real.format(name=name, dtype=given.dtype))
    if array.ndim != 2:
        raise WorkbenchError(wording.not_2d.format(name=name, shape=array.shape))
    if array.size == 0:
        raise WorkbenchError((wording.empty or wording.not_2d).format(name=name, shape=array.shape))
    if n_columns is not None and array.shape[1] != n_columns:
        raise WorkbenchError(wording.columns.format(name=name, n_columns=n_columns, got=array.shape[1]))
    if points and array.shape[1] % 3:
        raise WorkbenchError(wording.not_points.format(name=name, got=array.shape[1]))
    if finite:
        check_finite(name, array, wording)
    return array


def check_finite(name: str, array: np.ndarray, wording: MatrixWording) -> None:
    """A :class:`WorkbenchError` naming ``name`` and the count of NaN and Inf entries when ``array`` holds any."""
    if not np.isfinite(array).all():
        raise WorkbenchError(wording.not_finite.format(name=name, bad=int(np.count_nonzero(~np.isfinite(array)))))
