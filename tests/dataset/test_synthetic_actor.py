"""Tests of the embedded synthetic actor: mesh, muscles, performance, markers and take."""

import numpy as np
import pytest
from muscles_reference import deform_reference

from workbench.core.errors import WorkbenchError
from workbench.dataset.storage import FrameStorage
from workbench.dataset.synthetic import (
    LOWER_FACE,
    MUSCLE_NAMES,
    UPPER_FACE,
    deform,
    deform_displacements,
    make_activations,
    make_face_mesh,
    make_synthetic_take,
)
from workbench.dataset.synthetic.face_mesh import eye_opening_mask
from workbench.numerics.frames import FramesOnDisk

MIRROR = np.array([-1.0, 1.0, 1.0])


@pytest.fixture(scope="module")
def mesh():
    return make_face_mesh()


@pytest.fixture(scope="module")
def take():
    return make_synthetic_take(n_frames=1200, seed=0, marker_noise_mm=0.2)  # noise set here: tests below use it


@pytest.fixture(scope="module")
def still_take():
    """No head motion, no noise: markers are the deformed mesh vertices."""
    return make_synthetic_take(
        n_frames=300, seed=1, head_rotation_deg=0.0, head_translation_mm=0.0, marker_noise_mm=0.0
    )


def one_hot(name, level=1.0):
    activations = np.zeros((1, len(MUSCLE_NAMES)))
    activations[0, MUSCLE_NAMES.index(name)] = level
    return activations


# --- mesh ---------------------------------------------------------------------------------------------------


def test_mesh_is_a_valid_triangle_mesh(mesh):
    assert mesh.vertices.shape == (4200, 3) and mesh.vertices.dtype == np.float64
    assert mesh.faces.ndim == 2 and mesh.faces.shape[1] == 3 and mesh.faces.dtype == np.int64
    assert mesh.faces.min() == 0 and mesh.faces.max() == mesh.n_vertices - 1
    corners = mesh.vertices[mesh.faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert np.linalg.norm(normals, axis=1).min() > 1e-3  # no degenerate triangle
    assert (normals[:, 2] > 0).mean() > 0.9  # counter-clockwise seen from the front
    assert np.isfinite(mesh.vertices).all()


def test_mesh_has_human_scale(mesh):
    width = np.ptp(mesh.vertices[:, 0])
    height = np.ptp(mesh.vertices[:, 1])
    assert 130.0 < width < 155.0
    assert 180.0 < height < 210.0


def test_landmarks_are_plausible(mesh):
    v = mesh.vertices
    lm = mesh.landmarks
    assert {
        "nose_tip",
        "chin",
        "mouth_corner_L",
        "mouth_corner_R",
        "upper_lip",
        "lower_lip",
        "brow_inner_L",
        "brow_inner_R",
        "brow_outer_L",
        "brow_outer_R",
        "eye_inner_L",
        "eye_inner_R",
        "eye_outer_L",
        "eye_outer_R",
        "forehead",
        "cheek_L",
        "cheek_R",
        "jaw_L",
        "jaw_R",
    } <= set(lm)
    nose = v[lm["nose_tip"]]
    assert lm["nose_tip"] == int(np.argmax(v[:, 2]))  # the most forward point of the face
    assert abs(nose[0]) < 5.0 and 95.0 <= nose[2] <= 110.0
    assert v[lm["chin"], 1] < v[lm["lower_lip"], 1] < v[lm["upper_lip"], 1] < nose[1]
    assert nose[1] < v[lm["eye_inner_L"], 1] < v[lm["brow_inner_L"], 1] < v[lm["forehead"], 1]
    for name, index in lm.items():
        if name.endswith("_L"):
            assert v[index, 0] > 5.0, name
            np.testing.assert_allclose(v[lm[name[:-2] + "_R"]], v[index] * MIRROR, atol=1e-9)


def test_mesh_arguments_are_checked():
    with pytest.raises(WorkbenchError, match="n_rows"):
        make_face_mesh(n_rows=5)
    with pytest.raises(WorkbenchError, match="n_cols"):
        make_face_mesh(n_cols=30.5)


# --- muscles ------------------------------------------------------------------------------------------------


def test_muscle_names():
    assert len(MUSCLE_NAMES) == 18 and len(UPPER_FACE) == 6 and len(LOWER_FACE) == 12
    assert MUSCLE_NAMES == UPPER_FACE + LOWER_FACE
    assert MUSCLE_NAMES[0] == "frontalis_inner_L" and MUSCLE_NAMES[-1] == "jaw_open"


def test_zero_activation_returns_rest_exactly(mesh):
    positions = deform(mesh.vertices, np.zeros((3, 18)))
    assert positions.shape == (3, mesh.n_vertices, 3) and positions.dtype == np.float64
    assert np.array_equal(positions, np.broadcast_to(mesh.vertices, positions.shape))


def test_deformation_is_per_point(mesh):
    rng = np.random.default_rng(5)
    activations = rng.uniform(0.0, 1.0, (12, 18))
    full = deform(mesh.vertices, activations)
    subset = rng.permutation(mesh.n_vertices)[:66]
    assert np.array_equal(deform(mesh.vertices[subset], activations), full[:, subset])
    # Chunking frames differently changes nothing either.
    assert np.array_equal(deform(mesh.vertices, activations, chunk_points=3 * mesh.n_vertices), full)


def test_skipping_unreachable_points_changes_nothing(mesh, monkeypatch):
    from workbench.dataset.synthetic import muscles

    rng = np.random.default_rng(9)
    activations = np.vstack([np.ones((1, 18)), rng.uniform(0.0, 1.0, (30, 18)), np.eye(18)])
    pruned = deform(mesh.vertices, activations)
    everything = {name: np.arange(mesh.n_vertices) for name in muscles._reachable_points(mesh.vertices)}
    monkeypatch.setattr(muscles, "_reachable_points", lambda points: everything)
    assert np.array_equal(deform(mesh.vertices, activations), pruned)


REFERENCE_TOLERANCE_MM = 1e-12
"""The compiled model against the NumPy steps: the same arithmetic, except that sin, cos, arccos and tanh may
differ from NumPy's vectorised ones in the last bit (about 1e-14 mm at these sizes)."""


def reference_cases():
    rng = np.random.default_rng(21)
    return {
        "random": rng.uniform(0.0, 1.0, (40, 18)),
        "sparse": rng.uniform(0.0, 1.0, (40, 18)) * (rng.uniform(size=(40, 18)) < 0.3),
        "one_hot": np.eye(18),
        "half_one_hot": 0.5 * np.eye(18),
        "all_ones": np.ones((2, 18)),
        "performance": make_activations(600, 120.0, np.random.default_rng(4))[::10],
    }


@pytest.mark.parametrize("case", list(reference_cases()))
def test_compiled_model_equals_the_numpy_reference(mesh, case):
    activations = reference_cases()[case]
    compiled = deform(mesh.vertices, activations)
    reference = deform_reference(mesh.vertices, activations)
    moved = np.abs(reference - mesh.vertices).max()
    assert moved > 1.0  # the case does move the face
    np.testing.assert_allclose(compiled, reference, rtol=0, atol=REFERENCE_TOLERANCE_MM)


@pytest.mark.slow
def test_compiled_model_at_rest_equals_the_reference_exactly(mesh):
    activations = np.zeros((3, 18))
    assert np.array_equal(deform(mesh.vertices, activations), deform_reference(mesh.vertices, activations))
    out = np.full((3, 3 * mesh.n_vertices), np.nan, dtype=np.float32)
    assert np.array_equal(deform_displacements(mesh.vertices, activations, out), np.zeros_like(out))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_displacements_are_the_deformed_points_less_rest_rounded_once(mesh, dtype):
    activations = np.random.default_rng(8).uniform(0.0, 1.0, (7, 18))
    expected = (deform(mesh.vertices, activations) - mesh.vertices).reshape(7, -1).astype(dtype)
    out = np.empty((7, 3 * mesh.n_vertices), dtype=dtype)
    assert deform_displacements(mesh.vertices, activations, out) is out
    assert np.array_equal(out, expected)


def test_displacements_arguments_are_checked(mesh):
    activations = np.zeros((2, 18))
    for bad in (
        np.empty((2, 3 * mesh.n_vertices - 1)),
        np.empty((3, 3 * mesh.n_vertices)),
        np.empty((2, 3 * mesh.n_vertices), dtype=np.float16),
        np.empty((3 * mesh.n_vertices, 2)).T,
        [[0.0] * 3 * mesh.n_vertices] * 2,
    ):
        with pytest.raises(WorkbenchError, match="out must be"):
            deform_displacements(mesh.vertices, activations, bad)
    frozen = np.empty((2, 3 * mesh.n_vertices))
    frozen.setflags(write=False)
    with pytest.raises(WorkbenchError, match="writeable"):
        deform_displacements(mesh.vertices, activations, frozen)
    with pytest.raises(WorkbenchError, match="activations"):
        deform_displacements(mesh.vertices, np.full((2, 18), -0.1), np.empty((2, 3 * mesh.n_vertices)))


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_dense_mesh_frames_are_the_same_in_memory_and_on_disk(tmp_path, dtype):
    from workbench.dataset.synthetic_builder import _mesh_frames, _take_key
    from workbench.settings.typed import dataset_settings

    cfg = {
        "kind": "synthetic",
        "n_frames": 61,
        "frame_rate": 120.0,
        "n_face_markers": 66,
        "n_head_markers": 7,
        "head_rotation_deg": 3.0,
        "head_translation_mm": 5.0,
        "marker_noise_mm": 0.05,
        "mesh_rows": 30,
        "mesh_cols": 25,
    }
    key = _take_key(dataset_settings(cfg), 3)
    take = make_synthetic_take(**dict(key))
    expected = (take.mesh_sequence() - take.mesh.vertices).reshape(61, -1).astype(dtype)
    in_memory = _mesh_frames(key, 1.0, FrameStorage(dtype=dtype))
    on_disk = _mesh_frames(key, 1.0, FrameStorage(dtype=dtype, folder=str(tmp_path)))
    assert isinstance(on_disk, FramesOnDisk) and in_memory.dtype == np.dtype(dtype)
    assert np.array_equal(in_memory, expected) and np.array_equal(on_disk.read(0, 61, np.dtype(dtype)), expected)


@pytest.mark.parametrize("left", [name for name in MUSCLE_NAMES if name.endswith("_L")])
def test_left_and_right_muscles_mirror_each_other(mesh, left):
    points = mesh.vertices
    mirrored = points * MIRROR
    right_displacement = deform(points, one_hot(left[:-2] + "_R"))[0] - points
    left_displacement = deform(mirrored, one_hot(left))[0] - mirrored
    assert np.abs(right_displacement).max() > 1.0
    np.testing.assert_allclose(left_displacement, right_displacement * MIRROR, rtol=0, atol=1e-9)


def test_full_contractions_have_realistic_size(mesh):
    shapes = deform(mesh.vertices, np.eye(18)) - mesh.vertices
    largest = np.linalg.norm(shapes, axis=2).max(axis=1)
    for name, size in zip(MUSCLE_NAMES, largest):
        if name == "jaw_open":
            assert 20.0 < size < 35.0, (name, size)
        else:
            assert 3.0 < size < 15.0, (name, size)
    chin_drop = -shapes[MUSCLE_NAMES.index("jaw_open"), mesh.landmarks["chin"], 1]
    assert chin_drop > 15.0
    assert np.abs(shapes[MUSCLE_NAMES.index("jaw_open"), mesh.landmarks["nose_tip"]]).max() == 0.0


def test_upper_face_muscles_leave_the_mouth_alone_and_vice_versa(mesh):
    shapes = deform(mesh.vertices, np.eye(18)) - mesh.vertices
    mouth = [mesh.landmarks[name] for name in ("upper_lip", "lower_lip", "mouth_corner_L", "mouth_corner_R")]
    brows = [mesh.landmarks[name] for name in ("brow_inner_L", "brow_inner_R", "brow_outer_L", "brow_outer_R")]
    for index, name in enumerate(MUSCLE_NAMES):
        quiet = mouth if name in UPPER_FACE else brows
        assert np.abs(shapes[index, quiet]).max() < 1e-6, name


def test_muscles_combine_non_linearly(mesh):
    points = mesh.vertices
    pairs = [
        ("zygomatic_major_L", "jaw_open"),
        ("orbicularis_oris", "risorius_L"),
        ("frontalis_inner_L", "corrugator_L"),
    ]
    for first, second in pairs:
        both = one_hot(first) * 0.7 + one_hot(second) * 0.7
        combined = deform(points, both)[0] - points
        summed = (deform(points, one_hot(first, 0.7))[0] - points) + (deform(points, one_hot(second, 0.7))[0] - points)
        assert np.abs(combined - summed).max() > 0.5, (first, second)


def test_performance_is_not_in_the_span_of_the_hand_shapes(take):
    hand = take.hand_shapes_mesh().reshape(18, -1)
    activations = take.activations[::4]
    displacements = (deform(take.mesh.vertices, activations) - take.mesh.vertices).reshape(len(activations), -1)
    weights, *_ = np.linalg.lstsq(hand.T, displacements.T, rcond=None)
    residual = np.linalg.norm(displacements.T - hand.T @ weights) / np.linalg.norm(displacements)
    assert residual > 0.01


def test_deform_arguments_are_checked(mesh):
    with pytest.raises(WorkbenchError, match="activations"):
        deform(mesh.vertices, np.zeros((2, 17)))
    with pytest.raises(WorkbenchError, match="activations"):
        deform(mesh.vertices, np.full((2, 18), 1.5))
    with pytest.raises(WorkbenchError, match="points"):
        deform(mesh.vertices[:, :2], np.zeros((2, 18)))


# --- performance --------------------------------------------------------------------------------------------


def test_activations_are_bounded_smooth_and_start_at_rest():
    activations = make_activations(6000, 120.0, np.random.default_rng(3))
    assert activations.shape == (6000, 18)
    assert activations.min() >= 0.0 and activations.max() <= 1.0
    assert np.abs(np.diff(activations, axis=0)).max() < 0.15
    assert np.array_equal(activations[:120], np.zeros((120, 18)))  # the first second is rest
    assert (activations.max(axis=0) > 0.2).sum() >= 12  # many muscles take part
    assert activations[:, MUSCLE_NAMES.index("jaw_open")].max() > 0.3


def test_activations_depend_only_on_the_generator():
    first = make_activations(2000, 120.0, np.random.default_rng(11))
    again = make_activations(2000, 120.0, np.random.default_rng(11))
    other = make_activations(2000, 120.0, np.random.default_rng(12))
    assert np.array_equal(first, again) and not np.array_equal(first, other)


def test_activations_arguments_are_checked():
    with pytest.raises(WorkbenchError, match="n_frames"):
        make_activations(0, 120.0, np.random.default_rng(0))
    with pytest.raises(WorkbenchError, match="frame_rate"):
        make_activations(10, -1.0, np.random.default_rng(0))
    with pytest.raises(WorkbenchError, match="rng"):
        make_activations(10, 120.0, 0)


# --- the take -----------------------------------------------------------------------------------------------


def test_take_shapes_and_labels(take):
    assert take.markers.shape == (1200, 73, 3) and take.activations.shape == (1200, 18)
    assert take.muscle_names == MUSCLE_NAMES
    assert take.face_marker_vertices.shape == (66,) and take.head_marker_rest.shape == (7, 3)
    assert len(take.marker_labels) == 73 and len(set(take.marker_labels)) == 73
    assert np.array_equal(take.face_marker_index, np.arange(66))
    assert np.array_equal(take.head_marker_index, np.arange(66, 73))
    assert all(label.startswith("H") for label in np.asarray(take.marker_labels)[take.head_marker_index])
    assert all(label.startswith("F") for label in np.asarray(take.marker_labels)[take.face_marker_index])
    assert take.head_motion.rotations.shape == (1200, 3, 3) and take.head_motion.translations.shape == (1200, 3)
    assert take.provenance["kind"] == "synthetic" and take.provenance["seed"] == 0
    assert "not real capture" in take.provenance["note"]
    assert take.provenance["n_face_markers"] == 66 and take.provenance["marker_noise_mm"] == 0.2


def test_face_markers_spread_over_the_face(take):
    mesh, vertices = take.mesh, take.face_marker_vertices
    assert len(np.unique(vertices)) == 66 and vertices[0] == mesh.landmarks["nose_tip"]
    assert not eye_opening_mask(mesh.face_plane[vertices]).any()
    rest = mesh.vertices[vertices]
    gaps = np.linalg.norm(rest[:, None] - rest[None], axis=2) + np.eye(66) * 1e9
    assert gaps.min() > 6.0
    x, y = mesh.face_plane[vertices].T
    assert (y > 40).sum() >= 5  # forehead
    assert ((y > 18) & (y < 35)).sum() >= 4  # brows
    assert ((np.abs(x) < 35) & (y < -45) & (y > -70)).sum() >= 8  # around the mouth
    assert (y < -78).sum() >= 3  # chin and jaw
    assert (x > 10).sum() >= 20 and (x < -10).sum() >= 20


def test_head_markers_are_rigid_and_off_the_face(take):
    rest = take.head_marker_rest
    assert rest[:, 1].min() > 30.0  # at the temples or above
    assert np.linalg.matrix_rank(rest - rest.mean(axis=0)) == 3  # not coplanar: usable for stabilisation
    motion = take.head_motion
    head = take.markers[:, take.head_marker_index]
    in_head_frame = np.einsum("fji,fpj->fpi", motion.rotations, head - motion.translations[:, None])
    # Only noise separates them from the rest positions.
    assert np.abs(in_head_frame - rest).max() < 6 * 0.2


def test_head_motion_is_a_small_smooth_rigid_motion(take):
    rotations, translations = take.head_motion.rotations, take.head_motion.translations
    np.testing.assert_allclose(
        rotations @ np.swapaxes(rotations, 1, 2), np.broadcast_to(np.eye(3), rotations.shape), atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.det(rotations), 1.0, atol=1e-12)
    angle = np.degrees(np.arccos(np.clip((np.trace(rotations, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    assert angle.max() <= 3.0 * np.sqrt(3) + 1e-9 and angle.max() > 0.1
    assert np.abs(translations).max() <= 5.0 + 1e-9
    assert np.abs(np.diff(translations, axis=0)).max() < 0.1  # mm per frame at 120 Hz


def test_markers_are_the_deformed_vertices_moved_rigidly(take):
    face = deform(take.mesh.vertices[take.face_marker_vertices], take.activations)
    expected = take.head_motion.to_lab(face)
    noise = take.markers[:, take.face_marker_index] - expected
    assert abs(noise.std() - 0.2) < 0.01 and abs(noise.mean()) < 0.01


def test_still_take_markers_equal_mesh_vertices(still_take):
    mesh = still_take.mesh
    face = still_take.markers[:, still_take.face_marker_index]
    assert np.array_equal(face[0], mesh.vertices[still_take.face_marker_vertices])  # the take starts at rest
    assert np.array_equal(
        still_take.markers[:, still_take.head_marker_index], np.broadcast_to(still_take.head_marker_rest, (300, 7, 3))
    )
    dense = still_take.mesh_sequence(200, 230)
    assert dense.shape == (30, mesh.n_vertices, 3)
    assert np.array_equal(dense[:, still_take.face_marker_vertices], face[200:230])


def test_hand_shapes(take):
    shapes = take.hand_shapes_mesh()
    assert shapes.shape == (18, take.mesh.n_vertices, 3)
    assert np.array_equal(take.hand_shapes_markers(), shapes[:, take.face_marker_vertices])
    full = deform(take.mesh.vertices, np.eye(18)[[MUSCLE_NAMES.index("mentalis")]])[0] - take.mesh.vertices
    assert np.array_equal(shapes[MUSCLE_NAMES.index("mentalis")], full)


def test_take_is_deterministic_in_the_seed():
    first = make_synthetic_take(n_frames=400, seed=7)
    again = make_synthetic_take(n_frames=400, seed=7)
    other = make_synthetic_take(n_frames=400, seed=8)
    assert np.array_equal(first.markers, again.markers)
    assert np.array_equal(first.activations, again.activations)
    assert np.array_equal(first.face_marker_vertices, again.face_marker_vertices)
    assert not np.array_equal(first.markers, other.markers)
    assert not np.array_equal(first.activations, other.activations)


def test_coarse_mesh_and_few_markers():
    small = make_synthetic_take(n_frames=20, n_face_markers=5, n_head_markers=3, mesh_rows=20, mesh_cols=20)
    assert small.mesh.n_vertices == 400 and small.markers.shape == (20, 8, 3)
    assert small.face_marker_vertices[0] == small.mesh.landmarks["nose_tip"]


def test_take_arrays_are_read_only(take):
    with pytest.raises(ValueError):
        take.markers[0, 0, 0] = 1.0


@pytest.mark.parametrize(
    "argument,value",
    [
        ("n_frames", 0),
        ("n_frames", 2.5),
        ("frame_rate", 0.0),
        ("frame_rate", float("nan")),
        ("n_face_markers", 0),
        ("n_face_markers", 100000),
        ("n_head_markers", 2),
        ("head_rotation_deg", -1.0),
        ("head_translation_mm", -0.5),
        ("marker_noise_mm", -0.1),
        ("seed", -3),
        ("mesh_rows", 4),
    ],
)
def test_bad_take_arguments_are_refused(argument, value):
    with pytest.raises(WorkbenchError, match=argument):
        make_synthetic_take(**{"n_frames": 10, argument: value})


def test_mesh_sequence_range_is_checked(still_take):
    with pytest.raises(WorkbenchError, match="start"):
        still_take.mesh_sequence(10, 5)
    with pytest.raises(WorkbenchError, match="stop"):
        still_take.mesh_sequence(0, 10000)


@pytest.mark.slow
def test_paper_scale_take():
    take = make_synthetic_take()
    assert take.markers.shape == (35000, 73, 3)
    assert take.activations.shape == (35000, 18)
    assert np.isfinite(take.markers).all()
    assert (take.activations.max(axis=0) > 0.3).all()  # every muscle acts somewhere in the take
