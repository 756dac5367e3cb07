"""Ctrl-C on the command line: one line and exit status 130, whenever it comes.

Starting the command takes seconds of imports (Hydra, pandas, SciPy, numba) before the command's own error handling
is in place; a Ctrl-C then would print Python's traceback of whatever was being imported. So the package installs
:func:`exit_at_once` first thing when it is started as the ``workbench`` command (nothing has been written yet, so
there is nothing to clean up), and the command switches back to Python's ``KeyboardInterrupt`` (:func:`raise_from_now_on`)
where its handlers take over: from then on an interrupted run removes what it wrote before it exits. A SIGINT the
parent process ignores (``nohup``, a background job) stays ignored. This module imports nothing beyond the
standard library, so that it is in place within milliseconds.
"""

import os
import signal
import sys
from contextlib import contextmanager

INTERRUPTED = 130
"""Exit code after Ctrl-C (128 + SIGINT), as shells report it."""
MESSAGE = "workbench: interrupted; rerun the same command to resume"


def started_as_command() -> bool:
    """Whether this process is the ``workbench`` command (``workbench ...`` or ``python -m workbench ...``), not a
    program importing the package (a test, a notebook), whose own Ctrl-C must keep working."""
    main_file = getattr(sys.modules.get("__main__"), "__file__", None) or ""
    return sys.argv[:1] == ["-m"] or os.path.basename(main_file) == "workbench"


def exit_at_once(signum, frame) -> None:
    """SIGINT handler while the command starts: the one line, exit 130, no traceback."""
    os.write(2, (MESSAGE + "\n").encode())
    os._exit(INTERRUPTED)


def exit_at_once_while_starting() -> None:
    """Install :func:`exit_at_once` unless SIGINT is ignored or handled by someone else."""
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, exit_at_once)


_interrupt_came = False
"""Whether :func:`raise_keyboard_interrupt` has run in this process."""


def raise_keyboard_interrupt(signum, frame) -> None:
    """SIGINT handler once the command's handlers are in place: Python's ``KeyboardInterrupt``, remembered, so that
    an error a library makes of the interrupt is still reported as the interrupt (:func:`caused_by_interrupt`).
    Seen: a Ctrl-C while numba's C extension loads becomes ``ImportError('numba._devicearray failed to import')``,
    which Hydra reports as a config target it could not locate."""
    global _interrupt_came
    _interrupt_came = True
    raise KeyboardInterrupt


def raise_from_now_on() -> None:
    """Ctrl-C raises ``KeyboardInterrupt`` again (the command's handlers are in place)."""
    if signal.getsignal(signal.SIGINT) is exit_at_once:
        signal.signal(signal.SIGINT, raise_keyboard_interrupt)


def ignore_further_interrupts() -> None:
    """Ignore Ctrl-C from now on: the command has done its work (or cleaned up after an interrupt) and only its
    last line and exit remain, which a Ctrl-C, or a signal still pending from a compiled loop, would only cut
    short."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: nothing to ignore here
        pass


def forget_handled_interrupt() -> None:
    """Keep exit status 130 after a Ctrl-C the command has handled.

    CPython (3.8-3.12) sets a private flag when a ``KeyboardInterrupt`` ends code it runs through its ``PyRun_*``
    functions, and a program started with ``-m`` (as the command is) then kills itself with SIGINT at exit, whatever
    status it exits with: its caller sees "killed by SIGINT" (a shell reports 130 for both). Seen in a few runs
    interrupted in their first seconds, after the command had caught the interrupt. Where the flag is not exported
    (other versions, other implementations) nothing changes.
    """
    try:
        import ctypes

        ctypes.c_int.in_dll(ctypes.pythonapi, "_Py_UnhandledKeyboardInterrupt").value = 0
    except (ImportError, AttributeError, ValueError, OSError):
        pass


def caused_by_interrupt(error: BaseException) -> bool:
    """Whether ``error`` is a ``KeyboardInterrupt`` or was raised because of one: a compiled function (numba)
    interrupted by Ctrl-C returns with the interrupt pending, which Python reports as a ``SystemError`` whose
    cause is the ``KeyboardInterrupt``. Once the command's Ctrl-C has come (:func:`raise_keyboard_interrupt`), any
    error is its consequence, whatever a library made of it."""
    if _interrupt_came:
        return True
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, KeyboardInterrupt):
            return True
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return False


@contextmanager
def interrupts_deferred():
    """Hold Ctrl-C back while a step that must not be cut in two runs (a store's schema being set up, a compiled
    function's results being handed back to Python), then act on it: a SIGINT that came meanwhile is handed to the
    handler that was in place (``KeyboardInterrupt``, or the start-up's :func:`exit_at_once`) as the step ends, so
    it is never lost, nor raised where a library would only print it as ignored. A SIGINT that is ignored stays
    ignored; outside the main thread nothing is held back."""
    came = []
    previous = signal.getsignal(signal.SIGINT)
    held = previous is not signal.SIG_IGN
    if held:
        try:
            signal.signal(signal.SIGINT, lambda signum, frame: came.append(frame))
        except ValueError:  # not the main thread: signals are handled there only
            held = False
    try:
        yield
    finally:
        if held:
            signal.signal(signal.SIGINT, previous if previous is not None else signal.default_int_handler)
            if came:
                if callable(previous):
                    previous(signal.SIGINT, came[0])
                else:  # SIG_DFL, or a handler not installed from Python
                    raise KeyboardInterrupt
