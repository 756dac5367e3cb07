"""What a run prints first: one sentence on the paper's two claims as the run stored them, and text that fits in 120
columns unless ``--wide`` is asked for."""

import pytest
from in_process import run_workbench

from workbench.reporting.text.run import PRINT_WIDTH, fit_width, reproduced_sentence
from workbench.stats.statistics import Interval
from workbench.study.claims import CLAIM_MARGIN, claim_entry

RESTS = {"unit": "frames", "frames": 900, "takes": 1, "batch_frames": 90, "batches": 10, "folds": 0, "persistence": 0.9}


def entry(data, protocol, h_over_qe, qe_over_pca, construction=""):
    def stored(name, bounds):
        interval = Interval(sum(bounds) / 2, *bounds, n=900, null=1.0, degrees=12.0)
        return claim_entry(name, interval, RESTS, "alpha_abs_mean", CLAIM_MARGIN, construction)

    return {
        "data": data,
        "base": "markers",
        "protocol": protocol,
        "protocol_text": {"training": "training frames", "tail": "held-out tail of each take"}[protocol],
        "m": [18],
        "n": 18,
        "H/QE": stored("H/QE", h_over_qe),
        "QE/PCA": stored("QE/PCA", qe_over_pca),
    }


def claims(*entries):
    return {"column": "alpha_abs_mean", "solver": "lstsq", "margin": CLAIM_MARGIN, "entries": list(entries)}


@pytest.mark.parametrize(
    "h_over_qe, first, qe_over_pca, second",
    [
        (
            (1.5, 2.5),
            "reproduced, H/QE 2.00 [1.50, 2.50] above 1; the paper's 7.2 lies above",
            (1.0, 1.1),
            "reproduced",
        ),
        (
            (0.9, 3.1),
            "not decided, H/QE 2.00 [0.900, 3.10] holds 1; the paper's 7.2 lies above",
            (1.1, 1.6),
            "not decided",
        ),
        (
            (0.5, 0.9),
            "reversed, H/QE 0.700 [0.500, 0.900] below 1; the paper's 7.2 lies above",
            (1.6, 1.8),
            "not reproduced",
        ),
        (
            (5.0, 9.0),
            "reproduced, H/QE 7.00 [5.00, 9.00] above 1; the paper's 7.2 lies inside",
            (1.2, 1.4),
            "reproduced",
        ),
    ],
)
def test_the_first_sentence_states_the_stored_verdicts(h_over_qe, first, qe_over_pca, second):
    sentence = reproduced_sentence(claims(entry("markers m=n", "training", h_over_qe, qe_over_pca)))
    assert sentence.startswith(
        f"The paper's claims at m = n (lstsq, alpha_abs_mean), on markers m=n (m = 18): QE better than H: {first} "
        f"the interval; QE nearly as accurate as PCA (QE/PCA <= 1.5): {second}, QE/PCA "
    )


def test_qe_within_pca_by_construction_is_not_tested_and_held_out_protocols_follow():
    spans = "QE <= PCA holds by construction (rank m + 1)"
    found = claims(
        entry("markers m=n", "training", (1.5, 2.5), (0.9, 0.95), spans),
        entry("markers held-out tail m=n", "tail", (0.8, 1.3), (1.0, 1.2)),
    )
    sentence = reproduced_sentence(found)
    assert f"QE nearly as accurate as PCA: not tested at m = n: {spans}" in sentence
    assert sentence.endswith(
        "held-out tail of each take (m = 18): H/QE 1.05 [0.800, 1.30] not decided, QE/PCA 1.10 [1.00, 1.20] reproduced."
    )
    assert reproduced_sentence(None) == ""


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
    assert lines[0].startswith(
        "The paper's claims at m = n (lstsq, alpha_abs_mean), on markers m=n (m = 18): QE better "
    )
    assert max(len(line) for line in lines[:-1]) <= PRINT_WIDTH  # all but the record's path
    assert "| markers m=n | QE        | lstsq      | 18 |" in narrow.stdout and "err_mm_median" not in narrow.stdout
    wide = run_workbench(*arguments, "hydra.run.dir=wide", "--wide", cwd=tmp_path)
    assert wide.returncode == 0, wide.stderr
    full = (tmp_path / "wide" / "alpha_table.md").read_text()
    assert wide.stdout == f"{full}\nrecord: {tmp_path / 'wide'}\n" and "| err_mm_median |" in full
    assert max(len(line) for line in full.splitlines()) > PRINT_WIDTH
    assert full.splitlines()[0] == lines[0] and (tmp_path / "narrow" / "alpha_table.md").read_text() == full
