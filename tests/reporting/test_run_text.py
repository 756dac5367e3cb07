"""What a run prints first: one sentence on the paper's two claims, each decided by the interval of its ratio, and
text that fits in 120 columns unless ``--wide`` is asked for."""

from types import SimpleNamespace

import pytest
from in_process import run_workbench

from workbench.reporting.text.run import PRINT_WIDTH, fit_width, reproduced_sentence

PAPER = {"paper": {"alpha": {"H": 5.2, "QE": 0.72, "PCA": 0.62}}, "metric": {}}


def result(data, m, protocol="training frames", n=18, rank=18):
    rows = [
        SimpleNamespace(
            basis=basis, solver=solver, n_shapes=n, conditioning=SimpleNamespace(as_dict=lambda: {"rank": rank})
        )
        for basis, solver in (("H", "lstsq"), ("QE", "lstsq"), ("PCA", "projection"))
    ]
    return SimpleNamespace(
        data=data,
        protocol=protocol,
        rows=rows,
        train_on=data,
        eval_on=data,
        eigenfaces=SimpleNamespace(n_components_=m, method_="covariance"),
        capture=SimpleNamespace(hand_names=("shape",) * n, notes=()),
    )


def ratios(h_over_qe, qe_over_pca):
    return {
        name: {"estimate": sum(bounds) / 2, "low": bounds[0], "high": bounds[1], "null": 1.0}
        for name, bounds in (("H/QE", h_over_qe), ("QE/PCA", qe_over_pca))
    }


@pytest.mark.parametrize(
    "h_over_qe, first, qe_over_pca, second",
    [
        ((1.5, 2.5), "reproduced, H/QE 2 [1.5, 2.5]; the paper's 7.2 lies above it", (1.0, 1.1), "reproduced"),
        ((0.9, 3.1), "not decided, H/QE 2 [0.9, 3.1]; the paper's 7.2 lies above it", (1.1, 1.3), "not decided"),
        (
            (0.5, 0.9),
            "not reproduced, H/QE 0.7 [0.5, 0.9]; the paper's 7.2 lies above it",
            (1.2, 1.4),
            "not reproduced",
        ),
        ((5.0, 9.0), "reproduced, H/QE 7 [5, 9]; the paper's 7.2 lies within it", (1.2, 1.4), "not reproduced"),
    ],
)
def test_each_claim_is_decided_by_the_interval_of_its_ratio(h_over_qe, first, qe_over_pca, second):
    results = [result("markers m=n", 18), result("markers", 13)]
    sentence = reproduced_sentence(results, PAPER, {"markers m=n": ratios(h_over_qe, qe_over_pca)})
    assert sentence.startswith(
        f"The paper's claims, on markers m=n (m = 18, lstsq, alpha_abs_mean): QE better than H: {first}; "
        f"QE nearly as accurate as PCA (QE/PCA <= 1.16): {second}, QE/PCA "
    )


def test_qe_within_pca_by_construction_is_not_tested_and_held_out_variants_are_left_out():
    held_out = result("markers held-out tail", 18, protocol="held-out tail of each take")
    found = {"markers": ratios((1.5, 2.5), (0.9, 0.95)), "markers held-out tail": ratios((9, 10), (9, 10))}
    # no variant at m = n: the first one scored on its training frames; QE's rank 14 = m + 1 spans PCA's subspace
    sentence = reproduced_sentence([result("markers", 13, rank=14), held_out], PAPER, found)
    assert "on markers (m = 13," in sentence and "held-out" not in sentence
    assert "QE nearly as accurate as PCA (QE/PCA <= 1.16): holds by construction" in sentence
    assert reproduced_sentence([result("markers", 13)], PAPER, {}) == ""


def test_long_lines_are_wrapped_and_tables_are_not():
    text = "  " + " ".join(["word"] * 60) + "\n| " + "x" * 150 + " |"
    lines = fit_width(text).split("\n")
    assert all(len(line) <= PRINT_WIDTH for line in lines[:-1]) and lines[-1] == "| " + "x" * 150 + " |"
    assert lines[0].startswith("  word") and lines[1].startswith("    word") and len(lines) == 4


def test_a_folder_name_longer_than_a_line_stays_on_the_line_of_the_word_before_it():
    folder = "sweep/" + ",".join(f"dataset.setting{i}=value" for i in range(8))  # 6 + 8 * 23 columns
    lines = fit_width(f"done {folder}: " + " ".join(["word"] * 40)).split("\n")
    assert lines[0] == f"done {folder}:" and all(len(line) <= PRINT_WIDTH for line in lines[1:])
    assert lines[1].startswith("  word")


def test_a_run_prints_its_verdict_first_within_120_columns_and_wide_on_request(tmp_path):
    arguments = ["dataset.n_frames=400", "solver=lstsq"]
    narrow = run_workbench(*arguments, "hydra.run.dir=narrow", cwd=tmp_path)
    assert narrow.returncode == 0, narrow.stderr
    lines = narrow.stdout.splitlines()
    assert lines[0].startswith("The paper's claims, on markers m=n (m = 18, lstsq, alpha_abs_mean): QE better than H: ")
    assert max(len(line) for line in lines[:-1]) <= PRINT_WIDTH  # all but the record's path
    assert "| markers m=n | QE        | lstsq      | 18 |" in narrow.stdout and "err_mm_median" not in narrow.stdout
    wide = run_workbench(*arguments, "hydra.run.dir=wide", "--wide", cwd=tmp_path)
    assert wide.returncode == 0, wide.stderr
    full = (tmp_path / "wide" / "alpha_table.md").read_text()
    assert wide.stdout == f"{full}\nrecord: {tmp_path / 'wide'}\n" and "| err_mm_median |" in full
    assert max(len(line) for line in full.splitlines()) > PRINT_WIDTH
    assert full.splitlines()[0] == lines[0] and (tmp_path / "narrow" / "alpha_table.md").read_text() == full
