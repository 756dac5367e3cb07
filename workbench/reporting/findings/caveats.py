"""Caveats a run's record shows about its data and its weights, generated from the record's numbers against stated
thresholds (never typed per report): a stabilisation that the face moves, and quasi-eigen weights no animator could
set. :func:`workbench.reporting.findings.run.caveat_texts` lists them with the others.
"""

from __future__ import annotations

import math
from typing import Mapping

STABILISATION_RESIDUAL_MM = 1.0
"""A take whose rigid markers stray more than this (RMS, mm) from their reference after stabilisation has a rigid
set the face moves: about thirty times the capture's marker jitter (0.01-0.03 mm in the AnimFace takes)."""
QE_WEIGHT_BOUND = 10.0
"""Least-squares QE weights beyond this (|w|, in full contractions of a shape) are no slider setting an animator
could use: a hand shape's weight runs from 0 to 1, a little past it for an exaggeration."""


def take_residuals(provenance: Mapping) -> dict:
    """Take -> its stabilisation residual (RMS over its frames, mm) as the record keeps it (``per_take``'s
    ``noise_floor_mm``); empty for data without a stabilisation (a synthetic or a blendshape-driven capture)."""
    found = {}
    for take, facts in (provenance.get("per_take") or {}).items():
        value = ((facts or {}).get("noise_floor_mm") or {}).get("stabilisation_residual_rms")
        if value is not None and math.isfinite(float(value)):
            found[take] = float(value)
    return found


def stabilisation_caveat(metrics: Mapping) -> str:
    """The caveat of a rigid set the face moves (empty when every take's residual is within
    :data:`STABILISATION_RESIDUAL_MM`): which takes stray, and that bases fitted to the capture can absorb the
    residual motion while the hand shapes cannot."""
    provenance = (metrics.get("dataset") or {}).get("provenance") or {}
    residuals = take_residuals(provenance)
    over = {take: value for take, value in residuals.items() if value > STABILISATION_RESIDUAL_MM}
    if not over:
        return ""
    rigid = list(provenance.get("rigid_markers") or [])
    takes = " and ".join(f"{take.rsplit('.', 1)[0]} ({value:.2f} mm)" for take, value in over.items())
    forehead = [label for label in rigid if "forehead" in label.lower()]
    return (
        f"the rigid set that removes head motion{' (' + ', '.join(rigid) + ')' if rigid else ''} is not rigid: "
        f"after stabilisation it strays more than {STABILISATION_RESIDUAL_MM:g} mm RMS from its reference in "
        f"{takes}" + (", its forehead markers moving with the brows" if forehead else "") + "; bases fitted to the "
        "capture (PCA, QE) can absorb the motion this leaves in the face markers, the hand shapes H cannot"
    )


def weights_caveat(metrics: Mapping) -> str:
    """The caveat of quasi-eigen weights no animator could use (empty when QE's largest least-squares |w| is
    within :data:`QE_WEIGHT_BOUND` in every data variant): the largest, and on which variant."""
    found = [
        (float(row["w_max_abs"]), row["data"])
        for row in metrics.get("rows") or []
        if row.get("basis") == "QE"
        and row.get("solver") == "lstsq"
        and row.get("w_max_abs") is not None
        and math.isfinite(float(row["w_max_abs"]))
    ]
    if not found:
        return ""
    largest, data = max(found)
    if largest <= QE_WEIGHT_BOUND:
        return ""
    return (
        f"QE's least-squares weights are unusable for an animator: largest |w| {largest:.3g} on {data}, beyond "
        f"{QE_WEIGHT_BOUND:g} full contractions of a shape; its accuracy rests on shapes that cancel each other"
    )
