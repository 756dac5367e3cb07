"""workbench collect: records into tidy tables, confidence intervals by hand, exact table text."""

import math

import pandas as pd
import pytest
import yaml

from workbench import record

from workbench.reporting.collect import collect_and_write, format_estimate, main
from workbench.reporting.runs import collect_runs, natural_key, summarise, t_interval
from workbench.tables import latex_table, markdown_table
from workbench.errors import WorkbenchError

ALPHA = {  # (coverage, seed) -> alpha_abs_mean of H, QE, PCA
    (0.9, 0): (1.0, 0.5, 0.4), (0.9, 1): (2.0, 0.7, 0.5), (0.9, 2): (4.0, 0.9, 0.6),
    (0.99, 0): (1.5, 0.2, 0.1), (0.99, 1): (1.5, 0.3, 0.2), (0.99, 2): (1.5, 0.4, 0.3),
}
M = {0.9: (4, 5, 6), 0.99: (12, 12, 12)}


def write_record(folder, coverage, seed, job_num, complete=True):
    """A run record as the workbench writes it (through workbench.record), with chosen numbers (rows: H and QE
    with lstsq, then PCA)."""
    h, qe, pca = ALPHA[(coverage, seed)]
    m = M[coverage][seed]
    rows = [{"data": "markers", "basis": basis, "projection": projection, "solver": solver, "n": n, "m": m,
             "coverage": coverage + 0.001, "alpha_abs_mean": value, "alpha_abs_pooled": value * 1.1,
             "alpha_disp_mean": value * 50, "alpha_disp_pooled": value * 20, "rms_mm": value / 2,
             "paper_alpha": paper}
            for basis, projection, solver, n, value, paper in (
                ("H", "-", "lstsq", 18, h, 5.2), ("QE", "affine", "lstsq", 18, qe, 0.72),
                ("PCA", "-", "projection", m, pca, 0.62))]
    config = {"study": "coverage", "dataset": {"kind": "synthetic", "seed": seed}, "basis": {"coverage": coverage},
              "paths": {"output_root": f"/x{seed}"}}
    metrics = {"study": "coverage", "config_hash": f"hash{coverage}{seed}", "job_num": job_num,
               "overrides": [f"dataset.seed={seed}", f"basis.coverage={coverage}", "paths.output_root=/x"],
               "dataset": {"name": "test", "frame_rate": 120.0},
               "data": {"markers": {"n_points": 66, "n_train_frames": 100, "n_eval_frames": 100}},
               "rows": [dict(row, train_on="markers", eval_on="markers") for row in rows],
               "git": {"commit": "abc", "dirty": False}}
    record.write_record(folder, resolved_yaml=yaml.safe_dump(config), table=pd.DataFrame(rows), text="",
                        metrics=metrics, timings={"pca": 0.5, "total": 1.0 + seed})
    if not complete:
        (folder / record.DONE).unlink()


@pytest.fixture
def sweep(tmp_path):
    folder = tmp_path / "sweep"
    job = 0
    for seed in (0, 1, 2):
        for coverage in (0.9, 0.99):
            write_record(folder / f"basis.coverage={coverage},dataset.seed={seed}", coverage, seed, job)
            job += 1
    write_record(folder / "killed", 0.9, 0, job, complete=False)
    return folder


def test_t_interval_matches_a_hand_computation():
    # values 1, 2, 4: mean 7/3, sample variance ((4/3)^2 + (1/3)^2 + (5/3)^2) / 2 = 7/3, t_{0.975, 2} = 4.3027
    result = t_interval([1.0, 2.0, 4.0])
    std = math.sqrt(7 / 3)
    assert result["n"] == 3
    assert result["mean"] == pytest.approx(7 / 3, rel=1e-12)
    assert result["std"] == pytest.approx(std, rel=1e-12)
    assert result["ci95_half"] == pytest.approx(4.3027 * std / math.sqrt(3), rel=1e-4)
    assert result["ci95_half"] == pytest.approx(3.7946, abs=1e-4)
    assert result["ci95_low"] == pytest.approx(7 / 3 - result["ci95_half"])


def test_t_interval_of_identical_and_single_values():
    assert t_interval([1.5, 1.5, 1.5])["ci95_half"] == 0.0
    single = t_interval([2.0, float("nan")])
    assert single["n"] == 1 and single["mean"] == 2.0 and math.isnan(single["ci95_half"])


def test_runs_table_is_tidy_and_in_sweep_order(sweep):
    runs, incomplete = collect_runs([sweep])
    assert [path.name for path in incomplete] == ["killed"]
    assert len(runs) == 6 * 3
    assert list(runs["job_num"].drop_duplicates()) == [0, 1, 2, 3, 4, 5]
    assert "paths.output_root" not in runs.columns  # where records go is no condition
    first = runs.iloc[0]
    assert (first["basis.coverage"], first["dataset.seed"], first["basis"], first["n_points"]) == (0.9, 0, "H", 66)
    assert first["time_total"] == 1.0 and first["time_pca"] == 0.5


def test_summary_averages_over_seeds(sweep):
    runs, _ = collect_runs([sweep])
    summary = summarise(runs)
    assert "dataset.seed" not in summary.columns
    h = summary[(summary["basis"] == "H") & (summary["metric"] == "alpha_abs_mean")].set_index("basis.coverage")
    assert h.loc[0.9, "n"] == 3
    assert h.loc[0.9, "mean"] == pytest.approx(7 / 3)
    assert h.loc[0.9, "ci95_half"] == pytest.approx(4.3027 * math.sqrt(7 / 3) / math.sqrt(3), rel=1e-4)
    assert h.loc[0.99, "ci95_half"] == 0.0


def test_alpha_table_exact_text(sweep, tmp_path):
    written = collect_and_write([sweep], tmp_path / "out", where={"solver": "lstsq"})
    expected_markdown = (
        "alpha_abs_mean (%), solver = lstsq; mean ± half-width of the 95 % t-interval over dataset.seed "
        "(n = 3 per cell)\n"
        "\n"
        "| basis.coverage |         m |             H |            QE |           PCA |\n"
        "|----------------|----------:|--------------:|--------------:|--------------:|\n"
        "| 0.9            | 5.0 ± 2.5 | 2.333 ± 3.795 | 0.700 ± 0.497 | 0.500 ± 0.248 |\n"
        "| 0.99           |      12.0 | 1.500 ± 0.000 | 0.300 ± 0.248 | 0.200 ± 0.248 |\n")
    assert written["markdown"] == expected_markdown
    assert (tmp_path / "out" / "alpha_table.md").read_text() == expected_markdown
    expected_latex = (
        "% alpha_abs_mean (%), solver = lstsq; mean ± half-width of the 95 % t-interval over dataset.seed "
        "(n = 3 per cell)\n"
        "\\begin{tabular}{lrrrr}\n"
        "\\toprule\n"
        "basis.coverage & m & H & QE & PCA \\\\\n"
        "\\midrule\n"
        "0.9 & 5.0 $\\pm$ 2.5 & 2.333 $\\pm$ 3.795 & 0.700 $\\pm$ 0.497 & 0.500 $\\pm$ 0.248 \\\\\n"
        "0.99 & 12.0 & 1.500 $\\pm$ 0.000 & 0.300 $\\pm$ 0.248 & 0.200 $\\pm$ 0.248 \\\\\n"
        "\\bottomrule\n"
        "\\end{tabular}\n")
    assert (tmp_path / "out" / "alpha_table.tex").read_text() == expected_latex
    assert written["n_runs"] == 6 and written["n_incomplete"] == 1


def test_csv_and_parquet_hold_the_same_tables(sweep, tmp_path):
    collect_and_write([sweep], tmp_path / "out")
    for name in ("runs", "summary"):
        from_csv = pd.read_csv(tmp_path / "out" / f"{name}.csv")
        from_parquet = pd.read_parquet(tmp_path / "out" / f"{name}.parquet")
        assert list(from_csv.columns) == list(from_parquet.columns)
        pd.testing.assert_frame_equal(from_csv, from_parquet, check_dtype=False)


def test_metrics_as_columns_table(sweep, tmp_path):
    text = collect_and_write([sweep], tmp_path / "out", columns="metric", where={"basis.coverage": "0.99"},
                             extra=())["markdown"]
    assert text.splitlines()[0].startswith("alpha (%) by metric, basis.coverage = 0.99; ")
    assert text.splitlines()[2:] == [
        "| basis | alpha_abs_mean | alpha_abs_pooled | alpha_disp_mean | alpha_disp_pooled |",
        "|-------|---------------:|-----------------:|----------------:|------------------:|",
        "| H     |  1.500 ± 0.000 |    1.650 ± 0.000 |    75.00 ± 0.00 |      30.00 ± 0.00 |",
        "| QE    |  0.300 ± 0.248 |    0.330 ± 0.273 |   15.00 ± 12.42 |       6.00 ± 4.97 |",
        "| PCA   |  0.200 ± 0.248 |    0.220 ± 0.273 |   10.00 ± 12.42 |       4.00 ± 4.97 |"]


def test_cli_collect_writes_next_to_the_sweep(sweep, capsys):
    assert main([str(sweep), "--where", "solver=lstsq", "--metric", "alpha_disp_pooled"]) == 0
    out = capsys.readouterr().out
    assert "alpha_disp_pooled (%)" in out and "1 incomplete run folders left out" in out
    assert (sweep / "collected" / "runs.parquet").is_file()


def test_collect_errors_name_the_problem(sweep, tmp_path):
    with pytest.raises(WorkbenchError, match="no complete run record"):
        collect_and_write([tmp_path / "sweep" / "killed"], tmp_path / "out")
    with pytest.raises(WorkbenchError, match="--metric must be one of"):
        collect_and_write([sweep], tmp_path / "out", metric="alpha_nonsense")
    with pytest.raises(WorkbenchError, match="give --out"):
        main([str(sweep), str(sweep)])


def test_formatting_helpers():
    assert format_estimate(0.31949, 0.01234, "{:.3f}") == "0.319 ± 0.012"
    assert format_estimate(0.31949, float("nan"), "{:.3f}") == "0.319"
    assert sorted(["random12", "random3", "all"], key=natural_key) == ["all", "random3", "random12"]
    assert markdown_table(["k", "v"], [["a", "1.0"]], [False, True]) == "| k |   v |\n|---|----:|\n| a | 1.0 |\n"
    assert latex_table(["a_b", "v"], [["x%", "1 ± 2"]], [False, True]) == (
        "\\begin{tabular}{lr}\n\\toprule\na\\_b & v \\\\\n\\midrule\nx\\% & 1 $\\pm$ 2 \\\\\n"
        "\\bottomrule\n\\end{tabular}\n")
