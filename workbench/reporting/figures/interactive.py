"""Faces you can turn: a self-contained interactive 3-D view of captured and reconstructed frames for the HTML
report, and a short animation of captured | H | QE over a stretch of the take.

The view uses plotly.js (its ``gl3d`` partial bundle, vendored from the npm package ``plotly.js-gl3d-dist-min``,
MIT licence): a maintained WebGL library that rotates and zooms a shaded mesh with a colour bar and needs no
server. It is a classic script, so the page works when opened from ``file://`` without network. The bundle is
written once per reports folder (``<reports>/vendor/``), the mesh data once per report (``figures/view3d.js``):
vertex displacements quantised to 0.05 mm (invisible at face scale) and colours to 256 levels, their bytes split
into planes (low bytes, then high bytes: the high ones are mostly equal and compress well), zlib-compressed and
decoded in the browser by ``DecompressionStream``.
"""

from __future__ import annotations

import base64
import json
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from workbench.record import write_atomic

PLOTLY_BUNDLE = Path(__file__).parent / "vendor" / "plotly-gl3d.min.js"
PLOTLY_VERSION = "3.7.0"
PLOTLY_FILE = f"plotly-gl3d-{PLOTLY_VERSION}.min.js"
DATA_FILE = "view3d.js"
STEP_MM = 0.05  # quantisation of the displacements in the page
# Matplotlib colour map -> plotly colour scale, reversed in the page (plotly's run from dark to light).
COLOURSCALES = {"YlGnBu": "YlGnBu", "YlOrRd": "YlOrRd"}


@dataclass(frozen=True)
class ViewState:
    """One mesh the view can show: a frame in a basis, coloured by per-vertex values.

    Attributes
    ----------
    frame : str
        Label of the frame (take, frame number, time).
    basis : str
        ``captured`` or a basis label.
    displacement : ndarray of shape (3 * n_vertices,)
    values : ndarray of shape (n_vertices,)
        Colour values, mapped over ``clim`` with ``cmap``.
    cmap : str
        A colour scale name plotly knows (``YlGnBu``, ``YlOrRd``).
    clim : tuple of float
    colour_title : str
    """

    frame: str
    basis: str
    displacement: np.ndarray
    values: np.ndarray
    cmap: str
    clim: tuple[float, float]
    colour_title: str


def _packed(array: np.ndarray) -> str:
    return base64.b64encode(zlib.compress(np.ascontiguousarray(array).tobytes(), 9)).decode("ascii")


def byte_planes(values: np.ndarray) -> np.ndarray:
    """The bytes of little-endian int16 values as two planes, every low byte first, then every high byte."""
    return np.ascontiguousarray(values.view(np.uint8).reshape(-1, 2).T).ravel()


def view_payload(neutral: np.ndarray, faces: np.ndarray, states: Sequence[ViewState],
                 support: np.ndarray | None = None, title: str = "") -> dict:
    """The data of the interactive view, ready for JSON.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_vertices,)
    faces : ndarray of shape (n_faces, 3) of int
    states : sequence of ViewState
        Every frame in every basis, in the order the menus list them.
    support : ndarray of shape (n_vertices,) of bool, optional
        Triangles touching a vertex where it is False (extrapolated) are left out of the view.
    title : str

    Returns
    -------
    dict
        ``neutral`` (float32), ``faces`` (uint16 when the mesh has fewer than 65,536 vertices, else uint32; see
        ``faces_bytes``), per state ``displacement`` (int16 in units of ``step``, as
        :func:`byte_planes`; an offset from state ``base`` unless ``base`` is -1) and
        ``values`` (uint8 over ``clim``), each zlib-compressed and base64-encoded; ``loops``: the mesh's openings
        (eyes, mouth) closed by dark caps in the page.
    """
    from workbench.reporting.figures.render import hole_loops

    faces = np.asarray(faces)
    loops = hole_loops(faces)  # the mesh's own openings, not the edges of a masked region
    if support is not None:
        support = np.asarray(support)
        faces = faces[support[faces].all(axis=1)]
        loops = [loop for loop in loops if support[loop].all()]
    encoded, firsts = [], {}
    for state in states:
        # a reconstruction is stored as its offset from the frame's first state (the captured frame): small
        # numbers, which compress several times better than positions
        base = firsts.setdefault(state.frame, len(encoded))
        offset = np.asarray(state.displacement) - (states[base].displacement if base != len(encoded) else 0.0)
        low, high = state.clim
        levels = np.nan_to_num((np.asarray(state.values, dtype=float) - low) / max(high - low, 1e-12), nan=0.0)
        encoded.append({
            "frame": state.frame, "basis": state.basis, "cmap": COLOURSCALES[state.cmap], "clim": [low, high],
            "colour_title": state.colour_title,
            "base": base if base != len(encoded) else -1,
            "displacement": _packed(byte_planes(np.round(offset / STEP_MM).astype("<i2"))),
            "values": _packed(np.round(np.clip(levels, 0.0, 1.0) * 255).astype(np.uint8))})
    return {"title": title, "step": STEP_MM, "n_vertices": int(np.asarray(neutral).size // 3),
            "neutral": _packed(np.asarray(neutral, dtype="<f4")),
            "faces": _packed(faces.astype("<u2" if faces.max() < 2 ** 16 else "<u4")),
            "faces_bytes": 2 if faces.max() < 2 ** 16 else 4,
            "loops": [loop.tolist() for loop in loops], "states": encoded}


def write_view_data(path: Path, payload: dict) -> Path:
    """Write the view's data as a classic script (``window.WORKBENCH_VIEW = {...};``), loadable from file://."""
    write_atomic(path, "window.WORKBENCH_VIEW = " + json.dumps(payload, separators=(",", ":")) + ";\n")
    return path


def install_plotly(reports_root: Path) -> Path:
    """Copy the vendored plotly.js bundle to ``<reports_root>/vendor/`` unless the same file is there."""
    target = Path(reports_root) / "vendor" / PLOTLY_FILE
    data = PLOTLY_BUNDLE.read_bytes()
    if not target.is_file() or target.read_bytes() != data:
        write_atomic(target, data)
        write_atomic(target.parent / "plotly-LICENSE.txt", (PLOTLY_BUNDLE.parent / "plotly-LICENSE.txt").read_bytes())
    return target


VIEWER_SCRIPT = r"""
(function () {
  const view = window.WORKBENCH_VIEW, root = document.getElementById("view3d");
  const status = (text) => root.setAttribute("data-status", text);
  if (!view || !window.Plotly) { status("error: data or plotly.js missing"); return; }
  if (!window.DecompressionStream) { status("error: this browser lacks DecompressionStream"); return; }
  async function unpack(text, Type) {
    const bytes = Uint8Array.from(atob(text), (c) => c.charCodeAt(0));
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
    return new Type(await new Response(stream).arrayBuffer());
  }
  function planes(bytes) {  // low-byte plane, then high-byte plane -> int16
    const n = bytes.length / 2, out = new Int16Array(n);
    for (let v = 0; v < n; v++) out[v] = (bytes[n + v] << 8) | bytes[v];
    return out;
  }
  function positions(neutral, delta, step) {
    const n = neutral.length / 3, x = new Float32Array(n), y = new Float32Array(n), z = new Float32Array(n);
    for (let v = 0; v < n; v++) {
      x[v] = neutral[3 * v] + step * delta[3 * v];
      y[v] = neutral[3 * v + 1] + step * delta[3 * v + 1];
      z[v] = neutral[3 * v + 2] + step * delta[3 * v + 2];
    }
    return {x, y, z};
  }
  function caps(p) {  // a fan from each opening's centre, drawn dark: eyes and mouth are not holes
    const x = [], y = [], z = [], i = [], j = [], k = [];
    for (const loop of view.loops) {
      const base = x.length;
      let cx = 0, cy = 0, cz = 0;
      for (const v of loop) { x.push(p.x[v]); y.push(p.y[v]); z.push(p.z[v]); cx += p.x[v]; cy += p.y[v]; cz += p.z[v]; }
      x.push(cx / loop.length); y.push(cy / loop.length); z.push(cz / loop.length);
      for (let a = 0; a < loop.length; a++) { i.push(base + a); j.push(base + (a + 1) % loop.length); k.push(base + loop.length); }
    }
    return {x, y, z, i, j, k};
  }
  async function main() {
    const neutral = await unpack(view.neutral, Float32Array);
    const faces = await unpack(view.faces, view.faces_bytes === 2 ? Uint16Array : Uint32Array);
    const nf = faces.length / 3, fi = new Uint32Array(nf), fj = new Uint32Array(nf), fk = new Uint32Array(nf);
    for (let f = 0; f < nf; f++) { fi[f] = faces[3 * f]; fj[f] = faces[3 * f + 1]; fk[f] = faces[3 * f + 2]; }
    const frames = [...new Set(view.states.map((s) => s.frame))], bases = [...new Set(view.states.map((s) => s.basis))];
    const pickFrame = document.getElementById("view3d-frame"), pickBasis = document.getElementById("view3d-basis");
    frames.forEach((f) => pickFrame.add(new Option(f, f)));
    bases.forEach((b) => pickBasis.add(new Option(b, b)));
    async function traces(state) {
      const delta = planes(await unpack(state.displacement, Uint8Array));
      if (state.base >= 0) {
        const base = planes(await unpack(view.states[state.base].displacement, Uint8Array));
        for (let v = 0; v < delta.length; v++) delta[v] += base[v];
      }
      const p = positions(neutral, delta, view.step);
      const levels = await unpack(state.values, Uint8Array), [low, high] = state.clim;
      const intensity = Float32Array.from(levels, (l) => low + (high - low) * l / 255);
      const c = caps(p);
      return [
        {type: "mesh3d", x: p.x, y: p.y, z: p.z, i: fi, j: fj, k: fk, intensity: intensity,
         colorscale: state.cmap, reversescale: true, cmin: low, cmax: high, flatshading: false, hoverinfo: "skip",
         colorbar: {title: {text: state.colour_title, side: "right"}, len: 0.8},
         lighting: {ambient: 0.45, diffuse: 0.75, specular: 0.15, roughness: 0.6},
         lightposition: {x: 20000, y: 60000, z: 100000}},
        {type: "mesh3d", x: c.x, y: c.y, z: c.z, i: c.i, j: c.j, k: c.k, color: "#2a2020", hoverinfo: "skip",
         showscale: false}];
    }
    const axis = {visible: false};
    const layout = {margin: {l: 0, r: 0, t: 30, b: 0}, title: {text: view.title, font: {size: 13}},
      scene: {xaxis: axis, yaxis: axis, zaxis: axis, aspectmode: "data",
              camera: {eye: {x: 0, y: 0.25, z: 1.9}, up: {x: 0, y: 1, z: 0}}}};
    async function show() {
      const state = view.states.find((s) => s.frame === pickFrame.value && s.basis === pickBasis.value);
      const camera = root.layout && root.layout.scene && root.layout.scene.camera;
      await Plotly.react(root, await traces(state), camera ? {...layout, scene: {...layout.scene, camera}} : layout,
                         {displaylogo: false, responsive: true});
    }
    // a link can open a given view: index.html#frame=2&shown=QE (frame: 1, 2, 3 in the menu's order)
    const asked = new URLSearchParams(location.hash.slice(1));
    if (asked.get("frame")) pickFrame.selectedIndex = Math.min(Number(asked.get("frame")), frames.length) - 1;
    if (bases.includes(asked.get("shown"))) pickBasis.value = asked.get("shown");
    pickFrame.onchange = show; pickBasis.onchange = show;
    await show();
    // Self-check (read by the test and shown to nobody): render the scene to an image and count the pixels that
    // are not background.
    const url = await Plotly.toImage(root, {format: "png", width: 400, height: 400});
    const image = new Image();
    image.onload = () => {
      const canvas = document.createElement("canvas");
      canvas.width = image.width; canvas.height = image.height;
      const context = canvas.getContext("2d");
      context.drawImage(image, 0, 0);
      const pixels = context.getImageData(0, 0, canvas.width, canvas.height).data;
      let drawn = 0;
      for (let p = 0; p < pixels.length; p += 4) if (pixels[p] < 235 || pixels[p + 1] < 235 || pixels[p + 2] < 235) drawn++;
      status("drawn " + drawn + " of " + (pixels.length / 4));
    };
    image.src = url;
  }
  main().catch((error) => status("error: " + error));
})();
"""


def viewer_html(plotly_src: str, data_src: str, caption: str) -> str:
    """The HTML of the interactive view: menus for frame and basis, the WebGL view and the scripts it loads.

    Parameters
    ----------
    plotly_src, data_src : str
        Relative URLs of the plotly.js bundle and of the view's data script.
    caption : str
        HTML text under the view.
    """
    return (f"<figure id=\"view3d-figure\"><div class=\"view3d-controls\"><label>frame <select id=\"view3d-frame\">"
            "</select></label> <label>shown <select id=\"view3d-basis\"></select></label> <span class=\"hint\">drag "
            "to turn, scroll to zoom</span></div><div id=\"view3d\" data-status=\"loading\" "
            "style=\"width:100%;max-width:900px;height:640px\"></div>"
            f"<figcaption>{caption}</figcaption></figure>\n"
            f"<script src=\"{plotly_src}\"></script>\n<script src=\"{data_src}\"></script>\n"
            f"<script>{VIEWER_SCRIPT}</script>")


def write_animation(path: Path, panels: Sequence[Sequence[np.ndarray]], titles: Sequence[str], captions: Sequence[str],
                    *, fps: float = 10.0) -> Path:
    """A looping GIF of several panels side by side, one image per time step.

    Parameters
    ----------
    path : pathlib.Path
    panels : sequence of sequence of ndarray of shape (height, width, 3) of uint8
        ``panels[p][t]``: panel p at time step t; all the same size.
    titles : sequence of str
        One per panel, written above it.
    captions : sequence of str
        One per time step (frame and time), written under the panels.
    fps : float
        Time steps per second of the animation.
    """
    import io

    from PIL import Image, ImageDraw

    height, width = panels[0][0].shape[:2]
    band = 22
    images = []
    for t, caption in enumerate(captions):
        canvas = Image.new("RGB", (width * len(panels), height + 2 * band), "white")
        draw = ImageDraw.Draw(canvas)
        for p, title in enumerate(titles):
            canvas.paste(Image.fromarray(panels[p][t]), (p * width, band))
            draw.text((p * width + 8, 4), title, fill="black")
        draw.text((8, height + band + 4), caption, fill="black")
        images.append(canvas.quantize(colors=128, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE))
    buffer = io.BytesIO()
    images[0].save(buffer, format="gif", save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0,
                   optimize=True)
    write_atomic(path, buffer.getvalue())
    return path
