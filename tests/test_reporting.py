"""``workbench report``: reports of a run and of a sweep, rebuilt from records only, and the committed reference."""

import json
import math
import re
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import yaml
from PIL import Image
from scipy import stats

from workbench.cli import COMMANDS, run
from workbench.config import REPO_ROOT, compose
from workbench.errors import WorkbenchError
from workbench.record import find_records, load_record
from workbench.reporting.pages import (RUN_FIGURES, figure_solver, frame_alpha, headline_table, main,
                                       quasi_eigen_shapes, reconstruct_frames)
from workbench.reporting.runs import flatten, summarise, varying_keys, wide
from workbench.tables import markdown_frame

# A small run on both data variants: 5 s of performance on a coarse mesh (1,050 vertices), inputs saved.
TINY = ["dataset.train_on=[markers,mesh]", "dataset.n_frames=600", "dataset.mesh_rows=35", "dataset.mesh_cols=30",
        "save_inputs=true"]
# The committed reference reports and the overrides of the runs they were built from. All are reduced in size so
# that this test can redo each run in about half a minute: the synthetic actor at 4,000 frames instead of the
# paper's 35,000 (its mesh variant at paper scale is 3.5 GB of frames), the real takes at every 4th frame.
REFERENCES = {
    "paper": ["dataset.train_on=[markers,mesh]", "dataset.n_frames=4000", "dataset.held_out=tail", "save_inputs=true"],
    "paper-ict_livelink": ["dataset=ict_livelink", "dataset.frame_step=4", "dataset.held_out=tail",
                           "save_inputs=true"],
    "paper-animface": ["dataset=animface", "dataset.frame_step=4", "dataset.held_out=[tail,take]", "save_inputs=true"],
}
FIGURE_STEMS = [spec[0] for spec in RUN_FIGURES]


@pytest.fixture(scope="module")
def tiny_report(tmp_path_factory):
    record = tmp_path_factory.mktemp("run")
    run(compose("paper", TINY), record)
    out = tmp_path_factory.mktemp("reports")
    assert main([str(record), "--out", str(out / "paper")]) == 0
    return record, out / "paper"


def test_run_writes_per_frame_alpha_that_matches_the_table(tiny_report):
    record, _ = tiny_report
    table = pd.read_csv(record / "alpha_table.csv")
    with np.load(record / "alpha_per_frame.npz") as arrays:
        for data in ("markers", "mesh"):
            part = table[table["data"] == data]
            assert list(arrays[f"{data}.basis"]) == list(part["basis"])
            assert list(arrays[f"{data}.solver"]) == list(part["solver"])
            np.testing.assert_allclose(np.nanmean(arrays[f"{data}.absolute"], axis=1), part["alpha_abs_mean"],
                                       rtol=1e-12)
            np.testing.assert_allclose(np.nanmean(arrays[f"{data}.displacement"], axis=1),
                                       part["alpha_disp_mean"], rtol=1e-12)
            np.testing.assert_allclose(np.median(arrays[f"{data}.error_mm"], axis=1), part["err_mm_median"],
                                       rtol=1e-12)
    # read back, PCA's empty weight cells are NaN in numeric columns
    read = load_record(record).table
    assert read["w_max_abs"].dtype == float and read.loc[read["basis"] == "PCA", "w_max_abs"].isna().all()


def test_recorded_comparisons_are_those_of_the_recorded_per_frame_alpha(tiny_report):
    """Every paired comparison in metrics.json is the block bootstrap of the per-frame alpha the record keeps."""
    from workbench.reporting.statistics import paired_mean_difference

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


def test_every_figure_exists_and_is_non_trivial(tiny_report):
    _, report = tiny_report
    for stem in FIGURE_STEMS:
        png, svg = report / "figures" / f"{stem}.png", report / "figures" / f"{stem}.svg"
        assert png.is_file(), stem
        assert 15_000 < png.stat().st_size < 1_000_000, (stem, png.stat().st_size)
        if stem.startswith(("fig2", "fig3", "vertex_rms")):  # rendered faces: PNG only, at print resolution
            assert not svg.is_file() and Image.open(png).info["dpi"][0] > 130, stem
            continue
        assert svg.is_file(), stem
        image = Image.open(png)
        assert image.size[0] >= 500 and image.size[1] >= 350, (stem, image.size)
        pixels = np.asarray(image.convert("RGB"))
        assert np.any(pixels < 250, axis=2).mean() > 0.05, stem  # not an empty canvas
        assert "<svg" in svg.read_text()[:2000]


def test_report_documents_hold_tables_figures_provenance_choices_and_versions(tiny_report):
    record, report = tiny_report
    page = (report / "index.html").read_text()
    readme = (report / "README.md").read_text()
    for stem in FIGURE_STEMS:
        assert f'src="figures/{stem}.png"' in page and f"](figures/{stem}.png)" in readme
    for document in (page, readme):
        for heading in ("Alpha beside the paper", "Full alpha table", "Choices the run made",
                        "Dataset provenance and licence", "Versions and commit", "Findings", "Run facts",
                        "Faces you can turn", "Error in millimetres and the weights",
                        "Paired comparisons within the run"):
            assert heading in document
        assert "synthetic" in document and "not applicable: generated by the workbench" in document
        assert json.loads((record / "metrics.json").read_text())["git"]["commit"] in document
    assert "affine, linear" in readme and "lstsq (lstsq), nnls (nnls, bounds [0.0, None])" in readme
    # The README's full table is the very text the run printed.
    printed = (record / "alpha_table.md").read_text()
    assert table_after("## Full alpha table", readme) == table_after("| data", printed)
    pd.testing.assert_frame_equal(pd.read_csv(report / "alpha_table.csv"), pd.read_csv(record / "alpha_table.csv"))
    assert yaml.safe_load((report / "run_config.yaml").read_text()) == load_record(record).config


def browser_page(chromium: str, page, *args: str) -> str:
    """Load a page in headless Chromium (software WebGL), let its scripts run, and return the DOM (or what the
    extra arguments ask for)."""
    done = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
                           "--virtual-time-budget=30000", *args, page.as_uri()], capture_output=True, text=True,
                          timeout=180)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def test_interactive_view_draws_the_face_in_a_browser_from_file(tiny_report, chromium):
    """The page opened from file:// with no server and no network: plotly.js and the mesh data load, the 3-D view
    renders, and the rendered scene is not blank (the page counts its non-background pixels)."""
    _, report = tiny_report
    page = (report / "index.html").read_text()
    assert 'src="../vendor/plotly-gl3d-3.7.0.min.js"' in page and 'src="figures/view3d.js"' in page
    assert "http://" not in page and "https://" not in page  # nothing fetched from the network
    assert (report.parent / "vendor" / "plotly-gl3d-3.7.0.min.js").is_file()
    dom = browser_page(chromium, report / "index.html", "--dump-dom")
    status = re.search(r'data-status="([^"]*)"', dom).group(1)
    assert status.startswith("drawn"), status
    drawn, total = map(int, re.findall(r"\d+", status))
    assert 0.05 < drawn / total < 0.95, status
    # the menus list figure 3's frames (take, file frame, time) and the bases
    assert "synthetic seed 0 frame" in dom and ">captured</option>" in dom and ">PCA</option>" in dom


def test_animation_and_report_text(tiny_report):
    _, report = tiny_report
    gif = Image.open(report / "figures" / "captured_h_qe.gif")
    assert gif.n_frames == 12 and gif.size[0] > 3 * 120
    readme = (report / "README.md").read_text()
    assert readme.index("## Findings") < readme.index("## Run facts") < readme.index("## Alpha beside the paper")
    assert "(paper 7.22)" in readme and "(paper: m = 18)" in readme
    assert "uncommitted changes" in readme and "frames per second in the frames used" in readme


def table_after(marker: str, text: str) -> str:
    """The first Markdown table at or after ``marker``."""
    lines = text[text.index(marker):].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("|"))
    end = next((i for i in range(start, len(lines)) if not lines[i].startswith("|")), len(lines))
    return "\n".join(lines[start:end])


def test_headline_table_puts_the_paper_beside_the_measured_values(tiny_report):
    record, _ = tiny_report
    table = load_record(record).table
    headline = headline_table(table, "alpha_abs_mean")
    assert list(headline.columns) == ["data", "basis", "paper_alpha", "alpha_abs_mean lstsq", "alpha_abs_mean nnls",
                                      "alpha_abs_mean box"]
    row = headline[(headline["data"] == "mesh") & (headline["basis"] == "QE")].iloc[0]
    assert row["paper_alpha"] == 0.72
    expected = table[(table["data"] == "mesh") & (table["basis"] == "QE") & (table["solver"] == "nnls")]
    assert row["alpha_abs_mean nnls"] == expected["alpha_abs_mean"].iloc[0]
    pca = headline[(headline["data"] == "mesh") & (headline["basis"] == "PCA")].iloc[0]
    assert pca["alpha_abs_mean lstsq"] == pca["alpha_abs_mean box"]  # PCA has no solver: the same in every column
    text = markdown_frame(headline)
    assert "|        0.72 |" in text and "| QE-linear |           - |" in text


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
        for label, shapes in (("H", inputs["hand"]), ("QE", quasi_eigen_shapes(inputs, "affine")),
                              ("QE-linear", quasi_eigen_shapes(inputs, "linear"))):
            alpha = frame_alpha(inputs["neutral"], captured, reconstruct_frames(shapes, captured, solver))
            row = [i for i, (b, s) in enumerate(zip(bases, solvers)) if b == label and s == "lstsq"][0]
            np.testing.assert_allclose(alpha["absolute"], per_frame[f"{data}.absolute"][row, frames], rtol=1e-9)
            np.testing.assert_allclose(alpha["displacement"], per_frame[f"{data}.displacement"][row, frames],
                                       rtol=1e-9)


def test_figures_that_need_inputs_are_listed_not_drawn_without_them(tmp_path):
    record = tmp_path / "run"
    run(compose("paper", ["dataset.n_frames=300", "solver=lstsq"]), record)
    assert main([str(record), "--out", str(tmp_path / "reports" / "paper"), "--formats", "png"]) == 0
    readme = (tmp_path / "reports" / "paper" / "README.md").read_text()
    assert "**Figure 2: hand shapes beside their quasi-eigen faces**: not drawn (needs a mesh data variant" in readme
    assert "**Alpha per frame over time**: not drawn" in readme
    figures = sorted(path.name for path in (tmp_path / "reports" / "paper" / "figures").iterdir())
    # what the record holds is drawn without inputs: the error distribution and the weights come from metrics.json
    assert figures == ["alpha_per_solver.png", "coverage_curve.png", "error_cdf.png", "fig1_analogy.png",
                       "intuitiveness.png", "weight_statistics.png"]


def make_sweep(root, coverages=(0.99, 0.999), seeds=(0, 1)):
    k = 0
    for coverage in coverages:
        for seed in seeds:
            run(compose("paper", ["dataset.n_frames=300", f"basis.coverage={coverage}", f"dataset.seed={seed}",
                                  "solver=lstsq"]), root / str(k))
            k += 1
    (root / "incomplete").mkdir()
    (root / "incomplete" / "config.yaml").write_text("study: paper\n")  # no 'done': a run still going or failed
    return root


def test_sweep_report_summarises_seeds_and_plots_every_swept_setting(tmp_path):
    root = make_sweep(tmp_path / "sweep")
    assert [path.name for path in find_records([root])[0]] == ["0", "1", "2", "3"]
    assert main([str(root), "--out", str(tmp_path / "reports" / "coverage")]) == 0
    report = tmp_path / "reports" / "coverage"
    summary = pd.read_csv(report / "summary.csv")
    assert set(summary["basis.coverage"]) == {0.99, 0.999} and (summary["n_seeds"] == 2).all()
    runs = pd.read_csv(report / "runs.csv", dtype={"run": str})
    assert sorted(runs["run"].unique()) == ["0", "1", "2", "3"]
    # The interval is the Student-t interval of the mean over the two seeds.
    values = runs[(runs["basis.coverage"] == 0.99) & (runs["basis"] == "QE")]["alpha_abs_mean"].to_numpy()
    row = summary[(summary["basis.coverage"] == 0.99) & (summary["basis"] == "QE")].iloc[0]
    half = stats.t.ppf(0.975, 1) * values.std(ddof=1) / math.sqrt(2)
    assert row["alpha_abs_mean"] == pytest.approx(values.mean())
    assert row["alpha_abs_mean_ci_high"] == pytest.approx(values.mean() + half)
    for stem in ("coverage_curve", "alpha_vs_basis_coverage", "alpha_vs_m"):
        assert (report / "figures" / f"{stem}.png").stat().st_size > 15_000, stem
    page = (report / "index.html").read_text()
    assert "sweep over basis.coverage" in page and "replicates over dataset.seed 0, 1" in page


def test_collect_and_report_give_the_same_numbers_for_one_sweep(tmp_path):
    from workbench.record import ALPHA_COLUMNS
    from workbench.reporting.collect import collect_and_write

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
        np.testing.assert_array_equal(both[column], both["mean"])
        np.testing.assert_array_equal(both[f"{column}_ci_low"], both["ci95_low"])
        np.testing.assert_array_equal(both[f"{column}_ci_high"], both["ci95_high"])


def test_summarise_runs_known_answer():
    per_run = pd.DataFrame({
        "study": "noise", "dataset.noise": [0.1, 0.1, 0.1, 0.2], "dataset.seed": [0, 1, 2, 0], "data": "markers",
        "train_on": "markers", "eval_on": "markers", "basis": "H", "projection": "-", "solver": "lstsq",
        "m": [10, 11, 12, 13], "n": 18, "alpha_abs_mean": [1.0, 2.0, 3.0, 5.0]})
    summary = wide(summarise(per_run, metrics=["alpha_abs_mean", "m"]))
    first, second = summary.iloc[0], summary.iloc[1]
    assert first["n_seeds"] == 3 and first["m"] == 11.0 and first["alpha_abs_mean"] == 2.0
    half = stats.t.ppf(0.975, 2) * 1.0 / math.sqrt(3)
    assert first["alpha_abs_mean_ci_low"] == pytest.approx(2.0 - half)
    assert second["n_seeds"] == 1 and math.isnan(second["alpha_abs_mean_ci_low"])


def test_varying_keys_leave_out_paths_and_identical_settings():
    configs = [{"study": "paper", "paths": {"output_root": "a"}, "basis": {"coverage": 0.99, "projections": ["affine"]},
                "dataset": {"seed": 0}},
               {"study": "paper", "paths": {"output_root": "b"}, "basis": {"coverage": 0.999, "projections": ["affine"]},
                "dataset": {"seed": 1}}]
    assert varying_keys(configs) == ["basis.coverage", "dataset.seed"]
    assert flatten(configs[0])["basis.projections"] == "[affine]"


def test_command_is_registered_and_reports_errors_in_one_line(tmp_path):
    assert COMMANDS["report"] == "workbench.reporting.pages:main"
    with pytest.raises(WorkbenchError, match="not a folder"):
        main([str(tmp_path / "missing")])
    with pytest.raises(WorkbenchError, match="no complete run record"):
        main([str(tmp_path)])
    done = subprocess.run([sys.executable, "-c", "from workbench.cli import main; main()", "report", str(tmp_path)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1].startswith("workbench report: error: ")


@pytest.mark.slow
@pytest.mark.parametrize("name", list(REFERENCES))
def test_committed_reference_report_has_the_numbers_a_fresh_run_gives(name, tmp_path, request):
    reference = REPO_ROOT / "reports" / name
    if not (reference / "alpha_table.csv").is_file():
        pytest.skip(f"no committed reference report {reference}")
    overrides = [o for o in REFERENCES[name] if not o.startswith("save_inputs")]  # inputs change no number
    if name != "paper":
        overrides.append(f"paths.data_root={request.getfixturevalue('shared_data')}")
    fresh_config = compose("paper", overrides)
    # Every setting of the committed run is the one these overrides give (where the data lie aside).
    committed = yaml.safe_load((reference / "run_config.yaml").read_text())
    fresh_flat = flatten(yaml.safe_load(_resolved(fresh_config)))
    for key, value in flatten(committed).items():
        if not key.startswith(("paths.", "save_inputs")) and not key.endswith("data_root"):
            assert fresh_flat.get(key) == value, key
    record = tmp_path / "run"
    run(fresh_config, record)
    assert main([str(record), "--out", str(tmp_path / "reports" / name), "--formats", "png"]) == 0
    fresh = tmp_path / "reports" / name
    expected, got = pd.read_csv(reference / "alpha_table.csv"), pd.read_csv(fresh / "alpha_table.csv")
    pd.testing.assert_frame_equal(got, expected, rtol=1e-9, atol=1e-12)
    committed_readme, fresh_readme = (reference / "README.md").read_text(), (fresh / "README.md").read_text()
    for heading in ("## Alpha beside the paper", "## Full alpha table", "## Run facts"):
        assert table_after(heading, fresh_readme) == table_after(heading, committed_readme), heading
    # the findings come from the record alone (no saved inputs needed): the same text
    assert section_text("## Findings", fresh_readme) == section_text("## Findings", committed_readme)
    for heading in ("## Paired comparisons within the run", "## Error in millimetres and the weights"):
        assert table_after(heading, fresh_readme) == table_after(heading, committed_readme), heading
    assert_reference_is_small_and_clean(reference, committed_readme)


def section_text(heading: str, text: str) -> str:
    """The text of a Markdown section, up to the next heading of its level."""
    start = text.index(heading)
    return text[start:text.index("\n## ", start + 1)]


def assert_reference_is_small_and_clean(reference, readme: str) -> None:
    """A committed report: files small enough for git, made from a clean commit, no path of the machine."""
    for path in reference.rglob("*"):
        if path.is_file():
            assert path.stat().st_size < 1_500_000, path
    assert "uncommitted changes: True" not in readme
    assert "/work/" not in readme and "/home/" not in readme


# The committed report of the bases study and the runs it was built from (the alternatives' seeds 0 and 1).
BASES_REFERENCE = ["dataset.n_frames=4000", "dataset.held_out=tail"]


def test_committed_bases_report_has_the_numbers_a_fresh_sweep_gives(tmp_path):
    reference = REPO_ROOT / "reports" / "bases"
    if not (reference / "summary.csv").is_file():
        pytest.skip(f"no committed reference report {reference}")
    sweep = tmp_path / "sweep"
    for seed in (0, 1):
        run(compose("bases", [*BASES_REFERENCE, f"basis.alternatives_seed={seed}"]), sweep / str(seed))
    assert main([str(sweep), "--out", str(tmp_path / "report"), "--formats", "png"]) == 0
    # the run folders' names and the timings differ between sweeps, the numbers do not
    numeric = lambda frame: frame.select_dtypes("number").drop(  # noqa: E731
        columns=[c for c in frame.columns if c.startswith("time")], errors="ignore")
    expected, got = pd.read_csv(reference / "summary.csv"), pd.read_csv(tmp_path / "report" / "summary.csv")
    pd.testing.assert_frame_equal(numeric(got), numeric(expected), rtol=1e-9, atol=1e-12)
    committed_readme = (reference / "README.md").read_text()
    fresh_readme = (tmp_path / "report" / "README.md").read_text()
    heading = "## Other bases: alpha against intuitiveness"
    assert table_after(heading, fresh_readme) == table_after(heading, committed_readme)
    assert_reference_is_small_and_clean(reference, committed_readme)


def _resolved(config) -> str:
    from omegaconf import OmegaConf

    from workbench.cli import resolved_without_hydra

    return OmegaConf.to_yaml(OmegaConf.create(resolved_without_hydra(config)))


def test_animface_report_times_and_figure_4_frame(shared_data, tmp_path):
    """On AnimFace (60 Hz, every 20th frame): the per-frame times are the file's frame numbers over its rate, the
    takes are named, and figure 4 shows figure 3's first frame."""
    from workbench.dataset.c3d_markers import read_c3d_markers
    from workbench.dataset.capture import Timeline
    from workbench.reporting.pages import (_marker_variant, _mesh_variant, figure3_frames, figure4_frame,
                                           record_timeline)

    record_dir = tmp_path / "run"
    run(compose("paper", ["dataset=animface", f"paths.data_root={shared_data}", "dataset.frame_step=20",
                          "solver=lstsq", "save_inputs=true"]), record_dir)
    record, cache = load_record(record_dir), {}
    rate = read_c3d_markers(shared_data / "animface/animface_cheeks.c3d").frame_rate
    assert rate == 60.0 and record.metrics["dataset"]["frame_rate"] == rate / 20
    with np.load(record_dir / "alpha_per_frame.npz") as arrays:
        timeline = Timeline.from_arrays(arrays, "markers.")
    cheeks = timeline.take == "animface_cheeks"
    np.testing.assert_array_equal(timeline.frame[cheeks], np.arange(0, 1499, 20))
    np.testing.assert_allclose(timeline.seconds[cheeks], np.arange(0, 1499, 20) / rate)
    mesh_data, mesh_inputs = _mesh_variant(record, cache)
    marker_data, marker_inputs = _marker_variant(record, cache)
    first = figure3_frames(mesh_inputs)[0]
    frame, why = figure4_frame(record, marker_inputs, cache)
    mesh_timeline, marker_timeline = record_timeline(record, mesh_inputs), record_timeline(record, marker_inputs)
    assert why == "figure 3's first frame"
    assert marker_timeline.label(frame) == mesh_timeline.label(first)
    assert re.fullmatch(r"animface_\w+ frame \d+ \(t = \d+\.\d\d s\)", mesh_timeline.label(first))
    # the report states the rates as they are
    out = tmp_path / "report"
    assert main([str(record_dir), "--out", str(out), "--formats", "png"]) == 0
    readme = (out / "README.md").read_text()
    assert "3 frames per second in the frames used (the file's 60 Hz, every 20 frame)" in readme
    assert str(shared_data) not in readme


def test_rebuilding_reports_does_not_mark_the_code_as_changed(tmp_path):
    """A reference report rewritten under reports/ is output, not code: the commit stays clean for the next run."""
    from workbench.record import git_state

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
