"""The paper's regime: eigenfaces fitted at m = n (as many eigenfaces as hand shapes, Kim & Ko's 18 for 18), scored
beside the coverage rule's m as an extra data variant (``basis.paper_regime``)."""

from __future__ import annotations

from dataclasses import replace

from workbench.dataset.capture import Capture
from workbench.settings.schema import BasisSchema

PAPER_REGIME_SUFFIX = "m=n"
"""The paper-regime variant of data variant ``markers`` is named ``markers m=n``."""

PAPER_REGIME_NOTE = "the paper's regime"
"""How the notes on the paper's regime begin (the m = n variant's, or why a run has none)."""


def paper_regime_name(data: str) -> str:
    """The name of the paper-regime variant of a data variant."""
    return f"{data} {PAPER_REGIME_SUFFIX}"


def is_paper_regime(data: str) -> bool:
    """Whether a data variant's name is that of a paper-regime variant."""
    return str(data).endswith(f" {PAPER_REGIME_SUFFIX}")


def paper_regime_fit(
    capture: Capture, basis: BasisSchema, fitted_m: int
) -> tuple[Capture, BasisSchema | None, str | None]:
    """Whether and how a data variant is also fitted at m = n (``basis.paper_regime``).

    Parameters
    ----------
    capture : Capture
        The capture the coverage rule's bases were fitted on (hand shapes already subset).
    basis : BasisSchema
        The ``basis`` settings the coverage rule's bases were fitted with.
    fitted_m : int
        The m the coverage rule kept.

    Returns
    -------
    capture : Capture
        The capture of the m = n variant, with a note saying what it is (``capture`` itself when there is none).
    basis : BasisSchema or None
        The settings of the m = n fit (``n_components`` = the hand basis size, no alternative bases), or None when
        there is no extra fit: ``paper_regime`` off, ``n_components`` set explicitly, the coverage rule already at
        m = n, or fewer directions in the training frames than hand shapes.
    note : str or None
        Why no extra fit was made, for the coverage rule's variant (None when made or when the setting is off or m
        is fixed).
    """
    if basis.paper_regime is not True or basis.n_components is not None:
        return capture, None, None
    n = len(capture.hand_names)
    if fitted_m == n:
        return (
            capture,
            None,
            (
                f"{PAPER_REGIME_NOTE}: the coverage rule already keeps m = n = {n} eigenfaces, so this "
                "variant is the paper's regime (no separate m = n fit)"
            ),
        )
    frames = capture.train_source if capture.train_source is not None else capture.train
    rank = min(len(frames) - 1, frames.shape[1])
    if rank < n:
        return (
            capture,
            None,
            (
                f"{PAPER_REGIME_NOTE}: m = n = {n} eigenfaces need {n} directions, and the training "
                f"frames have at most {rank}: no m = n fit"
            ),
        )
    note = (
        f"{PAPER_REGIME_NOTE}: m = n = {n} eigenfaces, as many as hand shapes (Kim & Ko: 18 for 18), fitted on the "
        f"same training frames beside the coverage rule's m = {fitted_m} (basis.paper_regime)"
    )
    return (replace(capture, notes=capture.notes + (note,)), replace(basis, n_components=n, alternatives=[]), None)
