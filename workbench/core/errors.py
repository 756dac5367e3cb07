"""The workbench's own error type, and the exit policy.

Every check at a boundary raises :class:`WorkbenchError` (a ``ValueError``) whose message names the input and
the rule it broke; the command line prints that message as one line (:func:`exit_on_error`).
"""

from __future__ import annotations

import sys
import traceback

from workbench.core.extras import missing_extra
from workbench.core.interrupt import (
    caused_by_interrupt,
    exit_status,
    forget_handled_interrupt,
    ignore_further_interrupts,
    signal_that_came,
)
from workbench.core.interrupt import message as interrupted_message

VERBOSE_FLAG = "--verbose"
_verbose = False


class WorkbenchError(ValueError):
    """Bad input or configuration: the message names the file, field or parameter and the rule it broke."""


def single_line(text) -> str:
    """A message as one line: its non-empty lines joined with '; ' (a library's text may span several)."""
    return "; ".join(line.strip() for line in str(text).splitlines() if line.strip())


def show_tracebacks() -> None:
    """``--verbose``: :func:`exit_on_error` prints the traceback before the one line."""
    global _verbose
    _verbose = True


def tracebacks_shown() -> bool:
    """Whether ``--verbose`` was given (:func:`show_tracebacks`)."""
    return _verbose


def exit_on_error(program: str, error: BaseException) -> None:
    """Print one line for ``error`` (the traceback too with ``--verbose``) and exit non-zero.

    A :class:`WorkbenchError` is bad input or configuration, and a fault of the environment (a file that cannot
    be read or written, a full disk, too little memory) is named with its path: both exit 2. Ctrl-C exits 130,
    SIGTERM 143 and SIGHUP 129 (128 + the signal).
    Anything else is unexpected (exit 3) and names its type, since its message alone may not say where it came
    from.
    """
    if isinstance(error, SystemExit):
        raise error
    if _verbose:
        traceback.print_exception(error, file=sys.stderr)
    if caused_by_interrupt(error):
        ignore_further_interrupts()  # a signal still pending (a compiled loop's) must not cut the exit short
        print(interrupted_message(signal_that_came(), program), file=sys.stderr)
        forget_handled_interrupt()
        sys.exit(exit_status(signal_that_came()))
    fault = environment_fault(error)
    if fault is not None:
        print(f"{program}: error: {single_line(fault)}", file=sys.stderr)
        sys.exit(2)
    hint = "" if _verbose else f" (run with {VERBOSE_FLAG} for the traceback)"
    print(f"{program}: error: unexpected {type(error).__name__}: {single_line(error)}{hint}", file=sys.stderr)
    sys.exit(3)


def environment_fault(error: BaseException) -> str | None:
    """The one-line message of bad input (:class:`WorkbenchError`) or of a fault of the environment (an
    optional dependency not installed, naming its extra; an ``OSError`` such as a denied permission or a full
    disk, naming its path; running out of memory), or None for anything else."""
    if isinstance(error, WorkbenchError):
        return str(error)
    missing = missing_extra(error)
    if missing is not None:
        return missing
    if isinstance(error, MemoryError):
        return (
            "out of memory (MemoryError); use a smaller dataset (dataset.n_frames, dataset.max_frames, "
            "dataset.frame_step, dataset.mesh_vertex_step)"
        )
    if isinstance(error, OSError) and error.strerror:
        paths = " -> ".join(str(path) for path in (error.filename, error.filename2) if path is not None)
        return f"{paths or 'a file of the run'}: {error.strerror}"
    return None


def check_utf8(text: str, what: str) -> None:
    """Refuse a name or path that is not valid UTF-8 (Python keeps such bytes as lone surrogates, which no file of
    a record can hold): one line naming ``what`` and the first bad byte, before anything is computed.

    Raises
    ------
    WorkbenchError
    """
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as error:
        character = text[error.start]
        byte = f"0x{ord(character) - 0xDC00:02x}" if 0xDC80 <= ord(character) <= 0xDCFF else repr(character)
        shown = text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
        raise WorkbenchError(
            f"{what} '{shown}' is not valid UTF-8 (byte {byte} at position {error.start}); "
            "name files, folders and settings in UTF-8"
        ) from None
