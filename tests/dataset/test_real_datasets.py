"""The real-data datasets ``ict_livelink`` and ``animface``: what they build, their errors, and the paper study on
each (at reduced size: every k-th frame, a coarser mesh)."""

import json

import numpy as np
import pandas as pd
import pytest
from in_process import run_workbench

from workbench.api import run
from workbench.core.errors import WorkbenchError
from workbench.dataset import build_captures
from workbench.settings.config import compose, resolved_without_hydra

UPPER = {"browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R", "browDown_L", "browDown_R"}


def dataset_cfg(shared_data, name, *overrides):
    cfg = resolved_without_hydra(compose("paper", [f"dataset={name}", f"paths.data_root={shared_data}", *overrides]))
    return cfg["dataset"]


@pytest.fixture(scope="module")
def ict_livelink(shared_data):
    return build_captures(dataset_cfg(shared_data, "ict_livelink", "dataset.frame_step=40"))


@pytest.fixture(scope="module")
def animface(shared_data):
    return build_captures(dataset_cfg(shared_data, "animface", "dataset.frame_step=20"))


def test_ict_livelink_mesh_and_virtual_markers(ict_livelink):
    assert list(ict_livelink) == ["mesh", "markers"]
    mesh, markers = ict_livelink["mesh"], ict_livelink["markers"]
    assert mesh.n_points == 9409 and mesh.faces.shape == (18460, 3) and markers.n_points == 41
    assert mesh.train.shape == (101, 3 * 9409) and mesh.frame_rate == pytest.approx(30.0 / 40)
    assert mesh.units == "mm" and "ICT FaceKit model origin" in mesh.origin
    # The default hand basis: 18 FACS-style shapes, 6 upper face and 12 lower face.
    assert len(mesh.hand_names) == 18 and len(UPPER & set(mesh.hand_names)) == 6
    assert not {"mouthClose", "PupilDilate_L", "PupilDilate_R"} & set(mesh.hand_names)
    # Virtual markers are the mesh's own vertices: the same motion and hand shapes there.
    vertices = np.array([mesh.point_labels.index(f"v{v}") for v in mesh.provenance["virtual_marker_vertices"].values()])
    as_points = mesh.train.reshape(101, -1, 3)[:, vertices]
    np.testing.assert_allclose(markers.train.reshape(101, -1, 3), as_points)
    np.testing.assert_allclose(markers.hand.reshape(18, -1, 3), mesh.hand.reshape(18, -1, 3)[:, vertices])
    assert sum("TongueOut" in note for note in mesh.notes) == 1
    assert any("cm" in note and "mm" in note for note in mesh.notes)
    assert mesh.provenance["arkit_mapping"]["BrowInnerUp"] == ["browInnerUp_L", "browInnerUp_R"]
    assert any("MIT" in credit and "Donciu-Julin" in credit for credit in mesh.provenance["credits"])


def test_ict_livelink_performance_is_the_weighted_blend(shared_data, ict_livelink):
    """One frame of the mesh performance against an independent sum over the ARKit channels."""
    from workbench.formats.livelink import read_livelink_csv
    from workbench.formats.obj import load_blendshapes

    mesh = ict_livelink["mesh"]
    mapping = mesh.provenance["arkit_mapping"]
    take = read_livelink_csv(shared_data / "livelinkface" / "alex_rom_3.csv")
    face = load_blendshapes(
        shared_data / "ict-facekit" / "FaceXModel",
        neutral_file="generic_neutral_mesh.obj",
        names=sorted({shape for targets in mapping.values() for shape in targets}),
        region_vertices=9409,
        unit_mm=10.0,
    )
    frame = 37  # of every 40th: frame 1480 of the take
    expected = np.zeros((9409, 3))
    for channel, weight in zip(take.names, take.weights[frame * 40]):
        for shape in mapping[channel]:
            expected += weight * face.shapes([shape])[0]
    np.testing.assert_allclose(mesh.train[frame].reshape(-1, 3), expected, atol=1e-9)
    np.testing.assert_allclose(mesh.neutral.reshape(-1, 3), face.neutral)


def test_animface_markers_and_mesh(animface, shared_data):
    assert list(animface) == ["markers", "mesh"]
    markers, mesh = animface["markers"], animface["mesh"]
    n_frames = sum(len(range(0, n, 20)) for n in (1590, 1499, 902))
    # The markers variant scores the 35 face markers; the 6 rigid ones only remove head motion.
    rigid = markers.provenance["rigid_markers"]
    assert len(rigid) == 6 and not set(rigid) & set(markers.point_labels) and markers.n_points == 41 - 6
    assert markers.train.shape == (n_frames, 3 * 35) and mesh.train.shape == (n_frames, 3 * 9409)
    assert markers.point_labels[0] == "Leyebrow_M" and markers.frame_rate == 3.0 and markers.units == "mm"
    for capture in (markers, mesh):
        assert "performer and basis come from different faces" in capture.notes[0]
        assert any(
            "AnimFace by Miguel Ramos Carretero, CC BY-SA 4.0" in credit for credit in capture.provenance["credits"]
        )
    # RBF with smoothing 0 reproduces the marker displacements at the markers' vertices.
    placed = markers.provenance["placement"]["vertices"]
    vertices = [placed[label] for label in markers.point_labels]
    at_markers = mesh.train.reshape(n_frames, -1, 3)[:, vertices]
    np.testing.assert_allclose(at_markers, markers.train.reshape(n_frames, -1, 3), atol=1e-8)
    # Vertices far from every marker (neck, back of the head) are marked extrapolated; the markers' own are not.
    assert markers.point_support is None and mesh.point_support[list(placed.values())].all()
    assert 0.1 < 1 - mesh.point_support.mean() < 0.6
    # The hand basis at the markers is the mesh's hand basis at their vertices (one scaled ICT face).
    np.testing.assert_allclose(markers.hand.reshape(18, -1, 3), mesh.hand.reshape(18, -1, 3)[:, vertices])
    scale = markers.provenance["placement"]["scale"]
    assert 0.9 < scale < 1.1
    residual = markers.provenance["per_take"]["animface_eyebrows.c3d"]["stabilisation_residual_rms_mm"]
    assert residual["mean"] < 2.5 and residual["max"] < 5.0
    # The capture's noise floor, in the provenance (metrics.json) and in the notes the run prints.
    floor = markers.provenance["noise_floor_mm"]
    assert 0.3 < floor["stabilisation_residual_rms"] < 2.5 and 0 < floor["marker_jitter_rms"] < 0.5
    assert (
        sum(
            note.startswith("noise floor: stabilisation residual ") and "below the capture's noise" in note
            for note in markers.notes
        )
        == 1
    )


def test_animface_neutral_is_the_rest_face_of_its_take(animface, shared_data):
    """The default neutral is the jaw take's frame nearest its median pose (head motion removed), and the notes say
    how far it lies from that pose; the take's first frame holds the inner brows off rest."""
    from workbench.dataset.animface import neutral_rest
    from workbench.dataset.rigid import stabilise
    from workbench.formats.c3d import read_c3d_markers

    rest = animface["markers"].provenance["neutral_from_rest_mm"]
    assert rest["take_frame_nearest_rest"] == 1544 and rest["rms"] < 0.8
    assert animface["markers"].provenance["neutral"] == "animface_jaw frame 1544"  # dataset.neutral_frame: null
    assert any(
        note.startswith("the neutral, animface_jaw frame 1544, lies") and "it is the take's frame nearest" in note
        for note in animface["mesh"].notes
    )
    take = read_c3d_markers(shared_data / "animface/animface_jaw.c3d")
    rigid = take.index_of(
        ["ForeHead_M", "ForeHead_L", "ForeHead_R", "NoseTop", "Leye_Inside", "Reye_Inside"], named_in="the test"
    )
    markers = stabilise(take.positions, rigid, take.positions[0, rigid]).markers
    first = neutral_rest(markers, take.labels, 0)
    assert first.nearest_frame == 1544 and first.rms_mm > 2 * rest["rms"]
    brows = [list(take.labels).index(name) for name in ("Reyebrow_Inside", "Leyebrow_Inside")]
    offset = (markers[0] - np.nanmedian(markers, axis=0))[brows, 2]  # forward (z) offset of each inner brow at frame 0
    assert offset[0] < -2.5 and offset[1] > 1.5  # the right inner brow 3 mm back, the left 2 mm forward


def test_neutral_rest_known_answer():
    from workbench.dataset.animface import neutral_rest

    markers = np.zeros((5, 2, 3))
    markers[0, 1] = [3.0, 4.0, 0.0]  # frame 0: the second marker 5 mm off; every other frame at rest
    markers[1:, 0, 0] = [0.1, -0.1, 0.0, 0.2]
    found = neutral_rest(markers, ["a", "b"], 0)
    assert found.largest_marker == "b" and found.largest_mm == pytest.approx(5.0)
    assert found.rms_mm == pytest.approx(np.sqrt(25.0 / 2)) and found.nearest_frame == 3 and found.nearest_rms_mm == 0
    assert "it is the take's frame nearest" in neutral_rest(markers, ["a", "b"], 3).describe("take")


def test_animface_timeline_is_the_files_frames_and_times(animface, shared_data):
    """Every evaluated frame names its take and its frame in that file; its time is that frame over the file's 60 Hz
    (not the sub-sampled index over 60 Hz), so the take lasts as long as the file."""
    from workbench.formats.c3d import read_c3d_markers

    timeline = animface["markers"].timeline()
    assert len(timeline) == len(animface["markers"].eval)
    lengths = {}
    for name in ("jaw", "cheeks", "eyebrows"):
        take = read_c3d_markers(shared_data / f"animface/animface_{name}.c3d")
        assert take.frame_rate == 60.0
        mine = timeline.take == f"animface_{name}"
        np.testing.assert_array_equal(timeline.frame[mine], np.arange(0, take.n_frames, 20))
        np.testing.assert_allclose(timeline.seconds[mine], np.arange(0, take.n_frames, 20) / 60.0)
        lengths[name] = take.n_frames / 60.0
    assert [timeline.take[start] for start, _ in timeline.take_spans()] == [
        "animface_jaw",
        "animface_cheeks",
        "animface_eyebrows",
    ]
    # one axis through the three takes: the whole capture (about 66 s), not the sub-sampled count over 60 Hz
    assert abs(timeline.elapsed()[-1] - sum(lengths.values())) < 20 / 60.0 + 1e-9
    assert timeline.label(1) == "animface_jaw frame 20 (t = 0.33 s)"
    np.testing.assert_array_equal(animface["mesh"].timeline().frame, timeline.frame)


def test_animface_takes_are_configurable(shared_data):
    cfg = dataset_cfg(
        shared_data,
        "animface",
        "dataset.takes=[animface/animface_eyebrows.c3d]",
        "dataset.max_frames_per_take=50",
        "dataset.train_on=markers",
    )
    captures = build_captures(cfg)
    assert list(captures) == ["markers"] and captures["markers"].train.shape == (50, 3 * 35)  # the face markers
    assert "animface_eyebrows 50 frames" in captures["markers"].notes[1]
    # the neutral is this take's own rest face
    assert captures["markers"].provenance["neutral"].startswith("animface_eyebrows frame ")


@pytest.mark.parametrize(
    "override,message",
    [
        (
            "dataset.rigid_markers=[ForeHead_M,NoseTop,Ear_L]",
            r"animface_jaw\.c3d: unknown marker label\(s\) \['Ear_L'\] named in dataset\.rigid_markers",
        ),
        ("dataset.hand_shapes=[jawOpen,smile]", r"dataset\.hand_shapes names \['smile'\], which the blendshape folder"),
        ("dataset.takes=[animface/none.c3d]", r"none\.c3d: C3D file not found"),
        ("dataset.rbf.kernel=spline", r"rbf\.kernel must be one of"),
    ],
)
def test_animface_configuration_errors(shared_data, override, message):
    with pytest.raises(WorkbenchError, match=message):
        build_captures(dataset_cfg(shared_data, "animface", "dataset.max_frames_per_take=20", override))


def test_missing_data_root_is_a_clear_error(tmp_path):
    cfg = resolved_without_hydra(compose("paper", ["dataset=ict_livelink", f"paths.data_root={tmp_path / 'none'}"]))
    with pytest.raises(WorkbenchError, match=r"dataset\.data_root .* is not a folder: set WORKBENCH_DATA_ROOT"):
        build_captures(cfg["dataset"])


def test_geodesic_rbf_beats_euclidean_on_the_ict_ground_truth(ict_livelink):
    """Interpolating the ICT performance from its virtual markers: the configured geodesic RBF is closer to the
    true dense motion than Euclidean thin-plate splines (the reason for animface's default)."""
    from workbench.dataset.rbf import interpolate_frames, mesh_rbf_operator

    mesh, markers = ict_livelink["mesh"], ict_livelink["markers"]
    vertices = np.array(list(mesh.provenance["virtual_marker_vertices"].values()))
    truth = mesh.train.reshape(len(mesh.train), -1, 3)
    neutral = mesh.neutral.reshape(-1, 3)
    errors = {}
    for metric, kernel, epsilon, degree in (
        ("geodesic", "inverse_multiquadric", 0.05, 0),
        ("euclidean", "thin_plate_spline", None, 1),
    ):
        operator = mesh_rbf_operator(
            neutral,
            mesh.faces,
            vertices,
            np.arange(len(neutral)),
            metric=metric,
            kernel=kernel,
            epsilon=epsilon,
            degree=degree,
        )
        estimate = interpolate_frames(operator, markers.train.reshape(len(markers.train), -1, 3))
        errors[metric] = np.sqrt(np.mean(np.sum((estimate - truth) ** 2, axis=2)))
    assert errors["geodesic"] < 0.8 * errors["euclidean"]


def paper_table(shared_data, tmp_path, *overrides):
    text = run(compose("paper", [f"paths.data_root={shared_data}", *overrides]), tmp_path)
    return text, pd.read_csv(tmp_path / "alpha_table.csv"), json.loads((tmp_path / "metrics.json").read_text())


def assert_paper_regime_has_m_equal_n(table):
    """Every row of an 'm=n' variant fits as many eigenfaces as there are hand shapes."""
    regime = table[table["data"].str.endswith(" m=n")]
    hand = regime[regime["basis"] == "H"]
    assert len(regime) and (regime["m"] == hand["n"].iloc[0]).all()


def test_paper_study_on_ict_livelink(shared_data, tmp_path):
    text, table, metrics = paper_table(
        shared_data, tmp_path, "dataset=ict_livelink", "dataset.frame_step=20", "dataset.mesh_vertex_step=4"
    )
    assert list(table["data"].unique()) == ["mesh m=n", "mesh", "markers m=n", "markers"]  # the paper's m = n first
    assert {"H", "QE", "QE-linear", "PCA"} == set(table["basis"])
    assert_paper_regime_has_m_equal_n(table)
    rows = table.set_index(["data", "basis", "solver"])
    for data in ("mesh", "markers"):
        assert rows.loc[(data, "QE", "lstsq"), "alpha_abs_mean"] < rows.loc[(data, "H", "lstsq"), "alpha_abs_mean"]
    assert metrics["data"]["mesh"]["n_points"] == 2353 and metrics["data"]["markers"]["n_points"] == 41
    assert "Live Link Face" in metrics["dataset"]["name"] and "| mesh " in text and "| markers " in text


def test_paper_study_on_animface_trains_on_markers_and_mesh(shared_data, tmp_path):
    text, table, metrics = paper_table(
        shared_data, tmp_path, "dataset=animface", "dataset.frame_step=10", "dataset.mesh_vertex_step=4"
    )
    assert list(table["data"].unique()) == ["markers m=n", "markers", "mesh m=n", "mesh"]
    assert len(table) == 4 * 10
    assert_paper_regime_has_m_equal_n(table)
    assert "performer and basis come from different faces" in text
    assert metrics["dataset"]["provenance"]["performer_and_basis"] == "different faces"
    rows = table.set_index(["data", "basis", "solver"])
    for data in ("markers", "mesh"):
        assert rows.loc[(data, "QE", "lstsq"), "alpha_abs_mean"] < rows.loc[(data, "H", "lstsq"), "alpha_abs_mean"]
        assert rows.loc[(data, "H", "lstsq"), "rms_mm"] < 10.0  # millimetres, not an RBF blow-up


def test_cli_names_an_unknown_marker_label_in_one_line(shared_data, tmp_path):
    result = run_workbench(
        "dataset=animface",
        f"paths.data_root={shared_data}",
        "dataset.rigid_markers=[ForeHead_M,NoseTop,Ear_L]",
        f"hydra.run.dir={tmp_path / 'run'}",
        cwd=tmp_path,
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("workbench: error: ")
    assert "animface_jaw.c3d: unknown marker label(s) ['Ear_L'] named in dataset.rigid_markers" in lines[0]


def test_data_file_checksums_name_every_file_and_folder_a_config_reads(tmp_path):
    import hashlib

    from workbench.dataset.real import data_file_checksums

    (tmp_path / "takes").mkdir()
    (tmp_path / "takes" / "a.c3d").write_bytes(b"first")
    (tmp_path / "faces").mkdir()
    for name, data in (("b.obj", b"bee"), ("a.obj", b"ay")):
        (tmp_path / "faces" / name).write_bytes(data)
    cfg = {
        "kind": "takes",
        "data_root": str(tmp_path),
        "takes": ["takes/a.c3d"],
        "blendshapes": {"folder": "faces", "neutral": "a.obj"},
        "marker_table": "correspondence/animface_ict.csv",
    }
    found = data_file_checksums(cfg)
    assert list(found) == ["takes/a.c3d", "faces", "conf/correspondence/animface_ict.csv"]  # 'kind' names no file
    assert found["takes/a.c3d"] == {"sha256": hashlib.sha256(b"first").hexdigest(), "bytes": 5}
    # a folder: the SHA-256 of `sha256sum *` in it, file names sorted
    lines = "".join(
        f"{hashlib.sha256(data).hexdigest()}  {name}\n" for name, data in (("a.obj", b"ay"), ("b.obj", b"bee"))
    )
    assert found["faces"] == {"sha256": hashlib.sha256(lines.encode()).hexdigest(), "bytes": 5, "files": 2}
    assert data_file_checksums({"kind": "synthetic", "seed": 0}) == {}
