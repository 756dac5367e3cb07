"""The paper's two claims, computed once per run (workbench.study.claims) and only rendered by every surface: the
verdict rules, "not estimable", and a run whose surfaces used to disagree."""

import math
import re
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from workbench.reporting.findings.claims import claims_sentence, entry_text, number, short_entry_text
from workbench.stats.statistics import PAIRED_LOG_RATIO, Interval
from workbench.study.claims import (
    ABOVE,
    BELOW,
    CLAIM_MARGIN,
    INSIDE,
    MIN_DEGREES,
    NOT_DECIDED,
    NOT_ESTIMABLE,
    NOT_REPRODUCED,
    NOT_TESTED,
    PAPER_RATIOS,
    REPRODUCED,
    REVERSED,
    claim_entry,
)

RESTS = {"unit": "folds", "frames": 500, "takes": 1, "batch_frames": 0, "batches": 5, "folds": 5, "persistence": 0.5}


def ratio(estimate, low, high, degrees=10.0):
    return Interval(estimate, low, high, n=11, method=PAIRED_LOG_RATIO, null=1.0, degrees=degrees)


def entry(name, estimate, low, high, degrees=10.0, rests=RESTS, construction=""):
    return claim_entry(name, ratio(estimate, low, high, degrees), rests, "alpha_abs_mean", CLAIM_MARGIN, construction)


def test_the_paper_ratios_come_from_its_alpha():
    assert PAPER_RATIOS["H/QE"] == 5.2 / 0.72 and round(PAPER_RATIOS["QE/PCA"], 2) == 1.16
    assert CLAIM_MARGIN == 1.5 and MIN_DEGREES == 3


def test_claim_one_is_superiority_with_the_size_said_apart():
    above = entry("H/QE", 2.1, 1.7, 2.6)
    assert (above["verdict"], above["size"]) == (REPRODUCED, ABOVE)  # the paper's 7.2 lies above the interval
    assert entry("H/QE", 0.8, 0.7, 0.9)["verdict"] == REVERSED
    straddles = entry("H/QE", 3.0, 0.9, 10.0)
    assert (straddles["verdict"], straddles["size"]) == (NOT_DECIDED, INSIDE)
    assert entry("H/QE", 9.0, 8.0, 10.0)["size"] == BELOW
    assert math.isclose(above["log_estimate"], math.log(2.1)) and math.isclose(above["log_low"], math.log(1.7))


def test_claim_two_is_non_inferiority_against_the_margin_and_consistency_with_the_paper():
    assert entry("QE/PCA", 1.3, 1.2, 1.5)["verdict"] == REPRODUCED  # at the margin counts
    assert entry("QE/PCA", 1.7, 1.55, 1.9)["verdict"] == NOT_REPRODUCED
    holds = entry("QE/PCA", 1.4, 1.2, 1.6)
    assert (holds["verdict"], holds["consistency"]) == (NOT_DECIDED, BELOW)  # the paper's 1.16 lies below it
    # data that reproduce the paper exactly are "reproduced", which a margin of 1.16 could never give
    paper = entry("QE/PCA", 1.16, 1.10, 1.22)
    assert (paper["verdict"], paper["consistency"]) == (REPRODUCED, INSIDE)
    spans = entry("QE/PCA", 0.95, 0.9, 1.0, construction="QE <= PCA holds by construction (rank m + 1)")
    assert spans["verdict"] == NOT_TESTED and spans["not_tested"].startswith("QE <= PCA")


def test_an_interval_that_cannot_inform_is_not_estimable_and_shows_no_numbers():
    few = entry("H/QE", 2.0, 1.1, 3.6, degrees=2.0)
    assert few["verdict"] == NOT_ESTIMABLE and few["why_not_estimable"].startswith("fewer than 3 degrees of freedom")
    floor = entry("H/QE", 2.0, 1.5, 2.6, degrees=2.998)  # three overlapping batches: just under the threshold
    assert floor["verdict"] == NOT_ESTIMABLE
    capped = entry("QE/PCA", 1.0, 0.9, 1.1, rests=dict(RESTS, unit="frames", persistence=0.999))
    assert capped["verdict"] == NOT_ESTIMABLE and "persistence is at its cap 0.999" in capped["why_not_estimable"]
    over_time = claim_entry(
        "H/QE",
        replace(ratio(2.0, 1.5, 2.6), not_estimable="3 degrees of freedom, below 6"),
        dict(RESTS, unit="frames"),
        "alpha_abs_mean",
        CLAIM_MARGIN,
    )
    assert over_time["verdict"] == NOT_ESTIMABLE and over_time["why_not_estimable"].startswith("3 degrees of freedom")
    none = entry("H/QE", 2.0, math.nan, math.nan)
    assert none["verdict"] == NOT_ESTIMABLE and none["why_not_estimable"].startswith("no interval")
    text = short_entry_text({"H/QE": dict(few), "QE/PCA": entry("QE/PCA", 1.1, 1.0, 1.2)})
    assert text.startswith("H/QE not estimable: fewer than 3 degrees of freedom, QE/PCA 1.10 [1.00, 1.20] reproduced")
    assert "3.6" not in text


def test_numbers_keep_their_trailing_zeros():
    assert [number(v) for v in (1.0, 0.17, 2.049, 746.2, 1234.0)] == ["1.00", "0.170", "2.05", "746", "1.23e+03"]


def test_a_run_without_a_variant_at_m_equal_n_says_the_claims_are_not_tested():
    claims = {
        "entries": [],
        "not_tested": "not tested at m = n: no variant is fitted at m = n (markers: m = 8, n = 18)",
    }
    assert claims_sentence(claims) == f"The paper's claims: {claims['not_tested']}."


# ---------------------------------------------------------------------------------------------------------------
# A run: every surface says the stored verdict
# ---------------------------------------------------------------------------------------------------------------

RUN = ("dataset.n_frames=1500", "dataset.held_out=[tail,kfold]", "save_inputs=true")
"""A run where, on the held-out tail at m = n, the per-frame difference QE - PCA excludes 0 (on 20 degrees of
freedom) while the ratio QE/PCA rests on three batches: the comparisons table said "a > b" where the claim cannot
be estimated; and the k-fold ratios were pooled alphas while the summary named the mean."""


@pytest.fixture(scope="module")
def claims_run(tmp_path_factory):
    from in_process import run_workbench

    from workbench.record.record import load_record

    folder = tmp_path_factory.mktemp("claims") / "run"
    done = run_workbench(*RUN, f"hydra.run.dir={folder}", cwd=folder.parent)
    assert done.returncode == 0, done.stderr
    return load_record(folder), done.stdout


def stored(record, data):
    return next(entry for entry in record.claims["entries"] if entry["data"] == data)


def test_the_record_keeps_the_claims_for_training_and_each_held_out_protocol(claims_run):
    record, _ = claims_run
    claims = record.claims
    assert claims["format"] == 1 and claims["column"] == "alpha_abs_mean" and claims["margin"] == CLAIM_MARGIN
    assert [(e["data"], e["protocol"]) for e in claims["entries"]] == [
        ("markers m=n", "training"),
        ("markers held-out tail m=n", "tail"),
        ("markers held-out kfold m=n", "kfold"),
    ]
    for found in claims["entries"]:
        for name in ("H/QE", "QE/PCA"):
            assert found[name]["column"] == "alpha_abs_mean" and found[name]["rests_on"]


def test_the_two_statistics_that_used_to_disagree_now_give_one_verdict_everywhere(claims_run):
    from workbench.reporting.figures.headline import claim_table
    from workbench.reporting.findings.comparisons import comparison_table
    from workbench.reporting.findings.run import run_findings
    from workbench.reporting.findings.run_summary import run_summary
    from workbench.reporting.findings.sweep_summary import stored_claims_text

    record, printed = claims_run
    metrics = record.metrics
    tail = "markers held-out tail m=n"
    # the difference test of the primary contrast QE vs PCA excludes 0 on the tail ...
    difference = next(
        Interval.from_dict(c)
        for c in metrics["data"][tail]["comparisons"]
        if (tuple(c["a"]), tuple(c["b"])) == (("QE", "lstsq"), ("PCA", "projection"))
    )
    assert difference.low > 0
    # ... while the claim's ratio rests on three batches: not estimable
    assert stored(record, tail)["QE/PCA"]["verdict"] == NOT_ESTIMABLE
    summary = run_summary(record.table, "alpha_abs_mean", metrics)
    sentence = printed.split("\nStudy ")[0].replace("\n  ", " ")
    table = comparison_table(metrics)
    findings = " ".join(map(str, run_findings(record.table, "alpha_abs_mean", record.config["paper"], {}, metrics)))
    figure = claim_table(metrics)
    sweep = stored_claims_text([record], "markers m=n")
    for found in record.claims["entries"]:
        protocol = found["protocol_text"].removeprefix("held-out ")
        said = entry_text(found) if found["protocol"] == "training" else short_entry_text(found)
        assert said in sentence, (said, sentence)
        assert said in summary, (said, summary)
        for name in ("H/QE", "QE/PCA"):
            verdict = found[name]["verdict"]
            row = table[
                (table["data"] == found["data"])
                & (table["a"] == ("H lstsq" if name == "H/QE" else "QE lstsq"))
                & (table["b"] == ("QE lstsq" if name == "H/QE" else "PCA projection"))
            ]
            assert len(row) == 1 and row["verdict"].iloc[0].startswith(f"the paper's claim, {name}")
            assert row["verdict"].iloc[0].split(" (")[0].endswith(verdict) and math.isnan(row["a - b"].iloc[0])
            drawn = figure[(figure["ratio"] == name) & (figure["protocol"] == found["protocol_text"])]
            assert drawn["verdict"].tolist() == [verdict]
            assert f"{found['data']} ({found['protocol_text']}" in findings
            assert protocol in sweep
    training = stored(record, "markers m=n")
    assert f"QE better than H: {training['H/QE']['verdict']}" in summary
    assert f"QE better than H: {training['H/QE']['verdict']}" in sentence
    # no surface orders QE and PCA on the tail by the difference test
    pair = table[(table["data"] == tail) & (table["a"] == "QE lstsq") & (table["b"] == "PCA projection")]
    assert pair["verdict"].tolist() == ["the paper's claim, QE/PCA: not estimable (" + pair_rests(record, tail) + ")"]


def test_the_headline_draws_no_level_interval_that_cannot_inform(claims_run):
    from workbench.reporting.figures.headline import headline_tables, level_interval, variant_label

    record, _ = claims_run
    per_frame = record.load_alpha_per_frame()
    levels, _ = headline_tables(record.table, record.metrics, per_frame, "alpha_abs_mean")
    assert len(levels)
    for row in levels.to_dict("records"):
        solver = "projection" if row["basis"] == "PCA" else "lstsq"
        interval = level_interval(per_frame, row["data"], row["basis"], solver, "alpha_abs_mean")
        assert row["not_estimable"] == interval.not_estimable
        drawn = math.isfinite(row["low"]) and math.isfinite(row["high"])
        assert drawn == interval.estimable
        assert ("no interval for " in variant_label(levels, row["data"])) == any(
            levels.loc[levels["data"] == row["data"], "not_estimable"]
        )


def test_a_level_on_a_wandering_series_is_drawn_without_bounds():
    import numpy as np
    import pandas as pd

    from workbench.reporting.figures.headline import headline_tables, variant_label

    rng = np.random.default_rng(0)
    frames = 600
    wandering = 1.0 + np.abs(np.cumsum(rng.normal(0.0, 0.05, frames)))  # persistence near 1: batches cannot inform
    steady = 0.5 + rng.normal(0.0, 0.05, frames) ** 2  # independent frames
    per_frame = {
        "markers m=n.basis": np.array(["H", "QE", "PCA"]),
        "markers m=n.solver": np.array(["lstsq", "lstsq", "projection"]),
        "markers m=n.absolute": np.stack([wandering, steady, steady * 0.9]),
    }
    table = pd.DataFrame(
        {
            "data": "markers m=n",
            "basis": ["H", "QE", "PCA"],
            "solver": ["lstsq", "lstsq", "projection"],
            "m": 18,
            "n": 18,
            "alpha_abs_mean": [float(wandering.mean()), float(steady.mean()), float(steady.mean() * 0.9)],
        }
    )
    levels, _ = headline_tables(table, {"data": {"markers m=n": {}}}, per_frame, "alpha_abs_mean")
    found = levels.set_index("basis")
    assert found.loc["H", "not_estimable"] and math.isnan(found.loc["H", "low"]) and math.isnan(found.loc["H", "high"])
    assert not found.loc["QE", "not_estimable"] and found.loc["QE", "low"] < found.loc["QE", "alpha"]
    assert variant_label(levels, "markers m=n").endswith("; no interval for H: not estimable")


def test_a_record_without_per_frame_alphas_says_why_its_levels_have_no_interval(claims_run):
    from workbench.reporting.figures.headline import figure_headline, headline_tables

    record, _ = claims_run
    levels, claims = headline_tables(record.table, record.metrics, None, "alpha_abs_mean")
    assert levels["low"].isna().all() and set(levels["no_interval"]) == {
        "the record keeps no per-frame alphas (save_inputs=true keeps them)"
    }
    figure = figure_headline(levels, claims, "alpha_abs_mean", "test")
    assert "(no interval: the record keeps no per-frame alphas" in figure.axes[0].get_title()


def pair_rests(record, data):
    return stored(record, data)["QE/PCA"]["rests_on"]


FOUND = re.compile(r"(H/QE|QE/PCA) ([0-9.e+-]+) \[([0-9.e+-]+), ([0-9.e+-]+)\]")


def test_every_ratio_and_interval_the_summary_prints_recomputes_from_the_per_frame_arrays(claims_run):
    from workbench.reporting.findings.run_summary import run_summary
    from workbench.stats.ratios import ratio_of_means

    record, _ = claims_run
    summary = run_summary(record.table, "alpha_abs_mean", record.metrics)
    assert "`alpha_abs_mean`" in summary
    arrays = record.load_alpha_per_frame()
    recomputed = []
    for found in record.claims["entries"]:
        data = found["data"]
        rows = [(str(b), str(s)) for b, s in zip(arrays[f"{data}.basis"], arrays[f"{data}.solver"])]
        alpha = {key: np.asarray(arrays[f"{data}.absolute"][rows.index(key)], float) for key in rows}
        takes = np.unique(arrays[f"{data}.take"], return_inverse=True)[1]
        folds = record.metrics["data"][data].get("folds")
        for name, (a, b) in {
            "H/QE": (("H", "lstsq"), ("QE", "lstsq")),
            "QE/PCA": (("QE", "lstsq"), ("PCA", "projection")),
        }.items():
            if found[name]["why_not_estimable"]:
                continue
            if folds:  # each fold's mean alpha, then the t interval of the mean log ratio, by hand
                edges = np.cumsum([0, *folds["n_eval_frames"]])
                logs = np.log(
                    [alpha[a][lo:hi].mean() / alpha[b][lo:hi].mean() for lo, hi in zip(edges[:-1], edges[1:])]
                )
                half = stats.t.ppf(0.975, len(logs) - 1) * logs.std(ddof=1) / math.sqrt(len(logs))
                value = (math.exp(logs.mean()), math.exp(logs.mean() - half), math.exp(logs.mean() + half))
            else:
                interval = ratio_of_means(alpha[a], alpha[b], takes=takes, seconds=arrays[f"{data}.seconds"])
                assert math.isclose(interval.estimate, alpha[a].mean() / alpha[b].mean(), rel_tol=1e-12)
                value = (interval.estimate, interval.low, interval.high)
            recomputed.append((name, *(number(v) for v in value)))
    printed = FOUND.findall(summary)
    assert printed and sorted(printed) == sorted(recomputed), (printed, recomputed)


def test_a_round_off_difference_is_an_equal_sign_without_an_interval():
    from workbench.reporting.findings.comparisons import comparison_table

    tie = Interval(-7.98e-19, -1.6e-18, 2.5e-20, n=800, method="batch means", null=0.0, scale=0.3, p_value=0.1)
    metrics = {
        "data": {"markers": {"comparisons": [{"a": ["QE", "nnls"], "b": ["QE-linear", "nnls"], **tie.as_dict()}]}},
        "rows": [],
    }
    row = comparison_table(metrics).iloc[0]
    assert row["verdict"] == "a = b (within the tie tolerance)"
    assert all(math.isnan(row[key]) for key in ("a - b", "low", "high", "p"))


def test_a_k_fold_variant_whose_folds_differ_names_every_fold_s_m():
    import pandas as pd

    from workbench.reporting.findings.run import fitted_m_text

    part = pd.DataFrame({"m": [8.4]})
    assert fitted_m_text(part, {"folds": {"m": [8, 9, 8, 8, 9]}}) == "m = [8, 9, 8, 8, 9]"
    assert fitted_m_text(pd.DataFrame({"m": [8]}), {"folds": {"m": [8, 8]}}) == "m = 8"
