"""Research workbench for Kim & Ko's intuitive quasi-eigen faces.

Data flows one way: ``dataset`` -> ``bases`` -> ``solve`` -> ``metrics`` -> ``record`` -> ``report``.
The numerical core (``bases``, ``solve``, ``metrics``) is pure: arrays in, arrays and frozen dataclasses out.
The public API (``__all__``, docs/api.md): the method as an estimator on plain arrays (:class:`QuasiEigenFaces`), the
readers, the real datasets' steps (``arkit_mapping``, ``stabilise_markers``, ...), ``build_captures``, ``run_study``
and ``read_record``.
"""

import os

from workbench.core.interrupt import exit_at_once_while_starting, started_as_command

if started_as_command():  # first, before the seconds of imports: Ctrl-C then is one line, not a traceback
    exit_at_once_while_starting()

# OpenBLAS's worker threads spin for about 2**28 cycles (~0.1 s) after every threaded call before they sleep.
# The compiled per-frame solvers run their own threads right after such a call (the projection of the frames),
# and the spinning workers halved their speed on a 2-core machine. 2**16 cycles keeps a short spin for
# back-to-back BLAS calls. It only takes effect when set before NumPy loads OpenBLAS; a value the user set wins.
os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "16")

from workbench.version import __version__  # noqa: E402, F401 - after the environment is set

# The public API, imported on first use (module ``__getattr__``, PEP 562): ``import workbench`` and the command's
# start-up stay free of NumPy, pandas and Hydra until a name below is used.
_PUBLIC = {
    "QuasiEigenFaces": "workbench.numerics.estimator",
    "NotFittedError": "workbench.numerics.estimator",
    "WorkbenchError": "workbench.core.errors",
    "read_c3d": "workbench.api",
    "read_livelink": "workbench.api",
    "read_weight_curves": "workbench.api",
    "read_obj": "workbench.api",
    "read_blendshapes": "workbench.api",
    "read_gltf": "workbench.api",
    "read_mesh_sequence": "workbench.api",
    "read_obj_sequence": "workbench.api",
    "arkit_mapping": "workbench.api",
    "rest_frame": "workbench.api",
    "stabilise_markers": "workbench.api",
    "read_marker_table": "workbench.api",
    "place_markers": "workbench.api",
    "rbf_carry": "workbench.api",
    "compose_config": "workbench.api",
    "build_captures": "workbench.api",
    "run_study": "workbench.api",
    "record_study": "workbench.api",
    "read_record": "workbench.api",
    "write_rig": "workbench.api",
}

__all__ = list(_PUBLIC)


def __getattr__(name: str):
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'workbench' has no attribute {name!r}")
    from importlib import import_module

    value = getattr(import_module(module), name)
    globals()[name] = value  # later uses skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
