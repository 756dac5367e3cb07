"""A sweep's paper claims are judged once, by each run (``metrics.json`` ``claims``): its summary, its report's
findings and ``workbench collect``'s findings all count the same stored verdicts per sweep cell, and none
decides a claim again from the sweep's own ratios."""

import re

import pandas as pd
import pytest
from test_collect import ALPHA, M, write_record

from workbench.record import record
from workbench.reporting.collect.sweep import collect_and_write
from workbench.reporting.findings.claims import RATIOS, counted_claims_text, counted_verdicts
from workbench.reporting.findings.sweep import holm_verdicts
from workbench.reporting.findings.sweep_summary import sweep_summary
from workbench.reporting.report.sweep import hand_basis_size, sweep_sections
from workbench.reporting.tables.runs import runs_table, summarise, sweep_comparisons, wide
from workbench.study.claims import NOT_TESTED


def verdict_phrases(records, base="markers") -> list[str]:
    """``QE better than H reproduced in 3``, ... : each claim's verdicts counted over the records, from the stored
    claims themselves."""
    counted = counted_verdicts([item.claims for item in records], base)
    return [
        f"{RATIOS[name]} " + ", ".join(f"{verdict} in {count}" for verdict, count in verdicts.items())
        for (_, name), verdicts in counted.items()
    ]


def test_every_sweep_surface_states_each_cells_stored_claims(tmp_path, monkeypatch):
    monkeypatch.setitem(M, 0.99, (18, 18, 18))  # at 0.99 every run keeps m = n = 18 and stores its claims
    folder = tmp_path / "sweep"
    for job, (coverage, seed) in enumerate(ALPHA):
        write_record(folder / f"basis.coverage={coverage},dataset.seed={seed}", coverage, seed, job)
    records = [record.load_record(path) for path in sorted(folder.iterdir())]
    per_run = runs_table(records, folder)
    over, swept, column = ["dataset.seed"], ["basis.coverage"], "alpha_abs_mean"
    comparisons = holm_verdicts(sweep_comparisons(per_run, [column], over))
    summary = wide(summarise(per_run, over=over))
    summary["paper_alpha"] = summary["basis"].map(per_run.groupby("basis", sort=False)["paper_alpha"].first())
    summary["n_hand"] = hand_basis_size(summary, swept)

    at_n = [item for item in records if item.config["basis"]["coverage"] == 0.99]
    expected = verdict_phrases(at_n)
    # the fixture's stored verdicts: H/QE 7.5, 5, 3.75 all above 1; QE/PCA 2, 1.5, 1.33 against the margin 1.5
    assert expected == [
        "QE better than H reproduced in 3",
        "QE nearly as accurate as PCA not reproduced in 1, not decided in 1, reproduced in 1",
    ]
    text = sweep_summary(records, per_run, comparisons, swept, over, column)
    # the fixture's records keep no solver settings: the report's findings use least squares, as they would, and
    # its table of choices is left empty (it is not a surface of the claims)
    monkeypatch.setattr("workbench.reporting.report.sweep.figure_solver", lambda config: ("lstsq", {}))
    for name in ("choices_rows", "provenance_section", "versions_section"):  # nor its provenance and versions
        monkeypatch.setattr(f"workbench.reporting.report.sweep.{name}", lambda *args: [])
    _, sections = sweep_sections(folder, records, per_run, summary, comparisons, swept, [], "test", over)
    report = [str(line) for line in next(s for s in sections if s.heading == "Findings").blocks[1]]
    collected = collect_and_write([folder], tmp_path / "out", where={"solver": "lstsq"})["findings"]
    for surface, lines in (("report", report), ("collect", collected)):
        cell = [line for line in lines if line.startswith("basis.coverage = 0.99, **markers**: the paper's claims")]
        assert len(cell) == 1, (surface, lines)
        assert all(phrase in cell[0] for phrase in expected), (surface, cell)
        # at m = n the sweep's own QE/H and QE/PCA would judge the claims a second time: not stated, not tested
        assert not any("QE/H" in line for line in lines if line.startswith("basis.coverage = 0.99")), surface
        other = [line for line in lines if line.startswith("basis.coverage = 0.9, **markers**: ")]
        assert len(other) == 1 and f"{NOT_TESTED} in all 3 runs" in other[0], (surface, other)
        # at the coverage rule's m the sweep's QE/H and QE/PCA are labelled as secondary, not the claims
        pairs = [line for line in lines if "QE/H" in line and line.startswith("basis.coverage = 0.9,")]
        assert pairs and all("secondary comparisons at m = 4-6 (not the paper's claims)" in p for p in pairs)
    assert all(phrase in text for phrase in expected), text
    # no surface decides a claim from the sweep's ratios: the comparisons table holds no primary family
    assert "primary" not in set(comparisons["family"])
    table = pd.read_csv(tmp_path / "out" / "comparisons.csv")
    assert "primary" not in set(table["family"])


@pytest.mark.slow
def test_a_real_sweep_with_the_papers_regime_states_its_runs_claims_alike_everywhere(tmp_path):
    """Four tiny runs (two coverages, two seeds) with the m = n variant: the summary, the report's findings and
    collect's findings count the same stored verdicts, and no ordering at m = n puts its own '<' between QE and H
    or PCA."""
    from workbench.api import run
    from workbench.reporting.report.sweep import build_sweep_report
    from workbench.settings.config import compose

    root = tmp_path / "sweep"
    for k, (coverage, seed) in enumerate((c, s) for c in (0.99, 0.999) for s in (0, 1)):
        overrides = ["dataset.n_frames=300", f"basis.coverage={coverage}", f"dataset.seed={seed}", "solver=lstsq"]
        run(compose("paper", overrides), root / str(k))
    records = [record.load_record(root / str(k)) for k in range(4)]
    build_sweep_report(root, tmp_path / "report", formats=("svg",))
    readme = (tmp_path / "report" / "README.md").read_text()
    summary = readme.split("## Summary\n\n", 1)[1].split("\n## ", 1)[0]
    report = [
        line[2:] for line in readme.split("## Findings", 1)[1].split("\n## ", 1)[0].splitlines() if line[:2] == "- "
    ]
    collected = collect_and_write([root], tmp_path / "out")["findings"]
    cell = [item for item in records if item.config["basis"]["coverage"] == 0.99]
    phrases = verdict_phrases(cell)
    assert all(phrase in summary for phrase in phrases), (phrases, summary)
    for lines in (report, collected):
        said = [line for line in lines if line.startswith("basis.coverage = 0.99, **markers m=n**: the paper's")]
        assert len(said) == 1 and all(phrase in said[0] for phrase in phrases), (phrases, said)
        for line in lines:
            if "**markers m=n** (" in line and ", lstsq) `alpha_abs_mean`" in line:
                assert not re.search(r"QE [0-9.]+ < (H|PCA) |(H|PCA) [0-9.]+ < QE ", line), line
                assert line.endswith("(QE against H and PCA: the runs' stored claims)."), line


def test_a_run_without_claims_for_a_variant_counts_as_not_tested_for_it():
    """A run that stored claims for mesh only is not tested at m = n on markers: no other variant's verdicts stand
    in for the one asked."""
    from test_collect import stored_claims

    mesh = stored_claims(18, 5.0, 1.2)
    mesh["entries"] = [dict(entry, data="mesh m=n", base="mesh") for entry in mesh["entries"]]
    assert counted_verdicts([mesh], "mesh") == {
        ("training frames", "H/QE"): {"reproduced": 1},
        ("training frames", "QE/PCA"): {"reproduced": 1},
    }
    assert counted_verdicts([mesh], "markers") == {
        ("training frames", "H/QE"): {NOT_TESTED: 1},
        ("training frames", "QE/PCA"): {NOT_TESTED: 1},
    }
    assert counted_claims_text([mesh], "markers") == (
        "the paper's claims (QE better than H; QE nearly as accurate as PCA): not tested at m = n in 1 run: the "
        "run's claims are of mesh (its variants at m = n), not of markers"
    )
