"""Every study and every config-group option composes."""

import pytest

from workbench.settings.config import CONF_DIR, STUDIES_DIR, compose

STUDIES = sorted(path.stem for path in STUDIES_DIR.glob("*.yaml"))
GROUP_OPTIONS = sorted(
    (folder.name, path.stem) for folder in CONF_DIR.iterdir() if folder.is_dir() for path in folder.glob("*.yaml")
)


def test_there_is_a_paper_study():
    assert "paper" in STUDIES


@pytest.mark.parametrize("study", STUDIES)
def test_every_study_composes(study):
    cfg = compose(study)
    assert cfg.study == study
    assert {"dataset", "basis", "solver", "metric", "paths"} <= set(cfg)


@pytest.mark.parametrize("group,option", GROUP_OPTIONS)
def test_every_group_option_composes(group, option):
    cfg = compose("paper", [f"{group}={option}"])
    assert cfg[group] is not None


def test_overrides_reach_the_config():
    cfg = compose("paper", ["dataset.n_frames=2000", "basis.coverage=0.99", "solver=box"])
    assert cfg.dataset.n_frames == 2000
    assert cfg.basis.coverage == 0.99
    assert list(cfg.solver) == ["box"]


def test_default_solver_group_holds_every_solver():
    assert list(compose("paper").solver) == ["lstsq", "nnls", "box"]
