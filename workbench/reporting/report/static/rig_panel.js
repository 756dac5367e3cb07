(function () {
  "use strict";
  const data = window.WORKBENCH_RIGS, root = document.getElementById("rigs");
  const status = (text) => root.setAttribute("data-status", text);
  if (!data) { status("error: the rigs' data (figures/rigs.js) did not load"); return; }
  if (!window.THREE || !THREE.GLTFLoader) { status("error: three.js (figures/three.min.js) did not load"); return; }
  if (!window.DecompressionStream) { status("error: this browser lacks DecompressionStream"); return; }
  const $ = (id) => document.getElementById(id);
  const n = data.shapes.length;
  const solver = () => $("rigs-solver").value;

  async function inflate(text) {
    const bytes = Uint8Array.from(atob(text), (c) => c.charCodeAt(0));
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
    return new Response(stream).arrayBuffer();
  }
  function planes(buffer) {  // low-byte plane, then high-byte plane -> int16
    const bytes = new Uint8Array(buffer), count = bytes.length / 2, out = new Int16Array(count);
    for (let v = 0; v < count; v++) out[v] = (bytes[count + v] << 8) | bytes[v];
    return out;
  }
  const colours = [];
  for (let k = 0; k < data.difference.colours.length / 6; k++) {
    colours.push([0, 2, 4].map((o) => parseInt(data.difference.colours.substr(6 * k + o, 2), 16) / 255));
  }
  const plain = [1, 3, 5].map((o) => parseInt(data.plain.substr(o, 2), 16) / 255);

  // A rig: the glTF scene's morph mesh, its targets' shapes and scales, and its animations' keys (one per take).
  async function loadRig(spec) {
    const gltf = await new THREE.GLTFLoader().parseAsync(await inflate(spec.glb), "");
    let mesh = null;
    gltf.scene.traverse((object) => { if (!mesh && object.isMesh && object.morphTargetInfluences) mesh = object; });
    if (!mesh) throw new Error(spec.key + ": the rig has no mesh with morph targets");
    // one morph target per shape (the rig as write_rig writes it without frames); its index in the mesh
    const targets = spec.targets.map((name) => ({shape: data.shapes.indexOf(name), index: mesh.morphTargetDictionary[name]}));
    if (targets.some((t) => t.index === undefined)) throw new Error(spec.key + ": a shape has no morph target");
    const geometry = mesh.geometry;
    geometry.setAttribute("color", new THREE.BufferAttribute(new Float32Array(geometry.attributes.position.count * 3).fill(1), 3));
    mesh.material = new THREE.MeshStandardMaterial({vertexColors: true, flatShading: true, roughness: 0.75,
                                                    metalness: 0.0, side: THREE.DoubleSide});
    mesh.frustumCulled = false;
    return {spec, mesh, targets, scene: gltf.scene};
  }

  // Slider values -> morph target influences, a shape's raw weight on its target (three.js does not clamp
  // influences); the timeline sets every target, appended eigenfaces too, to the weights the run's solver found.
  function pose(rig, values) {
    const influences = rig.mesh.morphTargetInfluences;
    influences.fill(0);
    rig.targets.forEach((t) => { if (t.shape >= 0) influences[t.index] = values[t.shape]; });
  }
  function playKey(rig, key) {
    const influences = rig.mesh.morphTargetInfluences, weights = rig.spec.weights[solver()][key];
    rig.targets.forEach((t, i) => { influences[t.index] = weights[i]; });
  }
  function rawWeights(rig) {  // each hand shape's weight, as the sliders and the weights CSV give it
    const out = new Array(n).fill(0);
    rig.targets.forEach((t) => { if (t.shape >= 0) out[t.shape] = rig.mesh.morphTargetInfluences[t.index]; });
    return out;
  }
  function positions(rig) {  // neutral + sum of influence x target, as three.js morphs them, in mm
    const geometry = rig.mesh.geometry, base = geometry.attributes.position.array;
    const out = Float64Array.from(base);
    const morphs = geometry.morphAttributes.position, influences = rig.mesh.morphTargetInfluences;
    for (let k = 0; k < morphs.length; k++) {
      const w = influences[k];
      if (w === 0) continue;
      const delta = morphs[k].array;
      for (let i = 0; i < out.length; i++) out[i] += w * delta[i];
    }
    for (let i = 0; i < out.length; i++) out[i] *= 1000;
    return out;
  }

  async function start() {
    const rigs = [];
    for (const spec of data.rigs) rigs.push(await loadRig(spec));
    const captured = planes(await inflate(data.captured));
    const nv = data.n_vertices;
    const h = rigs[0];
    let qe = rigs[1];
    // the captured face: the H rig's neutral mesh with the captured displacement of the timeline's frame
    const capturedGeometry = new THREE.BufferGeometry();
    const neutral = h.mesh.geometry.attributes.position.array;
    capturedGeometry.setAttribute("position", new THREE.BufferAttribute(Float32Array.from(neutral), 3));
    capturedGeometry.setIndex(h.mesh.geometry.index);
    const capturedMesh = new THREE.Mesh(capturedGeometry, new THREE.MeshStandardMaterial({
      color: new THREE.Color(plain[0], plain[1], plain[2]), flatShading: true, roughness: 0.75, side: THREE.DoubleSide}));
    const capturedScene = new THREE.Scene();
    capturedScene.add(capturedMesh);

    const canvas = $("rigs-canvas");
    const renderer = new THREE.WebGLRenderer({canvas, antialias: true, preserveDrawingBuffer: true});
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    renderer.setClearColor(0xffffff, 1);
    const box = new THREE.Box3().setFromBufferAttribute(h.mesh.geometry.attributes.position);
    const centre = box.getCenter(new THREE.Vector3()), size = box.getSize(new THREE.Vector3());
    const camera = new THREE.PerspectiveCamera(24, 1, size.length() / 100, size.length() * 20);
    const distance = 1.25 * Math.max(size.x, size.y) / (2 * Math.tan(12 * Math.PI / 180));
    camera.position.set(centre.x, centre.y, centre.z + distance);
    const controls = new THREE.OrbitControls(camera, canvas);
    controls.target.copy(centre);
    controls.update();
    for (const scene of [capturedScene, ...rigs.map((r) => r.scene)]) {
      scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 1.4));
      const light = new THREE.DirectionalLight(0xffffff, 1.6);
      light.position.set(centre.x - 0.35 * distance, centre.y + 0.55 * distance, centre.z + distance);
      light.target.position.copy(centre);
      scene.add(light, light.target);
    }

    const values = new Array(n).fill(0);
    let key = -1, selected = 0, raw = false;
    const sliders = [];
    const range = (i) => raw ? data.ranges[i] : [0, 1];
    data.shapes.forEach((name, i) => {
      const row = document.createElement("div");
      row.className = "rigs-shape";
      row.innerHTML = `<label for="rigs-s${i}">${name}</label><input type="range" id="rigs-s${i}" step="any">` +
        `<span class="value"></span><span><button type="button">solo</button> <span class="both"></span></span>`;
      $("rigs-sliders").appendChild(row);
      const input = row.querySelector("input");
      input.addEventListener("input", () => { setSlider(i, parseFloat(input.value)); });
      row.querySelector("button").addEventListener("click", () => solo(i));
      sliders.push({input, value: row.querySelector(".value"), both: row.querySelector(".both")});
    });
    function showSliders(hValues, qeValues) {
      sliders.forEach((s, i) => {
        const [low, high] = range(i);
        s.input.min = low; s.input.max = high;
        s.input.value = Math.min(high, Math.max(low, key < 0 ? values[i] : qeValues[i]));
        s.value.textContent = key < 0 ? values[i].toFixed(2) : "";
        s.both.textContent = key < 0 ? "" : `H ${hValues[i].toFixed(2)}, QE ${qeValues[i].toFixed(2)}`;
      });
    }
    function colour() {
      const on = $("rigs-colour").checked;
      const a = positions(h), b = positions(qe);
      const [low, high] = data.difference.clim;
      for (const rig of [h, qe]) {
        const attribute = rig.mesh.geometry.attributes.color, c = attribute.array;
        for (let v = 0; v < nv; v++) {
          const d = Math.hypot(a[3 * v] - b[3 * v], a[3 * v + 1] - b[3 * v + 1], a[3 * v + 2] - b[3 * v + 2]);
          const t = Math.min(1, Math.max(0, (d - low) / (high - low)));
          const rgb = on ? colours[Math.round(t * (colours.length - 1))] : plain;
          c[3 * v] = rgb[0]; c[3 * v + 1] = rgb[1]; c[3 * v + 2] = rgb[2];
        }
        attribute.needsUpdate = true;
      }
      $("rigs-bar").textContent = on ? `|QE - H|: 0 to ${high.toFixed(2)} mm (yellow to red)` : "";
    }
    function update() {
      if (key < 0) {
        rigs.forEach((rig) => pose(rig, values));
        $("rigs-frame").textContent = "posed by the sliders";
        capturedMesh.visible = false;
      } else {
        rigs.forEach((rig) => playKey(rig, key));
        const t = data.timeline, position = capturedGeometry.attributes.position.array;
        for (let i = 0; i < 3 * nv; i++) position[i] = neutral[i] + captured[key * 3 * nv + i] * data.step / 1000;
        capturedGeometry.attributes.position.needsUpdate = true;
        capturedMesh.visible = true;
        const e = (rig) => rig.spec.errors[solver()];
        $("rigs-frame").textContent = `${t.take[key]} frame ${t.frame[key]} (t = ${t.seconds[key].toFixed(2)} s), ` +
          `solver ${solver()}: error H alpha ${e(h).alpha[key].toFixed(3)} %, RMS ${e(h).rms[key].toFixed(2)} mm; ` +
          `${qe.spec.key} alpha ${e(qe).alpha[key].toFixed(3)} %, RMS ${e(qe).rms[key].toFixed(2)} mm`;
      }
      $("rigs-title-h").textContent = h.spec.label;
      $("rigs-title-qe").textContent = qe.spec.label;
      showSliders(rawWeights(h), rawWeights(qe));
      colour();
      curves();
      draw();
      root.setAttribute("data-key", String(key));
    }
    function setSlider(i, value) { key = -1; values[i] = value; selected = i; $("rigs-key").value = 0; update(); }
    function solo(i) { key = -1; values.fill(0); values[i] = 1; selected = i; update(); }
    function reset() { key = -1; values.fill(0); update(); }
    function setKey(k) { key = k; $("rigs-key").value = k; update(); }

    function curves() {  // the selected shape's weights over the timeline in H and in QE, a cursor at the frame
      const c = $("rigs-curves"), g = c.getContext("2d"), count = data.timeline.rows.length;
      const series = [h, qe].map((rig) => rig.spec.weights[solver()].map((row) => row[rig.targets.findIndex((t) => t.shape === selected)]));
      const all = series.flat().concat([0, 1]);
      const low = Math.min(...all), high = Math.max(...all);
      const x = (k) => 40 + (c.width - 50) * k / Math.max(1, count - 1), y = (w) => 10 + (c.height - 30) * (high - w) / (high - low || 1);
      g.clearRect(0, 0, c.width, c.height);
      g.font = "12px sans-serif"; g.fillStyle = "#333";
      g.fillText(`${data.shapes[selected]}: H (blue), ${qe.spec.key} (orange), solver ${solver()}`, 70, 12);
      g.fillText(high.toPrecision(3), 0, 14); g.fillText(low.toPrecision(3), 0, c.height - 20);
      g.strokeStyle = "#bbb"; g.beginPath(); g.moveTo(40, y(0)); g.lineTo(c.width - 10, y(0)); g.stroke();
      series.forEach((s, r) => {
        g.strokeStyle = r ? "#e66101" : "#2c7bb6"; g.beginPath();
        s.forEach((w, k) => (k ? g.lineTo(x(k), y(w)) : g.moveTo(x(k), y(w)))); g.stroke();
      });
      if (key >= 0) { g.strokeStyle = "#000"; g.beginPath(); g.moveTo(x(key), 10); g.lineTo(x(key), c.height - 20); g.stroke(); }
    }
    function draw() {
      const width = canvas.clientWidth, height = canvas.clientHeight;
      if (canvas.width !== Math.round(width * renderer.getPixelRatio())) renderer.setSize(width, height, false);
      camera.aspect = width / 3 / height;
      camera.updateProjectionMatrix();
      renderer.setScissorTest(true);
      [capturedScene, h.scene, qe.scene].forEach((scene, p) => {
        renderer.setViewport(p * width / 3, 0, width / 3, height);
        renderer.setScissor(p * width / 3, 0, width / 3, height);
        renderer.render(scene, camera);
      });
    }

    rigs.slice(1).forEach((rig, r) => {
      const option = document.createElement("option");
      option.value = String(r + 1); option.textContent = rig.spec.label;
      $("rigs-qe").appendChild(option);
    });
    data.solvers.forEach((name) => {
      const option = document.createElement("option");
      option.value = name; option.textContent = name;
      $("rigs-solver").appendChild(option);
    });
    $("rigs-solver").addEventListener("change", update);
    $("rigs-qe").addEventListener("change", () => { qe = rigs[parseInt($("rigs-qe").value, 10)]; update(); });
    $("rigs-raw").addEventListener("change", () => { raw = $("rigs-raw").checked; update(); });
    $("rigs-colour").addEventListener("change", update);
    $("rigs-reset").addEventListener("click", reset);
    $("rigs-key").max = data.timeline.rows.length - 1;
    $("rigs-key").addEventListener("input", () => setKey(parseInt($("rigs-key").value, 10)));
    let timer = null;
    $("rigs-play").addEventListener("click", () => {
      if (timer) { clearInterval(timer); timer = null; $("rigs-play").textContent = "play"; return; }
      $("rigs-play").textContent = "pause";
      timer = setInterval(() => setKey((key + 1) % data.timeline.rows.length), 100);
    });
    controls.addEventListener("change", draw);
    window.addEventListener("resize", draw);
    update();
    // what the page's tests read back: the posed vertices (mm) and raw weights of each rig
    window.workbenchRigs = {
      shapes: data.shapes, rigs: rigs.map((r) => r.spec.key),
      setSlider, solo, reset, setKey, selectQE: (k) => { qe = rigs.find((r) => r.spec.key === k); update(); },
      positions: (k) => Array.from(positions(rigs.find((r) => r.spec.key === k))),
      rawWeights: (k) => rawWeights(rigs.find((r) => r.spec.key === k)),
    };
    status("drawn");
  }
  start().catch((error) => { status("error: " + error.message); console.error(error); });
})();
