"""``workbench report``: reports of a run and of a sweep, rebuilt from records only, and the committed reference."""

import json
import math
import re
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import yaml
from PIL import Image
from scipy import stats

from workbench.api import run
from workbench.cli.main import COMMANDS
from workbench.core.errors import WorkbenchError
from workbench.record.record import find_records, load_record
from workbench.reporting.findings.run_summary import SUMMARY_WORDS as RUN_SUMMARY_WORDS
from workbench.reporting.findings.sweep_summary import SUMMARY_WORDS as SWEEP_SUMMARY_WORDS
from workbench.reporting.report.command import main
from workbench.reporting.report.data import figure_solver, frame_alpha, quasi_eigen_shapes, reconstruct_frames
from workbench.reporting.report.run_figures import RUN_FIGURES
from workbench.reporting.report.sections import headline_table
from workbench.reporting.tables.cells import markdown_frame
from workbench.reporting.tables.runs import flatten, summarise, varying_keys, wide
from workbench.settings.config import REPO_ROOT, compose
from workbench.settings.schema import RETIRED_SETTINGS

# The committed reference reports and the overrides of the runs they were built from, each checked against a fresh
# run. The real takes run at every 4th frame, so that this test can redo each run in a few minutes (most of it the
# folds of kfold). The synthetic actor's report is at the paper's 35,000 frames, too large to redo here (its mesh
# variant alone is 3.5 GB of frames; 16 GB at its peak): its 4,000-frame rerun is checked against the text and table
# of the same run committed beside this file (tests/reference/paper-4000, rebuilt with the reports).
REFERENCE_RUNS = REPO_ROOT / "tests" / "reference"
REFERENCES = {
    "paper": (
        REFERENCE_RUNS / "paper-4000",
        [
            "dataset.train_on=[markers,mesh]",
            "dataset.n_frames=4000",
            "dataset.held_out=[tail,kfold]",
            "save_inputs=true",
        ],
    ),
    "paper-ict_livelink": (
        REPO_ROOT / "reports" / "paper-ict_livelink",
        ["dataset=ict_livelink", "dataset.frame_step=4", "dataset.held_out=[tail,kfold]", "save_inputs=true"],
    ),
    # each take held out in turn (take_out) includes the last take held out (the protocol take): not run twice
    "paper-animface": (
        REPO_ROOT / "reports" / "paper-animface",
        ["dataset=animface", "dataset.frame_step=4", "dataset.held_out=[tail,kfold,take_out]", "save_inputs=true"],
    ),
}
PAPER_SIZE = {"paper": {"dataset.n_frames": 35000, "dataset.held_out": "[tail, kfold]"}}
"""Settings of the committed reports at the paper's size, beside the run each is checked by."""
FIGURE_STEMS = [spec[0] for spec in RUN_FIGURES]


# tiny_report (tests/conftest.py): a small run on both data variants, inputs saved, and its report


@pytest.mark.slow
def test_run_writes_per_frame_alpha_that_matches_the_table(tiny_report):
    record, _ = tiny_report
    table = pd.read_csv(record / "alpha_table.csv")
    with np.load(record / "alpha_per_frame.npz") as arrays:
        for data in ("markers", "mesh"):
            part = table[table["data"] == data]
            assert list(arrays[f"{data}.basis"]) == list(part["basis"])
            assert list(arrays[f"{data}.solver"]) == list(part["solver"])
            np.testing.assert_allclose(
                np.nanmean(arrays[f"{data}.absolute"], axis=1), part["alpha_abs_mean"], rtol=1e-12
            )
            np.testing.assert_allclose(
                np.nanmean(arrays[f"{data}.displacement"], axis=1), part["alpha_disp_mean"], rtol=1e-12
            )
            np.testing.assert_allclose(np.median(arrays[f"{data}.error_mm"], axis=1), part["err_mm_median"], rtol=1e-12)
    # read back, PCA's empty weight cells are NaN in numeric columns
    read = load_record(record).table
    assert read["w_max_abs"].dtype == float and read.loc[read["basis"] == "PCA", "w_max_abs"].isna().all()


@pytest.mark.slow
def test_recorded_comparisons_are_those_of_the_recorded_per_frame_alpha(tiny_report):
    """Every paired comparison in metrics.json is the block bootstrap of the per-frame alpha the record keeps."""
    from workbench.stats.statistics import paired_mean_difference

    record, _ = tiny_report
    metrics = json.loads((record / "metrics.json").read_text())
    with np.load(record / "alpha_per_frame.npz") as arrays:
        for data in ("markers", "mesh"):
            rows = list(zip(arrays[f"{data}.basis"], arrays[f"{data}.solver"]))
            comparisons = metrics["data"][data]["comparisons"]
            assert len(comparisons) == 27  # 6 pairs under each of 3 solvers, 3 pairs of solvers for 3 bases
            for entry in comparisons[::5]:
                a, b = (arrays[f"{data}.absolute"][rows.index(tuple(entry[key]))] for key in ("a", "b"))
                again = paired_mean_difference(a, b, takes=arrays[f"{data}.take"], seconds=arrays[f"{data}.seconds"])
                assert (again.estimate, again.low, again.high) == (entry["estimate"], entry["low"], entry["high"])


RENDERED = ("fig2", "fig3", "vertex_rms", "weight_statistics")  # rendered faces and the bar chart: lossless WebP;
# the rest are line plots: SVG


@pytest.mark.slow
def test_every_figure_exists_and_is_non_trivial(tiny_report):
    _, report = tiny_report
    for stem in FIGURE_STEMS:
        webp, svg = report / "figures" / f"{stem}.webp", report / "figures" / f"{stem}.svg"
        if stem.startswith(RENDERED):
            assert webp.is_file() and not svg.is_file(), stem
            image = Image.open(webp)
            assert 30_000 < webp.stat().st_size < 1_000_000 and image.size[0] >= 1000, (stem, image.size)
            pixels = np.asarray(image.convert("RGB"))
            assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 256, stem  # full colour, no palette
            continue
        assert svg.is_file() and not webp.is_file() and not (report / "figures" / f"{stem}.png").is_file(), stem
        text = svg.read_text()
        assert "<svg" in text[:2000] and 5_000 < len(text) < 400_000, (stem, len(text))
        assert "<text" in text  # labels are text, sharp at any zoom


@pytest.mark.slow
def test_report_documents_hold_tables_figures_provenance_choices_and_versions(tiny_report):
    record, report = tiny_report
    page = (report / "index.html").read_text()
    readme = (report / "README.md").read_text()
    for stem in FIGURE_STEMS:
        shown = f"figures/{stem}.{'webp' if stem.startswith(RENDERED) else 'svg'}"
        assert f'src="{shown}"' in page and f"]({shown})" in readme
    for document in (page, readme):
        for heading in (
            "Alpha beside the paper",
            "Full alpha table",
            "Choices the run made",
            "Dataset provenance and licence",
            "Versions and commit",
            "Findings",
            "Run facts",
            "Faces you can turn",
            "Left and right",
            "Error in millimetres and the weights",
            "Paired comparisons within the run",
        ):
            assert heading in document
        assert "synthetic" in document and "not applicable: generated by the workbench" in document
        assert json.loads((record / "metrics.json").read_text())["git"]["commit"] in document
        assert re.search(r"Run made on 20\d\d-\d\d-\d\d \d\d:\d\d UTC", document)
        assert re.search(r"Report built on 20\d\d-\d\d-\d\d \d\d:\d\d UTC", document)
        assert "the capture moves the two sides of the face together" in document
    assert "affine, linear" in readme and "lstsq (lstsq), nnls (nnls, bounds [0.0, None])" in readme
    # the summary, then the headline figure with intervals, then findings within 800 words
    assert readme.index("## Summary") < readme.index("](figures/headline.svg)") < readme.index("## Findings")
    assert 'src="figures/headline.svg"' in page
    assert len(section_text("## Findings", readme).split()) <= 800
    # The README's full table is the very text the run printed.
    printed = (record / "alpha_table.md").read_text()
    assert table_after("## Full alpha table", readme) == table_after("| data", printed)
    pd.testing.assert_frame_equal(pd.read_csv(report / "alpha_table.csv"), pd.read_csv(record / "alpha_table.csv"))
    assert yaml.safe_load((report / "run_config.yaml").read_text()) == load_record(record).config


# Headless Chromium with software WebGL and no network: every host resolves to nothing and every request goes to a
# closed proxy, so a page that needed anything from outside its folder would show it.
OFFLINE_CHROMIUM = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--proxy-server=127.0.0.1:9",
    "--host-resolver-rules=MAP * ~NOTFOUND",
    "--virtual-time-budget=30000",
)


def browser_page(chromium: str, page, *args: str) -> str:
    """Load a page in headless Chromium (software WebGL), let its scripts run, and return the DOM (or what the
    extra arguments ask for)."""
    done = subprocess.run(
        [chromium, *OFFLINE_CHROMIUM, *args, page.as_uri()], capture_output=True, text=True, timeout=180
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def view_status(chromium: str, page, *args: str) -> tuple[str, str]:
    """The 3-D view's self-check (``data-status``) and the page's DOM after its scripts ran."""
    dom = browser_page(chromium, page, *args, "--dump-dom")
    return re.search(r'data-status="([^"]*)"', dom).group(1), dom


def assert_both_halves_drawn(status: str) -> None:
    assert status.startswith("drawn"), status
    left, right, half = map(int, re.findall(r"\d+", status))
    assert 0.05 < left / half < 0.9 and 0.05 < right / half < 0.9, status


@pytest.mark.slow
@pytest.mark.process
def test_interactive_view_draws_the_face_in_a_browser_from_file(tiny_report, chromium):
    """The page opened from file:// with no server and no network: the viewer and the mesh data load, the captured
    and the reconstructed face are drawn side by side (the page counts each half's non-background pixels), and the
    menus list figure 3's frames and every basis of the table."""
    _, report = tiny_report
    page = (report / "index.html").read_text()
    assert 'src="figures/view3d.js"' in page and "../" not in re.sub(r"<(a|img) [^>]*>", "", page)
    assert "http://" not in page and "https://" not in page  # nothing fetched from the network
    status, dom = view_status(chromium, report / "index.html")
    assert_both_halves_drawn(status)
    assert "most displaced mouth: synthetic seed 0 frame" in dom and ">captured</option>" not in dom
    for basis in (
        "H, the hand shapes",
        "QE, quasi-eigen faces (affine projection)",
        "QE-linear, quasi-eigen faces (linear projection)",
        "PCA, the m eigenfaces",
    ):
        assert f">{basis}</option>" in dom
    assert 'id="view3d-left">captured: most displaced' in dom and 'id="view3d-right">reconstructed with H' in dom


@pytest.mark.slow
@pytest.mark.process
def test_a_report_folder_copied_anywhere_still_draws_its_3d_view(tiny_report, chromium, tmp_path):
    """Everything the page needs is inside the report folder: a copy elsewhere, away from every other report, opened
    from file:// with no network, loads every figure and the animation and draws its 3-D view, and a link to
    another frame and basis opens them."""
    _, report = tiny_report
    copy = tmp_path / "elsewhere" / "deeper" / "my report"
    shutil.copytree(report, copy)
    status, dom = view_status(chromium, copy / "index.html")
    assert_both_halves_drawn(status)
    assert_every_figure_loaded(dom, copy / "index.html")
    uri = (copy / "index.html").as_uri() + "#frame=2&shown=QE-linear&colour=plain"
    done = subprocess.run([chromium, *OFFLINE_CHROMIUM, "--dump-dom", uri], capture_output=True, text=True, timeout=180)
    linked = done.stdout
    assert_both_halves_drawn(re.search(r'data-status="([^"]*)"', linked).group(1))
    assert 'id="view3d-right">reconstructed with QE-linear, quasi-eigen faces (linear projection)' in linked
    assert "plain shaded: the geometry alone" in linked


def assert_every_figure_loaded(dom: str, page) -> None:
    """Every image of the page (each figure and the animation) loaded in the browser: the page marks each one."""
    images = re.findall(r"<img [^>]*>", dom)
    assert len(images) == page.read_text().count("<img "), "the page's figure check did not run"
    broken = [image for image in images if 'data-loaded="yes"' not in image]
    assert not broken, broken


@pytest.mark.slow
@pytest.mark.process
def test_a_copied_report_missing_a_figure_says_so(tiny_report, chromium, tmp_path):
    """The browser check can fail: a copy without one of its figures marks that image as not loaded and names the
    file under it."""
    _, report = tiny_report
    copy = tmp_path / "partial"
    shutil.copytree(report, copy)
    (copy / "figures" / "coverage_curve.svg").unlink()
    dom = browser_page(chromium, copy / "index.html", "--dump-dom")
    with pytest.raises(AssertionError, match="coverage_curve"):
        assert_every_figure_loaded(dom, copy / "index.html")
    assert "Figure file not found beside this page: figures/coverage_curve.svg" in dom


@pytest.mark.slow
def test_animation_and_report_text(tiny_report):
    _, report = tiny_report
    animation = Image.open(report / "figures" / "animation.webp")
    animation.load()
    # 2 s of the take at 10 frames per second (the 120 Hz actor, every 12th frame), played in real time
    assert animation.n_frames == 20 and animation.info["duration"] == 100 and animation.size[0] >= 960
    readme = (report / "README.md").read_text()
    assert "played in real time: 10 frames per second" in readme
    assert readme.index("## Findings") < readme.index("## Run facts") < readme.index("## Alpha beside the paper")
    assert "(paper 7.22)" in readme and "(paper: m = 18)" in readme
    assert "uncommitted changes" in readme and "frames per second in the frames used" in readme


def table_after(marker: str, text: str) -> str:
    """The first Markdown table at or after ``marker``."""
    lines = text[text.index(marker) :].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("|"))
    end = next((i for i in range(start, len(lines)) if not lines[i].startswith("|")), len(lines))
    return "\n".join(lines[start:end])


@pytest.mark.slow
def test_headline_table_puts_the_paper_beside_the_measured_values(tiny_report):
    record, _ = tiny_report
    table = load_record(record).table
    headline = headline_table(table, "alpha_abs_mean")
    assert list(headline.columns) == [
        "data",
        "basis",
        "paper_alpha",
        "alpha_abs_mean lstsq",
        "alpha_abs_mean nnls",
        "alpha_abs_mean box",
    ]
    row = headline[(headline["data"] == "mesh") & (headline["basis"] == "QE")].iloc[0]
    assert row["paper_alpha"] == 0.72
    expected = table[(table["data"] == "mesh") & (table["basis"] == "QE") & (table["solver"] == "nnls")]
    assert row["alpha_abs_mean nnls"] == expected["alpha_abs_mean"].iloc[0]
    pca = headline[(headline["data"] == "mesh") & (headline["basis"] == "PCA")].iloc[0]
    assert pca["alpha_abs_mean lstsq"] == pca["alpha_abs_mean box"]  # PCA has no solver: the same in every column
    text = markdown_frame(headline)
    assert "|        0.72 |" in text and "| QE-linear |           - |" in text


@pytest.mark.slow
def test_figures_recompute_exactly_what_the_run_measured(tiny_report):
    """The arrays behind figures 3-4, recomputed from inputs with the core, give the run's per-frame alpha."""
    record, _ = tiny_report
    loaded = load_record(record)
    _, solver = figure_solver(loaded.config)
    per_frame = loaded.load_alpha_per_frame()
    for data in ("markers", "mesh"):
        inputs = loaded.load_inputs(data)
        frames = [3, 250, 599]
        captured = inputs["eval"][frames]
        bases = list(per_frame[f"{data}.basis"])
        solvers = list(per_frame[f"{data}.solver"])
        for label, shapes in (
            ("H", inputs["hand"]),
            ("QE", quasi_eigen_shapes(inputs, "affine")),
            ("QE-linear", quasi_eigen_shapes(inputs, "linear")),
        ):
            alpha = frame_alpha(inputs["neutral"], captured, reconstruct_frames(shapes, captured, solver))
            row = [i for i, (b, s) in enumerate(zip(bases, solvers)) if b == label and s == "lstsq"][0]
            np.testing.assert_allclose(alpha["absolute"], per_frame[f"{data}.absolute"][row, frames], rtol=1e-9)
            np.testing.assert_allclose(alpha["displacement"], per_frame[f"{data}.displacement"][row, frames], rtol=1e-9)


@pytest.mark.slow
def test_figures_of_a_run_without_saved_inputs_are_drawn_from_rebuilt_inputs_save_those_of_a_missing_variant(
    tmp_path, capfd
):
    record = tmp_path / "run"
    run(compose("paper", ["dataset.n_frames=300", "solver=lstsq"]), record)
    capfd.readouterr()
    assert main([str(record), "--out", str(tmp_path / "reports" / "paper"), "--formats", "png"]) == 0
    # rendering off-screen (VTK's warning about the X server on a headless machine): no raw terminal codes
    printed = "".join(capfd.readouterr())
    assert "\x1b[" not in printed, printed
    readme = (tmp_path / "reports" / "paper" / "README.md").read_text()
    # a run on markers only has no mesh variant: its faces are the markers carried onto the mesh, and they say so
    assert "not drawn" not in readme and "could not be read again" not in readme
    assert (
        "Markers carried onto the mesh by RBF (as in the paper); the run has no mesh data variant: the faces "
        "drawn are the displacement fields of the 'markers m=n' variant"
    ) in readme
    # the faces and the markers are those of the paper's regime m = n, the variant the summary's verdict is about
    assert "data variant 'markers m=n', m = 18 (m = n, the paper's regime)" in readme
    assert "data variant 'markers'," not in readme
    figures = sorted(path.name for path in (tmp_path / "reports" / "paper" / "figures").iterdir())
    # what the record holds is drawn from metrics.json (the headline figure too); the rest from the inputs rebuilt
    # from its config; marker versus mesh is no figure of a run on one data variant
    stems = {name.rsplit(".", 1)[0] for name in figures}
    assert stems == {
        "headline",
        "alpha_per_solver",
        "coverage_curve",
        "error_cdf",
        "fig1_analogy",
        "intuitiveness",
        "weight_statistics",
        "alpha_over_time",
        "fig4_marker_errors",
        "weight_curves",
        "fig2_hand_vs_quasi_eigen",
        "fig3_reconstructions",
        "vertex_rms",
        "animation",
        "view3d",
        "rigs",  # the rig panel's data, and three.js with its licence beside it
        "three.min",
        "three-LICENSE",
    }, figures
    assert "Marker versus mesh" not in readme
    assert not any(path.name.startswith("inputs") for path in record.iterdir())  # the record is left as it was


def make_sweep(root, coverages=(0.99, 0.999), seeds=(0, 1)):
    k = 0
    for coverage in coverages:
        for seed in seeds:
            run(
                compose(
                    "paper",
                    [
                        "dataset.n_frames=300",
                        f"basis.coverage={coverage}",
                        f"dataset.seed={seed}",
                        "solver=lstsq",
                        "basis.paper_regime=false",
                    ],
                ),
                root / str(k),
            )
            k += 1
    (root / "incomplete").mkdir()
    (root / "incomplete" / "config.yaml").write_text("study: paper\n")  # no 'done': a run still going or failed
    return root


@pytest.mark.slow
def test_sweep_report_summarises_seeds_and_plots_every_swept_setting(tmp_path):
    root = make_sweep(tmp_path / "sweep")
    assert [path.name for path in find_records([root])[0]] == ["0", "1", "2", "3"]
    assert main([str(root), "--out", str(tmp_path / "reports" / "coverage")]) == 0
    report = tmp_path / "reports" / "coverage"
    summary = pd.read_csv(report / "summary.csv")
    assert set(summary["basis.coverage"]) == {0.99, 0.999} and (summary["n_seeds"] == 2).all()
    runs = pd.read_csv(report / "runs.csv", dtype={"run": str})
    assert sorted(runs["run"].unique()) == ["0", "1", "2", "3"]
    # The interval is the t-interval of the mean log over the two seeds, taken back: around the geometric mean.
    values = runs[(runs["basis.coverage"] == 0.99) & (runs["basis"] == "QE")]["alpha_abs_mean"].to_numpy()
    row = summary[(summary["basis.coverage"] == 0.99) & (summary["basis"] == "QE")].iloc[0]
    logs = np.log(values)
    half = stats.t.ppf(0.975, 1) * logs.std(ddof=1) / math.sqrt(2)
    assert row["alpha_abs_mean"] == pytest.approx(math.exp(logs.mean()))
    assert row["alpha_abs_mean_ci_high"] == pytest.approx(math.exp(logs.mean() + half))
    lows = summary.filter(like="_ci_low")  # NaN where the seeds gave the same value: no interval
    assert lows.notna().any(axis=None) and (lows.isna() | (lows > 0)).all(axis=None)
    assert row["ci_method"] == "geometric mean, t-interval on log values"
    for stem in ("coverage_curve", "alpha_vs_basis_coverage", "alpha_vs_m"):
        assert (report / "figures" / f"{stem}.svg").stat().st_size > 15_000, stem
    page = (report / "index.html").read_text()
    assert "sweep over basis.coverage" in page and "replicates over dataset.seed 0, 1" in page
    readme = (report / "README.md").read_text()
    findings = section_text("## Findings", readme)
    assert len(findings.split()) <= 800
    assert findings.count("(paired t on log ratios, n = 2)") == 1  # the method, said once
    comparisons = pd.read_csv(report / "comparisons.csv")
    assert len(comparisons) == 2 * 6 and set(comparisons["verdict"]) <= {
        "<",
        "not distinguishable",
        "<= by construction",
    }
    # every tested row is one Holm family, QE/H and QE/PCA among them (the paper's claims are the runs' stored
    # ones), and an ordering by construction is none: it has no p-value
    assert set(comparisons["family"]) <= {"secondary", "identity"}
    tested = comparisons["family"] != "identity"
    assert comparisons.loc[tested, "p_holm"].notna().all() and comparisons.loc[~tested, "p_holm"].isna().all()
    assert (comparisons.loc[~tested, "verdict"] == "<= by construction").all()
    assert readme.split("\n## ", 2)[1].startswith("Summary\n")  # the report opens with its summary
    assert len(section_text("## Summary", readme).split()) <= RUN_SUMMARY_WORDS
    joins = 0
    for row in comparisons.to_dict("records"):  # every pair a finding joins is a row of the comparisons table
        line = " ".join(  # the cell's stored claims, its ordering and its secondary QE/H and QE/PCA
            line for line in findings.splitlines() if line.startswith(f"- basis.coverage = {row['basis.coverage']},")
        )
        first, second = row["first"], row["second"]
        joined = re.search(
            rf"{re.escape(first)}(?: \(n = [^)]*\))? [0-9.e+-]+(?: by construction \([^)]*\))? "
            rf"(<=|[<~=]) {re.escape(second)}[ ,;.]",
            line,
        )
        if joined:
            joins += 1
            said = {"<": "<", "<= by construction": "<="}.get(row["verdict"], "~")
            assert joined.group(1) == said, (row, line)
            if said == "<=":  # an identity: stated with its reason, never tested
                assert isinstance(row["by_construction"], str) and math.isnan(row["p"]), row
        if {first, second} in ({"QE", "H"}, {"QE", "PCA"}):  # secondary at the cell's m: ratio and interval, QE first
            other = second if first == "QE" else first
            ratio, low, high = (
                (row["ratio"], row["ratio_low"], row["ratio_high"])
                if first == "QE"
                else (1 / row["ratio"], 1 / row["ratio_high"], 1 / row["ratio_low"])
            )
            assert f"QE/{other} {ratio:.3g} [{low:.3g}, {high:.3g}]" in line, (row, line)
    assert joins == 2 * 3  # 3 neighbouring pairs at each coverage


def test_alpha_against_m_groups_runs_by_m_and_counts_a_run_once():
    from workbench.reporting.report.sweep import by_m

    # seed 0 keeps m = 3 at 0.9 and 4 at 0.99; seed 1 keeps 4 at both thresholds (the same run twice)
    per_run = pd.DataFrame(
        {
            "study": "coverage",
            "basis.coverage": [0.9, 0.99, 0.9, 0.99],
            "dataset.seed": [0, 0, 1, 1],
            "data": "markers",
            "train_on": "markers",
            "eval_on": "markers",
            "basis": "QE",
            "projection": "affine",
            "solver": "lstsq",
            "m": [3, 4, 4, 4],
            "n": 18,
            "alpha_abs_mean": [0.4, 0.2, 0.3, 0.3],
        }
    )
    summary = by_m(per_run, ["basis.coverage"], ["dataset.seed"]).set_index("m")
    assert list(summary.index) == [3, 4] and list(summary["n_seeds"]) == [1, 2]
    assert summary.loc[4, "alpha_abs_mean"] == pytest.approx(math.sqrt(0.2 * 0.3))  # never m = 3.5 or 4.0 averaged


def test_collect_and_report_give_the_same_numbers_for_one_sweep(tmp_path):
    from workbench.reporting.collect.sweep import collect_and_write
    from workbench.study.table import ALPHA_COLUMNS

    root = make_sweep(tmp_path / "sweep", coverages=(0.99, 0.995))
    assert main([str(root), "--formats", "png"]) == 0  # beside the runs: <sweep>/report
    collect_and_write([root], tmp_path / "collected")
    reported = pd.read_csv(root / "report" / "summary.csv")
    collected = pd.read_csv(tmp_path / "collected" / "summary.csv")
    keys = ["basis.coverage", "data", "basis", "solver"]
    for column in ALPHA_COLUMNS:
        long = collected[collected["metric"] == column].set_index(keys)
        both = reported.set_index(keys)[[column, f"{column}_ci_low", f"{column}_ci_high"]].join(long, how="outer")
        assert len(both) == len(reported) == len(long), column
        np.testing.assert_array_equal(both[column], both["geomean"])
        np.testing.assert_array_equal(both[f"{column}_ci_low"], both["ci95_low"])
        np.testing.assert_array_equal(both[f"{column}_ci_high"], both["ci95_high"])


def test_summarise_runs_known_answer():
    per_run = pd.DataFrame(
        {
            "study": "noise",
            "dataset.noise": [0.1, 0.1, 0.1, 0.2],
            "dataset.seed": [0, 1, 2, 0],
            "data": "markers",
            "train_on": "markers",
            "eval_on": "markers",
            "basis": "H",
            "projection": "-",
            "solver": "lstsq",
            "m": [10, 11, 12, 13],
            "n": 18,
            "alpha_abs_mean": [1.0, 2.0, 3.0, 5.0],
        }
    )
    summary = wide(summarise(per_run, metrics=["alpha_abs_mean", "m"]))
    first, second = summary.iloc[0], summary.iloc[1]
    assert first["n_seeds"] == 3 and (first["m_min"], first["m_max"]) == (10, 12)
    logs = np.log([1.0, 2.0, 3.0])
    half = stats.t.ppf(0.975, 2) * logs.std(ddof=1) / math.sqrt(3)
    assert first["alpha_abs_mean"] == pytest.approx(6 ** (1 / 3))
    assert first["alpha_abs_mean_ci_low"] == pytest.approx(math.exp(logs.mean() - half))
    assert second["n_seeds"] == 1 and math.isnan(second["alpha_abs_mean_ci_low"])


def test_varying_keys_leave_out_paths_and_identical_settings():
    configs = [
        {
            "study": "paper",
            "paths": {"output_root": "a"},
            "basis": {"coverage": 0.99, "projections": ["affine"]},
            "dataset": {"seed": 0},
        },
        {
            "study": "paper",
            "paths": {"output_root": "b"},
            "basis": {"coverage": 0.999, "projections": ["affine"]},
            "dataset": {"seed": 1},
        },
    ]
    assert varying_keys(configs) == ["basis.coverage", "dataset.seed"]
    assert flatten(configs[0])["basis.projections"] == "[affine]"


@pytest.mark.process
def test_command_is_registered_and_reports_errors_in_one_line(tmp_path):
    assert COMMANDS["report"] == "workbench.reporting.report.command:main"
    with pytest.raises(WorkbenchError, match="not a folder"):
        main([str(tmp_path / "missing")])
    with pytest.raises(WorkbenchError, match="no complete run record"):
        main([str(tmp_path)])
    done = subprocess.run(
        [sys.executable, "-c", "from workbench.cli.main import main; main()", "report", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1].startswith("workbench report: error: ")


@pytest.fixture
def undrawn(monkeypatch):
    """A report's figures are listed but not drawn: the reruns of the committed reports compare their numbers and
    text, which the figures play no part in (half of a report's time). The figures are drawn from real data by
    the tests of the tiny report, of the AnimFace report and of the documents' commands (docs/reports.md draws the
    ICT report), and checked in the committed reports."""
    from workbench.reporting.report import run, sweep
    from workbench.reporting.report.run_figures import FigureEntry

    def listed(specs, argument, folder, formats, options):
        return [
            FigureEntry(stem=stem, title=title, caption=caption, section=section, missing="not drawn in this test")
            for stem, title, caption, draw, section in specs
        ]

    monkeypatch.setattr(run, "make_figures", listed)
    monkeypatch.setattr(sweep, "make_figures", listed)


def reference_rerun_class(name: str) -> type:
    """A test class of its own for one committed reference report's fresh run (a minute or two each): pytest-xdist
    (``--dist loadscope``) sends each class to whichever process is free, so the reruns spread over both processes
    while this file's other tests keep their module fixtures on one."""

    @pytest.mark.slow
    class TestReferenceRerun:
        def test_committed_reference_report_has_the_numbers_a_fresh_run_gives(self, tmp_path, request, undrawn):
            check_committed_reference_report(name, tmp_path, request)

    TestReferenceRerun.__name__ = TestReferenceRerun.__qualname__ = "TestReferenceRerun_" + re.sub(r"\W", "_", name)
    return TestReferenceRerun


def check_committed_reference_report(name: str, tmp_path, request) -> None:
    reference, overrides = REFERENCES[name]
    if not (reference / "alpha_table.csv").is_file():
        pytest.skip(f"no committed reference report {reference}")
    overrides = list(overrides)  # with the inputs: the findings, the left/right table and the faces need them
    if name != "paper":
        overrides.append(f"paths.data_root={request.getfixturevalue('shared_data')}")
    fresh_config = compose("paper", overrides)
    # Every setting of the committed run is the one these overrides give (where the data lie aside; a setting
    # retired since the committed run, which drew nothing, is not asked of the fresh one).
    committed = yaml.safe_load((reference / "run_config.yaml").read_text())
    fresh_flat = flatten(yaml.safe_load(_resolved(fresh_config)))
    for key, value in flatten(committed).items():
        if not key.startswith("paths.") and not key.endswith("data_root") and key not in RETIRED_SETTINGS:
            assert fresh_flat.get(key) == value, key
    record = tmp_path / "run"
    run(fresh_config, record)
    assert main([str(record), "--out", str(tmp_path / "reports" / name)]) == 0
    shutil.rmtree(record)  # the saved inputs are hundreds of megabytes; the test tree is kept after the session
    fresh = tmp_path / "reports" / name
    expected, got = pd.read_csv(reference / "alpha_table.csv"), pd.read_csv(fresh / "alpha_table.csv")
    assert_same_alpha_table(got, expected)
    committed_readme, fresh_readme = (reference / "README.md").read_text(), (fresh / "README.md").read_text()
    for heading in ("## Alpha beside the paper", "## Run facts", "## Left and right"):
        assert table_after(heading, fresh_readme) == table_after(heading, committed_readme), heading
    if name != "paper":  # the data the committed report was made from are the data here (checksums)
        marker = "The data the run read"
        assert table_after(marker, fresh_readme) == table_after(marker, committed_readme)
    # the findings come from the record (and the saved inputs: the left/right finding): the same text
    assert section_text("## Findings", fresh_readme) == section_text("## Findings", committed_readme)
    deficient = set(expected.loc[rank_deficient_by_construction(expected), KEY_COLUMNS].itertuples(index=False))
    for heading in (
        "## Full alpha table",
        "## Paired comparisons within the run",
        "## Error in millimetres and the weights",
    ):
        assert_same_markdown_table(
            table_after(heading, fresh_readme), table_after(heading, committed_readme), deficient
        )
    # the animation shows the same stretch of the same take
    assert section_text("## Faces you can turn", fresh_readme) == section_text(
        "## Faces you can turn", committed_readme
    )
    assert_reference_is_small_and_clean(reference, committed_readme)


for _name in REFERENCES:
    _class = reference_rerun_class(_name)
    globals()[_class.__name__] = _class


def test_the_synthetic_reference_report_is_the_papers_size_and_otherwise_the_run_checked_in_its_place():
    for name, settings in PAPER_SIZE.items():
        report, reduced = REPO_ROOT / "reports" / name, REFERENCES[name][0]
        if not (report / "run_config.yaml").is_file():
            pytest.skip(f"no committed reference report {report}")
        full = flatten(yaml.safe_load((report / "run_config.yaml").read_text()))
        small = flatten(yaml.safe_load((reduced / "run_config.yaml").read_text()))
        assert {key: full[key] for key in settings} == settings, name
        differ = {key for key in full.keys() | small.keys() if full.get(key) != small.get(key)}
        assert {key for key in differ if not key.startswith("paths.")} == {"dataset.n_frames"}, differ


KEY_COLUMNS = ["data", "basis", "projection", "solver"]
WEIGHT_COLUMNS = ["w_max_abs", "w_outside_01", "w_sparsity", "w_roughness"]


def rank_deficient_by_construction(table: pd.DataFrame) -> pd.Series:
    """Rows of a basis with fewer independent shapes than shapes, by construction: the n affine quasi-eigen faces
    lie in mu + span(eigenfaces), of rank at most m + 1, the linear ones in the span, of rank at most m."""
    affine, linear = table["basis"] == "QE", table["basis"] == "QE-linear"
    return (affine & (table["m"] + 1 < table["n"])) | (linear & (table["m"] < table["n"]))


def assert_same_alpha_table(got: pd.DataFrame, expected: pd.DataFrame) -> None:
    """A fresh alpha table equals the committed one to 1e-9, save the weight statistics of a rank-deficient basis.

    Those weights are one choice among many of the same error (nnls, box) or the minimum-norm solution of a system
    whose condition is unbounded (lstsq), and round-off makes the choice: another count of BLAS threads than the
    committed run's moves it (measured here with one OpenBLAS thread against the committed two: w_max_abs 5.7e-6 and
    w_sparsity 6.5e-9 apart, relatively, every alpha equal to 1e-9). They are compared to 1e-3, and the share of
    frames with a weight outside [0, 1] to a few frames. The three reruns pass so with one thread, and with
    OpenBLAS's Haswell kernel in place of the committed SkylakeX."""
    deficient = rank_deficient_by_construction(expected)
    pd.testing.assert_frame_equal(
        got.drop(columns=WEIGHT_COLUMNS), expected.drop(columns=WEIGHT_COLUMNS), rtol=1e-9, atol=1e-12
    )
    pd.testing.assert_frame_equal(
        got.loc[~deficient, WEIGHT_COLUMNS], expected.loc[~deficient, WEIGHT_COLUMNS], rtol=1e-9, atol=1e-12
    )
    pd.testing.assert_frame_equal(
        got.loc[deficient, WEIGHT_COLUMNS], expected.loc[deficient, WEIGHT_COLUMNS], rtol=1e-3, atol=1e-3
    )


def assert_same_markdown_table(fresh: str, committed: str, deficient: set = frozenset()) -> None:
    """Two Markdown tables of a report equal cell by cell, save two kinds of number that round-off makes. A paired
    comparison whose verdict holds by construction compares a difference that is zero but for round-off (it prints
    as 1e-18 or so, or as exactly 0): its numbers, the batch length chosen from that noise's correlation included,
    are round-off's, and only its text is compared. The weight statistics of the rows in ``deficient`` (keys of
    :data:`KEY_COLUMNS`; :func:`assert_same_alpha_table` says why) may differ in their last printed digit (three
    significant digits: 1.1 % apart at most)."""
    rows = [[cell.strip() for cell in line.strip("|").split("|")] for line in fresh.splitlines()]
    theirs = [[cell.strip() for cell in line.strip("|").split("|")] for line in committed.splitlines()]
    assert len(rows) == len(theirs) and rows[0] == theirs[0], (fresh, committed)
    header = rows[0]
    keyed = all(column in header for column in KEY_COLUMNS)
    loose = {header.index(column) for column in WEIGHT_COLUMNS if column in header}
    for ours, committed_row in zip(rows, theirs):
        assert len(ours) == len(committed_row), (ours, committed_row)
        weights = keyed and tuple(ours[header.index(column)] for column in KEY_COLUMNS) in deficient
        identity = "by construction" in committed_row[-1]
        for index, (cell, committed_cell) in enumerate(zip(ours, committed_row)):
            if cell == committed_cell:
                continue
            if identity:  # numbers of round-off (or '-' where the difference is exactly 0): only the text is compared
                assert is_number_or_dash(cell) and is_number_or_dash(committed_cell), (header[index], ours)
            else:
                close = pytest.approx(number(committed_cell), rel=0.011 if weights and index in loose else 0)
                assert number(cell) == close, (header[index], ours, committed_row)


def number(cell: str) -> float:
    """A table cell as a number (the message names the cell when it is none)."""
    try:
        return float(cell)
    except ValueError:
        raise AssertionError(f"cells differ and {cell!r} is no number") from None


def is_number_or_dash(cell: str) -> bool:
    """Whether a table cell is a number, or '-' (a value the report leaves out)."""
    if cell == "-":
        return True
    try:
        float(cell)
    except ValueError:
        return False
    return True


def section_text(heading: str, text: str) -> str:
    """The text of a Markdown section, up to the next heading of its level."""
    start = text.index(heading)
    return text[start : text.index("\n## ", start + 1)]


def assert_reference_is_small_and_clean(reference, readme: str) -> None:
    """A committed report: files small enough for git, made from a clean commit, no path of the machine."""
    for path in reference.rglob("*"):
        if path.is_file():
            assert path.stat().st_size < 1_500_000, path
    assert "uncommitted changes: True" not in readme
    assert "/work/" not in readme and "/home/" not in readme


# bytes, every file under reports/: half of the 13 MB that reports/ held before its figures were made smaller (PNG
# renders, plotly.js beside them, figure 1 in every report), with the held-out protocols, paired comparisons and the
# figures of the weights and errors added since; then 7.40 MB once the three paper reports gained the paper's regime
# m = n as a data variant of its own beside each coverage-rule variant (its lines in every plot and table); then
# 9.0 MB once every held-out protocol got its m = n variant and the paper and ICT runs blocked k-fold beside the tail
# (AnimFace: k-fold and leave-one-take-out in place of its last take): 8.80 MB measured at that rebuild; then 12.5 MB
# once the three paper reports gained the "Pose the rigs" panel (its rigs and weights, 0.69-1.04 MB a report, and one
# shared three.js of 0.64 MB with its licence): 12.19 MB measured at that rebuild; then 14.0 MB once the panel drew
# QE at m = n beside QE at the coverage rule and H (a third rig, 0.37-0.41 MB more a report) and the reports carried
# their stored claims, the synthetic one at the paper's 35,000 frames: 13.46 MB measured at that rebuild.
REPORTS_BUDGET = 14_000_000


def test_committed_reports_are_small_share_figure_1_and_hold_what_their_pages_show():
    root = REPO_ROOT / "reports"
    files = [path for path in root.rglob("*") if path.is_file()]
    if not any(path.name == "alpha_table.csv" for path in files):
        pytest.skip("no committed reference reports")
    total = sum(path.stat().st_size for path in files)
    assert total <= REPORTS_BUDGET, f"reports/ holds {total / 1e6:.2f} MB, over {REPORTS_BUDGET / 1e6} MB"
    for readme in [*root.glob("*/README.md"), *REFERENCE_RUNS.glob("*/README.md")]:  # made from clean commits
        assert "uncommitted changes: True" not in readme.read_text(), readme
    assert not (root / "vendor").exists()
    assert [path.relative_to(root).as_posix() for path in files if path.stem == "fig1_analogy"] == [
        "shared/fig1_analogy.svg"
    ]  # figure 1 once
    for page in root.glob("*/index.html"):
        for target in re.findall(r'(?:src|href)="([^"#]+)"', page.read_text()):
            assert "://" not in target, (page, target)
            where = (page.parent / target).resolve()
            assert where.is_file(), (page, target)
            # inside the report folder; figure 1 and three.js (the rig panel) from the one shared copy
            shared = (root / "shared" / "fig1_analogy.svg", root / "shared" / "three.min.js")
            assert where.is_relative_to(page.parent) or where in shared, (page, target)


def _markdown_rows(section: str) -> list[dict]:
    """The rows of the first Markdown table of a section, as column -> cell."""
    lines = [line for line in section.splitlines() if line.startswith("|")]
    header = [cell.strip() for cell in lines[0].strip("|").split("|")]
    return [dict(zip(header, (cell.strip() for cell in line.strip("|").split("|")))) for line in lines[2:]]


def test_committed_reports_open_with_both_claims_and_test_no_identity():
    root = REPO_ROOT / "reports"
    readmes = {page.parent.name: page.read_text() for page in root.glob("*/README.md") if page.parent.name != "shared"}
    if not readmes:
        pytest.skip("no committed reference reports")
    for name, readme in readmes.items():
        summary = section_text("## Summary", readme).split("\n### ")[0]
        assert "QE nearly as accurate as PCA" in summary, name
        # each claim has its verdict, or the summary says it was not tested at m = n (the bases study's m = 8-10)
        assert (
            "QE better than H: " in summary
            or "QE better than H and QE nearly as accurate as PCA not tested at m = n" in summary
            or "(QE better than H; QE nearly as accurate as PCA): not tested at m = n" in summary
        ), name
        words = SWEEP_SUMMARY_WORDS if name == "bases" else RUN_SUMMARY_WORDS
        assert len(summary.split()) - 2 <= words, name  # the heading's two words aside
        tables = [heading for heading in re.findall(r"^## (.*)$", readme, re.M) if "comparisons" in heading.lower()]
        assert len(tables) == 1, (name, tables)  # one comparison table, one Holm family
        rows = _markdown_rows(section_text(f"## {tables[0]}", readme + "\n## end"))
        p_columns = [column for column in rows[0] if column.startswith("p")]
        for row in rows:
            if "by construction" in " ".join(row.values()) or row.get("verdict", "").startswith("a = b"):
                assert all(row[column] in ("-", "") for column in p_columns), (name, row)


# The committed report of the bases study and the runs it was built from (five takes, seeds 0 to 4, each with its
# own start of ICA and NMF; the last 20 % of every take held out beside the training frames).
BASES_REFERENCE = ["dataset.n_frames=4000", "dataset.held_out=tail"]


@pytest.mark.slow
class TestBasesReferenceRerun:  # a class: a scope of its own for pytest-xdist, as the reruns above
    def test_committed_bases_report_has_the_numbers_a_fresh_sweep_gives(self, tmp_path, undrawn):
        check_committed_bases_report(tmp_path)


def check_committed_bases_report(tmp_path) -> None:
    reference = REPO_ROOT / "reports" / "bases"
    if not (reference / "summary.csv").is_file():
        pytest.skip(f"no committed reference report {reference}")
    sweep = tmp_path / "sweep"
    for seed in range(5):
        run(compose("bases", [*BASES_REFERENCE, f"dataset.seed={seed}"]), sweep / str(seed))
    assert main([str(sweep), "--out", str(tmp_path / "report")]) == 0
    # the run folders' names and the timings differ between sweeps, the numbers do not
    numeric = lambda frame: frame.select_dtypes("number").drop(  # noqa: E731
        columns=[c for c in frame.columns if c.startswith("time")], errors="ignore"
    )
    expected, got = pd.read_csv(reference / "summary.csv"), pd.read_csv(tmp_path / "report" / "summary.csv")
    pd.testing.assert_frame_equal(numeric(got), numeric(expected), rtol=1e-9, atol=1e-12)
    committed_readme = (reference / "README.md").read_text()
    fresh_readme = (tmp_path / "report" / "README.md").read_text()
    heading = "## Other bases: alpha against intuitiveness"
    assert table_after(heading, fresh_readme) == table_after(heading, committed_readme)
    assert_reference_is_small_and_clean(reference, committed_readme)


def _resolved(config) -> str:
    from omegaconf import OmegaConf

    from workbench.settings.config import resolved_without_hydra

    return OmegaConf.to_yaml(OmegaConf.create(resolved_without_hydra(config)))


@pytest.fixture(scope="module")
def animface_run(shared_data, tmp_path_factory):
    """AnimFace at every 20th frame (60 Hz takes), least squares, inputs saved, and its report."""
    record_dir = tmp_path_factory.mktemp("animface") / "run"
    run(
        compose(
            "paper",
            [
                "dataset=animface",
                f"paths.data_root={shared_data}",
                "dataset.frame_step=20",
                "solver=lstsq",
                "save_inputs=true",
            ],
        ),
        record_dir,
    )
    out = record_dir.parent / "report"
    assert main([str(record_dir), "--out", str(out)]) == 0
    return record_dir, out


@pytest.mark.slow
def test_animface_report_times_and_figure_4_frame(animface_run, shared_data):
    """On AnimFace (60 Hz, every 20th frame): the per-frame times are the file's frame numbers over its rate, the
    takes are named, figure 3 shows one frame per region of the face, the brows' from the eyebrows take, and figure
    4 the most displaced of them; the report names the data files with their checksums."""
    from workbench.core.files import sha256_of_file as file_sha256
    from workbench.dataset.capture import Timeline
    from workbench.formats.c3d import read_c3d_markers
    from workbench.reporting.report.data import (
        figure3_frames,
        marker_variant,
        mesh_variant,
        most_displaced,
        record_timeline,
    )
    from workbench.reporting.report.run_figures import figure4_frame

    record_dir, out = animface_run
    record, cache = load_record(record_dir), {}
    rate = read_c3d_markers(shared_data / "animface/animface_cheeks.c3d").frame_rate
    assert rate == 60.0 and record.metrics["dataset"]["frame_rate"] == rate / 20
    with np.load(record_dir / "alpha_per_frame.npz") as arrays:
        timeline = Timeline.from_arrays(arrays, "markers.")
    cheeks = timeline.take == "animface_cheeks"
    np.testing.assert_array_equal(timeline.frame[cheeks], np.arange(0, 1499, 20))
    np.testing.assert_allclose(timeline.seconds[cheeks], np.arange(0, 1499, 20) / rate)
    mesh_data, mesh_inputs = mesh_variant(record, cache)
    marker_data, marker_inputs = marker_variant(record, cache)
    mesh_timeline, marker_timeline = record_timeline(record, mesh_inputs), record_timeline(record, marker_inputs)
    chosen = figure3_frames(record, mesh_inputs)
    assert [region for region, _ in chosen] == ["brows", "mouth", "jaw"]
    assert mesh_timeline.take[chosen[0][1]] == "animface_eyebrows"
    frame, why = figure4_frame(record, marker_inputs, cache)
    assert why == "the most displaced of figure 3's frames"
    assert marker_timeline.label(frame) == mesh_timeline.label(most_displaced(mesh_inputs, [f for _, f in chosen]))
    assert re.fullmatch(r"animface_\w+ frame \d+ \(t = \d+\.\d\d s\)", marker_timeline.label(frame))
    # the report states the rates as they are, and the data it read with their checksums
    readme = (out / "README.md").read_text()
    assert "3 frames per second in the frames used (the file's 60 Hz, every 20 frame)" in readme
    assert str(shared_data) not in readme
    for name in ("animface/animface_jaw.c3d", "animface/animface_eyebrows.c3d"):
        assert f"| {name} " in readme and file_sha256(shared_data / name) in readme
    assert re.search(r"\| ict-facekit/FaceXModel +\| folder of 60 files", readme)
    assert re.search(r"\| conf/correspondence/animface_ict.csv +\| file ", readme)


def face_panels(figure) -> list[np.ndarray]:
    """The rendered faces shown in a figure's panels (a draw's (figure, caption) pair or a figure)."""
    figure = figure[0] if isinstance(figure, tuple) else figure
    return [np.asarray(ax.images[0].get_array()) for ax in figure.axes if ax.images]


def holes(image: np.ndarray, smallest_face: int = 20_000, smallest_hole: int = 6, lossy: bool = False) -> int:
    """Background pixels enclosed by a rendered face (a connected drawn region of at least ``smallest_face``
    pixels, so the letters of labels do not count): a hole through it (openings are capped dark). Enclosed specks
    under ``smallest_hole`` pixels are left out: a lossy codec (the animation) leaves one or two light pixels at an
    edge, while a missing triangle of the face is several pixels across. ``lossy``: also leave out enclosed
    background narrower than 3 pixels, where the codec's smear closed a notch of the silhouette (between ear and
    cheek) into a ring."""
    from scipy import ndimage

    drawn = np.any(image < 250, axis=2)
    regions, count = ndimage.label(drawn)
    sizes = ndimage.sum(drawn, regions, index=np.arange(1, count + 1))
    faces = np.isin(regions, 1 + np.flatnonzero(sizes >= smallest_face))
    background = ndimage.binary_fill_holes(faces) & ~drawn
    if lossy:
        background = ndimage.binary_opening(background, structure=np.ones((3, 3), bool))
    enclosed, count = ndimage.label(background)
    sizes = ndimage.sum(enclosed > 0, enclosed, index=np.arange(1, count + 1))
    return int(sizes[sizes >= smallest_hole].sum())


def test_the_hole_count_sees_a_missing_patch_and_not_a_capped_opening():
    rows, cols = np.mgrid[:300, :300]
    disc = lambda y, x, r: (rows - y) ** 2 + (cols - x) ** 2 < r**2  # noqa: E731
    image = np.full((300, 300, 3), 255, np.uint8)
    image[disc(150, 150, 120)] = 180  # a shaded face
    image[140:150, 20:60] = 0  # a label beside it: too small to count as a face
    assert holes(image) == 0
    image[disc(120, 110, 10)] = 30  # an eye opening, capped dark
    assert holes(image) == 0
    image[disc(190, 180, 6)] = 255  # a patch of the face not drawn: the background shows through
    assert holes(image) == disc(190, 180, 6).sum()
    image[200, 100] = 255  # one light pixel at an edge (a lossy codec's speck) is no hole
    assert holes(image) == disc(190, 180, 6).sum()
    image[100:110, 60:62] = 255  # a sliver two pixels wide: a hole, unless a lossy codec may have made it
    assert holes(image) == disc(190, 180, 6).sum() + 20
    assert holes(image, lossy=True) == disc(190, 180, 6).sum()


# The reference reports' renders of faces: every figure of rendered faces and the animation.
FACE_RENDERS = ("fig2_hand_vs_quasi_eigen.webp", "fig3_reconstructions.webp", "vertex_rms.webp", "animation.webp")


@pytest.mark.parametrize("name", FACE_RENDERS)
def test_committed_animface_renders_have_no_holes(name):
    """The committed AnimFace report as a reader sees it: no face in its images lets the background through (the
    eye and mouth openings are capped dark; regions without data are plain shaded, not cut out). Every frame of
    the animation is checked."""
    path = REPO_ROOT / "reports" / "paper-animface" / "figures" / name
    if not path.is_file():
        pytest.skip(f"no committed reference report {path.parent.parent}")
    image = Image.open(path)
    for k in range(getattr(image, "n_frames", 1)):
        image.seek(k)
        assert holes(np.asarray(image.convert("RGB")), lossy=name == "animation.webp") == 0, (name, k)


@pytest.mark.slow
def test_animface_faces_have_no_holes_and_no_masked_vertices(animface_run):
    """Every face render of the AnimFace report (figures 2 and 3, the per-vertex error, the animation's panels) is
    whole, eye and mouth openings closed; where the capture has no data (beyond the markers' reach) a coloured map
    shows the plain shaded geometry, not a mask: the same pixels as a plain render of the same face."""
    from workbench.reporting.figures.render import MeshView, render_meshes, support_weight
    from workbench.reporting.report.run_figures import draw_hand_vs_quasi_eigen, draw_reconstructions, draw_vertex_rms

    record_dir, out = animface_run
    record, cache = load_record(record_dir), {}
    inputs = record.load_inputs("mesh")
    support = inputs["point_support"]
    assert 0.1 < (~support).mean() < 0.6  # this capture has regions without data
    panels = [
        image
        for draw in (draw_hand_vs_quasi_eigen, draw_reconstructions, draw_vertex_rms)
        for image in face_panels(draw(record, cache=cache))
    ]
    animation = Image.open(out / "figures" / "animation.webp")
    panels.append(np.asarray(animation.convert("RGB")))
    assert len(panels) == 16 + 15 + 4 + 1
    for k, image in enumerate(panels):
        assert holes(image) == 0, k
    # a map over every vertex, on the report's own support: plain exactly where the capture has no data
    neutral, faces = inputs["neutral"], inputs["faces"]
    weight = support_weight(neutral, support)
    plain = render_meshes([neutral], faces, None, MeshView())[0]
    mapped = render_meshes([neutral], faces, [np.ones(len(support))], MeshView(cmap="Reds", clim=(0.0, 1.0)), weight)[0]
    face = np.any(plain < 250, axis=2)
    np.testing.assert_array_equal(np.any(mapped < 250, axis=2), face)  # the same silhouette: nothing cut away
    same = np.all(np.abs(mapped.astype(int) - plain.astype(int)) <= 2, axis=2) & face
    assert 0.05 < same.sum() / face.sum() < 0.7  # the regions without data: plain geometry
    assert holes(plain) == 0 and holes(mapped) == 0
    # the 3-D view keeps every triangle of its mesh (the decimated face), and fades colour where there are no data
    import base64
    import zlib

    from workbench.dataset.decimate import decimate
    from workbench.reporting.report.faces import VIEW_VERTICES

    text = (out / "figures" / "view3d.js").read_text()
    payload = json.loads(text[text.index("{") : text.rindex("}") + 1])
    points = neutral.reshape(-1, 3)
    mesh = decimate(points, faces, VIEW_VERTICES / len(points))
    shown = np.frombuffer(zlib.decompress(base64.b64decode(payload["faces"])), "<u2").reshape(-1, 3)
    np.testing.assert_array_equal(shown, mesh.faces)
    weight = np.frombuffer(zlib.decompress(base64.b64decode(payload["weight"])), np.uint8)
    assert weight.size == mesh.kept.size and (weight == 0).any() and (weight == 255).any()


@pytest.mark.process
def test_rebuilding_reports_does_not_mark_the_code_as_changed(tmp_path):
    """A reference report rewritten under reports/ is output, not code: the commit stays clean for the next run."""
    from workbench.record.record import git_state

    def git(*args):
        subprocess.run(["git", "-C", str(tmp_path), *args], check=True, capture_output=True)

    git("init", "-q")
    (tmp_path / "reports").mkdir()
    (tmp_path / "code.py").write_text("x = 1\n")
    (tmp_path / "reports" / "README.md").write_text("old\n")
    git("add", "-A")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "one")
    (tmp_path / "reports" / "README.md").write_text("rebuilt\n")
    assert git_state(tmp_path)["dirty"] is False
    (tmp_path / "code.py").write_text("x = 2\n")
    assert git_state(tmp_path)["dirty"] is True


def test_the_animation_shows_the_stretch_of_one_take_where_the_face_moves_most():
    from workbench.dataset.capture import Timeline
    from workbench.reporting.report.data import moving_stretch

    timeline = Timeline.concatenate(
        [Timeline.uniform("a", np.arange(10), 10.0), Timeline.uniform("b", np.arange(6), 10.0)]
    )
    frames = np.zeros((16, 3))
    frames[12:15, 0] = [5.0, -5.0, 5.0]  # take b moves; the jump from take a's end to b's start is no motion
    frames[9, 0] = 20.0
    np.testing.assert_array_equal(moving_stretch({"eval": frames}, timeline, 4), [11, 12, 13, 14])
    # longer than every take: the longest take whole
    np.testing.assert_array_equal(moving_stretch({"eval": frames}, timeline, 20), np.arange(10))
