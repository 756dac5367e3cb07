"""Weight curves beyond Live Link Face: MediaPipe face blendshapes and generic CSV/JSON (small files written here),
bad input, and the ICT face driven by them equals the ICT face driven by the same weights as Live Link Face CSV."""

import json

import numpy as np
import pandas as pd
import pytest

from workbench.core.errors import WorkbenchError
from workbench.formats.livelink import ARKIT_NAMES, map_arkit_channels, read_livelink_csv
from workbench.formats.weight_curves import read_weight_curves

MEDIAPIPE_NAMES = ["_neutral", "browDownLeft", "browInnerUp", "jawOpen", "mouthSmileLeft", "mouthSmileRight"]


def mediapipe_results(weights, *, timestamps_ms=None, camel=False):
    """MediaPipe face-landmarker results, one per frame, as its Python (or, camel=True, JS) API serialises them."""
    name_key, faces_key, time_key = (
        ("categoryName", "faceBlendshapes", "timestampMs")
        if camel
        else ("category_name", "face_blendshapes", "timestamp_ms")
    )
    frames = []
    for i, row in enumerate(weights):
        categories = [
            {"index": j, name_key: name, "score": float(score)}
            for j, (name, score) in enumerate(zip(MEDIAPIPE_NAMES, row))
        ]
        frame = {faces_key: [{"categories": categories} if camel else categories]}
        if timestamps_ms is not None:
            frame[time_key] = timestamps_ms[i]
        frames.append(frame)
    return frames


@pytest.fixture
def weights():
    return np.random.default_rng(0).uniform(0.0, 1.0, (6, len(MEDIAPIPE_NAMES)))


@pytest.mark.parametrize("camel", [False, True])
def test_mediapipe_json_drops_neutral_and_keeps_names_times(tmp_path, weights, camel):
    path = tmp_path / "face.json"
    path.write_text(
        json.dumps(mediapipe_results(weights, timestamps_ms=[1000 + 33.3 * i for i in range(6)], camel=camel))
    )
    take = read_weight_curves(path)
    assert take.names == tuple(MEDIAPIPE_NAMES[1:]) and take.rotations is None
    np.testing.assert_allclose(take.weights, weights[:, 1:])
    np.testing.assert_allclose(take.seconds, np.arange(6) * 0.0333, atol=1e-9)
    assert take.frame_rate == pytest.approx(1 / 0.0333)


def test_mediapipe_names_map_like_arkit_with_the_override_table():
    basis = ["browDown_L", "browInnerUp_L", "browInnerUp_R", "jawOpen", "mouthSmile_L", "mouthSmile_R"]
    mapping = map_arkit_channels(MEDIAPIPE_NAMES[1:], basis, {"mouthSmileRight": []})
    assert mapping.targets["browDownLeft"] == ("browDown_L",)
    assert mapping.targets["browInnerUp"] == ("browInnerUp_L", "browInnerUp_R")
    assert mapping.targets["mouthSmileLeft"] == ("mouthSmile_L",) and mapping.unmapped == ("mouthSmileRight",)


def test_generic_csv_with_time_or_frames_and_json_object(tmp_path, weights):
    table = pd.DataFrame(weights, columns=MEDIAPIPE_NAMES)
    table.insert(0, "time", np.arange(6) / 25.0)
    table.to_csv(tmp_path / "timed.csv", index=False)
    timed = read_weight_curves(tmp_path / "timed.csv")
    assert timed.names == tuple(MEDIAPIPE_NAMES[1:]) and timed.frame_rate == pytest.approx(25.0)
    np.testing.assert_allclose(timed.weights, weights[:, 1:])
    table = table.drop(columns="time")
    table.insert(0, "frame", np.arange(10, 16))
    table.to_csv(tmp_path / "framed.csv", index=False)
    framed = read_weight_curves(tmp_path / "framed.csv", frame_rate=50.0)
    np.testing.assert_allclose(framed.seconds, np.arange(6) / 50.0)
    (tmp_path / "curves.json").write_text(
        json.dumps({"names": MEDIAPIPE_NAMES, "weights": weights.tolist(), "frame_rate": 60})
    )
    document = read_weight_curves(tmp_path / "curves.json")
    assert document.frame_rate == pytest.approx(60.0) and document.weights.shape == (6, 5)


def test_livelink_csv_goes_to_the_livelink_reader(tmp_path, shared_data):
    take = read_weight_curves(shared_data / "livelinkface" / "alex_rom_3.csv")
    assert take.names == ARKIT_NAMES and take.rotations is not None and take.n_frames == 4030


def test_bad_weight_curves_are_one_line_errors(tmp_path, weights):
    def fails(name, text, pattern, **options):
        (tmp_path / name).write_text(text)
        with pytest.raises(WorkbenchError, match=pattern) as error:
            read_weight_curves(tmp_path / name, **options)
        assert "\n" not in str(error.value)

    header = ",".join(MEDIAPIPE_NAMES)
    rows = "\n".join(",".join(f"{v:.3f}" for v in row) for row in weights)
    fails("untimed.csv", f"{header}\n{rows}\n", r"untimed\.csv: no time column \(time, timestamp_ms\) or frame column")
    framed = f"frame,{header}\n" + "\n".join(f"{i}," + line for i, line in enumerate(rows.splitlines()))
    fails("framed.csv", framed, r"framed\.csv: frames are numbered, not timed: set the frame rate")
    fails("rate.csv", framed, r"rate\.csv: frame rate must be a positive, finite number, got 0", frame_rate=0)
    fails(
        "percent.csv",
        "time,jawOpen\n0,10\n0.1,50\n",
        r"percent\.csv: row 2, column jawOpen: weight 10 is outside "
        r"\[0, 1\]",
    )
    fails(
        "back.csv",
        "time,jawOpen\n0,0.1\n0.1,0.2\n0.05,0.3\n",
        r"back\.csv: frame times must increase from row "
        r"to row \(row 4 does not\)",
    )
    fails("text.csv", "time,jawOpen\n0,0.1\n0.1,open\n", r"text\.csv: row 3, column jawOpen: 'open' is not a finite")
    fails(
        "twice.csv",
        "time,jawOpen,jawOpen\n0,0.1,0.1\n0.1,0.2,0.2\n",
        r"twice\.csv: column\(s\) \['jawOpen'\] "
        r"appear more than once",
    )
    fails("one.csv", "time,jawOpen\n0,0.1\n", r"one\.csv: 1 frame\(s\); a take needs at least 2")
    fails("list.json", "[1, 2]", r"list\.json: frame 0: no face_blendshapes")
    results = mediapipe_results(weights[:2], timestamps_ms=[0, 33])
    results[1]["face_blendshapes"][0] = results[1]["face_blendshapes"][0][::-1]
    fails("order.json", json.dumps(results), r"order\.json: frame 1: its blendshape names differ from frame 0's")
    fails(
        "shape.json",
        json.dumps({"names": ["a", "b"], "weights": [[0.1], [0.2]], "frame_rate": 30}),
        r"shape\.json: 'weights' must have one row per frame of 2 numbers",
    )
    fails("bad.json", "{", r"bad\.json: not valid JSON")
    fails("curves.txt", "x", r"curves\.txt: weight curves must be a \.csv or \.json file")
    with pytest.raises(WorkbenchError, match=r"missing\.csv: weight-curve file not found"):
        read_weight_curves(tmp_path / "missing.csv")


def test_ict_face_driven_by_mediapipe_json_equals_the_livelink_take(tmp_path, shared_data):
    """The same real weights, as MediaPipe JSON (camelCase names, _neutral, ms timestamps) and as Live Link Face
    CSV, drive the ICT face to the same capture."""
    from workbench.dataset import build_captures
    from workbench.settings.config import compose

    take = read_livelink_csv(shared_data / "livelinkface" / "alex_rom_3.csv")
    n = 120
    camel = [name[:1].lower() + name[1:] for name in ARKIT_NAMES]
    frames = [
        {
            "timestamp_ms": float(1000.0 * take.seconds[i]),
            "face_blendshapes": [
                [{"category_name": "_neutral", "score": 0.0}]
                + [{"category_name": name, "score": float(w)} for name, w in zip(camel, take.weights[i])]
            ],
        }
        for i in range(n)
    ]
    (tmp_path / "take.json").write_text(json.dumps(frames))
    base = [
        "dataset=ict_livelink",
        f"dataset.max_frames={n}",
        "dataset.train_on=markers",
        f"paths.data_root={shared_data}",
    ]
    livelink = build_captures(compose("paper", base).dataset)["markers"]
    mediapipe = build_captures(compose("paper", base + [f"+dataset.weight_curves={tmp_path / 'take.json'}"]).dataset)[
        "markers"
    ]
    np.testing.assert_allclose(mediapipe.eval, livelink.eval, rtol=1e-12, atol=1e-12)
    assert mediapipe.frame_rate == pytest.approx(livelink.frame_rate, rel=1e-9)
    assert "take.json" in mediapipe.name and mediapipe.provenance["files"]["weight_curves"].endswith("take.json")


def test_timestamps_must_be_numbers_for_every_frame(tmp_path, weights):
    path = tmp_path / "face.json"
    for times, message in (
        ([0, 33, "66", 99, 132, 165], r"frame 2: timestamp_ms '66' is not a number"),
        ([0, 33, True, 99, 132, 165], r"frame 2: timestamp_ms True is not a number"),
        ([0, 33, None, 99, 132, 165], r"frame 2 has no timestamp_ms but frame 0 has one"),
    ):
        results = mediapipe_results(weights, timestamps_ms=times)
        results[2].pop("timestamp_ms") if times[2] is None else None
        path.write_text(json.dumps(results))
        with pytest.raises(WorkbenchError, match=message):
            read_weight_curves(path)
    path.write_text(
        json.dumps({"names": MEDIAPIPE_NAMES, "weights": weights.tolist(), "time": [0, 0.1, "x", 0.3, 0.4, 0.5]})
    )
    with pytest.raises(WorkbenchError, match=r"'time' must hold 6 finite numbers \(seconds\), one per frame"):
        read_weight_curves(path)
