"""Capture gaps: the gap policies, the masked solve of eq. 5, alpha over visible markers, and the policies on the
synthetic actor and on the real optical takes with markers removed at random."""

import numpy as np
import pytest
from scipy.optimize import lsq_linear, nnls

from workbench.api import run_study
from workbench.core.errors import WorkbenchError
from workbench.dataset import build_captures
from workbench.dataset.gaps import apply_gap_policy
from workbench.numerics.metrics import summarise_alpha
from workbench.numerics.solve import solve_weights
from workbench.settings.config import compose, resolved_without_hydra


def random_masked_problem(seed, n_shapes=5, n_points=12, n_frames=150, missing=0.25):
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((n_shapes, 3 * n_points))
    targets = rng.uniform(-0.5, 1.5, (n_frames, n_shapes)) @ basis + 0.3 * rng.standard_normal((n_frames, 3 * n_points))
    # few patterns, as occlusion gaps give: each frame takes one of 6 random masks
    patterns = rng.random((6, n_points)) > missing
    patterns[:, :n_shapes] = True  # enough visible points to determine the weights
    visible = patterns[rng.integers(0, 6, n_frames)]
    holed = np.where(np.repeat(visible, 3, axis=1), targets, np.nan)
    return basis, targets, holed, visible


def per_frame_reference(basis, targets, visible, kind):
    """Each frame solved alone on its visible coordinates by NumPy/SciPy."""
    weights = []
    for frame, seen in zip(targets, visible):
        dims = np.repeat(seen, 3)
        design, target = basis[:, dims].T, frame[dims]
        if kind == "lstsq":
            weights.append(np.linalg.lstsq(design, target, rcond=None)[0])
        elif kind == "nnls":
            weights.append(nnls(design, target)[0])
        else:
            weights.append(lsq_linear(design, target, bounds=(0.0, 1.0), method="bvls", tol=1e-13).x)
    return np.array(weights)


@pytest.mark.parametrize("kind", ["lstsq", "nnls", "box"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_masked_solve_equals_per_frame_solves_on_the_visible_points(kind, seed):
    basis, _, holed, visible = random_masked_problem(seed)
    bounds = {"lower": 0.0, "upper": 1.0} if kind == "box" else {}
    solution = solve_weights(basis, holed, kind=kind, visible=visible, **bounds)
    expected = per_frame_reference(basis, holed, visible, kind)
    np.testing.assert_allclose(solution.weights, expected, rtol=1e-6, atol=1e-8)
    assert solution.max_kkt_violation < 1e-9


def test_all_visible_mask_gives_the_unmasked_solution():
    basis, targets, _, visible = random_masked_problem(3)
    everything = np.ones_like(visible)
    for kind, bounds in (("lstsq", {}), ("nnls", {}), ("box", {"lower": -0.2, "upper": 0.8})):
        masked = solve_weights(basis, targets, kind=kind, visible=everything, **bounds).weights
        plain = solve_weights(basis, targets, kind=kind, **bounds).weights
        np.testing.assert_allclose(masked, plain, rtol=1e-9, atol=1e-12)  # the masked path adds a 1e-12 ridge


def test_masked_solve_rejects_bad_masks():
    basis, _, holed, visible = random_masked_problem(4)
    with pytest.raises(WorkbenchError, match="visible must have shape"):
        solve_weights(basis, holed, visible=visible[:, :-1])
    with pytest.raises(WorkbenchError, match="boolean mask"):
        solve_weights(basis, holed, visible=visible.astype(int))
    blind = visible.copy()
    blind[7] = False
    with pytest.raises(WorkbenchError, match="see no point at all .*frame 7"):
        solve_weights(basis, holed, visible=blind)
    seen_nan = holed.copy()
    seen_nan[0, np.flatnonzero(np.repeat(visible[0], 3))[0]] = np.nan
    with pytest.raises(WorkbenchError, match="finite at every visible point"):
        solve_weights(basis, seen_nan, visible=visible)
    with pytest.raises(WorkbenchError, match="targets must be finite"):
        solve_weights(basis, holed)  # NaN without a mask stays an error


def test_alpha_over_visible_points_equals_alpha_of_the_visible_subset():
    rng = np.random.default_rng(5)
    neutral = rng.normal(50.0, 10.0, 30)
    captured = rng.normal(0.0, 2.0, (40, 30))
    reconstructed = captured + rng.normal(0.0, 0.2, captured.shape)
    visible = rng.random((40, 10)) > 0.3
    visible[:, 0] = True
    holed = np.where(np.repeat(visible, 3, axis=1), captured, np.nan)
    summary = summarise_alpha(neutral, holed, reconstructed, visible=visible)
    for frame in (0, 13, 39):
        dims = np.repeat(visible[frame], 3)
        error = np.linalg.norm(captured[frame, dims] - reconstructed[frame, dims])
        assert summary.displacement_per_frame[frame] == pytest.approx(
            100 * error / np.linalg.norm(captured[frame, dims]), rel=1e-12
        )
        assert summary.absolute_per_frame[frame] == pytest.approx(
            100 * error / np.linalg.norm(neutral[dims] + captured[frame, dims]), rel=1e-12
        )
    seen = np.repeat(visible, 3, axis=1)
    squared_error = ((captured - reconstructed)[seen] ** 2).sum()
    assert summary.displacement_pooled == pytest.approx(100 * np.sqrt(squared_error / (captured[seen] ** 2).sum()))
    assert summary.rms_mm == pytest.approx(np.sqrt(squared_error / visible.sum()))


def test_gap_policies_on_known_trajectories():
    frames = np.arange(12, dtype=float)
    positions = np.stack([np.stack([frames, 2 * frames, -frames], axis=1)] * 3, axis=1)  # (12, 3, 3), linear
    holed = positions.copy()
    holed[2:4, 0] = np.nan  # a 2-frame gap
    holed[6:11, 1] = np.nan  # a 5-frame gap

    dropped = apply_gap_policy(holed, "drop")
    assert dropped.kept.tolist() == [f not in (2, 3, 6, 7, 8, 9, 10) for f in range(12)]
    assert dropped.visible is None and dropped.report.n_dropped_frames == 7
    np.testing.assert_array_equal(dropped.positions, positions[dropped.kept])

    filled = apply_gap_policy(holed, "linear")
    assert filled.kept.all() and filled.report.n_filled_samples == 7
    np.testing.assert_allclose(filled.positions, positions)  # linear motion: interpolation is exact

    short_only = apply_gap_policy(holed, "linear", max_fill_frames=3)
    assert short_only.kept.tolist() == [f not in range(6, 11) for f in range(12)]
    assert short_only.report.n_filled_samples == 2 and short_only.report.n_dropped_frames == 5
    np.testing.assert_allclose(short_only.positions, positions[short_only.kept])

    masked = apply_gap_policy(holed, "masked")
    assert masked.kept.all() and masked.report.n_missing_samples == 7
    np.testing.assert_array_equal(masked.visible, ~np.isnan(holed).any(axis=2))
    np.testing.assert_allclose(masked.positions, positions)  # filled for training

    # the two settings are checked with the others, before anything is built
    with pytest.raises(WorkbenchError, match=r"^dataset\.gap_policy must be one of \('drop', 'linear', 'masked'\)"):
        build_captures({"kind": "synthetic", "gap_policy": "spline"})
    with pytest.raises(WorkbenchError, match=r"^dataset\.gap_max_fill_frames must be an integer >= 1 or null"):
        build_captures({"kind": "synthetic", "gap_max_fill_frames": 0})


def test_masked_policy_on_the_synthetic_actor():
    cfg = resolved_without_hydra(
        compose(
            "paper",
            [
                "dataset.n_frames=800",
                "dataset.gap_rate=0.05",
                "dataset.gap_policy=masked",
                "solver=all",
                "dataset.mesh_rows=30",
                "dataset.mesh_cols=26",
                "dataset.train_on=[markers,mesh]",
            ],
        )
    )
    results = {result.data: result for result in run_study(cfg)}
    markers, mesh = results["markers"].capture, results["mesh"].capture
    assert markers.eval_visible is not None and mesh.eval_visible is None
    missing = ~markers.eval_visible
    assert missing.mean() == pytest.approx(0.05, abs=0.02)
    assert np.isnan(markers.eval[np.repeat(missing, 3, axis=1)]).all() and np.isfinite(markers.train).all()
    assert any("masked solve" in note and f"{int(missing.sum())} of" in note for note in markers.notes)
    for row in results["markers"].rows:
        assert np.isfinite(row.alpha.absolute_mean) and row.max_kkt_violation < 1e-9, row


def test_masked_policy_with_eval_on_is_refused():
    cfg = resolved_without_hydra(
        compose(
            "paper",
            [
                "dataset.n_frames=300",
                "dataset.gap_rate=0.05",
                "dataset.gap_policy=masked",
                "solver=lstsq",
                "dataset.train_on=mesh",
                "+dataset.eval_on=markers",
            ],
        )
    )
    with pytest.raises(WorkbenchError, match="masked.*eval_on"):
        run_study(cfg)


def lstsq_alpha(results):
    """alpha_abs_mean of H, QE and PCA (lstsq) of the one data variant."""
    rows = results[0].rows
    return {row.basis: row.alpha.absolute_mean for row in rows if row.basis in ("H", "QE", "PCA")}


def test_masked_solve_on_real_takes_with_markers_removed_at_random(shared_data):
    """AnimFace markers with 5 % of the samples removed in random occlusion gaps: scored on the markers each frame
    saw, alpha stays within 10 % of the gap-free run's for every basis (measured: within 7 %)."""
    common = [
        f"paths.data_root={shared_data}",
        "dataset=animface",
        "dataset.train_on=markers",
        "solver=lstsq",
        "dataset.frame_step=2",
    ]
    clean = lstsq_alpha(run_study(resolved_without_hydra(compose("paper", common))))
    holed_results = run_study(
        resolved_without_hydra(
            compose("paper", common + ["dataset.gap_rate=0.05", "dataset.gap_policy=masked", "dataset.gap_seed=3"])
        )
    )
    holed = lstsq_alpha(holed_results)
    capture = holed_results[0].capture
    assert (~capture.eval_visible).mean() == pytest.approx(0.05, abs=0.015)
    assert any("missing" in note for note in capture.notes)
    for basis in ("H", "QE", "PCA"):
        assert holed[basis] == pytest.approx(clean[basis], rel=0.10), (basis, holed, clean)
    assert holed["QE"] < holed["H"]


def test_drop_and_linear_policies_on_real_takes(shared_data):
    common = [
        f"paths.data_root={shared_data}",
        "dataset=animface",
        "dataset.train_on=markers",
        "dataset.frame_step=4",
        "dataset.gap_rate=0.02",
        "dataset.gap_mean_frames=6",
    ]
    cfg = resolved_without_hydra(compose("paper", common + ["dataset.gap_policy=drop"]))
    dropped = build_captures(cfg["dataset"])["markers"]
    cfg = resolved_without_hydra(compose("paper", common + ["dataset.gap_policy=linear"]))
    filled = build_captures(cfg["dataset"])["markers"]
    assert len(dropped.train) < len(filled.train) and np.isfinite(filled.train).all()
    per_take = dropped.provenance["per_take"]
    assert sum(take["frames_dropped_for_gaps"] for take in per_take.values()) == len(filled.train) - len(dropped.train)


def test_masked_policy_can_fit_on_the_complete_frames_only():
    overrides = [
        "dataset.n_frames=600",
        "dataset.gap_rate=0.02",
        "dataset.gap_policy=masked",
        "dataset.train_on=markers",
    ]
    filled = build_captures(resolved_without_hydra(compose("paper", overrides))["dataset"])["markers"]
    complete = build_captures(
        resolved_without_hydra(compose("paper", overrides + ["dataset.gap_fit_on=complete"]))["dataset"]
    )["markers"]
    saw_all = filled.eval_visible.all(axis=1)
    assert len(filled.train) == 600 and 0 < saw_all.sum() < 600
    np.testing.assert_array_equal(complete.train, filled.train[saw_all])
    np.testing.assert_array_equal(complete.eval, filled.eval, strict=False)
    assert any(
        f"fitted on the {int(saw_all.sum())} of 600 training frames that saw every marker" in note
        for note in complete.notes
    )
    with pytest.raises(WorkbenchError, match="gap_fit_on must be one of"):
        build_captures(resolved_without_hydra(compose("paper", overrides + ["dataset.gap_fit_on=all"]))["dataset"])


@pytest.mark.slow
def test_report_of_a_masked_run_draws_the_marker_figure_on_a_complete_frame(tmp_path):
    from workbench.api import run
    from workbench.reporting.report.command import main

    record = tmp_path / "run"
    run(
        compose(
            "paper",
            [
                "dataset.n_frames=600",
                "dataset.gap_rate=0.02",
                "dataset.gap_policy=masked",
                "dataset.train_on=markers",
                "solver=lstsq",
                "save_inputs=true",
                "basis.paper_regime=false",
            ],
        ),
        record,
    )
    with np.load(record / "inputs.npz", allow_pickle=False) as inputs:
        visible = inputs["eval_visible"]
        assert np.isnan(inputs["eval"][np.repeat(~visible, 3, axis=1)]).all()
    assert main([str(record), "--out", str(tmp_path / "reports" / "paper"), "--formats", "png"]) == 0
    # figure 4 is drawn (before the fix, its frame's NaN samples stopped the report)
    assert (tmp_path / "reports" / "paper" / "figures" / "fig4_marker_errors.png").is_file()
