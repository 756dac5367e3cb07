"""The command line keeps Hydra's conventions: completion, flags after overrides, --info, --help, --version,
typed configs failing at composition in one line, ad-hoc sweeps that resume, and logging into workbench.log."""

import pytest

from workbench import __version__
from workbench.record.record import DONE
from workbench.settings.config import REPO_ROOT


def completions(line, cli):
    """Hydra's bash completion answer for a command line typed up to its end."""
    result = cli("-sc", "query=bash", env={"COMP_LINE": line, "COMP_POINT": str(len(line))})
    assert result.returncode == 0, result.stderr
    return result.stdout.split()


def test_tab_completion_completes_groups_keys_and_studies(cli):
    assert completions("workbench dataset=", cli) == [
        "dataset=animface",
        "dataset=ict_livelink",
        "dataset=mesh_sequence",
        "dataset=synthetic",
    ]
    assert completions("workbench dataset.n_", cli) == [
        "dataset.n_face_markers=",
        "dataset.n_frames=",
        "dataset.n_head_markers=",
    ]
    assert completions("workbench solver=", cli) == ["solver=all", "solver=box", "solver=lstsq", "solver=nnls"]
    assert completions("workbench --config-name=cov", cli) == [
        "--config-name=coverage",
        "--config-name=coverage_small",
    ]
    studies = completions("workbench --config-name=", cli)
    assert "--config-name=paper" in studies and "--config-name=noise_small" in studies and len(studies) == 16


def test_tab_completion_offers_commands_and_only_config_groups(tmp_path, cli):
    assert completions("workbench rep", cli) == ["report"]
    assert completions("workbench co", cli) == ["collect"]
    first = completions("workbench ", cli)
    assert {"report", "collect", "mlflow", "export", "dataset=", "solver=", "basis."} <= set(first)
    # conf/correspondence holds CSV tables, not configs: not a group
    assert not any(word.startswith("correspondence") for word in first)
    # a command's arguments are folders: nothing from the workbench, so the shell offers file names
    assert completions("workbench report ", cli) == []
    refused = cli("correspondence=animface_ict", cwd=tmp_path)
    assert refused.returncode == 2 and "Key 'correspondence' not in" in refused.stderr


def test_help_is_hydras_help(tmp_path, cli):
    """--help is rendered by the workbench for speed; Hydra's own rendering (used when --config-dir adds a folder,
    here an empty one) gives the same text."""
    (tmp_path / "empty").mkdir()
    for args in (["--help"], ["dataset=animface", "--help"], ["--config-name", "coverage_small", "-h", "--resolve"]):
        ours = cli(*args, cwd=tmp_path)
        hydras = cli(*args, "--config-dir", str(tmp_path / "empty"), cwd=tmp_path)
        assert ours.returncode == hydras.returncode == 0, ours.stderr + hydras.stderr
        assert ours.stdout == hydras.stdout


def test_flags_after_the_overrides(tmp_path, cli):
    shown = cli("dataset.n_frames=2000", "--cfg", "job", cwd=tmp_path)
    assert shown.returncode == 0, shown.stderr
    assert "  n_frames: 2000\n" in shown.stdout and "hydra:" not in shown.stdout
    resolved = cli("dataset=ict_livelink", "paths.data_root=somewhere", "--cfg", "job", "--resolve", cwd=tmp_path)
    assert resolved.returncode == 0 and "  data_root: somewhere\n" in resolved.stdout


def test_bare_info_lists_the_search_path(tmp_path, cli):
    result = cli("--info", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert f"workbench://{REPO_ROOT / 'conf'}" in result.stdout and f"file://{REPO_ROOT / 'studies'}" in result.stdout


def test_help_lists_studies_groups_and_commands(tmp_path, cli):
    result = cli("--help", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    text = result.stdout
    assert text.startswith(f"workbench {__version__}: ") and "powered by Hydra" not in text
    studies = text.split("== Studies")[1].split("== Commands")[0]
    assert "coverage_small" in studies and "paper                 Paper reproduction" in studies
    commands = text.split("== Commands ==")[1].split("==")[0]
    assert [line.split()[0] for line in commands.strip().splitlines()] == ["report", "collect", "mlflow", "export"]
    groups = text.split("== Configuration groups ==")[1].split("==")[0]
    assert groups.strip().splitlines()[1:] == [
        "",
        "basis: default",
        "dataset: animface, ict_livelink, mesh_sequence, synthetic",
        "metric: default",
        "paths: default",
        "solver: all, box, lstsq, nnls",
    ]


def test_version_is_the_workbenchs(tmp_path, cli):
    result = cli("--version", cwd=tmp_path)
    assert (result.returncode, result.stdout) == (0, f"workbench {__version__}\n")


@pytest.mark.parametrize(
    "override, expected",
    [
        (
            "solver.box.lower=x",
            "workbench: error: Error merging override solver.box.lower=x; "
            "Value 'x' of type 'str' could not be converted to Float",
        ),
        (
            "basis.projections=affine",
            "workbench: error: Error merging override basis.projections=affine; "
            "Invalid value assigned: str is not a ListConfig, list or tuple",
        ),
        (
            "dataset.n_frames=2000.5",
            "workbench: error: Error merging override dataset.n_frames=2000.5; "
            "Value '2000.5' of type 'float' could not be converted to Integer",
        ),
        (
            "basis.covrage=0.9",
            "workbench: error: Could not override 'basis.covrage'; To append to your config use "
            "+basis.covrage=0.9; Key 'covrage' not in 'BasisSchema'",
        ),
        (
            "metric.bootstrap_seed=3",
            "workbench: error: setting metric.bootstrap_seed was retired: the within-run "
            "intervals are batch means over time and draw nothing at random "
            "(docs/statistics.md); leave it out",
        ),
    ],
)
def test_wrong_type_or_unknown_key_fails_at_composition_in_one_line(tmp_path, override, expected, cli):
    result = cli(override, "paths.output_root=out", cwd=tmp_path)
    assert (result.returncode, result.stderr.strip()) == (2, expected)
    assert not (tmp_path / "out").exists(), "nothing may run before the config is valid"


def test_range_checks_fail_at_composition_in_one_line(tmp_path, cli):
    result = cli("basis.coverage=1.5", "paths.output_root=out", cwd=tmp_path)
    assert (result.returncode, result.stderr.strip()) == (
        2,
        "workbench: error: basis.coverage must be in (0, 1], got 1.5",
    )
    assert not (tmp_path / "out").exists(), "nothing may run before the config is valid"


def test_adhoc_sweep_with_trailing_flag_resumes_and_logs(tmp_path, cli):
    sweep = ["dataset.n_frames=400", "solver=lstsq", "dataset.seed=0,1", "paths.output_root=out"]
    first = cli(*sweep, "-m", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    sweep_dir = tmp_path / "out" / "paper-multirun" / "default"
    runs = sorted(path.name for path in sweep_dir.iterdir() if path.is_dir())
    assert runs == [
        "dataset.n_frames=400,dataset.seed=0,solver=lstsq",
        "dataset.n_frames=400,dataset.seed=1,solver=lstsq",
    ]
    log = (sweep_dir / runs[0] / "workbench.log").read_text()
    folder = (sweep_dir / runs[0]).relative_to(tmp_path).as_posix()  # named from the working folder
    unwrapped = " ".join(line.strip() for line in log.splitlines())
    assert unwrapped.startswith(f"done {folder}: markers m=n: alpha_abs_mean with lstsq: ")  # paper regime first
    assert log.splitlines()[0] in first.stdout
    printed = (first.stdout + first.stderr).splitlines()  # each run's line within 120 columns
    assert max(len(line) for line in printed) <= 120, max(printed, key=len)

    done_times = [(sweep_dir / run / DONE).stat().st_mtime_ns for run in runs]
    again = cli("-m", *reversed(sweep), cwd=tmp_path)  # the same sweep, typed in another order
    assert again.returncode == 0, again.stderr
    assert again.stdout.count("skip ") == 2 and "done " not in again.stdout
    assert "skip" not in log + (sweep_dir / runs[0] / "workbench.log").read_text()
    assert [(sweep_dir / run / DONE).stat().st_mtime_ns for run in runs] == done_times


def test_single_run_job_name_and_log(tmp_path, cli):
    result = cli("dataset.n_frames=400", "solver=lstsq", "paths.output_root=out", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    [run_dir] = (tmp_path / "out" / "paper").iterdir()
    assert (run_dir / "workbench.log").read_text() == result.stdout
    assert result.stdout.startswith("The paper's claims, on markers m=n") and "| QE " in result.stdout
    assert "\nStudy 'paper' on synthetic actor" in result.stdout
    assert result.stdout.endswith(f"\nrecord: {run_dir}\n")
    assert not (run_dir / ".hydra").exists(), "the record keeps the config; Hydra writes nothing into a run folder"
