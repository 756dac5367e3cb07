"""Plausibility checks on data made here from the shared takes: each rule refused in one line naming the file,
take, marker or vertex, or kept with a warning under dataset.plausibility=warn."""

import json
import re

import numpy as np
import pytest
from omegaconf import OmegaConf

from tests.cli.test_bad_input import write_c3d
from workbench.api import run
from workbench.core.errors import WorkbenchError
from workbench.dataset import build_captures
from workbench.dataset.cache import clear_memory
from workbench.formats.c3d import read_c3d_markers
from workbench.formats.plausibility import check_rigid_set
from workbench.settings.config import compose

TAKE = "animface/animface_eyebrows.c3d"


@pytest.fixture(autouse=True)
def empty_memory():
    clear_memory()
    yield
    clear_memory()


@pytest.fixture
def data_root(shared_data, tmp_path):
    """A data root with the shared ICT folder and Live Link take, and room for changed AnimFace takes."""
    root = tmp_path / "data"
    (root / "animface").mkdir(parents=True)
    (root / "ict-facekit").symlink_to(shared_data / "ict-facekit")
    (root / "livelinkface").symlink_to(shared_data / "livelinkface")
    return root


def changed_take(shared_data, root, name, change, units="mm"):
    take = read_c3d_markers(shared_data / TAKE)
    positions = take.positions.copy()
    change(positions, take.labels)
    write_c3d(root / "animface" / name, positions, take.labels, units=units)
    return f"animface/{name}"


def animface(root, takes, *overrides):
    listed = "[" + ",".join(takes) + "]"
    cfg = compose(
        "paper",
        [
            "dataset=animface",
            f"paths.data_root={root}",
            f"dataset.takes={listed}",
            "dataset.train_on=markers",
            "dataset.frame_step=3",
            *overrides,
        ],
    )
    return OmegaConf.to_container(cfg.dataset, resolve=True)


def test_a_take_in_metres_labelled_mm_is_refused(shared_data, data_root):
    metres = changed_take(shared_data, data_root, "metres.c3d", lambda p, _: p.__itruediv__(1000.0))
    good = changed_take(shared_data, data_root, "good.c3d", lambda p, _: None)
    with pytest.raises(
        WorkbenchError,
        match=re.escape(
            f"{data_root / metres}: markers spread 0.0637 mm from their centroid (file units 'mm'); a face spans "
            "20-500 mm, so the take's units are not what the file says"
        ),
    ):
        build_captures(animface(data_root, [good, metres]))


def test_takes_of_different_units_are_refused(shared_data, data_root):
    inches = changed_take(shared_data, data_root, "inches.c3d", lambda p, _: p.__imul__(4.0))
    good = changed_take(shared_data, data_root, "good.c3d", lambda p, _: None)
    third = changed_take(shared_data, data_root, "third.c3d", lambda p, _: p.__iadd__(0.5))
    with pytest.raises(
        WorkbenchError,
        match=re.escape(
            f"{data_root / inches}: markers spread 255 mm from their "
            f"centroid against 63.7 mm in {data_root / good} (more than "
            "3 x apart"
        ),
    ):
        build_captures(animface(data_root, [good, inches, third]))


def test_a_take_scaled_x4_beside_its_original_is_refused(shared_data, data_root):
    # with two takes, each against the median (their mean) was within 3x; smallest and largest are not
    scaled = changed_take(shared_data, data_root, "scaled.c3d", lambda p, _: p.__imul__(4.0))
    good = changed_take(shared_data, data_root, "good.c3d", lambda p, _: None)
    with pytest.raises(
        WorkbenchError,
        match=re.escape(
            f"{data_root / scaled}: markers spread 255 mm from their centroid against 63.7 mm in {data_root / good}"
        ),
    ):
        build_captures(animface(data_root, [good, scaled]))


def test_a_take_listed_twice_or_copied_is_refused(shared_data, data_root):
    good = changed_take(shared_data, data_root, "good.c3d", lambda p, _: None)
    copy = changed_take(shared_data, data_root, "copy.c3d", lambda p, _: None)
    with pytest.raises(WorkbenchError, match=re.escape(f"dataset.takes: {good} is listed twice")):
        build_captures(animface(data_root, [good, good]))
    with pytest.raises(WorkbenchError, match=re.escape(f"dataset.takes: {copy} holds the same frames as {good}")):
        build_captures(animface(data_root, [good, copy]))


def test_a_c3d_rate_no_camera_records_at_is_refused(shared_data, data_root):
    take = read_c3d_markers(shared_data / TAKE)
    write_c3d(data_root / "animface" / "fast.c3d", take.positions, take.labels, rate=1e9)
    with pytest.raises(
        WorkbenchError,
        match=re.escape(
            f"{data_root / 'animface' / 'fast.c3d'}: POINT:RATE 1e+09 frames per second is not a face capture's "
            "(1-10000); the rate or the time stamps are in other units"
        ),
    ):
        build_captures(animface(data_root, ["animface/fast.c3d"]))


def move_sample(positions, labels):
    positions[300, labels.index("Leyebrow_M"), 1] += 1e6


def test_a_sample_moved_by_a_million_mm_is_named_by_marker_and_frame(shared_data, data_root):
    take = changed_take(shared_data, data_root, "jump.c3d", move_sample)
    with pytest.raises(
        WorkbenchError,
        match=r"jump\.c3d: marker Leyebrow_M is 1e\+06 mm from its median position in "
        r"frame 300 \(1 such sample\(s\)\), more than 20 x the capture's spread",
    ):
        build_captures(animface(data_root, [take]))


def test_a_warned_outlier_is_printed_above_the_table_and_flagged_in_metrics(shared_data, data_root, tmp_path):
    take = changed_take(shared_data, data_root, "jump.c3d", move_sample)
    cfg = compose(
        "paper",
        [
            "dataset=animface",
            f"paths.data_root={data_root}",
            f"dataset.takes=[{take}]",
            "dataset.train_on=markers",
            "dataset.frame_step=3",
            "dataset.plausibility=warn",
            "solver=lstsq",
        ],
    )
    text = run(cfg, tmp_path / "run")
    header = text[: text.index("\n|")]
    assert "note: WARNING: " in header and "marker Leyebrow_M is 1e+06 mm" in header
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    [warning] = metrics["dataset"]["provenance"]["plausibility_warnings"]
    assert "jump.c3d: marker Leyebrow_M" in warning


def test_a_marker_parked_at_the_origin_is_refused(shared_data, data_root):
    def park(positions, labels):
        positions[100:150, labels.index("Chin")] = 0.0

    take = changed_take(shared_data, data_root, "parked.c3d", park)
    with pytest.raises(
        WorkbenchError,
        match=r"parked\.c3d: marker Chin is at the origin \(0, 0, 0\) in 50 frame\(s\) "
        r"\(first: frame 100\)",
    ):
        build_captures(animface(data_root, [take]))


def test_a_repeated_rigid_marker_is_refused(shared_data, data_root):
    take = changed_take(shared_data, data_root, "good.c3d", lambda p, _: None)
    with pytest.raises(WorkbenchError, match=r"dataset\.rigid_markers lists \['NoseTop'\] more than once"):
        build_captures(animface(data_root, [take], "dataset.rigid_markers=[NoseTop,NoseTop,NoseTop]"))


def test_collinear_or_too_few_rigid_markers_are_refused():
    line = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [20.0, 0.01, 0.0]])
    with pytest.raises(WorkbenchError, match=r"\['a', 'b', 'c'\] are \(nearly\) collinear in take\.c3d frame 0"):
        check_rigid_set(["a", "b", "c"], line, "take.c3d frame 0")
    with pytest.raises(WorkbenchError, match=r"has 2 marker\(s\); a head pose needs at least 3"):
        check_rigid_set(["a", "b"], line[:2], "take.c3d frame 0")
    check_rigid_set(["a", "b", "c"], line + [[0, 0, 0], [0, 0, 0], [0, 5.0, 0]], "take.c3d frame 0")


def ict_folder(shared_data, root, leave_out=(), change=None):
    """A FaceXModel folder of links to the shared OBJs, without ``leave_out``; ``change``: (name, edit of its text)."""
    source = shared_data / "ict-facekit" / "FaceXModel"
    folder = root / "ict" / "FaceXModel"
    folder.mkdir(parents=True)
    for path in source.iterdir():
        if path.stem in leave_out:
            continue
        if change and path.stem == change[0]:
            (folder / path.name).write_text(change[1](path.read_text()))
        else:
            (folder / path.name).symlink_to(path)
    return "ict/FaceXModel"


def ict_livelink(root, folder, *overrides):
    cfg = compose(
        "paper",
        [
            "dataset=ict_livelink",
            f"paths.data_root={root}",
            f"dataset.blendshapes.folder={folder}",
            "dataset.train_on=markers",
            "dataset.max_frames=50",
            *overrides,
        ],
    )
    return OmegaConf.to_container(cfg.dataset, resolve=True)


def test_expression_objs_missing_from_the_folder_are_refused(shared_data, data_root):
    folder = ict_folder(shared_data, data_root, leave_out=("eyeBlink_L", "eyeBlink_R"))
    with pytest.raises(
        WorkbenchError,
        match=r"alex_rom_3\.csv with .*FaceXModel: the take uses channel\(s\) "
        r"EyeBlinkLeft \(max weight 0\.\d\d\), EyeBlinkRight .* no shape for them",
    ):
        build_captures(ict_livelink(data_root, folder))


def test_a_hand_shape_missing_from_the_folder_is_refused(shared_data, data_root):
    folder = ict_folder(shared_data, data_root, leave_out=("mouthPucker",))
    with pytest.raises(
        WorkbenchError,
        match=r"dataset\.hand_shapes names \['mouthPucker'\], which the blendshape "
        r"folder does not have",
    ):
        build_captures(ict_livelink(data_root, folder, "dataset.plausibility=warn"))


@pytest.mark.parametrize("value", ["1e6", "1e300"])
def test_an_obj_vertex_far_outside_the_face_is_named(shared_data, data_root, value):
    def move_vertex_10(text):
        lines = text.split("\n")
        index = [i for i, line in enumerate(lines) if line.startswith("v ")][10]
        lines[index] = f"v {value} 0 0"
        return "\n".join(lines)

    folder = ict_folder(shared_data, data_root, change=("browInnerUp_L", move_vertex_10))
    with pytest.raises(
        WorkbenchError,
        match=r"browInnerUp_L\.obj: vertex 10 lies 1e\+(06|300) file units from the "
        r"face's centre along an axis \(1 such vertices\), more than 20 x the neutral",
    ):
        build_captures(ict_livelink(data_root, folder))


def test_the_shared_data_passes_every_check(shared_data):
    for name in ("animface", "ict_livelink"):
        cfg = OmegaConf.to_container(
            compose("paper", [f"dataset={name}", f"paths.data_root={shared_data}", "dataset.train_on=markers"]).dataset,
            resolve=True,
        )
        captures = build_captures(cfg)
        assert not any(note.startswith("WARNING") for note in captures["markers"].notes)


def test_a_take_whose_markers_all_jump_at_one_frame_is_refused_or_warned(shared_data, data_root):
    def jump(positions, labels):
        positions[300:] += np.array([500.0, 0.0, 0.0])

    take = changed_take(shared_data, data_root, "jump.c3d", jump)
    line = (
        f"{data_root / take}: the markers jump 500 mm together (median over markers) from frame 299 to frame 300 "
        "(1 such frame(s)), more than 1 x the face's size (63.7 mm); a head moves a few millimetres a frame"
    )
    with pytest.raises(WorkbenchError, match=re.escape(line)):
        build_captures(animface(data_root, [take]))
    captures = build_captures(animface(data_root, [take], "dataset.plausibility=warn"))
    assert line in captures["markers"].provenance["plausibility_warnings"]


def test_a_take_that_never_moves_is_refused_naming_it(shared_data, data_root):
    take = changed_take(shared_data, data_root, "static.c3d", lambda p, _: p.__setitem__(slice(None), p[0]))
    with pytest.raises(WorkbenchError, match=re.escape(f"{data_root / take}: the take is static: no marker moves")):
        build_captures(animface(data_root, [take]))


def test_a_c3d_rate_of_zero_is_refused_naming_the_rate(shared_data, tmp_path):
    import struct

    take = read_c3d_markers(shared_data / TAKE)
    path = write_c3d(tmp_path / "rate0.c3d", take.positions, take.labels)
    data = path.read_bytes()
    parameters_end = (struct.unpack_from("<H", data, 16)[0] - 1) * 512  # header word 9: first data block
    rate, zero = struct.pack("<f", 60.0), struct.pack("<f", 0.0)
    path.write_bytes(data[:parameters_end].replace(rate, zero) + data[parameters_end:])
    with pytest.raises(WorkbenchError, match=re.escape(f"{path}: POINT:RATE (the frame rate) must be positive, got 0")):
        read_c3d_markers(path)
