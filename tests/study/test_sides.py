"""Left and right: the capture's left/right correlation, what the eigenfaces keep of one-sided shapes, and a
quasi-eigen face pulled to the other side by the affine projection's shared term, on constructed data with known
answers."""

import numpy as np
import pytest

from workbench.numerics.bases import pca_to_qe_weights, quasi_eigen_faces
from workbench.reporting.report.sides import left_side, pair_sides, shared_term, side_pairs, sides_finding, sides_frame


def face() -> np.ndarray:
    """Six points: a left and a right brow, a left and a right mouth corner, two on the midline (x = 0)."""
    return np.array([[30.0, 60, 0], [-30, 60, 0], [25, -30, 0], [-25, -30, 0], [0, 80, 0], [0, -60, 0]])


def shape(axis: int = 1, **moves) -> np.ndarray:
    """A flattened displacement moving the named points (0-5) by the given mm along ``axis`` (1: up)."""
    out = np.zeros((6, 3))
    for point, up in moves.items():
        out[int(point[1:]), axis] = up
    return out.ravel()


NAMES = ["browInnerUp_L", "browInnerUp_R", "mouthSmile_L", "mouthSmile_R"]
HAND = np.array([shape(p0=6.0), shape(p1=6.0), shape(p2=8.0), shape(p3=8.0)])


def symmetric_capture(n_frames: int = 200, one_sided: float = 0.0, offset=None, seed: int = 0) -> np.ndarray:
    """Frames in which both brows rise together (and the mouth corners together), plus ``one_sided`` of a left
    brow alone, plus a constant ``offset`` in every frame."""
    rng = np.random.default_rng(seed)
    brows, mouth, left = rng.normal(size=(3, n_frames))
    frames = (
        brows[:, None] * (HAND[0] + HAND[1]) / 6
        + mouth[:, None] * (HAND[2] + HAND[3]) / 8
        + one_sided * left[:, None] * HAND[0] / 6
    )
    return frames + (0.0 if offset is None else offset)


def eigenfaces(frames: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    mean = frames.mean(axis=0)
    _, _, vt = np.linalg.svd(frames - mean, full_matrices=False)
    return vt[:m], mean


def bases_of(frames: np.ndarray, m: int) -> tuple[dict, np.ndarray, np.ndarray]:
    components, mean = eigenfaces(frames, m)
    bases = {"H": HAND}
    for label, projection in (("QE", "affine"), ("QE-linear", "linear")):
        weights = pca_to_qe_weights(HAND, components, mean, projection)
        bases[label] = quasi_eigen_faces(weights, components, mean, projection)
    return bases, components, mean


def test_pairs_and_sides_come_from_the_names_and_the_hand_peaks():
    assert side_pairs(NAMES + ["jawOpen", "mouthPucker_L"]) == [("browInnerUp", 0, 1), ("mouthSmile", 2, 3)]
    on_left = left_side(face(), HAND[0], HAND[1])
    assert list(on_left) == [True, False, True, False, False, False]  # the midline is neither side's
    # mirrored axes (left at -x) change nothing: sides follow the shapes, not the coordinates
    mirrored = face() * [-1, 1, 1]
    assert list(left_side(mirrored, HAND[0], HAND[1])) == list(on_left)


def test_a_symmetric_capture_keeps_the_symmetric_part_of_a_one_sided_shape():
    frames = symmetric_capture()
    bases, components, _ = bases_of(frames, 2)  # the two eigenfaces span both brows up and both corners up
    brows, mouth = pair_sides(face(), frames, components, NAMES, bases)
    assert brows.pair == "browInnerUp" and brows.correlation == pytest.approx(1.0)
    assert brows.kept["L+R"] == pytest.approx(1.0) and brows.kept["L-R"] == pytest.approx(0.0, abs=1e-12)
    assert brows.kept["L"] == pytest.approx(np.sqrt(0.5))  # a one-sided shape keeps its symmetric half
    # the linear quasi-eigen face of browInnerUp_L moves both brows by 3 mm: no side wins
    (own, other), _ = brows.peaks["QE-linear"]
    assert own == pytest.approx(3.0) and other == pytest.approx(3.0)
    assert brows.crossed("QE-linear") == [] and brows.peaks["H"] == ((6.0, 0.0), (6.0, 0.0))


def test_the_affine_term_pulls_a_weakly_kept_shape_to_the_side_where_the_mean_lies_off_the_eigenfaces():
    # every frame carries a constant 2 mm forward offset of the right brow (a neutral frame away from rest), which
    # no eigenface spans; the brows move together, so browInnerUp_L keeps 3 mm on each brow
    frames = symmetric_capture(offset=shape(axis=2, p1=2.0))
    bases, components, mean = bases_of(frames, 2)
    term = shared_term(face(), components, mean, NAMES, HAND)
    np.testing.assert_allclose(term.norm_mm, np.linalg.norm(mean - (components @ mean) @ components))
    assert term.norm_mm == pytest.approx(2.0, abs=0.05) and term.side == "R" and term.point == 1
    brows = pair_sides(face(), frames, components, NAMES, bases)[0]
    assert brows.crossed("QE-linear") == []  # 3 mm on each side: symmetric, not crossed
    assert brows.crossed("QE") == ["browInnerUp_L"]  # the affine face of the left brow peaks on the right
    (own, other), _ = brows.peaks["QE"]
    assert own == pytest.approx(3.0, abs=0.05) and other == pytest.approx(np.hypot(3.0, 2.0), abs=0.05)
    text = sides_finding("mesh", [brows], term)
    assert "QE faces moving the other side most: browInnerUp_L (3.6 mm against 3.0 on its own side)" in text
    assert "every QE-linear face of a pair moves its own side most" in text
    assert "(I - P) mu, to every quasi-eigen face: 2.0 mm long" in text and "(right)" in text
    # without the offset the same capture gives no crossing
    clean = symmetric_capture()
    bases, components, mean = bases_of(clean, 2)
    assert pair_sides(face(), clean, components, NAMES, bases)[0].crossed("QE") == []


def test_the_table_marks_the_faces_that_cross():
    frames = symmetric_capture(offset=shape(axis=2, p1=2.0))
    bases, components, _ = bases_of(frames, 2)
    table = sides_frame(pair_sides(face(), frames, components, NAMES, bases))
    assert list(table["pair"]) == ["browInnerUp", "mouthSmile"]
    assert (
        table.loc[0, "QE _L own / other"] == "3.0 / 3.6 !" and table.loc[0, "QE-linear _L own / other"] == "3.0 / 3.0"
    )
    assert table.loc[0, "H _L own / other"] == "6.0 / 0.0" and table.loc[0, "kept L-R"] == "0.00"
