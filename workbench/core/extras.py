"""The optional parts of the workbench: which extra of the package installs each, and the one line that says so.

The core install (``pip install quasi-eigen-workbench``) runs every study and prints its tables. The extras add
what one use needs (``pyproject.toml`` lists them): ``report`` (figures and rendered faces), ``parquet`` (parquet
copies of collected tables), ``bases`` (ICA and NMF of the alternative bases), ``hdf5`` (HDF5 mesh sequences),
``cluster`` (the SLURM launcher), ``mlflow`` (the tracking store); ``all`` is all of them.
"""

from __future__ import annotations

import importlib.util

DISTRIBUTION = "quasi-eigen-workbench"

EXTRA_OF_MODULE = {
    "matplotlib": "report",
    "pyvista": "report",
    "vtk": "report",
    "vtkmodules": "report",
    "PIL": "report",
    "jinja2": "report",
    "markupsafe": "report",
    "pyarrow": "parquet",
    "sklearn": "bases",
    "h5py": "hdf5",
    "submitit": "cluster",
    "mlflow": "mlflow",
}
"""Top-level module of an optional dependency -> the extra that installs it."""


def install_hint(extra: str) -> str:
    """The command that installs an extra, for a built package and for a checkout."""
    return f"pip install '{DISTRIBUTION}[{extra}]' (in a checkout: pip install -e '.[{extra}]')"


def has_module(name: str) -> bool:
    """Whether a module can be imported, without importing it."""
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def missing_extra(error: BaseException) -> str | None:
    """The one-line message for an optional dependency that is not installed, or None when ``error`` is anything
    else: an ``ImportError`` of one of :data:`EXTRA_OF_MODULE`, or Hydra failing to load the SLURM launcher's
    config because its plugin (the cluster extra) is missing."""
    if isinstance(error, ImportError) and error.name:
        extra = EXTRA_OF_MODULE.get(error.name.split(".")[0])
        if extra is not None:
            return f"{error.name} is not installed (the {extra} extra): {install_hint(extra)}"
    if "hydra/launcher/submitit" in str(error) and not has_module("hydra_plugins.hydra_submitit_launcher"):
        return f"hydra/launcher=slurm needs hydra-submitit-launcher (the cluster extra): {install_hint('cluster')}"
    return None
