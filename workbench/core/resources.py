"""The machine's resources a run needs: refuse a dataset too large for memory before allocating it."""

from __future__ import annotations

import os

from workbench.core.errors import WorkbenchError

FLOAT_BYTES = 8


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux ``MemAvailable``; free pages elsewhere), or None when
    the system does not say."""
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def require_memory(n_values: int, what: str, settings: str) -> None:
    """Refuse up front when ``n_values`` float64 values would not fit in the memory available.

    Parameters
    ----------
    n_values : int
        Values the dataset will hold (frames x points x 3, summed over its arrays).
    what : str
        What is being built, for the message.
    settings : str
        The settings that decide the size, for the message.

    Raises
    ------
    WorkbenchError
    """
    available = available_memory()
    needed = int(n_values) * FLOAT_BYTES
    if available is not None and needed > available:
        raise WorkbenchError(
            f"{what} would need about {needed / 2**30:.1f} GiB of memory but "
            f"{available / 2**30:.1f} GiB is available; reduce {settings}"
        )
