"""The layers contract (``[tool.importlinter]`` in pyproject.toml): every module imports only downward, function-level
imports included, and every module of the package is in a layer."""

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytest.importorskip("importlinter")
try:
    import tomllib
except ImportError:  # Python 3.10
    tomllib = pytest.importorskip("tomli")

ROOT = Path(__file__).resolve().parents[2]
LINT = "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"


def lint_imports(folder: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", LINT, "--no-cache"],
        cwd=folder,
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(folder), "PATH": "/usr/bin:/bin"},
        timeout=300,
    )


def layers_contracts() -> list[dict]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    return [contract for contract in config["contracts"] if contract["type"] == "layers"]


def contract_layers(container: str | None = None) -> list[list[str]]:
    """The layers of the contract over ``container`` (None: the package-wide one), each a list of its names."""
    (contract,) = [item for item in layers_contracts() if item.get("containers", [None]) == [container]]
    return [[name.strip() for name in layer.replace("|", ":").split(":")] for layer in contract["layers"]]


@pytest.mark.process
def test_imports_only_go_down_the_layers():
    done = lint_imports(ROOT)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert "0 broken" in done.stdout


def test_every_module_is_in_a_layer():
    """The folders are the layers: at the package's top only its entry points, every other module inside a folder
    that the contract names."""
    listed = {name for layer in contract_layers() for name in layer}
    package = ROOT / "workbench"
    top = {path.stem for path in package.glob("*.py")}
    assert top <= {"__init__", "__main__", "version", "api"}, "modules at the package's top: move them into a layer"
    found = {f"workbench.{stem}" for stem in top if stem != "__init__"}
    found |= {f"workbench.{path.parent.name}" for path in package.glob("*/__init__.py")}
    assert found - listed == set(), "modules in no layer of the contract"
    assert listed - found == set(), "layers naming no module"


def test_the_reporting_wing_is_folders_each_a_layer():
    """The reporting wing's rooms: every module of ``workbench/reporting`` is inside a folder its contract names, and
    the contract is exhaustive, so a new module outside them fails :func:`test_imports_only_go_down_the_layers`."""
    (contract,) = [item for item in layers_contracts() if item.get("containers") == ["workbench.reporting"]]
    assert contract.get("exhaustive") is True
    listed = {name for layer in contract_layers("workbench.reporting") for name in layer}
    wing = ROOT / "workbench" / "reporting"
    assert {path.stem for path in wing.glob("*.py")} == {"__init__"}, "modules loose in workbench/reporting"
    assert {path.parent.name for path in wing.glob("*/__init__.py")} == listed


@pytest.mark.process
def test_an_upward_import_in_a_function_breaks_the_contract(tmp_path):
    """The check is not vacuous: a function-level import from a lower layer up to a higher one is found."""
    package = tmp_path / "toy"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "high.py").write_text("from toy.low import value\n")
    (package / "low.py").write_text(
        textwrap.dedent("""
        value = 1

        def upward():
            from toy import high
            return high
    """)
    )
    (tmp_path / "pyproject.toml").write_text(
        textwrap.dedent("""
        [tool.importlinter]
        root_package = "toy"

        [[tool.importlinter.contracts]]
        name = "toy layers"
        type = "layers"
        layers = ["toy.high", "toy.low"]
    """)
    )
    done = lint_imports(tmp_path)
    assert done.returncode != 0
    assert "toy.low is not allowed to import toy.high" in done.stdout
