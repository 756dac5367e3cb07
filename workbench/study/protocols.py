"""Which frames and hand shapes a run fits and scores on: data variants, held-out frames, the clean capture (its m
and its frames), subsets of the hand shapes."""

from __future__ import annotations

import re
from dataclasses import replace
from typing import Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.capture import Capture
from workbench.dataset.common import name_list
from workbench.settings.schema import HELD_OUT_PROTOCOLS
from workbench.study.fitting import fit_eigenfaces

HELD_OUT = HELD_OUT_PROTOCOLS
"""``dataset.held_out`` protocol -> how its frames are described (:data:`workbench.settings.schema.HELD_OUT_PROTOCOLS`)."""


def held_out_protocols(value) -> list[str]:
    """``dataset.held_out`` (one protocol of :data:`HELD_OUT`, a list of them, or None) as a list (empty when null)."""
    return [] if value is None else [value] if isinstance(value, str) else list(value)


def held_out_capture(capture: Capture, protocol: str, eval_fraction: float) -> Capture:
    """The capture cut into training frames and held-out evaluated frames, from its frames of split 'same'.

    Parameters
    ----------
    capture : Capture
        Trained and evaluated on the same frames.
    protocol : {"tail", "take"}
        ``tail``: the last ``eval_fraction`` of every take is held out (of the one take, as ``split: tail``);
        ``take``: the last take is held out whole, the bases fitted on the others.
    eval_fraction : float

    Returns
    -------
    Capture
    """
    if len(capture.train) != len(capture.eval) or (
        capture.train_source is not None and len(capture.train_source) != len(capture.train)
    ):
        raise WorkbenchError(
            "dataset.held_out needs the training and evaluated frames to be the same frames "
            "(split 'same'; with gap_policy masked, gap_fit_on filled)"
        )
    timeline = capture.timeline()
    spans = timeline.take_spans()
    if protocol == "take":
        if len(spans) < 2:
            raise WorkbenchError(
                "dataset.held_out 'take' holds out the last take, and this capture has one take; use 'tail'"
            )
        held = np.arange(spans[-1][0], spans[-1][1])
        described = (
            f"held out: the last take, {timeline.take[held[0]]}, scored with bases fitted on the other "
            f"{len(spans) - 1} takes"
        )
    else:
        counts = [int(round(eval_fraction * (stop - start))) for start, stop in spans]
        if any(count < 1 or count > stop - start - 2 for count, (start, stop) in zip(counts, spans)):
            raise WorkbenchError(
                f"dataset.eval_fraction {eval_fraction} holds out {counts} frames of takes of "
                f"{[stop - start for start, stop in spans]}; each take needs at least 1 held out "
                "and 2 for training"
            )
        held = np.concatenate([np.arange(stop - count, stop) for count, (_, stop) in zip(counts, spans)])
        described = (
            f"held out: the last {100 * eval_fraction:g} % of {'every' if len(spans) > 1 else 'the'} take, "
            "scored with bases fitted on the rest"
        )
    kept = np.setdiff1d(np.arange(len(capture.eval)), held)
    notes = tuple(note for note in capture.notes if not note.startswith("split '")) + (
        f"{described}: {len(kept)} training frames, {len(held)} evaluated",
    )
    return replace(
        capture,
        train=select_frames(capture.train, kept),
        eval=select_frames(capture.eval, held),
        eval_visible=None if capture.eval_visible is None else capture.eval_visible[held],
        train_source=None if capture.train_source is None else capture.train_source[kept],
        eval_timeline=timeline[held],
        notes=notes,
    )


def select_frames(frames, index: np.ndarray):
    """Some frames of a capture: a slice when ``index`` is a run of consecutive frames (frames on disk stay on
    disk), else a copy in memory."""
    from workbench.numerics.frames import FramesOnDisk

    if index.size and np.all(np.diff(index) == 1):
        start, stop = int(index[0]), int(index[-1]) + 1
        return frames.rows(start, stop) if isinstance(frames, FramesOnDisk) else frames[start:stop]
    if isinstance(frames, FramesOnDisk):
        raise WorkbenchError(
            "dataset.held_out 'tail' of several takes picks frames from each, which frames on disk "
            "(dataset.storage disk) cannot give; use dataset.storage memory or held_out 'take'"
        )
    return frames[index]


CLEAN_M_NOTE = "m chosen on the clean capture"


def with_clean_m(capture: Capture, coverage: float, clean: Capture | None) -> tuple[Capture, int | None]:
    """The capture to fit and the number of eigenfaces to fit it with: unchanged and None (the coverage rule's m)
    without a clean capture; with one, the m the coverage threshold keeps on the clean capture's training frames,
    said in a note.

    Parameters
    ----------
    capture : Capture
    coverage : float
        ``basis.coverage``.
    clean : Capture or None
        The same data variant of the clean capture (:func:`workbench.settings.typed.clean_dataset`).

    Returns
    -------
    capture : Capture
    m : int or None
    """
    if clean is None:
        return capture, None
    clean_pca = fit_eigenfaces(clean, coverage)
    m = int(clean_pca.n_components_)
    note = (
        f"{CLEAN_M_NOTE}: m = {m} eigenfaces reach coverage {clean_pca.coverage_:.4f} >= {coverage} "
        "on the clean capture of the same take (no marker noise, no dropout); the eigenfaces are fitted on this "
        "capture with that m (basis.coverage_on clean)"
    )
    return replace(capture, notes=capture.notes + (note,)), m


def clean_frames(capture: Capture, clean: Capture) -> np.ndarray:
    """The clean capture's frames at the evaluated frames of ``capture``, matched by take and frame number.

    Parameters
    ----------
    capture : Capture
        The evaluated capture (noise, dropout; its frames may be a subset of the take's).
    clean : Capture
        The same data variant of the clean capture (:func:`workbench.settings.typed.clean_dataset`), same points.

    Returns
    -------
    ndarray of shape (n_eval_frames, 3 * n_points)
    """
    ours, theirs = capture.timeline(), clean.timeline()
    if clean.neutral.shape != capture.neutral.shape:
        raise WorkbenchError("metric.score_clean: the clean capture has other points than the evaluated one")
    index = np.full(len(ours), -1)
    for take in np.unique(ours.take):
        mine, pool = np.flatnonzero(ours.take == take), np.flatnonzero(theirs.take == take)
        if pool.size == 0:
            continue
        order = np.argsort(theirs.frame[pool], kind="stable")
        frames = theirs.frame[pool][order]
        at = np.minimum(np.searchsorted(frames, ours.frame[mine]), len(frames) - 1)
        found = frames[at] == ours.frame[mine]
        index[mine[found]] = pool[order[at[found]]]
    if np.any(index < 0):
        raise WorkbenchError(
            f"metric.score_clean: {int((index < 0).sum())} evaluated frames are not among the clean "
            "capture's evaluated frames (frames a gap policy dropped before a tail split); use "
            "dataset.split same or gap_policy linear"
        )
    return np.asarray(clean.eval)[index]


def data_variants(train_on, eval_on) -> tuple[list[str], list[str] | None]:
    """``dataset.train_on`` and ``dataset.eval_on`` (a name or a list of them) as lists of names (``eval_on`` None
    when not set)."""
    if eval_on is not None and train_on is None:
        raise WorkbenchError("dataset.eval_on needs dataset.train_on to name the variants the bases are fitted on")
    return [] if train_on is None else name_list(train_on), None if eval_on is None else name_list(eval_on)


def hand_subset_indices(names: Sequence[str], spec, seed: int) -> np.ndarray:
    """Which hand shapes a ``basis.hand_subset`` setting keeps.

    Parameters
    ----------
    names : sequence of str
        The capture's hand-shape names.
    spec : str or sequence of str
        ``all``; ``upper`` or ``lower`` (the synthetic actor's 6 upper-face and 12 lower-face muscles, as in
        the paper's section 5.3); ``random<k>`` (``k`` shapes drawn without replacement); or a list of names.
    seed : int
        Seed of the draw for ``random<k>`` (``basis.subset_seed``).

    Returns
    -------
    ndarray of int
        Indices into ``names``, ascending.
    """
    from workbench.dataset.synthetic.muscles import LOWER_FACE, UPPER_FACE

    names = list(names)
    if isinstance(spec, str) and spec == "all":
        return np.arange(len(names))
    if isinstance(spec, str) and spec in ("upper", "lower"):
        region = UPPER_FACE if spec == "upper" else LOWER_FACE
        index = np.array([i for i, name in enumerate(names) if name in region], dtype=int)
        if index.size == 0:
            raise WorkbenchError(
                f"basis.hand_subset={spec} names the synthetic actor's {spec}-face muscles, and "
                "this dataset's hand shapes include none of them; list the shapes by name instead"
            )
        return index
    if isinstance(spec, str):
        match = re.fullmatch(r"random(\d+)", spec)
        if match is None:
            raise WorkbenchError(
                f"basis.hand_subset must be all, upper, lower, random<k> or a list of hand-shape names, got {spec!r}"
            )
        k = int(match.group(1))
        if not 1 <= k <= len(names):
            raise WorkbenchError(f"basis.hand_subset=random{k} needs 1 <= k <= {len(names)} (the hand shapes)")
        return np.sort(np.random.default_rng(seed).choice(len(names), size=k, replace=False))
    unknown = [name for name in spec if name not in names]
    if unknown or not spec or len(set(spec)) != len(spec):
        raise WorkbenchError(f"basis.hand_subset as a list must name distinct hand shapes of {names}; got {list(spec)}")
    return np.array(sorted(names.index(name) for name in spec), dtype=int)


def subset_hand_shapes(capture: Capture, hand_subset, subset_seed: int) -> Capture:
    """The capture with only the hand shapes ``basis.hand_subset`` keeps (drawn with ``basis.subset_seed``)."""
    index = hand_subset_indices(capture.hand_names, hand_subset, subset_seed)
    if index.size == len(capture.hand_names):
        return capture
    return select_shapes(capture, [capture.hand_names[i] for i in index])


def select_shapes(capture: Capture, names: Sequence[str]) -> Capture:
    """The capture with the hand shapes of these names, in this order."""
    if tuple(names) == tuple(capture.hand_names):
        return capture
    missing = [name for name in names if name not in capture.hand_names]
    if missing:
        raise WorkbenchError(f"hand shapes {missing} are missing from the evaluated data's hand basis")
    index = [capture.hand_names.index(name) for name in names]
    return replace(capture, hand=capture.hand[index], hand_names=tuple(names))
