"""The first minutes on a fresh clone: what the README's commands cost before any cache is warm, and after.

Run from the repository root (Python's standard library only; it installs the workbench into the clone's own
virtual environment):

    python3 benchmarks/first_minute.py                 # install, first run, a later run, workbench report
    python3 benchmarks/first_minute.py --tests         # and the tests' inner loop: pytest -m "not slow", cold

It clones the checkout's committed HEAD into a temporary folder (``../shared`` linked beside it when the checkout
has one, so the real data are found), then times each step as a child process in that clone: the README's install
(``pip install -e .``; pip's own download cache is whatever this machine has, so a first install anywhere also
downloads), the paper study's first run (numba compiles the solvers' kernels and the synthetic actor's muscle
model and caches them beside the modules, ``NUMBA_CACHE_DIR`` unset), a later run (the compiled cache in place),
the report extra's install and ``workbench report`` of the last run; with ``--tests``, in a second fresh clone,
the test extras' install and ``pytest -m "not slow"`` (the README's test command with the inner loop's marker;
its exit code is printed with it). For each step it prints the wall time, the CPU time (user + system of the
step's processes) and the load average when it started; wall time grows with whatever else the machine runs, CPU
time much less. The clones are removed at the end unless ``--keep``.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

STEPS = [
    ("install", "python3 -m venv .venv && .venv/bin/pip install -q -e ."),
    ("first run", ".venv/bin/workbench"),
    ("later run", ".venv/bin/workbench"),
    ("install report extra", ".venv/bin/pip install -q -e '.[report]'"),
    ("workbench report", '.venv/bin/workbench report "$(ls -d outputs/paper/*/ | tail -1)"'),
]
TEST_STEPS = [
    ("install test extras", "python3 -m venv .venv && .venv/bin/pip install -q -e '.[test,mlflow]'"),
    ("pytest -m 'not slow'", ".venv/bin/pytest -m 'not slow' -q -p no:cacheprovider"),
]


def timed(command: str, cwd: Path, log: Path) -> tuple[float, float, float, int]:
    """Run ``command`` in bash in ``cwd``, its output appended to ``log``.

    Returns
    -------
    tuple of float, float, float, int
        Wall seconds, CPU seconds (user + system of every child process that ended), the one-minute load average
        when it started, and the exit code.
    """
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.monotonic()
    with open(log, "a") as out:
        out.write(f"\n$ {command}\n")
        out.flush()
        done = subprocess.run(["bash", "-c", command], cwd=cwd, stdout=out, stderr=subprocess.STDOUT)
    wall = time.monotonic() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, load, done.returncode


def measure(steps: list[tuple[str, str]], clone: Path, log: Path) -> None:
    """Clone the checkout's HEAD into ``clone`` and print one row per step run in it; stop at a failed install or
    run (a failed test run is printed with its exit code)."""
    subprocess.run(["git", "clone", "-q", str(REPO), str(clone)], check=True)
    for name, command in steps:
        wall, cpu, load, code = timed(command, clone, log)
        status = "" if code == 0 else f" (exit code {code})"
        shown = command.replace("|", "\\|")  # a cell of a Markdown table
        print(f"| {name} | `{shown}`{status} | {wall:.0f} s | {cpu:.0f} s | {load:.1f} |", flush=True)
        if code != 0 and not command.startswith(".venv/bin/pytest"):
            sys.exit(f"first_minute: '{command}' failed with exit code {code}; its output is in {log}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tests", action="store_true", help="also time the tests' inner loop on a cold clone")
    parser.add_argument("--keep", action="store_true", help="keep the temporary clone")
    args = parser.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="workbench-first-minute-"))
    if (REPO.parent / "shared").exists():
        (scratch / "shared").symlink_to((REPO.parent / "shared").resolve())
    os.environ.pop("NUMBA_CACHE_DIR", None)  # the compiled cache beside the clone's modules, empty at first
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    print(f"fresh clones of {commit.stdout.strip()} in {scratch}, {os.cpu_count()} CPUs; output in {scratch / 'log'}")
    print("| step | command | wall time | CPU time | load at start |\n|---|---|---:|---:|---:|")
    measure(STEPS, scratch / "checkout", scratch / "log")
    if args.tests:
        measure(TEST_STEPS, scratch / "checkout-tests", scratch / "log")
    if not args.keep:
        shutil.rmtree(scratch)


if __name__ == "__main__":
    main()
