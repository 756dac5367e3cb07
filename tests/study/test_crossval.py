"""Held-out frames by cross-validation (dataset.held_out kfold and take_out): the folds and the pooled results."""

import numpy as np
import pytest

from workbench.api import run_study
from workbench.core.errors import WorkbenchError
from workbench.dataset.capture import Timeline
from workbench.settings.config import compose
from workbench.study.crossval import fold_indices
from workbench.study.regime import is_paper_regime


def two_takes() -> Timeline:
    """Take a of 50 frames and take b of 37, both at 10 Hz."""
    a, b = Timeline.uniform("a", np.arange(50), 10.0), Timeline.uniform("b", np.arange(37), 10.0)
    return Timeline(
        take=np.concatenate([a.take, b.take]),
        frame=np.concatenate([a.frame, b.frame]),
        seconds=np.concatenate([a.seconds, b.seconds]),
    )


def test_kfold_blocks_are_contiguous_disjoint_cover_every_frame_and_leave_a_gap():
    timeline = two_takes()
    folds = fold_indices(timeline, "kfold", folds=4, gap_s=0.25)
    assert len(folds) == 4
    held_all = np.concatenate([held for _, held in folds])
    np.testing.assert_array_equal(np.sort(held_all), np.arange(87))  # every frame held out exactly once
    for train, held in folds:
        assert np.intersect1d(train, held).size == 0
        for take in ("a", "b"):
            block = held[timeline.take[held] == take]
            assert block.size and np.all(np.diff(block) == 1)  # one contiguous block per take, never across takes
        gap = np.setdiff1d(np.arange(87), np.union1d(train, held))
        assert gap.size > 0 and np.intersect1d(gap, train).size == 0 and np.intersect1d(gap, held).size == 0
    # known answer: take a's blocks are 0-12, 13-25, 26-37, 38-49; 0.25 s at 10 Hz leaves 2 frames each side
    train, held = folds[1]
    np.testing.assert_array_equal(held[:13], np.arange(13, 26))
    gap = np.setdiff1d(np.arange(87), np.union1d(train, held))
    np.testing.assert_array_equal(gap[gap < 50], [11, 12, 26, 27])
    # no gap: training is everything else
    for train, held in fold_indices(timeline, "kfold", folds=4, gap_s=0.0):
        np.testing.assert_array_equal(np.sort(np.concatenate([train, held])), np.arange(87))


def test_take_out_holds_out_each_take_once():
    folds = fold_indices(two_takes(), "take_out")
    assert [held.tolist() for _, held in folds] == [list(range(50)), list(range(50, 87))]
    assert [train.tolist() for train, _ in folds] == [list(range(50, 87)), list(range(50))]


@pytest.mark.parametrize(
    "protocol, options, message",
    [
        ("take_out", {}, "has one take"),
        ("kfold", {"folds": 11}, "at least 11 frames"),
        ("kfold", {"folds": 2, "gap_s": 10.0}, "fewer than 2 training frames"),
    ],
)
def test_bad_folds_are_named(protocol, options, message):
    with pytest.raises(WorkbenchError, match=message):
        fold_indices(Timeline.uniform("a", np.arange(10), 10.0), protocol, **options)


def test_kfold_scores_every_basis_on_the_same_frames_and_keeps_per_fold_values():
    results = run_study(
        compose(
            "paper",
            [
                "dataset.n_frames=500",
                "solver=lstsq",
                "dataset.held_out=kfold",
                "dataset.folds=4",
                "dataset.fold_gap_s=0.2",
            ],
        )
    )
    # the coverage rule keeps m = n on these training frames, not in every fold: the folds' m = n variant is added
    assert [result.data for result in results] == ["markers", "markers held-out kfold m=n", "markers held-out kfold"]
    trained, held = results[0], results[-1]
    assert held.data == "markers held-out kfold" and held.folds["n_folds"] == 4
    assert len(held.capture.eval) == 500 and len(held.folds["m"]) == 4
    assert sum(held.folds["n_eval_frames"]) == 500
    for row in held.rows:  # every basis scored on all 500 held-out frames
        assert row.alpha.error_sq.shape == (500,)
    pooled = {row.basis: row.alpha for row in held.rows}
    # H is not fitted, so held out over every frame once it is the training-frame value
    h_trained = next(row.alpha for row in trained.rows if row.basis == "H")
    assert pooled["H"].absolute_pooled == pytest.approx(h_trained.absolute_pooled, rel=1e-9)
    for i, row in enumerate(held.rows):
        per_fold = held.folds["alpha_abs_pooled"][i]
        assert len(per_fold) == 4 and min(per_fold) <= row.alpha.absolute_pooled <= max(per_fold)
    from workbench.study.summary import data_metrics

    comparisons = data_metrics(held)["fold_comparisons"]
    assert comparisons and all(c["n"] == 4 and c["method"] == "paired t on log ratios" for c in comparisons)


def test_animface_take_out_gives_a_fold_per_take(shared_data):
    results = run_study(
        compose(
            "paper",
            [
                "dataset=animface",
                "dataset.frame_step=20",
                "dataset.train_on=markers",
                "dataset.held_out=take_out",
                "solver=lstsq",
                f"paths.data_root={shared_data}",
            ],
        )
    )
    by_name = {result.data: result for result in results}
    held, trained = by_name["markers held-out take_out"], by_name["markers"]
    assert held.folds["n_folds"] == 3
    assert len(held.capture.eval) == len(trained.capture.eval) == sum(held.folds["n_eval_frames"])


def test_held_out_protocols_have_the_paper_regime_at_m_equal_n_scored_on_the_same_frames():
    """basis.paper_regime: every held-out protocol also fitted at m = n (in each fold), first, on the same frames."""
    results = run_study(
        compose(
            "paper",
            ["dataset.n_frames=600", "solver=lstsq", "dataset.held_out=[tail,kfold]", "dataset.folds=3"],
        )
    )
    by_name = {result.data: result for result in results}
    assert list(by_name) == [
        "markers m=n",
        "markers",
        "markers held-out tail m=n",
        "markers held-out tail",
        "markers held-out kfold m=n",
        "markers held-out kfold",
    ]
    n = 18
    for protocol in ("tail", "kfold"):
        regime, rule = by_name[f"markers held-out {protocol} m=n"], by_name[f"markers held-out {protocol}"]
        assert is_paper_regime(regime.data) and not is_paper_regime(rule.data)
        assert regime.protocol == rule.protocol != "training frames"
        assert regime.train_on == regime.eval_on == "markers m=n"  # compared with the training frames' m = n
        assert rule.train_on == "markers"
        assert any(
            note.startswith("the paper's regime on held-out frames: m = n = 18") for note in regime.capture.notes
        )
        # the same held-out frames, the same frames in each fold
        np.testing.assert_array_equal(np.asarray(regime.capture.eval), np.asarray(rule.capture.eval))
        np.testing.assert_array_equal(regime.capture.eval_timeline.frame, rule.capture.eval_timeline.frame)
        # H is not fitted: on the same frames its per-frame errors are the same
        h_regime, h_rule = (next(row for row in result.rows if row.basis == "H") for result in (regime, rule))
        np.testing.assert_allclose(h_regime.alpha.error_sq, h_rule.alpha.error_sq, rtol=1e-12, atol=0.0)
    tail, tail_rule = by_name["markers held-out tail m=n"], by_name["markers held-out tail"]
    assert tail.eigenfaces.n_components_ == n != tail_rule.eigenfaces.n_components_
    np.testing.assert_array_equal(np.asarray(tail.capture.train), np.asarray(tail_rule.capture.train))
    kfold, kfold_rule = by_name["markers held-out kfold m=n"], by_name["markers held-out kfold"]
    assert kfold.folds["m"] == [n] * 3 and kfold_rule.folds["m"] != [n] * 3
    for key in ("n_train_frames", "n_eval_frames"):
        assert kfold.folds[key] == kfold_rule.folds[key]
    assert "m = n in each fold (m = [18, 18, 18])" in kfold.capture.notes[-1]
    from workbench.study.summary import data_metrics

    comparisons = data_metrics(kfold)["fold_comparisons"]
    assert comparisons and all(c["n"] == 3 for c in comparisons)  # paired over its own folds
