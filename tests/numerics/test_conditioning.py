"""Ill-conditioned bases are reported: condition number, rank, zero and near-duplicate shapes, and a warning above
the alpha table when the hand basis is affected."""

import numpy as np
import pytest

from workbench.api import run_study
from workbench.numerics.metrics import basis_conditioning
from workbench.reporting.text.run import conditioning_lines, study_header
from workbench.settings.config import compose, resolved_without_hydra


def test_conditioning_known_values():
    orthogonal = np.eye(4, 12) * np.array([[3.0], [3.0], [3.0], [3.0]])
    report = basis_conditioning(orthogonal)
    assert report.condition_number == pytest.approx(1.0) and report.rank == 4
    assert report.zero_shapes == () and report.near_duplicates == ()

    scaled = np.eye(3, 9) * np.array([[1.0], [10.0], [100.0]])
    assert basis_conditioning(scaled).condition_number == pytest.approx(100.0)

    rng = np.random.default_rng(0)
    shapes = rng.standard_normal((5, 30))
    shapes[3] = -2.0 * shapes[1] + 1e-9 * rng.standard_normal(30)  # an (anti-)parallel near copy
    shapes[4] = 0.0
    report = basis_conditioning(shapes)
    assert report.zero_shapes == (4,) and report.rank == 4 and report.condition_number == np.inf
    assert [(i, j) for i, j, _ in report.near_duplicates] == [(1, 3)]
    assert report.near_duplicates[0][2] == pytest.approx(-1.0)


def test_hand_basis_with_a_duplicate_shape_gets_a_warning_above_the_table():
    cfg = resolved_without_hydra(compose("paper", ["dataset.n_frames=400", "dataset.train_on=markers", "solver=lstsq"]))
    results = run_study(cfg)
    lines = conditioning_lines(results[0].rows)
    assert lines[0].startswith("  bases: H condition number ") and "; QE " in lines[0]
    assert not any("WARNING" in line for line in lines)

    # the same run with one hand shape duplicated
    from dataclasses import replace

    from workbench.study.results import Timings
    from workbench.study.run import run_on_capture

    capture = results[0].capture
    # an exact copy is refused as input (see test_bad_input); a near copy is legal, and reported
    rng = np.random.default_rng(1)
    noise = rng.standard_normal(capture.hand.shape[1])
    near_copy = capture.hand[0] + 0.01 * np.linalg.norm(capture.hand[0]) * noise / np.linalg.norm(noise)
    duplicated = replace(
        capture,
        hand=np.vstack([capture.hand, near_copy]),
        hand_names=capture.hand_names + (capture.hand_names[0] + "_copy",),
    )
    solvers = {"lstsq": {"kind": "lstsq", "lower": None, "upper": None}}
    from workbench.settings.typed import study_settings

    result = run_on_capture("markers", duplicated, study_settings(cfg).basis, solvers, Timings())
    header = study_header([result], study_settings(cfg))
    assert "WARNING: basis H is ill-conditioned: near-duplicate shapes 0~18 (cos 1.0000)" in header
    assert "H condition number" in header and "largest |w|" in header
