"""The real-data steps of the public API: a notebook that builds the real datasets' arrays from the readers and
these functions alone gets the arrays of ``build_captures`` and the same alpha."""

import numpy as np
import pytest

import workbench
from workbench.settings.config import REPO_ROOT

HAND = [
    "browInnerUp_L",
    "browInnerUp_R",
    "browOuterUp_L",
    "browOuterUp_R",
    "browDown_L",
    "browDown_R",
    "jawOpen",
    "mouthSmile_L",
    "mouthSmile_R",
    "mouthFrown_L",
    "mouthFrown_R",
    "mouthStretch_L",
    "mouthStretch_R",
    "mouthUpperUp_L",
    "mouthUpperUp_R",
    "mouthLowerDown_L",
    "mouthLowerDown_R",
    "mouthPucker",
]
RIGID = ["ForeHead_M", "ForeHead_L", "ForeHead_R", "NoseTop", "Leye_Inside", "Reye_Inside"]
TABLE = REPO_ROOT / "conf" / "correspondence" / "animface_ict.csv"
STEP = 20  # every 20th frame: about 200 frames over the whole take (a few seconds)


def same_alpha(frames, hand, neutral, capture):
    """The notebook's arrays equal the capture's (the ICT frames to round-off: the builder multiplies a chunk of
    frames at a time, 3e-15 mm apart; the rest exactly), and the estimator fitted on each gives the same alpha."""
    np.testing.assert_allclose(frames, capture.train, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(hand, capture.hand)
    np.testing.assert_array_equal(neutral, capture.neutral)
    alphas = [
        workbench.QuasiEigenFaces(hand_shapes=shapes, neutral=rest).fit(data).alpha(data, solver=solver)
        for shapes, rest, data in ((hand, neutral, frames), (capture.hand, capture.neutral, capture.train))
        for solver in ("lstsq", "nnls")
    ]
    assert abs(alphas[0] - alphas[2]) <= 1e-12 and abs(alphas[1] - alphas[3]) <= 1e-12


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:QuasiEigenFaces. the quasi-eigen basis is rank-deficient")  # m < 18, as in a run
def test_a_notebook_builds_the_ict_livelink_arrays(shared_data, tmp_path):
    overrides = [
        "dataset=ict_livelink",
        f"paths.data_root={shared_data}",
        f"dataset.frame_step={STEP}",
    ]
    captures = workbench.build_captures(workbench.compose_config("paper", overrides), cache_dir=str(tmp_path))

    take = workbench.read_livelink(shared_data / "livelinkface" / "alex_rom_3.csv")
    face = workbench.read_blendshapes(
        shared_data / "ict-facekit" / "FaceXModel", neutral="generic_neutral_mesh.obj", region_vertices=9409, unit_mm=10
    )
    overrides = {"TongueOut": []}  # ICT FaceKit has no tongue shape
    every = workbench.arkit_mapping(take.names, face.names, overrides)
    assert every.targets["JawLeft"] == ("jawLeft",)  # no _L: ICT's jaw shapes have no side
    assert every.targets["BrowInnerUp"] == ("browInnerUp_L", "browInnerUp_R")
    used = [name for name in face.names if name not in every.undriven or name in HAND]
    deltas = face.deltas[[face.names.index(name) for name in used]]
    mapping = workbench.arkit_mapping(take.names, used, overrides)
    weights = take.weights[::STEP] @ mapping.matrix
    hand_rows = [used.index(name) for name in HAND]

    vertices = workbench.read_marker_table(TABLE, n_vertices=9409).vertices
    for name, points in (("markers", vertices), ("mesh", np.arange(9409))):
        point_deltas = deltas[:, points].reshape(len(used), -1)
        frames = weights @ point_deltas
        same_alpha(frames, point_deltas[hand_rows], face.neutral[points].reshape(-1), captures[name])


@pytest.mark.slow
def test_a_notebook_builds_the_animface_arrays(shared_data, tmp_path):
    overrides = [
        "dataset=animface",
        f"paths.data_root={shared_data}",
        f"dataset.frame_step={STEP // 2}",
        "dataset.train_on=[markers,mesh]",
    ]
    captures = workbench.build_captures(workbench.compose_config("paper", overrides), cache_dir=str(tmp_path))

    table = workbench.read_marker_table(TABLE, n_vertices=9409)
    rigid = [table.labels.index(label) for label in RIGID]
    takes = [
        workbench.read_c3d(shared_data / "animface" / f"animface_{name}.c3d") for name in ("jaw", "cheeks", "eyebrows")
    ]
    in_table = [take.positions[:, [take.labels.index(label) for label in table.labels]] for take in takes]
    neutral_frame = workbench.rest_frame(in_table[0], rigid)  # dataset.neutral_frame: null
    marker_neutral = in_table[0][neutral_frame]
    pieces = []
    for markers in in_table:
        stable = workbench.stabilise_markers(markers[:: STEP // 2], rigid, marker_neutral[rigid]).markers
        pieces.append(stable[np.isfinite(stable).all(axis=(1, 2))])  # dataset.gap_policy: drop
    face = workbench.read_blendshapes(
        shared_data / "ict-facekit" / "FaceXModel",
        neutral="generic_neutral_mesh.obj",
        names=HAND,
        region_vertices=9409,
        unit_mm=10,
    )
    placement = workbench.place_markers(table, marker_neutral, face.neutral, refine_iterations=50)
    scale = placement.mesh_to_capture.scale
    neutral = placement.in_mesh_frame(marker_neutral)
    displacements = placement.in_mesh_frame(np.concatenate(pieces)) - neutral

    scored = np.array([label not in RIGID for label in table.labels])
    same_alpha(
        displacements[:, scored].reshape(len(displacements), -1),
        scale * face.deltas[:, placement.vertices[scored]].reshape(len(HAND), -1),
        neutral[scored].reshape(-1),
        captures["markers"],
    )
    mesh = workbench.rbf_carry(
        displacements,
        scale * face.neutral,
        face.triangles,
        placement.vertices,
        metric="geodesic",
        kernel="inverse_multiquadric",
        epsilon=0.05,
        degree=0,
    )
    same_alpha(
        mesh.reshape(len(mesh), -1),
        scale * face.deltas.reshape(len(HAND), -1),
        scale * face.neutral.reshape(-1),
        captures["mesh"],
    )


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: workbench.arkit_mapping("JawOpen", ["jawOpen"]), "channel_names must be a list of names"),
        (lambda: workbench.arkit_mapping(["JawOpen"], [1]), "basis_names must be a list of names"),
        (lambda: workbench.arkit_mapping(["JawOpen"], ["jawOpen"], ["x"]), "overrides must be a mapping"),
        (lambda: workbench.stabilise_markers(np.zeros((4, 5)), [0, 1, 2], np.zeros((3, 3))), "markers must have shape"),
        (lambda: workbench.stabilise_markers(np.zeros((4, 5, 3)), [0, 1, 9], np.zeros((3, 3))), "rigid_markers must"),
        (lambda: workbench.stabilise_markers(np.zeros((4, 5, 3)), [0, 1, 2], np.zeros((2, 3))), "reference must"),
        (lambda: workbench.rest_frame(np.zeros((4, 5, 3)), [0.5, 1, 2]), "rigid_markers must"),
        (lambda: workbench.read_marker_table(None), "path must be the path"),
        (lambda: workbench.place_markers("table.csv", np.zeros((3, 3)), np.zeros((3, 3))), "table must be"),
        (lambda: workbench.rbf_carry(np.zeros((2, 3, 3)), np.zeros((9, 3)), None, [0, 1]), "marker_vertices must"),
        (lambda: workbench.rbf_carry(np.zeros((2, 3)), np.zeros((9, 3)), None, [0, 1]), "marker_displacements must"),
    ],
)
def test_the_real_data_functions_refuse_bad_arguments_in_one_line(call, message):
    with pytest.raises(workbench.WorkbenchError, match=message) as error:
        call()
    assert "\n" not in str(error.value)


# --- a researcher's own data: positions given where displacements are expected ------------------------------------

CAPTURES = {
    "synthetic": ["dataset=synthetic", "dataset.n_frames=2000"],
    "ict_livelink": ["dataset=ict_livelink", f"dataset.frame_step={STEP}", "dataset.train_on=[markers,mesh]"],
    "animface": ["dataset=animface", f"dataset.frame_step={STEP // 2}", "dataset.train_on=markers"],
}


@pytest.mark.filterwarnings("ignore:QuasiEigenFaces. the quasi-eigen basis is rank-deficient")  # m < 18, as in a run
@pytest.mark.parametrize("dataset", list(CAPTURES))
def test_the_positions_rule_tells_every_shared_capture_from_its_positions(shared_data, tmp_path, dataset):
    """The rule of QuasiEigenFaces(frames_as="auto") on real frames: displacements well below its threshold, the
    same frames as positions well above it (docs/api.md gives the measured figures)."""
    from workbench.numerics.displacements import POSITIONS_ABOVE, frames_mean_and_motion, shape_over_motion

    overrides = [*CAPTURES[dataset], f"paths.data_root={shared_data}"]
    captures = workbench.build_captures(workbench.compose_config("paper", overrides), cache_dir=str(tmp_path))
    for capture in captures.values():
        mean, motion = frames_mean_and_motion(capture.train)
        assert shape_over_motion(mean, motion) < POSITIONS_ABOVE / 4
        assert shape_over_motion(mean + capture.neutral, motion) > 2 * POSITIONS_ABOVE
        extreme = capture.train[np.argmax(np.abs(capture.train).sum(axis=1))]  # a single frame at transform
        assert shape_over_motion(extreme, motion) < POSITIONS_ABOVE / 1.5
    capture = next(iter(captures.values()))
    positions = capture.train + capture.neutral
    with pytest.raises(workbench.WorkbenchError, match="^frames look like positions.*frames_as='positions'"):
        workbench.QuasiEigenFaces(hand_shapes=capture.hand, neutral=capture.neutral).fit(positions)
    said = workbench.QuasiEigenFaces(hand_shapes=capture.hand, neutral=capture.neutral, frames_as="positions")
    direct = workbench.QuasiEigenFaces(hand_shapes=capture.hand, neutral=capture.neutral).fit(capture.train)
    assert said.fit(positions).alpha(positions) == pytest.approx(direct.alpha(capture.train), rel=1e-9)


def test_an_obj_sequence_of_ict_meshes_is_fitted_once_its_neutral_is_subtracted(shared_data, tmp_path):
    """A capture exported as one OBJ per frame (here ICT FaceKit's expressions linked as frames): read as positions,
    refused as displacements, fitted once the neutral is said and subtracted."""
    folder = shared_data / "ict-facekit" / "FaceXModel"
    names = ["generic_neutral_mesh", "jawOpen", "mouthSmile_L", "mouthSmile_R", "browInnerUp_L", "mouthPucker"]
    for index, name in enumerate(names):
        (tmp_path / f"take_{index + 1}.obj").symlink_to(folder / f"{name}.obj")
    sequence = workbench.read_obj_sequence(tmp_path)
    assert [path.name for path in sequence.paths] == [f"take_{index + 1}.obj" for index in range(len(names))]
    np.testing.assert_array_equal(sequence.vertices[1], workbench.read_obj(folder / "jawOpen.obj").vertices)
    frames = sequence.vertices.reshape(len(names), -1) * 10.0  # centimetres to millimetres
    neutral = frames[0]
    hand = frames[1:4] - neutral
    with pytest.raises(workbench.WorkbenchError, match="^frames look like positions.*neutral=v0"):
        workbench.QuasiEigenFaces(hand_shapes=hand, neutral=neutral).fit(frames)
    fitted = workbench.QuasiEigenFaces(hand_shapes=hand, neutral=neutral, frames_as="positions").fit(frames)
    # frames 2 to 4 are the neutral plus one hand shape each: their hand-shape weights are the identity
    np.testing.assert_allclose(fitted.transform(frames, basis="H")[1:4], np.eye(3), rtol=0, atol=1e-9)
    np.testing.assert_allclose(fitted.inverse_transform(np.eye(3), basis="H"), frames[1:4], rtol=0, atol=1e-9)
