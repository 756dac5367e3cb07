"""The servers the suite starts (the MLflow tracking server), kept from outliving the test run that started them.

A server runs under a guard (``python tests/servers.py guard ...``): the guard leads a process group of its own
with the server in it, and ends the whole group when the server ends, when the guard gets SIGTERM or SIGINT, or
when a pytest process that owns the server is gone (the test process, and under pytest-xdist also the controller
that started it). So a server goes away however the run ends: a normal teardown, Ctrl-C, SIGTERM, or SIGKILL of
pytest, where no teardown runs at all.

Every process of a server carries ``WORKBENCH_TEST_SERVER=<id>`` in its environment, and a pid file
``<registry>/<id>.json`` names the id, the guard and the owners. Should a guard itself be killed (SIGKILL), its
server is left; the next test session finds it through the pid file and ends it (:func:`clean_stale`), taking as
the server's only the processes that carry its id, never another process that happens to reuse a number.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

MARK = "WORKBENCH_TEST_SERVER"
POLL_SECONDS = 0.2
GRACE_SECONDS = 10.0


def sigint_at_default() -> None:
    """A child's ``preexec_fn``: SIGINT at its default action, as a terminal's Ctrl-C finds a command, whatever the
    test process has it set to (a suite started as a background job of a shell without job control inherits SIGINT
    ignored, and a process started with SIGINT ignored keeps ignoring it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def registry() -> Path:
    """The folder of the pid files of the suite's servers, under the temporary folder, one per user."""
    return Path(tempfile.gettempdir()) / f"workbench-tests-{os.getuid()}" / "servers"


def start_time(pid: int) -> int | None:
    """When process ``pid`` started (clock ticks since boot, field 22 of ``/proc/<pid>/stat``); None if it is gone.

    A process is named by its pid and start time, so a pid reused by a later process is not taken for it."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return int(stat[stat.rindex(")") + 2 :].split()[19])


def alive(owner: tuple[int, int | None]) -> bool:
    """Whether ``owner`` (pid, start time) is still the process it was."""
    pid, started = owner
    now = start_time(pid)
    return now is not None and (started is None or now == started)


def owners_of_this_process() -> list[tuple[int, int | None]]:
    """This pytest process, and under pytest-xdist the controller that started it (its parent)."""
    pids = [os.getpid()] + ([os.getppid()] if os.environ.get("PYTEST_XDIST_WORKER") else [])
    return [(pid, start_time(pid)) for pid in pids]


def processes_of(server_id: str) -> list[int]:
    """The pids of the processes whose environment carries ``WORKBENCH_TEST_SERVER=<server_id>``."""
    wanted = f"{MARK}={server_id}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            environment = (entry / "environ").read_bytes()
        except OSError:
            continue
        if wanted in environment.split(b"\0"):
            found.append(int(entry.name))
    return found


def end_processes(pids: list[int], grace: float = GRACE_SECONDS) -> None:
    """SIGTERM to ``pids``, then SIGKILL to those still there after ``grace`` seconds."""
    for number in (signal.SIGTERM, signal.SIGKILL):
        for pid in pids:
            try:
                os.kill(pid, number)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + grace
        while number == signal.SIGTERM and time.monotonic() < deadline:
            if all(start_time(pid) is None or _zombie(pid) for pid in pids):
                return
            time.sleep(POLL_SECONDS)


def _zombie(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True
    return stat[stat.rindex(")") + 2] == "Z"


def clean_stale(folder: Path | None = None) -> list[str]:
    """End the servers of earlier test runs whose owners are all gone, and remove their pid files.

    Returns
    -------
    list of str
        The ids of the servers found stale (their processes ended, if any were left).
    """
    folder = folder or registry()
    stale = []
    for pid_file in sorted(folder.glob("*.json")) if folder.is_dir() else []:
        try:
            entry = json.loads(pid_file.read_text())
            owners = [tuple(owner) for owner in entry["owners"]]
            server_id = entry["id"]
        except (OSError, ValueError, KeyError, TypeError):
            continue  # being written by a session starting now, or not one of ours
        if any(alive(owner) for owner in owners):
            continue
        end_processes(processes_of(server_id))
        pid_file.unlink(missing_ok=True)
        stale.append(server_id)
    return stale


def start_guarded(command: list[str], log: Path, env: dict | None = None) -> tuple[subprocess.Popen, str]:
    """Start ``command`` under a guard owned by this pytest process; its output goes to ``log``.

    Returns
    -------
    subprocess.Popen, str
        The guard (its pid is the server's process group) and the server's id.
    """
    server_id = uuid.uuid4().hex
    owners = owners_of_this_process()
    folder = registry()
    folder.mkdir(parents=True, exist_ok=True)
    pid_file = folder / f"{server_id}.json"
    written = folder / f".{server_id}.tmp"
    written.write_text(json.dumps({"id": server_id, "owners": owners, "command": command}))
    os.replace(written, pid_file)
    arguments = [arg for pid, started in owners for arg in ("--owner", f"{pid}:{started}")]
    with open(log, "wb") as out:
        guard = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), "guard", *arguments, "--", *command],
            env={**(env or os.environ), MARK: server_id},
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    return guard, server_id


def stop_guarded(guard: subprocess.Popen, server_id: str) -> None:
    """End a server started by :func:`start_guarded`, every process of it, and remove its pid file."""
    if guard.poll() is None:
        guard.send_signal(signal.SIGTERM)
        try:
            guard.wait(timeout=GRACE_SECONDS + 5)
        except subprocess.TimeoutExpired:
            os.killpg(guard.pid, signal.SIGKILL)
            guard.wait()
    end_processes(processes_of(server_id))
    (registry() / f"{server_id}.json").unlink(missing_ok=True)


def guard(owners: list[tuple[int, int | None]], command: list[str]) -> int:
    """Run ``command`` in this process's group; end the group when it ends, on SIGTERM or SIGINT, or once an
    owner is gone. Returns the exit code to leave with."""
    stop = []
    for number in (signal.SIGTERM, signal.SIGINT):
        signal.signal(number, lambda received, frame: stop.append(received))
    server = subprocess.Popen(command)
    while server.poll() is None and not stop and all(alive(owner) for owner in owners):
        time.sleep(POLL_SECONDS)
    if server.poll() is not None:
        return server.returncode
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the guard outlives the group's SIGTERM to escalate
    os.killpg(0, signal.SIGTERM)
    try:
        server.wait(timeout=GRACE_SECONDS)
    except subprocess.TimeoutExpired:
        pass
    os.killpg(0, signal.SIGKILL)  # what is still there, the guard with it
    return 0


def main(arguments: list[str]) -> int:
    """``guard --owner PID:START [--owner ...] -- COMMAND...``"""
    split = arguments.index("--")
    options, command = arguments[:split], arguments[split + 1 :]
    flags, values = options[1::2], options[2::2]
    if options[:1] != ["guard"] or not command or len(flags) != len(values) or set(flags) - {"--owner"}:
        sys.exit(f"usage: {sys.argv[0]} guard --owner PID:START [--owner PID:START] -- COMMAND")
    owners = []
    for value in values:
        pid, _, started = value.partition(":")
        owners.append((int(pid), None if started in ("", "None") else int(started)))
    return guard(owners, command)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
