"""The command line's error behaviour: one line naming the problem, non-zero exit, the traceback only with
``--verbose``."""

import pytest


def test_bad_setting_is_one_line_and_verbose_adds_the_traceback(tmp_path, cli, tiny_study):
    quiet = cli("basis.coverage=1.5", *tiny_study, f"paths.output_root={tmp_path}", cwd=tmp_path)
    assert quiet.returncode == 2
    assert quiet.stderr.strip().splitlines() == ["workbench: error: basis.coverage must be in (0, 1], got 1.5"]
    assert "Traceback" not in quiet.stdout + quiet.stderr

    verbose = cli("--verbose", "basis.coverage=1.5", *tiny_study, f"paths.output_root={tmp_path}", cwd=tmp_path)
    assert verbose.returncode == 2
    assert "Traceback (most recent call last)" in verbose.stderr and "schema.py" in verbose.stderr
    assert verbose.stderr.strip().splitlines()[-1] == "workbench: error: basis.coverage must be in (0, 1], got 1.5"


def test_bad_solver_bounds_name_the_setting(tmp_path, cli, tiny_study):
    result = cli(
        "solver=box",
        "solver.box.lower=2",
        "solver.box.upper=1",
        *tiny_study,
        f"paths.output_root={tmp_path}",
        cwd=tmp_path,
    )
    assert result.returncode == 2
    assert result.stderr.strip() == "workbench: error: solver.box.lower (2.0) must not exceed solver.box.upper (1.0)"


def test_subcommand_errors_are_one_line(tmp_path, cli):
    result = cli("report", str(tmp_path / "nowhere"), cwd=tmp_path)
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1
    assert result.stderr.startswith("workbench report: error: ") and "nowhere" in result.stderr


def test_every_subcommand_error_is_one_line_naming_the_problem(tmp_path, cli, tiny_study):
    """argparse's usage block, a figure that needs four shapes, an unknown table layout: one line each, exit 2."""
    from workbench.api import run
    from workbench.settings.config import compose

    record = tmp_path / "sweep" / "run"
    run(compose("paper", [*tiny_study, "solver=lstsq"]), record)
    cases = {
        ("collect",): "workbench collect: error: the following arguments are required: paths (see workbench "
        "collect --help)",
        ("report", str(record), "--bogus", "1"): "workbench report: error: unrecognized arguments: --bogus 1 (see "
        "workbench report --help)",
        ("export",): "workbench export: error: the following arguments are required: run (see workbench export --help)",
        ("report", str(record), "--shapes", "jaw_open,smile"): "workbench report: error: --shapes takes 4 distinct "
        "hand-shape names (figure 2 shows 4), got ['jaw_open', "
        "'smile']",
        ("collect", str(tmp_path / "sweep"), "--columns", "nope"): "workbench collect: error: collect --columns must "
        "be 'metric' or a key of the runs",
    }
    for arguments, expected in cases.items():
        result = cli(*arguments, cwd=tmp_path)
        assert result.returncode == 2, (arguments, result.stderr)
        assert len(result.stderr.splitlines()) == 1 and result.stderr.startswith(expected), (arguments, result.stderr)
    assert not (record / "report").exists() and not (tmp_path / "sweep" / "collected").exists()


@pytest.mark.process
def test_a_removed_current_folder_is_named_in_one_line(tmp_path):
    """A child process: its own working folder is what is tested (removed while the shell was in it)."""
    import os
    import subprocess
    import sys

    from workbench.settings.config import REPO_ROOT

    gone = tmp_path / "gone"
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    line = (
        "workbench: error: the current folder was removed (deleted or moved away while this shell was in it); cd "
        "into an existing folder and run the command again"
    )
    for arguments in (["dataset.n_frames=300"], ["-m", "dataset.n_frames=300,400"], ["report", "x"]):
        gone.mkdir()
        script = f'cd "{gone}" && rmdir "{gone}" && exec "$0" -m workbench "$@"'
        done = subprocess.run(
            ["sh", "-c", script, sys.executable, *arguments], env=env, capture_output=True, text=True, timeout=120
        )
        assert done.returncode == 2 and done.stderr.splitlines() == [line], (arguments, done.stderr)
