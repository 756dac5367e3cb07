"""Where the workbench's configs live, and composing a study without running it (for tests and notebooks)."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from workbench.errors import WorkbenchError

REPO_ROOT = Path(__file__).resolve().parents[1]
CONF_DIR = REPO_ROOT / "conf"
STUDIES_DIR = REPO_ROOT / "studies"
DEFAULT_STUDY = "paper"


def check_config_dirs() -> None:
    """The config folders sit beside the package in the checkout (install with ``pip install -e .``)."""
    for folder in (CONF_DIR, STUDIES_DIR):
        if not folder.is_dir():
            raise WorkbenchError(f"config folder {folder} is missing: install the workbench from its checkout "
                                 "with 'pip install -e .' so that conf/ and studies/ stay beside the package")


def compose(study: str = DEFAULT_STUDY, overrides: Sequence[str] = ()):
    """Compose a study's config as the command line would, without running it.

    Parameters
    ----------
    study : str
        Name of a file in ``studies/`` without ``.yaml``.
    overrides : sequence of str
        Hydra overrides such as ``"dataset.n_frames=2000"``.

    Returns
    -------
    omegaconf.DictConfig
    """
    from hydra import compose as hydra_compose, initialize_config_dir

    from workbench.cli import register_cli_resolvers

    register_cli_resolvers()
    check_config_dirs()
    with initialize_config_dir(config_dir=str(STUDIES_DIR), version_base="1.3"):
        return hydra_compose(config_name=study, overrides=list(overrides),
                             return_hydra_config=True)
