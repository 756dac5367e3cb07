"""Bad input that was accepted silently, crashed or was reported without naming its culprit: each case is one
line naming the setting or the file and the rule it breaks (exit 2 on the command line).

The tiny face, its data root and its C3D writer are those of ``test_bad_input.py``.
"""

import re
import struct

import numpy as np
import pytest

from test_bad_input import tiny_config, tiny_root, write_c3d  # noqa: F401 - tiny_root is a fixture
from workbench.config import compose
from workbench.dataset import build_captures
from workbench.dataset.c3d_markers import read_c3d_markers
from workbench.dataset.weight_curves import read_weight_curves
from workbench.errors import WorkbenchError
from workbench.schema import check_study_config

SMALL = ["dataset.n_frames=200", "solver=lstsq"]


# ----------------------------------------------------------------------------------------------------------
# Settings: keys no schema knows are refused whatever the prefix; the weight curves' frame rate has a range
# ----------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("override, message", [
    ("+basis.nope=1", "setting basis.nope does not exist; basis has ["),
    ("++basis.nope=1", "setting basis.nope does not exist; basis has ["),
    ("+paths.nope=1", "setting paths.nope does not exist; paths has ['cache_dir', 'data_root', 'output_root']"),
    ("+basis.hand_basis=x", "setting basis.hand_basis does not exist (did you mean dataset.hand_basis?)"),
    ("+metric.nope=1", "setting metric.nope does not exist"),
    ("+solver.lstsq.nope=1", "setting solver.lstsq.nope does not exist; solver.lstsq has ['kind', 'lower', 'upper']"),
    ("+basis.spca.nope=1", "setting basis.spca.nope does not exist; basis.spca has ['alpha', 'max_iter']"),
    ("+paper.alpha.X=3", "setting paper.alpha.X does not exist; paper.alpha has ['H', 'PCA', 'QE']"),
    ("++dataset.foo=1", "dataset.foo has no effect with dataset=synthetic: dataset kind 'synthetic' has no such "
                        "setting"),
])
def test_unknown_keys_are_refused_whatever_the_prefix(override, message):
    cfg = compose("paper", SMALL + [override])
    with pytest.raises(WorkbenchError, match=re.escape(message)) as error:
        check_study_config(cfg, [override], refuse_ineffective=True)
    assert "\n" not in str(error.value)


def test_dataset_settings_added_with_plus_are_still_taken():
    cfg = compose("paper", ["dataset=ict_livelink", "+dataset.weight_curves=take.json",
                            "+dataset.weight_frame_rate=30", "+dataset.eval_on=mesh"])
    check_study_config(cfg)


@pytest.mark.parametrize("rate", ["-30", "0", "1e9"])
def test_weight_frame_rate_must_be_a_capture_rate(rate):
    cfg = compose("paper", ["dataset=ict_livelink", "+dataset.weight_curves=take.json",
                            f"+dataset.weight_frame_rate={rate}"])
    with pytest.raises(WorkbenchError, match=r"^dataset\.weight_frame_rate must be in \(0, 10000\] or null, got "):
        check_study_config(cfg)


# ----------------------------------------------------------------------------------------------------------
# Plausibility: the neutral face's size, on every dataset with a unit setting
# ----------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["ict_livelink", "animface"])
@pytest.mark.parametrize("unit_mm, spans", [(0.1, "7 mm"), (1000.0, "7e+04 mm")])
def test_face_size_names_the_unit_setting(tiny_root, kind, unit_mm, spans):  # noqa: F811
    cfg = tiny_config(tiny_root, kind, blendshapes={"unit_mm": unit_mm})
    message = (f"face: with dataset.blendshapes.unit_mm={unit_mm:g} the neutral face spans {spans}, not a human "
               "face's size (40-1000 mm); dataset.blendshapes.unit_mm (mm per file unit) is off by a factor; set "
               "dataset.plausibility=warn")
    with pytest.raises(WorkbenchError, match=re.escape(message)):
        build_captures(cfg)


def test_face_size_is_a_warning_under_warn(tiny_root):  # noqa: F811
    cfg = tiny_config(tiny_root, "ict_livelink", blendshapes={"unit_mm": 0.1}, plausibility="warn")
    capture = build_captures(cfg)["mesh"]
    assert any("the neutral face spans 7 mm" in note for note in capture.notes)


def test_missing_blendshape_folder_is_named(tiny_root):  # noqa: F811
    cfg = tiny_config(tiny_root, "ict_livelink", blendshapes={"folder": "nope"})
    with pytest.raises(WorkbenchError, match=r"^blendshape folder .*nope not found$"):
        build_captures(cfg)


# ----------------------------------------------------------------------------------------------------------
# Readers: C3D frame ranges, weight curves nested too deep
# ----------------------------------------------------------------------------------------------------------

def test_c3d_header_frames_running_backwards(tmp_path):
    path = write_c3d(tmp_path / "take.c3d", np.random.default_rng(0).uniform(-100, 100, (10, 3, 3)), "ABC")
    data = bytearray(path.read_bytes())
    assert struct.unpack("<HH", data[6:10]) == (1, 10)  # the header's first and last frame
    data[6:10] = struct.pack("<HH", 10, 5)
    path.write_bytes(bytes(data))
    with pytest.raises(WorkbenchError, match=re.escape(f"{path}: its header says the last frame (5) precedes the "
                                                       "first (10)")):
        read_c3d_markers(path)


def test_one_frame_c3d_names_the_file(tmp_path):
    path = write_c3d(tmp_path / "one.c3d", np.random.default_rng(0).uniform(-100, 100, (1, 3, 3)), "ABC")
    with pytest.raises(WorkbenchError, match=re.escape(f"{path}: holds 1 frame; a take needs at least 2")):
        read_c3d_markers(path)


def test_weight_curves_nested_deep_are_refused(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(WorkbenchError, match=re.escape(f"{path}: JSON nested too deeply to be weight curves")):
        read_weight_curves(path)
