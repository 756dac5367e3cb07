"""Faces you can turn: a self-contained interactive 3-D view of captured and reconstructed frames for the HTML
report, and a short animation of captured | H | QE over a stretch of the take.

The view is a small WebGL viewer written here (no library): the captured frame and its reconstruction side by side
under one camera (drag to turn both, scroll to zoom), a frame and a basis picked from menus, plain shaded or
coloured by displacement and error with colour bars. Everything it needs is in the report folder: the viewer's
script inline in ``index.html`` and the mesh data in ``figures/view3d.js``, a classic script, so the page works
from ``file://`` after the folder is copied anywhere, with no network. The data: vertex displacements quantised
to 0.05 mm (invisible at face scale), a reconstruction stored as its offset from the captured frame, their bytes
split into planes (low bytes, then high bytes: the high ones are mostly equal and compress well), zlib-compressed
and decoded in the browser by ``DecompressionStream``; colours are computed in the page from the displacements.
"""

from __future__ import annotations

import base64
import json
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from workbench.files import write_atomic

DATA_FILE = "view3d.js"
STEP_MM = 0.05  # quantisation of the displacements in the page
COLOUR_LEVELS = 64  # entries of each colour map sent to the page


@dataclass(frozen=True)
class ViewFrame:
    """One frame the view can show: captured, and reconstructed with each basis.

    Attributes
    ----------
    label : str
        Why it is shown, take, frame number and time.
    captured : ndarray of shape (3 * n_vertices,)
        Captured displacement.
    reconstructed : mapping
        Basis label -> ndarray of shape (3 * n_vertices,), the reconstructed displacement.
    notes : mapping
        Basis label -> text shown with the reconstruction (its alpha on this frame).
    """

    label: str
    captured: np.ndarray
    reconstructed: Mapping[str, np.ndarray]
    notes: Mapping[str, str]


def _packed(array: np.ndarray) -> str:
    return base64.b64encode(zlib.compress(np.ascontiguousarray(array).tobytes(), 9)).decode("ascii")


def byte_planes(values: np.ndarray) -> np.ndarray:
    """The bytes of little-endian int16 values as two planes, every low byte first, then every high byte."""
    return np.ascontiguousarray(values.view(np.uint8).reshape(-1, 2).T).ravel()


def _quantised(displacement: np.ndarray) -> str:
    return _packed(byte_planes(np.round(np.asarray(displacement) / STEP_MM).astype("<i2")))


def colour_table(cmap: str, levels: int = COLOUR_LEVELS) -> str:
    """A matplotlib colour map sampled at ``levels`` points, as hex RGB (6 characters each), for the page."""
    from matplotlib import colormaps

    rgb = np.round(255 * colormaps[cmap](np.linspace(0.0, 1.0, levels))[:, :3]).astype(int)
    return "".join(f"{r:02x}{g:02x}{b:02x}" for r, g, b in rgb)


def view_payload(neutral: np.ndarray, faces: np.ndarray, frames: Sequence[ViewFrame], *, bases: Mapping[str, str],
                 displacement_range: tuple[float, float, bool], error_range: tuple[float, float, bool],
                 cmaps: tuple[str, str], weight: np.ndarray | None = None, title: str = "",
                 plain_colour: str = "#cfc6be") -> dict:
    """The data of the interactive view, ready for JSON.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_vertices,)
    faces : ndarray of shape (n_faces, 3) of int
    frames : sequence of ViewFrame
        In the order the menu lists them.
    bases : mapping
        Basis label -> its name in the page (e.g. ``QE`` -> ``quasi-eigen E^QE (affine)``), in the menu's order;
        every frame has a reconstruction for each.
    displacement_range, error_range : (float, float, bool)
        Colour range of the captured displacement length and of the reconstruction error, and whether the data go
        beyond it (the colour bar then shows an arrow).
    cmaps : (str, str)
        Matplotlib colour maps of the displacement and of the error.
    weight : ndarray of shape (n_vertices,) in [0, 1], optional
        Share of colour at each vertex: 0 where the capture has no data (shown plain, as geometry).
    title : str
    plain_colour : str
        The plain shade.

    Returns
    -------
    dict
        ``neutral`` (float32), ``faces`` (uint16 below 65,536 vertices, else uint32; see ``faces_bytes``),
        ``weight`` (uint8 or null), per frame ``captured`` and per basis its offset from the captured frame (int16
        in units of ``step``, as :func:`byte_planes`), each zlib-compressed and base64-encoded; ``loops``: the
        mesh's openings (eyes, mouth), closed by dark caps in the page.
    """
    from workbench.reporting.figures.render import hole_loops

    faces = np.asarray(faces)
    wide = faces.max() >= 2 ** 16
    return {
        "title": title, "step": STEP_MM, "n_vertices": int(np.asarray(neutral).size // 3),
        "neutral": _packed(np.asarray(neutral, dtype="<f4")),
        "faces": _packed(faces.astype("<u4" if wide else "<u2")), "faces_bytes": 4 if wide else 2,
        "loops": [loop.tolist() for loop in hole_loops(faces)],
        "weight": None if weight is None else _packed(np.round(255 * np.clip(weight, 0, 1)).astype(np.uint8)),
        "bases": [{"key": key, "name": name} for key, name in bases.items()],
        "frames": [{"label": frame.label, "captured": _quantised(frame.captured),
                    "shown": {key: _quantised(np.asarray(frame.reconstructed[key]) - frame.captured) for key in bases},
                    "notes": {key: frame.notes.get(key, "") for key in bases}} for frame in frames],
        "displacement": {"clim": list(displacement_range[:2]), "beyond": bool(displacement_range[2]),
                         "colours": colour_table(cmaps[0])},
        "error": {"clim": list(error_range[:2]), "beyond": bool(error_range[2]), "colours": colour_table(cmaps[1])},
        "plain": plain_colour,
    }


def write_view_data(path: Path, payload: dict) -> Path:
    """Write the view's data as a classic script (``window.WORKBENCH_VIEW = {...};``), loadable from file://."""
    write_atomic(path, "window.WORKBENCH_VIEW = " + json.dumps(payload, separators=(",", ":")) + ";\n")
    return path


VIEWER_SCRIPT = r"""
(function () {
  "use strict";
  const view = window.WORKBENCH_VIEW, root = document.getElementById("view3d");
  const canvas = document.getElementById("view3d-canvas");
  const status = (text) => root.setAttribute("data-status", text);
  if (!view) { status("error: the view's data (figures/view3d.js) did not load"); return; }
  if (!window.DecompressionStream) { status("error: this browser lacks DecompressionStream"); return; }
  const gl = canvas.getContext("webgl", {antialias: true, preserveDrawingBuffer: true});
  if (!gl) { status("error: this browser has no WebGL"); return; }
  const wideIndex = gl.getExtension("OES_element_index_uint");

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
  const hex = (text, k) => [0, 2, 4].map((o) => parseInt(text.substr(6 * k + o, 2), 16) / 255);
  function table(text) { const n = text.length / 6, out = []; for (let k = 0; k < n; k++) out.push(hex(text, k)); return out; }
  const plain = [1, 3, 5].map((o) => parseInt(view.plain.substr(o, 2), 16) / 255);
  const CAP = [0.16, 0.12, 0.12];

  const VERTEX = `attribute vec3 position; attribute vec3 normal; attribute vec3 colour;
    uniform mat4 projection, modelview; varying vec3 n, c, eye;
    void main() { vec4 p = modelview * vec4(position, 1.0); eye = -p.xyz; n = (modelview * vec4(normal, 0.0)).xyz; c = colour;
                  gl_Position = projection * p; }`;
  const FRAGMENT = `precision mediump float; varying vec3 n, c, eye;
    void main() { vec3 N = normalize(n); if (dot(N, eye) < 0.0) N = -N;
      vec3 L = normalize(vec3(-0.35, 0.55, 1.0)), V = normalize(eye), H = normalize(L + V);
      float diffuse = max(dot(N, L), 0.0), fill = 0.22 * max(dot(N, normalize(vec3(0.6, -0.2, 0.8))), 0.0);
      float specular = 0.06 * pow(max(dot(N, H), 0.0), 30.0);
      gl_FragColor = vec4(c * (0.16 + 0.66 * diffuse + fill) + vec3(specular), 1.0); }`;
  function shader(type, text) {
    const s = gl.createShader(type); gl.shaderSource(s, text); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  const program = gl.createProgram();
  gl.attachShader(program, shader(gl.VERTEX_SHADER, VERTEX));
  gl.attachShader(program, shader(gl.FRAGMENT_SHADER, FRAGMENT));
  gl.linkProgram(program);
  gl.useProgram(program);
  const where = {position: gl.getAttribLocation(program, "position"), normal: gl.getAttribLocation(program, "normal"),
                 colour: gl.getAttribLocation(program, "colour"),
                 projection: gl.getUniformLocation(program, "projection"),
                 modelview: gl.getUniformLocation(program, "modelview")};

  function multiply(a, b) {  // column-major 4x4
    const out = new Float32Array(16);
    for (let i = 0; i < 4; i++) for (let j = 0; j < 4; j++) {
      let sum = 0; for (let k = 0; k < 4; k++) sum += a[k * 4 + j] * b[i * 4 + k]; out[i * 4 + j] = sum;
    }
    return out;
  }
  const translation = (x, y, z) => new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, y, z, 1]);
  function rotationX(a) { const c = Math.cos(a), s = Math.sin(a); return new Float32Array([1, 0, 0, 0, 0, c, s, 0, 0, -s, c, 0, 0, 0, 0, 1]); }
  function rotationY(a) { const c = Math.cos(a), s = Math.sin(a); return new Float32Array([c, 0, -s, 0, 0, 1, 0, 0, s, 0, c, 0, 0, 0, 0, 1]); }
  function perspective(fov, aspect, near, far) {
    const f = 1 / Math.tan(fov / 2), d = near - far;
    return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) / d, -1, 0, 0, 2 * far * near / d, 0]);
  }

  async function main() {
    const neutral = await unpack(view.neutral, Float32Array);
    const faces = await unpack(view.faces, view.faces_bytes === 2 ? Uint16Array : Uint32Array);
    const weight = view.weight ? await unpack(view.weight, Uint8Array) : null;
    const n = view.n_vertices, loops = view.loops, total = n + loops.length;
    if (total >= 65536 && !wideIndex) throw new Error("this browser cannot index a mesh this large");
    let capCount = 0; for (const loop of loops) capCount += loop.length;
    const IndexType = total >= 65536 ? Uint32Array : Uint16Array;
    const index = new IndexType(faces.length + 3 * capCount);
    index.set(faces);
    let at = faces.length;
    loops.forEach((loop, k) => { for (let a = 0; a < loop.length; a++) { index[at++] = loop[a]; index[at++] = loop[(a + 1) % loop.length]; index[at++] = n + k; } });
    const indexBuffer = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, indexBuffer);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, index, gl.STATIC_DRAW);
    const buffers = {position: gl.createBuffer(), normal: gl.createBuffer(), colour: gl.createBuffer()};
    let centre = [0, 0, 0], size = 1;
    {
      const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
      for (let v = 0; v < n; v++) for (let a = 0; a < 3; a++) { lo[a] = Math.min(lo[a], neutral[3 * v + a]); hi[a] = Math.max(hi[a], neutral[3 * v + a]); }
      centre = [0, 1, 2].map((a) => (lo[a] + hi[a]) / 2); size = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    }

    function geometry(delta) {  // positions (mesh + cap centres) and area-weighted normals
      const p = new Float32Array(3 * total), normal = new Float32Array(3 * total);
      for (let v = 0; v < 3 * n; v++) p[v] = neutral[v] + view.step * delta[v];
      loops.forEach((loop, k) => {
        for (let a = 0; a < 3; a++) { let sum = 0; for (const v of loop) sum += p[3 * v + a]; p[3 * (n + k) + a] = sum / loop.length; }
      });
      for (let f = 0; f < index.length; f += 3) {
        const i = 3 * index[f], j = 3 * index[f + 1], k = 3 * index[f + 2];
        const ux = p[j] - p[i], uy = p[j + 1] - p[i + 1], uz = p[j + 2] - p[i + 2];
        const vx = p[k] - p[i], vy = p[k + 1] - p[i + 1], vz = p[k + 2] - p[i + 2];
        const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
        for (const o of [i, j, k]) { normal[o] += nx; normal[o + 1] += ny; normal[o + 2] += nz; }
      }
      return {p, normal};
    }
    function colours(values, scale) {  // colour map blended into the plain shade by the support weight
      const out = new Float32Array(3 * total), [low, high] = scale.clim, map = table(scale.colours);
      for (let v = 0; v < total; v++) {
        let rgb = v < n ? plain : CAP;
        if (v < n && values) {
          const t = Math.min(Math.max((values[v] - low) / (high - low), 0), 1), c = map[Math.round(t * (map.length - 1))];
          const w = weight ? weight[v] / 255 : 1;
          rgb = [0, 1, 2].map((a) => w * c[a] + (1 - w) * plain[a]);
        }
        out.set(rgb, 3 * v);
      }
      return out;
    }
    function lengths(delta, base) {  // per-vertex length of delta (minus base) in mm
      const out = new Float32Array(n);
      for (let v = 0; v < n; v++) {
        let sum = 0;
        for (let a = 0; a < 3; a++) { const d = view.step * (delta[3 * v + a] - (base ? base[3 * v + a] : 0)); sum += d * d; }
        out[v] = Math.sqrt(sum);
      }
      return out;
    }

    const pickFrame = document.getElementById("view3d-frame"), pickBasis = document.getElementById("view3d-basis");
    const pickColour = document.getElementById("view3d-colour");
    view.frames.forEach((f, k) => pickFrame.add(new Option(f.label, String(k))));
    view.bases.forEach((b) => pickBasis.add(new Option(b.name, b.key)));
    const asked = new URLSearchParams(location.hash.slice(1));  // index.html#frame=2&shown=QE&colour=plain
    if (asked.get("frame")) pickFrame.value = String(Math.min(Math.max(Number(asked.get("frame")), 1), view.frames.length) - 1);
    if (view.bases.some((b) => b.key === asked.get("shown"))) pickBasis.value = asked.get("shown");
    if (asked.get("colour")) pickColour.value = asked.get("colour");

    let scene = null;
    const camera = {yaw: 0, pitch: 0.12, distance: 2.3};
    async function load() {
      const frame = view.frames[Number(pickFrame.value)], key = pickBasis.value, coloured = pickColour.value !== "plain";
      const captured = planes(await unpack(frame.captured, Uint8Array));
      const offset = planes(await unpack(frame.shown[key], Uint8Array));
      const shown = Int16Array.from(captured, (c, v) => c + offset[v]);
      const left = geometry(captured), right = geometry(shown);
      scene = [
        {...left, colour: colours(coloured ? lengths(captured) : null, view.displacement)},
        {...right, colour: colours(coloured ? lengths(shown, captured) : null, view.error)}];
      const basis = view.bases.find((b) => b.key === key);
      document.getElementById("view3d-left").textContent = "captured: " + frame.label;
      document.getElementById("view3d-right").textContent = "reconstructed with " + basis.name + (frame.notes[key] ? ": " + frame.notes[key] : "");
      bar("view3d-bar-left", coloured ? view.displacement : null, "captured displacement |d*| (mm)");
      bar("view3d-bar-right", coloured ? view.error : null, "reconstruction error |d - d*| (mm)");
      draw();
    }
    function bar(id, scale, label) {  // a colour bar with its range; an arrow when the data go beyond it
      const element = document.getElementById(id);
      if (!scale) { element.innerHTML = "<span class=\"hint\">plain shaded: the geometry alone</span>"; return; }
      const map = table(scale.colours), stops = map.map((c, k) => `rgb(${c.map((x) => Math.round(255 * x)).join(",")}) ${(100 * k / (map.length - 1)).toFixed(1)}%`);
      const [low, high] = scale.clim, digits = high < 1 ? 2 : high < 10 ? 1 : 0;
      element.innerHTML = `<span>${low.toFixed(digits)}</span><span class="ramp" style="background:linear-gradient(to right,${stops.join(",")})"></span>`
        + `<span>${high.toFixed(digits)}${scale.beyond ? " &#9654; beyond" : ""}</span><span class="hint">${label}</span>`;
    }
    function draw() {
      const width = canvas.clientWidth, height = canvas.clientHeight, ratio = window.devicePixelRatio || 1;
      if (canvas.width !== Math.round(width * ratio) || canvas.height !== Math.round(height * ratio)) {
        canvas.width = Math.round(width * ratio); canvas.height = Math.round(height * ratio);
      }
      gl.enable(gl.DEPTH_TEST); gl.enable(gl.SCISSOR_TEST);
      gl.clearColor(1, 1, 1, 1);
      const half = Math.floor(canvas.width / 2);
      const projection = perspective(0.5, half / canvas.height, 0.05 * size, 20 * size);
      const modelview = multiply(translation(0, 0, -camera.distance * size),
                                 multiply(rotationX(camera.pitch), multiply(rotationY(camera.yaw), translation(-centre[0], -centre[1], -centre[2]))));
      scene.forEach((mesh, k) => {
        gl.viewport(k * half, 0, half, canvas.height); gl.scissor(k * half, 0, half, canvas.height);
        gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
        for (const [name, data] of [["position", mesh.p], ["normal", mesh.normal], ["colour", mesh.colour]]) {
          gl.bindBuffer(gl.ARRAY_BUFFER, buffers[name]); gl.bufferData(gl.ARRAY_BUFFER, data, gl.DYNAMIC_DRAW);
          gl.enableVertexAttribArray(where[name]); gl.vertexAttribPointer(where[name], 3, gl.FLOAT, false, 0, 0);
        }
        gl.uniformMatrix4fv(where.projection, false, projection); gl.uniformMatrix4fv(where.modelview, false, modelview);
        gl.drawElements(gl.TRIANGLES, index.length, IndexType === Uint32Array ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT, 0);
      });
    }
    let dragging = null;
    canvas.addEventListener("pointerdown", (e) => { dragging = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
    canvas.addEventListener("pointerup", () => { dragging = null; });
    canvas.addEventListener("pointermove", (e) => {
      if (!dragging) return;
      camera.yaw += 0.01 * (e.clientX - dragging[0]);
      camera.pitch = Math.max(-1.4, Math.min(1.4, camera.pitch + 0.01 * (e.clientY - dragging[1])));
      dragging = [e.clientX, e.clientY]; draw();
    });
    canvas.addEventListener("wheel", (e) => { e.preventDefault(); camera.distance = Math.max(0.6, Math.min(8, camera.distance * Math.exp(0.001 * e.deltaY))); draw(); }, {passive: false});
    canvas.addEventListener("dblclick", () => { Object.assign(camera, {yaw: 0, pitch: 0.12, distance: 2.3}); draw(); });
    window.addEventListener("resize", () => scene && draw());
    pickFrame.onchange = load; pickBasis.onchange = load; pickColour.onchange = load;
    await load();
    // Self-check (read by the tests, shown to nobody): the pixels of each half that are not background.
    const pixels = new Uint8Array(4 * canvas.width * canvas.height);
    gl.readPixels(0, 0, canvas.width, canvas.height, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
    const half = Math.floor(canvas.width / 2), drawn = [0, 0];
    for (let p = 0; p < pixels.length; p += 4) {
      if (pixels[p] < 235 || pixels[p + 1] < 235 || pixels[p + 2] < 235) drawn[((p / 4) % canvas.width) < half ? 0 : 1]++;
    }
    status(`drawn ${drawn[0]} and ${drawn[1]} of ${half * canvas.height} pixels per half`);
  }
  main().catch((error) => status("error: " + error.message));
})();
"""

VIEWER_STYLE = """
#view3d-figure { max-width: 1100px; }
.view3d-controls { margin: .4em 0; } .view3d-controls select { margin: 0 .8em 0 .3em; max-width: 30em; }
.view3d-controls .hint, .view3d-bar .hint { color: #666; font-size: .9em; }
.view3d-panels { display: flex; } .view3d-panels > div { flex: 1; font-size: .9em; padding: 0 .4em; min-height: 2.6em; }
#view3d-canvas { width: 100%; height: 560px; display: block; touch-action: none; cursor: grab; }
.view3d-bar { display: flex; align-items: center; gap: .4em; font-size: .85em; flex-wrap: wrap; }
.view3d-bar .ramp { display: inline-block; width: 180px; height: 12px; border: 1px solid #aaa; }
"""


def viewer_html(data_src: str, caption: str) -> str:
    """The HTML of the interactive view: menus (frame, basis, colouring), the two panels under one camera, colour
    bars, the data script and the viewer's script inline.

    Parameters
    ----------
    data_src : str
        Relative URL of the view's data script, inside the report folder.
    caption : str
        HTML text under the view.
    """
    return (f"<style>{VIEWER_STYLE}</style>"
            "<figure id=\"view3d-figure\"><div class=\"view3d-controls\"><label>frame <select id=\"view3d-frame\">"
            "</select></label> <label>reconstructed with <select id=\"view3d-basis\"></select></label> <label>shown "
            "<select id=\"view3d-colour\"><option value=\"colour\">coloured by displacement and error</option>"
            "<option value=\"plain\">plain shaded</option></select></label> <span class=\"hint\">drag to turn, scroll "
            "to zoom, double-click to reset</span></div>"
            "<div id=\"view3d\" data-status=\"loading\"><div class=\"view3d-panels\"><div id=\"view3d-left\"></div>"
            "<div id=\"view3d-right\"></div></div><canvas id=\"view3d-canvas\"></canvas>"
            "<div class=\"view3d-panels\"><div id=\"view3d-bar-left\" class=\"view3d-bar\"></div>"
            "<div id=\"view3d-bar-right\" class=\"view3d-bar\"></div></div></div>"
            f"<figcaption>{caption}</figcaption></figure>\n"
            f"<script src=\"{data_src}\"></script>\n<script>{VIEWER_SCRIPT}</script>")


ANIMATION_WIDTH = 960
"""Smallest width of the animation in pixels: its labels stay readable when a page shows it at full size."""


def colour_bar_strip(width: int, cmap: str, clim: tuple[float, float], extend: str, label: str) -> np.ndarray:
    """A horizontal colour bar with ticks and label as an RGB image ``width`` pixels wide."""
    import io

    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from PIL import Image

    figure = Figure(figsize=(width / 100, 0.82), dpi=100)
    ax = figure.add_axes((0.06, 0.62, 0.86, 0.3))
    bar = figure.colorbar(ScalarMappable(Normalize(*clim), cmap), cax=ax, orientation="horizontal", extend=extend)
    bar.ax.tick_params(labelsize=12)
    bar.set_label(label, fontsize=13)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    return np.asarray(Image.open(buffer).convert("RGB"))


def write_animation(path: Path, panels: Sequence[Sequence[np.ndarray]], titles: Sequence[str], captions: Sequence[str],
                    *, fps: float, speed: str, colour: tuple[str, tuple[float, float], str, str] | None = None,
                    quality: int = 45) -> Path:
    """A looping animated WebP of several panels side by side, one image per time step, with each panel's title, the
    frame shown, the playback speed and a colour bar under the coloured panels, at least
    :data:`ANIMATION_WIDTH` pixels wide in type a reader can read.

    Parameters
    ----------
    path : pathlib.Path
    panels : sequence of sequence of ndarray of shape (height, width, 3) of uint8
        ``panels[p][t]``: panel p at time step t; all the same size. Panels after the first are the coloured ones.
    titles : sequence of str
        One per panel, written above it.
    captions : sequence of str
        One per time step (take, frame and time), written under the first panel.
    fps : float
        Time steps per second of the animation.
    speed : str
        The playback speed in words (``real time: 15 frames per second``), written under the caption.
    colour : (cmap, (low, high), extend, label), optional
        The colour bar under the coloured panels.
    quality : int
        WebP quality (lossy: full colour, no palette).
    """
    import io

    from matplotlib import font_manager
    from PIL import Image, ImageDraw, ImageFont

    height, width = panels[0][0].shape[:2]
    gap = max(16, (ANIMATION_WIDTH - len(panels) * width) // (len(panels) + 1))
    canvas_width = max(ANIMATION_WIDTH, len(panels) * width + (len(panels) + 1) * gap)
    title_band, bottom_band = 40, 96
    font_file = font_manager.findfont("DejaVu Sans")
    title_font, text_font = ImageFont.truetype(font_file, 21), ImageFont.truetype(font_file, 16)
    base = Image.new("RGB", (canvas_width, title_band + height + bottom_band), "white")
    draw = ImageDraw.Draw(base)
    for p, title in enumerate(titles):
        centre = gap + p * (width + gap) + width // 2
        draw.text((centre, title_band // 2 + 4), title, fill="black", font=title_font, anchor="mm")
    if colour is not None and len(panels) > 1:
        cmap, clim, extend, label = colour
        left = 2 * gap + width
        strip = colour_bar_strip(canvas_width - left - gap // 2, cmap, clim, extend, label)
        base.paste(Image.fromarray(strip), (left, title_band + height + 4))
    frames = []
    for t, caption in enumerate(captions):
        frame = base.copy()
        for p, images in enumerate(panels):
            frame.paste(Image.fromarray(images[t]), (gap + p * (width + gap), title_band))
        draw = ImageDraw.Draw(frame)
        draw.text((gap, title_band + height + 14), caption, fill="black", font=text_font)
        draw.text((gap, title_band + height + 44), speed, fill="#333333", font=text_font)
        frames.append(frame)
    buffer = io.BytesIO()
    # every frame a key frame: a lossy frame that updates only part of the last one leaves block seams on the face
    frames[0].save(buffer, format="webp", save_all=True, append_images=frames[1:], duration=round(1000 / fps), loop=0,
                   quality=quality, method=4, kmin=1, kmax=1)
    write_atomic(path, buffer.getvalue())
    return path
