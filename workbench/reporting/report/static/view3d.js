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
