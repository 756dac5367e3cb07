"""The paper's regime: eigenfaces fitted at m = n (as many eigenfaces as hand shapes, Kim & Ko's 18 for 18), scored
beside the coverage rule's m as an extra data variant (``basis.paper_regime``)."""

from __future__ import annotations

from dataclasses import replace
from typing import Sequence

import numpy as np

from workbench.dataset.capture import Capture

PAPER_REGIME_SUFFIX = "m=n"
"""The paper-regime variant of data variant ``markers`` is named ``markers m=n``."""

PAPER_REGIME_NOTE = "the paper's regime"
"""How the notes on the paper's regime begin (the m = n variant's, or why a run has none)."""


HELD_OUT_NOTE = " on held-out frames"
"""Appended to :data:`PAPER_REGIME_NOTE` in the note of an m = n variant scored on held-out frames."""


def paper_regime_name(data: str) -> str:
    """The name of the paper-regime variant of a data variant."""
    return f"{data} {PAPER_REGIME_SUFFIX}"


def is_paper_regime(data: str) -> bool:
    """Whether a data variant's name is that of a paper-regime variant."""
    return str(data).endswith(f" {PAPER_REGIME_SUFFIX}")


def coverage_rule_name(data: str) -> str:
    """The coverage rule's data variant of ``data``: ``mesh`` for ``mesh m=n``, ``data`` itself otherwise."""
    return data[: -len(PAPER_REGIME_SUFFIX) - 1] if is_paper_regime(data) else data


def paper_regime_fit(
    capture: Capture,
    paper_regime: bool,
    n_components: int | None,
    fitted_m: int | Sequence[int],
    n_train: Sequence[int] | None = None,
    held_out: bool = False,
) -> tuple[Capture, int | None, str | None]:
    """Whether and how a data variant is also fitted at m = n (``basis.paper_regime``).

    Parameters
    ----------
    capture : Capture
        The capture the coverage rule's bases were fitted on (hand shapes already subset); for a cross-validated
        variant, the capture its folds are cut from.
    paper_regime : bool
        ``basis.paper_regime``, checked.
    n_components : int or None
        ``basis.n_components`` of the coverage rule's fit (set explicitly: no m = n fit).
    fitted_m : int or sequence of int
        The m the coverage rule kept (one per fold for a cross-validated variant).
    n_train : sequence of int, optional
        The training frames of each fold (a cross-validated variant); ``capture``'s training frames otherwise.
    held_out : bool
        Whether the variant is scored on held-out frames (``dataset.held_out``): said in the note.

    Returns
    -------
    capture : Capture
        The capture of the m = n variant, with a note saying what it is (``capture`` itself when there is none).
    n : int or None
        The m of the m = n fit (the hand basis size; it is fitted without alternative bases), or None when there
        is no extra fit: ``paper_regime`` off, ``n_components`` set explicitly, the coverage rule already at
        m = n (in every fold), or fewer directions in the (smallest fold's) training frames than hand shapes.
    note : str or None
        Why no extra fit was made, for the coverage rule's variant (None when made or when the setting is off or m
        is fixed).
    """
    if paper_regime is not True or n_components is not None:
        return capture, None, None
    n = len(capture.hand_names)
    fitted = [int(m) for m in np.atleast_1d(fitted_m)]
    folds = np.ndim(fitted_m) > 0
    frames = capture.train_source if capture.train_source is not None else capture.train
    smallest = min(n_train) if n_train is not None else len(frames)
    rank = min(smallest - 1, frames.shape[1])
    regime = f"{PAPER_REGIME_NOTE}{HELD_OUT_NOTE if held_out else ''}"
    note = regime_skip_note(n, fitted, rank, folds, regime)
    if note is not None:
        return capture, None, note
    rule = f"m = {fitted} (per fold)" if folds else f"m = {fitted[0]}"
    note = (
        f"{regime}: m = n = {n} eigenfaces, as many as hand shapes (Kim & Ko: 18 for 18), fitted on the "
        f"same training frames{' in each fold' if folds else ''} beside the coverage rule's {rule}"
        + (", scored on the same held-out frames" if held_out else "")
        + " (basis.paper_regime)"
    )
    return replace(capture, notes=capture.notes + (note,)), n, None


def regime_skip_note(n: int, fitted: Sequence[int], rank: int, folds: bool, regime: str) -> str | None:
    """Why a variant gets no separate m = n fit (the coverage rule already keeps m = n, or its training frames have
    fewer than n directions), or None when it gets one."""
    where = " in every fold" if folds else ""
    if all(m == n for m in fitted):
        return (
            f"{regime}: the coverage rule already keeps m = n = {n} eigenfaces{where}, so this variant is the "
            "paper's regime (no separate m = n fit)"
        )
    if rank < n:
        return (
            f"{PAPER_REGIME_NOTE}: m = n = {n} eigenfaces need {n} directions, and the training frames"
            f"{' of the smallest fold' if folds else ''} have at most {rank}: no m = n fit"
        )
    return None
