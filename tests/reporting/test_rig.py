"""A fitted estimator posed by hand (``QuasiEigenFaces.pose``) and written as a glTF rig (``workbench.write_rig``): the
pose is neutral + weights x shapes; the rig read back by the workbench's reader, the Khronos validator and Blender
gives the same faces."""

import shutil
import sys

import numpy as np
import pytest
from test_export import read_glb, require_tool, validate  # the export's independent readers

import workbench
from workbench.core.errors import WorkbenchError
from workbench.settings.config import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "tests" / "tools"))
from playback_check import playback_differences  # noqa: E402


def grid_face(rng, rows=12, cols=10, n_shapes=5, n_frames=160):
    """A grid mesh in mm (triangles), smooth local hand shapes and frames they drive with noise off their span."""
    x, y = np.meshgrid(np.linspace(-60, 60, cols), np.linspace(-80, 80, rows))
    neutral = np.stack([x, y, 20 * np.cos(x / 60) * np.cos(y / 80)], axis=-1).reshape(-1, 3)
    index = np.arange(rows * cols).reshape(rows, cols)
    corners = index[:-1, :-1].ravel(), index[:-1, 1:].ravel(), index[1:, :-1].ravel(), index[1:, 1:].ravel()
    triangles = np.concatenate([np.stack(corners[:3], 1), np.stack([corners[1], corners[3], corners[2]], 1)])
    centres = rng.uniform([-50, -70], [50, 70], (n_shapes, 2))
    falloff = np.exp(-((neutral[None, :, :2] - centres[:, None]) ** 2).sum(-1) / (2 * 30.0**2))
    directions = rng.standard_normal((n_shapes, 1, 3))
    hand = (8.0 * falloff[..., None] * directions).reshape(n_shapes, -1)
    frames = rng.uniform(0, 1, (n_frames, n_shapes)) @ hand + 0.3 * rng.standard_normal((n_frames, hand.shape[1]))
    return neutral.ravel(), triangles, hand, frames


@pytest.fixture(scope="module")
def fitted():
    rng = np.random.default_rng(7)
    neutral, triangles, hand, frames = grid_face(rng)
    names = ["jawOpen", "mouthSmile_L", "mouthSmile_R", "browInnerUp", "eyeBlink_L"]
    qe = workbench.QuasiEigenFaces(hand_shapes=hand, neutral=neutral, names=names, n_components=5).fit(frames)
    return qe, triangles, frames


def test_pose_is_neutral_plus_weights_times_shapes(fitted):
    qe, _, _ = fitted
    rng = np.random.default_rng(1)
    weights = rng.uniform(-0.5, 1.5, (4, 5))
    for basis, shapes in (("QE", qe.shapes_), ("H", qe.hand_shapes_)):
        by_hand = np.einsum("fs,sd->fd", weights, shapes)
        np.testing.assert_allclose(qe.pose(weights, basis=basis), by_hand, rtol=0, atol=1e-12)
        np.testing.assert_allclose(qe.pose(weights[2], basis), by_hand[2], rtol=0, atol=1e-12)
        np.testing.assert_allclose(qe.pose(weights, basis, positions=True), qe.neutral_ + by_hand, rtol=0, atol=1e-12)
    coefficients = rng.standard_normal(qe.m_)
    np.testing.assert_allclose(
        qe.pose(coefficients, "PCA"), qe.mean_ + coefficients @ qe.eigenfaces_, rtol=0, atol=1e-12
    )
    # one shape alone by name (figure 2): the smile at 1, the rest at 0
    np.testing.assert_allclose(qe.pose({"mouthSmile_L": 1.0}, "H"), qe.hand_shapes_[1], rtol=0, atol=0)
    solo = qe.pose({"mouthSmile_L": 1.0}, "QE")
    np.testing.assert_allclose(solo, qe.shapes_[1], rtol=0, atol=0)
    assert not np.allclose(solo, qe.hand_shapes_[1])  # the quasi-eigen face is the hand shape projected


def test_pose_refuses_what_it_cannot_pose(fitted):
    qe, _, frames = fitted
    with pytest.raises(WorkbenchError, match="no shape 'smile'; its shapes are"):
        qe.pose({"smile": 1.0})
    with pytest.raises(WorkbenchError, match=r"one value per shape of basis 'H' \(5\), got 3"):
        qe.pose([1.0, 0.0, 0.0], "H")
    with pytest.raises(WorkbenchError, match="basis must be one of"):
        qe.pose(np.zeros(5), "QE-linear")
    with pytest.raises(WorkbenchError, match="weights holds NaN"):
        qe.pose([np.nan, 0, 0, 0, 0])
    bare = workbench.QuasiEigenFaces(hand_shapes=qe.hand_shapes_, n_components=5).fit(frames)
    with pytest.raises(WorkbenchError, match="needs the neutral positions"):
        bare.pose(np.ones(5), positions=True)
    with pytest.raises(workbench.NotFittedError):
        workbench.QuasiEigenFaces(hand_shapes=qe.hand_shapes_).pose(np.ones(5))


@pytest.fixture(scope="module")
def rigs(fitted, tmp_path_factory):
    """H and QE written with the lstsq weights of the frames (QE's reach outside [0, 1]), and QE without frames."""
    qe, triangles, frames = fitted
    out = tmp_path_factory.mktemp("rigs")
    written = {
        basis: workbench.write_rig(
            out / f"{basis}.glb", qe, triangles=triangles, basis=basis, frames=frames, frame_rate=30, solver="lstsq"
        )
        for basis in ("H", "QE")
    }
    written["bare"] = workbench.write_rig(out / "bare.glb", qe, triangles=triangles)
    return out, written


def test_written_rig_read_back_poses_the_estimators_faces(fitted, rigs):
    qe, triangles, frames = fitted
    out, written = rigs
    for basis in ("H", "QE"):
        mesh = workbench.read_gltf(out / f"{basis}.glb")
        np.testing.assert_allclose(mesh.neutral.ravel(), qe.neutral_, rtol=0, atol=1e-4)
        np.testing.assert_array_equal(mesh.triangles, triangles)
        (animation,) = mesh.animations
        assert animation.name == f"{basis}_lstsq_take" and written[basis]["animations"] == [animation.name]
        np.testing.assert_allclose(animation.seconds, np.arange(len(frames)) / 30, rtol=0, atol=1e-6)
        targets = written[basis]["targets"]
        assert list(mesh.names) == [t["target"] for t in targets]
        raw = np.zeros((len(frames), len(written[basis]["shapes"])))
        for k, target in enumerate(targets):
            raw[:, written[basis]["shapes"].index(target["shape"])] += target["scale"] * animation.weights[:, k]
        expected = qe.transform(frames, basis=basis, solver="lstsq")
        np.testing.assert_allclose(written[basis]["weights"], expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(raw, expected, rtol=0, atol=1e-5 * np.abs(expected).max())
        played = mesh.neutral.ravel() + animation.weights @ mesh.deltas.reshape(len(mesh.names), -1)
        np.testing.assert_allclose(played, qe.pose(expected, basis, positions=True), rtol=0, atol=1e-3)
    assert any(t["target"].endswith(("_over", "_neg")) for t in written["QE"]["targets"])  # the split was exercised
    bare = workbench.read_gltf(out / "bare.glb")
    assert bare.animations == () and list(bare.names) == list(qe.shape_names_)
    np.testing.assert_allclose(bare.deltas.reshape(len(bare.names), -1), qe.shapes_, rtol=0, atol=1e-4)


def test_write_rig_refuses_files_it_did_not_write_and_bad_input(fitted, rigs, tmp_path):
    qe, triangles, frames = fitted
    out, _ = rigs
    foreign = tmp_path / "mine.glb"
    foreign.write_bytes(b"not a rig")
    with pytest.raises(WorkbenchError, match="is not a rig the workbench wrote; it is left alone"):
        workbench.write_rig(foreign, qe, triangles=triangles)
    assert foreign.read_bytes() == b"not a rig"
    again = tmp_path / "again.glb"
    shutil.copy(out / "bare.glb", again)
    workbench.write_rig(again, qe, triangles=triangles, basis="H")  # its own earlier rig: replaced
    assert workbench.read_gltf(again).names == tuple(qe.shape_names_)
    assert read_glb(again)[0]["asset"]["extras"]["basis"] == "H"
    for kwargs, message in (
        ({"triangles": triangles[:, :2]}, "triangles must be integers of shape"),
        ({"triangles": triangles, "basis": "QE-linear"}, "basis must be one of"),
        ({"triangles": triangles, "seconds": [0.0]}, "give frames too"),
        ({"triangles": triangles, "frames": frames, "seconds": [0.0, 1.0]}, "seconds must be 160 finite times"),
        ({"triangles": triangles + 1000}, "triangles refer to vertices outside"),
        ({"triangles": triangles, "frame_rate": 0}, "frame_rate must be a positive number"),
    ):
        with pytest.raises(WorkbenchError, match=message):
            workbench.write_rig(tmp_path / "new.glb", qe, **kwargs)
    with pytest.raises(WorkbenchError, match="estimator must be a fitted QuasiEigenFaces, got dict"):
        workbench.write_rig(tmp_path / "new.glb", {}, triangles=triangles)
    with pytest.raises(workbench.NotFittedError):
        workbench.write_rig(tmp_path / "new.glb", workbench.QuasiEigenFaces(), triangles=triangles)
    with pytest.raises(WorkbenchError, match=r"must end in \.glb"):
        workbench.write_rig(tmp_path / "rig.gltf", qe, triangles=triangles)
    assert not (tmp_path / "new.glb").exists()


@pytest.mark.process
def test_written_rig_passes_the_khronos_validator(rigs):
    out, _ = rigs
    for name in ("H", "QE", "bare"):
        issues = validate(out / f"{name}.glb")
        assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, (name, issues["messages"][:5])


@pytest.mark.slow
@pytest.mark.process
def test_written_rig_plays_back_in_blender_as_the_estimator_poses(fitted, rigs, tmp_path):
    """Blender's stock importer and the docs' recipe, as for the export: every vertex within 1e-3 mm."""
    from workbench.reporting.export.rig import estimator_basis

    require_tool(shutil.which("blender") is not None, "blender")
    qe, _, frames = fitted
    out, written = rigs
    manifest = {
        "n_frames": len(frames),
        "bases": [{"basis": basis, "animations": written[basis]["animations"]} for basis in ("H", "QE")],
    }
    bases = [estimator_basis(qe, basis, frames, "lstsq") for basis in ("H", "QE")]
    found = playback_differences(out, manifest, bases, qe.neutral_.reshape(-1, 3), 6, tmp_path)
    assert max(entry["max_abs_mm"] for entry in found.values()) < 1e-3, found
