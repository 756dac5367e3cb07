"""Caveats generated from a record's numbers against stated thresholds: a rigid set the face moves (AnimFace's
forehead markers, about 2 mm in its eyebrows take) and quasi-eigen weights no animator could set (ICT's largest
|w| about 4.79e3); the summary says that caveats exist even when it has no room for them."""

import pytest

from workbench.reporting.findings.caveats import (
    QE_WEIGHT_BOUND,
    STABILISATION_RESIDUAL_MM,
    stabilisation_caveat,
    weights_caveat,
)
from workbench.reporting.findings.run import caveat_texts
from workbench.reporting.findings.run_summary import caveat_sentence

RIGID = ["ForeHead_M", "ForeHead_L", "ForeHead_R", "NoseTop", "Leye_Inside", "Reye_Inside"]


def animface_metrics(residuals):
    """The part of an AnimFace record the caveat reads: its rigid set and each take's stabilisation residual."""
    per_take = {
        f"animface_{take}.c3d": {"noise_floor_mm": {"stabilisation_residual_rms": value, "marker_jitter_rms": 0.03}}
        for take, value in residuals.items()
    }
    return {"dataset": {"provenance": {"kind": "animface", "rigid_markers": RIGID, "per_take": per_take}}}


def qe_rows(largest):
    return [
        {"data": "mesh m=n", "basis": "QE", "solver": "lstsq", "w_max_abs": largest},
        {"data": "mesh m=n", "basis": "QE", "solver": "box", "w_max_abs": 1.0},
        {"data": "mesh m=n", "basis": "H", "solver": "lstsq", "w_max_abs": 1.63},
        {"data": "mesh", "basis": "QE", "solver": "lstsq", "w_max_abs": 33.6},
    ]


def test_a_rigid_set_the_face_moves_is_a_caveat_above_its_threshold():
    metrics = animface_metrics({"jaw": 0.52, "cheeks": 1.19, "eyebrows": 2.35})
    text = stabilisation_caveat(metrics)
    assert text.startswith("the rigid set that removes head motion (ForeHead_M, ForeHead_L, ForeHead_R, NoseTop")
    assert f"more than {STABILISATION_RESIDUAL_MM:g} mm RMS" in text
    assert "animface_cheeks (1.19 mm) and animface_eyebrows (2.35 mm)" in text and "jaw" not in text
    assert "its forehead markers moving with the brows" in text and "the hand shapes H cannot" in text
    assert text in caveat_texts(metrics)
    # within the threshold in every take, or no stabilisation at all: no caveat
    assert stabilisation_caveat(animface_metrics({"jaw": 0.52, "cheeks": 0.9})) == ""
    assert stabilisation_caveat({"dataset": {"provenance": {"kind": "synthetic"}}}) == ""


def test_quasi_eigen_weights_no_animator_could_set_are_a_caveat_above_the_bound():
    text = weights_caveat({"rows": qe_rows(4794.88)})
    assert text == (
        "QE's least-squares weights are unusable for an animator: largest |w| 4.79e+03 on mesh m=n, beyond "
        f"{QE_WEIGHT_BOUND:g} full contractions of a shape; its accuracy rests on shapes that cancel each other"
    )
    # the largest over the variants with least squares; a box's bounded weights and H's do not count
    assert "largest |w| 33.6 on mesh," in weights_caveat({"rows": qe_rows(2.0)})
    within = [dict(row, w_max_abs=min(row["w_max_abs"], QE_WEIGHT_BOUND)) for row in qe_rows(2.0)]
    assert weights_caveat({"rows": within}) == ""
    assert weights_caveat({"rows": [dict(row, w_max_abs=float("nan")) for row in qe_rows(1.0)]}) == ""


def test_the_summary_says_caveats_exist_when_it_states_only_the_first_or_none():
    caveats = ["the capture is a blend", "QE's weights are unusable", "scored on the training frames"]
    assert caveat_sentence(caveats, caveats[0]) == "Caveat: the capture is a blend. 2 more caveats in the findings."
    assert caveat_sentence(caveats[:2], "the capture") == "Caveat: the capture. 1 more caveat in the findings."
    assert caveat_sentence(caveats, "") == "3 caveats in the findings."
    assert caveat_sentence(caveats[:1], caveats[0]) == "Caveat: the capture is a blend."
    assert caveat_sentence([], "") == ""


@pytest.mark.slow
def test_the_animface_record_shows_its_rigid_set_moving_and_its_report_says_so(shared_data, tmp_path):
    """On the real AnimFace takes (every 20th frame, least squares) the record's own stabilisation residuals put the
    caveat into the findings, and the summary says how many caveats the findings hold."""
    from workbench.api import run
    from workbench.record.record import load_record
    from workbench.reporting.findings.run_summary import SUMMARY_WORDS, run_summary
    from workbench.settings.config import compose
    from workbench.study.summary import headline_column

    folder = tmp_path / "run"
    overrides = ["dataset=animface", f"paths.data_root={shared_data}", "dataset.frame_step=20", "solver=lstsq"]
    run(compose("paper", overrides), folder)
    record = load_record(folder)
    caveats = caveat_texts(record.metrics)
    moving = next(text for text in caveats if text.startswith("the rigid set that removes head motion"))
    assert "ForeHead_M" in moving and "animface_eyebrows (" in moving, moving
    summary = run_summary(record.table, headline_column(record.config), record.metrics, record.config["solver"])
    assert len(summary.split()) <= SUMMARY_WORDS
    assert f"{len(caveats) - 1} more caveats in the findings." in summary or f"{len(caveats)} caveats" in summary
