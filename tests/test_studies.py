"""The studies: the options they sweep (hand subsets, cross-evaluation, decimation, gaps, other takes) and each
study's small preset run end to end through the command line."""

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from workbench.config import REPO_ROOT, STUDIES_DIR, compose
from workbench.dataset import build_captures
from workbench.dataset.decimate import decimate
from workbench.dataset.gaps import apply_gap_policy, longest_run, make_gap_mask
from workbench.dataset.synthetic import LOWER_FACE, MUSCLE_NAMES, UPPER_FACE, make_face_mesh, make_synthetic_take
from workbench.dataset.transfer import point_transfer
from workbench.errors import WorkbenchError
from workbench.pipeline import hand_subset_indices, run_study
from workbench.cli import resolved_without_hydra

STUDIES = ("coverage", "basis_count", "marker_mesh", "noise", "choices", "generalisation")


def plain_config(study="paper", overrides=()):
    return resolved_without_hydra(compose(study, list(overrides)))


# --- options the studies sweep -------------------------------------------------------------------------------

def test_hand_subsets():
    assert [MUSCLE_NAMES[i] for i in hand_subset_indices(MUSCLE_NAMES, "upper", 0)] == list(UPPER_FACE)
    assert [MUSCLE_NAMES[i] for i in hand_subset_indices(MUSCLE_NAMES, "lower", 0)] == list(LOWER_FACE)
    assert len(UPPER_FACE) == 6 and len(LOWER_FACE) == 12
    assert hand_subset_indices(MUSCLE_NAMES, "all", 0).tolist() == list(range(18))
    drawn = hand_subset_indices(MUSCLE_NAMES, "random6", 3)
    assert drawn.size == 6 and np.all(np.diff(drawn) > 0)
    assert drawn.tolist() == hand_subset_indices(MUSCLE_NAMES, "random6", 3).tolist()
    assert drawn.tolist() != hand_subset_indices(MUSCLE_NAMES, "random6", 4).tolist()
    assert hand_subset_indices(MUSCLE_NAMES, ["jaw_open", "mentalis"], 0).tolist() == [15, 17]
    for spec, message in (("random0", "1 <= k <= 18"), ("middle", "all, upper, lower, random<k>"),
                          (["nose"], "distinct hand shapes")):
        with pytest.raises(WorkbenchError, match=message):
            hand_subset_indices(MUSCLE_NAMES, spec, 0)


def test_gap_mask_rate_length_and_seed():
    mask = make_gap_mask(20000, 20, 0.05, 12.0, np.random.default_rng(0))
    assert mask.mean() == pytest.approx(0.05, abs=0.01)
    starts = np.sum(mask[1:] & ~mask[:-1]) + np.sum(mask[0])
    assert mask.sum() / starts == pytest.approx(12.0, rel=0.15)  # mean gap length
    assert np.array_equal(mask, make_gap_mask(20000, 20, 0.05, 12.0, np.random.default_rng(0)))
    assert not make_gap_mask(100, 3, 0.0, 12.0, np.random.default_rng(0)).any()
    with pytest.raises(WorkbenchError, match="gap_rate must be in"):
        make_gap_mask(10, 2, 1.0, 12.0, np.random.default_rng(0))


def test_linear_gap_filling():
    frames = np.arange(10, dtype=float)
    positions = np.stack([np.stack([2 * frames, -frames, frames ** 2], axis=1)] * 2, axis=1)  # (10, 2, 3)
    holed = positions.copy()
    holed[3:6, 0] = np.nan  # inside: linear interpolation is exact for the linear coordinates
    holed[:2, 1] = np.nan  # at the start: the first sample is held
    outcome = apply_gap_policy(holed, "linear")
    filled, report = outcome.positions, outcome.report
    np.testing.assert_allclose(filled[:, 0, :2], positions[:, 0, :2])
    np.testing.assert_allclose(filled[3:6, 0, 2], np.interp([3, 4, 5], [2, 6], [4, 36]))
    np.testing.assert_allclose(filled[:2, 1], np.repeat(positions[2:3, 1], 2, axis=0))
    assert (report.n_missing_samples, report.longest_gap_frames) == (5, 3)
    assert longest_run(np.isnan(holed[:, :, 0])) == 3
    holed[:, 1] = np.nan
    with pytest.raises(WorkbenchError, match="missing in every frame"):
        apply_gap_policy(holed, "linear")


def test_decimation_keeps_original_vertices():
    mesh = make_face_mesh(40, 30)
    full = decimate(mesh.vertices, mesh.faces, 1.0)
    assert full.kept.tolist() == list(range(mesh.n_vertices))
    quarter = decimate(mesh.vertices, mesh.faces, 0.25)
    assert quarter.kept.size == pytest.approx(0.25 * mesh.n_vertices, rel=0.1)
    assert np.all(np.diff(quarter.kept) > 0)
    assert quarter.faces.min() == 0 and quarter.faces.max() == quarter.kept.size - 1
    with pytest.raises(WorkbenchError, match="mesh_fraction must be in"):
        decimate(mesh.vertices, mesh.faces, 0.0)


def test_point_transfers():
    rng = np.random.default_rng(0)
    mesh = rng.normal(size=(600, 3)) * 50
    markers = mesh[[5, 50, 300, 7, 120, 9, 44, 210, 333, 500]]
    assert point_transfer(mesh, mesh).method == "identity"
    selection = point_transfer(mesh, markers)
    assert selection.method == "coincident"
    fields = rng.normal(size=(4, 600 * 3))
    np.testing.assert_array_equal(selection.apply(fields), fields.reshape(4, 600, 3)[:, [5, 50, 300, 7, 120, 9, 44,
                                                                                           210, 333, 500]].reshape(4, -1))
    rbf = point_transfer(markers, mesh)
    assert rbf.method == "rbf"
    affine = np.array([[1.0, 2.0, -1.0], [0.5, 0.0, 3.0], [0.0, 1.0, 1.0]])  # a thin-plate spline with a linear
    np.testing.assert_allclose(rbf.apply_one((markers @ affine.T).reshape(-1)),  # tail reproduces affine fields
                               (mesh @ affine.T).reshape(-1), atol=1e-6)
    nearest = point_transfer(mesh, markers + 0.5)
    assert nearest.method == "nearest" and nearest.max_distance == pytest.approx(np.sqrt(3) * 0.5)


def test_mesh_frames_at_kept_vertices_are_rows_of_the_full_mesh():
    cfg = plain_config(overrides=["dataset.n_frames=120", "dataset.train_on=mesh", "dataset.mesh_fraction=0.1"])
    capture = build_captures(cfg["dataset"])["mesh"]
    take = make_synthetic_take(n_frames=120)
    kept = decimate(take.mesh.vertices, take.mesh.faces, 0.1).kept
    full = take.mesh_sequence() - take.mesh.vertices
    np.testing.assert_allclose(capture.train, full[:, kept].reshape(120, -1), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(capture.hand, (take.hand_shapes_mesh()[:, kept]).reshape(18, -1))
    assert capture.faces.max() == kept.size - 1 and "decimated to" in capture.notes[0]


def test_dropout_and_other_take_in_the_dataset():
    cfg = plain_config(overrides=["dataset.n_frames=1200", "dataset.gap_rate=0.05", "dataset.split=other_take",
                                  "dataset.train_on=[markers,mesh_rbf]"])
    captures = build_captures(cfg["dataset"])
    markers, interpolated = captures["markers"], captures["mesh_rbf"]
    gaps = markers.provenance["gaps"]
    assert gaps["policy"] == "linear" and 0.02 < gaps["missing_fraction"] < 0.08
    assert any("marker dropout" in note for note in markers.notes)
    assert markers.provenance["eval_seed"] == 1 and not np.array_equal(markers.train, markers.eval)
    assert interpolated.n_points == 4200 and np.all(np.isfinite(interpolated.train))
    # the RBF interpolates: at the marker vertices the mesh_rbf frames are the marker frames
    take = make_synthetic_take(n_frames=10)
    at_markers = interpolated.train.reshape(1200, 4200, 3)[:, take.face_marker_vertices]
    np.testing.assert_allclose(at_markers.reshape(1200, -1), markers.train, atol=1e-6)


def test_cross_evaluation_of_data_variants():
    base = ["dataset.n_frames=300", "solver=lstsq", "dataset.train_on=[markers,mesh]"]
    results = run_study(plain_config(overrides=base + ["dataset.eval_on=[markers,mesh]"]))
    assert [result.data for result in results] == ["markers->markers", "markers->mesh", "mesh->markers",
                                                    "mesh->mesh"]
    assert [result.transfer for result in results] == ["identity", "rbf", "coincident", "identity"]
    assert [result.capture.n_points for result in results] == [66, 4200, 66, 4200]
    same = {result.data: result for result in run_study(plain_config(overrides=base))}
    for cross, own in (("markers->markers", "markers"), ("mesh->mesh", "mesh")):
        crossed = {(row.basis, row.solver): row.alpha.absolute_mean for row in results[
            [result.data for result in results].index(cross)].rows}
        assert crossed == {(row.basis, row.solver): row.alpha.absolute_mean for row in same[own].rows}
    # a basis fitted on the mesh and carried to the markers (vertex selection) scores its own restriction
    mesh_to_markers = results[2]
    assert mesh_to_markers.eigenfaces.mean_.size == 3 * 4200
    assert mesh_to_markers.quasi_eigen["affine"].shapes.shape == (18, 3 * 66)


def test_eval_on_needs_train_on():
    with pytest.raises(WorkbenchError, match="eval_on must be"):
        run_study(plain_config(overrides=["dataset.n_frames=100", "dataset.eval_on=[]"]))


@pytest.mark.parametrize("study", STUDIES)
def test_study_and_preset_compose(study):
    full, small = compose(study), compose(f"{study}_small")
    assert (full.study, small.study) == (study, f"{study}_small")
    assert full.hydra.mode.name == "MULTIRUN" and full.hydra.output_subdir is None
    assert str(full.hydra.sweep.dir) == f"outputs/{study}/default"
    assert set(small.hydra.sweeper.params) <= set(full.hydra.sweeper.params)
    assert (STUDIES_DIR / f"{study}.yaml").read_text().startswith("# ")


def test_cluster_launcher_config_composes():
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    cfg = compose("coverage", ["hydra/launcher=slurm"])
    assert cfg.hydra.launcher._target_.endswith("SlurmLauncher")
    assert cfg.hydra.launcher.cpus_per_task == 2 and cfg.hydra.launcher.timeout_min == 60


# --- every study's small preset, end to end through the command line -------------------------------------------

def run_preset(study, tmp_path):
    sweep = tmp_path / study
    result = subprocess.run([sys.executable, "-m", "workbench", "--config-name", f"{study}_small",
                             f"hydra.sweep.dir={sweep}"], capture_output=True, text=True, cwd=tmp_path, timeout=600,
                            env=dict(os.environ, PYTHONPATH=str(REPO_ROOT)))
    assert result.returncode == 0, result.stderr[-3000:]
    collected = sweep / "collected"
    for name in ("runs.csv", "runs.parquet", "summary.csv", "summary.parquet", "alpha_table.md", "alpha_table.tex"):
        assert (collected / name).is_file(), name
    runs = pd.read_parquet(collected / "runs.parquet")
    assert runs.groupby("run").ngroups == sum(1 for _ in sweep.glob("*/done"))
    return sweep, runs, result.stdout


def lstsq_alpha(runs, basis, **conditions):
    keep = (runs["basis"] == basis) & runs["solver"].isin(["lstsq", "projection"])
    for key, value in conditions.items():
        keep &= runs[key] == value
    return runs.loc[keep, "alpha_abs_mean"]


def test_coverage_preset(tmp_path):
    sweep, runs, stdout = run_preset("coverage", tmp_path)
    assert runs.groupby("run").ngroups == 4 and "| basis.coverage |" in stdout
    m = runs[runs["basis"] == "PCA"].set_index(["dataset.seed", "basis.coverage"])["m"]
    for seed in (0, 1):
        assert m[(seed, 0.95)] < m[(seed, 0.995)]
    assert (lstsq_alpha(runs, "PCA", **{"basis.coverage": 0.995}).to_numpy()
            < lstsq_alpha(runs, "PCA", **{"basis.coverage": 0.95}).to_numpy()).all()


def test_basis_count_preset(tmp_path):
    sweep, runs, _ = run_preset("basis_count", tmp_path)
    assert runs.groupby("run").ngroups == 12
    h = runs[runs["basis"] == "H"].set_index(["basis.hand_subset", "dataset.seed", "basis.append_empty_axes"])["n"]
    assert h[("upper", 0, False)] == 6 and h[("random6", 1, True)] == 6 and h[("all", 0, False)] == 18
    drawn = {}
    for path in sweep.glob("*/metrics.json"):
        metrics = json.loads(path.read_text())
        if {"basis.hand_subset=random6", "basis.append_empty_axes=False"} <= set(metrics["overrides"]):
            drawn[metrics["dataset"]["provenance"]["seed"]] = tuple(metrics["dataset"]["hand_names"])
    assert sorted(drawn) == [0, 1] and drawn[0] != drawn[1]  # a new draw per seed
    upper = lstsq_alpha(runs, "QE", **{"basis.hand_subset": "upper", "basis.append_empty_axes": False})
    full = lstsq_alpha(runs, "QE", **{"basis.hand_subset": "all", "basis.append_empty_axes": False})
    assert upper.mean() > full.mean()


def test_marker_mesh_preset(tmp_path):
    sweep, runs, stdout = run_preset("marker_mesh", tmp_path)
    assert runs.groupby("run").ngroups == 8
    assert set(runs["data"]) == {"markers->markers", "markers->mesh", "mesh->markers", "mesh->mesh"}
    points = runs.drop_duplicates(["dataset.mesh_fraction", "eval_on"]).set_index(
        ["dataset.mesh_fraction", "eval_on"])["n_points"]
    assert points[(1.0, "mesh")] == 4200 and points[(1.0, "markers")] == 66
    assert 900 < points[(0.25, "mesh")] < 1200
    # fitted on the dense mesh and scored there, the quasi-eigen faces beat the hand shapes
    assert (lstsq_alpha(runs, "QE", data="mesh->mesh").to_numpy()
            < lstsq_alpha(runs, "H", data="mesh->mesh").to_numpy()).all()
    assert "n_points" in stdout and "time_total" in stdout


def test_noise_preset(tmp_path):
    sweep, runs, _ = run_preset("noise", tmp_path)
    assert runs.groupby("run").ngroups == 8
    m = runs[runs["basis"] == "PCA"].groupby("dataset.marker_noise_mm")["m"].mean()
    assert m[0.5] > 3 * m[0.0]  # the coverage rule keeps axes until the noise is covered
    gapped = next(sweep.glob("*gap_rate=0.05*/metrics.json"))
    gaps = json.loads(gapped.read_text())["dataset"]["provenance"]["gaps"]
    assert gaps["policy"] == "linear" and gaps["n_missing_samples"] > 0


def test_choices_preset(tmp_path):
    sweep, runs, stdout = run_preset("choices", tmp_path)
    assert runs.groupby("run").ngroups == 2
    assert set(runs["solver"]) == {"lstsq", "nnls", "box", "projection"}
    assert set(runs["projection"]) == {"-", "affine", "linear"}
    header = next(line for line in stdout.splitlines() if line.startswith("| basis"))
    assert [cell.strip() for cell in header.strip("|").split("|")] == [
        "basis", "solver", "m", "alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled"]


def test_generalisation_preset(tmp_path):
    sweep, runs, stdout = run_preset("generalisation", tmp_path)
    assert runs.groupby("run").ngroups == 6
    frames = runs.drop_duplicates("dataset.split").set_index("dataset.split")[["n_train_frames", "n_eval_frames"]]
    assert frames.loc["same"].tolist() == [1500, 1500] and frames.loc["tail"].tolist() == [750, 750]
    assert frames.loc["other_take"].tolist() == [1500, 1500]
    rows = [line.split("|")[1].strip() for line in stdout.splitlines() if line.startswith("| ")][1:]
    assert rows == ["same", "tail", "other_take"]  # the study's order, not the alphabet's
    held_out = lstsq_alpha(runs, "QE", **{"dataset.split": "other_take"}).mean()
    assert held_out > lstsq_alpha(runs, "QE", **{"dataset.split": "same"}).mean()
