"""The verdicts on the paper's two claims (workbench.reporting.findings.claims): decided by where the intervals lie."""

import math

from workbench.reporting.findings.claims import (
    BY_CONSTRUCTION,
    NOT_DECIDED,
    NOT_REPRODUCED,
    PAPER_RATIOS,
    REPRODUCED,
    claim_verdicts,
)
from workbench.stats.statistics import PAIRED_LOG_RATIO, Interval


def ratio(estimate, low, high, p_adjusted=math.nan):
    return Interval(estimate, low, high, n=5, method=PAIRED_LOG_RATIO, null=1.0, p_adjusted=p_adjusted)


def test_the_paper_ratios_come_from_its_alpha():
    assert PAPER_RATIOS["H/QE"] == 5.2 / 0.72 and round(PAPER_RATIOS["QE/PCA"], 2) == 1.16


def test_claim_one_by_where_the_interval_of_h_over_qe_lies():
    above = claim_verdicts(ratio(2.1, 1.7, 2.6), ratio(0.95, 0.9, 1.0), False)
    assert above.h_over_qe_decision == REPRODUCED
    assert above.h_over_qe == (
        "QE better than H: reproduced, H/QE 2.1 [1.7, 2.6] (95 % interval, paired t on log ratios, n = 5); "
        "the paper's 7.2 lies above it"
    )
    assert claim_verdicts(ratio(0.8, 0.7, 0.9), ratio(1, 0.9, 1.1), False).h_over_qe_decision == NOT_REPRODUCED
    straddles = claim_verdicts(ratio(3.0, 0.9, 10.0), ratio(1, 0.9, 1.1), False)
    assert straddles.h_over_qe_decision == NOT_DECIDED and straddles.h_over_qe.endswith("7.2 lies within it")
    # a Holm-adjusted p-value decides whether 1 is excluded, and is shown
    held_back = claim_verdicts(ratio(2.1, 1.7, 2.6, p_adjusted=0.08), ratio(1, 0.9, 1.1), False)
    assert held_back.h_over_qe_decision == NOT_DECIDED and "Holm p 0.08" in held_back.h_over_qe
    no_interval = claim_verdicts(ratio(2.0, math.nan, math.nan), ratio(1, 0.9, 1.1), False)
    assert no_interval.h_over_qe_decision == NOT_DECIDED and "no interval" in no_interval.h_over_qe


def test_claim_two_against_the_papers_bound_or_by_construction():
    def decide(low, high):
        return claim_verdicts(ratio(2, 1.5, 3), ratio((low + high) / 2, low, high), False)

    assert decide(0.9, 1.16).qe_over_pca_decision == REPRODUCED  # at the bound counts
    assert decide(1.17, 1.4).qe_over_pca_decision == NOT_REPRODUCED
    assert decide(1.0, 1.3).qe_over_pca_decision == NOT_DECIDED
    tested = claim_verdicts(ratio(2, 1.5, 3), ratio(1.3, 1.2, 1.4, p_adjusted=0.01), False)
    assert tested.qe_over_pca_decision == NOT_REPRODUCED and "Holm" not in tested.qe_over_pca
    assert decide(0.9, 1.1).qe_over_pca.startswith("QE nearly as accurate as PCA (QE/PCA <= 1.16): reproduced, QE/PCA")
    built = claim_verdicts(ratio(2, 1.5, 3), ratio(0.95, 0.92, 0.97), True)
    assert built.qe_over_pca_decision == BY_CONSTRUCTION
    assert built.qe_over_pca == (
        "QE nearly as accurate as PCA (QE/PCA <= 1.16): holds by construction (QE <= PCA in every run whatever the "
        "data), not tested; its size QE/PCA 0.95 [0.92, 0.97] (95 % interval, paired t on log ratios, n = 5)"
    )
