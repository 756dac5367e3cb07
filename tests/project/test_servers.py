"""The suite's servers never outlive the run that started them: not after SIGTERM to pytest, not after a kill."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from servers import MARK, clean_stale, processes_of, sigint_at_default, start_time

from workbench.settings.config import REPO_ROOT

pytestmark = pytest.mark.process

SLEEPER = [sys.executable, "-c", "import time; time.sleep(600)"]


def wait_until(condition, timeout=60.0):
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.2)
    return True


def pid_file(folder: Path, server_id: str, owners: list) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{server_id}.json").write_text(json.dumps({"id": server_id, "owners": owners, "command": SLEEPER}))


def test_a_server_whose_owners_are_gone_is_ended_at_the_next_start_and_a_live_ones_is_kept(tmp_path):
    folder = tmp_path / "servers"
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone_owner = [gone.pid, start_time(gone.pid)]
    gone.wait()
    stale = subprocess.Popen(SLEEPER, env=dict(os.environ, **{MARK: "stale"}))
    kept = subprocess.Popen(SLEEPER, env=dict(os.environ, **{MARK: "kept"}))
    try:
        pid_file(folder, "stale", [gone_owner])
        pid_file(folder, "kept", [[os.getpid(), start_time(os.getpid())]])
        assert processes_of("stale") == [stale.pid]

        assert clean_stale(folder) == ["stale"]

        assert stale.wait(timeout=30) == -signal.SIGTERM
        assert not (folder / "stale.json").exists()
        assert kept.poll() is None and (folder / "kept.json").is_file()
    finally:
        for process in (stale, kept):
            process.kill()
            process.wait()


def test_a_reused_pid_is_not_taken_for_the_owner(tmp_path):
    folder = tmp_path / "servers"
    stale = subprocess.Popen(SLEEPER, env=dict(os.environ, **{MARK: "reused"}))
    try:
        pid_file(folder, "reused", [[os.getpid(), start_time(os.getpid()) - 1]])  # this pid, another process's start
        assert clean_stale(folder) == ["reused"]
        assert stale.wait(timeout=30) == -signal.SIGTERM
    finally:
        stale.kill()
        stale.wait()


def test_the_guard_ends_its_server_when_its_owner_is_killed(tmp_path):
    owner = subprocess.Popen(SLEEPER)
    guard = subprocess.Popen(
        [sys.executable, str(REPO_ROOT / "tests" / "servers.py"), "guard", "--owner", f"{owner.pid}:"]
        + ["--", *SLEEPER],
        env=dict(os.environ, **{MARK: "guarded"}),
        start_new_session=True,
    )
    try:
        assert wait_until(lambda: len(processes_of("guarded")) == 2)  # the guard and its server
        time.sleep(1)
        assert guard.poll() is None, "the guard ended while its owner was there"
        owner.kill()
        owner.wait()
        assert wait_until(lambda: processes_of("guarded") == [] or guard.poll() is not None)
        guard.wait(timeout=30)
        assert wait_until(lambda: processes_of("guarded") == [], timeout=30)
    finally:
        owner.kill()
        owner.wait()
        if guard.poll() is None:
            os.killpg(guard.pid, signal.SIGKILL)
            guard.wait()


SERVER_TEST = """
import os
from pathlib import Path


def test_server_up(mlflow_server):
    Path(os.environ["SERVER_URL_FILE"]).write_text(mlflow_server)
    import time

    time.sleep(600)
"""


@pytest.mark.slow
@pytest.mark.parametrize(
    "number, processes",
    [(signal.SIGTERM, "0"), (signal.SIGTERM, "1"), (signal.SIGINT, "0"), (signal.SIGKILL, "1")],
    ids=["SIGTERM", "SIGTERM-xdist", "SIGINT", "SIGKILL-xdist"],
)
def test_a_signal_to_pytest_leaves_no_server_of_the_suite(tmp_path, number, processes):
    pytest.importorskip("mlflow", reason="the mlflow extra is not installed (pip install -e '.[mlflow]')")
    (tmp_path / "test_up.py").write_text(SERVER_TEST)
    url_file = tmp_path / "url"
    env = {key: value for key, value in os.environ.items() if key != "WORKBENCH_MLFLOW_SERVER"}
    env.update(
        TMPDIR=str(tmp_path),  # the pid files of this run's servers, apart from any other run's
        SERVER_URL_FILE=str(url_file),
        PYTHONPATH=os.pathsep.join([str(REPO_ROOT / "tests"), str(REPO_ROOT)]),
    )
    command = [sys.executable, "-m", "pytest", "-c", os.devnull, "-p", "conftest", "-p", "no:cacheprovider"]
    command += ["-n", processes, "-q", str(tmp_path / "test_up.py")]
    pytest_run = subprocess.Popen(
        command,
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        preexec_fn=sigint_at_default,
    )
    try:
        assert wait_until(lambda: url_file.is_file() or pytest_run.poll() is not None, timeout=600)
        assert url_file.is_file(), pytest_run.communicate()[0].decode()[-3000:]
        pid_files = list((tmp_path / f"workbench-tests-{os.getuid()}" / "servers").glob("*.json"))
        assert len(pid_files) == 1
        server_id = json.loads(pid_files[0].read_text())["id"]
        assert processes_of(server_id), "the server's processes do not carry its id"

        pytest_run.send_signal(number)
        pytest_run.communicate(timeout=120)

        assert wait_until(lambda: processes_of(server_id) == [], timeout=60), processes_of(server_id)
    finally:
        if pytest_run.poll() is None:
            pytest_run.kill()
            pytest_run.wait()
