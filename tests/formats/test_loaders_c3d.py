"""C3D markers: labels, rate, units, gaps and damaged files (small files written here), and the AnimFace takes."""

import warnings

import numpy as np
import pytest

from workbench.core.errors import WorkbenchError
from workbench.formats.c3d import read_c3d_markers

LABELS = ["Nose", "Chin", "Brow"]


def write_c3d(path, positions, *, labels=LABELS, units="m", rate=100.0, gaps=(), n_markers=None):
    """A float C3D with ``positions`` (frames, markers, 3) in ``units``; ``gaps``: (frame, marker) invalid;
    ``n_markers`` points per frame (default: one per label)."""
    import c3d

    writer = c3d.Writer(point_rate=rate, point_units=units.ljust(4))
    writer.set_point_labels(labels[:255])
    # A parameter holds at most 255 entries: more labels go on in LABELS2, LABELS3, ... (as Vicon writes them).
    for group, start in enumerate(range(255, len(labels), 255), start=2):
        text, size = c3d.Writer.pack_labels(labels[start : start + 255])
        writer.point_group.add_str(f"LABELS{group}", "More point labels.", text, size, len(labels[start : start + 255]))
    if len(labels) > 255:
        writer.point_group.add_str("DESCRIPTIONS", "Point descriptions.", " " * 255, 1, 255)
    n_markers = len(labels) if n_markers is None else n_markers
    frames = []
    for f, frame in enumerate(positions):
        points = np.zeros((n_markers, 5), dtype=np.float32)
        points[:, :3] = frame
        for gap_frame, marker in gaps:
            if gap_frame == f:
                points[marker, 3] = -1.0
        frames.append((points, np.zeros((0, 0), dtype=np.float32)))  # (points, analog) pairs
    writer.add_frames(frames)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "no analog data"
        with open(path, "wb") as handle:
            writer.write(handle)
    return path


@pytest.fixture
def positions():
    rng = np.random.default_rng(0)
    return (rng.uniform(-0.1, 0.1, (12, 3, 3))).astype(np.float32)  # metres


def test_labels_rate_units_converted_to_mm(tmp_path, positions):
    take = read_c3d_markers(write_c3d(tmp_path / "take.c3d", positions))
    assert take.labels == tuple(LABELS) and take.frame_rate == 100.0 and take.units == "m"
    assert take.n_frames == 12 and take.n_missing == 0
    np.testing.assert_allclose(take.positions, positions.astype(float) * 1000.0, atol=1e-3)
    in_cm = read_c3d_markers(write_c3d(tmp_path / "cm.c3d", positions, units="cm"))
    np.testing.assert_allclose(in_cm.positions, positions.astype(float) * 10.0, atol=1e-4)


def test_invalid_samples_become_nan(tmp_path, positions):
    take = read_c3d_markers(write_c3d(tmp_path / "gaps.c3d", positions, gaps=[(3, 1), (7, 0)]))
    assert take.n_missing == 2
    assert np.isnan(take.positions[3, 1]).all() and np.isnan(take.positions[7, 0]).all()
    assert np.isfinite(take.positions[3, 0]).all()


def test_truncated_c3d_is_one_clear_error(tmp_path, positions):
    path = write_c3d(tmp_path / "take.c3d", positions)
    data = path.read_bytes()
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(data[: len(data) - 600])  # past the padding of the last 512-byte block
    with pytest.raises(WorkbenchError) as error:
        read_c3d_markers(cut)
    assert str(error.value).startswith(f"{cut}: truncated: its header declares 12 frames but the data ends after")
    cut.write_bytes(data[:300])
    with pytest.raises(WorkbenchError, match=r"cut\.c3d: not a readable C3D file"):
        read_c3d_markers(cut)


def test_not_a_c3d_duplicate_labels_unknown_units_and_unknown_labels(tmp_path, positions):
    (tmp_path / "text.c3d").write_text("hello")
    with pytest.raises(WorkbenchError, match=r"text\.c3d: not a readable C3D file"):
        read_c3d_markers(tmp_path / "text.c3d")
    with pytest.raises(WorkbenchError, match=r"dup\.c3d: duplicate marker labels \['Nose'\]"):
        read_c3d_markers(write_c3d(tmp_path / "dup.c3d", positions, labels=["Nose", "Chin", "Nose"]))
    with pytest.raises(WorkbenchError, match=r"ft\.c3d: POINT:UNITS 'ft' is not one of"):
        read_c3d_markers(write_c3d(tmp_path / "ft.c3d", positions, units="ft"))
    take = read_c3d_markers(write_c3d(tmp_path / "take.c3d", positions))
    np.testing.assert_array_equal(take.index_of(["Brow", "Nose"], named_in="a test"), [2, 0])
    with pytest.raises(WorkbenchError) as error:
        take.index_of(["Nose", "Ear_L"], named_in="dataset.rigid_markers")
    assert str(error.value) == (
        f"{take.path}: unknown marker label(s) ['Ear_L'] named in dataset.rigid_markers; "
        "the file's 3 labels are Nose, Chin, Brow"
    )
    with pytest.raises(WorkbenchError, match="C3D file not found"):
        read_c3d_markers(tmp_path / "missing.c3d")


@pytest.mark.parametrize("take_name,n_frames", [("jaw", 1590), ("cheeks", 1499), ("eyebrows", 902)])
def test_animface_takes(shared_data, take_name, n_frames):
    take = read_c3d_markers(shared_data / "animface" / f"animface_{take_name}.c3d")
    assert take.n_frames == n_frames and take.frame_rate == 60.0 and take.units == "mm"
    assert len(take.labels) == 41 and take.n_missing == 0
    assert {"ForeHead_M", "NoseTop", "Leye_Inside", "Reye_Inside", "Mouth_Lend", "Chin"} <= set(take.labels)
    # Millimetres: the inner eye corners of an adult are about 30 mm apart, the face about 150 mm tall.
    eyes = take.positions[0, take.index_of(["Leye_Inside", "Reye_Inside"], named_in="test")]
    assert 20 < np.linalg.norm(eyes[0] - eyes[1]) < 45
    height = np.ptp(take.positions[0, :, 1])
    assert 120 < height < 250


def test_more_than_255_markers_read_every_label_group(tmp_path):
    """Vicon-style files continue the labels in LABELS2: 300 markers must come back with 300 labels."""
    labels = [f"M{i:03d}" for i in range(300)]
    positions = np.random.default_rng(1).uniform(-0.1, 0.1, (4, 300, 3)).astype(np.float32)
    take = read_c3d_markers(write_c3d(tmp_path / "many.c3d", positions, labels=labels))
    assert take.labels == tuple(labels) and take.positions.shape == (4, 300, 3)
    np.testing.assert_allclose(take.positions, positions.astype(float) * 1000.0, atol=1e-3)
    np.testing.assert_array_equal(take.index_of(["M299", "M254", "M255"], named_in="a test"), [299, 254, 255])


def test_label_count_other_than_marker_count_is_one_clear_error(tmp_path, positions):
    short = write_c3d(tmp_path / "short.c3d", np.zeros((2, 4, 3), np.float32), labels=LABELS, n_markers=4)
    with pytest.raises(
        WorkbenchError,
        match=r"short\.c3d: 3 labels in POINT:LABELS, LABELS2, \.\.\. for 4 markers "
        r"\(POINT:USED\); every marker needs one label$",
    ):
        read_c3d_markers(short)
