"""The ``workbench`` command run inside the test process: what a test of the command line needs, without the seconds
a new interpreter spends importing NumPy, Hydra and pandas and compiling the solvers.

A child process is kept where the process itself is what a test checks (signals and kills, exit at start-up, the
installed command, packaging, concurrency, the cluster). Everything the command changes in the process is put back
afterwards: the arguments, the working folder, the environment, the signal handlers, the verbose flag, the logging
handlers Hydra's job logging adds and Hydra's global state. Each call starts, as a new process would, with the
dataset stage's memory (the captures built and the file digests of earlier calls) empty.
"""

from __future__ import annotations

import io
import logging
import os
import signal
import sys
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

from workbench.cli import main as cli
from workbench.cli import sweep_failures
from workbench.core import errors
from workbench.dataset import cache

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


@dataclass
class Done:
    """What ``subprocess.run(..., capture_output=True, text=True)`` returns, as far as the tests read it."""

    args: list[str]
    returncode: int
    stdout: str
    stderr: str = field(repr=False)


def _loggers() -> dict[str, logging.Logger]:
    found = {
        name: logger for name, logger in logging.Logger.manager.loggerDict.items() if isinstance(logger, logging.Logger)
    }
    return {"": logging.getLogger(), **found}


def run_workbench(*args, cwd: str | Path, env: Mapping[str, str | None] | None = None) -> Done:
    """Run ``workbench ARGS`` in ``cwd`` inside this process, with ``env`` set on top of the environment (None
    removes a variable); returns its exit code and what it printed."""
    from hydra.core.global_hydra import GlobalHydra

    arguments = [str(arg) for arg in args]
    saved_argv, saved_cwd, saved_environ = sys.argv[:], os.getcwd(), dict(os.environ)
    saved_signals = {number: signal.getsignal(number) for number in SIGNALS}
    saved_loggers = {
        name: (logger.handlers[:], logger.level, logger.propagate, logger.disabled)
        for name, logger in _loggers().items()
    }
    saved_verbose, saved_main = errors._verbose, sweep_failures.MAIN_PROCESS
    out, err = io.StringIO(), io.StringIO()
    cache._memory.clear()
    cache._digests.clear()
    try:
        for name, value in (env or {}).items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = str(value)
        os.chdir(cwd)
        sys.argv = ["workbench", *arguments]
        with redirect_stdout(out), redirect_stderr(err):
            try:
                cli.main()
                code = 0
            except SystemExit as stop:
                if stop.code is None or isinstance(stop.code, int):
                    code = stop.code or 0
                else:
                    print(stop.code, file=sys.stderr)
                    code = 1
    finally:
        sys.argv = saved_argv
        os.chdir(saved_cwd)
        os.environ.clear()
        os.environ.update(saved_environ)
        for number, handler in saved_signals.items():
            signal.signal(number, handler)
        for name, logger in _loggers().items():
            handlers, level, propagate, disabled = saved_loggers.get(name, ([], logging.NOTSET, True, False))
            for handler in logger.handlers:
                if handler not in handlers:
                    handler.close()
            logger.handlers[:] = handlers
            logger.setLevel(level)
            logger.propagate, logger.disabled = propagate, disabled
        errors._verbose, sweep_failures.MAIN_PROCESS = saved_verbose, saved_main
        GlobalHydra.instance().clear()
    return Done(["workbench", *arguments], code, out.getvalue(), err.getvalue())
