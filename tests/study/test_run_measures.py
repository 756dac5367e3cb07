"""What a run measures beside alpha: the per-frame error over the face region, the weights' statistics, the
offset of the affine projection, the paired comparisons it records, and the held-out frames beside the training
frames."""

from dataclasses import replace

import numpy as np
import pytest

from workbench.api import run_study
from workbench.core.errors import WorkbenchError
from workbench.dataset.capture import Capture, Timeline
from workbench.numerics.metrics import needs_negative_share, weight_statistics
from workbench.settings.config import compose
from workbench.study.protocols import held_out_capture
from workbench.study.scoring import face_region

SMALL = [
    "dataset.n_frames=600",
    "dataset.mesh_rows=35",
    "dataset.mesh_cols=30",
    "basis.paper_regime=false",
]  # the coverage rule's variants alone (the m = n variant: tests/study/test_regime.py)


@pytest.fixture(scope="module")
def markers_and_mesh():
    return run_study(compose("paper", [*SMALL, "dataset.train_on=[markers,mesh]"]))


def test_error_over_the_face_region_is_the_explicit_error_of_the_vertices_the_muscles_move(markers_and_mesh):
    mesh = next(result for result in markers_and_mesh if result.data == "mesh")
    capture = mesh.capture
    region = face_region(capture)
    moved = np.linalg.norm(capture.hand.reshape(len(capture.hand), -1, 3), axis=2).max(axis=0) > 0
    assert region.points is not None and np.array_equal(region.points, moved) and 0 < moved.sum() < len(moved)
    assert f"the {moved.sum()} of {capture.n_points} mesh vertices some hand shape moves" in mesh.face_region
    dims = np.repeat(moved, 3)
    shapes = {
        "H": capture.hand,
        **{label: mesh.quasi_eigen[p].shapes for label, p in (("QE", "affine"), ("QE-linear", "linear"))},
    }
    for row in mesh.rows:
        if row.basis == "PCA":
            coefficients = (capture.eval - mesh.eigenfaces.mean_) @ mesh.eigenfaces.components_.T
            reconstruction = mesh.eigenfaces.mean_ + coefficients @ mesh.eigenfaces.components_
        else:
            reconstruction = mesh.weights[row.basis, row.solver] @ shapes[row.basis]
        error = (capture.eval - reconstruction)[:, dims].reshape(len(capture.eval), -1, 3)
        expected = np.sqrt((error**2).sum(axis=2).mean(axis=1))
        np.testing.assert_allclose(row.frame_error_mm, expected, rtol=1e-9, atol=1e-12)
        assert row.error_mm.median == pytest.approx(np.median(expected), rel=1e-9)
        assert row.error_mm.max == pytest.approx(expected.max(), rel=1e-9)


def test_markers_region_is_every_marker_and_weights_statistics_are_the_core_s(markers_and_mesh):
    markers = markers_and_mesh[0]
    assert face_region(markers.capture).points is None
    timeline = markers.capture.timeline()
    for row in markers.rows:
        np.testing.assert_allclose(row.frame_error_mm, np.sqrt(row.alpha.error_sq / markers.capture.n_points))
        if row.basis == "PCA":
            assert row.weight_statistics is None
        else:
            core = weight_statistics(markers.weights[row.basis, row.solver], timeline.seconds, timeline.take)
            if row.solver == "lstsq":  # the share of frames whose nnls error exceeds the lstsq error
                nnls = next(other for other in markers.rows if other.basis == row.basis and other.solver == "nnls")
                core = replace(
                    core,
                    needs_negative_share=needs_negative_share(
                        row.alpha.error_sq, nnls.alpha.error_sq, row.alpha.displacement_sq
                    ),
                )
            assert row.weight_statistics == core


def test_offset_share_is_the_squared_error_along_the_mean_s_part_outside_the_span(markers_and_mesh):
    markers = markers_and_mesh[0]
    components, mean = markers.eigenfaces.components_, markers.eigenfaces.mean_
    outside = mean - components.T @ (components @ mean)
    unit = outside / np.linalg.norm(outside)
    frames = markers.capture.eval
    assert markers.offset["norm"] == pytest.approx(np.linalg.norm(outside), rel=1e-12)
    assert markers.offset["ratio"] == pytest.approx(
        np.linalg.norm(outside) / np.median(np.linalg.norm(frames, axis=1)), rel=1e-12
    )
    qe = markers.quasi_eigen["affine"].shapes
    for solver in ("lstsq", "nnls"):
        row = next(row for row in markers.rows if row.basis == "QE" and row.solver == solver)
        residual = frames - markers.weights["QE", solver] @ qe
        expected = np.sum((residual @ unit) ** 2) / np.sum(residual**2)
        assert row.offset_error_share == pytest.approx(expected, rel=1e-8, abs=1e-12)
    # least squares reproduces the offset (each affine shape carries it once; the weights sum to about 1)
    lstsq = next(row for row in markers.rows if row.basis == "QE" and row.solver == "lstsq")
    assert lstsq.offset_error_share < 1e-6


def test_held_out_tail_of_one_take_gives_what_split_tail_gives():
    held = run_study(compose("paper", [*SMALL, "dataset.held_out=tail", "dataset.eval_fraction=0.25"]))
    split = run_study(compose("paper", [*SMALL, "dataset.split=tail", "dataset.eval_fraction=0.25"]))
    assert [result.data for result in held] == ["markers", "markers held-out tail"]
    assert held[0].protocol == "training frames" and held[1].protocol == "held-out tail of each take"
    assert len(held[1].capture.eval) == 150 and held[1].capture.timeline().frame[0] == 450
    for mine, theirs in zip(held[1].rows, split[0].rows):
        assert (mine.basis, mine.solver) == (theirs.basis, theirs.solver)
        assert mine.alpha.absolute_mean == pytest.approx(theirs.alpha.absolute_mean, rel=1e-12)
        assert mine.alpha.displacement_pooled == pytest.approx(theirs.alpha.displacement_pooled, rel=1e-12)
    assert held[1].eigenfaces.n_components_ == split[0].eigenfaces.n_components_


def two_takes() -> Capture:
    frames = (3.0 * np.arange(10))[:, None].repeat(3, axis=1)
    timeline = Timeline(
        take=np.array(["jaw"] * 6 + ["brows"] * 4),
        frame=np.r_[np.arange(6), np.arange(4)],
        seconds=np.r_[np.arange(6), np.arange(4)] / 60.0,
    )
    return Capture(
        name="two takes",
        neutral=np.zeros(3),
        train=frames,
        eval=frames,
        hand=np.ones((1, 3)),
        hand_names=("a",),
        point_labels=("p",),
        units="mm",
        origin="o",
        frame_rate=60.0,
        eval_timeline=timeline,
        notes=("split 'same': 10 training frames, 10 evaluated",),
    )


def test_held_out_frames_of_several_takes():
    capture = two_takes()
    tail = held_out_capture(capture, "tail", 0.25)  # 2 of jaw's 6 frames, 1 of brows' 4
    np.testing.assert_array_equal(tail.eval[:, 0], [12.0, 15.0, 27.0])
    np.testing.assert_array_equal(tail.train[:, 0], [0.0, 3.0, 6.0, 9.0, 18.0, 21.0, 24.0])
    assert list(tail.timeline().take) == ["jaw", "jaw", "brows"]
    assert tail.notes == (
        "held out: the last 25 % of every take, scored with bases fitted on the rest: 7 training frames, 3 evaluated",
    )
    take = held_out_capture(capture, "take", 0.25)
    assert list(take.timeline().take) == ["brows"] * 4 and len(take.train) == 6
    with pytest.raises(WorkbenchError, match="has one take"):
        held_out_capture(replace(capture, eval_timeline=None), "take", 0.25)
    with pytest.raises(WorkbenchError, match="each take needs at least 1 held out and 2 for training"):
        held_out_capture(capture, "tail", 0.05)


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["dataset.held_out=sideways"], "dataset.held_out must be one of"),
        (["dataset.held_out=tail", "dataset.split=tail"], "the run is already held out"),
        (["dataset.held_out=take"], "holds out the last take, and this capture has one take"),
        (["dataset.held_out=tail", "dataset.train_on=markers", "dataset.eval_on=markers"], "dataset.eval_on"),
    ],
)
def test_held_out_settings_are_checked(overrides, message):
    with pytest.raises(WorkbenchError, match=message):
        run_study(compose("paper", ["dataset.n_frames=300", "solver=lstsq", *overrides]))


def test_animface_holds_out_its_last_take(shared_data):
    results = run_study(
        compose(
            "paper",
            [
                "dataset=animface",
                "dataset.frame_step=20",
                "dataset.train_on=markers",
                "dataset.held_out=take",
                "solver=lstsq",
                "basis.paper_regime=false",
                f"paths.data_root={shared_data}",
            ],
        )
    )
    held = results[1]
    assert held.data == "markers held-out take"
    assert set(held.capture.timeline().take) == {"animface_eyebrows"}
    assert len(held.capture.train) + len(held.capture.eval) == len(results[0].capture.eval)
