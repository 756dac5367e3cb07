"""Settings are checked whether or not the run uses them, and messages name the setting at fault."""

import re

import pytest
from in_process import run_workbench

from workbench.api import run
from workbench.core.errors import WorkbenchError
from workbench.record.record import DONE
from workbench.settings.config import compose


@pytest.mark.parametrize(
    "override, message",
    [
        ("dataset.gap_policy=spline", "dataset.gap_policy must be one of ('drop', 'linear', 'masked'), got 'spline'"),
        ("dataset.gap_fit_on=all", "dataset.gap_fit_on must be one of ('complete', 'filled'), got 'all'"),
        (
            "dataset.eval_on=[scan]",
            "dataset.eval_on must be one of ('markers', 'mesh', 'mesh_rbf', 'face') or a list "
            "of distinct ones or null, got ['scan']",
        ),
        (
            "dataset.train_on=[markers,markers]",
            "dataset.train_on must be one of ('markers', 'mesh', 'mesh_rbf', 'face') "
            "or a list of distinct ones, got ['markers', 'markers']",
        ),
    ],
)
def test_unused_settings_are_checked(tmp_path, override, message):
    cfg = compose("paper", ["dataset.n_frames=200", "solver=lstsq", override])
    with pytest.raises(WorkbenchError, match=re.escape(message)):
        run(cfg, tmp_path / "run")
    assert not (tmp_path / "run" / DONE).exists()


def test_settings_of_the_wrong_type_fail_at_composition():
    with pytest.raises(WorkbenchError, match=re.escape("dataset.gap_max_fill_frames=abc")):
        compose("paper", ["dataset.n_frames=200", "solver=lstsq", "dataset.gap_max_fill_frames=abc"])


@pytest.mark.parametrize(
    "override, shown", [("save_inputs=maybe", "'maybe'"), ("save_inputs=2", "2"), ("dataset.stabilise=1", "1")]
)
def test_true_false_settings_take_only_true_or_false(tmp_path, override, shown):
    key = override.split("=")[0]
    with pytest.raises(WorkbenchError, match=re.escape(f"{key} must be true or false, got {shown}")):
        run(compose("paper", ["dataset.n_frames=200", "solver=lstsq", override]), tmp_path / "run")


def test_other_take_with_the_training_seed_is_refused(tmp_path):
    cfg = compose(
        "paper",
        ["dataset.n_frames=200", "solver=lstsq", "dataset.split=other_take", "dataset.seed=3", "dataset.eval_seed=3"],
    )
    with pytest.raises(
        WorkbenchError,
        match=r"dataset\.eval_seed 3 equals dataset\.seed: split 'other_take' "
        r"evaluates on another take",
    ):
        run(cfg, tmp_path / "run")


def test_eval_on_of_the_real_datasets_names_their_variants(tmp_path):
    cfg = compose("paper", ["dataset=animface", "+dataset.eval_on=[scan]"])
    with pytest.raises(WorkbenchError, match=re.escape("dataset.eval_on must be one of ('markers', 'mesh')")):
        run(cfg, tmp_path / "run")


# Every setting is checked when the config is composed: ranges, names, keys no schema knows, interpolations, and
# settings that would have no effect. Each case was an unexpected error (exit 3) or silently accepted before.
COMPOSITION_CASES = {
    "basis.hand_subset=5": "basis.hand_subset must be all, upper, lower, random<k> or a list of distinct hand-shape "
    "names, got 5",
    "basis.ica.max_iter=0": "basis.ica.max_iter must be an integer >= 1, got 0",
    "basis.nmf.tol=-1": "basis.nmf.tol must be a finite number >= 0, got -1.0",
    "basis.spca.max_iter=-2": "basis.spca.max_iter must be an integer >= 1, got -2",
    "basis.splocs.n_iterations=0": "basis.splocs.n_iterations must be an integer >= 1, got 0",
    "basis.hand_fit.n_iterations=0": "basis.hand_fit.n_iterations must be an integer >= 1, got 0",
    "basis.coverage=${nope}": "setting basis.coverage cannot be resolved: Interpolation key 'nope' not found",
    "basis.coverage=${basis.coverage}": "setting basis.coverage cannot be resolved: Recursive interpolation detected",
    "+loop=1": "setting loop does not exist",
    "save_inputs=2": "save_inputs must be true or false, got 2",
    "study=": "study must be a plain name",
    "paper.m=-3": "paper.m must be an integer >= 1, got -3",
    "paper.coverage=5": "paper.coverage must be in (0, 1], got 5.0",
    "paper.alpha.H=nan": "paper.alpha.H must be in (0, 100], got nan",
    "dataset.marker_noise_mm=1e9": "dataset.marker_noise_mm must be in [0, 10] (mm; optical marker noise is below a "
    "millimetre, and 10 mm is a tenth of the face), got 1000000000.0",
    "dataset.frame_rate=1e9": "dataset.frame_rate must be in (0, 10000], got 1000000000.0",
    "+dataset.nonexistent=1": "dataset.nonexistent has no effect with dataset=synthetic: dataset kind 'synthetic' has "
    "no such setting",
    "+dataset.weight_curves=take.csv": "dataset.weight_curves has no effect with dataset=synthetic: only dataset "
    "kind(s) ['ict_livelink'] read it",
    "dataset.eval_fraction=0.3": "dataset.eval_fraction has no effect in this run: only dataset.split=tail or "
    "dataset.held_out=tail uses it (this run: split=same)",
    "basis.subset_seed=4": "basis.subset_seed has no effect in this run: only basis.hand_subset=random<k> draws",
    "basis.splocs.d_min=0.9": "basis.splocs.d_min (0.9) must be below basis.splocs.d_max (0.7)",
    "basis.coverage_on=noisy": "basis.coverage_on must be one of ('training', 'clean'), got 'noisy'",
    "metric.score_clean=yes": "metric.score_clean must be true or false, got 'yes'",
    "+metric.bootstrap_resamples=500": "setting metric.bootstrap_resamples was retired: the within-run intervals "
    "are batch means over time and draw nothing at random",
    "dataset.held_out=[tail,tail]": "dataset.held_out must be one of ('tail', 'take', 'kfold', 'take_out') or a list "
    "of distinct ones or null, got ['tail', 'tail']",
    "dataset.folds=1": "dataset.folds must be an integer >= 2, got 1",
}


@pytest.mark.parametrize("override", list(COMPOSITION_CASES))
def test_settings_are_checked_when_composed(override):
    from workbench.settings.schema import check_study_config

    with pytest.raises(WorkbenchError, match="^" + re.escape(COMPOSITION_CASES[override])):
        # a retired setting is refused by compose itself, the others by the check
        cfg = compose("paper", ["dataset.n_frames=200", "solver=lstsq", override])
        check_study_config(cfg, [override], refuse_ineffective=True)


@pytest.mark.parametrize(
    "overrides, message",
    [
        (
            ["basis.coverage_on=clean", "basis.n_components=5"],
            "basis.coverage_on=clean chooses m from the clean capture, so basis.n_components must be null, got 5",
        ),
        (
            ["dataset=animface", "basis.coverage_on=clean"],
            "basis.coverage_on needs the clean capture, which only dataset.kind synthetic has, got 'animface'",
        ),
        (
            ["dataset=ict_livelink", "metric.score_clean=true"],
            "metric.score_clean needs the clean capture, which only dataset.kind synthetic has, got 'ict_livelink'",
        ),
    ],
)
def test_scoring_against_the_clean_capture_is_checked_with_the_settings_it_needs(overrides, message):
    from workbench.settings.schema import check_study_config

    cfg = compose("paper", ["solver=lstsq", *overrides])
    with pytest.raises(WorkbenchError, match="^" + re.escape(message) + "$"):
        check_study_config(cfg, overrides, refuse_ineffective=True)


def test_settings_with_no_effect_in_a_sweep_are_named_not_refused():
    from workbench.settings.schema import check_study_config

    cfg = compose("paper", ["dataset.n_frames=200", "solver=lstsq", "dataset.eval_fraction=0.3"])
    assert check_study_config(cfg, ["dataset.eval_fraction=0.3"]) == [
        "dataset.eval_fraction has no effect in this run: only dataset.split=tail or dataset.held_out=tail uses it "
        "(this run: split=same)"
    ]
    cfg = compose("paper", ["dataset.n_frames=200", "dataset.split=tail", "dataset.eval_fraction=0.3"])
    assert check_study_config(cfg, ["dataset.split=tail", "dataset.eval_fraction=0.3"], refuse_ineffective=True) == []


def test_every_study_and_dataset_passes_its_own_checks():
    from workbench.settings.config import STUDIES_DIR
    from workbench.settings.schema import check_study_config

    for study in sorted(path.stem for path in STUDIES_DIR.glob("*.yaml")):
        assert check_study_config(compose(study), refuse_ineffective=True) == [], study
    for dataset in ("ict_livelink", "animface", "mesh_sequence"):
        assert check_study_config(compose("paper", [f"dataset={dataset}"]), refuse_ineffective=True) == []


def test_the_command_refuses_them_in_one_line_before_making_any_folder(tmp_path):
    """The command: exit 2, one line, no output folder (the former exit-3 cases among them)."""
    cases = [
        "basis.hand_subset=5",
        "basis.ica.max_iter=0",
        "basis.coverage=${nope}",
        "save_inputs=2",
        "paper.alpha.H=nan",
        "+dataset.nonexistent=1",
        "dataset.eval_fraction=0.3",
        "basis.nmf.tol=-1",
    ]
    for case in cases:
        done = run_workbench("dataset.n_frames=200", "solver=lstsq", case, "paths.output_root=out", cwd=tmp_path)
        assert done.returncode == 2, (case, done.stderr)
        assert done.stderr.splitlines() == [
            f"workbench: error: {COMPOSITION_CASES[case]}"
            + ("; leave it out" if "no effect" in COMPOSITION_CASES[case] else "")
        ], (case, done.stderr)
    assert not (tmp_path / "out").exists()


HYDRA_CASES = {
    "+hydra.nope=1": "setting hydra.nope does not exist; hydra has ['callbacks', 'defaults', ",
    "++hydra.job.nope=1": "setting hydra.job.nope does not exist; hydra.job has ['chdir', 'config', ",
    "+hydra.launcher.nope=1": "setting hydra.launcher.nope does not exist; hydra.launcher has ['_target_']",
}


@pytest.mark.parametrize("override", list(HYDRA_CASES))
def test_a_key_hydras_own_settings_do_not_have_is_refused(override):
    from workbench.settings.schema import check_hydra_settings

    with pytest.raises(WorkbenchError, match="^" + re.escape(HYDRA_CASES[override])):
        check_hydra_settings(compose("paper", [override]).hydra)


@pytest.mark.slow
def test_hydras_own_settings_of_every_study_and_launcher_pass_and_free_mappings_take_any_key():
    from workbench.settings.config import STUDIES_DIR
    from workbench.settings.schema import check_hydra_settings

    for study in sorted(path.stem for path in STUDIES_DIR.glob("*.yaml")):
        for launcher in ([], ["hydra/launcher=joblib"], ["hydra/launcher=slurm"]):
            check_hydra_settings(compose(study, launcher).hydra)
    free = ["+hydra.job.env_set.X=1", "++hydra.job.chdir=false", "+hydra.callbacks.x={_target_:builtins.dict}"]
    check_hydra_settings(compose("paper", free).hydra)


def test_the_command_refuses_a_key_hydra_does_not_have_in_one_line_before_making_any_folder(tmp_path):
    for case in HYDRA_CASES:
        for sweep in ([], ["-m", "dataset.seed=0,1"]):
            done = run_workbench(
                *sweep, "dataset.n_frames=200", "solver=lstsq", case, "paths.output_root=out", cwd=tmp_path
            )
            assert done.returncode == 2, (case, done.stderr)
            lines = done.stderr.splitlines()
            assert len(lines) == 1 and lines[0].startswith(f"workbench: error: {HYDRA_CASES[case]}"), (case, lines)
    assert not (tmp_path / "out").exists()


def test_fold_settings_have_effect_only_with_kfold():
    from workbench.settings.schema import check_study_config

    cfg = compose("paper", ["dataset.n_frames=200", "solver=lstsq", "dataset.folds=3"])
    assert check_study_config(cfg, ["dataset.folds=3"]) == [
        "dataset.folds has no effect in this run: only dataset.held_out=kfold uses it"
    ]
    cfg = compose(
        "paper", ["dataset.n_frames=200", "dataset.held_out=kfold", "dataset.folds=3", "dataset.fold_gap_s=0.1"]
    )
    assert (
        check_study_config(
            cfg, ["dataset.held_out=kfold", "dataset.folds=3", "dataset.fold_gap_s=0.1"], refuse_ineffective=True
        )
        == []
    )


def test_a_record_of_an_earlier_version_holding_retired_settings_is_still_read():
    from omegaconf import OmegaConf

    from workbench.settings.schema import check_study_config, resolved_settings

    plain = resolved_settings(compose("paper", ["dataset.n_frames=200", "solver=lstsq"]))
    plain["metric"] |= {"bootstrap_resamples": 2000, "bootstrap_seed": 0}  # what records of earlier versions hold
    assert check_study_config(OmegaConf.create(plain)) == []
    with pytest.raises(WorkbenchError, match="^setting metric.bootstrap_seed was retired"):
        check_study_config(OmegaConf.create(plain), ["+metric.bootstrap_seed=0"])
