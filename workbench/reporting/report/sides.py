"""Left and right: where each one-sided hand shape and its quasi-eigen faces peak, and why a quasi-eigen face can
peak on the other side.

Two things move a one-sided shape when it is projected onto the eigenfaces (eq. 3-4). A capture whose two sides
move together (brows raised together) spans the pair's symmetric part ``e_L + e_R`` better than its one-sided
part ``e_L - e_R``, so the projection keeps mostly the symmetric half. And the affine projection (as written)
adds the same vector ``(I - P) mu`` to every quasi-eigen face: the part of the capture mean the eigenfaces do not
span. Where that vector is larger than what a small shape keeps, the shape's quasi-eigen face peaks where the
vector peaks. The functions here measure both from a run's saved inputs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from workbench.numerics import metrics

OTHER_SIDE_MARGIN = 1.1
"""A face moves the other side of the face most when its largest displacement there exceeds the largest on its own
side by this factor (closer than that, the face is about as large on both sides: symmetric, not crossed)."""


@dataclass(frozen=True)
class PairSides:
    """One left/right pair of hand shapes and how one-sided it and its quasi-eigen faces are.

    Attributes
    ----------
    pair : str
        The shapes' common stem (``browInnerUp`` for ``browInnerUp_L`` and ``browInnerUp_R``).
    correlation : float
        Correlation over the evaluated frames of the captured motion at the two hand shapes' peaks (each along
        its shape's direction there): near 1 when the capture moves the two sides together.
    kept : dict
        ``L``, ``R``, ``L+R``, ``L-R`` -> ``|P e| / |e|``, the share of each shape's length the eigenfaces span.
    peaks : dict
        Basis label (``H``, ``QE``, ``QE-linear``) -> for the ``_L`` and the ``_R`` shape, (its largest point
        displacement on its own side of the face, on the other side), in mm.
    """

    pair: str
    correlation: float
    kept: dict
    peaks: dict

    def crossed(self, label: str) -> list[str]:
        """The shapes of the pair whose face in basis ``label`` moves the other side of the face most."""
        return [
            f"{self.pair}_{side}"
            for side, (own, other) in zip("LR", self.peaks[label])
            if other > OTHER_SIDE_MARGIN * own
        ]


def side_pairs(names: Sequence[str]) -> list[tuple[str, int, int]]:
    """(stem, index of ``<stem>_L``, index of ``<stem>_R``) for every left/right pair among the shape names."""
    index = {name: i for i, name in enumerate(names)}
    return [
        (name[:-2], index[name], index[name[:-2] + "_R"])
        for name in names
        if name.endswith("_L") and name[:-2] + "_R" in index
    ]


def point_norms(shape: np.ndarray, support: np.ndarray | None = None) -> np.ndarray:
    """Displacement length at every point of a flattened shape, 0 outside ``support``."""
    norms = metrics.point_norms(shape)
    return norms if support is None else np.where(support, norms, 0.0)


def left_side(
    points: np.ndarray, hand_left: np.ndarray, hand_right: np.ndarray, support: np.ndarray | None = None
) -> np.ndarray:
    """Which points lie on the side of the face of a pair's ``_L`` shape: the side of its peak, with the midline
    halfway between the ``_L`` and ``_R`` shapes' peaks (no assumption on the axes).

    Parameters
    ----------
    points : ndarray of shape (n_points, 3)
    hand_left, hand_right : ndarray of shape (3 * n_points,)
    support : ndarray of shape (n_points,) of bool, optional

    Returns
    -------
    ndarray of shape (n_points,) of bool
    """
    peak_left, peak_right = (points[int(np.argmax(point_norms(shape, support)))] for shape in (hand_left, hand_right))
    across = peak_left - peak_right
    return (points - 0.5 * (peak_left + peak_right)) @ across > 0


def pair_sides(
    neutral: np.ndarray,
    frames: np.ndarray,
    components: np.ndarray,
    names: Sequence[str],
    bases: Mapping[str, np.ndarray],
    support: np.ndarray | None = None,
) -> list[PairSides]:
    """How one-sided every left/right pair of hand shapes and its quasi-eigen faces are, with the capture's
    left/right correlation and the share of each shape the eigenfaces span.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_points,)
    frames : ndarray of shape (n_frames, 3 * n_points)
        Captured displacements (the evaluated frames; frames with a gap are left out).
    components : ndarray of shape (m, 3 * n_points)
        The eigenfaces (orthonormal rows).
    names : sequence of str
        The hand shapes' names, in the order of the bases' rows.
    bases : mapping
        Basis label -> ndarray of shape (n_shapes, 3 * n_points); ``H`` is the hand basis.
    support : ndarray of shape (n_points,) of bool, optional
        Points with data (displacements are compared there only).

    Returns
    -------
    list of PairSides
        In the order of the names.
    """
    points = np.asarray(neutral).reshape(-1, 3)
    frames = np.asarray(frames)
    frames = frames[np.isfinite(frames).all(axis=1)].reshape(-1, len(points), 3)
    hand = bases["H"]
    found = []
    for stem, left, right in side_pairs(names):
        on_left = left_side(points, hand[left], hand[right], support)
        motion = []
        for i in (left, right):
            peak = int(np.argmax(point_norms(hand[i], support)))
            direction = hand[i].reshape(-1, 3)[peak]
            motion.append(frames[:, peak] @ (direction / np.linalg.norm(direction)))
        correlation = float(np.corrcoef(*motion)[0, 1]) if len(frames) > 2 else float("nan")
        parts = {"L": hand[left], "R": hand[right], "L+R": hand[left] + hand[right], "L-R": hand[left] - hand[right]}
        kept = {key: float(np.linalg.norm(components @ part) / np.linalg.norm(part)) for key, part in parts.items()}
        peaks = {}
        for label, shapes in bases.items():
            peaks[label] = tuple(
                (float(heights[own].max(initial=0.0)), float(heights[~own].max(initial=0.0)))
                for heights, own in (
                    (point_norms(shapes[left], support), on_left),
                    (point_norms(shapes[right], support), ~on_left),
                )
            )
        found.append(PairSides(pair=stem, correlation=correlation, kept=kept, peaks=peaks))
    return found


@dataclass(frozen=True)
class SharedTerm:
    """``(I - P) mu``: what the affine projection adds to every quasi-eigen face.

    Attributes
    ----------
    norm_mm, mean_norm_mm : float
        Its length and the capture mean's (over every coordinate).
    largest_mm : float
        Its largest displacement at one point, at ``point`` (index), on side ``side`` of the face (``L``, ``R``
        or ``midline`` when within 5 % of the face's width of it).
    point : int
    side : str
    """

    norm_mm: float
    mean_norm_mm: float
    largest_mm: float
    point: int
    side: str


def shared_term(
    neutral: np.ndarray,
    components: np.ndarray,
    mean: np.ndarray,
    names: Sequence[str],
    hand: np.ndarray,
    support: np.ndarray | None = None,
) -> SharedTerm:
    """The part of the capture mean outside the eigenfaces' span, which eq. 4 adds to every quasi-eigen face.

    Its side is read against the first left/right pair of hand shapes (:func:`left_side`); ``midline`` when it
    peaks within 5 % of the face's width of the midline, or there is no pair.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_points,)
    components : ndarray of shape (m, 3 * n_points)
    mean : ndarray of shape (3 * n_points,)
    names : sequence of str
    hand : ndarray of shape (n_shapes, 3 * n_points)
    support : ndarray of shape (n_points,) of bool, optional

    Returns
    -------
    SharedTerm
    """
    points = np.asarray(neutral).reshape(-1, 3)
    term = mean - (components @ mean) @ components
    heights = point_norms(term, support)
    top = int(np.argmax(heights))
    side = "midline"
    pairs = side_pairs(names)
    if pairs:
        _, left, right = pairs[0]
        peak_left, peak_right = (points[int(np.argmax(point_norms(hand[i], support)))] for i in (left, right))
        across = (peak_left - peak_right) / np.linalg.norm(peak_left - peak_right)
        offset = float((points[top] - 0.5 * (peak_left + peak_right)) @ across)
        if abs(offset) > 0.05 * float(np.ptp(points @ across)):
            side = "L" if offset > 0 else "R"
    return SharedTerm(
        norm_mm=float(np.linalg.norm(term)),
        mean_norm_mm=float(np.linalg.norm(mean)),
        largest_mm=float(heights[top]),
        point=top,
        side=side,
    )


SIDE_WORDS = {"L": "left", "R": "right", "midline": "midline"}


def millimetre_decimals(pairs: Sequence[PairSides]) -> int:
    """One number format for every displacement of the pairs: two significant digits of the smallest hand peak."""
    from workbench.reporting.figures import fixed_decimals

    return fixed_decimals([sides[0] for pair in pairs for sides in pair.peaks["H"]], significant=2)


def sides_frame(pairs: Sequence[PairSides]) -> pd.DataFrame:
    """The pairs as a table: the capture's correlation, the share each part keeps, and for each basis the largest
    displacement of the ``_L`` and the ``_R`` face on its own side and on the other (mm, ``own / other``; ``!``
    where the other side moves most, :data:`OTHER_SIDE_MARGIN`)."""
    decimals = millimetre_decimals(pairs)
    rows = []
    for pair in pairs:
        row = {"pair": pair.pair, "capture L/R correlation": f"{pair.correlation:.2f}"}
        row.update({f"kept {key}": f"{value:.2f}" for key, value in pair.kept.items()})
        for label, sides in pair.peaks.items():
            for side, (own, other) in zip("LR", sides):
                crossed = other > OTHER_SIDE_MARGIN * own
                row[f"{label} _{side} own / other"] = f"{own:.{decimals}f} / {other:.{decimals}f}" + (
                    " !" if crossed else ""
                )
        rows.append(row)
    return pd.DataFrame.from_records(rows)


def sides_finding(data: str, pairs: Sequence[PairSides], term: SharedTerm | None, qe_label: str = "QE") -> str:
    """One finding from the pairs: how together the capture moves the two sides of the face, what the eigenfaces
    keep of a pair's symmetric and one-sided parts, what the affine projection adds to every quasi-eigen face, and
    which quasi-eigen faces move the other side of the face most."""
    if not pairs:
        return ""
    correlations = [pair.correlation for pair in pairs]
    text = (
        f"**{data}**: the capture moves the two sides of the face together (correlation of the motion at the "
        f"_L and _R hand peaks {min(correlations):.2f} to {max(correlations):.2f} over the {len(pairs)} left/right "
        "pairs), so the eigenfaces keep more of a pair's symmetric part L+R than of its one-sided part L-R "
        f"(|P e| / |e|, median {np.median([pair.kept['L+R'] for pair in pairs]):.2f} against "
        f"{np.median([pair.kept['L-R'] for pair in pairs]):.2f})"
    )
    weakest = min(pairs, key=lambda pair: pair.kept["L-R"])
    text += (
        f"; least of {weakest.pair} (correlation {weakest.correlation:.2f}; L+R {weakest.kept['L+R']:.2f}, L-R "
        f"{weakest.kept['L-R']:.2f}; {weakest.pair}_L {weakest.kept['L']:.2f}, {weakest.pair}_R "
        f"{weakest.kept['R']:.2f})"
    )
    if term is not None:
        text += (
            f"; the affine projection adds the capture mean's part outside the eigenfaces, (I - P) mu, to every "
            f"quasi-eigen face: {term.norm_mm:.1f} mm long ({100 * term.norm_mm / term.mean_norm_mm:.0f} % of the "
            f"mean), largest {term.largest_mm:.{millimetre_decimals(pairs)}f} mm at one point "
            f"({SIDE_WORDS[term.side]})"
        )
    decimals = millimetre_decimals(pairs)
    for label in (label for label in pairs[0].peaks if label != "H"):
        crossed = [(pair, name) for pair in pairs for name in pair.crossed(label)]
        listed = ", ".join(
            f"{name} ({pair.peaks[label]['LR'.index(name[-1])][1]:.{decimals}f} mm against "
            f"{pair.peaks[label]['LR'.index(name[-1])][0]:.{decimals}f} on its own side)"
            for pair, name in crossed
        )
        text += (
            f"; {label} faces moving the other side most: {listed}"
            if crossed
            else f"; every {label} face of a pair moves its own side most"
        )
    return text + "."
