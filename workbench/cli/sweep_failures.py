"""The runs of a sweep that failed once started (a bad value refuses the whole sweep before it starts:
:func:`workbench.record.tracking.check_sweep_values`): the sweep goes on with its other runs and, when every run
has ended, names the failed ones in one line and exits non-zero (2 for bad input, 3 when a run failed
unexpectedly).

Jobs that run in the workbench's own process (Hydra's basic launcher, the default) keep their failure here and
return; the command line then prints the closing line (:func:`exit_if_runs_failed`). A job in another process (the
joblib or SLURM launchers) prints its own line and raises :class:`SweepRunFailed`, which Hydra's sweeper raises
once the batch has ended; the closing line then names the first failure.
"""

from __future__ import annotations

import os
import sys

from workbench.core.errors import WorkbenchError

AGAIN = "fix what each names and run the sweep again (complete runs are skipped)"


class SweepRunFailed(WorkbenchError):
    """A run of a sweep failed: ``run`` names it (its folder, which lists its overrides), ``code`` is the exit
    code its failure alone would have given."""

    def __init__(self, run: str, message: str, code: int):
        super().__init__(f"run {run}: {message}")
        self.run, self.message, self.code = run, message, code

    def __reduce__(self):  # a launcher returns a job's exception from another process
        return SweepRunFailed, (self.run, self.message, self.code)


FAILED: list[SweepRunFailed] = []
"""The failed runs of the sweep running in this process, in the order they ended."""
MAIN_PROCESS: int | None = None
"""The process id of the command line (set by :func:`workbench.cli.main.main`); a job elsewhere raises its failure."""


def sweep_run_failed(run: str, message: str, code: int) -> None:
    """Keep a failed run (in the command line's process) or print it and raise it (in another process).

    Raises
    ------
    SweepRunFailed
        In a process other than the command line's.
    """
    failure = SweepRunFailed(run, message, code)
    if MAIN_PROCESS == os.getpid():
        FAILED.append(failure)
        return
    print(f"workbench: error: {failure}", file=sys.stderr, flush=True)
    raise failure


def closing_line(first: SweepRunFailed | None = None) -> tuple[str, int] | None:
    """The sweep's closing line and exit code once every run has ended, or None when no run failed (``first``:
    the failure Hydra raised from a job in another process)."""
    if FAILED:
        runs = " | ".join(str(failure) for failure in FAILED)
        return (
            f"{len(FAILED)} run(s) of the sweep failed, every other run ran: {runs}; {AGAIN}",
            max(failure.code for failure in FAILED),
        )
    if first is not None:
        return (
            f"runs of the sweep failed, each named above (the first: {first.run}), every other run ran; {AGAIN}",
            first.code,
        )
    return None


def exit_if_runs_failed(first: SweepRunFailed | None = None) -> None:
    """Print the closing line and exit when a run of the sweep failed."""
    closing = closing_line(first)
    if closing is not None:
        print(f"workbench: error: {closing[0]}", file=sys.stderr)
        sys.exit(closing[1])
