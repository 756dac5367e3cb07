"""The order the suite's scopes are handed out to pytest-xdist's processes (the longest first, as measured), and the
folders the suite is kept in."""

from pathlib import Path

from conftest import LONGEST_FIRST, hand_out_rank, scope_of


def test_a_scope_is_a_methods_class_or_else_its_file():
    assert scope_of("tests/project/test_docs.py::TestCommandsOf_README_md::test_commands_run") == (
        "tests/project/test_docs.py::TestCommandsOf_README_md"
    )
    assert scope_of("tests/test_a.py::test_b[x::y-1]") == "tests/test_a.py"
    assert scope_of("tests/test_a.py::test_b") == "tests/test_a.py"


def test_scopes_go_out_longest_first_and_unmeasured_ones_last_each_in_one_block():
    seconds = {"tests/test_short.py": 2.0, "tests/test_long.py::TestBig": 30.0, "tests/test_middle.py": 10.0}
    collected = [
        "tests/test_new.py::test_one",
        "tests/test_short.py::test_one",
        "tests/test_short.py::test_two",
        "tests/test_long.py::TestBig::test_one",
        "tests/test_long.py::test_outside_the_class",
        f"{LONGEST_FIRST[1]}::test_commands_run",
        "tests/test_middle.py::test_one",
        "tests/test_long.py::TestBig::test_two",
    ]
    ordered = sorted(collected, key=lambda nodeid: hand_out_rank(nodeid, seconds))
    assert ordered == [
        f"{LONGEST_FIRST[1]}::test_commands_run",
        "tests/test_long.py::TestBig::test_one",
        "tests/test_long.py::TestBig::test_two",
        "tests/test_middle.py::test_one",
        "tests/test_short.py::test_one",
        "tests/test_short.py::test_two",
        "tests/test_new.py::test_one",
        "tests/test_long.py::test_outside_the_class",
    ]


def test_the_test_folders_are_the_layers_of_the_package():
    """Each test file sits in the folder of the layer it tests (``pytest tests/numerics`` tests one layer); ``api``
    for the module of that name, ``project`` for the documentation, the layers, the packaging and the suite."""
    tests = Path(__file__).resolve().parents[1]
    package = tests.parent / "workbench"
    layers = {path.name for path in package.iterdir() if (path / "__init__.py").is_file()} | {"api", "project"}
    folders = {path.parent.name for path in tests.rglob("test_*.py")}
    assert not list(tests.glob("test_*.py")) and folders <= layers, sorted(folders - layers)
