"""The columns the workbench prints in: every printed line within :data:`PRINT_WIDTH` (:func:`fit_width`), or, with
``workbench --wide``, the full text whole (:func:`print_whole`, :func:`printed`)."""

from __future__ import annotations

import textwrap

PRINT_WIDTH = 120
"""The columns a run's and a sweep's printed text fits in by default; ``workbench --wide`` prints the full text (the
record's ``alpha_table.md`` and a sweep's ``collected/`` files hold it)."""
_whole = {"wide": False}


def fit_width(text: str, width: int = PRINT_WIDTH) -> str:
    """``text`` with every line longer than ``width`` wrapped at spaces, its continuations indented two spaces more
    than it; table lines (starting with ``|``) are left whole, and so is a word longer than ``width`` (a folder's
    name); one that would leave the line's first word alone (``done``) joins it.

    Parameters
    ----------
    text : str
    width : int

    Returns
    -------
    str
    """
    lines = []
    for line in text.split("\n"):
        if len(line) <= width or line.startswith("|"):
            lines.append(line)
            continue
        indent = line[: len(line) - len(line.lstrip(" "))]
        wrapped = textwrap.wrap(
            line.strip(),
            width,
            initial_indent=indent,
            subsequent_indent=indent + "  ",
            break_long_words=False,
            break_on_hyphens=False,
        )
        if len(wrapped) > 1 and " " not in wrapped[0].strip():  # "done" alone: the name after it is too long anyway
            wrapped[:2] = [wrapped[0] + " " + wrapped[1].strip()]
        lines += wrapped
    return "\n".join(lines)


def print_whole(wide: bool) -> None:
    """Whether :func:`printed` leaves text whole (``workbench --wide``), for the rest of the process."""
    _whole["wide"] = bool(wide)


def printed(text: str) -> str:
    """``text`` as the workbench prints it: within :data:`PRINT_WIDTH` columns, or whole after
    ``print_whole(True)``."""
    return text if _whole["wide"] else fit_width(text)
