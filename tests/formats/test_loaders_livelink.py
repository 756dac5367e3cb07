"""Live Link Face CSV: reading, the ARKit-to-basis mapping and driving a basis; small files and the shared take."""

import numpy as np
import pytest

from workbench.core.errors import WorkbenchError
from workbench.formats.livelink import (
    ARKIT_NAMES,
    ROTATION_NAMES,
    arkit_target_names,
    drive_blendshapes,
    map_arkit_channels,
    parse_timecodes,
    read_livelink_csv,
)

BASIS = [
    "jawOpen",
    "jawLeft",
    "mouthLeft",
    "mouthSmile_L",
    "mouthSmile_R",
    "browInnerUp_L",
    "browInnerUp_R",
    "eyeBlink_L",
    "eyeBlink_R",
    "PupilDilate_L",
]


def write_csv(path, n_frames=5, drop=(), rotations=True, weights=None):
    columns = ["Timecode", "BlendShapeCount"] + [name for name in ARKIT_NAMES if name not in drop]
    if rotations:
        columns += list(ROTATION_NAMES)
    rng = np.random.default_rng(0)
    rows = []
    for i in range(n_frames):
        values = weights[i] if weights is not None else rng.uniform(0, 1, len(columns) - 2)
        # Frames every 2 timecode frames at a 60 fps timecode base: a 30 fps take.
        rows.append([f"13:13:04:{31 + 2 * i:02d}.652", "61"] + [f"{value:.6f}" for value in values])
    path.write_text("\n".join([",".join(columns)] + [",".join(row) for row in rows]) + "\n")
    return path


def test_mapping_rules_left_right_pairs_and_unmapped():
    assert arkit_target_names("JawOpen", BASIS) == ("jawOpen",)
    assert arkit_target_names("JawLeft", BASIS) == ("jawLeft",)  # the whole name first: not jaw_L
    assert arkit_target_names("MouthLeft", BASIS) == ("mouthLeft",)
    assert arkit_target_names("MouthSmileLeft", BASIS) == ("mouthSmile_L",)
    assert arkit_target_names("MouthSmileRight", BASIS) == ("mouthSmile_R",)
    assert arkit_target_names("BrowInnerUp", BASIS) == ("browInnerUp_L", "browInnerUp_R")
    assert arkit_target_names("TongueOut", BASIS) == ()


def test_mapping_matrix_reports_unmapped_channels_and_undriven_shapes_once():
    mapping = map_arkit_channels(ARKIT_NAMES, BASIS)
    assert mapping.matrix.shape == (52, len(BASIS))
    row = mapping.matrix[ARKIT_NAMES.index("BrowInnerUp")]
    assert row[BASIS.index("browInnerUp_L")] == row[BASIS.index("browInnerUp_R")] == 1 and row.sum() == 2
    assert "TongueOut" in mapping.unmapped and "EyeWideLeft" in mapping.unmapped
    assert mapping.undriven == ("PupilDilate_L",)
    lines = mapping.describe()
    assert len(lines) == 2 and sum("TongueOut" in line for line in lines) == 1


def test_mapping_overrides_replace_or_drop_a_channel():
    mapping = map_arkit_channels(ARKIT_NAMES, BASIS, {"JawOpen": ["jawOpen", "mouthLeft"], "MouthSmileLeft": []})
    assert mapping.targets["JawOpen"] == ("jawOpen", "mouthLeft") and "MouthSmileLeft" in mapping.unmapped
    with pytest.raises(WorkbenchError, match=r"arkit_overrides\.JawOpen names shape\(s\) \['jaw'\]"):
        map_arkit_channels(ARKIT_NAMES, BASIS, {"JawOpen": ["jaw"]})
    with pytest.raises(WorkbenchError, match=r"names channel\(s\) \['Jaw'\] that are not ARKit channels"):
        map_arkit_channels(ARKIT_NAMES, BASIS, {"Jaw": ["jawOpen"]})


def test_drive_blendshapes_is_the_linear_blend():
    mapping = map_arkit_channels(ARKIT_NAMES, BASIS)
    deltas = np.random.default_rng(1).normal(size=(len(BASIS), 6))
    weights = np.zeros((2, 52))
    weights[0, ARKIT_NAMES.index("JawOpen")] = 0.5
    weights[1, ARKIT_NAMES.index("BrowInnerUp")] = 1.0
    weights[1, ARKIT_NAMES.index("TongueOut")] = 1.0  # unmapped: no effect
    frames = drive_blendshapes(weights, mapping, deltas)
    np.testing.assert_allclose(frames[0], 0.5 * deltas[0])
    np.testing.assert_allclose(frames[1], deltas[5] + deltas[6])


def test_read_csv_weights_rotations_and_frame_rate(tmp_path):
    weights = np.random.default_rng(2).uniform(0, 1, (4, 61))
    take = read_livelink_csv(write_csv(tmp_path / "take.csv", n_frames=4, weights=weights))
    assert take.names == ARKIT_NAMES and take.n_frames == 4
    np.testing.assert_allclose(take.weights, weights[:, :52], atol=1e-6)
    np.testing.assert_allclose(take.rotations, weights[:, 52:], atol=1e-6)
    assert take.frame_rate == pytest.approx(30.0)
    np.testing.assert_allclose(take.seconds, [0, 2 / 60, 4 / 60, 6 / 60])
    assert read_livelink_csv(write_csv(tmp_path / "bare.csv", rotations=False)).rotations is None


def test_timecodes_across_midnight():
    seconds = parse_timecodes(["23:59:59:58.0", "00:00:00:00.0"], 60.0, path=None)
    np.testing.assert_allclose(seconds, [0.0, 2 / 60])


def test_csv_missing_weight_columns_is_one_clear_error(tmp_path):
    path = write_csv(tmp_path / "partial.csv", drop=("JawOpen", "TongueOut"))
    with pytest.raises(WorkbenchError) as error:
        read_livelink_csv(path)
    assert str(error.value) == f"{path}: missing 2 of the 52 ARKit weight columns: JawOpen, TongueOut"


def test_csv_other_malformations(tmp_path):
    path = write_csv(tmp_path / "text.csv")
    lines = path.read_text().splitlines()
    lines[2] = lines[2].replace(lines[2].split(",")[3], "abc", 1)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(WorkbenchError, match=r"text\.csv: row 3, column EyeLookDownLeft: 'abc' is not a finite"):
        read_livelink_csv(path)
    (tmp_path / "nocode.csv").write_text("Time,JawOpen\n1,0.5\n")
    with pytest.raises(WorkbenchError, match=r"nocode\.csv: no 'Timecode' column"):
        read_livelink_csv(tmp_path / "nocode.csv")
    path = write_csv(tmp_path / "clock.csv")
    path.write_text(path.read_text().replace("13:13:04:33.652", "13:13:04", 1))
    with pytest.raises(WorkbenchError, match=r"clock\.csv: row 3: Timecode '13:13:04' is not HH:MM:SS:FF"):
        read_livelink_csv(path)
    with pytest.raises(WorkbenchError, match="Live Link Face CSV not found"):
        read_livelink_csv(tmp_path / "missing.csv")


def test_shared_take_frames_rate_names_and_mapping_onto_ict(shared_data):
    take = read_livelink_csv(shared_data / "livelinkface" / "alex_rom_3.csv")
    assert take.n_frames == 4030 and take.weights.shape == (4030, 52)
    assert take.frame_rate == pytest.approx(30.0, rel=1e-6)
    assert take.rotations.shape == (4030, 9)
    assert take.weights.min() >= 0 and take.weights.max() < 1.01  # weights in [0, 1] (one slightly above)

    from workbench.formats.obj import expression_names

    names = expression_names(shared_data / "ict-facekit" / "FaceXModel", "generic_neutral_mesh.obj")
    mapping = map_arkit_channels(take.names, names)
    assert mapping.targets["JawOpen"] == ("jawOpen",) and mapping.targets["MouthSmileLeft"] == ("mouthSmile_L",)
    assert mapping.targets["BrowInnerUp"] == ("browInnerUp_L", "browInnerUp_R")
    assert mapping.targets["CheekPuff"] == ("cheekPuff_L", "cheekPuff_R")
    assert mapping.targets["JawLeft"] == ("jawLeft",) and mapping.targets["MouthLeft"] == ("mouthLeft",)
    assert mapping.unmapped == ("TongueOut",)
    assert set(mapping.undriven) == {"PupilDilate_L", "PupilDilate_R", "cheekRaiser_L", "cheekRaiser_R"}


def test_a_csv_pandas_cannot_parse_is_one_line_naming_the_row(tmp_path, shared_data):
    lines = (shared_data / "livelinkface" / "alex_rom_3.csv").read_text().splitlines()
    (tmp_path / "ragged.csv").write_text("\n".join(lines[:5] + [lines[5] + ",1,2"] + lines[6:20]) + "\n")
    with pytest.raises(WorkbenchError) as error:
        read_livelink_csv(tmp_path / "ragged.csv")
    assert str(error.value) == (
        f"{tmp_path / 'ragged.csv'}: not a readable CSV (Error tokenizing data. C error: "
        "Expected 63 fields in line 6, saw 65)"
    )
