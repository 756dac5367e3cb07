"""workbench collect: records into tidy tables, intervals and paired comparisons by hand, exact table text."""

import functools
import math

import pandas as pd
import pytest
import yaml

from workbench.core.errors import WorkbenchError
from workbench.record import record
from workbench.reporting.collect.command import main
from workbench.reporting.collect.sweep import collect_and_write, format_estimate, format_range
from workbench.reporting.tables.cells import latex_table, markdown_table
from workbench.reporting.tables.runs import collect_runs, level_statistics, natural_key, paired_comparisons, summarise
from workbench.settings.config import compose
from workbench.settings.schema import resolved_settings

ALPHA = {  # (coverage, seed) -> alpha_abs_mean of H, QE, PCA
    (0.9, 0): (1.0, 0.5, 0.4),
    (0.9, 1): (2.0, 0.7, 0.5),
    (0.9, 2): (4.0, 0.9, 0.6),
    (0.99, 0): (1.5, 0.2, 0.1),
    (0.99, 1): (1.5, 0.3, 0.2),
    (0.99, 2): (1.5, 0.4, 0.3),
}
M = {0.9: (4, 5, 6), 0.99: (12, 12, 12)}


def stored_claims(m, h_over_qe, qe_over_pca):
    """The claims a run at m stores: at m = n = 18 on its training frames, each ratio within 10 % of its value on
    10 degrees of freedom; none at another m."""
    from workbench.stats.statistics import Interval
    from workbench.study.claims import CLAIM_MARGIN, CLAIMS_FORMAT, claim_entry

    rests = {"unit": "frames", "frames": 100, "takes": 1, "batch_frames": 10, "batches": 10, "folds": 0}
    entries = []
    if m == 18:
        entries.append(
            {
                "data": "markers",
                "base": "markers",
                "protocol": "training",
                "protocol_text": "training frames",
                "m": [18],
                "n": 18,
                **{
                    name: claim_entry(
                        name,
                        Interval(value, 0.9 * value, 1.1 * value, n=100, null=1.0, degrees=10.0),
                        dict(rests, persistence=0.5),
                        "alpha_abs_mean",
                        CLAIM_MARGIN,
                    )
                    for name, value in (("H/QE", h_over_qe), ("QE/PCA", qe_over_pca))
                },
            }
        )
    return {
        "format": CLAIMS_FORMAT,
        "column": "alpha_abs_mean",
        "solver": "lstsq",
        "margin": CLAIM_MARGIN,
        "not_tested": "" if entries else f"not tested at m = n: markers: m = {m}, n = 18",
        "entries": entries,
    }


@functools.cache
def study_config(coverage: float, seed: int) -> dict:
    """The coverage study's resolved config at one cell, as a run writes it (``config.yaml``)."""
    overrides = [f"dataset.seed={seed}", f"basis.coverage={coverage}", f"paths.output_root=/x{seed}"]
    return resolved_settings(compose("coverage", overrides))


def write_record(folder, coverage, seed, job_num, complete=True, qe_rank=None, alpha=ALPHA):
    """A run record as the workbench writes it (through workbench.record.record), with chosen numbers (rows: H and QE
    with lstsq, then PCA); with ``qe_rank``, the QE basis's rank and PCA's exact method are recorded too."""
    h, qe, pca = alpha[(coverage, seed)]
    m = M[coverage][seed]
    rows = [
        {
            "data": "markers",
            "basis": basis,
            "projection": projection,
            "solver": solver,
            "n": n,
            "m": m,
            "coverage": coverage + 0.001,
            "alpha_abs_mean": value,
            "alpha_abs_pooled": value * 1.1,
            "alpha_disp_mean": value * 50,
            "alpha_disp_pooled": value * 20,
            "rms_mm": value / 2,
            "paper_alpha": paper,
        }
        for basis, projection, solver, n, value, paper in (
            ("H", "-", "lstsq", 18, h, 5.2),
            ("QE", "affine", "lstsq", 18, qe, 0.72),
            ("PCA", "-", "projection", m, pca, 0.62),
        )
    ]
    config = study_config(coverage, seed)
    metrics = {
        "study": "coverage",
        "config_hash": f"hash{coverage}{seed}",
        "job_num": job_num,
        "overrides": [f"dataset.seed={seed}", f"basis.coverage={coverage}", "paths.output_root=/x"],
        "dataset": {"name": "test", "frame_rate": 120.0},
        "data": {"markers": {"n_points": 66, "n_train_frames": 100, "n_eval_frames": 100}},
        "rows": [dict(row, train_on="markers", eval_on="markers") for row in rows],
        **({} if qe_rank is None else {"pca_facts": {"m": m, "method": "covariance"}}),
        "git": {"commit": "abc", "dirty": False},
    }
    metrics["claims"] = stored_claims(m, h / qe, qe / pca)
    if qe_rank is not None:
        metrics["data"]["markers"]["pca"] = metrics.pop("pca_facts")
        metrics["rows"][1]["basis_conditioning"] = {"rank": qe_rank(m), "n_shapes": 18}
    record.write_record(
        folder,
        resolved_yaml=yaml.safe_dump(config),
        table=pd.DataFrame(rows),
        text="",
        metrics=metrics,
        timings={"pca": 0.5, "total": 1.0 + seed},
    )
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


T_975_2 = 4.302652729749462  # Student t, 97.5 % quantile, 2 degrees of freedom


def test_level_statistics_match_a_hand_computation():
    # values 1, 2, 4: mean 7/3, sample sd sqrt(7/3); logs 0, ln 2, 2 ln 2: geometric mean 2, log sd ln 2
    result = level_statistics([1.0, 2.0, 4.0, float("nan")])
    half = T_975_2 * math.log(2.0) / math.sqrt(3)
    assert (result["n"], result["min"], result["max"]) == (3, 1.0, 4.0)
    assert result["mean"] == pytest.approx(7 / 3, rel=1e-12) and result["std"] == pytest.approx(math.sqrt(7 / 3))
    assert result["geomean"] == pytest.approx(2.0, rel=1e-12)
    assert (result["ci95_low"], result["ci95_high"]) == pytest.approx((2 * math.exp(-half), 2 * math.exp(half)))
    assert result["ci95_low"] == pytest.approx(0.3575, abs=1e-4)  # where the Student-t interval gave -1.46
    assert result["ci_method"] == "geometric mean, t-interval on log values"


def test_level_statistics_of_identical_and_single_values():
    same = level_statistics([1.5, 1.5, 1.5])
    assert same["geomean"] == pytest.approx(1.5) and math.isnan(same["ci95_low"]) and math.isnan(same["ci95_high"])
    single = level_statistics([2.0, float("nan")])
    assert single["n"] == 1 and single["geomean"] == 2.0 and math.isnan(single["ci95_low"])


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
    assert h.loc[0.9, "mean"] == pytest.approx(7 / 3) and h.loc[0.9, "geomean"] == pytest.approx(2.0)
    assert h.loc[0.9, "ci95_high"] == pytest.approx(2 * math.exp(T_975_2 * math.log(2) / math.sqrt(3)))
    assert h.loc[0.99, "geomean"] == pytest.approx(1.5) and math.isnan(h.loc[0.99, "ci95_low"])  # same every seed
    m = summary[(summary["basis"] == "PCA") & (summary["metric"] == "m")].set_index("basis.coverage")
    assert (m.loc[0.9, "min"], m.loc[0.9, "max"]) == (4, 6)


def test_paired_comparisons_by_hand(sweep):
    runs, _ = collect_runs([sweep])
    comparisons = paired_comparisons(runs, "alpha_abs_mean").set_index(["basis.coverage", "first", "second"])
    # coverage 0.99: PCA/QE per seed 0.1/0.2, 0.2/0.3, 0.3/0.4; the smaller first
    logs = [math.log(0.5), math.log(2 / 3), math.log(0.75)]
    mean = sum(logs) / 3
    half = T_975_2 * math.sqrt(sum((value - mean) ** 2 for value in logs) / 2) / math.sqrt(3)
    row = comparisons.loc[(0.99, "PCA", "QE")]
    assert (row["ratio"], row["ratio_low"], row["ratio_high"]) == pytest.approx(
        (math.exp(mean), math.exp(mean - half), math.exp(mean + half))
    )
    assert row["n"] == 3 and row["verdict"] == "not distinguishable" and row["ratio_high"] > 1
    assert comparisons.loc[(0.99, "QE", "H"), "verdict"] == "<"
    assert (comparisons["ratio"] <= 1).all() and (comparisons["ratio_low"] > 0).all()


def test_alpha_table_exact_text(sweep, tmp_path):
    written = collect_and_write([sweep], tmp_path / "out", where={"solver": "lstsq"})
    caption = (
        "alpha_abs_mean (%), solver = lstsq; cells: geometric mean over dataset.seed [95 % interval] "
        "(geometric mean, t-interval on log values, n = 3 per cell); m: range over the runs"
    )
    expected_markdown = (
        f"{caption}\n"
        "\n"
        "| basis.coverage |   m |                     H |                   QE |                  PCA |\n"
        "|----------------|----:|----------------------:|---------------------:|---------------------:|\n"
        "| 0.9            | 4-6 | 2.000 [0.357, 11.190] | 0.680 [0.327, 1.416] | 0.493 [0.298, 0.817] |\n"
        "| 0.99           |  12 |                 1.500 | 0.288 [0.121, 0.685] | 0.182 [0.046, 0.722] |\n"
    )
    assert written["markdown"] == expected_markdown
    assert (tmp_path / "out" / "alpha_table.md").read_text() == expected_markdown
    expected_latex = (
        f"% {caption}\n"
        "\\begin{tabular}{lrrrr}\n"
        "\\toprule\n"
        "basis.coverage & m & H & QE & PCA \\\\\n"
        "\\midrule\n"
        "0.9 & 4-6 & 2.000 [0.357, 11.190] & 0.680 [0.327, 1.416] & 0.493 [0.298, 0.817] \\\\\n"
        "0.99 & 12 & 1.500 & 0.288 [0.121, 0.685] & 0.182 [0.046, 0.722] \\\\\n"
        "\\bottomrule\n"
        "\\end{tabular}\n"
    )
    assert (tmp_path / "out" / "alpha_table.tex").read_text() == expected_latex
    assert written["n_runs"] == 6 and written["n_incomplete"] == 1
    findings = (tmp_path / "out" / "findings.md").read_text().splitlines()
    assert findings[0].startswith(
        "- **how to read**: the paper's claims are those each run stored at m = n (its own interval), counted per "
        "condition; levels: geometric means over the replicates; 'A < B': A/B per replicate (paired t on log "
        "ratios, n = 3) below 1 by its p_holm < 0.05, Holm over every tested row (6 rows, QE/H and QE/PCA at each "
        "cell's m among them: secondary, not the paper's claims)"
    )
    # no run is at m = n: each cell says so from its runs' stored claims, and QE/H, QE/PCA at the coverage rule's
    # m are secondary comparisons, Holm-adjusted with every other row (QE/H at 0.99: p 0.0146 * 6 = 0.087)
    assert findings[4] == (
        "- basis.coverage = 0.99, **markers**: the paper's claims (QE better than H; QE nearly as accurate as PCA): "
        "not tested at m = n in all 3 runs: markers: m = 12, n = 18."
    )
    assert findings[5:] == [
        "- basis.coverage = 0.99, **markers** (m = 12; 3 seeds, lstsq) `alpha_abs_mean`: PCA (n = 12) 0.182 ~ QE "
        "0.288 ~ H 1.5.",
        "- basis.coverage = 0.99, **markers**, lstsq, `alpha_abs_mean`: secondary comparisons at m = 12 (not the "
        "paper's claims): QE/H 0.192 [0.081, 0.457], Holm p 0.087, QE/PCA 1.59 [0.945, 2.67], Holm p 0.12.",
    ]
    # each number of the finding is a cell of the tables written beside it (QE/PCA: PCA/QE's row inverted)
    table = (tmp_path / "out" / "comparisons.md").read_text()
    assert "|           0.99 | PCA   | QE     | 3 |   0.63 |    0.3752 |      1.058 | not distinguishable |" in table
    assert (
        "|           0.99 | QE    | H      | 3 | 0.1923 |   0.08096 |     0.4567 | not distinguishable | 0.01455 | 0.08729 |"
        in table
    )
    assert "95 % interval, unadjusted; verdict by Holm" in table


def test_csv_and_parquet_hold_the_same_tables(sweep, tmp_path):
    collect_and_write([sweep], tmp_path / "out")
    for name in ("runs", "summary"):
        from_csv = pd.read_csv(tmp_path / "out" / f"{name}.csv")
        from_parquet = pd.read_parquet(tmp_path / "out" / f"{name}.parquet")
        assert list(from_csv.columns) == list(from_parquet.columns)
        pd.testing.assert_frame_equal(from_csv, from_parquet, check_dtype=False)


def test_without_pyarrow_the_csv_files_are_written_and_the_notice_waits_for_verbose(
    sweep, tmp_path, monkeypatch, caplog
):
    """No parquet copies without pyarrow; the line saying so is a debug note (``--verbose``), not on every call."""
    import logging

    monkeypatch.setattr("workbench.reporting.collect.sweep.has_module", lambda name: False)
    with caplog.at_level(logging.INFO, logger="workbench"):
        collect_and_write([sweep], tmp_path / "quiet")
    assert not caplog.records and not list((tmp_path / "quiet").glob("*.parquet"))
    assert (tmp_path / "quiet" / "runs.csv").is_file()
    with caplog.at_level(logging.DEBUG, logger="workbench"):
        collect_and_write([sweep], tmp_path / "verbose")
    assert [record.getMessage().split(": pip")[0] for record in caplog.records] == [
        "parquet copies of the tables left out"
    ]


def test_metrics_as_columns_table(sweep, tmp_path):
    text = collect_and_write([sweep], tmp_path / "out", columns="metric", where={"basis.coverage": "0.99"}, extra=())[
        "markdown"
    ]
    assert text.splitlines()[0].startswith("alpha (%) by metric, basis.coverage = 0.99; ")
    assert text.splitlines()[2:] == [
        "| basis |       alpha_abs_mean |     alpha_abs_pooled |     alpha_disp_mean |  alpha_disp_pooled |",
        "|-------|---------------------:|---------------------:|--------------------:|-------------------:|",
        "| H     |                1.500 |                1.650 |               75.00 |              30.00 |",
        "| QE    | 0.288 [0.121, 0.685] | 0.317 [0.134, 0.754] | 14.42 [6.07, 34.26] | 5.77 [2.43, 13.70] |",
        "| PCA   | 0.182 [0.046, 0.722] | 0.200 [0.050, 0.795] |  9.09 [2.29, 36.12] | 3.63 [0.91, 14.45] |",
    ]


def test_cli_collect_writes_next_to_the_sweep(sweep, capsys):
    assert main([str(sweep), "--where", "solver=lstsq", "--metric", "alpha_disp_pooled"]) == 0
    out = " ".join(capsys.readouterr().out.split())  # lines wrapped within 120 columns, joined
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
    assert format_estimate(0.31949, 0.30712, 0.33201, "{:.3f}") == "0.319 [0.307, 0.332]"
    assert format_estimate(0.31949, float("nan"), float("nan"), "{:.3f}") == "0.319"
    assert format_range(4.0, 6.0, "{:.0f}") == "4-6" and format_range(12.0, 12.0, "{:.0f}") == "12"
    assert sorted(["random12", "random3", "all"], key=natural_key) == ["all", "random3", "random12"]
    assert markdown_table(["k", "v"], [["a", "1.0"]], [False, True]) == "| k |   v |\n|---|----:|\n| a | 1.0 |\n"
    assert latex_table(["a_b", "v"], [["x%", "1 ± 2"]], [False, True]) == (
        "\\begin{tabular}{lr}\n\\toprule\na\\_b & v \\\\\n\\midrule\nx\\% & 1 $\\pm$ 2 \\\\\n"
        "\\bottomrule\n\\end{tabular}\n"
    )


def test_an_ordering_that_holds_by_construction_in_every_replicate_is_stated_not_tested(tmp_path):
    # at coverage 0.99 the QE basis has rank m + 1 in every run: QE <= PCA by construction, no test, no Holm share;
    # at 0.9 one run's QE basis falls short of m + 1, so there QE against PCA is a question for the data
    alpha = {
        (0.9, 0): (1.0, 0.5, 0.55),
        (0.9, 1): (2.0, 0.6, 0.66),
        (0.9, 2): (4.0, 0.7, 0.8),
        (0.99, 0): (1.5, 0.1, 0.12),
        (0.99, 1): (1.5, 0.2, 0.22),
        (0.99, 2): (1.5, 0.3, 0.35),
    }
    folder = tmp_path / "sweep"
    for job, (coverage, seed) in enumerate(alpha):
        short = coverage == 0.9 and seed == 1
        write_record(
            folder / f"basis.coverage={coverage},dataset.seed={seed}",
            coverage,
            seed,
            job,
            alpha=alpha,
            qe_rank=lambda m, short=short: m if short else m + 1,
        )
    written = collect_and_write([folder], tmp_path / "out", where={"solver": "lstsq"})
    comparisons = pd.read_csv(tmp_path / "out" / "comparisons.csv")
    qe_pca = comparisons[(comparisons["first"] == "QE") & (comparisons["second"] == "PCA")].set_index("basis.coverage")
    assert qe_pca.loc[0.99, "verdict"] == "<= by construction" and math.isnan(qe_pca.loc[0.99, "p"])
    assert qe_pca.loc[0.99, "by_construction"] == "QE spans PCA's affine subspace, rank m + 1 in every run"
    assert qe_pca.loc[0.9, "verdict"] != "<= by construction" and 0.0 < qe_pca.loc[0.9, "p"] < 1.0
    assert math.isnan(qe_pca.loc[0.99, "p_holm"])  # not in the Holm family
    line = next(line for line in written["findings"] if line.startswith("basis.coverage = 0.99, **markers** (m"))
    assert "QE 0.182 <= PCA (n = 12) 0.21 by construction (QE spans PCA's affine subspace" in line, line
    pairs = next(line for line in written["findings"] if line.startswith("basis.coverage = 0.99, **markers**, "))
    assert "QE/PCA 0.866 [0.776, 0.967]" in pairs and "(by construction: its size, not its sign)" in pairs, pairs
    tested = next(line for line in written["findings"] if line.startswith("basis.coverage = 0.9, **markers** (m"))
    assert "by construction" not in tested, tested
    runs = pd.read_csv(tmp_path / "out" / "runs.csv")
    assert set(runs.loc[(runs["basis"] == "QE"), "never_worse_than"]) == {"PCA/projection", "-"}


def summary_inputs(folder):
    """The records of a sweep folder written by write_record, its runs table and its comparisons with families."""
    from workbench.reporting.findings.sweep import holm_verdicts
    from workbench.reporting.tables.runs import runs_table, sweep_comparisons

    records = [record.load_record(path) for path in sorted(folder.iterdir()) if (path / record.DONE).exists()]
    runs = runs_table(records, folder)
    comparisons = holm_verdicts(sweep_comparisons(runs, ["alpha_abs_mean"], ["dataset.seed"]))
    return records, runs, comparisons


def test_sweep_summary_states_the_two_claims_where_every_run_kept_m_equal_n(tmp_path, monkeypatch):
    from workbench.reporting.findings.sweep_summary import sweep_summary

    monkeypatch.setitem(M, 0.99, (18, 18, 18))  # at 0.99 every run keeps m = n = 18: the paper's regime
    folder = tmp_path / "sweep"
    for job, (coverage, seed) in enumerate(ALPHA):
        write_record(folder / f"basis.coverage={coverage},dataset.seed={seed}", coverage, seed, job)
    records, runs, comparisons = summary_inputs(folder)
    text = sweep_summary(records, runs, comparisons, ["basis.coverage"], ["dataset.seed"], "alpha_abs_mean")
    assert len(text.split()) <= 200
    assert "on markers, at basis.coverage = 0.99, where every run kept m = n = 18 (the paper's regime)." in text
    # each run's stored claims, counted: H/QE 7.5, 5, 3.75 each within 10 %; QE/PCA 2, 1.5, 1.33 against 1.5
    assert (
        "The paper's claims at m = n, as each run stored them (its own interval; claim 2 against the margin 1.5): "
        "training frames: QE "
        "better than H reproduced in 3 (H/QE 3.75-7.5); QE nearly as accurate as PCA not reproduced in 1, not "
        "decided in 1, reproduced in 1 (QE/PCA 1.33-2)." in text
    ), text
    assert text.endswith(
        "Design: 3 runs (dataset.seed), 100 training and 100 evaluated frames each; intervals over the runs, 2 "
        "degrees of freedom; one metric, `alpha_abs_mean`, at a time."
    )


def test_sweep_summary_says_when_it_is_not_the_papers_regime_and_when_qe_below_pca_is_built_in(tmp_path):
    from workbench.reporting.findings.sweep_summary import summary_condition, sweep_summary

    alpha = {key: (h, qe, qe * 1.1) for key, (h, qe, _) in ALPHA.items()}
    folder = tmp_path / "sweep"
    for job, (coverage, seed) in enumerate(alpha):
        write_record(
            folder / f"basis.coverage={coverage},dataset.seed={seed}",
            coverage,
            seed,
            job,
            alpha=alpha,
            qe_rank=lambda m: m + 1,
        )
    records, runs, comparisons = summary_inputs(folder)
    text = sweep_summary(records, runs, comparisons, ["basis.coverage"], ["dataset.seed"], "alpha_abs_mean")
    assert "at the lead condition basis.coverage = 0.9, not the paper's regime m = n (m = 4-6, n = 18)" in text
    assert (
        "The paper's claims (QE better than H; QE nearly as accurate as PCA): not tested at m = n in all 3 runs: "
        "markers: m = 4, n = 18" in text
    ), text
    assert "QE rank 5-7 of 18 (singular)" in text  # rank m + 1 of the 18 shapes, over the three runs
    # with many swept settings the summary names the condition by its place, to stay within 200 words
    assert summary_condition(runs, ["basis.coverage"], "markers", values=False)[1] == (
        "at the lead condition (the first row of the tables), not the paper's regime m = n (m = 4-6, n = 18)"
    )
    regime = runs.assign(data="markers m=n")
    assert summary_condition(regime, ["basis.coverage"], "markers m=n") == (
        {"basis.coverage": 0.9},
        "at the paper's regime m = n (the variant markers m=n, basis.coverage = 0.9)",
    )
