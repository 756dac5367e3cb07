"""Orderings that hold by construction, in every variant: the solvers' nesting decided by their bounds, QE spanning
PCA and QE-linear in every fold of a cross-validated variant, the sweep's reason for QE against QE-linear, and
seeds that leave the data the same (pseudo-replicates), from which no "A < B" is drawn."""

import math

import pandas as pd

from workbench.reporting.findings.sweep import comparison_interval, holm_verdicts, pair_text
from workbench.reporting.tables.runs import construction_reason, paired_comparisons
from workbench.stats.identities import identity_lookup, identity_text, run_identities, solver_contains
from workbench.stats.replicates import PSEUDO_REPLICATES, changes_data, pseudo_replicate_reason


def rows_of(*solvers, basis="H"):
    return [{"basis": basis, "solver": solver, "n": 18} for solver in solvers]


def nested(identities):
    return {(item.smaller[1], item.larger[1]) for item in identities}


def test_the_solvers_nest_by_their_bounds():
    rows = rows_of("lstsq", "nnls", "box")
    # a box [0, 1] (the kind's default) lies inside the non-negative weights, which lie inside least squares'
    assert nested(run_identities(rows, {})) == {("lstsq", "nnls"), ("lstsq", "box"), ("nnls", "box")}
    # a box reaching below 0 is not inside the non-negative weights: nnls <= box is no identity
    below = {"box": {"kind": "box", "lower": -1.0, "upper": 2.0}}
    assert nested(run_identities(rows, {}, below)) == {("lstsq", "nnls"), ("lstsq", "box")}
    assert not solver_contains("nnls", "box", below) and solver_contains("lstsq", "box", below)
    lookup = identity_lookup(run_identities(rows, {}, below), "alpha_abs_mean")
    assert lookup(("H", "nnls"), ("H", "box")) is None and lookup(("H", "lstsq"), ("H", "box")) is not None
    assert "[-1, 2]" in lookup(("H", "lstsq"), ("H", "box")).reason
    # the same from a record that keeps its solvers' settings, and for a box [0, 2]
    assert nested(run_identities(rows, {"solvers": below})) == {("lstsq", "nnls"), ("lstsq", "box")}
    wider = {"box": {"kind": "box", "lower": 0.0, "upper": 2.0}}
    assert ("nnls", "box") in nested(run_identities(rows, {}, wider))
    # a solver named otherwise, of kind box, and PCA's projection, which has no bounds
    named = {"clamp": {"kind": "box", "lower": 0.0, "upper": 1.0}}
    assert nested(run_identities(rows_of("nnls", "clamp"), {}, named)) == {("nnls", "clamp")}
    assert not solver_contains("lstsq", "projection")


def folds_with(ranks, ms=(8, 9, 8)):
    rows = [["QE", "affine", "lstsq"], ["QE-linear", "linear", "lstsq"], ["PCA", "projection", "projection"]]
    return {
        "n_folds": len(ms),
        "m": list(ms),
        "rows": rows,
        "n_shapes": [18, 18, 9],
        "rank": [list(ranks), [18] * len(ms), [None] * len(ms)],
    }


KFOLD_ROWS = [
    {"basis": "QE", "solver": "lstsq", "n": 18, "basis_conditioning": None},
    {"basis": "QE-linear", "solver": "lstsq", "n": 18, "basis_conditioning": None},
    {"basis": "PCA", "solver": "projection", "n": 8, "basis_conditioning": None},
]
KFOLD = {"pca": {"m": 8}, "protocol": "held-out blocked k-fold", "notes": []}


def test_kfold_variants_state_qe_below_pca_and_qe_linear_as_identities_from_each_folds_rank():
    found = run_identities(KFOLD_ROWS, dict(KFOLD, folds=folds_with([9, 10, 9])))
    pairs = {(item.smaller, item.larger) for item in found}
    assert pairs == {(("QE", "lstsq"), ("PCA", "projection")), (("QE", "lstsq"), ("QE-linear", "lstsq"))}
    text = identity_text(next(item for item in found if item.larger[0] == "PCA"))
    assert "in each of the 3 folds" in text and "m = [8, 9, 8]" in text and "rank = [9, 10, 9]" in text
    # one fold short of m + 1 (or a record without ranks): tested, not an identity
    assert run_identities(KFOLD_ROWS, dict(KFOLD, folds=folds_with([9, 9, 9]))) == []
    no_ranks = folds_with([9, 10, 9])
    del no_ranks["rank"]
    assert run_identities(KFOLD_ROWS, dict(KFOLD, folds=no_ranks)) == []


def test_the_sweep_gives_qe_against_qe_linear_its_own_reason():
    assert construction_reason("QE", "PCA") == "QE spans PCA's affine subspace, rank m + 1 in every run"
    reason = construction_reason("QE", "QE-linear")
    assert "PCA's affine subspace" not in reason and "QE-linear's shapes" in reason and "rank m + 1" in reason
    assert construction_reason("PCA", "H").startswith("Eckart-Young")


def test_seeds_that_leave_the_data_the_same_are_not_replicates():
    assert not changes_data("basis.alternatives_seed", {})
    assert not changes_data("basis.subset_seed", {"basis.hand_subset": "all"})
    assert changes_data("basis.subset_seed", {"basis.hand_subset": "random6"})
    assert changes_data("dataset.seed", {})
    reason = pseudo_replicate_reason(["basis.alternatives_seed"], {})
    assert "ICA's initial rotation" in reason and reason.endswith("the data are the same in every run")
    assert pseudo_replicate_reason(["basis.alternatives_seed", "dataset.seed"], {}) == ""
    assert pseudo_replicate_reason([], {}) == ""


def sweep_runs(seed_key):
    # ICA clearly below H-fit on each of three runs that differ only in ``seed_key``
    records = []
    for k, (ica, fit) in enumerate([(0.0610, 0.0626), (0.0612, 0.0626), (0.0615, 0.0626)]):
        for basis, value in (("ICA", ica), ("H-fit", fit)):
            records.append(
                {
                    "study": "bases",
                    "sweep": "s",
                    "run": f"r{k}",
                    seed_key: k,
                    "basis.hand_subset": "all",
                    "data": "markers",
                    "train_on": "markers",
                    "eval_on": "markers",
                    "basis": basis,
                    "projection": "-",
                    "solver": "lstsq",
                    "alpha_abs_mean": value,
                }
            )
    return pd.DataFrame.from_records(records)


def test_a_sweep_over_an_optimisers_seed_draws_no_ordering():
    pseudo = paired_comparisons(sweep_runs("basis.alternatives_seed"), "alpha_abs_mean")
    row = pseudo.iloc[0]
    assert row["verdict"] == PSEUDO_REPLICATES and math.isnan(row["p"])
    assert "basis.alternatives_seed" in row["pseudo_replicates"] and row["ratio_high"] < 1.0  # the bounds stay
    adjusted = holm_verdicts(pseudo)
    assert adjusted["verdict"].iloc[0] == PSEUDO_REPLICATES
    interval = comparison_interval(adjusted, "ICA", "H-fit")
    assert not interval.excludes_null and "not replicates" in interval.not_estimable
    text = pair_text(adjusted, "ICA", "H-fit")
    assert "<" not in text and "not replicates" in text, text
    # the same runs over a seed of the data: replicates, and the ordering is drawn
    real = paired_comparisons(sweep_runs("dataset.seed"), "alpha_abs_mean").iloc[0]
    assert real["verdict"] == "<" and real["pseudo_replicates"] is None and 0.0 < real["p"] < 0.05


def test_qe_is_h_when_every_hand_shape_lies_in_the_eigenface_hyperplane():
    import numpy as np

    from workbench.numerics.bases import Eigenfaces, build_quasi_eigen_basis

    rng = np.random.default_rng(5)
    hand = rng.standard_normal((4, 30))
    frames = rng.standard_normal((200, 4)) @ hand  # every frame a mix of the hand shapes
    names = ["a", "b", "c", "d"]
    spanning = build_quasi_eigen_basis(hand, names, Eigenfaces(n_components=4).fit(frames))
    assert spanning.hand_residual < 1e-10 and np.allclose(spanning.shapes, hand)
    short = build_quasi_eigen_basis(hand, names, Eigenfaces(n_components=2).fit(frames))
    assert short.hand_residual > 0.1
    rows = [{"basis": basis, "solver": solver, "n": 4} for basis in ("QE", "H") for solver in ("lstsq", "nnls")]

    def facts(residual, appended=()):
        return {"pca": {"m": 4}, "quasi_eigen": {"affine": {"hand_residual": residual, "appended_axes": appended}}}

    found = run_identities(rows, facts(spanning.hand_residual))
    lookup = identity_lookup(found, "alpha_abs_mean")
    for solver in ("lstsq", "nnls"):  # both ways: QE = H under every solver
        assert lookup(("QE", solver), ("H", solver)) is not None and lookup(("H", solver), ("QE", solver))
    assert "QE = H" in lookup(("QE", "lstsq"), ("H", "lstsq")).reason
    assert (
        identity_lookup(run_identities(rows, facts(short.hand_residual)), "alpha_abs_mean")(
            ("QE", "lstsq"), ("H", "lstsq")
        )
        is None
    )
    with_appended = run_identities(rows, facts(0.0, [3]))  # an appended eigenface: QE is more than H
    assert identity_lookup(with_appended, "alpha_abs_mean")(("H", "lstsq"), ("QE", "lstsq")) is None
    # a cross-validated variant: in every fold
    folded = dict(facts(0.0), folds={"hand_residual": {"affine": [1e-12, 0.2]}})
    assert identity_lookup(run_identities(rows, folded), "alpha_abs_mean")(("QE", "lstsq"), ("H", "lstsq")) is None


def test_the_sweep_figures_say_in_their_legends_when_the_runs_are_not_replicates():
    """Runs that differ only in an optimiser's seed: every sweep figure's legend says they are not replicates, and
    no figure text orders them; over a seed of the data the legend says nothing of it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from workbench.reporting.figures.bases import plot_alpha_against_intuitiveness
    from workbench.reporting.figures.studies import plot_alpha_against, plot_marker_vs_mesh
    from workbench.reporting.tables.runs import not_replicates_reason, summarise, wide

    def texts(figure):
        return [text.get_text() for text in figure.findobj(matplotlib.text.Text)]

    for seed_key, pseudo in (("basis.alternatives_seed", True), ("dataset.seed", False)):
        runs = sweep_runs(seed_key).assign(study="bases")
        reason = not_replicates_reason(runs, [seed_key])
        assert bool(reason) == pseudo and (not pseudo or "basis.alternatives_seed" in reason)
        summary = wide(summarise(runs, over=[seed_key])).assign(
            **{"basis.hand_subset": "all", "matched_abs_cosine": 0.5, "locality": 0.2, "usage": 0.5}
        )
        figures = [
            plot_alpha_against(summary, "basis.hand_subset", title="t", not_replicates=reason),
            plot_marker_vs_mesh(summary, "alpha_abs_mean", title="t", not_replicates=reason),
            plot_alpha_against_intuitiveness(summary, title="t", not_replicates=reason),
        ]
        for figure in figures:
            title = figure.legends[0].get_title().get_text().replace("\n", " ")
            assert title.startswith("not replicates: the runs differ only in basis.alternatives_seed") == pseudo
            assert not any("<" in text for text in texts(figure)), texts(figure)
            plt.close(figure)
