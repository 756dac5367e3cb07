"""The paper's regime (basis.paper_regime): eigenfaces also fitted at m = n beside the coverage rule, leading the
printed header and the summary."""

import numpy as np
import pandas as pd
import pytest

from workbench.api import run_study
from workbench.numerics.bases import Eigenfaces
from workbench.reporting.findings.run_summary import SUMMARY_WORDS as RUN_SUMMARY_WORDS
from workbench.reporting.findings.run_summary import beside_regime_text
from workbench.reporting.text.run import study_header
from workbench.settings.config import compose
from workbench.study.fitting import fit_eigenfaces
from workbench.study.regime import paper_regime_fit

SMALL = ["dataset.n_frames=600"]  # the synthetic actor's coverage rule keeps m < 18 here


@pytest.fixture(scope="module")
def regime_run():
    cfg = compose("paper", SMALL)
    return cfg, run_study(cfg)


def test_the_m_equal_n_variant_comes_first_with_every_basis_and_solver(regime_run):
    cfg, results = regime_run
    assert [result.data for result in results] == ["markers m=n", "markers"]
    regime, rule = results
    n = len(regime.capture.hand_names)
    assert n == 18 and regime.eigenfaces.n_components_ == n
    assert rule.eigenfaces.n_components_ != n
    assert regime.capture.train is rule.capture.train  # the same training frames, another m
    solvers = list(cfg["solver"])
    scored = {(row.basis, row.solver) for row in regime.rows}
    expected = {(basis, solver) for basis in ("H", "QE", "QE-linear") for solver in solvers} | {("PCA", "projection")}
    assert scored == expected
    assert any("the paper's regime: m = n = 18" in note for note in regime.capture.notes)


def test_the_m_equal_n_variant_reuses_the_coverage_rule_s_decomposition(regime_run):
    """Decomposed once: the m = n eigenfaces come from the coverage rule's fit, equal to decomposing again."""
    _, results = regime_run
    regime, rule = results
    assert regime.eigenfaces.mean_ is rule.eigenfaces.mean_  # no second fit
    fresh = Eigenfaces(n_components=18).fit(rule.capture.train)
    np.testing.assert_array_equal(regime.eigenfaces.components_, fresh.components_)  # exact path: every eigenpair
    np.testing.assert_array_equal(regime.eigenfaces.explained_variance_ratio_, fresh.explained_variance_ratio_)
    assert regime.eigenfaces.method_ == fresh.method_ == "covariance"
    assert fit_eigenfaces(rule.capture, 0.995, 18, previous=rule.eigenfaces).mean_ is rule.eigenfaces.mean_
    assert fit_eigenfaces(rule.capture, 0.995, 18).mean_ is not rule.eigenfaces.mean_  # nothing handed on
    assert regime.span_pass is None and rule.span_pass is None  # handed on to the refit, not kept in the results


def test_the_header_leads_with_the_m_equal_n_comparison(regime_run):
    cfg, results = regime_run
    from workbench.settings.typed import study_settings

    lines = study_header(results, study_settings(cfg)).splitlines()
    assert lines[1].startswith("  the paper's regime m = n (paper: H/QE 7.2, QE/PCA 1.16")
    assert lines[2].startswith("    markers m=n (m = 18, n = 18): H/QE ")
    assert "QE cond " in lines[2] and "max |w| " in lines[2]
    assert lines[3] == "  beside it, the coverage rule's m:"
    assert lines[4].startswith(f"    markers (m = {results[1].eigenfaces.n_components_}, n = 18): H/QE ")
    regime = {(row.basis, row.solver): row.alpha.absolute_mean for row in results[0].rows}
    ratio = regime[("H", "lstsq")] / regime[("QE", "lstsq")]
    assert f"H/QE {ratio:.3g}," in lines[2]


def test_no_extra_fit_when_m_is_fixed():
    results = run_study(compose("paper", [*SMALL, "basis.n_components=12", "solver=lstsq"]))
    assert [result.data for result in results] == ["markers"]
    assert results[0].eigenfaces.n_components_ == 12


def test_no_extra_fit_when_the_coverage_rule_already_gives_m_equal_n(regime_run):
    cfg, results = regime_run
    from workbench.settings.typed import study_settings

    capture, basis = results[1].capture, study_settings(cfg).basis
    regime = (basis.paper_regime, basis.n_components)
    same, fitted, note = paper_regime_fit(capture, *regime, len(capture.hand_names))
    assert fitted is None and same is capture and "already keeps m = n = 18" in note
    assert paper_regime_fit(capture, False, basis.n_components, 9) == (capture, None, None)
    assert paper_regime_fit(capture, True, 12, 9) == (capture, None, None)
    _, fitted, _ = paper_regime_fit(capture, *regime, 9)
    assert fitted == 18


def test_the_summary_states_the_coverage_rule_beside_the_m_equal_n_run():
    rows = [
        {"data": data, "basis": basis, "solver": solver, "m": m, "alpha": value}
        for data, m, values in (("markers m=n", 18, (1.8, 0.7, 0.5)), ("markers", 33, (1.8, 1.44, 0.3)))
        for (basis, solver), value in zip((("H", "lstsq"), ("QE", "lstsq"), ("PCA", "projection")), values)
    ]
    table = pd.DataFrame(rows)
    assert (
        beside_regime_text(table, "markers m=n", "alpha")
        == " Beside it, the coverage rule on markers (m = 33): H/QE 1.25, QE/PCA 4.8."
    )
    assert beside_regime_text(table, "markers", "alpha") == ""


def test_a_record_of_the_default_study_leads_with_the_paper_s_regime(tmp_path):
    import json

    from workbench.api import run
    from workbench.reporting.findings.run import run_findings
    from workbench.reporting.findings.run_summary import run_summary

    text = run(compose("paper", [*SMALL, "solver=lstsq"]), tmp_path)
    lines = text.splitlines()
    study = next(i for i, line in enumerate(lines) if line.startswith("Study 'paper' on "))
    assert lines[0].startswith(
        "The paper's claims at m = n (lstsq, alpha_abs_mean), on markers m=n (m = 18)"
    )  # the verdict, first
    assert lines[study + 1].startswith("  the paper's regime m = n")
    table = pd.read_csv(tmp_path / "alpha_table.csv")
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert list(metrics["data"]) == ["markers m=n", "markers"]
    summary = run_summary(table, "alpha_abs_mean", metrics)
    assert "On markers m=n (m = 18, n = 18: the paper's regime m = n, coverage 0.99" in summary
    assert "QE better than H: " in summary and "QE nearly as accurate as PCA (QE/PCA <= 1.5): " in summary
    assert "H condition number " in summary and "; QE condition number " in summary
    assert len(summary.split()) <= RUN_SUMMARY_WORDS  # the coverage rule's sentence gives way first (here it does)
    lines = run_findings(table, "alpha_abs_mean", {"m": 18, "alpha": {"H": 5.2, "QE": 0.72, "PCA": 0.62}}, {}, metrics)
    assert next(line for line in lines if line.startswith("**markers")).startswith("**markers m=n**")
    assert sum(1 for line in lines if line.startswith("**markers** (the coverage rule, beside markers m=n)")) == 1
    assert sum(len(line.split()) for line in lines) <= 800


@pytest.mark.parametrize("setting", ["basis.paper_regime=false", "basis.n_components=12"])
def test_no_held_out_m_equal_n_variant_when_the_regime_is_off_or_m_is_fixed(setting):
    results = run_study(compose("paper", [*SMALL, setting, "solver=lstsq", "dataset.held_out=[tail,kfold]"]))
    assert [result.data for result in results] == ["markers", "markers held-out tail", "markers held-out kfold"]


def test_held_out_folds_get_the_no_extra_fit_notes(regime_run):
    cfg, results = regime_run
    from workbench.settings.typed import study_settings

    capture, basis = results[1].capture, study_settings(cfg).basis
    regime = (basis.paper_regime, basis.n_components)
    same, fitted, note = paper_regime_fit(capture, *regime, [18, 18, 18], [400, 400, 400], held_out=True)
    assert fitted is None and same is capture
    assert note.startswith("the paper's regime on held-out frames: the coverage rule already keeps m = n = 18")
    assert "in every fold" in note
    _, fitted, note = paper_regime_fit(capture, *regime, [5, 6, 7], [400, 12, 400], held_out=True)
    assert fitted is None and "the training frames of the smallest fold have at most 11: no m = n fit" in note
    regime, fitted, note = paper_regime_fit(capture, *regime, [5, 6, 7], [400, 400, 400], held_out=True)
    assert note is None and fitted == 18
    assert regime.notes[-1].startswith("the paper's regime on held-out frames: m = n = 18 eigenfaces")
    assert "coverage rule's m = [5, 6, 7] (per fold), scored on the same held-out frames" in regime.notes[-1]


def test_a_record_shows_the_held_out_m_equal_n_beside_the_training_frames(tmp_path):
    import json

    from workbench.api import run
    from workbench.reporting.findings.run import run_findings

    text = run(compose("paper", [*SMALL, "solver=lstsq", "dataset.held_out=tail"]), tmp_path)
    header = text.splitlines()
    at = header.index("  the paper's regime m = n on held-out frames (dataset.held_out; folds pooled):")
    assert header[at + 1].startswith("    markers held-out tail m=n (m = 18, n = 18): H/QE ")
    table = pd.read_csv(tmp_path / "alpha_table.csv")
    names = ["markers m=n", "markers", "markers held-out tail m=n", "markers held-out tail"]
    assert list(table["data"].unique()) == names
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert list(metrics["data"]) == names and metrics["data"]["markers held-out tail m=n"]["comparisons"]
    rows = [row for row in metrics["rows"] if row["data"] == "markers held-out tail m=n"]
    assert rows and all(row["train_on"] == "markers m=n" for row in rows)
    lines = run_findings(table, "alpha_abs_mean", {"m": 18, "alpha": {"H": 5.2, "QE": 0.72, "PCA": 0.62}}, {}, metrics)
    assert (
        sum(1 for line in lines if line.startswith("**markers held-out tail m=n** (m = 18; training frames: m = 18)"))
        == 1
    )
    assert sum(1 for line in lines if line.startswith("**markers held-out tail** (m = ")) == 1  # its own held-out line
