"""The default study's report (``workbench`` with no arguments: the synthetic actor, trained on markers only) draws
every figure: its faces are the markers carried onto the actor's mesh by the RBF map, as the paper showed them."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.reporting.report.command import main

# the default study at a small size (a coarse mesh draws faster): markers only, no save_inputs
DEFAULT_SMALL = ["dataset.n_frames=1000", "dataset.mesh_rows=35", "dataset.mesh_cols=30"]


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    from workbench.api import run
    from workbench.settings.config import compose

    record = tmp_path_factory.mktemp("default") / "run"
    cfg = compose(overrides=DEFAULT_SMALL)
    assert cfg.dataset.train_on == "markers" and cfg.dataset.eval_on is None  # the default has no mesh variant
    run(cfg, record)
    return record


@pytest.mark.slow
def test_the_default_runs_report_has_no_placeholder(default_run, tmp_path):
    out = tmp_path / "report"
    assert main([str(default_run), "--out", str(out)]) == 0
    page, readme = (out / "index.html").read_text(), (out / "README.md").read_text()
    assert "not drawn" not in page.lower() and "not drawn" not in readme.lower()
    assert 'class="missing"' not in page
    stems = {path.stem for path in (out / "figures").iterdir()}
    for name in (
        "fig2_hand_vs_quasi_eigen",
        "fig3_reconstructions",
        "fig4_marker_errors",
        "vertex_rms",
        "animation",
        "view3d",
    ):
        assert name in stems, name
    # marker versus mesh is no figure of a run on one data variant: left out, not a placeholder
    assert "marker_vs_mesh" not in stems and "Marker versus mesh" not in page
    # every carried face says so, once per figure 2, 3, the per-vertex RMS, the animation and the 3-D view
    note = "arkers carried onto the mesh by RBF (as in the paper); the run has no mesh data variant"
    assert readme.count(note) >= 3 and page.count(note) >= 5


def captured_arguments(monkeypatch, name):
    """Replace a figure function of :mod:`workbench.reporting.figures.faces` by one that keeps its arguments."""
    seen = {}

    def keep(*args, **kwargs):
        seen.update(args=args, kwargs=kwargs)
        return "figure"

    monkeypatch.setattr(f"workbench.reporting.figures.faces.{name}", keep)
    return seen


@pytest.fixture(scope="module")
def carried(default_run):
    from workbench.record.record import load_record
    from workbench.reporting.report.data import face_data

    record, cache = load_record(default_run), {}
    face = face_data(record, cache)
    assert (
        not isinstance(face, str) and face.carried and face.data == "markers m=n"
    )  # figures draw the paper's regime first
    return record, cache, face


def marker_rows(face) -> np.ndarray:
    """The mesh vertices the markers sit on (the synthetic markers are mesh vertices)."""
    from scipy.spatial import cKDTree

    distance, vertex = cKDTree(face.neutral.reshape(-1, 3)).query(face.inputs["neutral"].reshape(-1, 3))
    assert distance.max() < 1e-9
    return vertex


def test_the_carried_map_is_the_datasets_marker_to_mesh_rbf(carried):
    from workbench.dataset.rbf import mesh_rbf_operator

    _, _, face = carried
    assert face.transfer.method == "rbf"
    vertices = face.neutral.reshape(-1, 3)
    # the map the mesh_rbf data variant interpolates the markers with (thin-plate spline, linear polynomial)
    expected = mesh_rbf_operator(vertices, face.faces, marker_rows(face), np.arange(len(vertices)))
    np.testing.assert_allclose(face.transfer.operator, expected, rtol=0, atol=1e-10)


def test_figure_3_carries_the_markers_reconstruction_and_does_not_solve_on_the_mesh(carried, monkeypatch):
    from workbench.reporting.report.data import figure3_frames, figure_bases, figure_solver, reconstruct_frames
    from workbench.reporting.report.run_figures import draw_reconstructions

    record, cache, face = carried
    seen = captured_arguments(monkeypatch, "figure_reconstructions")
    assert draw_reconstructions(record, cache)[0] == "figure"
    neutral, triangles, captured, reconstructed = seen["args"][:4]
    np.testing.assert_array_equal(neutral, face.neutral)
    np.testing.assert_array_equal(triangles, face.faces)
    frames = [frame for _, frame in figure3_frames(record, face.inputs)]
    markers = face.inputs["eval"][frames]
    operator = face.transfer.operator

    def by_hand(fields):  # T @ each field's (n_markers, 3) block
        return np.stack([(operator @ field.reshape(-1, 3)).reshape(-1) for field in fields])

    np.testing.assert_allclose(captured, by_hand(markers), rtol=0, atol=1e-10)
    _, solver = figure_solver(record.config)
    for name, shapes in figure_bases(record, face.data, face.inputs, cache).items():
        on_markers = reconstruct_frames(shapes, markers, solver)
        np.testing.assert_allclose(reconstructed[name], by_hand(on_markers), rtol=0, atol=1e-10)
        # the RBF interpolates its centres: at the markers' vertices the carried reconstruction is the markers'
        at_markers = reconstructed[name].reshape(len(frames), -1, 3)[:, marker_rows(face)]
        np.testing.assert_allclose(at_markers, on_markers.reshape(len(frames), -1, 3), rtol=0, atol=1e-8)
    assert "markers' own" in seen["kwargs"]["title"] and "alpha" in seen["kwargs"]["title"]


def test_figure_2_hand_shapes_carried_onto_the_mesh_keep_their_marker_displacements(carried, monkeypatch):
    from workbench.reporting.report.run_figures import draw_hand_vs_quasi_eigen

    record, cache, face = carried
    seen = captured_arguments(monkeypatch, "figure_hand_vs_quasi_eigen")
    figure, caption = draw_hand_vs_quasi_eigen(record, ["jaw_open", "zygomatic_major_L"], cache)
    assert figure == "figure" and "weights are solved on the markers" in caption
    hand_on_mesh, names = seen["args"][2], seen["args"][4]
    assert names == ["jaw_open", "zygomatic_major_L"]
    own = [list(face.inputs["hand_names"]).index(name) for name in names]
    hand_on_markers = face.inputs["hand"][own].reshape(len(own), -1, 3)
    at_markers = hand_on_mesh.reshape(len(own), -1, 3)[:, marker_rows(face)]
    # the RBF interpolates its centres (smoothing 0): exact at the markers up to the solve's rounding
    np.testing.assert_allclose(at_markers, hand_on_markers, rtol=0, atol=1e-8 * np.abs(hand_on_markers).max())
    # between the markers it moves the face too: the jaw shape moves vertices no marker sits on
    moved = np.linalg.norm(hand_on_mesh[0].reshape(-1, 3), axis=1) > 1.0
    moved[marker_rows(face)] = False
    assert moved.sum() > 50


def test_frames_missing_a_marker_are_not_picked_for_the_faces():
    from workbench.dataset.capture import Timeline
    from workbench.reporting.report.data import moving_stretch, seen_frames

    frames = np.zeros((6, 6))
    frames[2] = 5.0  # the most displaced frame, but it missed a marker (gap_policy=masked)
    frames[2, 0] = np.nan
    frames[4] = 1.0
    picked = seen_frames(frames)
    assert int(np.argmax(np.abs(picked).sum(axis=1))) == 4 and np.isfinite(picked).all()
    np.testing.assert_array_equal(seen_frames(frames[[0, 1, 4]]), frames[[0, 1, 4]])  # all seen: unchanged
    # the stretch where the face moves most, counted without the frame that missed a marker
    stretch = moving_stretch({"eval": frames}, Timeline.uniform("take", np.arange(6), 1.0), 2)
    np.testing.assert_array_equal(stretch, [3, 4])


@pytest.mark.parametrize("name, step", [("ict_livelink", 40), ("animface", 20)])
def test_the_real_datasets_give_the_face_mesh_their_markers_are_carried_onto(shared_data, name, step):
    from scipy.spatial import cKDTree

    from workbench.dataset import build_captures
    from workbench.dataset.rest_mesh import rest_mesh
    from workbench.dataset.transfer import point_transfer
    from workbench.settings.config import compose, resolved_without_hydra

    cfg = resolved_without_hydra(
        compose(
            "paper",
            [
                f"dataset={name}",
                f"paths.data_root={shared_data}",
                "dataset.train_on=markers",
                f"dataset.frame_step={step}",
            ],
        )
    )
    markers = build_captures(cfg["dataset"])["markers"]
    from workbench.settings.typed import dataset_settings

    mesh = rest_mesh(dataset_settings(cfg["dataset"]), markers.provenance)
    distance, vertex = cKDTree(mesh.vertices).query(markers.neutral.reshape(-1, 3))
    # ICT's virtual markers are vertices of its face; AnimFace's performer's markers lie near the placed face
    assert distance.max() < (1e-9 if name == "ict_livelink" else 10.0)
    assert mesh.support[vertex].all() and 0.3 < mesh.support.mean() < 1.0  # the markers' reach, not the neck
    assert mesh.triangles.max() < len(mesh.vertices)
    transfer = point_transfer(markers.neutral.reshape(-1, 3), mesh.vertices)
    assert transfer.method == "rbf"
    if name == "ict_livelink":  # the RBF interpolates its centres: a hand shape keeps its marker displacements
        carried = transfer.apply(markers.hand[:3]).reshape(3, -1, 3)[:, vertex]
        on_markers = markers.hand[:3].reshape(3, -1, 3)
        np.testing.assert_allclose(carried, on_markers, rtol=0, atol=1e-8 * np.abs(on_markers).max())
