"""The findings text is produced from the numbers: checked on a constructed alpha table with known answers."""

import pandas as pd
import pytest

from workbench.errors import WorkbenchError

from workbench.reporting.findings import facts_frame, run_findings, shared_notes

PAPER = {"m": 18, "alpha": {"H": 5.2, "QE": 0.72, "PCA": 0.62}}


def known_table() -> pd.DataFrame:
    rows = []
    values = {("H", "lstsq"): 1.0, ("QE", "lstsq"): 0.25, ("H", "nnls"): 1.1, ("QE", "nnls"): 1.5,
              ("H", "box"): 1.2, ("QE", "box"): 1.0}
    for (basis, solver), alpha in values.items():
        rows.append({"data": "mesh", "basis": basis, "projection": "affine" if basis == "QE" else "-",
                     "solver": solver, "n": 18, "m": 10, "coverage": 0.9951, "alpha_abs_mean": alpha})
    rows.append({"data": "mesh", "basis": "PCA", "projection": "-", "solver": "projection", "n": 10, "m": 10,
                 "coverage": 0.9951, "alpha_abs_mean": 0.2})
    return pd.DataFrame.from_records(rows)


INTUITIVENESS = {"mesh": [
    {"shape": "jawOpen", "projection": "affine", "relative_distance": 0.2, "cosine": 0.98},
    {"shape": "browDown_L", "projection": "affine", "relative_distance": 0.9, "cosine": 0.45},
    {"shape": "mouthPucker", "projection": "affine", "relative_distance": 0.6, "cosine": 0.8},
    {"shape": "jawOpen", "projection": "linear", "relative_distance": 0.99, "cosine": 0.1},
]}


def test_findings_of_a_known_table():
    lines = run_findings(known_table(), "alpha_abs_mean", PAPER, INTUITIVENESS,
                         negative_share={"mesh": {"H": 0.1, "QE": 0.62}})
    assert lines == [
        "**mesh**: `alpha_abs_mean` from best to worst, lstsq: PCA 0.2 < QE 0.25 < H 1; "
        "nnls: PCA 0.2 < H 1.1 < QE 1.5; box: PCA 0.2 < QE 1 < H 1.2.",
        "**mesh**: H/QE = 4.00 (paper 7.22), QE/PCA = 1.25 (paper 1.16) with least squares; absolute alpha "
        "depends on the coordinate origin, the ratios compare across datasets.",
        "**mesh**: m = 10 eigenfaces reach coverage 0.9951 (paper: m = 18); the 18 hand shapes can span them, so "
        "QE can match PCA.",
        "**mesh**: with non-negative weights QE's alpha goes from 0.25 to 1.5 (x6.00) and H's from 1 to 1.1 "
        "(x1.10): QE becomes worse than H (1.5 against 1.1); under least squares 62 % of the frames give QE a "
        "negative weight (H: 10 %), which the constraint must undo.",
        "**mesh**: with box [0, 1] weights QE's alpha goes from 0.25 to 1 (x4.00) and H's from 1 to 1.2 (x1.20): "
        "QE stays better than H (1 against 1.2).",
        "**mesh**: the projection changes most browDown_L (cosine 0.45, relative distance 0.90), mouthPucker "
        "(cosine 0.80, relative distance 0.60), jawOpen (cosine 0.98, relative distance 0.20); median cosine of "
        "the 3 shapes to their quasi-eigen faces 0.80.",
    ]


def test_more_eigenfaces_than_hand_shapes_is_said():
    table = known_table().assign(m=33)
    lines = run_findings(table, "alpha_abs_mean", PAPER, {})
    assert "m = 33 eigenfaces reach coverage 0.9951 (paper: m = 18); the 18 hand shapes cannot span them, so QE " \
           "cannot reach PCA." in lines[2]


def test_facts_and_notes_are_stated_once():
    metrics = {"data": {
        "markers": {"n_points": 41, "n_train_frames": 100, "n_eval_frames": 100, "notes": ["shared", "markers only"],
                    "pca": {"m": 9, "coverage_reached": 0.99512, "method": "covariance"},
                    "quasi_eigen": {"affine": {"empty_axes": []}, "linear": {"empty_axes": [3, 5]}}},
        "mesh": {"n_points": 9409, "n_train_frames": 100, "n_eval_frames": 100, "notes": ["shared"],
                 "pca": {"m": 10, "coverage_reached": 0.9953, "method": "gram"},
                 "quasi_eigen": {"affine": {"empty_axes": []}, "linear": {"empty_axes": []}}}}}
    facts = facts_frame(metrics)
    assert list(facts["m"]) == [9, 10] and facts.loc[0, "empty PCA axes"] == "affine: none; linear: 3, 5"
    assert shared_notes(metrics) == (["shared"], {"markers": ["markers only"], "mesh": []})


# --- findings of sweeps: only from the paired comparisons ----------------------------------------------------

SEEDS = {  # coverage -> basis -> alpha_abs_mean of seeds 0 and 1 (the coverage preset's, as its records say)
    0.95: {"H": (0.31, 0.33), "QE": (0.42, 0.17), "QE-linear": (0.63, 0.39), "PCA": (0.49, 0.27)},
    0.995: {"H": (0.31, 0.33), "QE": (0.16, 0.16), "QE-linear": (0.23, 0.18), "PCA": (0.19, 0.17)}}


def write_disagreeing_sweep(folder):
    """Two seeds at two coverages; at 0.95 their orderings of QE and H disagree. Written as the workbench writes
    records."""
    import yaml

    from workbench import record

    for coverage, alpha in SEEDS.items():
        for seed in (0, 1):
            m = (4 - seed) if coverage == 0.95 else (6 - seed)
            rows = [{"data": "markers", "basis": basis, "projection": "affine" if basis.startswith("QE") else "-",
                     "solver": "projection" if basis == "PCA" else "lstsq", "n": m if basis == "PCA" else 18, "m": m,
                     "coverage": coverage, "alpha_abs_mean": values[seed], "alpha_abs_pooled": values[seed] * 1.1,
                     "alpha_disp_mean": values[seed] * 50, "alpha_disp_pooled": values[seed] * 20,
                     "rms_mm": values[seed] / 2, "paper_alpha": PAPER["alpha"].get(basis, float("nan"))}
                    for basis, values in alpha.items()]
            config = {"study": "coverage", "dataset": {"kind": "synthetic", "seed": seed},
                      "basis": {"coverage": coverage}}
            metrics = {"study": "coverage", "config_hash": f"h{coverage}{seed}", "job_num": seed,
                       "overrides": [f"dataset.seed={seed}", f"basis.coverage={coverage}"],
                       "dataset": {"name": "test", "frame_rate": 120.0},
                       "data": {"markers": {"n_points": 66, "n_train_frames": 100, "n_eval_frames": 100}},
                       "rows": [dict(row, train_on="markers", eval_on="markers") for row in rows],
                       "git": {"commit": "abc", "dirty": False}}
            record.write_record(folder / f"basis.coverage={coverage},dataset.seed={seed}",
                                resolved_yaml=yaml.safe_dump(config), table=pd.DataFrame(rows), text="",
                                metrics=metrics, timings={"total": 1.0})
    return folder


def drawn_intervals(figure):
    """Every interval a figure draws (bands and error bars) as arrays of y values."""
    from matplotlib.collections import LineCollection, PolyCollection

    values = []
    for ax in figure.axes:
        for collection in ax.collections:
            if isinstance(collection, PolyCollection):
                values += [path.vertices[:, 1] for path in collection.get_paths()]
            elif isinstance(collection, LineCollection):
                values += [segment[:, 1] for segment in collection.get_segments()]
    return values


def test_a_sweep_whose_seeds_disagree_is_not_distinguishable_and_no_interval_goes_below_zero(tmp_path, capsys):
    import re

    from scipy import stats

    from workbench.reporting.collect import main
    from workbench.reporting.figures.studies import plot_alpha_against, plot_marker_vs_mesh
    from workbench.reporting.runs import collect_runs, summarise, wide

    sweep = write_disagreeing_sweep(tmp_path / "sweep")
    qe = SEEDS[0.95]["QE"]
    # what the Student-t interval over the two seeds said: a mean of 0.295 and a lower bound of -1.29 %
    assert qe[0] > SEEDS[0.95]["H"][0] and qe[1] < SEEDS[0.95]["H"][1]
    assert (sum(qe) / 2 - stats.t.ppf(0.975, 1) * stats.tstd(qe) / 2 ** 0.5) < -1.2
    assert main([str(sweep), "--where", "solver=lstsq"]) == 0
    printed = capsys.readouterr().out
    finding = next(line for line in printed.splitlines() if line.startswith("- basis.coverage = 0.95"))
    assert "QE and H not distinguishable (QE/H " in finding and "(paired t on log ratios, n = 2)" in finding
    assert "QE < H" not in finding and "H < QE" not in finding
    # every interval printed, in the table and in the findings, lies above zero, and names its method and n
    bounds = [float(value) for pair in re.findall(r"\[([-0-9.e]+), ([-0-9.e]+)\]", printed) for value in pair]
    assert len(bounds) >= 2 * (7 + 6) and min(bounds) > 0  # QE at 0.995 is 0.16 on both seeds: no interval
    assert "geometric mean, t-interval on log values, n = 2 per cell" in printed
    comparisons = pd.read_csv(sweep / "collected" / "comparisons.csv")
    pair = comparisons[(comparisons["basis.coverage"] == 0.95) & (comparisons["first"] == "QE")
                       & (comparisons["second"] == "H")]
    assert pair["verdict"].tolist() == ["not distinguishable"] and (comparisons["ratio_low"] > 0).all()
    # every interval drawn lies above zero, and the figure names the method and n beside them
    runs, _ = collect_runs([sweep])
    summary = wide(summarise(runs))
    for figure in (plot_alpha_against(summary, "basis.coverage", points=runs, title="disagreeing seeds"),
                   plot_marker_vs_mesh(summary[summary["basis.coverage"] == 0.95], title="one variant")):
        drawn = drawn_intervals(figure)
        assert drawn and min(float(values.min()) for values in drawn) > 0
        assert "geometric mean, t-interval on log values; n = 2 seeds" in figure._suptitle.get_text().replace("\n", " ")
    # a table whose interval reaches below zero is refused, not drawn
    negative = summary.assign(alpha_abs_mean_ci_low=summary["alpha_abs_mean"] - 1.3)
    with pytest.raises(WorkbenchError, match="reaches below zero"):
        plot_alpha_against(negative, "basis.coverage", title="t-interval")


def known_comparisons(rows):
    columns = ["basis.coverage", "data", "solver", "metric", "first", "second", "n", "ratio", "ratio_low",
               "ratio_high", "method", "verdict"]
    return pd.DataFrame([dict(zip(columns, row)) for row in rows])


def test_sweep_findings_state_each_neighbouring_pair_from_its_interval():
    from workbench.reporting.findings import sweep_findings

    summary = pd.DataFrame({
        "basis.coverage": [0.99] * 3, "data": ["mesh"] * 3, "basis": ["H", "QE", "PCA"],
        "solver": ["lstsq", "lstsq", "projection"], "n_seeds": [5] * 3, "m_min": [9] * 3, "m_max": [11] * 3,
        "n_min": [18, 18, 9], "n_max": [18, 18, 11], "alpha_abs_mean": [0.312, 0.162, 0.169]})
    method = "paired t on log ratios"
    comparisons = known_comparisons([
        (0.99, "mesh", "lstsq", "alpha_abs_mean", "QE", "H", 5, 0.52, 0.46, 0.58, method, "<"),
        (0.99, "mesh", "lstsq", "alpha_abs_mean", "PCA", "H", 5, 0.54, 0.5, 0.6, method, "<"),
        (0.99, "mesh", "lstsq", "alpha_abs_mean", "QE", "PCA", 5, 0.9586, 0.9, 1.02, method, "not distinguishable")])
    assert sweep_findings(summary, comparisons, ["basis.coverage"], "alpha_abs_mean", "lstsq") == [
        "basis.coverage = 0.99, **mesh** (m = 9-11; 5 seeds, lstsq): `alpha_abs_mean` geometric means, best first: "
        "QE 0.162, PCA (n = 9-11) 0.169, H 0.312; QE and PCA not distinguishable (QE/PCA 0.9586, 95 % interval "
        "[0.9, 1.02] (paired t on log ratios, n = 5)); PCA < H (PCA/H 0.54, 95 % interval [0.5, 0.6] (paired t on "
        "log ratios, n = 5))."]
    # with nothing swept but the seed: one finding per data variant
    assert sweep_findings(summary, comparisons, [], "alpha_abs_mean", "lstsq")[0].startswith(
        "**mesh** (m = 9-11; 5 seeds, lstsq): ")


def test_bases_findings_mark_sizes_and_state_closeness_only_where_the_interval_allows():
    from workbench.reporting.findings import bases_findings

    summary = pd.DataFrame({"data": ["mesh"] * 4, "basis": ["H", "QE", "PCA", "SPCA"], "n_seeds": [5] * 4,
                            "n_min": [18, 18, 10, 18], "n_max": [18, 18, 10, 18],
                            "alpha_abs_mean": [1.0, 0.2, 0.15, 0.1], "matched_abs_cosine": [1.0, 0.66, 0.43, 0.45],
                            "locality": [0.07, 0.27, 0.25, 0.095]})
    method = "paired t on log ratios"
    rows = [("mesh", "alpha_abs_mean", "SPCA", "PCA", 5, 0.667, 0.6, 0.74, method, "<"),
            ("mesh", "alpha_abs_mean", "PCA", "QE", 5, 0.75, 0.7, 0.8, method, "<"),
            ("mesh", "alpha_abs_mean", "QE", "H", 5, 0.2, 0.18, 0.22, method, "<"),
            ("mesh", "matched_abs_cosine", "SPCA", "QE", 5, 0.68, 0.6, 0.77, method, "<"),
            ("mesh", "locality", "SPCA", "PCA", 5, 0.38, 0.3, 0.48, method, "<"),
            ("mesh", "locality", "PCA", "QE", 5, 0.93, 0.8, 1.08, method, "not distinguishable")]
    columns = ["data", "metric", "first", "second", "n", "ratio", "ratio_low", "ratio_high", "method", "verdict"]
    comparisons = pd.DataFrame([dict(zip(columns, row)) for row in rows])
    assert bases_findings(summary, comparisons, "alpha_abs_mean") == [
        "**mesh** (5 runs): `alpha_abs_mean` geometric means, best first: SPCA 0.100, PCA (n = 10) 0.150, QE 0.200, "
        "H 1.000; SPCA < PCA (SPCA/PCA 0.667, 95 % interval [0.6, 0.74] (paired t on log ratios, n = 5)); PCA < QE "
        "(PCA/QE 0.75, 95 % interval [0.7, 0.8] (paired t on log ratios, n = 5)); QE < H (QE/H 0.2, 95 % interval "
        "[0.18, 0.22] (paired t on log ratios, n = 5)).",
        "**mesh**: bases of other sizes than the hand basis's n = 18: PCA n = 10; their alpha is not that of a basis "
        "of the same size.",
        "**mesh**: closest to the hand shapes (mean matched |cosine|): QE 0.660, then SPCA 0.450 (the hand shapes' "
        "1.000); SPCA < QE (SPCA/QE 0.68, 95 % interval [0.6, 0.77] (paired t on log ratios, n = 5)).",
        "**mesh**: most local (share of the face holding an element's displacement): SPCA 0.095, then PCA 0.250 "
        "(the hand shapes' 0.070); SPCA < PCA (SPCA/PCA 0.38, 95 % interval [0.3, 0.48] (paired t on log ratios, "
        "n = 5))."]
