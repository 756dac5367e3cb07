"""Exact-text tests of the alpha table and its headline."""

import math

import numpy as np

from workbench.numerics.metrics import AlphaSummary
from workbench.reporting.tables.cells import markdown_frame as markdown_table
from workbench.reporting.text.run import headline, printed_tables
from workbench.study.results import Row
from workbench.study.table import FRAME_COLUMNS, alpha_table


def summary(absolute, displacement, rms):
    return AlphaSummary(
        absolute_per_frame=np.array([absolute]),
        displacement_per_frame=np.array([displacement]),
        absolute_mean=absolute,
        absolute_pooled=absolute * 1.1,
        displacement_mean=displacement,
        displacement_pooled=displacement * 0.9,
        rms_mm=rms,
        n_undefined_displacement_frames=0,
    )


ROWS = [
    Row("H", "-", "box", 18, summary(5.1234, 40.0, 3.5)),
    Row("QE", "affine", "box", 18, summary(0.7, 6.25, 0.41)),
    Row("PCA", "-", "projection", 12, summary(0.61, 5.0, 0.3)),
]
PAPER = {"H": 5.2, "QE": 0.72, "PCA": 0.62}


def test_markdown_table_exact_text():
    table = alpha_table(ROWS, data="markers", m=12, coverage=0.99512, paper_alpha={"H": 5.2, "PCA": 0.62})
    expected = (
        "| data    | basis | projection | solver     |  n |  m | coverage | alpha_abs_mean | alpha_abs_pooled "
        "| alpha_disp_mean | alpha_disp_pooled | rms_mm | paper_alpha |\n"
        "|---------|-------|------------|------------|---:|---:|---------:|---------------:|-----------------:"
        "|----------------:|------------------:|-------:|------------:|\n"
        "| markers | H     | -          | box        | 18 | 12 |   0.9951 |          5.123 |            5.636 "
        "|           40.00 |             36.00 |  3.500 |        5.20 |\n"
        "| markers | QE    | affine     | box        | 18 | 12 |   0.9951 |          0.700 |            0.770 "
        "|            6.25 |              5.62 |  0.410 |           - |\n"
        "| markers | PCA   | -          | projection | 12 | 12 |   0.9951 |          0.610 |            0.671 "
        "|            5.00 |              4.50 |  0.300 |        0.62 |\n"
    )
    assert markdown_table(table[[c for c in table.columns if c not in FRAME_COLUMNS]]) == expected
    # the run prints the alpha columns, then the per-frame error and the weights (NaN here: "-")
    printed = printed_tables(table)
    assert printed.startswith(expected)
    assert printed.endswith(
        "| data    | basis | projection | solver     | err_mm_median | err_mm_p95 | err_mm_max | w_max_abs "
        "| w_outside_01 | w_sparsity | w_roughness |\n"
        "|---------|-------|------------|------------|--------------:|-----------:|-----------:|----------:"
        "|-------------:|-----------:|------------:|\n"
        "| markers | H     | -          | box        |             - |          - |          - |         - "
        "|            - |          - |           - |\n"
        "| markers | QE    | affine     | box        |             - |          - |          - |         - "
        "|            - |          - |           - |\n"
        "| markers | PCA   | -          | projection |             - |          - |          - |         - "
        "|            - |          - |           - |\n"
    )


def test_frame_columns_of_a_row_with_errors_and_weights():
    from workbench.numerics.metrics import error_distribution, weight_statistics

    row = Row(
        "QE",
        "affine",
        "lstsq",
        2,
        summary(0.7, 6.25, 0.41),
        weight_statistics=weight_statistics(np.array([[0.0, 0.0], [1.0, 0.5], [4.0, 1.0], [9.0, 1.5]]), np.arange(4.0)),
        error_mm=error_distribution(np.array([1.0, 2.0, 3.0, 4.0])),
    )
    table = alpha_table([row], data="markers", m=2, coverage=0.99, paper_alpha={})
    assert table.loc[0, ["err_mm_median", "err_mm_max", "w_max_abs", "w_outside_01", "w_roughness"]].tolist() == [
        2.5,
        4.0,
        9.0,
        0.5,
        2.0,
    ]


def test_headline_states_an_order_only_where_the_paired_interval_excludes_zero():
    table = alpha_table(ROWS, data="markers", m=12, coverage=0.995, paper_alpha=PAPER)
    comparisons = {
        "markers": [
            {"a": ["H", "box"], "b": ["QE", "box"], "estimate": 4.42, "low": 3.9, "high": 4.9},
            {
                "a": ["QE", "box"],
                "b": ["PCA", "projection"],
                "estimate": 0.09,
                "low": -0.01,
                "high": 0.2,
                "n": 800,
                "method": "circular block bootstrap over time",
                "block_frames": 12,
                "block_seconds": 0.1,
            },
        ]
    }
    text = headline(table, {"headline_normalisation": "absolute", "headline_aggregate": "mean"}, PAPER, comparisons)
    assert text.splitlines()[0] == (
        "alpha_abs_mean with box: PCA 0.61 ~ QE 0.7 (PCA - QE -0.09, 95 % interval "
        "[-0.2, +0.01] (circular block bootstrap over time, blocks of 12 frames = 0.1 s, "
        "n = 800): not distinguishable) < H 5.12"
    )


def test_missing_paper_value_is_nan_in_the_frame():
    table = alpha_table(ROWS, data="markers", m=12, coverage=0.995, paper_alpha={})
    assert all(math.isnan(value) for value in table["paper_alpha"])


def test_headline_exact_text():
    table = alpha_table(ROWS, data="markers", m=12, coverage=0.995, paper_alpha=PAPER)
    text = headline(table, {"headline_normalisation": "absolute", "headline_aggregate": "mean"}, PAPER)
    assert text == (
        "alpha_abs_mean with box: H 5.12, QE 0.70, PCA 0.61\n"
        "paper (Kim & Ko, absolute alpha, QP solver with unstated constraints): "
        "H 5.2, QE 0.72, PCA 0.62\n"
        "paper_alpha is Kim & Ko's own capture (35,000 frames, 66 markers), its own coordinate origin "
        "and absolute alpha: absolute alpha divides by |v*| and so moves with where the origin lies, and "
        "another face, capture and hand basis give other values; compare the ratios H/QE and QE/PCA "
        "(paper 7.2 and 1.16), not alpha itself\n"
    )


def test_headline_states_identities_and_never_tests_them():
    from workbench.stats.identities import Identity

    table = alpha_table(ROWS, data="markers", m=12, coverage=0.995, paper_alpha=PAPER)
    comparisons = {
        "markers": [{"a": ["QE", "box"], "b": ["PCA", "projection"], "estimate": 0.09, "low": 0.05, "high": 0.2}]
    }
    identity = Identity(("PCA", "projection"), ("QE", "box"), "Eckart-Young", pooled_only=True)
    metric = {"headline_normalisation": "absolute", "headline_aggregate": "pooled"}
    text = headline(table, metric, PAPER, comparisons, {"markers": [identity]})
    assert "PCA 0.671 <= QE 0.77 by construction (Eckart-Young)" in text.splitlines()[0]
    # a per-frame mean is not what Eckart-Young orders: there the interval decides
    metric = {"headline_normalisation": "absolute", "headline_aggregate": "mean"}
    assert "PCA 0.61 < QE 0.7" in headline(table, metric, PAPER, comparisons, {"markers": [identity]})
