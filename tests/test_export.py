"""workbench export: the GLB read back by an independent reader gives the run's alpha; the OBJ folder read back as
a hand basis gives the run's table; marker bases, weight curves, the Live Link layout and bad input."""

import json
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.cli import run
from workbench.config import REPO_ROOT, compose
from workbench.errors import WorkbenchError
from workbench.export import export_run, livelink_csv, main
from workbench.metrics import summarise_alpha

RUN = ["dataset.n_frames=300", "dataset.train_on=[mesh,markers]", "solver=nnls", "save_inputs=true"]
ALPHA_COLUMNS = ["alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled"]
TOOLS_REQUIRED = os.environ.get("WORKBENCH_REQUIRE_TOOLS") == "1"
NODE_MODULES = Path(os.environ.get("WORKBENCH_NODE_MODULES", REPO_ROOT / ".ci" / "node" / "node_modules"))


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    folder = tmp_path_factory.mktemp("export") / "run"
    run(compose("paper", RUN), folder)
    return folder


@pytest.fixture(scope="module")
def mesh_export(record):
    out = record.parent / "mesh_export"
    return out, export_run(record, out, data="mesh")


def read_glb(path):
    """A minimal GLB reader independent of the writer's library: JSON chunk, binary chunk, tightly packed
    float32/uint32 accessors."""
    data = Path(path).read_bytes()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert magic == b"glTF" and version == 2 and length == len(data)
    json_length, json_type = struct.unpack_from("<II", data, 12)
    assert json_type == 0x4E4F534A
    document = json.loads(data[20:20 + json_length])
    bin_start = 20 + json_length
    bin_length, bin_type = struct.unpack_from("<II", data, bin_start)
    assert bin_type == 0x004E4942
    blob = data[bin_start + 8:bin_start + 8 + bin_length]

    def accessor(index):
        spec = document["accessors"][index]
        view = document["bufferViews"][spec["bufferView"]]
        dtype = {5126: np.float32, 5125: np.uint32}[spec["componentType"]]
        width = {"SCALAR": 1, "VEC3": 3}[spec["type"]]
        start = view.get("byteOffset", 0) + spec.get("byteOffset", 0)
        return np.frombuffer(blob, dtype=dtype, count=spec["count"] * width, offset=start).reshape(spec["count"],
                                                                                                  width)
    return document, accessor


def rebuild_from_glb(path):
    """Displacements (n_frames, 3 * n_vertices) in mm from a GLB's morph targets and its one animation."""
    document, accessor = read_glb(path)
    primitive = document["meshes"][0]["primitives"][0]
    targets = np.stack([accessor(target["POSITION"]).astype(np.float64) for target in primitive["targets"]])
    sampler = document["animations"][0]["samplers"][0]
    seconds = accessor(sampler["input"])[:, 0].astype(np.float64)
    weights = accessor(sampler["output"]).astype(np.float64).reshape(len(seconds), len(targets))
    frames = weights @ targets.reshape(len(targets), -1) * 1000.0
    return document, frames, seconds, accessor(primitive["attributes"]["POSITION"]).astype(np.float64)


@pytest.mark.parametrize("basis", ["H", "QE", "QE-linear", "PCA"])
def test_glb_morph_targets_and_animation_rebuild_the_runs_alpha(record, mesh_export, basis):
    out, manifest = mesh_export
    document, frames, seconds, neutral = rebuild_from_glb(out / f"{basis}.glb")
    inputs = np.load(record / "inputs_mesh.npz")
    table = pd.read_csv(record / "alpha_table.csv").query("data == 'mesh' and basis == @basis")
    summary = summarise_alpha(inputs["neutral"], inputs["eval"], frames)
    measured = [summary.absolute_mean, summary.absolute_pooled, summary.displacement_mean,
                summary.displacement_pooled]
    np.testing.assert_allclose(measured, table[ALPHA_COLUMNS].to_numpy()[0], rtol=1e-5, atol=0)
    np.testing.assert_allclose(neutral * 1000.0, inputs["neutral"].reshape(-1, 3), rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(seconds, np.arange(300) / 120.0, rtol=1e-6, atol=1e-7)
    entry = next(entry for entry in manifest["bases"] if entry["basis"] == basis)
    names = document["meshes"][0]["extras"]["targetNames"]
    assert names == entry["shapes"]
    if basis in ("H", "QE"):
        assert names == [str(name) for name in inputs["hand_names"]]
    if basis == "PCA":
        assert names[0] == "pca_mean" and names[1:] == [f"pca_{j + 1:02d}" for j in range(len(names) - 1)]
    assert document["asset"]["extras"]["units"] == "metres" and "+Y up" in document["asset"]["extras"]["axes"]
    curves = pd.read_csv(out / f"{basis}_weights.csv")
    assert list(curves.columns) == ["frame", "time", *names] and len(curves) == 300
    _, accessor = read_glb(out / f"{basis}.glb")
    animated = accessor(document["animations"][0]["samplers"][0]["output"]).reshape(300, len(names))
    np.testing.assert_allclose(curves[names].to_numpy(), animated, rtol=1e-6, atol=1e-6)


def test_triangles_cover_the_mesh(record, mesh_export):
    out, manifest = mesh_export
    document, accessor = read_glb(out / "H.glb")
    primitive = document["meshes"][0]["primitives"][0]
    triangles = accessor(primitive["indices"]).reshape(-1, 3)
    np.testing.assert_array_equal(triangles, np.load(record / "inputs_mesh.npz")["faces"])
    assert primitive["mode"] == 4 and manifest["n_triangles"] == len(triangles)


@pytest.mark.parametrize("exported, rtol", [("H_obj", 1e-6), ("H.glb", 1e-4)])  # glTF holds float32
def test_export_read_back_as_hand_basis_gives_the_same_table(record, mesh_export, tmp_path, exported, rtol):
    out, _ = mesh_export
    again = tmp_path / "again"
    run(compose("paper", RUN[:-1] + ["dataset.train_on=mesh", f"+dataset.hand_basis.path={out / exported}"]), again)
    before = pd.read_csv(record / "alpha_table.csv").query("data == 'mesh'").reset_index(drop=True)
    after = pd.read_csv(again / "alpha_table.csv")
    assert (before[["basis", "solver", "n", "m"]] == after[["basis", "solver", "n", "m"]]).all().all()
    np.testing.assert_allclose(after[ALPHA_COLUMNS].to_numpy(), before[ALPHA_COLUMNS].to_numpy(), rtol=rtol)
    metrics = json.loads((again / "metrics.json").read_text())
    assert any("hand basis: 18 shapes read from" in note for note in metrics["data"]["mesh"]["notes"])


def test_marker_data_exports_bases_and_curves(record, tmp_path):
    manifest = export_run(record, tmp_path, data="markers", bases=["H", "PCA"])
    inputs = np.load(record / "inputs_markers.npz")
    with np.load(tmp_path / "H_basis.npz") as basis:
        np.testing.assert_array_equal(basis["neutral"].reshape(-1), inputs["neutral"])
        np.testing.assert_array_equal(basis["shapes"].reshape(18, -1), inputs["hand"])
        assert list(basis["names"]) == list(inputs["hand_names"]) and len(basis["labels"]) == 66
    table = pd.read_csv(tmp_path / "H_basis.csv")
    assert table["shape"].tolist() == ["neutral", *inputs["hand_names"]] and table.shape[1] == 1 + 3 * 66
    np.testing.assert_allclose(table.iloc[1:, 1:].to_numpy(), inputs["hand"], rtol=1e-8, atol=1e-12)
    pca = np.load(tmp_path / "PCA_basis.npz")
    np.testing.assert_allclose(pca["shapes"][0].reshape(-1), inputs["mean"], rtol=1e-12)
    curves = pd.read_csv(tmp_path / "PCA_weights.csv")
    reconstructed = curves.iloc[:, 2:].to_numpy() @ pca["shapes"].reshape(len(pca["shapes"]), -1)
    recorded = pd.read_csv(record / "alpha_table.csv").query("data == 'markers' and basis == 'PCA'")
    summary = summarise_alpha(inputs["neutral"], inputs["eval"], reconstructed)
    np.testing.assert_allclose(summary.absolute_mean, recorded["alpha_abs_mean"].iloc[0], rtol=1e-6)
    assert not list(tmp_path.glob("*.glb")) and manifest["points"].startswith("points without triangles")


def test_livelink_layout_reads_back_with_the_livelink_reader(tmp_path):
    from workbench.dataset.livelink import read_livelink_csv

    names = ["jawOpen", "browInnerUp_L", "browInnerUp_R", "mouthSmile_L", "custom"]
    weights = np.column_stack([np.linspace(0, 1, 5), [0.2] * 5, [0.4] * 5, [-0.5, 0, 0.5, 1, 1.5], [9] * 5])
    text, clipped = livelink_csv(names, weights, np.arange(5) / 30.0)
    (tmp_path / "take.csv").write_text(text)
    take = read_livelink_csv(tmp_path / "take.csv")
    column = {name: i for i, name in enumerate(take.names)}
    np.testing.assert_allclose(take.weights[:, column["JawOpen"]], weights[:, 0], atol=1e-6)
    np.testing.assert_allclose(take.weights[:, column["BrowInnerUp"]], 0.3, atol=1e-6)
    np.testing.assert_allclose(take.weights[:, column["MouthSmileLeft"]], [0, 0, 0.5, 1, 1], atol=1e-6)
    assert clipped == 2 and take.weights[:, column["TongueOut"]].max() == 0
    np.testing.assert_allclose(take.seconds, np.arange(5) / 30.0, atol=1e-4)
    assert livelink_csv(["a", "b"], weights[:, :2], np.arange(5) / 30.0) is None


def test_bad_requests_are_one_line_errors(record, tmp_path):
    with pytest.raises(WorkbenchError, match=r"is not a complete run record \(no 'done' file\)"):
        export_run(tmp_path, tmp_path / "out")
    with pytest.raises(WorkbenchError, match=r"export --data face: the run's data variants are \['mesh', 'markers'\]"):
        export_run(record, tmp_path / "out", data="face")
    with pytest.raises(WorkbenchError, match=r"export --solver box: the run's solvers are \['nnls'\]"):
        export_run(record, tmp_path / "out", solver="box")
    with pytest.raises(WorkbenchError, match=r"export --bases ICA: data 'mesh' with solver 'nnls' has bases "
                                             r"\['H', 'QE', 'QE-linear', 'PCA'\]"):
        export_run(record, tmp_path / "out", bases=["ICA"])
    tampered = tmp_path / "tampered"
    shutil.copytree(record, tampered)
    table = pd.read_csv(tampered / "alpha_table.csv")
    table.loc[1, "alpha_abs_mean"] *= 1.01
    table.to_csv(tampered / "alpha_table.csv", index=False)
    with pytest.raises(WorkbenchError, match=r"alpha_table\.csv was changed after the run"):
        export_run(tampered, tmp_path / "out")
    # a table whose checksum matches (a record written by other code) is still recomputed and compared
    import json

    from workbench.record import DONE, file_checksum

    done = json.loads((tampered / DONE).read_text())
    done["sha256"]["alpha_table.csv"] = file_checksum(tampered / "alpha_table.csv")
    (tampered / DONE).write_text(json.dumps(done))
    with pytest.raises(WorkbenchError, match=r"recomputing the run gives alpha .* away from the recorded table"):
        export_run(tampered, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_hand_basis_bad_input(record, mesh_export, tmp_path):
    out, _ = mesh_export

    def build(**spec):
        from workbench.dataset import build_captures

        cfg = compose("paper", RUN[:-1] + ["dataset.train_on=mesh"]).dataset
        return build_captures(dict(cfg, hand_basis=spec))

    with pytest.raises(WorkbenchError, match=r"dataset.hand_basis.path .*nowhere: not found"):
        build(path=str(tmp_path / "nowhere"))
    with pytest.raises(WorkbenchError, match=r"its neutral lies up to .* mm from the data's .*other units \(unit_mm\)"):
        build(path=str(out / "H_obj"), unit_mm=10.0)
    with pytest.raises(WorkbenchError, match=r"dataset.hand_basis has unknown key\(s\) \['unit'\]"):
        build(path=str(out / "H_obj"), unit=10.0)
    with pytest.raises(WorkbenchError, match=r"dataset.hand_basis: needs distinct shape names of the file's .*"
                                             r"missing \['smile'\]"):
        build(path=str(out / "H_obj"), shapes=["jaw_open", "smile"])
    (tmp_path / "basis.obj").write_text("v 0 0 0\n")
    with pytest.raises(WorkbenchError, match=r"must be a blendshape folder .* or a \.glb file"):
        build(path=str(tmp_path / "basis.obj"))
    (tmp_path / "fake.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
    with pytest.raises(WorkbenchError, match=r"fake\.glb: not a readable glTF file"):
        build(path=str(tmp_path / "fake.glb"))
    (tmp_path / "text.glb").write_text("{}")
    with pytest.raises(WorkbenchError, match=r"text\.glb: not a binary glTF file"):
        build(path=str(tmp_path / "text.glb"))


def test_cli_export_prints_one_line_per_basis(record, tmp_path, capsys):
    assert main([str(record), "--out", str(tmp_path / "cli"), "--bases", "QE", "--data", "mesh"]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("QE (nnls, 18 shapes, alpha ") and "QE.glb, QE_obj/" in printed
    result = subprocess.run([str(Path(os.sys.executable).parent / "workbench"), "export", str(record), "--bases",
                             "XYZ", "--out", str(tmp_path / "x")], capture_output=True, text=True)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert result.stderr.startswith("workbench export: error: export --bases XYZ")


# --- independent readers: the Khronos validator and Blender (required where WORKBENCH_REQUIRE_TOOLS=1, as in CI) ---

def require_tool(available: bool, what: str):
    if not available:
        if TOOLS_REQUIRED:
            pytest.fail(f"{what} not found -- required because WORKBENCH_REQUIRE_TOOLS=1", pytrace=False)
        pytest.skip(f"{what} not found (see docs/export.md to install it)")


@pytest.mark.parametrize("basis", ["H", "PCA"])
def test_glb_passes_the_khronos_validator(mesh_export, basis):
    out, _ = mesh_export
    require_tool(shutil.which("node") is not None and (NODE_MODULES / "gltf-validator").is_dir(),
                 f"node and the gltf-validator package (in {NODE_MODULES})")
    script = REPO_ROOT / "tests" / "tools" / "validate_gltf.js"
    result = subprocess.run(["node", str(script), str(out / f"{basis}.glb")],
                            capture_output=True, text=True, env=dict(os.environ, NODE_PATH=str(NODE_MODULES)),
                            timeout=120)
    assert result.returncode == 0, result.stderr
    issues = json.loads(result.stdout)["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:5]


def test_glb_imports_in_blender_with_named_shape_keys_and_an_action(mesh_export):
    out, manifest = mesh_export
    require_tool(shutil.which("blender") is not None, "blender")
    result = subprocess.run(["blender", "--background", "--factory-startup", "--python",
                             str(REPO_ROOT / "tests" / "tools" / "blender_import.py"), "--", str(out / "QE.glb"),
                             "120"], capture_output=True, text=True, timeout=300)
    line = next((line for line in result.stdout.splitlines() if line.startswith("IMPORTED ")), None)
    assert line is not None, result.stdout[-2000:] + result.stderr[-2000:]
    imported = json.loads(line[len("IMPORTED "):])
    qe = next(entry for entry in manifest["bases"] if entry["basis"] == "QE")
    assert imported["shape_keys"] == ["Basis", *qe["shapes"]]
    assert imported["vertices"] == 4200 and imported["polygons"] == manifest["n_triangles"]
    ((name, frame_range, n_curves),) = imported["actions"]
    assert name.startswith("QE_nnls") and frame_range == [0.0, 299.0] and n_curves == 18
