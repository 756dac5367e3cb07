"""numba's ``njit`` and ``prange``, for every module of the workbench that compiles a loop.

numba is imported here once, with Ctrl-C held back until it has loaded: its C extension turns an interrupt during
its import into an ImportError and prints a traceback (seen: 'numba._devicearray failed to import') instead of the
command's one line.

The compiled kernels are cached on disk (``cache=True``: ``<name>-<line>.py<version>.nbi``, the index, and
``.<n>.nbc``, the machine code, in ``__pycache__`` beside the module, or under ``NUMBA_CACHE_DIR``). numba reads them
with ``pickle`` and lets any error out: a truncated, emptied or garbled file stopped every run that used the kernel
(``unexpected UnpicklingError``), again on every rerun, with nothing pointing at the cache. The ``njit`` here loads
through :class:`HealingCache`, which removes a damaged function's cache files, says so in one line naming the cache
folder, and compiles the function again (the new files are written as numba always writes them).
"""

from __future__ import annotations

import glob
import inspect
import os
import sys

from workbench.core.interrupt import interrupts_deferred

with interrupts_deferred():
    import numba
    from numba import prange
    from numba.core.caching import FunctionCache

__all__ = ["njit", "prange", "HealingCache"]

_reported: set[str] = set()
"""Cache folders already named on stderr in this process (one line per folder, however many files were damaged)."""


class HealingCache(FunctionCache):
    """numba's cache of one compiled function, loaded so that a damaged file costs a compilation, not the run.

    A file that cannot be read back (truncated, empty, garbage, a file of another numba version's layout), or that
    holds the compiled code of another function (two data files swapped), is removed with the function's other
    cache files; the function is then compiled as if it had never been cached, and the cache written anew.
    """

    def load_overload(self, sig, target_context):
        """The cached compiled function for ``sig``, or None (compile it) when there is none or it was damaged."""
        try:
            loaded = super().load_overload(sig, target_context)
        except Exception as error:  # noqa: BLE001 - whatever pickle or numba makes of a damaged file
            self.remove_damaged(f"{type(error).__name__}: {error}")
            return None
        fndesc = getattr(loaded, "fndesc", None)
        if fndesc is not None and (fndesc.qualname, fndesc.modname) != (
            self._py_func.__qualname__,
            self._py_func.__module__,
        ):
            self.remove_damaged(f"it holds {fndesc.modname}.{fndesc.qualname}, not this function")
            return None
        return loaded

    def save_overload(self, sig, data):
        """Save the compiled function; a damaged index in the way is removed first, and a cache that still cannot
        be written costs only the cache (the function is compiled and runs)."""
        try:
            super().save_overload(sig, data)
        except Exception as error:  # noqa: BLE001 - as in load_overload
            self.remove_damaged(f"{type(error).__name__}: {error}")
            try:
                super().save_overload(sig, data)
            except Exception:  # noqa: BLE001 - not cached this time; the next run tries again
                pass

    def cache_files(self) -> list[str]:
        """Paths of this function's index and data files."""
        index = self._cache_file._index_path
        pattern = glob.escape(index[: -len(".nbi")]) + ".*.nbc"
        return [index, *sorted(glob.glob(pattern))]

    def remove_damaged(self, reason: str) -> None:
        """Remove this function's cache files and say so, once per cache folder in this process."""
        removed = []
        for path in self.cache_files():
            try:
                os.unlink(path)
                removed.append(os.path.basename(path))
            except FileNotFoundError:
                pass
            except OSError:  # left for numba to overwrite
                pass
        if self._cache_path not in _reported:
            _reported.add(self._cache_path)
            shown = " ".join(str(reason).split())[:200]
            print(
                f"workbench: numba's compiled cache {self._cache_path}: the files of {self._py_func.__qualname__} "
                f"were damaged ({shown}); removed {', '.join(removed) or 'them'}, compiling again",
                file=sys.stderr,
            )


def _with_healing_cache(dispatcher):
    """``dispatcher`` loading its on-disk cache through :class:`HealingCache` (where it caches at all)."""
    if isinstance(getattr(dispatcher, "_cache", None), FunctionCache):
        dispatcher._cache = HealingCache(dispatcher.py_func)
    return dispatcher


def njit(*args, **options):
    """``numba.njit``, as a decorator with or without options (``@njit``, ``@njit(cache=True, parallel=True)``),
    its cache loaded through :class:`HealingCache`."""
    if len(args) == 1 and not options and inspect.isfunction(args[0]):
        return _with_healing_cache(numba.njit(args[0]))
    decorate = numba.njit(*args, **options)
    return lambda function: _with_healing_cache(decorate(function))
