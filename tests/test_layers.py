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

ROOT = Path(__file__).resolve().parents[1]
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


def contract_layers() -> list[list[str]]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    (contract,) = [contract for contract in config["contracts"] if contract["type"] == "layers"]
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
