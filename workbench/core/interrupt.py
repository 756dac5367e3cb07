"""Ctrl-C on the command line: one line and exit status 130, whenever it comes; SIGTERM (what ``kill``, ``timeout``,
SLURM and systemd send) and SIGHUP (the terminal closed) likewise, with their own status (143, 129).

Starting the command takes seconds of imports (Hydra, pandas, SciPy, numba) before the command's own error handling
is in place; a Ctrl-C then would print Python's traceback of whatever was being imported. So the package installs
:func:`exit_at_once` first thing when it is started as the ``workbench`` command (nothing has been written yet, so
there is nothing to clean up), and the command switches back to Python's ``KeyboardInterrupt`` (:func:`raise_from_now_on`)
where its handlers take over: from then on an interrupted run removes what it wrote before it exits. A SIGINT the
parent process ignores (``nohup``, a background job) stays ignored. SIGTERM and SIGHUP take the same course: they
too raise ``KeyboardInterrupt``, so every clean-up that Ctrl-C runs runs for them, and only the last line and the
exit status say which signal came. This module imports nothing beyond the
standard library, so that it is in place within milliseconds.
"""

import os
import signal
import sys
from contextlib import contextmanager

INTERRUPTED = 130
"""Exit code after Ctrl-C (128 + SIGINT), as shells report it."""
MESSAGE = "workbench: interrupted; rerun the same command to resume"
SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
"""The signals that stop the command cleanly (SIGHUP does not exist on Windows)."""


def exit_status(signum: int = signal.SIGINT) -> int:
    """The exit status after signal ``signum``, as shells report a process it ended: 128 + its number."""
    return 128 + int(signum)


def message(signum: int = signal.SIGINT, program: str = "workbench") -> str:
    """The one line after signal ``signum``: :data:`MESSAGE` for Ctrl-C, naming the signal for the others."""
    if signum == signal.SIGINT:
        return MESSAGE.replace("workbench", program, 1)
    return f"{program}: stopped by {signal.Signals(signum).name}; rerun the same command to resume"


def _default_handler(signum: int):
    """The handler Python starts with for ``signum``."""
    return signal.default_int_handler if signum == signal.SIGINT else signal.SIG_DFL


def started_as_command() -> bool:
    """Whether this process is the ``workbench`` command (``workbench ...`` or ``python -m workbench ...``), not a
    program importing the package (a test, a notebook), whose own Ctrl-C must keep working."""
    main_file = getattr(sys.modules.get("__main__"), "__file__", None) or ""
    return sys.argv[:1] == ["-m"] or os.path.basename(main_file) == "workbench"


def exit_at_once(signum, frame) -> None:
    """Handler of :data:`SIGNALS` while the command starts: the one line, exit 128 + the signal, no traceback."""
    os.write(2, (message(signum) + "\n").encode())
    os._exit(exit_status(signum))


def exit_at_once_while_starting() -> None:
    """Install :func:`exit_at_once` for each of :data:`SIGNALS` that is neither ignored nor handled by someone
    else."""
    for signum in SIGNALS:
        if signal.getsignal(signum) is _default_handler(signum):
            signal.signal(signum, exit_at_once)


_interrupt_came = False
"""Whether :func:`raise_keyboard_interrupt` has run in this process."""
_signal_came = signal.SIGINT
"""The signal it ran for last (what the exit status and the last line name)."""


def raise_keyboard_interrupt(signum, frame) -> None:
    """Handler of :data:`SIGNALS` once the command's handlers are in place: Python's ``KeyboardInterrupt``,
    remembered, so that an error a library makes of the interrupt is still reported as the interrupt
    (:func:`caused_by_interrupt`), with the signal that came. Seen: a Ctrl-C while numba's C extension loads becomes
    ``ImportError('numba._devicearray failed to import')``, which Hydra reports as a config target it could not
    locate."""
    global _interrupt_came, _signal_came
    _interrupt_came, _signal_came = True, signum
    raise KeyboardInterrupt


def signal_that_came() -> int:
    """The signal :func:`raise_keyboard_interrupt` last ran for (SIGINT when none came: a ``KeyboardInterrupt``
    raised in Python, a test's)."""
    return _signal_came if _interrupt_came else signal.SIGINT


def raise_from_now_on() -> None:
    """Ctrl-C, SIGTERM and SIGHUP raise ``KeyboardInterrupt`` again (the command's handlers are in place), and an
    interrupt that Python would swallow is raised again where it can be caught (:func:`keep_swallowed_interrupt`)."""
    switched = False
    for signum in SIGNALS:
        if signal.getsignal(signum) is exit_at_once:
            signal.signal(signum, raise_keyboard_interrupt)
            switched = True
    if switched and sys.unraisablehook is not keep_swallowed_interrupt:
        global _previous_unraisablehook
        _previous_unraisablehook, sys.unraisablehook = sys.unraisablehook, keep_swallowed_interrupt


_previous_unraisablehook = sys.__unraisablehook__
"""The hook :func:`keep_swallowed_interrupt` hands every other unraisable exception to."""


def keep_swallowed_interrupt(unraisable) -> None:
    """``sys.unraisablehook`` of the command: a ``KeyboardInterrupt`` raised where Python cannot propagate it is
    raised again as soon as Python code runs outside this hook, instead of being printed as ignored and lost.

    Seen: a Ctrl-C while a module is imported came while importlib's weak-reference callback that drops the
    module's lock ran; Python printed "Exception ignored in: <function _get_module_lock.<locals>.cb>" with a
    traceback and the command went on as if no Ctrl-C had come. A signal cannot be sent again from here (its handler
    would run inside this hook, whose exceptions Python also ignores), so a one-shot profile function raises it at
    the next call or return. Any other unraisable exception goes to the hook that was in place."""
    if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
        sys.setprofile(_raise_swallowed_interrupt)
    else:
        _previous_unraisablehook(unraisable)


def _raise_swallowed_interrupt(frame, event, arg) -> None:
    """One-shot profile function of :func:`keep_swallowed_interrupt`: raise the interrupt at the first event
    outside that hook (its own return is the first event it sees)."""
    if frame.f_code is keep_swallowed_interrupt.__code__:
        return
    sys.setprofile(None)
    raise KeyboardInterrupt


def ignore_further_interrupts() -> None:
    """Ignore :data:`SIGNALS` from now on: the command has done its work (or cleaned up after an interrupt) and
    only its last line and exit remain, which a signal, or one still pending from a compiled loop, would only cut
    short."""
    try:
        for signum in SIGNALS:
            signal.signal(signum, signal.SIG_IGN)
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
    """Hold :data:`SIGNALS` back while a step that must not be cut in two runs (a store's schema being set up, a
    compiled function's results being handed back to Python), then act on the first that came: it is handed to
    the handler that was in place (``KeyboardInterrupt``, or the start-up's :func:`exit_at_once`) as the step ends,
    so it is never lost, nor raised where a library would only print it as ignored; a signal whose handler was the
    default is sent again, to end the process as it would have. A signal that is ignored stays ignored; outside the
    main thread nothing is held back."""
    came = []
    previous = {}
    for signum in SIGNALS:
        handler = signal.getsignal(signum)
        if handler is signal.SIG_IGN:
            continue
        try:
            signal.signal(signum, lambda number, frame: came.append((number, frame)))
        except ValueError:  # not the main thread: signals are handled there only
            break
        previous[signum] = handler
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler if handler is not None else _default_handler(signum))
        if came:
            signum, frame = came[0]
            handler = previous[signum]
            if callable(handler):
                handler(signum, frame)
            elif signum == signal.SIGINT:  # SIG_DFL, or a handler not installed from Python
                raise KeyboardInterrupt
            else:
                os.kill(os.getpid(), signum)
