"""Settings are checked whether or not the run uses them, and messages name the setting at fault."""

import re

import pytest

from workbench.cli import run
from workbench.config import compose
from workbench.errors import WorkbenchError
from workbench.record import DONE


@pytest.mark.parametrize("override, message", [
    ("dataset.gap_policy=spline", "dataset.gap_policy must be one of ('drop', 'linear', 'masked'), got 'spline'"),
    ("dataset.gap_fit_on=all", "dataset.gap_fit_on must be one of ('complete', 'filled'), got 'all'"),
    ("dataset.eval_on=[scan]", "dataset.eval_on must be one of ('markers', 'mesh', 'mesh_rbf', 'face') or a list "
                               "of distinct ones, got ['scan']"),
    ("dataset.train_on=[markers,markers]", "dataset.train_on must be one of ('markers', 'mesh', 'mesh_rbf', 'face') "
                                           "or a list of distinct ones, got ['markers', 'markers']"),
])
def test_unused_settings_are_checked(tmp_path, override, message):
    cfg = compose("paper", ["dataset.n_frames=200", "solver=lstsq", override])
    with pytest.raises(WorkbenchError, match=re.escape(message)):
        run(cfg, tmp_path / "run")
    assert not (tmp_path / "run" / DONE).exists()


@pytest.mark.parametrize("override, key", [
    ("dataset.gap_max_fill_frames=abc", "dataset.gap_max_fill_frames"),
    ("save_inputs=maybe", "save_inputs"),
])
def test_settings_of_the_wrong_type_fail_at_composition(override, key):
    from hydra.errors import ConfigCompositionException

    with pytest.raises(ConfigCompositionException, match=re.escape(override)):
        compose("paper", ["dataset.n_frames=200", "solver=lstsq", override])


def test_save_inputs_must_be_a_boolean(tmp_path):
    with pytest.raises(WorkbenchError, match=re.escape("save_inputs must be true or false, got 1")):
        run({**compose("paper", ["dataset.n_frames=200", "solver=lstsq"]), "save_inputs": 1}, tmp_path / "run")


def test_other_take_with_the_training_seed_is_refused(tmp_path):
    cfg = compose("paper", ["dataset.n_frames=200", "solver=lstsq", "dataset.split=other_take", "dataset.seed=3",
                            "dataset.eval_seed=3"])
    with pytest.raises(WorkbenchError, match=r"dataset\.eval_seed 3 equals dataset\.seed: split 'other_take' "
                                             r"evaluates on another take"):
        run(cfg, tmp_path / "run")


def test_eval_on_of_the_real_datasets_names_their_variants(tmp_path):
    cfg = compose("paper", ["dataset=animface", "+dataset.eval_on=[scan]"])
    with pytest.raises(WorkbenchError, match=re.escape("dataset.eval_on must be one of ('markers', 'mesh')")):
        run(cfg, tmp_path / "run")
