"""Shared fixtures: where the shared face data lives (``../shared/data`` or ``WORKBENCH_DATA_ROOT``), the tiny study
most tests run, the ``cli`` command run in-process, the suite's servers, and the order test scopes are handed out."""

import json
import os
import signal
import sys
from pathlib import Path

import pytest

from workbench.settings.config import REPO_ROOT

DURATIONS = Path(__file__).with_name("durations.json")
"""Seconds each scope of the suite took (a test file, or a class of one, as pytest-xdist's ``--dist loadscope``
hands them out), as ``pytest --record-durations`` measured them."""

TINY_STUDY = ("dataset.n_frames=300",)
"""The size of the smallest synthetic study that still fits and scores every basis with every solver: the settings
of ``tiny_study``. A test adds the settings it is about (a solver, a sweep, an output folder) after these."""


def pytest_addoption(parser):
    parser.addoption(
        "--record-durations",
        action="store_true",
        help=f"write the seconds each test scope took into {DURATIONS.name} (kept for scopes that did not run), "
        "from which the longest scopes are handed out first",
    )


def pytest_configure(config):
    """Before any test: end the servers a killed earlier run of the suite left, and let SIGTERM end this run as
    Ctrl-C does, through the fixtures' teardown (which stops the servers this run started)."""
    from servers import clean_stale

    if not os.environ.get("PYTEST_XDIST_WORKER"):
        for server_id in clean_stale():
            print(f"ended the server {server_id} a killed earlier test run left")
    if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _interrupt)


def _interrupt(number, frame):
    raise KeyboardInterrupt(f"signal {number}")


@pytest.fixture(autouse=True)
def signal_handlers_kept():
    """Each test leaves SIGINT, SIGTERM and SIGHUP as it found them: a command run in the test process ignores them
    once its work is done (``workbench.core.interrupt.ignore_further_interrupts``), and an ignored SIGTERM left
    behind is inherited by every child process a later test starts, which then cannot be terminated."""
    numbers = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    saved = {number: signal.getsignal(number) for number in numbers}
    hook = sys.unraisablehook
    yield
    for number, handler in saved.items():
        if handler is not None and signal.getsignal(number) is not handler:
            signal.signal(number, handler)
    sys.unraisablehook = hook


def scope_of(nodeid: str) -> str:
    """The scope pytest-xdist's ``--dist loadscope`` hands out whole: the class of a method, else the file."""
    parts = nodeid.split("[", 1)[0].split("::")
    return "::".join(parts[:2]) if len(parts) > 2 else parts[0]


def measured_durations() -> dict[str, float]:
    """The seconds of each scope in :data:`DURATIONS` (empty when there is no such file)."""
    return json.loads(DURATIONS.read_text())["seconds"] if DURATIONS.is_file() else {}


LONGEST_FIRST = (
    "tests/project/test_docs.py::TestCommandsOf_docs_studies_md",
    "tests/project/test_docs.py::TestCommandsOf_docs_reports_md",
    "tests/project/test_docs.py::TestCommandsOf_README_md",
    "tests/reporting/test_reporting.py::TestReferenceRerun_paper",  # the 4,000-frame reference run redone
    "tests/reporting/test_reporting.py",
    "tests/project/test_docs.py::TestCommandsOf_docs_performance_md",
    "tests/project/test_docs.py::TestCommandsOf_docs_formats_md",
    "tests/reporting/test_reporting.py::TestReferenceRerun_paper_ict_livelink",
    "tests/reporting/test_reporting.py::TestBasesReferenceRerun",
    "tests/reporting/test_reporting.py::TestReferenceRerun_paper_animface",
    "tests/project/test_docs.py::TestCommandsOf_docs_export_md",
    "tests/record/test_mlflow_store.py",
    "tests/project/test_docs.py::TestCommandsOf_docs_tracking_md",
    "tests/cli/test_kill.py::TestKilledRuns",  # its sweeps (TestKilledSweeps) go by their seconds
    "tests/cli/test_cluster.py",  # no seconds: it needs CI's test cluster; not to be handed out last, unmeasured
)
"""The longest scopes of the whole suite, slow tests included, longest first: handed out before every other
scope. The documents' commands, tests/record/test_mlflow_store.py and tests/cli/test_kill.py's in the order CI measured
them (no seconds were kept), the scopes of tests/reporting/test_reporting.py placed among them by their seconds
(:data:`DURATIONS`, measured with ``-n 0``); then tests/cli/test_cluster.py, which only CI runs: a scope not
measured is otherwise handed out last, where a long one keeps one process busy alone at the end."""


def pytest_collection_modifyitems(items):
    """Hand out the scopes that take longest first (pytest-xdist gives out scopes in collection order, and a long
    one given out last keeps one process busy alone at the end): those of :data:`LONGEST_FIRST`, then the others by
    their seconds in :data:`DURATIONS`, scopes not measured yet last. Every scope stays in one block, so its module
    fixtures are built once."""
    seconds = measured_durations()
    items.sort(key=lambda item: hand_out_rank(item.nodeid, seconds))


def hand_out_rank(nodeid: str, seconds: dict[str, float]) -> tuple[int, float]:
    """Where a test's scope goes in the order scopes are handed out (lowest first), given each scope's seconds."""
    scope = scope_of(nodeid)
    if scope in LONGEST_FIRST:
        return LONGEST_FIRST.index(scope), 0.0
    return len(LONGEST_FIRST), -seconds.get(scope, 0.0)


_measured: dict[str, float] = {}


def pytest_runtest_logreport(report):
    _measured[scope_of(report.nodeid)] = _measured.get(scope_of(report.nodeid), 0.0) + report.duration


def pytest_sessionfinish(session):
    if not session.config.getoption("--record-durations") or os.environ.get("PYTEST_XDIST_WORKER"):
        return
    import datetime
    import shlex

    seconds = {**measured_durations(), **{scope: round(value, 1) for scope, value in _measured.items()}}
    DURATIONS.write_text(
        json.dumps(
            {
                "recorded": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
                "command": shlex.join(["pytest", *session.config.invocation_params.args]),
                "load": round(os.getloadavg()[0], 1),
                "seconds": dict(sorted(seconds.items(), key=lambda pair: (-pair[1], pair[0]))),
            },
            indent=1,
        )
        + "\n"
    )


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
def tiny_study() -> tuple[str, ...]:
    """The overrides of the smallest synthetic study (:data:`TINY_STUDY`): what a test runs when it needs a run,
    not a particular size."""
    return TINY_STUDY


TINY_REPORT = (
    "dataset.train_on=[markers,mesh]",
    "dataset.n_frames=600",
    "dataset.mesh_rows=35",
    "dataset.mesh_cols=30",
    "save_inputs=true",
)
"""The run of ``tiny_report``: both data variants, 5 s of performance on a coarse mesh (1,050 vertices), inputs
saved."""


def shared_temporary_folder(tmp_path_factory) -> Path:
    """This test run's temporary folder that every test process sees: under pytest-xdist the folder above the
    processes' own ones."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


@pytest.fixture(scope="session")
def tiny_report(tmp_path_factory) -> tuple[Path, Path]:
    """``(record, report)``: a run of :data:`TINY_REPORT` and its report (``workbench report``, every figure), built
    once per test run, whichever test process asks first (the others wait for it and take it), for the tests that
    read a report (tests/reporting/test_reporting.py, tests/reporting/test_rig_panel.py). Read only: a test that
    changes a report changes a copy."""
    import fcntl

    from workbench.api import run
    from workbench.reporting.report.command import main
    from workbench.settings.config import compose

    folder = shared_temporary_folder(tmp_path_factory) / "tiny-report"
    record, report = folder / "run", folder / "reports" / "paper"
    with open(folder.with_name("tiny-report.lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file is closed
        if not (folder / "built").is_file():
            if folder.exists():  # a process that failed half way left it
                import shutil

                shutil.rmtree(folder)
            folder.mkdir()
            run(compose("paper", list(TINY_REPORT)), record)
            assert main([str(record), "--out", str(report)]) == 0
            (folder / "built").write_text("")
    return record, report


@pytest.fixture
def cli(tmp_path):
    """``cli(*args, cwd=tmp_path, env=None)``: the ``workbench`` command run inside the test process
    (:func:`in_process.run_workbench`), in the test's own folder unless ``cwd`` says otherwise; returns its exit
    code and what it printed as ``returncode``, ``stdout`` and ``stderr``."""
    from in_process import run_workbench

    def call(*args, cwd=None, env=None):
        return run_workbench(*args, cwd=tmp_path if cwd is None else cwd, env=env)

    return call


@pytest.fixture(scope="session")
def mlflow_server(tmp_path_factory):
    """URL of an MLflow tracking server: ``WORKBENCH_MLFLOW_SERVER`` (CI starts one beside the test run), else
    one started here for the session (SQLite backend, local artifact folder, loopback only); needs the mlflow
    extra. It runs under the suite's guard (``tests/servers.py``): stopped at the session's end, on SIGINT and
    SIGTERM, and when pytest is killed."""
    import socket
    import sys
    import time
    import urllib.request

    from servers import start_guarded, stop_guarded

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
    command = [sys.executable, "-m", "mlflow", "server", "--backend-store-uri", f"sqlite:///{folder / 'mlflow.db'}"]
    command += ["--artifacts-destination", str(folder / "artifacts"), "--host", "127.0.0.1", "--port", str(port)]
    command += ["--workers", "1"]
    server, server_id = start_guarded(
        command, folder / "server.log", env=dict(os.environ, MLFLOW_SERVER_ENABLE_JOB_EXECUTION="false")
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
        stop_guarded(server, server_id)


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
