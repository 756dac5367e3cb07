"""The findings text is produced from the numbers: checked on a constructed alpha table with known answers."""

import pandas as pd

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


def test_sweep_findings_order_the_bases_at_each_swept_value():
    from workbench.reporting.findings import sweep_findings

    table = pd.concat([known_table().assign(**{"basis.coverage": 0.99}),
                       known_table().assign(**{"basis.coverage": 0.995, "alpha_abs_mean": lambda t: t["alpha_abs_mean"] * 2})])
    lines = sweep_findings(table, ["basis.coverage"], "alpha_abs_mean", "lstsq", PAPER)
    assert lines == ["basis.coverage = 0.99: mesh PCA 0.2 < QE 0.25 < H 1",
                     "basis.coverage = 0.995: mesh PCA 0.4 < QE 0.5 < H 2"]
    assert sweep_findings(known_table(), [], "alpha_abs_mean", "lstsq", PAPER)[0].startswith("**mesh**")


def test_bases_findings():
    from workbench.reporting.findings import bases_findings

    summary = pd.DataFrame({"data": ["mesh"] * 3, "basis": ["H", "QE", "SPCA"], "alpha_abs_mean": [1.0, 0.2, 0.1],
                            "matched_abs_cosine": [1.0, 0.66, 0.45], "locality": [0.07, 0.27, 0.095]})
    assert bases_findings(summary, "alpha_abs_mean") == [
        "**mesh**: `alpha_abs_mean` from best to worst: SPCA 0.1 < QE 0.2 < H 1.",
        "**mesh**: closest to the hand shapes: QE (mean matched |cosine| 0.66); most local: SPCA (10 % of the face "
        "holds its elements' displacement, the hand shapes' 7 %)."]
