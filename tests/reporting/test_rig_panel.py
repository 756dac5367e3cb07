"""Pose the rigs: the report's panel of the H and QE rigs, used in real headless Chromium as a person would use it
(Debian's chromium driven by puppeteer-core from npm): it loads from file:// without errors, a slider moves both
faces, the vertices it poses are the rig's neutral + sum w e, and the timeline shows the weights the export writes."""

import base64
import json
import os
import shutil
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image
from test_export import validate

import workbench
from workbench.api import run
from workbench.reporting.export.run import export_run
from workbench.reporting.report.command import main
from workbench.settings.config import REPO_ROOT, compose

NODE_MODULES = Path(os.environ.get("WORKBENCH_NODE_MODULES", REPO_ROOT / ".ci" / "node" / "node_modules"))
STEPS_SCRIPT = REPO_ROOT / "tests" / "tools" / "browser_steps.js"
pytestmark = [pytest.mark.slow, pytest.mark.process]  # a report built, then node and Chromium drive its page


def panel_data(report_folder: Path) -> dict:
    text = (report_folder / "figures" / "rigs.js").read_text()
    assert text.startswith("window.WORKBENCH_RIGS = ")
    return json.loads(text[len("window.WORKBENCH_RIGS = ") :].rstrip().rstrip(";"))


def rig_files(data: dict, folder: Path) -> dict:
    """Each rig's .glb as the page holds it, written to a file."""
    files = {}
    for rig in data["rigs"]:
        path = folder / f"{rig['key'].replace(' ', '_').replace('=', '')}.glb"
        path.write_bytes(zlib.decompress(base64.b64decode(rig["glb"])))
        files[rig["key"]] = path
    return files


def test_report_on_a_mesh_run_writes_the_panel_with_the_exports_rigs(tiny_report, tmp_path):
    """The section, three.js with its licence beside the page, and every rig a .glb the workbench's reader reads
    and the Khronos validator passes: the H rig's targets are the hand shapes, the QE rigs' their projections."""
    _, out = tiny_report
    page = (out / "index.html").read_text()
    assert "<h2>Pose the rigs</h2>" in page and "Pose the rigs" in (out / "README.md").read_text()
    assert 'src="figures/three.min.js"' in page and 'src="figures/rigs.js"' in page
    assert "MIT License" in (out / "figures" / "three-LICENSE.txt").read_text()
    assert (out / "figures" / "three.min.js").stat().st_size > 100_000
    data = panel_data(out)
    assert [rig["key"] for rig in data["rigs"]] == ["H", "QE", "QE m=n"]
    assert data["shapes"][-1] == "jaw_open" and len(data["shapes"]) == 18
    with _inputs(tiny_report) as inputs:
        hand, kept = inputs["hand"], np.asarray(data["kept"])
        rows = (3 * kept[:, None] + np.arange(3)).ravel()
        neutral = inputs["neutral"][rows]
    for key, path in rig_files(data, tmp_path).items():
        mesh = workbench.read_gltf(path)
        assert mesh.names[: len(data["shapes"])] == tuple(data["shapes"]) and mesh.animations == ()
        np.testing.assert_allclose(mesh.neutral.ravel(), neutral, rtol=0, atol=1e-4)
        if key == "H":
            np.testing.assert_allclose(mesh.deltas.reshape(len(mesh.names), -1), hand[:, rows], rtol=0, atol=1e-5)
        else:
            assert np.abs(mesh.deltas.reshape(len(mesh.names), -1)[:18] - hand[:, rows]).max() > 0.1
        issues = validate(path)
        assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, (key, issues["messages"][:5])


def _inputs(report):
    record, _ = report
    return np.load(record / "inputs_mesh.npz")


def browser_steps(chromium: str, page: Path, steps: list, scratch: Path) -> dict:
    """Run ``tests/tools/browser_steps.js`` on a page: what each step saw, the page's console errors and warnings
    and its uncaught exceptions."""
    from test_export import require_tool

    require_tool(
        shutil.which("node") is not None and (NODE_MODULES / "puppeteer-core").is_dir(),
        f"node and the puppeteer-core package (in {NODE_MODULES})",
    )
    file = scratch / "steps.json"
    file.write_text(json.dumps(steps))
    done = subprocess.run(
        ["node", str(STEPS_SCRIPT), chromium, str(page), str(file)],
        capture_output=True,
        text=True,
        timeout=300,
        env=dict(os.environ, NODE_PATH=str(NODE_MODULES)),
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout)


def page_problems(seen: dict) -> list[str]:
    """Errors the page logged or threw (the software renderer's performance notes aside)."""
    logged = [line for line in seen["console"] if not line.startswith("warn: [.WebGL-") or "GL_INVALID" in line]
    return logged + seen["errors"]


def thirds(path: Path) -> list[np.ndarray]:
    pixels = np.asarray(Image.open(path).convert("RGB"), dtype=np.int16)
    width = pixels.shape[1] // 3
    return [pixels[:, k * width : (k + 1) * width] for k in range(3)]


def posed(mesh, weights: np.ndarray) -> np.ndarray:
    """neutral + sum w e of a rig read by the workbench (mm), one value per morph target."""
    return mesh.neutral.ravel() + weights @ mesh.deltas.reshape(len(mesh.names), -1)


def test_sliders_pose_both_rigs_as_the_rigs_files_say(tiny_report, chromium, tmp_path):
    """Loaded from file:// with no network: no console errors; dragging a slider changes the pixels of both faces;
    the vertices the page poses (read back from it) equal neutral + sum w e of the rig's .glb to 1e-4 mm, for H and
    both QE rigs, at the slider's value, after solo and after reset."""
    _, out = tiny_report
    data = panel_data(out)
    jaw = data["shapes"].index("jaw_open")
    read_back = "JSON.stringify({w: Object.fromEntries(workbenchRigs.rigs.map((k) => [k, workbenchRigs.rawWeights(k)])), p: Object.fromEntries(workbenchRigs.rigs.map((k) => [k, workbenchRigs.positions(k)]))})"
    steps = [
        {"wait": "#rigs", "attribute": "data-status", "not": "loading"},
        {"screenshot": str(tmp_path / "rest.png"), "selector": "#rigs-canvas"},
        {"click": f"#rigs-s{jaw}", "x": 0.7},
        {"screenshot": str(tmp_path / "jaw.png"), "selector": "#rigs-canvas"},
        {"eval": read_back},
        {
            "eval": "document.querySelector('#rigs-qe').selectedIndex = 1; document.querySelector('#rigs-qe').dispatchEvent(new Event('change')); 0"
        },
        {"eval": read_back},
        {"click": f"#rigs-sliders .rigs-shape:nth-child({jaw + 1}) button", "x": 0.5},
        {"eval": read_back},
        {"click": "#rigs-reset", "x": 0.5},
        {"eval": read_back},
        {"screenshot": str(tmp_path / "panel.png"), "selector": "#rigs-figure"},
    ]
    seen = browser_steps(chromium, out / "index.html", steps, tmp_path)
    assert seen["results"][0] == "drawn", seen["results"][0]
    assert not page_problems(seen), page_problems(seen)
    before, after = thirds(tmp_path / "rest.png"), thirds(tmp_path / "jaw.png")
    for face, name in ((1, "H"), (2, "QE")):
        changed = np.abs(after[face] - before[face]).sum(axis=2) > 30
        assert changed.mean() > 0.002, (name, changed.mean())
    meshes = {key: workbench.read_gltf(path) for key, path in rig_files(data, tmp_path).items()}
    dragged = json.loads(seen["results"][4])["w"]["H"][jaw]
    assert 0.5 < dragged < 0.9  # where the click put the slider
    for index, expected in ((4, dragged), (6, dragged), (8, 1.0), (10, 0.0)):
        state = json.loads(seen["results"][index])
        for key, mesh in meshes.items():
            weights = np.zeros(len(mesh.names))
            weights[jaw] = expected
            assert state["w"][key][jaw] == pytest.approx(expected, abs=1e-12) and sum(map(abs, state["w"][key])) == (
                pytest.approx(abs(expected), abs=1e-12)
            )
            np.testing.assert_allclose(state["p"][key], posed(mesh, weights), rtol=0, atol=1e-4)
    shutil.copy(tmp_path / "panel.png", Path(os.environ.get("WORKBENCH_PANEL_SCREENSHOT", tmp_path / "kept.png")))


def test_the_timeline_shows_the_weights_the_export_writes(tiny_report, chromium, tmp_path):
    """Moving the timeline to a frame drives the rigs with the weights the chosen solver found: those of the weights
    CSV ``workbench export`` writes for that frame (H and QE of the mesh data, QE of its m = n variant), for lstsq and
    box; the faces are the rig's neutral + sum w e."""
    record, out = tiny_report
    data = panel_data(out)
    assert data["solvers"] == ["lstsq", "nnls", "box"]  # the run's, the figures' lstsq first
    read_back = (
        "JSON.stringify([document.querySelector('#rigs').getAttribute('data-key'), Object.fromEntries("
        "workbenchRigs.rigs.map((k) => [k, [workbenchRigs.rawWeights(k), workbenchRigs.positions(k)]]))])"
    )
    steps = [{"wait": "#rigs", "attribute": "data-status", "not": "loading"}]
    for solver, x in (("lstsq", 0.3), ("box", 0.85)):
        choose = (
            "(() => { const s = document.querySelector('#rigs-solver'); "
            f"s.value = '{solver}'; s.dispatchEvent(new Event('change')); return s.value; }})()"
        )
        steps += [{"eval": choose}, {"click": "#rigs-key", "x": x}, {"eval": read_back}]
    seen = browser_steps(chromium, out / "index.html", steps, tmp_path)
    assert not page_problems(seen), page_problems(seen)
    meshes = {key: workbench.read_gltf(path) for key, path in rig_files(data, tmp_path).items()}
    keys_seen = []
    for solver, at in (("lstsq", 3), ("box", 6)):
        assert seen["results"][at - 2] == solver
        csv = {}
        for variant, bases, keys in (("mesh", ["H", "QE"], ["H", "QE"]), ("mesh m=n", ["QE"], ["QE m=n"])):
            folder = tmp_path / f"{variant.replace(' ', '_').replace('=', '')}_{solver}"
            export_run(record, folder, data=variant, bases=bases, solver=solver)
            for basis, key in zip(bases, keys):
                csv[key] = pd.read_csv(folder / f"{basis}_weights.csv")
        key, state = json.loads(seen["results"][at])
        key = int(key)
        keys_seen.append(key)
        frame = data["timeline"]["frame"][key]
        for rig, table in csv.items():
            row = table[table["frame"] == frame]
            assert len(row) == 1, (rig, frame)
            np.testing.assert_allclose(state[rig][0], row[data["shapes"]].to_numpy()[0], rtol=1e-6, atol=1e-9)
            spec = data["rigs"][[r["key"] for r in data["rigs"]].index(rig)]
            weights = np.asarray(spec["weights"][solver][key])
            np.testing.assert_allclose(state[rig][1], posed(meshes[rig], weights), rtol=0, atol=1e-4)
        if solver == "box":
            assert all(0 <= w <= 1 for rig in csv for w in state[rig][0])
        else:
            assert any(not 0 <= w <= 1 for rig in csv for w in state[rig][0])  # lstsq leaves the slider range
    assert 0 <= keys_seen[0] < keys_seen[1]


def test_a_copied_report_poses_its_rigs_with_no_network(tiny_report, chromium, tmp_path):
    """Everything the panel needs is in the report's folder: a copy elsewhere loads three.js and the rigs."""
    _, out = tiny_report
    copy = tmp_path / "elsewhere" / "a copy"
    shutil.copytree(out, copy)
    seen = browser_steps(
        chromium, copy / "index.html", [{"wait": "#rigs", "attribute": "data-status", "not": "loading"}], tmp_path
    )
    assert seen["results"] == ["drawn"] and not page_problems(seen)
    (copy / "figures" / "three.min.js").unlink()
    seen = browser_steps(
        chromium, copy / "index.html", [{"wait": "#rigs", "attribute": "data-status", "not": "loading"}], tmp_path
    )
    assert seen["results"] == ["error: three.js (figures/three.min.js) did not load"]


def test_a_run_on_markers_alone_poses_its_rigs_carried_onto_the_face_mesh(chromium, tmp_path):
    """A run without a mesh variant (the default study: markers) gets the panel too: its marker shapes and frames
    carried onto the synthetic actor's face mesh, as its other face figures are, the weights solved on the markers."""
    record = tmp_path / "run"
    run(compose("paper", ["dataset.n_frames=300", "save_inputs=true", "solver=box"]), record)
    out = tmp_path / "report"
    assert main([str(record), "--out", str(out)]) == 0
    data = panel_data(out)
    assert data["solvers"] == ["box"] and [rig["key"] for rig in data["rigs"]] == ["H", "QE", "QE m=n"]
    assert "carried onto the mesh by RBF" in (out / "index.html").read_text()
    with np.load(record / "inputs_markers.npz") as inputs:
        n_markers = len(inputs["neutral"]) // 3
    mesh = workbench.read_gltf(rig_files(data, tmp_path)["H"])
    assert len(mesh.neutral) == data["n_vertices"] > 4 * n_markers  # a face mesh, not the markers
    assert all(0 <= w <= 1 for rig in data["rigs"] for row in rig["weights"]["box"] for w in row)
    seen = browser_steps(
        chromium,
        out / "index.html",
        [{"wait": "#rigs", "attribute": "data-status", "not": "loading"}, {"click": "#rigs-key", "x": 0.5}],
        tmp_path,
    )
    assert seen["results"][0] == "drawn" and not page_problems(seen), (seen["results"][0], page_problems(seen))
