"""Each vocabulary of the settings is stated once: the places that repeat one (a table of descriptions, a rule
copied into every dataset kind's schema) are tied to it here."""

from dataclasses import MISSING, fields

import pytest

from workbench.core.frames import FRAME_DTYPES
from workbench.numerics.frames import DTYPES
from workbench.settings.schema import (
    DATA_VARIANTS,
    DATASET_EXTRA_RULES,
    DATASET_SCHEMAS,
    HELD_OUT_PROTOCOLS,
    PLAUSIBILITY_POLICIES,
    SPLITS,
    STORAGES,
)
from workbench.study.crossval import FOLDED
from workbench.study.protocols import HELD_OUT

SHARED = ("split", "eval_fraction", "held_out", "folds", "fold_gap_s", "storage", "dtype")
"""The split and storage settings every dataset kind has."""


def field_of(schema, name):
    return {spec.name: spec for spec in fields(schema)}[name]


def default_of(spec):
    return spec.default if spec.default is not MISSING else spec.default_factory()


@pytest.mark.parametrize("name", SHARED)
def test_the_split_and_storage_settings_are_the_same_in_every_dataset_kind(name):
    specs = {kind: field_of(schema, name) for kind, schema in DATASET_SCHEMAS.items()}
    stated = {kind: (default_of(spec), spec.metadata["rule"]) for kind, spec in specs.items() if kind != "synthetic"}
    assert len(set(stated.values())) == 1, stated
    synthetic = specs["synthetic"]
    assert default_of(synthetic) == default_of(specs["animface"])
    words = next(iter(stated.values()))[1]
    if name == "split":  # the synthetic actor adds a second take of the same actor
        assert synthetic.metadata["rule"] == f"one of {(*SPLITS, 'other_take')}" and words == f"one of {SPLITS}"
    else:
        assert synthetic.metadata["rule"] == words


def test_the_vocabularies_are_the_rules_words():
    kinds = DATASET_SCHEMAS
    assert field_of(kinds["animface"], "storage").metadata["rule"] == f"one of {STORAGES}"
    assert field_of(kinds["animface"], "dtype").metadata["rule"] == f"one of {FRAME_DTYPES}"
    assert tuple(DTYPES) == FRAME_DTYPES
    for kind in ("animface", "ict_livelink", "mesh_sequence"):
        assert field_of(kinds[kind], "plausibility").metadata["rule"] == f"one of {PLAUSIBILITY_POLICIES}"
    assert set(DATA_VARIANTS) == set(kinds)
    for kind, schema in kinds.items():
        assert str(DATA_VARIANTS[kind]) in field_of(schema, "train_on").metadata["rule"]
        assert str(DATA_VARIANTS[kind]) in DATASET_EXTRA_RULES["eval_on"](kind)["rule"]


def test_the_held_out_protocols_are_described_once():
    assert HELD_OUT is HELD_OUT_PROTOCOLS
    assert FOLDED == {protocol: HELD_OUT_PROTOCOLS[protocol] for protocol in FOLDED}
    assert str(tuple(HELD_OUT_PROTOCOLS)) in field_of(DATASET_SCHEMAS["synthetic"], "held_out").metadata["rule"]


def test_the_claim_margin_and_the_paper_s_values_are_the_settings():
    from dataclasses import asdict

    from workbench.settings.config import compose
    from workbench.settings.schema import MetricSchema
    from workbench.settings.typed import study_settings
    from workbench.study.claims import CLAIM_MARGIN, PAPER_ALPHA

    assert field_of(MetricSchema, "claim_margin").default == CLAIM_MARGIN
    paper = study_settings(compose("paper")).paper
    assert asdict(paper.alpha) == PAPER_ALPHA
