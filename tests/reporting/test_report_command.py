"""The ``workbench report`` command's own rules: where a report goes, the names it takes, and what it says of
the code that made a run and the report."""

import pytest
from in_process import run_workbench

from workbench.core.errors import WorkbenchError
from workbench.reporting.report.command import main, report_folder
from workbench.reporting.report.sections import commit_text, versions_section
from workbench.settings.config import REPO_ROOT

CONFIG = ("paper", "synthetic")  # study, dataset.kind


def texts(section):
    return [block for block in section.blocks if isinstance(block, str)]


def test_a_run_and_a_report_outside_a_git_checkout_say_so():
    metrics = {
        "git": {"commit": None, "dirty": None},
        "versions": {"numpy": "2.0"},
        "config_hash": "abc",
        "started_at": "2026-01-02T03:04:05+00:00",
    }
    builder = {"git": {"commit": None, "dirty": None}, "packages": {"numpy": "2.0"}}
    run_line, report_line = texts(versions_section(metrics, builder))
    assert run_line == "Run made on 2026-01-02 03:04 UTC not a git checkout, config hash `abc`."
    assert report_line.endswith(" not a git checkout with numpy 2.0.")
    assert "None" not in run_line + report_line
    # a record written before runs stated it has no git entry at all
    assert commit_text(None) == "not a git checkout" and commit_text({}) == "not a git checkout"


def test_a_checkout_names_its_commit_as_before():
    assert commit_text({"commit": "0123abc", "dirty": False}) == "at commit `0123abc` (uncommitted changes: False)"
    metrics = {"git": {"commit": "0123abc", "dirty": True}, "config_hash": "abc", "versions": {}}
    run_line, _ = texts(versions_section(metrics, {"git": {"commit": "4567def", "dirty": False}, "packages": {}}))
    assert "at commit `0123abc` (uncommitted changes: True), config hash `abc`." in run_line


@pytest.mark.parametrize("name", ["", ".", "..", "a/b", " ", "\t"])
def test_a_reference_report_name_that_is_no_plain_folder_name_is_refused(name, tmp_path):
    with pytest.raises(WorkbenchError, match=r"^--name must be a plain folder name \(not empty"):
        report_folder(tmp_path, *CONFIG, out=None, reference=True, name=name)
    # refused before the folder is read: an empty folder (no record) gets the same line
    with pytest.raises(WorkbenchError, match=r"^--name must be a plain folder name"):
        main([str(tmp_path), "--reference", "--name", name])


def test_an_empty_name_is_never_taken_as_the_default_and_exits_2_with_one_line(tmp_path):
    reports = REPO_ROOT / "reports"
    before = sorted(path.relative_to(reports) for path in reports.rglob("*")) if reports.is_dir() else []
    result = run_workbench("report", str(tmp_path), "--reference", "--name", "", cwd=tmp_path)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "--name" in lines[0] and "not empty" in lines[0], result.stderr
    after = sorted(path.relative_to(reports) for path in reports.rglob("*")) if reports.is_dir() else []
    assert after == before
    # the default name still works as before when --name is not given
    assert report_folder(tmp_path, *CONFIG, out=None, reference=True, name=None).name == "paper"


@pytest.mark.parametrize("name", [" ", "\t", "shared"])
def test_a_blank_or_reserved_reference_name_exits_2_with_one_line_and_writes_nothing(name, tmp_path):
    reports = REPO_ROOT / "reports"
    before = sorted(path.relative_to(reports) for path in reports.rglob("*")) if reports.is_dir() else []
    result = run_workbench("report", str(tmp_path), "--reference", "--name", name, cwd=tmp_path)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "--name" in lines[0], result.stderr
    assert ("reserved" if name == "shared" else "blank") in lines[0]
    after = sorted(path.relative_to(reports) for path in reports.rglob("*")) if reports.is_dir() else []
    assert after == before
    # a study of that name is refused the same way as the default name of its reference report
    with pytest.raises(WorkbenchError, match="--name"):
        report_folder(tmp_path, name, "synthetic", out=None, reference=True, name=None)


# A small run on both data variants (5 s of performance on a coarse mesh), without save_inputs.
BOTH = ["dataset.train_on=[markers,mesh]", "dataset.n_frames=600", "dataset.mesh_rows=35", "dataset.mesh_cols=30"]


@pytest.fixture(scope="module")
def run_without_inputs(tmp_path_factory):
    from workbench.api import run
    from workbench.settings.config import compose

    record = tmp_path_factory.mktemp("without_inputs") / "run"
    run(compose("paper", BOTH), record)
    assert not any(path.name.startswith("inputs") for path in record.iterdir())
    return record


@pytest.mark.slow
def test_the_report_of_a_run_that_saved_no_inputs_draws_every_figure(run_without_inputs, tmp_path):
    out = tmp_path / "report"
    assert main([str(run_without_inputs), "--out", str(out)]) == 0
    readme, page = (out / "README.md").read_text(), (out / "index.html").read_text()
    assert "not drawn" not in readme.lower() and "not drawn" not in page.lower()
    assert 'class="missing"' not in page
    for name in (
        "fig2_hand_vs_quasi_eigen",
        "fig3_reconstructions",
        "fig4_marker_errors",
        "vertex_rms",
        "weight_curves",
        "alpha_over_time",
        "marker_vs_mesh",
        "animation",
        "view3d",
    ):
        assert any(path.stem == name for path in (out / "figures").iterdir()), name


@pytest.mark.slow
def test_a_placeholder_remains_only_where_the_data_cannot_be_had_and_names_why(
    run_without_inputs, tmp_path, monkeypatch
):
    def unreadable(config):
        raise WorkbenchError("dataset.blendshapes: no file /data/ICT/face.obj")

    monkeypatch.setattr("workbench.study.run.run_study", unreadable)
    out = tmp_path / "report"
    assert main([str(run_without_inputs), "--out", str(out)]) == 0
    readme = (out / "README.md").read_text()
    assert (
        "**Figure 3: captured frames and their reconstructions**: not drawn (needs the frames of a mesh data "
        "variant (a run with dataset.train_on=[markers,mesh]), or those of a marker variant and the dataset's "
        "face mesh to carry them onto; the run saved no inputs and its data could not be read again: "
        "dataset.blendshapes: no file /data/ICT/face.obj)"
    ) in readme


def test_rebuilt_data_that_differ_from_the_record_are_refused(run_without_inputs):
    from workbench.record.record import load_record
    from workbench.reporting.report.data import rebuilt_arrays

    record = load_record(run_without_inputs)
    record.table.loc[0, "alpha_abs_mean"] *= 1.001  # as if the data read again were not those of the run
    with pytest.raises(WorkbenchError, match=r"recomputing the run gives alpha .* for data 'markers m=n'"):
        rebuilt_arrays(record, {})


def test_the_html_page_escapes_every_text_and_the_markdown_keeps_it_as_written():
    import pandas as pd

    from workbench.reporting.report.page import render_html, render_markdown
    from workbench.reporting.report.run_figures import FigureEntry
    from workbench.reporting.report.sections import Section

    sections = [
        Section(
            "A <b> & c",
            [
                "`x<y` and **bold <i>** end",
                ["item <z>"],
                pd.DataFrame({"key": ["<td>"], "value": [1.5]}),
                FigureEntry("stem", "Fig <1>", "cap `c`", missing="needs <mesh>"),
            ],
        )
    ]
    page = render_html("T <script>", sections)
    assert "<title>T &lt;script&gt;</title>" in page and "<h2>A &lt;b&gt; &amp; c</h2>" in page
    assert "<p><code>x&lt;y</code> and <strong>bold &lt;i&gt;</strong> end</p>" in page
    assert "<li>item &lt;z&gt;</li>" in page and '<td>&lt;td&gt;</td><td class="num">1.5</td>' in page
    assert "<strong>Fig &lt;1&gt;</strong>: not drawn (needs &lt;mesh&gt;)." in page
    assert "<script>" not in page.split("</h1>")[0]
    readme = render_markdown("T <script>", sections)
    assert readme.startswith("# T <script>\n\n## A <b> & c\n\n`x<y` and **bold <i>** end\n\n- item <z>\n\n")
    assert "**Fig <1>**: not drawn (needs <mesh>).\n" in readme and readme.endswith(").\n")


def test_each_figure_goes_in_the_section_its_row_names(tmp_path):
    """The run's headline, its figures and the other bases' figure come through one list of rows; each row's last
    column is the section that shows it."""
    from workbench.reporting.report.run_figures import FIGURES_SECTION, make_figures, placed

    rows = [
        ("first", "First", "one", lambda _, options: "needs markers", FIGURES_SECTION),
        ("lead", "Lead", "two", lambda _, options: "needs a mesh", "Summary"),
        ("dropped", "Dropped", "none", lambda _, options: None, "Summary"),
        ("second", "Second", "three", lambda _, options: "needs takes", FIGURES_SECTION),
    ]
    entries = make_figures(rows, None, tmp_path / "figures", (), {})
    assert [(entry.stem, entry.section) for entry in entries] == [
        ("first", FIGURES_SECTION),
        ("lead", "Summary"),
        ("second", FIGURES_SECTION),
    ]
    assert [entry.stem for entry in placed(entries, FIGURES_SECTION)] == ["first", "second"]
    assert [entry.missing for entry in placed(entries, "Summary")] == ["needs a mesh"]
    assert placed(entries, "Other bases: alpha against intuitiveness") == []
