"""Where the workbench's configs live, and composing a study without running it (for tests and notebooks).

In the checkout (``pip install -e .``) the config groups and the studies are the top-level folders ``conf/`` and
``studies/`` beside the package. A built package (``pip install .``, a wheel, an sdist, ``pip install git+URL``)
carries copies of them inside the package, as ``workbench/conf`` and ``workbench/studies`` (the ``package-dir``
mapping in ``pyproject.toml``); those are used when they exist.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from workbench.errors import WorkbenchError

PACKAGE_DIR = Path(__file__).resolve().parent
INSTALLED = (PACKAGE_DIR / "conf").is_dir() and (PACKAGE_DIR / "studies").is_dir()
"""True for a built package (the configs inside it), False for the checkout (the configs beside it)."""
REPO_ROOT = PACKAGE_DIR.parent
"""The checkout holding the package (for a built package: the folder it is installed in, ``site-packages``)."""
CHECKOUT = None if INSTALLED else REPO_ROOT
"""The checkout the workbench runs from, or None for a built package (no git state, no reference reports)."""
CONF_DIR = (PACKAGE_DIR if INSTALLED else REPO_ROOT) / "conf"
STUDIES_DIR = (PACKAGE_DIR if INSTALLED else REPO_ROOT) / "studies"
DEFAULT_STUDY = "paper"


def check_config_dirs() -> None:
    """The config folders exist: beside the package in the checkout, or inside a built package."""
    for folder in (CONF_DIR, STUDIES_DIR):
        if not folder.is_dir():
            raise WorkbenchError(f"config folder {folder} is missing: reinstall the workbench (pip install "
                                 "quasi-eigen-workbench, or 'pip install -e .' in its checkout)")


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
