"""numba's ``njit`` and ``prange``, for every module of the workbench that compiles a loop.

numba is imported here once, with Ctrl-C held back until it has loaded: its C extension turns an interrupt during
its import into an ImportError and prints a traceback (seen: 'numba._devicearray failed to import') instead of the
command's one line.
"""

from workbench.core.interrupt import interrupts_deferred

with interrupts_deferred():
    from numba import njit, prange

__all__ = ["njit", "prange"]
