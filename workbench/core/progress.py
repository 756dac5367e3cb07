"""Progress bars on long steps, shown only when a person watches (stderr is a terminal)."""

from __future__ import annotations

import sys
from typing import Iterable, TypeVar

T = TypeVar("T")


def progress(items: Iterable[T], *, desc: str = "", total: int | None = None) -> Iterable[T]:
    """``items`` wrapped in a tqdm bar on a terminal, unchanged otherwise (logs, CI, pipes stay quiet).

    Parameters
    ----------
    items : iterable
    desc : str
        Label in front of the bar.
    total : int, optional
        Length, when ``items`` has none.
    """
    if not sys.stderr.isatty():
        return items
    from tqdm import tqdm

    return tqdm(items, desc=desc, total=total, leave=False, file=sys.stderr, dynamic_ncols=True)
