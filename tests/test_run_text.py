"""What a run prints first: one sentence on the paper's claims, decided by the paired comparison and the paper's
QE/PCA ratio, and text that fits in 120 columns unless ``--wide`` is asked for."""

from types import SimpleNamespace

import pytest
from in_process import run_workbench

from workbench.reporting.run_text import PRINT_WIDTH, fit_width, reproduced_sentence

PAPER = {"paper": {"alpha": {"H": 5.2, "QE": 0.72, "PCA": 0.62}}, "metric": {}}


def result(data, m, alphas, protocol="training frames", n=18):
    rows = [
        SimpleNamespace(basis=basis, solver=solver, alpha=SimpleNamespace(absolute_mean=alphas.get(basis, 1.0)))
        for basis, solver in (("H", "lstsq"), ("QE", "lstsq"), ("PCA", "projection"))
    ]
    return SimpleNamespace(
        data=data,
        protocol=protocol,
        rows=rows,
        eigenfaces=SimpleNamespace(n_components_=m),
        capture=SimpleNamespace(hand_names=("shape",) * n),
    )


def qe_minus_h(low, high):
    return {"a": ["QE", "lstsq"], "b": ["H", "lstsq"], "estimate": (low + high) / 2, "low": low, "high": high}


@pytest.mark.parametrize(
    "interval, verdict",
    [
        ((-0.2, -0.1), "reproduced"),
        ((-0.2, 0.1), "not decided (not distinguishable)"),
        ((0.1, 0.2), "not reproduced (H is better)"),
    ],
)
def test_qe_better_than_h_is_decided_by_the_paired_interval(interval, verdict):
    results = [result("markers m=n", 18, {"H": 0.4, "QE": 0.2, "PCA": 0.1}), result("markers", 13, {})]
    sentence = reproduced_sentence(results, PAPER, {"markers m=n": [qe_minus_h(*interval)]})
    assert sentence == (
        f"The paper's claims, on markers m=n (m = 18, lstsq, alpha_abs_mean): QE better than H: {verdict} (H/QE 2, "
        "paper 7.2); QE close to PCA: QE/PCA 2, paper 1.16 (a point value, no interval: not decided)."
    )


def test_qe_close_to_pca_is_stated_without_a_verdict_and_other_variants_are_left_out():
    close = result("markers m=n", 18, {"H": 0.4, "QE": 0.115, "PCA": 0.1})
    held_out = result("markers held-out tail", 18, {"H": 9, "QE": 9, "PCA": 9}, protocol="held-out tail of each take")
    sentence = reproduced_sentence([close, result("markers", 13, {}), held_out], PAPER, {})
    assert sentence.endswith("QE/PCA 1.15, paper 1.16 (a point value, no interval: not decided).")
    assert "held-out" not in sentence
    assert "QE better than H: not decided" in sentence  # no comparison stored: nothing is claimed
    # without a variant at m = n, the first one scored on its training frames
    assert "on markers (m = 13," in reproduced_sentence([result("markers", 13, {"H": 1, "QE": 1, "PCA": 1})], PAPER, {})


def test_long_lines_are_wrapped_and_tables_are_not():
    text = "  " + " ".join(["word"] * 60) + "\n| " + "x" * 150 + " |"
    lines = fit_width(text).split("\n")
    assert all(len(line) <= PRINT_WIDTH for line in lines[:-1]) and lines[-1] == "| " + "x" * 150 + " |"
    assert lines[0].startswith("  word") and lines[1].startswith("    word") and len(lines) == 4


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
