"""What makes :class:`workbench.numerics.estimator.QuasiEigenFaces` as strict as a scikit-learn estimator, on plain
code that runs with scikit-learn 1.4 to the newest and without it: the frames' column names remembered at ``fit``
and checked at every later use (``feature_names_in_``), the output's names (``get_feature_names_out``) and
container (``set_output``), and pickles that carry the workbench's version.
"""

from __future__ import annotations

import sys
import warnings

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.version import __version__

OUTPUTS = ("default", "pandas", "polars")
"""What ``set_output(transform=...)`` takes: NumPy arrays, pandas or polars DataFrames."""
VERSION_KEY = "_workbench_version"
"""The key of the workbench's version in a pickled estimator's state."""


def column_names(frames) -> np.ndarray | None:
    """The column names of a DataFrame (pandas, polars, anything with string ``columns``) as an object array of
    shape (n_dims,), or None for an array or a DataFrame whose columns are not named by strings (as scikit-learn).

    Raises
    ------
    WorkbenchError
        When some columns are named by strings and some are not.
    """
    columns = getattr(frames, "columns", None)
    if columns is None or isinstance(frames, np.ndarray) or not hasattr(frames, "shape"):
        return None
    names = np.asarray(list(columns), dtype=object)
    strings = np.array([isinstance(name, str) for name in names], dtype=bool)
    if names.size == 0 or not strings.any():
        return None
    if not strings.all():
        raise WorkbenchError(
            "frames' columns must all be named by strings or none of them: column "
            f"{names[~strings][0]!r} is a {type(names[~strings][0]).__name__}; rename it or pass frames.to_numpy()"
        )
    return names


def _outside_the_estimator() -> int:
    """The ``stacklevel`` of a warning that points at the first caller outside :mod:`workbench.numerics` (the
    estimator's methods call each other to different depths)."""
    frame, level = sys._getframe(1), 1
    while frame is not None and frame.f_globals.get("__name__", "").startswith("workbench.numerics"):
        frame, level = frame.f_back, level + 1
    return level


class ScikitLearnManners:
    """The column-name checks, output names and containers and the versioned pickles of an estimator whose
    ``transform`` gives one column per name of :meth:`get_feature_names_out`."""

    # -- the frames' columns: fit remembers them, every later use checks them --------------------------------

    def _remember_columns(self, frames) -> None:
        """At ``fit``: ``feature_names_in_`` from a DataFrame's column names, forgotten for an array."""
        names = column_names(frames)
        if names is not None:
            self.feature_names_in_ = names
        elif hasattr(self, "feature_names_in_"):
            del self.feature_names_in_

    def _check_columns(self, frames) -> None:
        """At every use after ``fit``: a DataFrame's columns must be the fitted ones in the fitted order (reordered
        or renamed columns would silently give other weights); a warning when only one of the two had names."""
        fitted = getattr(self, "feature_names_in_", None)
        given = column_names(frames)
        if fitted is None and given is None:
            return
        if fitted is None or given is None:
            warnings.warn(
                f"frames {'have' if fitted is None else 'do not have'} column names, but {type(self).__name__} was "
                f"fitted {'without' if fitted is None else 'with'} them: the columns are taken by position",
                UserWarning,
                stacklevel=_outside_the_estimator(),
            )
            return
        if len(given) == len(fitted) and np.array_equal(given, fitted):
            return
        unknown = [name for name in given if name not in set(fitted)]
        if unknown:
            rule = f"column {unknown[0]!r} was not among the columns fitted on"
        elif len(given) != len(fitted):
            missing = [name for name in fitted if name not in set(given)]
            rule = f"column {missing[0]!r} fitted on is missing"
        else:
            first = int(np.flatnonzero(given != fitted)[0])
            rule = f"they are reordered: column {first} is {given[first]!r}, fitted on {fitted[first]!r}"
        raise WorkbenchError(
            f"frames' columns must be those fitted on, in the same order, but {rule}; select them as "
            "frames[estimator.feature_names_in_]"
        )

    # -- what transform gives ------------------------------------------------------------------------------

    def get_feature_names_out(self, input_features=None) -> np.ndarray:
        """The names of :meth:`transform`'s columns: the shape names ``shape_names_``.

        Parameters
        ----------
        input_features : array-like of str or None, default None
            The input's column names, as a ``Pipeline`` passes them on; checked against ``feature_names_in_`` (or
            their number against ``n_features_in_``), not used.

        Returns
        -------
        ndarray of shape (n_shapes,)
            object dtype, one name per quasi-eigen face (``len(shapes_)``).
        """
        self._check_fitted()
        if input_features is not None:
            given = np.asarray(input_features, dtype=object)
            fitted = getattr(self, "feature_names_in_", None)
            if fitted is not None and not np.array_equal(given, fitted):
                raise WorkbenchError("input_features must equal feature_names_in_, the columns fitted on")
            if given.shape != (self.n_features_in_,):
                raise WorkbenchError(
                    f"input_features must hold {self.n_features_in_} names, one per column fitted on, got "
                    f"{given.shape[0] if given.ndim else given.size}"
                )
        return np.asarray(self.shape_names_, dtype=object)

    def set_output(self, *, transform=None):
        """The container :meth:`transform` and ``fit_transform`` give, as scikit-learn's ``set_output``.

        Parameters
        ----------
        transform : {"default", "pandas", "polars"} or None, default None
            ``default``: NumPy arrays (or scikit-learn's global ``transform_output`` when set with
            ``sklearn.set_config``); ``pandas`` / ``polars``: a DataFrame whose columns are the basis's shape
            names (the index of a pandas DataFrame given kept); None: unchanged.

        Returns
        -------
        self
        """
        if transform is None:
            return self
        if not isinstance(transform, str) or transform not in OUTPUTS:
            raise WorkbenchError(f"set_output's transform must be one of {', '.join(map(repr, OUTPUTS))} or None")
        # scikit-learn's own attribute, which its Pipeline and ColumnTransformer read
        self._sklearn_output_config = {**getattr(self, "_sklearn_output_config", {}), "transform": transform}
        return self

    def _output_container(self) -> str:
        """``set_output``'s choice, else scikit-learn's global ``transform_output`` when scikit-learn is loaded."""
        chosen = getattr(self, "_sklearn_output_config", {}).get("transform", "default")
        sklearn = sys.modules.get("sklearn")
        if chosen == "default" and sklearn is not None:
            chosen = sklearn.get_config().get("transform_output", "default")
        return chosen

    def _in_container(self, values: np.ndarray, frames, names) -> object:
        """``values`` of shape (n_frames, n_names) in the container :meth:`set_output` chose, columns ``names``."""
        container = self._output_container()
        if container == "pandas":
            import pandas as pd

            index = frames.index if isinstance(frames, pd.DataFrame) and len(frames.index) == len(values) else None
            return pd.DataFrame(values, columns=list(names), index=index, copy=False)
        if container == "polars":
            try:
                import polars as pl
            except ImportError:
                raise WorkbenchError("set_output(transform='polars') needs polars: pip install polars") from None
            return pl.DataFrame(values, schema=list(names), orient="row")
        return values

    # -- pickles -------------------------------------------------------------------------------------------

    def __getstate__(self) -> dict:
        return {**self.__dict__, VERSION_KEY: __version__}

    def __setstate__(self, state: dict) -> None:
        """Refuse, with "refit", a pickle of another version of the workbench (or of one from before pickles
        carried it, or one lacking a parameter): its attributes need not be this version's."""
        version = state.get(VERSION_KEY)
        missing = [name for name in self._parameter_names() if name not in state]
        if version != __version__ or missing:
            written = f"workbench {version}" if version else "an older workbench (its pickle carries no version)"
            lacking = f", without parameter {missing[0]!r}" if missing else ""
            raise WorkbenchError(
                f"This pickled {type(self).__name__} was written by {written}{lacking}; this is workbench "
                f"{__version__}: refit the estimator with this version and pickle it again"
            )
        self.__dict__.update({key: value for key, value in state.items() if key != VERSION_KEY})
