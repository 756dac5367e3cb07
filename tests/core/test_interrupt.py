"""Ctrl-C at any moment, with real processes: one line on stderr, exit status 130, and no partial record or stub
folder left behind (a plain run removes what it wrote; a complete record stays complete).

The children get the default SIGINT disposition whatever this test runner was started with: a runner started
with SIGINT ignored (``nohup``, a background job of a non-interactive shell) passes that on to its children, and
Python then keeps ignoring Ctrl-C there, as it should for a real user's command.
"""

import ctypes
import os
import re
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from workbench.core import interrupt
from workbench.core.interrupt import INTERRUPTED, MESSAGE, caused_by_interrupt, interrupts_deferred
from workbench.record.record import DONE, load_record
from workbench.settings.config import REPO_ROOT

RUN = ["dataset.n_frames=20000", "solver=all"]
DELAYS = (0.02, 0.15, 0.5, 1.0, 2.0, 3.5, 6.0)
"""Seconds after the start at which Ctrl-C comes: during Python's start-up, the imports, composing the config,
building the dataset and solving (the run takes several seconds on a loaded 2-core machine)."""


def default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(arguments, cwd, script=None):
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT), OPENBLAS_NUM_THREADS="1")
    command = [sys.executable, "-c", script] if script else [sys.executable, "-m", "workbench", *arguments]
    return subprocess.Popen(
        command, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint
    )


@pytest.fixture
def sigint_ignored_here():
    """This process ignores SIGINT while the test runs, as a runner started under ``nohup`` would."""
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    yield
    signal.signal(signal.SIGINT, previous)


STARTING = re.compile(r'workbench[/\\](__init__|core[/\\]interrupt)\.py", line \d+, in <module>$')
"""A traceback frame of the package's first lines: ``workbench/__init__.py`` importing ``core/interrupt.py``, which
installs the start-up handler once it has loaded. An interrupt there finds Python's own handler still in place."""


def before_the_handler(err):
    """Whether ``err`` is Python's report of an interrupt that came before the workbench's start-up handler was
    installed: no frame of the workbench's, or only frames of the package's first lines."""
    frames = [line for line in err.splitlines() if str(REPO_ROOT / "workbench") in line]
    return all(STARTING.search(line.strip()) for line in frames)


def check_interrupted(process, folder=None):
    out, err = process.communicate(timeout=300)
    lines = [line for line in err.splitlines() if line.strip()]
    if process.returncode == 0 or (folder is not None and (folder / DONE).exists()):
        # the run ended before the signal, or the signal came as the process exited (Python then no longer handles
        # it; a shell reports 130): a complete record either way
        assert process.returncode in (0, INTERRUPTED, -signal.SIGINT), (process.returncode, err)
        assert folder is None or load_record(folder).study == "paper"
        return "finished"
    if process.returncode != INTERRUPTED and before_the_handler(err):
        # while Python itself starts (its own imports, runpy for -m), or imports the module that installs the
        # workbench's handler, before that handler is in place: Python prints its own traceback or dies of the
        # signal (a shell reports 130); out of the workbench's reach
        assert out == "" and (folder is None or not folder.exists()), (process.returncode, err)
        return "before the workbench started"
    assert process.returncode == INTERRUPTED, (process.returncode, err)
    assert lines == [MESSAGE], (process.returncode, err)
    if folder is not None:
        assert not folder.exists() or (folder / DONE).exists(), sorted(path.name for path in folder.iterdir())
    return "interrupted"


@pytest.mark.process
@pytest.mark.slow
def test_ctrl_c_at_any_moment_is_one_line_and_exit_130(tmp_path, sigint_ignored_here):
    outcomes, signalled = [], 0
    for pair in range(0, len(DELAYS), 2):  # two at a time: the machine has two cores
        runs = []
        for delay in DELAYS[pair : pair + 2]:
            folder = tmp_path / f"run-{delay}"
            runs.append((start([*RUN, f"hydra.run.dir={folder}"], tmp_path), folder, time.monotonic() + delay))
        for process, folder, due in runs:
            time.sleep(max(0.0, due - time.monotonic()))
            signalled += process.poll() is None  # a run already ended (fast, its dataset cached) tests nothing
            process.send_signal(signal.SIGINT)
        outcomes += [check_interrupted(process, folder) for process, folder, _ in runs]
    # of the runs still going when the signal came, all but two (Python's own start-up) end with the one line
    assert outcomes.count("interrupted") >= signalled - 2 and signalled >= len(DELAYS) - 1, outcomes


@pytest.mark.process
def test_ctrl_c_while_the_run_writes_into_its_folder_leaves_no_partial_record(tmp_path, sigint_ignored_here):
    folder = tmp_path / "run"
    process = start([*RUN, f"hydra.run.dir={folder}"], tmp_path)
    deadline = time.monotonic() + 300
    while not (folder / ".lock").exists():
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.005)
    time.sleep(0.5)
    process.send_signal(signal.SIGINT)
    assert check_interrupted(process, folder) == "interrupted"
    assert not folder.exists()


SOLVER_CHILD = textwrap.dedent("""
    import sys
    import numpy as np
    from workbench.numerics.active_set import primal_active_set_frames
    from workbench.core.errors import exit_on_error

    def solve(n_frames, steps):
        rng = np.random.default_rng(0)
        basis = rng.normal(size=(40, 18))
        gram = basis.T @ basis
        inverse = np.linalg.inv(gram + np.eye(18))
        return primal_active_set_frames(gram, rng.normal(size=(n_frames, 18)), np.zeros(18), np.ones(18),
                                        np.zeros((n_frames, 18)), 100, 1e-10, inverse, np.eye(18) @ inverse, steps,
                                        1.5)

    solve(10, 2)  # compiled (or loaded from numba's cache) before the interrupt can come
    print("solving", flush=True)
    try:
        solve(50000, 200)
    except BaseException as error:
        exit_on_error("workbench", error)
    print("finished", flush=True)
""")


@pytest.mark.process
def test_ctrl_c_inside_the_compiled_solver_is_one_line_and_exit_130(tmp_path, sigint_ignored_here):
    """Python reports the interrupt when the compiled call returns, as ``SystemError: CPUDispatcher(<function
    primal_active_set_frames>) returned a result with an exception set`` (seen here: its cause chain ends in the
    ``KeyboardInterrupt``); it was an unexpected error, exit 3."""
    process = start([], tmp_path, script=SOLVER_CHILD)
    assert process.stdout.readline() == "solving\n", process.communicate()
    time.sleep(0.3)
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=300)
    assert (process.returncode, err.strip()) == (INTERRUPTED, MESSAGE), (out, err)
    assert "finished" not in out


def test_an_error_raised_because_of_ctrl_c_counts_as_ctrl_c():
    def compiled_call():
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as interrupt:
            raise SystemError(
                "CPUDispatcher(<function primal_active_set_frames>) returned a result with an exception set"
            ) from interrupt

    with pytest.raises(SystemError) as caught:
        compiled_call()
    assert caused_by_interrupt(caught.value)
    assert not caused_by_interrupt(ValueError("x"))


FLAGGED_CHILD = textwrap.dedent("""
    import ctypes
    import sys

    from workbench.core import errors

    if sys.argv[1:] == ["--keep-the-flag"]:  # what the workbench did before: the test must be able to fail
        errors.forget_handled_interrupt = lambda: None
    # a KeyboardInterrupt ends code CPython runs itself, as in a few runs interrupted in their first seconds (CPython
    # prints its traceback here); the command then handles a Ctrl-C and exits with 130
    ctypes.pythonapi.PyRun_SimpleString(b"raise KeyboardInterrupt")
    errors.exit_on_error("workbench", KeyboardInterrupt())
""")


@pytest.mark.process
@pytest.mark.skipif(
    not hasattr(ctypes.pythonapi, "_Py_UnhandledKeyboardInterrupt"), reason="CPython 3.8-3.12 only have the flag"
)
def test_a_handled_ctrl_c_exits_130_even_where_cpython_flagged_an_unhandled_one(tmp_path):
    """Started with ``-m``, as the command is: CPython kills itself with SIGINT at exit when its flag is set."""
    (tmp_path / "flagged_child.py").write_text(FLAGGED_CHILD)
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    for argument, status in (("--keep-the-flag", -signal.SIGINT), ("--as-the-command-does", INTERRUPTED)):
        process = subprocess.run(
            [sys.executable, "-m", "flagged_child", argument], cwd=tmp_path, env=env, capture_output=True, text=True
        )
        assert process.returncode == status, process.stderr
        assert process.stderr.strip().endswith(MESSAGE), process.stderr


def test_after_the_commands_ctrl_c_any_error_counts_as_ctrl_c(monkeypatch):
    """A library may make something else of the interrupt: a Ctrl-C while numba's C extension loads (inside Hydra's
    import of a config target) came back as ``ImportError('numba._devicearray failed to import')``, its cause
    chain without the ``KeyboardInterrupt``."""
    monkeypatch.setattr(interrupt, "_interrupt_came", False)
    lost = ImportError("Error loading 'workbench.record.tracking.RunFolders': ImportError('numba._devicearray')")
    assert not caused_by_interrupt(lost)
    with pytest.raises(KeyboardInterrupt):
        interrupt.raise_keyboard_interrupt(signal.SIGINT, None)
    assert caused_by_interrupt(lost)


def test_a_ctrl_c_python_would_swallow_is_raised_again_and_nothing_is_printed(capfd, monkeypatch):
    """A Ctrl-C whose handler runs inside a weak-reference callback (as importlib's module-lock callback, seen on
    CI) is not lost: the command's hook raises it at the next call, and Python prints no "Exception ignored"."""
    import weakref

    class Held:
        pass

    def callback(reference):
        interrupt.raise_keyboard_interrupt(signal.SIGINT, None)

    def work():
        held = Held()
        reference = weakref.ref(held, callback)  # noqa: F841 - the callback runs when ``held`` goes
        del held
        return sum(range(3))

    monkeypatch.setattr(interrupt, "_interrupt_came", False)  # put back after the test: later commands in-process
    monkeypatch.setattr(interrupt, "_signal_came", signal.SIGINT)
    signal.signal(signal.SIGINT, interrupt.exit_at_once)  # as at the command's start
    interrupt.raise_from_now_on()
    assert sys.unraisablehook is interrupt.keep_swallowed_interrupt
    with pytest.raises(KeyboardInterrupt):
        work()
    assert sys.getprofile() is None  # one interrupt, raised once
    assert sum(range(3)) == 3
    assert "Exception ignored" not in capfd.readouterr().err


def test_ctrl_c_held_back_is_acted_on_once_the_step_ends_and_an_ignored_one_stays_ignored():
    saved = signal.getsignal(signal.SIGINT)
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        steps = []
        with pytest.raises(KeyboardInterrupt):
            with interrupts_deferred():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.05)  # the signal is delivered here, and held back
                steps.append("ended")
        assert steps == ["ended"]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        with interrupts_deferred():  # no signal: nothing raised
            pass
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        with interrupts_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, saved)


def default_signals():
    for signum in interrupt.SIGNALS:
        signal.signal(signum, signal.SIG_DFL)


@pytest.fixture(scope="module")
def small_record(tmp_path_factory):
    from workbench.api import run
    from workbench.settings.config import compose

    folder = tmp_path_factory.mktemp("signals") / "run"
    run(compose("paper", ["dataset.n_frames=300", "basis.paper_regime=false"]), folder)
    return folder


@pytest.mark.process
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_are_one_line_and_leave_the_earlier_output_and_no_copy(tmp_path, small_record, signum):
    """What SLURM, ``timeout`` and systemd send (SIGTERM), or a closed terminal (SIGHUP), into a report replacing an
    earlier one: it ended with no message and left its temporary copy of the report beside the folder."""
    from workbench.core.files import output_folder, write_atomic

    out = tmp_path / "report"
    with output_folder(out, "--out", writer="a report") as staging:
        write_atomic(staging / "index.html", "the earlier report\n")
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT), OPENBLAS_NUM_THREADS="1")
    process = subprocess.Popen(
        [sys.executable, "-m", "workbench", "report", str(small_record), "--out", str(out)],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=default_signals,
    )
    deadline = time.monotonic() + 300
    while not any(name.endswith(".tmp") for name in os.listdir(tmp_path)):  # the report is being written
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.005)
    time.sleep(0.2)
    process.send_signal(signum)
    out_text, err = process.communicate(timeout=300)
    assert process.returncode == interrupt.exit_status(signum) == 128 + signum, (process.returncode, err)
    assert err.splitlines() == [
        f"workbench report: stopped by {signal.Signals(signum).name}; rerun the same command to resume"
    ]
    assert sorted(os.listdir(tmp_path)) == ["report"]
    assert (out / "index.html").read_text() == "the earlier report\n"


def test_sigterm_and_sighup_held_back_are_acted_on_once_the_step_ends():
    saved = {signum: signal.getsignal(signum) for signum in interrupt.SIGNALS}
    try:
        came = []
        for signum in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(signum, lambda number, frame: came.append(number))
            with interrupts_deferred():
                os.kill(os.getpid(), signum)
                time.sleep(0.05)
                assert came == [signal.SIGTERM] * (signum == signal.SIGHUP)  # held back until the step ends
            assert came[-1] == signum
    finally:
        for signum, handler in saved.items():
            signal.signal(signum, handler)
