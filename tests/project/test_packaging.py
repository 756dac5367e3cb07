"""The package: what a built package holds, the configs found inside it, a core without the extras, the one line
naming a missing extra, and a start-up that imports only what a command needs.

Building the wheel and the sdist and installing each into a fresh environment is CI's job (``.ci/run``); here the
installed layout is laid out by hand (the package with ``conf/`` and ``studies/`` inside it, as the wheel has them).
"""

import os
import re
import shutil
import subprocess
import sys

import pytest
import tomllib

from workbench.core.extras import EXTRA_OF_MODULE, install_hint, missing_extra
from workbench.settings.config import CONF_DIR, REPO_ROOT, STUDIES_DIR

OPTIONAL_MODULES = sorted(EXTRA_OF_MODULE)
PYPROJECT = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())


def python(code, *args, cwd, pythonpath=REPO_ROOT, timeout=300):
    env = dict(os.environ, PYTHONPATH=str(pythonpath), OPENBLAS_NUM_THREADS="1")
    return subprocess.run(
        [sys.executable, *(["-c", code] if code else []), *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def without(modules, argv):
    """Python code running the ``workbench`` command with ``argv`` as if ``modules`` were not installed."""
    return (
        f"import sys; sys.modules.update(dict.fromkeys({list(modules)!r})); sys.argv = ['workbench', *{argv!r}]; "
        "from workbench.cli.main import main; main()"
    )


def test_pyproject_lists_every_package_and_maps_the_configs_into_it():
    setuptools = PYPROJECT["tool"]["setuptools"]
    on_disk = {
        ".".join(path.parent.relative_to(REPO_ROOT).parts)
        for top in ("workbench", "hydra_plugins")
        for path in (REPO_ROOT / top).rglob("__init__.py")
    }
    assert set(setuptools["packages"]) == on_disk | {"hydra_plugins", "workbench.conf", "workbench.studies"}
    assert setuptools["package-dir"] == {"workbench.conf": "conf", "workbench.studies": "studies"}
    data = setuptools.get("package-data", {})
    kinds = {path.suffix for path in CONF_DIR.rglob("*") if path.is_file()}
    assert {f"**/*{suffix}" for suffix in kinds} <= set(data["workbench.conf"])
    assert {path.suffix for path in STUDIES_DIR.iterdir()} == {".yaml"} and data["workbench.studies"] == ["*.yaml"]


def test_build_system_reads_the_licence_field():
    assert PYPROJECT["project"]["license"] == "MIT" and (REPO_ROOT / "LICENSE").is_file()
    assert PYPROJECT["project"]["license-files"] == ["LICENSE"]
    # PEP 639's `license = "MIT"` needs setuptools 77 or later
    assert PYPROJECT["build-system"]["requires"] == ["setuptools>=77"]


def test_every_optional_module_belongs_to_an_extra_that_installs_it():
    extras = PYPROJECT["project"]["optional-dependencies"]
    distributions = {
        "matplotlib": "matplotlib",
        "pyvista": "pyvista",
        "vtk": "pyvista",
        "vtkmodules": "pyvista",
        "PIL": "pillow",
        "jinja2": "jinja2",
        "markupsafe": "jinja2",
        "pyarrow": "pyarrow",
        "sklearn": "scikit-learn",
        "h5py": "h5py",
        "submitit": "hydra-submitit-launcher",
        "mlflow": "mlflow",
    }
    for module, extra in EXTRA_OF_MODULE.items():
        assert any(requirement.startswith(distributions[module]) for requirement in extras[extra]), module
    core = " ".join(PYPROJECT["project"]["dependencies"])
    assert not any(distribution in core for distribution in set(distributions.values()))
    assert set(extras["all"][0].split("[")[1].rstrip("]").split(",")) == set(extras) - {"all", "test"}


@pytest.mark.parametrize("module", OPTIONAL_MODULES)
def test_a_missing_optional_module_names_its_extra(module):
    message = missing_extra(ModuleNotFoundError(f"No module named '{module}'", name=f"{module}.sub"))
    assert message is not None and install_hint(EXTRA_OF_MODULE[module]) in message
    assert f"pip install 'quasi-eigen-workbench[{EXTRA_OF_MODULE[module]}]'" in message
    assert missing_extra(ModuleNotFoundError("No module named 'numpy'", name="numpy")) is None


def test_the_slurm_launcher_without_its_plugin_names_the_cluster_extra(monkeypatch):
    error = ValueError("In 'hydra/launcher/slurm': Could not load 'hydra/launcher/submitit_slurm'")
    monkeypatch.setattr("workbench.core.extras.has_module", lambda name: False)
    assert install_hint("cluster") in missing_extra(error)
    monkeypatch.setattr("workbench.core.extras.has_module", lambda name: True)
    assert missing_extra(error) is None


@pytest.mark.slow
@pytest.mark.process
def test_the_core_runs_the_paper_study_without_any_extra(tmp_path):
    result = python(without(OPTIONAL_MODULES, ["dataset.n_frames=1000", "solver=lstsq"]), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    # the paper's regime m = n first, then the coverage rule's variant
    assert "| markers m=n | QE        | lstsq " in result.stdout
    assert "| markers     | QE        | lstsq " in result.stdout
    assert list((tmp_path / "outputs" / "paper").iterdir())


@pytest.mark.slow
@pytest.mark.process
def test_a_report_without_the_report_extra_is_one_line_exit_2(tmp_path):
    made = python(
        without(OPTIONAL_MODULES, ["dataset.n_frames=600", "solver=lstsq", "hydra.run.dir=outputs/run"]), cwd=tmp_path
    )
    assert made.returncode == 0, made.stderr
    result = python(without(["matplotlib", "pyvista", "PIL"], ["report", "outputs/run"]), cwd=tmp_path)
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("workbench report: error: ")
    assert "pip install 'quasi-eigen-workbench[report]'" in result.stderr
    assert not (tmp_path / "outputs" / "run" / "report").exists()


def imported_by(args, cwd, env=None):
    """The top-level modules ``python -X importtime -m workbench ARGS`` imports."""
    result = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "workbench", *args],
        cwd=cwd,
        env=dict(os.environ, PYTHONPATH=str(REPO_ROOT), **(env or {})),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    return {line.split("|")[-1].strip() for line in result.stderr.splitlines() if line.startswith("import time:")}


HEAVY = {"numpy", "pandas", "scipy", "numba", "matplotlib", "pyvista", "sklearn", "pyarrow", "h5py", "mlflow"}


@pytest.mark.process
@pytest.mark.parametrize(
    "args, env",
    [
        (["--version"], None),
        (["-sc", "query=bash"], {"COMP_LINE": "workbench --config-name=cov"}),
        (["-sc", "query=bash"], {"COMP_LINE": "workbench report "}),
    ],
)
def test_version_and_completions_without_config_import_neither_hydra_nor_numerics(tmp_path, args, env):
    assert not imported_by(args, tmp_path, env) & (HEAVY | {"hydra", "omegaconf"})


@pytest.mark.process
@pytest.mark.parametrize(
    "args, env",
    [
        (["--help"], None),
        (["dataset=animface", "--help"], None),
        (["-sc", "query=bash"], {"COMP_LINE": "workbench "}),
        (["-sc", "query=bash"], {"COMP_LINE": "workbench dataset."}),
        (["-sc", "query=bash"], {"COMP_LINE": "workbench rep"}),
    ],
)
def test_help_and_completions_import_hydra_but_no_numerics(tmp_path, args, env):
    imported = imported_by(args, tmp_path, env)
    assert "hydra" in imported and not imported & HEAVY


@pytest.mark.process
@pytest.mark.slow
def test_an_installed_package_finds_its_configs_inside_it_and_runs_from_any_folder(tmp_path):
    """The layout of the wheel (conf/ and studies/ inside the package), run from a folder outside the checkout:
    --help, a study at a small size, and no git state of whatever repository the environment lies in."""
    site = tmp_path / "site"
    shutil.copytree(REPO_ROOT / "workbench", site / "workbench", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(REPO_ROOT / "hydra_plugins", site / "hydra_plugins", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(CONF_DIR, site / "workbench" / "conf")
    shutil.copytree(STUDIES_DIR, site / "workbench" / "studies")
    work = tmp_path / "elsewhere"
    work.mkdir()
    where = python(
        "from workbench.settings import config; print(config.INSTALLED, config.CONF_DIR, config.CHECKOUT)",
        cwd=work,
        pythonpath=site,
    )
    assert where.stdout.split() == ["True", str(site / "workbench" / "conf"), "None"], where.stderr
    helped = python(None, "-m", "workbench", "--help", cwd=work, pythonpath=site)
    assert helped.returncode == 0 and "coverage_small" in helped.stdout and "solver: all, box" in helped.stdout
    run = python(
        None,
        "-m",
        "workbench",
        "dataset.n_frames=800",
        "solver=lstsq",
        "hydra.run.dir=outputs/one",
        cwd=work,
        pythonpath=site,
    )
    assert run.returncode == 0, run.stderr
    metrics = (work / "outputs" / "one" / "metrics.json").read_text()
    assert re.search(r'"commit": null', metrics) and re.search(r'"workbench": "\d', metrics)
    swept = python(
        None, "-m", "workbench", "--config-name", "coverage_small", "dataset.n_frames=600", cwd=work, pythonpath=site
    )
    assert swept.returncode == 0, swept.stderr
    assert (work / "outputs" / "coverage_small" / "default" / "collected" / "alpha_table.md").is_file()
    refused = python(None, "-m", "workbench", "report", "outputs/one", "--reference", cwd=work, pythonpath=site)
    assert refused.returncode == 2 and "installed package" in refused.stderr
