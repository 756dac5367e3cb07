"""workbench export: the GLB read back by an independent reader gives the run's alpha and plays back in Blender as
the workbench reconstructs it, whatever the solver; the OBJ folder read back as a hand basis gives the run's table;
takes and their times; the Live Link layout as the app writes it; marker bases, weight curves, bad input and names
that must not leave the export folder."""

import json
import os
import re
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from in_process import run_workbench

from workbench.api import run
from workbench.core.errors import WorkbenchError
from workbench.numerics.metrics import summarise_alpha
from workbench.reporting.export.bases import ExportedBasis, playback_targets
from workbench.reporting.export.command import main
from workbench.reporting.export.run import check_plan, export_path, export_run, file_plan
from workbench.reporting.export.takes import livelink_channels, livelink_csv, timecode
from workbench.settings.config import REPO_ROOT, compose

sys.path.insert(0, str(REPO_ROOT / "tests" / "tools"))
from playback_check import exports_played_back, playback_differences  # noqa: E402  (a helper script beside the Blender one)

# One fit per data variant (the paper regime's extra m = n variants are the regime tests' concern).
RUN = [
    "dataset.n_frames=300",
    "dataset.train_on=[mesh,markers]",
    "solver=nnls",
    "basis.paper_regime=false",
    "save_inputs=true",
]
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
    document = json.loads(data[20 : 20 + json_length])
    bin_start = 20 + json_length
    bin_length, bin_type = struct.unpack_from("<II", data, bin_start)
    assert bin_type == 0x004E4942
    blob = data[bin_start + 8 : bin_start + 8 + bin_length]

    def accessor(index):
        spec = document["accessors"][index]
        view = document["bufferViews"][spec["bufferView"]]
        dtype = {5126: np.float32, 5125: np.uint32}[spec["componentType"]]
        width = {"SCALAR": 1, "VEC3": 3}[spec["type"]]
        start = view.get("byteOffset", 0) + spec.get("byteOffset", 0)
        return np.frombuffer(blob, dtype=dtype, count=spec["count"] * width, offset=start).reshape(spec["count"], width)

    return document, accessor


def rebuild_from_glb(path):
    """Displacements (n_frames, 3 * n_vertices) in mm from a GLB's morph targets and its animations (one per take,
    in order), with the key times and target weights."""
    document, accessor = read_glb(path)
    primitive = document["meshes"][0]["primitives"][0]
    targets = np.stack([accessor(target["POSITION"]).astype(np.float64) for target in primitive["targets"]])
    seconds, weights = [], []
    for animation in document["animations"]:
        sampler = animation["samplers"][0]
        seconds.append(accessor(sampler["input"])[:, 0].astype(np.float64))
        weights.append(accessor(sampler["output"]).astype(np.float64).reshape(len(seconds[-1]), len(targets)))
    weights = np.concatenate(weights)
    frames = weights @ targets.reshape(len(targets), -1) * 1000.0
    return (
        document,
        frames,
        np.concatenate(seconds),
        accessor(primitive["attributes"]["POSITION"]).astype(np.float64),
        weights,
    )


@pytest.mark.parametrize("basis", ["H", "QE", "QE-linear", "PCA"])
def test_glb_morph_targets_and_animation_rebuild_the_runs_alpha(record, mesh_export, basis):
    out, manifest = mesh_export
    document, frames, seconds, neutral, animated = rebuild_from_glb(out / f"{basis}.glb")
    inputs = np.load(record / "inputs_mesh.npz")
    table = pd.read_csv(record / "alpha_table.csv").query("data == 'mesh' and basis == @basis")
    summary = summarise_alpha(inputs["neutral"], inputs["eval"], frames)
    measured = [summary.absolute_mean, summary.absolute_pooled, summary.displacement_mean, summary.displacement_pooled]
    np.testing.assert_allclose(measured, table[ALPHA_COLUMNS].to_numpy()[0], rtol=1e-5, atol=0)
    np.testing.assert_allclose(neutral * 1000.0, inputs["neutral"].reshape(-1, 3), rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(seconds, np.arange(300) / 120.0, rtol=1e-6, atol=1e-7)
    entry = next(entry for entry in manifest["bases"] if entry["basis"] == basis)
    names = entry["shapes"]
    if basis in ("H", "QE"):
        assert names == [str(name) for name in inputs["hand_names"]]
    if basis == "PCA":
        assert names[0] == "pca_mean" and names[1:] == [f"pca_{j + 1:02d}" for j in range(len(names) - 1)]
    assert document["asset"]["extras"]["units"] == "metres" and "+Y up" in document["asset"]["extras"]["axes"]
    extras = document["meshes"][0]["extras"]
    assert extras["targetNames"] == [target["target"] for target in entry["targets"]]
    assert extras["targetShapes"] == [target["shape"] for target in entry["targets"]]
    assert 0.0 <= animated.min() and animated.max() <= 1.0  # every weight within the shape-key slider's range
    curves = pd.read_csv(out / f"{basis}_weights.csv")
    assert list(curves.columns) == ["frame", "time", *names] and len(curves) == 300
    raw = np.zeros((300, len(names)))  # the manifest's recipe: sum of scale x target weight per shape
    for k, target in enumerate(entry["targets"]):
        raw[:, names.index(target["shape"])] += target["scale"] * animated[:, k]
    np.testing.assert_allclose(raw, curves[names].to_numpy(), rtol=1e-6, atol=1e-6)


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
    from workbench.formats.livelink import read_livelink_csv

    names = ["jawOpen", "browInnerUp_L", "browInnerUp_R", "mouthSmile_L", "custom"]
    weights = np.column_stack([np.linspace(0, 1, 5), [0.2] * 5, [0.4] * 5, [-0.5, 0, 0.5, 1, 1.5], [9] * 5])
    seconds = np.arange(5) / 30.0
    text, clipped = livelink_csv(livelink_channels(names, weights), [timecode(t) for t in seconds])
    (tmp_path / "take.csv").write_text(text)
    take = read_livelink_csv(tmp_path / "take.csv")
    column = {name: i for i, name in enumerate(take.names)}
    np.testing.assert_allclose(take.weights[:, column["JawOpen"]], weights[:, 0], atol=1e-10)
    np.testing.assert_allclose(take.weights[:, column["BrowInnerUp"]], 0.3, atol=1e-10)
    np.testing.assert_allclose(take.weights[:, column["MouthSmileLeft"]], [0, 0, 0.5, 1, 1], atol=1e-10)
    assert clipped == 2 and take.weights[:, column["TongueOut"]].max() == 0
    np.testing.assert_array_equal(take.rotations, 0.0)
    np.testing.assert_allclose(take.seconds, seconds, atol=1e-3 / 60)
    assert livelink_channels(["a", "b"], weights[:, :2]) is None


def test_timecodes_keep_the_frame_field_below_the_rate():
    # Live Link's recorded rate is a hair above 30 fps: i / rate falls just short of whole seconds
    seconds = np.arange(4030) / 30.000000000436557
    codes = [timecode(t) for t in seconds]
    fields = np.array([float(code.rsplit(":", 1)[1]) for code in codes])
    assert fields.max() < 60.0 and codes[30] == "00:00:01:00.000" and codes[1] == "00:00:00:02.000"
    assert timecode(3600 * 13 + 13 * 60 + 4 + 31.652 / 60) == "13:13:04:31.652"
    assert timecode(59.99999999) == "00:01:00:00.000" and timecode(0.5, 30.0) == "00:00:00:15.000"
    from workbench.formats.livelink import parse_timecodes

    np.testing.assert_allclose(parse_timecodes(codes, 60.0, Path("x")), seconds, atol=0.5e-3 / 60)


def test_playback_targets_keep_weights_in_the_slider_range_and_the_frames_exact():
    rng = np.random.default_rng(0)
    names = ["a", "b", "c", "pca_01", "pca_02"]
    weights = np.column_stack(
        [
            rng.uniform(0, 1, 50),
            rng.uniform(-2, 3.5, 50),
            rng.uniform(-0.5, 0.9, 50),
            rng.normal(0, 40, 50),
            np.zeros(50),
        ]
    )
    weights[3, 0] = 1.0 + 1e-12  # a solver's rounding: clipped, not split
    shapes = rng.normal(size=(5, 12))
    targets = playback_targets(names, weights, [True, True, True, False, False])
    assert targets.names == ("a", "b", "b_over", "b_neg", "c", "c_neg", "pca_01_pos", "pca_01_neg", "pca_02_pos")
    assert targets.weights.min() == 0.0 and targets.weights.max() == 1.0
    np.testing.assert_allclose(targets.scales[[0, 1, 2, 3]], [1.0, 1.0, weights[:, 1].max() - 1, weights[:, 1].min()])
    np.testing.assert_allclose(targets.scales[6:8], [weights[:, 3].max(), weights[:, 3].min()])
    np.testing.assert_allclose(
        targets.raw_weights(5), np.where(weights > 1 + 1e-9, weights, weights.clip(max=1)), rtol=0, atol=1e-13
    )
    np.testing.assert_allclose(targets.weights @ targets.deltas(shapes), weights @ shapes, rtol=0, atol=1e-11)
    with pytest.raises(WorkbenchError, match=r"morph target name\(s\) \['b_neg'\] would repeat"):
        playback_targets(["b", "b_neg"], np.array([[-1.0, 0.5]]), [True, True])


def test_bad_requests_are_one_line_errors(record, tmp_path):
    with pytest.raises(WorkbenchError, match=r"is not a complete run record \(no 'done' file\)"):
        export_run(tmp_path, tmp_path / "out")
    with pytest.raises(WorkbenchError, match=r"export --data face: the run's data variants are \['mesh', 'markers'\]"):
        export_run(record, tmp_path / "out", data="face")
    with pytest.raises(WorkbenchError, match=r"export --solver box: the run's solvers are \['nnls'\]"):
        export_run(record, tmp_path / "out", solver="box")
    with pytest.raises(
        WorkbenchError,
        match=r"export --bases ICA: data 'mesh' with solver 'nnls' has bases "
        r"\['H', 'QE', 'QE-linear', 'PCA'\]",
    ):
        export_run(record, tmp_path / "out", bases=["ICA"])
    tampered = tmp_path / "tampered"
    shutil.copytree(record, tampered)
    table = pd.read_csv(tampered / "alpha_table.csv")
    table.loc[1, "alpha_abs_pooled"] *= 1.01  # a pooled alpha: no per-frame array or comparison holds it
    table.to_csv(tampered / "alpha_table.csv", index=False)
    with pytest.raises(WorkbenchError, match=r"alpha_table\.csv was changed after the run"):
        export_run(tampered, tmp_path / "out")
    # a table whose checksum matches (a record written by other code) is still recomputed and compared
    import json

    from workbench.core.files import sha256_of_file as file_checksum
    from workbench.record.record import DONE

    # ... and whose metrics.json says the same (a record's values are read against its table first)
    metrics = json.loads((tampered / "metrics.json").read_text())
    metrics["rows"][1]["alpha_abs_pooled"] = float(table.loc[1, "alpha_abs_pooled"])  # the table's row 1, as read
    (tampered / "metrics.json").write_text(json.dumps(metrics))
    done = json.loads((tampered / DONE).read_text())
    for name in ("alpha_table.csv", "metrics.json"):
        done["sha256"][name] = file_checksum(tampered / name)
    (tampered / DONE).write_text(json.dumps(done))
    with pytest.raises(WorkbenchError, match=r"recomputing the run gives alpha .* away from the recorded table"):
        export_run(tampered, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_hand_basis_bad_input(record, mesh_export, tmp_path):
    out, _ = mesh_export

    def build(**spec):
        from workbench.api import build_captures  # checks the settings, as a study does

        cfg = compose("paper", RUN[:-1] + ["dataset.train_on=mesh"]).dataset
        return build_captures(dict(cfg, hand_basis=spec))

    with pytest.raises(WorkbenchError, match=r"dataset.hand_basis.path .*nowhere: not found"):
        build(path=str(tmp_path / "nowhere"))
    with pytest.raises(WorkbenchError, match=r"its neutral lies up to .* mm from the data's .*other units \(unit_mm\)"):
        build(path=str(out / "H_obj"), unit_mm=10.0)
    with pytest.raises(WorkbenchError, match=r"setting dataset.hand_basis.unit does not exist; dataset.hand_basis has"):
        build(path=str(out / "H_obj"), unit=10.0)
    with pytest.raises(
        WorkbenchError, match=r"dataset.hand_basis.region_vertices must be an integer >= 3 or null, got 2.5"
    ):
        build(path=str(out / "H_obj"), region_vertices=2.5)
    with pytest.raises(WorkbenchError, match=r"dataset.hand_basis.unit_mm must be a positive, finite number or null"):
        build(path=str(out / "H_obj"), unit_mm=-1)
    with pytest.raises(WorkbenchError, match=r"dataset.hand_basis must be a mapping with a 'path' \(an OBJ"):
        build(shapes=["jaw_open"])
    with pytest.raises(
        WorkbenchError,
        match=r"dataset.hand_basis: needs distinct shape names of the file's .*"
        r"missing \['smile'\]",
    ):
        build(path=str(out / "H_obj"), shapes=["jaw_open", "smile"])
    stated = tmp_path / "stated"
    shutil.copytree(out / "H_obj", stated)
    (stated / "manifest.json").write_text(json.dumps({"unit": "m", "unit_mm": "a lot"}))
    with pytest.raises(
        WorkbenchError, match=r"stated/manifest.json: field 'unit_mm' must be a positive, finite number"
    ):
        build(path=str(stated))
    (stated / "manifest.json").write_text("{")
    with pytest.raises(WorkbenchError, match=r"stated/manifest.json: not a readable JSON file"):
        build(path=str(stated))
    (stated / "manifest.json").unlink()  # no manifest: mm, so a metre folder is 1,000 times too small
    with pytest.raises(WorkbenchError, match=r"its neutral lies up to .* mm from the data's"):
        build(path=str(stated))
    assert build(path=str(stated), unit_mm=1000.0)
    from dataclasses import replace

    from workbench.formats.gltf import glb_bytes, read_morph_mesh

    mesh = read_morph_mesh(out / "H.glb")
    deltas = mesh.deltas.copy()
    deltas[2] = deltas[0] + deltas[1]  # a shape the two first make: the file's basis is rank-deficient
    (tmp_path / "dependent.glb").write_bytes(glb_bytes(replace(mesh, deltas=deltas, path=None)))
    with pytest.raises(
        WorkbenchError,
        match=f"^dataset.hand_basis.path {re.escape(str(tmp_path / 'dependent.glb'))}: hand basis is rank-deficient",
    ):
        build(path=str(tmp_path / "dependent.glb"))
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
    result = run_workbench("export", str(record), "--bases", "XYZ", "--out", str(tmp_path / "x"), cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert result.stderr.startswith("workbench export: error: export --bases XYZ")


# --- independent readers: the Khronos validator and Blender (required where WORKBENCH_REQUIRE_TOOLS=1, as in CI) ---


def require_tool(available: bool, what: str):
    if not available:
        if TOOLS_REQUIRED:
            pytest.fail(f"{what} not found -- required because WORKBENCH_REQUIRE_TOOLS=1", pytrace=False)
        pytest.skip(f"{what} not found (see docs/export.md to install it)")


def validate(path: Path) -> dict:
    """The Khronos validator's issues for one file."""
    require_tool(
        shutil.which("node") is not None and (NODE_MODULES / "gltf-validator").is_dir(),
        f"node and the gltf-validator package (in {NODE_MODULES})",
    )
    script = REPO_ROOT / "tests" / "tools" / "validate_gltf.js"
    result = subprocess.run(
        ["node", str(script), str(path)],
        capture_output=True,
        text=True,
        env=dict(os.environ, NODE_PATH=str(NODE_MODULES)),
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)["issues"]


@pytest.fixture(scope="module")
def every_solver(tmp_path_factory):
    """A synthetic mesh run under every solver, exported under each: (solver, folder, manifest, raw bases)."""
    from workbench.record.replay import replay
    from workbench.reporting.export.bases import exported_bases
    from workbench.reporting.export.run import read_run_record

    folder = tmp_path_factory.mktemp("solvers") / "run"
    run(
        compose("paper", ["dataset.n_frames=300", "dataset.train_on=mesh", "solver=all", "basis.paper_regime=false"]),
        folder,
    )
    record = read_run_record(folder)
    (result,) = replay(record, "a test replays it")
    exports = []
    for solver in ("lstsq", "nnls", "box"):
        out = folder.parent / solver
        exports.append(
            (solver, out, export_run(folder, out, solver=solver), exported_bases(result, None, solver, record.table))
        )
    return exports, result.capture.neutral.reshape(-1, 3)


@pytest.mark.slow
@pytest.mark.process
@pytest.mark.parametrize("basis", ["H", "QE", "PCA"])
def test_glb_passes_the_khronos_validator(mesh_export, every_solver, basis):
    out, _ = mesh_export
    (_, split, _, _), *_ = every_solver[0]  # lstsq: targets split on both sides of [0, 1]
    for path in (out / f"{basis}.glb", split / f"{basis}.glb"):
        issues = validate(path)
        assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, (path, issues["messages"][:5])


@pytest.mark.slow
@pytest.mark.process
def test_every_solvers_glb_plays_back_in_blender_as_the_workbench_reconstructs(every_solver, tmp_path):
    """The stock importer in Blender 3.4, the docs' recipe, the mesh evaluated through the depsgraph at keys spread
    over the take (and the one furthest outside [0, 1]): every vertex within 1e-3 mm of the workbench's
    reconstruction, for every basis and solver."""
    require_tool(shutil.which("blender") is not None, "blender")
    exports, neutral = every_solver
    worst = {}
    played_back = exports_played_back(exports, neutral, 12, tmp_path)  # every solver's files in one Blender
    for solver, out, manifest, bases in exports:
        for label, found in played_back[solver].items():
            worst[(label, solver)] = found["max_abs_mm"]
            entry = next(entry for entry in manifest["bases"] if entry["basis"] == label)
            imported = found["imported"]
            assert [key[0] for key in imported["shape_keys"]] == ["Basis", *[t["target"] for t in entry["targets"]]]
            assert all(key[1:] == [0.0, 1.0] for key in imported["shape_keys"])  # the sliders the importer set
            assert imported["vertices"] == 4200 and imported["polygons"] == manifest["n_triangles"]
            assert imported["fps"] == 120 and imported["fps_base"] == 1.0 and imported["frame_range"] == [0, 299]
            assert imported["actions"] == {entry["animations"][0]: [0.0, 299.0]}
    assert len(worst) == 12 and max(worst.values()) < 1e-3, worst
    lstsq = next(bases for solver, _, _, bases in exports if solver == "lstsq")
    assert all((basis.weights < -0.01).any() for basis in lstsq if basis.label != "PCA")  # the case that clamped


# --- real takes: several takes at 7.5 fps (AnimFace), the Live Link take's own timecodes (ICT) ---


@pytest.fixture(scope="module")
def animface_export(shared_data, tmp_path_factory):
    from workbench.record.replay import replay
    from workbench.reporting.export.bases import exported_bases
    from workbench.reporting.export.run import read_run_record

    folder = tmp_path_factory.mktemp("animface") / "run"
    run(
        compose(
            "paper",
            [
                "dataset=animface",
                f"paths.data_root={shared_data}",
                "dataset.frame_step=8",
                "dataset.max_frames_per_take=40",
                "dataset.train_on=mesh",
                "solver=lstsq",
                "basis.paper_regime=false",
            ],
        ),
        folder,
    )
    out = folder.parent / "export"
    manifest = export_run(folder, out)
    record = read_run_record(folder)
    (result,) = replay(record, "a test replays it")
    return out, manifest, exported_bases(result, None, "lstsq", record.table), result.capture.neutral.reshape(-1, 3)


@pytest.mark.slow
def test_takes_get_their_own_animation_files_and_times(animface_export):
    from workbench.formats.livelink import read_livelink_csv

    out, manifest, _, _ = animface_export
    takes = ["animface_jaw", "animface_cheeks", "animface_eyebrows"]
    assert [take["take"] for take in manifest["takes"]] == takes and manifest["frame_rate"] == 7.5
    for take, facts in zip(takes, manifest["takes"]):
        assert facts["blender"] == {"fps": 15, "fps_base": 2.0, "frame_start": 0, "frame_end": 39}
        curves = pd.read_csv(out / f"H_{take}_weights.csv")
        np.testing.assert_array_equal(curves["frame"], np.arange(40) * 8)
        np.testing.assert_allclose(curves["time"], np.arange(40) * 8 / 60.0, rtol=1e-8, atol=0)
        livelink = read_livelink_csv(out / f"H_{take}_livelink.csv")
        np.testing.assert_allclose(livelink.seconds, curves["time"], atol=1e-3 / 60)
    document, _ = read_glb(out / "QE.glb")
    assert [animation["name"] for animation in document["animations"]] == [f"QE_lstsq_{take}" for take in takes]
    assert [take["animation"] for take in document["asset"]["extras"]["takes"]] == [
        f"QE_lstsq_{take}" for take in takes
    ]
    assert not list(out.glob("H_weights.csv")) and not list(out.glob("H_livelink.csv"))


@pytest.mark.slow
@pytest.mark.process
def test_takes_play_back_in_blender_at_7_5_fps(animface_export, tmp_path):
    require_tool(shutil.which("blender") is not None, "blender")
    out, manifest, bases, neutral = animface_export
    found = playback_differences(out, manifest, bases, neutral, 6, tmp_path)
    assert max(facts["max_abs_mm"] for facts in found.values()) < 1e-3, found
    for label, facts in found.items():
        imported = facts["imported"]
        assert imported["fps"] == 15 and imported["fps_base"] == 2.0  # 7.5 frames per second
        assert sorted(imported["actions"].values()) == [[0.0, 39.0]] * 3  # one key per Blender frame
    for label in ("QE", "PCA"):
        issues = validate(out / f"{label}.glb")
        assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:5]


@pytest.fixture(scope="module")
def ict_export(shared_data, tmp_path_factory):
    folder = tmp_path_factory.mktemp("ict") / "run"
    run(
        compose(
            "paper",
            ["dataset=ict_livelink", f"paths.data_root={shared_data}", "dataset.train_on=markers", "solver=lstsq"],
        ),
        folder,
    )
    return folder


def test_livelink_csv_is_the_source_takes_layout_and_timecodes(shared_data, ict_export, tmp_path, capsys):
    from workbench.formats.livelink import ROTATION_NAMES, parse_timecodes

    source_path = shared_data / "livelinkface" / "alex_rom_3.csv"
    assert main([str(ict_export), "--out", str(tmp_path), "--bases", "H,QE"]) == 0
    warnings = capsys.readouterr().err.splitlines()
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    source_lines = source_path.read_text().splitlines()
    source = pd.read_csv(source_path, dtype=str)
    for entry in manifest["bases"]:
        lines = (tmp_path / f"{entry['basis']}_livelink.csv").read_text().splitlines()
        assert lines[0] == source_lines[0]  # the app's header, byte for byte: 61 channels, 63 columns
        ours = pd.read_csv(tmp_path / f"{entry['basis']}_livelink.csv", dtype=str)
        frames = pd.read_csv(tmp_path / f"{entry['basis']}_weights.csv")["frame"].to_numpy()
        assert len(ours) == len(frames) == 4030
        # frame by frame: the source's own timecodes (time of day, sub-frame part) and rotations
        assert (ours["Timecode"].to_numpy() == source["Timecode"].to_numpy()[frames]).all()
        assert (ours[list(ROTATION_NAMES)].to_numpy() == source[list(ROTATION_NAMES)].to_numpy()[frames]).all()
        assert (ours["BlendShapeCount"] == "61").all()
        numbers = ours.drop(columns=["Timecode", "BlendShapeCount"]).to_numpy().ravel()
        assert all(re.fullmatch(r"-?\d\.\d{10}", value) for value in numbers)
        fields = np.array([float(code.rsplit(":", 1)[1]) for code in ours["Timecode"]])
        assert fields.max() < 60.0
        seconds = parse_timecodes(list(ours["Timecode"]), 60.0, Path("ours"))
        times = pd.read_csv(tmp_path / f"{entry['basis']}_weights.csv")["time"].to_numpy()
        np.testing.assert_allclose(seconds - seconds[0], times, rtol=0, atol=1e-6)  # times in %.9g
        weights = pd.read_csv(tmp_path / f"{entry['basis']}_weights.csv")
        outside = ((weights["jawOpen"] < 0) | (weights["jawOpen"] > 1)).sum()
        np.testing.assert_allclose(ours["JawOpen"].astype(float), weights["jawOpen"].clip(0, 1), atol=6e-11)
        assert entry["livelink_clipped"]["values"] >= outside > 0
        assert entry["livelink_clipped"]["of"] == 4030 * 52
    assert manifest["takes"][0]["missing_frames"] == 3  # the take's dropped frames stay gaps
    qe = next(entry for entry in manifest["bases"] if entry["basis"] == "QE")["livelink_clipped"]["values"]
    assert f"warning: QE: {qe:,} of {4030 * 52:,} ARKit values" in warnings[1] and len(warnings) == 2


# --- units and names ---


def test_obj_folders_are_in_metres_unless_millimetres_are_asked_for(record, mesh_export, tmp_path):
    out, manifest = mesh_export
    neutral = np.load(record / "inputs_mesh.npz")["neutral"].reshape(-1, 3)

    def vertices(path):
        return np.array([line.split()[1:] for line in path.read_text().splitlines() if line.startswith("v ")], float)

    np.testing.assert_allclose(vertices(out / "H_obj" / "neutral.obj") * 1000.0, neutral, rtol=1e-8, atol=1e-9)
    assert json.loads((out / "H_obj" / "manifest.json").read_text())["unit_mm"] == 1000.0
    assert manifest["units"]["obj"] == "m"
    millimetres = export_run(record, tmp_path, data="mesh", bases=["H"], obj_unit="mm")
    np.testing.assert_allclose(vertices(tmp_path / "H_obj" / "neutral.obj"), neutral, rtol=1e-8, atol=1e-9)
    assert json.loads((tmp_path / "H_obj" / "manifest.json").read_text())["unit_mm"] == 1.0
    assert millimetres["units"]["obj"] == "mm"
    with pytest.raises(WorkbenchError, match=r"export --obj-unit cm: must be one of \['m', 'mm'\]"):
        export_run(record, tmp_path, obj_unit="cm")


@pytest.mark.parametrize("name", ["../../x", "sub/dir/name", "", ".", "..", "a\\b"])
def test_names_that_would_leave_the_export_folder_are_refused(tmp_path, name):
    with pytest.raises(
        WorkbenchError,
        match=r"cannot name a file inside .*: a shape, take or basis name must be a "
        r"plain name",
    ):
        export_path(tmp_path, "H_obj", f"{name}.obj" if name not in ("", ".", "..") else name)


@pytest.mark.parametrize(
    "names, message",
    [
        (["jaw", ""], r"'' cannot name a file inside"),
        (["jaw", "."], r"'\.' cannot name a file inside"),
        (["neutral", "jaw"], r"\['neutral\.obj'\] would be written twice into .*H_obj"),
        (["Jaw", "jaw"], r"\['Jaw\.obj', 'jaw\.obj'\] would be written twice"),
    ],
)
def test_every_file_name_is_checked_before_anything_is_written(tmp_path, names, message):
    from workbench.dataset.capture import Capture
    from workbench.reporting.export.takes import export_takes

    capture = Capture(
        name="x",
        neutral=np.zeros(9),
        train=np.zeros((2, 9)),
        eval=np.zeros((2, 9)),
        hand=np.zeros((2, 9)),
        hand_names=tuple(names),
        point_labels=("a", "b", "c"),
        units="mm",
        origin="o",
        frame_rate=30.0,
    )
    basis = ExportedBasis(
        label="H",
        names=tuple(names),
        shapes=np.zeros((2, 9)),
        weights=np.zeros((2, 2)),
        solver="lstsq",
        alpha={},
        sculpted=(True, True),
    )
    plan = file_plan(basis, export_takes(capture, None, 60.0), mesh=True, arkit=False)
    with pytest.raises(WorkbenchError, match=message):
        check_plan(tmp_path / "out", [plan])
    assert not (tmp_path / "out").exists()


def with_target_names(glb: Path, names: list, path: Path) -> None:
    """A copy of a .glb with other morph-target names (the JSON chunk rewritten, padded to 4 bytes)."""
    data = glb.read_bytes()
    length = struct.unpack_from("<I", data, 12)[0]
    document = json.loads(data[20 : 20 + length])
    document["meshes"][0]["extras"]["targetNames"] = names
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    rest = data[20 + length :]
    path.write_bytes(
        struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + len(rest))
        + struct.pack("<II", len(text), 0x4E4F534A)
        + text
        + rest
    )


def test_export_of_shapes_named_like_paths_stops_before_writing(mesh_export, tmp_path):
    out, manifest = mesh_export
    targets = [target["target"] for target in next(e for e in manifest["bases"] if e["basis"] == "H")["targets"]]
    hostile = ["../../x", "sub/dir/name", ""] + targets[3:]
    with_target_names(out / "H.glb", hostile, tmp_path / "hostile.glb")
    shapes = "[" + ",".join(f"'{name}'" for name in hostile[:18]) + "]"
    folder = tmp_path / "run"
    run(
        compose(
            "paper",
            [
                "dataset.n_frames=300",
                "dataset.train_on=mesh",
                "solver=lstsq",
                f"+dataset.hand_basis.path={tmp_path / 'hostile.glb'}",
                f"+dataset.hand_basis.shapes={shapes}",
            ],
        ),
        folder,
    )
    before = sorted(path for path in tmp_path.rglob("*"))
    result = run_workbench("export", str(folder), "--out", str(tmp_path / "deep" / "out"), cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert "'../../x' cannot name a file inside" in result.stderr
    assert sorted(path for path in tmp_path.rglob("*")) == before and not (tmp_path / "x.obj").exists()


def test_export_never_follows_a_symbolic_link_out_of_its_folder(record, tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.glb").write_bytes(b"not the workbench's")
    out = tmp_path / "out"
    out.mkdir()
    (out / "H_obj").symlink_to(outside, target_is_directory=True)
    with pytest.raises(WorkbenchError, match=r"refusing to write .*H_obj.*: .*H_obj is a symbolic link"):
        export_run(record, out, data="mesh", bases=["H"])
    (out / "H_obj").unlink()
    (out / "H.glb").symlink_to(outside / "keep.glb")
    with pytest.raises(WorkbenchError, match=r"H\.glb is a symbolic link"):
        export_run(record, out, data="mesh", bases=["H"])
    assert sorted(p.name for p in outside.iterdir()) == ["keep.glb"]
    assert (outside / "keep.glb").read_bytes() == b"not the workbench's"
    assert sorted(p.name for p in out.iterdir()) == ["H.glb"]  # nothing written
