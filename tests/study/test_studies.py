"""The studies: the options they sweep (hand subsets, cross-evaluation, decimation, gaps, other takes) and each
study's small preset run end to end through the command line."""

import json

import numpy as np
import pandas as pd
import pytest
from in_process import run_workbench

from workbench.api import run_study
from workbench.core.errors import WorkbenchError
from workbench.dataset import build_captures
from workbench.dataset.decimate import decimate
from workbench.dataset.gaps import apply_gap_policy, longest_run, make_gap_mask
from workbench.dataset.synthetic import LOWER_FACE, MUSCLE_NAMES, UPPER_FACE, make_face_mesh, make_synthetic_take
from workbench.dataset.transfer import point_transfer
from workbench.settings.config import STUDIES_DIR, compose, resolved_without_hydra
from workbench.study.protocols import hand_subset_indices

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
    for spec, message in (
        ("random0", "1 <= k <= 18"),
        ("middle", "all, upper, lower, random<k>"),
        (["nose"], "distinct hand shapes"),
    ):
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
    positions = np.stack([np.stack([2 * frames, -frames, frames**2], axis=1)] * 2, axis=1)  # (10, 2, 3)
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


def test_point_transfers():
    rng = np.random.default_rng(0)
    mesh = rng.normal(size=(600, 3)) * 50
    markers = mesh[[5, 50, 300, 7, 120, 9, 44, 210, 333, 500]]
    assert point_transfer(mesh, mesh).method == "identity"
    selection = point_transfer(mesh, markers)
    assert selection.method == "coincident"
    fields = rng.normal(size=(4, 600 * 3))
    np.testing.assert_array_equal(
        selection.apply(fields), fields.reshape(4, 600, 3)[:, [5, 50, 300, 7, 120, 9, 44, 210, 333, 500]].reshape(4, -1)
    )
    rbf = point_transfer(markers, mesh)
    assert rbf.method == "rbf"
    affine = np.array([[1.0, 2.0, -1.0], [0.5, 0.0, 3.0], [0.0, 1.0, 1.0]])  # a thin-plate spline with a linear
    np.testing.assert_allclose(
        rbf.apply_one((markers @ affine.T).reshape(-1)),  # tail reproduces affine fields
        (mesh @ affine.T).reshape(-1),
        atol=1e-6,
    )
    nearest = point_transfer(mesh, markers + 0.5)
    assert nearest.method == "nearest" and nearest.max_distance == pytest.approx(np.sqrt(3) * 0.5)


@pytest.mark.slow
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
    cfg = plain_config(
        overrides=[
            "dataset.n_frames=1200",
            "dataset.gap_rate=0.05",
            "dataset.split=other_take",
            "dataset.train_on=[markers,mesh_rbf]",
        ]
    )
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
    assert [result.data for result in results] == ["markers->markers", "markers->mesh", "mesh->markers", "mesh->mesh"]
    assert [result.transfer for result in results] == ["identity", "rbf", "coincident", "identity"]
    assert [result.capture.n_points for result in results] == [66, 4200, 66, 4200]
    same = {result.data: result for result in run_study(plain_config(overrides=base))}
    for cross, own in (("markers->markers", "markers"), ("mesh->mesh", "mesh")):
        crossed = {
            (row.basis, row.solver): row.alpha.absolute_mean
            for row in results[[result.data for result in results].index(cross)].rows
        }
        assert crossed == {(row.basis, row.solver): row.alpha.absolute_mean for row in same[own].rows}
    # a basis fitted on the mesh and carried to the markers (vertex selection) scores its own restriction
    mesh_to_markers = results[2]
    assert mesh_to_markers.eigenfaces.mean_.size == 3 * 4200
    assert mesh_to_markers.quasi_eigen["affine"].shapes.shape == (18, 3 * 66)


def test_face_region_is_the_dense_mesh_inside_the_markers_at_full_resolution():
    from scipy.spatial import Delaunay

    from workbench.dataset.synthetic_builder import face_region

    cfg = plain_config(overrides=["dataset.n_frames=60", "dataset.train_on=[markers,face]"])
    captures = build_captures(cfg["dataset"])
    take = make_synthetic_take(n_frames=60)
    vertices, faces = face_region(70, 60, 66)
    inside = Delaunay(take.mesh.face_plane[take.face_marker_vertices]).find_simplex(take.mesh.face_plane) >= 0
    np.testing.assert_array_equal(vertices, np.flatnonzero(inside))
    assert set(take.face_marker_vertices) <= set(vertices) and 0.5 < vertices.size / 4200 < 0.9
    face = captures["face"]
    full = take.mesh_sequence() - take.mesh.vertices
    np.testing.assert_allclose(face.train, full[:, vertices].reshape(60, -1), rtol=0, atol=1e-12)
    assert face.faces.max() == vertices.size - 1 and face.point_labels[0] == f"v{vertices[0]}"


@pytest.mark.slow
def test_marker_mesh_scores_every_basis_on_the_same_evaluation_points():
    """Fitted on markers, RBF mesh or (decimated) mesh: each evaluation set, the markers and the face region, is
    scored on the same points and frames, so the study compares bases and never point sets."""
    study = compose("marker_mesh")
    assert list(study.dataset.eval_on) == ["markers", "face"]
    scored = {}
    for fraction in (1.0, 0.25):
        cfg = plain_config(
            "marker_mesh",
            ["dataset.n_frames=200", "dataset.train_on=[markers,mesh_rbf,mesh]", f"dataset.mesh_fraction={fraction}"],
        )
        for result in run_study(cfg):
            scored.setdefault(result.eval_on, []).append(result)
    assert sorted(scored) == ["face", "markers"]
    for eval_on, results in scored.items():
        assert len(results) == 6  # 3 data variants fitted on x 2 mesh densities
        first = results[0].capture
        for result in results[1:]:
            np.testing.assert_array_equal(result.capture.neutral, first.neutral)
            np.testing.assert_array_equal(result.capture.eval, first.eval)
            np.testing.assert_array_equal(result.capture.hand, first.hand)
            assert result.capture.point_labels == first.point_labels
        hand = {next(row.alpha.displacement_pooled for row in result.rows if row.basis == "H") for result in results}
        assert len(hand) == 1  # the hand shapes need no fit: one score per evaluation set
    assert scored["markers"][0].capture.n_points == 66 and scored["face"][0].capture.n_points > 2000


def test_noise_study_holds_m_at_the_clean_value_at_its_largest_noise():
    study = compose("noise")
    params = {key: str(value).split(",") for key, value in study.hydra.sweeper.params.items()}
    assert params["basis.coverage_on"][0] == "clean"  # the primary axis
    largest_noise, largest_gaps = (
        max(map(float, params["dataset.marker_noise_mm"])),
        max(map(float, params["dataset.gap_rate"])),
    )
    assert largest_noise == 2.0 and study.metric.score_clean
    for seed in (0, 1):
        base = ["dataset.n_frames=1000", f"dataset.seed={seed}"]
        clean = run_study(
            plain_config(
                "noise", base + ["dataset.marker_noise_mm=0", "dataset.gap_rate=0", "basis.coverage_on=training"]
            )
        )[0]
        noisy = run_study(
            plain_config(
                "noise",
                base
                + [
                    f"dataset.marker_noise_mm={largest_noise}",
                    f"dataset.gap_rate={largest_gaps}",
                    "basis.coverage_on=clean",
                ],
            )
        )[0]
        free = run_study(
            plain_config("noise", base + [f"dataset.marker_noise_mm={largest_noise}", "basis.coverage_on=training"])
        )[0]
        assert noisy.eigenfaces.n_components_ == clean.eigenfaces.n_components_ < 20
        assert free.eigenfaces.n_components_ > 150  # the coverage rule on the noisy frames keeps the noise
        assert any(
            note.startswith(f"m chosen on the clean capture: m = {clean.eigenfaces.n_components_} ")
            for note in noisy.capture.notes
        )
        # scored against the clean frames: the clean run scores the same there as against its own frames
        for row in clean.rows:
            assert row.clean_alpha.absolute_mean == pytest.approx(row.alpha.absolute_mean, rel=1e-9)
        held, kept = (next(row for row in result.rows if row.basis == "PCA") for result in (noisy, free))
        # PCA with 150+ eigenfaces reproduces the noise: close to the noisy frames, far from the clean ones
        assert kept.alpha.rms_mm < kept.clean_alpha.rms_mm
        assert held.clean_alpha.rms_mm < kept.clean_alpha.rms_mm


def test_clean_frames_are_matched_by_take_and_frame_number():
    from workbench.settings.typed import clean_dataset, dataset_settings
    from workbench.study.protocols import clean_frames

    # dropout without noise, frames with a gap dropped: the kept frames are exactly the clean frames of the same number
    cfg = plain_config(
        overrides=[
            "dataset.n_frames=600",
            "dataset.marker_noise_mm=0",
            "dataset.gap_rate=0.02",
            "dataset.gap_policy=drop",
        ]
    )
    dropped = build_captures(cfg["dataset"])["markers"]
    clean = build_captures(clean_dataset(dataset_settings(cfg["dataset"])))["markers"]
    assert len(dropped.eval) < len(clean.eval) == 600
    truth = clean_frames(dropped, clean)
    np.testing.assert_allclose(truth, dropped.eval, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(truth, clean.eval[dropped.timeline().frame])
    tail = plain_config(
        overrides=["dataset.n_frames=600", "dataset.gap_rate=0.05", "dataset.gap_policy=drop", "dataset.split=tail"]
    )
    with pytest.raises(WorkbenchError, match="not among the clean capture's evaluated frames"):
        clean_frames(
            build_captures(tail["dataset"])["markers"],
            build_captures(clean_dataset(dataset_settings(tail["dataset"])))["markers"],
        )


def test_clean_scores_need_the_synthetic_actor_and_leave_n_components_to_the_rule():
    with pytest.raises(WorkbenchError, match="coverage_on must be one of"):
        run_study(plain_config(overrides=["dataset.n_frames=100", "basis.coverage_on=noisy"]))
    with pytest.raises(
        WorkbenchError, match="coverage_on=clean chooses m from the clean capture, so basis.n_components must be null"
    ):
        run_study(plain_config(overrides=["dataset.n_frames=100", "basis.coverage_on=clean", "basis.n_components=5"]))
    with pytest.raises(WorkbenchError, match="only the synthetic actor has"):
        from workbench.settings.typed import clean_dataset, dataset_settings

        clean_dataset(dataset_settings({"kind": "animface"}))


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
# Each preset's test is a class of its own: pytest-xdist (--dist loadscope) sends each class to whichever process is
# free, so the sweeps spread over both processes (they share no fixture).


def run_preset(study, tmp_path):
    sweep = tmp_path / study
    result = run_workbench("--config-name", f"{study}_small", f"hydra.sweep.dir={sweep}", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    collected = sweep / "collected"
    for name in ("runs.csv", "runs.parquet", "summary.csv", "summary.parquet", "alpha_table.md", "alpha_table.tex"):
        assert (collected / name).is_file(), name
    runs = pd.read_parquet(collected / "runs.parquet")
    assert runs.groupby("run").ngroups == sum(1 for _ in sweep.glob("*/done"))
    return sweep, runs, result.stdout


def test_a_sweep_prints_every_line_within_120_columns_and_its_full_text_with_wide(tmp_path):
    """A study's sweep prints a line per run, then the collected alpha table and findings: every line within 120
    columns; ``--wide`` prints the same text with its long lines whole."""
    small = ["--config-name", "coverage_small", "dataset.n_frames=300", "dataset.seed=0", "basis.coverage=0.95,0.995"]

    def printed(folder, *more):
        result = run_workbench(*small, f"hydra.sweep.dir={folder}", "-m", *more, cwd=tmp_path)
        assert result.returncode == 0, result.stderr[-3000:]
        return (result.stdout + result.stderr).splitlines()

    fitted, whole = printed("fitted"), printed("whole", "--wide")
    assert "Findings (comparisons.md has every pair):" in fitted and any(line.startswith("done ") for line in fitted)
    assert max(len(line) for line in fitted) <= 120, max(fitted, key=len)
    assert max(len(line) for line in whole) > 120  # the findings' long lines, whole
    findings = whole[whole.index("Findings (comparisons.md has every pair):") + 1 :]
    start = fitted.index("Findings (comparisons.md has every pair):") + 1
    assert " ".join(line.strip() for line in fitted[start:]) == " ".join(line.strip() for line in findings)


def lstsq_alpha(runs, basis, **conditions):
    keep = (runs["basis"] == basis) & runs["solver"].isin(["lstsq", "projection"])
    for key, value in conditions.items():
        keep &= runs[key] == value
    return runs.loc[keep, "alpha_abs_mean"]


def test_every_preset_runs_five_seeds():
    for study in (*STUDIES, "bases"):
        for name in (study, f"{study}_small"):
            seeds = compose(name).hydra.sweeper.params["dataset.seed"]
            assert str(seeds).split(",") == ["0", "1", "2", "3", "4"], name


@pytest.mark.slow
class TestCoveragePreset:
    def test_coverage_preset(self, tmp_path):
        sweep, runs, stdout = run_preset("coverage", tmp_path)
        assert runs.groupby("run").ngroups == 10 and "| basis.coverage |" in stdout
        m = runs[runs["basis"] == "PCA"].set_index(["dataset.seed", "basis.coverage"])["m"]
        for seed in range(5):
            assert m[(seed, 0.95)] < m[(seed, 0.995)]
        assert (
            lstsq_alpha(runs, "PCA", **{"basis.coverage": 0.995}).to_numpy()
            < lstsq_alpha(runs, "PCA", **{"basis.coverage": 0.95}).to_numpy()
        ).all()


@pytest.mark.slow
class TestBasisCountPreset:
    def test_basis_count_preset(self, tmp_path):
        sweep, runs, _ = run_preset("basis_count", tmp_path)
        assert runs.groupby("run").ngroups == 30
        h = runs[runs["basis"] == "H"].set_index(["basis.hand_subset", "dataset.seed", "basis.append_empty_axes"])["n"]
        assert h[("upper", 0, False)] == 6 and h[("random6", 1, True)] == 6 and h[("all", 0, False)] == 18
        drawn = {}
        for path in sweep.glob("*/metrics.json"):
            metrics = json.loads(path.read_text())
            if {"basis.hand_subset=random6", "basis.append_empty_axes=False"} <= set(metrics["overrides"]):
                drawn[metrics["dataset"]["provenance"]["seed"]] = tuple(metrics["dataset"]["hand_names"])
        assert sorted(drawn) == [0, 1, 2, 3, 4] and drawn[0] != drawn[1]  # a new draw per seed
        upper = lstsq_alpha(runs, "QE", **{"basis.hand_subset": "upper", "basis.append_empty_axes": False})
        full = lstsq_alpha(runs, "QE", **{"basis.hand_subset": "all", "basis.append_empty_axes": False})
        assert upper.mean() > full.mean()


@pytest.mark.slow
class TestMarkerMeshPreset:
    def test_marker_mesh_preset(self, tmp_path):
        sweep, runs, stdout = run_preset("marker_mesh", tmp_path)
        assert runs.groupby("run").ngroups == 20
        assert set(runs["data"]) == {"markers->markers", "markers->face", "mesh->markers", "mesh->face"}
        points = runs.drop_duplicates(["dataset.mesh_fraction", "eval_on"]).set_index(
            ["dataset.mesh_fraction", "eval_on"]
        )["n_points"]
        # one evaluation set each, whatever the mesh density the bases were fitted on
        assert points[(1.0, "markers")] == points[(0.25, "markers")] == 66
        assert points[(1.0, "face")] == points[(0.25, "face")] > 2000
        # fitted on the full dense mesh and scored on its face region, the quasi-eigen faces beat the hand shapes
        full = {"dataset.mesh_fraction": 1.0}
        assert (
            lstsq_alpha(runs, "QE", data="mesh->face", **full).to_numpy()
            < lstsq_alpha(runs, "H", data="mesh->face", **full).to_numpy()
        ).all()
        assert "alpha_disp_pooled (%)" in stdout and "n_points" in stdout and "time_total" in stdout
        # the findings compare the data each basis was fitted on, within one evaluation set
        assert "scored on **face**, QE (5 seeds, lstsq) `alpha_disp_pooled` by the data fitted on: " in stdout
        comparisons = pd.read_csv(sweep / "collected" / "comparisons.csv")
        fitted = comparisons[comparisons["eval_on"].notna() & comparisons["basis"].notna()]
        assert set(fitted["first"]) | set(fitted["second"]) == {"markers", "mesh"} and (fitted["n"] == 5).all()


@pytest.mark.slow
class TestNoisePreset:
    def test_noise_preset(self, tmp_path):
        sweep, runs, stdout = run_preset("noise", tmp_path)
        assert runs.groupby("run").ngroups == 40
        m = runs[runs["basis"] == "PCA"].set_index(
            ["dataset.seed", "basis.coverage_on", "dataset.marker_noise_mm", "dataset.gap_rate"]
        )["m"]
        for seed in range(5):
            assert m[(seed, "clean", 0.5, 0.05)] == m[(seed, "training", 0.0, 0.0)]  # m held at the clean capture's
            assert m[(seed, "training", 0.5, 0.0)] > 10 * m[(seed, "training", 0.0, 0.0)]  # the rule keeps the noise
        assert {"clean_alpha_abs_mean", "clean_rms_mm"} <= set(runs.columns)
        assert "lstsq) `clean_alpha_abs_mean`: H " in stdout  # findings against the clean frames too
        gapped = next(sweep.glob("*gap_rate=0.05*/metrics.json"))
        gaps = json.loads(gapped.read_text())["dataset"]["provenance"]["gaps"]
        assert gaps["policy"] == "linear" and gaps["n_missing_samples"] > 0


@pytest.mark.slow
class TestChoicesPreset:
    def test_choices_preset(self, tmp_path):
        sweep, runs, stdout = run_preset("choices", tmp_path)
        assert runs.groupby("run").ngroups == 5
        assert set(runs["solver"]) == {"lstsq", "nnls", "box", "projection"}
        assert set(runs["projection"]) == {"-", "affine", "linear"}
        header = next(line for line in stdout.splitlines() if line.startswith("| basis"))
        assert [cell.strip() for cell in header.strip("|").split("|")] == [
            "basis",
            "solver",
            "m",
            "alpha_abs_mean",
            "alpha_abs_pooled",
            "alpha_disp_mean",
            "alpha_disp_pooled",
        ]


@pytest.mark.slow
class TestGeneralisationPreset:
    def test_generalisation_preset(self, tmp_path):
        sweep, runs, stdout = run_preset("generalisation", tmp_path)
        assert runs.groupby("run").ngroups == 15
        frames = runs.drop_duplicates("dataset.split").set_index("dataset.split")[["n_train_frames", "n_eval_frames"]]
        assert frames.loc["same"].tolist() == [1000, 1000] and frames.loc["tail"].tolist() == [500, 500]
        assert frames.loc["other_take"].tolist() == [1000, 1000]
        rows = [line.split("|")[1].strip() for line in stdout.splitlines() if line.startswith("| ")][1:]
        assert rows == ["same", "tail", "other_take"]  # the study's order, not the alphabet's
        held_out = lstsq_alpha(runs, "QE", **{"dataset.split": "other_take"}).mean()
        assert held_out > lstsq_alpha(runs, "QE", **{"dataset.split": "same"}).mean()
