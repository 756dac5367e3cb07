"""Shared fixtures: where the shared face data lives (``../shared/data`` or ``WORKBENCH_DATA_ROOT``)."""

import os
from pathlib import Path

import pytest

from workbench.settings.config import REPO_ROOT

LONGEST_FIRST = (
    "tests/test_reporting.py::",  # the reference reports redone: about ten minutes in all
    "tests/test_docs.py::TestCommandsOf_docs_studies_md::",
    "tests/test_docs.py::TestCommandsOf_docs_reports_md::",
    "tests/test_docs.py::TestCommandsOf_README_md::",
    "tests/test_docs.py::TestCommandsOf_docs_performance_md::",
    "tests/test_docs.py::TestCommandsOf_docs_formats_md::",
    "tests/test_studies.py::",
    "tests/test_docs.py::TestCommandsOf_docs_export_md::",
    "tests/test_mlflow_store.py::",
    "tests/test_docs.py::TestCommandsOf_docs_tracking_md::",
    "tests/test_kill.py::",
)
"""The longest scopes of the suite (a file, or a document's commands in tests/test_docs.py), longest first, as CI
measured them: pytest-xdist hands scopes out in the order they are collected, and a long one handed out last keeps
one process busy alone at the end."""


def pytest_collection_modifyitems(items):
    """Collect the scopes of :data:`LONGEST_FIRST` first, in that order; everything else after them, as before
    (every scope stays in one block, so its module fixtures are built once)."""

    def rank(item) -> int:
        return next((i for i, prefix in enumerate(LONGEST_FIRST) if item.nodeid.startswith(prefix)), len(LONGEST_FIRST))

    items.sort(key=rank)


def shared_data_root() -> Path:
    """The data root the loader tests read: ``WORKBENCH_DATA_ROOT`` or ``<repo>/../shared/data``."""
    configured = os.environ.get("WORKBENCH_DATA_ROOT")
    return Path(configured).expanduser().resolve() if configured else (REPO_ROOT.parent / "shared" / "data").resolve()


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The shared face data folder; skipped when absent, failed when ``WORKBENCH_REQUIRE_DATA=1`` (as CI sets)."""
    root = shared_data_root()
    expected = (
        "ict-facekit/FaceXModel/generic_neutral_mesh.obj",
        "livelinkface/alex_rom_3.csv",
        "animface/animface_jaw.c3d",
    )
    missing = [name for name in expected if not (root / name).is_file()]
    if missing:
        reason = (
            f"shared face data not found at {root} (missing {', '.join(missing)}); set WORKBENCH_DATA_ROOT "
            "to the folder holding ict-facekit/, livelinkface/ and animface/"
        )
        if os.environ.get("WORKBENCH_REQUIRE_DATA") == "1":
            pytest.fail(reason + " -- required because WORKBENCH_REQUIRE_DATA=1", pytrace=False)
        pytest.skip(reason)
    return root


@pytest.fixture(scope="session")
def chromium() -> str:
    """Path of a headless Chromium; skipped when absent, failed when ``WORKBENCH_REQUIRE_BROWSER=1`` (as CI sets,
    after installing Debian's ``chromium``)."""
    import shutil

    found = next(
        (shutil.which(name) for name in ("chromium", "chromium-browser", "google-chrome") if shutil.which(name)), None
    )
    if found is None:
        reason = "headless Chromium not found (install Debian's 'chromium' to check the report pages in a browser)"
        if os.environ.get("WORKBENCH_REQUIRE_BROWSER") == "1":
            pytest.fail(reason + " -- required because WORKBENCH_REQUIRE_BROWSER=1", pytrace=False)
        pytest.skip(reason)
    return found


def require_or_skip(variable: str, reason: str) -> None:
    """Skip with ``reason``, or fail when the environment variable ``variable`` is 1 (CI sets it where the thing
    must be there)."""
    if os.environ.get(variable) == "1":
        pytest.fail(f"{reason} -- required because {variable}=1", pytrace=False)
    pytest.skip(reason)


@pytest.fixture(scope="session")
def mlflow_server(tmp_path_factory):
    """URL of an MLflow tracking server: ``WORKBENCH_MLFLOW_SERVER`` (CI starts one beside the test run), else
    one started here for the session (SQLite backend, local artifact folder, loopback only); needs the mlflow
    extra."""
    import signal
    import socket
    import subprocess
    import sys
    import time
    import urllib.request

    pytest.importorskip("mlflow", reason="the mlflow extra is not installed (pip install -e '.[mlflow]')")

    def healthy(url: str) -> bool:
        try:
            with urllib.request.urlopen(f"{url}/health", timeout=5) as answer:
                return answer.status == 200
        except OSError:
            return False

    configured = os.environ.get("WORKBENCH_MLFLOW_SERVER")
    if configured:
        if not healthy(configured):
            pytest.fail(f"WORKBENCH_MLFLOW_SERVER={configured} does not answer on /health", pytrace=False)
        yield configured.rstrip("/")
        return
    folder = tmp_path_factory.mktemp("mlflow-server")
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    url = f"http://127.0.0.1:{port}"
    with open(folder / "server.log", "wb") as server_log:
        server = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "mlflow",
                "server",
                "--backend-store-uri",
                f"sqlite:///{folder / 'mlflow.db'}",
                "--artifacts-destination",
                str(folder / "artifacts"),
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
                "--workers",
                "1",
            ],
            env=dict(os.environ, MLFLOW_SERVER_ENABLE_JOB_EXECUTION="false"),
            stdout=server_log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    try:
        deadline = time.monotonic() + 300
        while not healthy(url):
            if server.poll() is not None or time.monotonic() > deadline:
                pytest.fail(
                    f"mlflow server did not start: {(folder / 'server.log').read_text()[-2000:]}", pytrace=False
                )
            time.sleep(0.5)
        yield url
    finally:
        os.killpg(server.pid, signal.SIGTERM)  # the server and the workers it started, in their own session
        try:
            server.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()


@pytest.fixture(scope="session")
def slurm_cluster() -> Path:
    """The folder of the single-node SLURM cluster ``.ci/slurm-cluster start`` brought up (``SLURM_CONF`` names
    its slurm.conf); skipped without it, failed when ``WORKBENCH_REQUIRE_CLUSTER=1`` (as CI sets)."""
    import subprocess

    conf = Path(os.environ.get("SLURM_CONF", "/nonexistent"))
    how = "start one with 'sudo .ci/slurm-cluster start' and export the SLURM_CONF it prints"
    if not conf.is_file() or not conf.read_text().startswith("# Written by .ci/slurm-cluster"):
        require_or_skip("WORKBENCH_REQUIRE_CLUSTER", f"no test SLURM cluster (SLURM_CONF={conf}): {how}")
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher", reason="the cluster extra is not installed")
    try:
        state = subprocess.run(
            ["sinfo", "--noheader", "--partition", "debug", "--format", "%T"],
            capture_output=True,
            text=True,
            timeout=30,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError) as error:
        state = f"sinfo failed: {error}"
    if state not in ("idle", "mixed", "allocated"):
        require_or_skip("WORKBENCH_REQUIRE_CLUSTER", f"the test SLURM cluster's node is not up ({state!r}): {how}")
    return conf.parent
