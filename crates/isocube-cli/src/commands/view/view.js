"use strict";
// isocube view: the page. No dependencies: WebGL 2 for the surface, 2-d canvases for the
// histogram, the slices and the angle histogram. Every request carries the page's token.

const token = new URLSearchParams(location.search).get("token") || "";
const $ = (id) => document.getElementById(id);
const api = (route, params = {}) =>
  `/api/${route}?` + new URLSearchParams({ ...params, token }).toString();

// ---- state ----------------------------------------------------------------------------------
let volume = null;          // /api/volume: a volume, or fixed surfaces ("parts")
let level = 0;              // the level shown
let seq = 0;                // mesh requests sent
let inflight = null;        // AbortController of the newest mesh request
let selected = 0;           // the surface the figures, quality and downloads are about
const parts = [];           // drawn surfaces: one for a volume, one per label / region / file
const latencies = [];       // slider to the first picture of the new level, ms
const fullLatencies = [];   // slider to the full-resolution picture, ms (large volumes)
const timings = [];         // where each picture's time went: extraction, request, upload, drawing
// What a browser test reads and drives.
window.isocube = {
  latencies, fullLatencies, timings,
  figures: () => (parts[selected] ? parts[selected].figures : null),
  setLevel: (l) => setLevel(l, true),
  setLevels: (n) => setLevels(n),
  previewStride: () => previewStride(),
  toggle: (i, on) => { $(`part${i}`).checked = on; parts[i].visible = on; draw(); },
  parts: () => parts.map((p, i) => ({ name: p.name, number: volume.parts ? volume.parts[i].number : null, visible: p.visible, figures: p.figures })),
  lines: () => overlay.count / 2,
};

// ---- WebGL ----------------------------------------------------------------------------------
const canvas = $("gl");
// Without a GPU (SwiftShader, llvmpipe) every sample is shaded on the CPU, which the server's
// extractions share: no multisampling there.
const software = (() => {
  const probe = document.createElement("canvas").getContext("webgl2");
  const info = probe && probe.getExtension("WEBGL_debug_renderer_info");
  const renderer = info ? String(probe.getParameter(info.UNMASKED_RENDERER_WEBGL)) : "";
  const lose = probe && probe.getExtension("WEBGL_lose_context");
  if (lose) lose.loseContext();
  return /swiftshader|llvmpipe|softpipe|software/i.test(renderer);
})();
const gl = canvas.getContext("webgl2", { antialias: !software, preserveDrawingBuffer: true });
if (!gl) {
  $("status").textContent = "WebGL 2 is not available in this browser";
}
const compile = (type, src) => {
  const s = gl.createShader(type);
  gl.shaderSource(s, src);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
};
const program = (vs, fs) => {
  const p = gl.createProgram();
  gl.attachShader(p, compile(gl.VERTEX_SHADER, vs));
  gl.attachShader(p, compile(gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  return p;
};
const surface = program(
  `#version 300 es
  in vec3 position; in vec3 normal;
  uniform mat4 mvp; uniform mat4 view; uniform vec3 origin; uniform vec3 scale;
  out vec3 n; out vec3 eye;
  void main() {
    vec3 p = origin + scale * position;  // positions arrive quantised on the bounding box
    n = mat3(view) * normal;
    eye = (view * vec4(p, 1.0)).xyz;
    gl_Position = mvp * vec4(p, 1.0);
  }`,
  `#version 300 es
  precision highp float;
  in vec3 n; in vec3 eye; out vec4 color;
  uniform vec3 front; uniform vec3 back;
  void main() {
    vec3 N = normalize(n);
    // Two-sided: a volume's surface warm on the side facing increasing values, cool on the
    // other; a label's or a mesh's own colour, darker inside.
    vec3 base = gl_FrontFacing ? front : back;
    if (!gl_FrontFacing) N = -N;
    vec3 L = normalize(vec3(0.3, 0.5, 1.0));
    float d = max(dot(N, L), 0.0);
    vec3 H = normalize(L + normalize(-eye));
    float s = pow(max(dot(N, H), 0.0), 40.0) * 0.25;
    color = vec4(base * (0.18 + 0.82 * d) + s, 1.0);
  }`
);
const lines = program(
  `#version 300 es
  in vec3 position; uniform mat4 mvp; uniform vec3 origin; uniform vec3 scale;
  void main() {
    gl_Position = mvp * vec4(origin + scale * position, 1.0);
    gl_Position.z -= 1e-4 * gl_Position.w;
  }`,
  `#version 300 es
  precision highp float; out vec4 color; uniform vec4 tint;
  void main() { color = tint; }`
);
// One surface's buffers: positions, normals, triangles, and its edges for the overlay.
function makePart(name, front, back) {
  const p = {
    name, front, back, visible: true, count: 0, edges: 0, figures: null, tris: null, nv: 0,
    origin: [0, 0, 0], scale: [1, 1, 1],
    position: gl.createBuffer(), normal: gl.createBuffer(), index: gl.createBuffer(),
    edgeIndex: gl.createBuffer(), vao: gl.createVertexArray(), edgeVao: gl.createVertexArray(),
  };
  // Positions as u16 × 3 (scaled in the shader), normals as normalised i8 × 4.
  gl.bindVertexArray(p.vao);
  let at = gl.getAttribLocation(surface, "position");
  gl.bindBuffer(gl.ARRAY_BUFFER, p.position);
  gl.enableVertexAttribArray(at);
  gl.vertexAttribPointer(at, 3, gl.UNSIGNED_SHORT, false, 6, 0);
  at = gl.getAttribLocation(surface, "normal");
  gl.bindBuffer(gl.ARRAY_BUFFER, p.normal);
  gl.enableVertexAttribArray(at);
  gl.vertexAttribPointer(at, 3, gl.BYTE, true, 4, 0);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, p.index);
  gl.bindVertexArray(p.edgeVao);
  at = gl.getAttribLocation(lines, "position");
  gl.bindBuffer(gl.ARRAY_BUFFER, p.position);
  gl.enableVertexAttribArray(at);
  gl.vertexAttribPointer(at, 3, gl.UNSIGNED_SHORT, false, 6, 0);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, p.edgeIndex);
  gl.bindVertexArray(null);
  return p;
}
// Lines over the surfaces: a contour stack's contours, a cage's edges.
const overlay = { buffer: gl.createBuffer(), vao: gl.createVertexArray(), count: 0 };
gl.bindVertexArray(overlay.vao);
{
  const at = gl.getAttribLocation(lines, "position");
  gl.bindBuffer(gl.ARRAY_BUFFER, overlay.buffer);
  gl.enableVertexAttribArray(at);
  gl.vertexAttribPointer(at, 3, gl.FLOAT, false, 0, 0);
}
gl.bindVertexArray(null);
// Distinct colours for labels and regions (front; the back is darker).
const palette = [
  [0.89, 0.42, 0.33], [0.38, 0.72, 0.45], [0.36, 0.56, 0.90], [0.93, 0.74, 0.28],
  [0.68, 0.45, 0.86], [0.32, 0.78, 0.80], [0.95, 0.56, 0.74], [0.62, 0.62, 0.34],
  [0.55, 0.40, 0.30], [0.80, 0.80, 0.82], [0.20, 0.55, 0.55], [0.85, 0.35, 0.60],
];

// ---- camera ---------------------------------------------------------------------------------
const camera = { yaw: 0.6, pitch: 0.45, distance: 3, target: [0, 0, 0], radius: 1 };
const mul = (a, b) => {
  const o = new Float32Array(16);
  for (let i = 0; i < 4; i++) for (let j = 0; j < 4; j++) {
    let s = 0;
    for (let k = 0; k < 4; k++) s += a[k * 4 + j] * b[i * 4 + k];
    o[i * 4 + j] = s;
  }
  return o;
};
const perspective = (fovy, aspect, near, far) => {
  const f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
  return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0]);
};
const lookAt = (eye, at, up) => {
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const norm = (a) => { const l = Math.hypot(...a) || 1; return a.map((v) => v / l); };
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const z = norm(sub(eye, at)), x = norm(cross(up, z)), y = cross(z, x);
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  return new Float32Array([x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0, -dot(x, eye), -dot(y, eye), -dot(z, eye), 1]);
};
// Previews on software WebGL are drawn at half resolution: the CPU rasterises every pixel.
let sketch = false;
function draw() {
  const dpr = (window.devicePixelRatio || 1) * (sketch && software ? 0.5 : 1);
  const w = Math.max(1, Math.floor(canvas.clientWidth * dpr)), h = Math.max(1, Math.floor(canvas.clientHeight * dpr));
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  gl.viewport(0, 0, w, h);
  gl.clearColor(0.07, 0.08, 0.1, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  if (!parts.some((p) => p.count) && !overlay.count) return;
  const r = camera.radius * camera.distance;
  const c = Math.cos(camera.pitch);
  const eye = [
    camera.target[0] + r * c * Math.cos(camera.yaw),
    camera.target[1] + r * c * Math.sin(camera.yaw),
    camera.target[2] + r * Math.sin(camera.pitch),
  ];
  const view = lookAt(eye, camera.target, [0, 0, 1]);
  const proj = perspective(0.7, w / h, r * 0.02, r * 4);
  const mvp = mul(proj, view);
  gl.enable(gl.DEPTH_TEST);
  gl.useProgram(surface);
  gl.uniformMatrix4fv(gl.getUniformLocation(surface, "mvp"), false, mvp);
  gl.uniformMatrix4fv(gl.getUniformLocation(surface, "view"), false, view);
  for (const p of parts) {
    if (!p.visible || !p.count) continue;
    gl.uniform3fv(gl.getUniformLocation(surface, "origin"), p.origin);
    gl.uniform3fv(gl.getUniformLocation(surface, "scale"), p.scale);
    gl.uniform3fv(gl.getUniformLocation(surface, "front"), p.front);
    gl.uniform3fv(gl.getUniformLocation(surface, "back"), p.back);
    gl.bindVertexArray(p.vao);
    gl.drawElements(gl.TRIANGLES, p.count, gl.UNSIGNED_INT, 0);
  }
  gl.enable(gl.BLEND);
  gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
  gl.useProgram(lines);
  gl.uniformMatrix4fv(gl.getUniformLocation(lines, "mvp"), false, mvp);
  if ($("edges").checked) {
    gl.uniform4fv(gl.getUniformLocation(lines, "tint"), [0.08, 0.08, 0.1, 0.55]);
    for (const p of parts) {
      if (!p.visible || !p.edges) continue;
      gl.uniform3fv(gl.getUniformLocation(lines, "origin"), p.origin);
      gl.uniform3fv(gl.getUniformLocation(lines, "scale"), p.scale);
      gl.bindVertexArray(p.edgeVao);
      gl.drawElements(gl.LINES, p.edges, gl.UNSIGNED_INT, 0);
    }
  }
  if ($("lines").checked && overlay.count) {
    gl.uniform4fv(gl.getUniformLocation(lines, "tint"), [0.95, 0.95, 0.3, 0.9]);
    gl.uniform3fv(gl.getUniformLocation(lines, "origin"), [0, 0, 0]);
    gl.uniform3fv(gl.getUniformLocation(lines, "scale"), [1, 1, 1]);
    gl.bindVertexArray(overlay.vao);
    gl.drawArrays(gl.LINES, 0, overlay.count);
  }
  gl.disable(gl.BLEND);
  gl.bindVertexArray(null);
}
let dragging = null;
canvas.addEventListener("pointerdown", (e) => { dragging = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
canvas.addEventListener("pointerup", () => { dragging = null; });
canvas.addEventListener("pointermove", (e) => {
  if (!dragging) return;
  camera.yaw -= (e.clientX - dragging[0]) * 0.01;
  camera.pitch = Math.max(-1.55, Math.min(1.55, camera.pitch + (e.clientY - dragging[1]) * 0.01));
  dragging = [e.clientX, e.clientY];
  requestAnimationFrame(draw);
});
canvas.addEventListener("wheel", (e) => {
  e.preventDefault();
  camera.distance = Math.max(0.3, Math.min(20, camera.distance * Math.exp(e.deltaY * 0.001)));
  requestAnimationFrame(draw);
}, { passive: false });
window.addEventListener("resize", () => requestAnimationFrame(draw));

// ---- the mesh -------------------------------------------------------------------------------
// The parameters naming the surface a request is about: the level and extraction settings
// of a volume; the part (and a cage's subdivision levels) otherwise.
const isVolume = () => volume.kind === "volume";
const settings = (part = selected) => isVolume() ? {
  level: String(level),
  method: $("method").value,
  topology: $("topology").value,
  triangulate: $("triangulate").value,
  snap: $("snap").value,
} : { part, ...(volume.kind === "cage" ? { levels: $("levels").value } : {}) };
function edgesOf(tris, vertices) {
  const seen = new Set(), out = [];
  for (let t = 0; t < tris.length; t += 3) {
    for (let e = 0; e < 3; e++) {
      const a = tris[t + e], b = tris[t + (e + 1) % 3];
      const key = a < b ? a * vertices + b : b * vertices + a;
      if (!seen.has(key)) { seen.add(key); out.push(a, b); }
    }
  }
  return new Uint32Array(out);
}
let framed = false;
function uploadEdges(p) {
  if (!$("edges").checked || !p.tris) { p.edges = 0; return; }
  const e = edgesOf(p.tris, p.nv);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, p.edgeIndex);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, e, gl.STATIC_DRAW);
  p.edges = e.length;
}
// A mesh reply (`ICM2`: counts, figures as JSON, quantised positions and normals, triangles)
// into a surface's buffers; returns its bounding box's corners (for framing).
function upload(p, data) {
  const head = new DataView(data, 0, 16);
  const nv = head.getUint32(4, true), nt = head.getUint32(8, true), nj = head.getUint32(12, true);
  const figures = JSON.parse(new TextDecoder().decode(new Uint8Array(data, 16, nj)));
  const at = 16 + nj, normalsAt = at + Math.ceil((nv * 6) / 4) * 4;
  const positions = new Uint16Array(data, at, nv * 3);
  const normals = new Int8Array(data, normalsAt, nv * 4);
  const tris = new Uint32Array(data, normalsAt + nv * 4, nt * 3);
  gl.bindBuffer(gl.ARRAY_BUFFER, p.position);
  gl.bufferData(gl.ARRAY_BUFFER, positions, gl.STATIC_DRAW);
  gl.bindBuffer(gl.ARRAY_BUFFER, p.normal);
  gl.bufferData(gl.ARRAY_BUFFER, normals, gl.STATIC_DRAW);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, p.index);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, tris, gl.STATIC_DRAW);
  p.count = tris.length;
  p.tris = tris;
  p.nv = nv;
  p.origin = figures.origin;
  p.scale = figures.scale;
  p.figures = figures;
  uploadEdges(p);
  return nv ? figures.bounds.flat() : null;
}
// The camera orbits the centre of the first surfaces' bounding box.
function frame(arrays) {
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (const positions of arrays) for (let i = 0; i < positions.length; i += 3) for (let a = 0; a < 3; a++) {
    lo[a] = Math.min(lo[a], positions[i + a]); hi[a] = Math.max(hi[a], positions[i + a]);
  }
  if (!(lo[0] <= hi[0])) return;
  camera.target = lo.map((v, a) => (v + hi[a]) / 2);
  camera.radius = Math.max(1e-9, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
  framed = true;
}
function show(figures) {
  $("triangles").textContent = figures.triangles.toLocaleString("en");
  $("vertices").textContent = figures.vertices.toLocaleString("en");
  $("millis").textContent = `${figures.millis.toFixed(1)} ms`;
  $("watertight").textContent = $("genus").textContent = "…";
}
// The topology after the picture, for the surface still shown.
// A request made in the background: a server that has stopped (Ctrl-C) is said, not thrown.
async function quietly(url) {
  try {
    return await fetch(url);
  } catch (e) {
    $("status").textContent = "the isocube view server does not answer (stopped?)";
    return { ok: false };
  }
}
async function showTopology(shown) {
  const reply = await quietly(api("topology", settings()));
  const current = () => parts[selected] && parts[selected].figures === shown;
  if (!reply.ok || !current()) return;
  const t = await reply.json();
  if (!current()) return;
  $("watertight").textContent = t.watertight ? "yes" : `no (${t.boundary_edges} boundary edges)`;
  $("genus").textContent = `${t.components}, ${t.genus ?? "–"}`;
}
const percentile = (values, p) => {
  const s = [...values].sort((a, b) => a - b);
  return s[Math.min(s.length - 1, Math.floor(p * s.length))];
};
// Fetches the mesh for the current settings; the newest request wins (older ones are
// aborted here and refused by the server). Resolves once the picture is drawn.
async function remesh(started, coarse = false) {
  clearTimeout(topologyTimer);
  if (inflight) inflight.abort();
  const controller = (inflight = new AbortController());
  seq += 1;
  const t0 = performance.now();
  let reply, data;
  try {
    const params = { ...settings(), seq, ...(coarse ? { coarse: previewStride() } : {}) };
    reply = await fetch(api("mesh", params), { signal: controller.signal });
    if (reply.status === 409) return false;
    if (!reply.ok) { $("status").textContent = await reply.text(); return false; }
    data = await reply.arrayBuffer();
  } catch (e) {
    // A newer request took over: this one's answer no longer matters.
    if (e.name === "AbortError") return false;
    throw e;
  }
  if (controller !== inflight) return false;
  $("status").textContent = "";
  const t1 = performance.now();
  const corners = upload(parts[0], data);
  const figures = parts[0].figures;
  if (!framed && corners) frame([corners]);
  const t2 = performance.now();
  sketch = coarse;
  draw();
  show(figures);
  // The picture counts as shown once the browser has produced the frame after it (two
  // animation frames: the canvas is composited in the first). Measured aside: nothing waits
  // for frames (a hidden page has none).
  const list = started === undefined ? null : !coarse && pendingFull === started ? fullLatencies : latencies;
  if (list === fullLatencies) pendingFull = null;
  requestAnimationFrame(() => requestAnimationFrame(() => {
    const t3 = performance.now();
    // Where each picture's time went (ms): the request, the upload, drawing until shown.
    timings.push({ coarse, extract: figures.millis, fetch: t1 - t0, upload: t2 - t1, draw: t3 - t2, bytes: data.byteLength });
    if (!list) return;
    list.push(t3 - started);
    if (latencies.length) $("latency").textContent = `${percentile(latencies, 0.5).toFixed(0)} / ${percentile(latencies, 0.95).toFixed(0)} ms`;
  }));
  if (coarse) {
    $("triangles").textContent += " (preview)";
    return true;
  }
  drawSlices();
  // The topology (an edge table on the server) once the slider rests: asked at every step it
  // would hold the single-threaded server up before the next surface.
  clearTimeout(topologyTimer);
  topologyTimer = setTimeout(() => showTopology(figures), 300);
  return true;
}
let topologyTimer = 0;

// ---- the level: slider over the value range, histogram behind --------------------------------
const toSlider = (l) => Math.round(((l - volume.min) / (volume.max - volume.min || 1)) * 10000);
const fromSlider = (s) => volume.min + (s / 10000) * (volume.max - volume.min);
// Volumes above 4 M points show a preview on a coarser grid while the slider moves, and the
// full surface once it rests for 200 ms.
const points = () => volume.dims[0] * volume.dims[1] * volume.dims[2];
const large = () => points() > 1 << 22;
// The preview takes every k-th point along each axis: every other one (a quarter of the
// triangles), or on software WebGL as many as keep it within a million points.
const previewStride = () => {
  let k = 2;
  while (software && k < 8 && points() / k ** 3 > 1 << 20) k += 1;
  return k;
};
let restTimer = 0, pendingFull = null;
function setLevel(l, fromCode) {
  level = l;
  $("levelvalue").textContent = `= ${Number(l.toPrecision(6))}`;
  if (fromCode) $("level").value = String(toSlider(l));
  $("levelnum").value = String(Number(l.toPrecision(8)));
  clearTimeout(restTimer);
  const started = performance.now();
  if (fromCode || !large()) {
    pendingFull = null;
    return remesh(started);
  }
  pendingFull = started;
  // The rest is counted from the preview's picture: a slow preview is not overtaken.
  return remesh(started, true).then((shown) => {
    if (shown && pendingFull === started) restTimer = setTimeout(() => remesh(started), 200);
    return shown;
  });
}
function drawHistogram() {
  const c = $("histogram"), ctx = c.getContext("2d");
  c.width = c.clientWidth; c.height = c.clientHeight;
  const counts = volume.histogram, top = Math.log1p(Math.max(...counts));
  ctx.fillStyle = "#4b5563";
  for (let i = 0; i < counts.length; i++) {
    const h = (Math.log1p(counts[i]) / (top || 1)) * c.height;
    ctx.fillRect((i / counts.length) * c.width, c.height - h, c.width / counts.length + 0.5, h);
  }
}
$("level").addEventListener("input", () => setLevel(fromSlider(Number($("level").value)), false));
$("levelnum").addEventListener("change", () => {
  const l = Number($("levelnum").value);
  if (Number.isFinite(l)) setLevel(l, true);
});
for (const id of ["method", "topology", "triangulate", "snap"]) {
  $(id).addEventListener("change", () => remesh(performance.now()));
}
$("edges").addEventListener("change", () => { parts.forEach(uploadEdges); draw(); });
$("lines").addEventListener("change", draw);

// ---- slices: the volume across each axis, the level's contour on it ---------------------------
const sliceCache = [null, null, null];
async function loadSlice(axis) {
  const index = Number($(`index${axis}`).value);
  const reply = await quietly(api("slice", { axis, index }));
  if (!reply.ok) return;
  const data = await reply.arrayBuffer();
  const head = new DataView(data, 0, 8);
  sliceCache[axis] = { w: head.getUint32(0, true), h: head.getUint32(4, true), v: new Float32Array(data, 8) };
  drawSlice(axis);
}
function drawSlice(axis) {
  const s = sliceCache[axis];
  if (!s) return;
  const c = $(`slice${axis}`), ctx = c.getContext("2d");
  const scale = Math.max(1, Math.floor(192 / Math.max(s.w, s.h)));
  c.width = s.w * scale; c.height = s.h * scale;
  const image = ctx.createImageData(s.w, s.h);
  const span = volume.max - volume.min || 1;
  for (let y = 0; y < s.h; y++) for (let x = 0; x < s.w; x++) {
    // Rows drawn bottom-up, so the second axis points up.
    const g = Math.max(0, Math.min(255, ((s.v[y * s.w + x] - volume.min) / span) * 255));
    const o = ((s.h - 1 - y) * s.w + x) * 4;
    image.data[o] = image.data[o + 1] = image.data[o + 2] = g; image.data[o + 3] = 255;
  }
  const tmp = document.createElement("canvas");
  tmp.width = s.w; tmp.height = s.h;
  tmp.getContext("2d").putImageData(image, 0, 0);
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(tmp, 0, 0, c.width, c.height);
  // Marching squares at the level: a segment across every cell whose corners straddle it.
  ctx.strokeStyle = "#e0a530"; ctx.lineWidth = 1.5; ctx.beginPath();
  const at = (x, y) => s.v[y * s.w + x];
  const px = (x, y) => [(x + 0.5) * scale, (s.h - 0.5 - y) * scale];
  for (let y = 0; y + 1 < s.h; y++) for (let x = 0; x + 1 < s.w; x++) {
    const corners = [[x, y], [x + 1, y], [x + 1, y + 1], [x, y + 1]];
    const cross = [];
    for (let e = 0; e < 4; e++) {
      const [ax, ay] = corners[e], [bx, by] = corners[(e + 1) % 4];
      const a = at(ax, ay) - level, b = at(bx, by) - level;
      if ((a < 0) !== (b < 0)) {
        const t = a / (a - b);
        cross.push(px(ax + t * (bx - ax), ay + t * (by - ay)));
      }
    }
    for (let k = 0; k + 1 < cross.length; k += 2) {
      ctx.moveTo(...cross[k]); ctx.lineTo(...cross[k + 1]);
    }
  }
  ctx.stroke();
}
const drawSlices = () => [0, 1, 2].forEach(drawSlice);
for (const axis of [0, 1, 2]) $(`index${axis}`).addEventListener("input", () => loadSlice(axis));

// ---- quality and downloads ------------------------------------------------------------------
$("measure").addEventListener("click", async () => {
  const reply = await fetch(api("quality", settings()));
  if (!reply.ok) return;
  const q = await reply.json();
  $("minangle").textContent = `${q.min_angle.min.toFixed(1)}° / ${q.min_angle.mean.toFixed(1)}°`;
  $("below").textContent = q.below.map((b) => `${(100 * b).toFixed(1)} %`).join(" / ");
  const c = $("angles"), ctx = c.getContext("2d");
  c.width = c.clientWidth; c.height = c.clientHeight;
  const top = Math.max(...q.histogram) || 1;
  ctx.fillStyle = "#e0a530";
  q.histogram.forEach((n, i) => {
    const h = (n / top) * c.height;
    ctx.fillRect((i / 36) * c.width, c.height - h, c.width / 36 - 1, h);
  });
});
for (const link of document.querySelectorAll("a.dl")) {
  link.addEventListener("click", (e) => {
    e.preventDefault();
    location.href = api("download", { ...settings(), format: link.dataset.format });
  });
}

// ---- fixed surfaces: labels, a mesh, a cage and its subdivision, contour stacks --------------
const hex = (c) => "#" + c.map((v) => Math.round(v * 255).toString(16).padStart(2, "0")).join("");
// Shows surface `i`'s figures, topology and quality, and makes it the one downloads are of.
function select(i) {
  selected = i;
  document.querySelectorAll("#partlist tr").forEach((row, k) => row.classList.toggle("chosen", k === i));
  const figures = parts[i].figures;
  show(figures);
  clearTimeout(topologyTimer);
  topologyTimer = setTimeout(() => showTopology(figures), 0);
}
async function fetchPart(i) {
  const reply = await fetch(api("mesh", settings(i)));
  if (!reply.ok) { $("status").textContent = await reply.text(); return null; }
  return upload(parts[i], await reply.arrayBuffer());
}
// A cage's subdivision at `n` levels (the server subdivides the cage again).
async function setLevels(n) {
  $("levels").value = String(n);
  const started = performance.now();
  await fetchPart(0);
  $("partlist").rows[0].cells[2].textContent = parts[0].figures.triangles.toLocaleString("en");
  draw();
  select(0);
  latencies.push(performance.now() - started);
}
async function loadParts() {
  $("volumeonly").hidden = true;
  $("slicebox").hidden = true;
  $("partsbox").hidden = false;
  const what = { labels: "labels", mesh: "mesh", cage: "cage", contours: "contour stack" }[volume.kind];
  $("dims").textContent = `${what}: ${volume.parts.length} surface${volume.parts.length === 1 ? "" : "s"}` +
    (volume.notes.length ? ` (${volume.notes.join("; ")})` : "");
  if (volume.kind === "cage") {
    $("levelsrow").hidden = false;
    for (let n = 0; n <= volume.max_levels; n++) $("levels").add(new Option(String(n), String(n)));
    $("levels").value = String(volume.levels);
    $("levels").addEventListener("change", () => setLevels(Number($("levels").value)));
  }
  if (volume.lines) {
    $("linesrow").hidden = false;
    $("lineslabel").textContent = volume.kind === "cage" ? "cage" : "contours";
    $("lines").checked = true;
  }
  const list = $("partlist");
  volume.parts.forEach((info, i) => {
    const colour = volume.kind === "labels" || volume.kind === "contours" ? palette[i % palette.length] : [0.88, 0.66, 0.25];
    parts.push(makePart(info.name, colour, colour.map((v) => v * 0.5)));
    const row = list.insertRow();
    row.innerHTML = `<td><input type="checkbox" id="part${i}" checked></td>` +
      `<td><span class="swatch" style="background:${hex(colour)}"></span> </td><td></td>`;
    row.cells[1].append(info.name);
    row.cells[2].textContent = info.triangles.toLocaleString("en");
    row.addEventListener("click", (e) => { if (e.target.tagName !== "INPUT") select(i); });
    $(`part${i}`).addEventListener("change", (e) => { parts[i].visible = e.target.checked; draw(); });
  });
  const arrays = [];
  for (let i = 0; i < parts.length; i++) arrays.push(await fetchPart(i));
  if (volume.lines) {
    const data = await (await fetch(api("lines"))).arrayBuffer();
    const n = new DataView(data, 0, 8).getUint32(4, true);
    const points = new Float32Array(data, 8, n * 3);
    gl.bindBuffer(gl.ARRAY_BUFFER, overlay.buffer);
    gl.bufferData(gl.ARRAY_BUFFER, points, gl.STATIC_DRAW);
    overlay.count = n;
    arrays.push(points);
  }
  frame(arrays.filter(Boolean));
  draw();
  select(0);
}

// ---- start ----------------------------------------------------------------------------------
(async () => {
  volume = await (await fetch(api("volume"))).json();
  // The file's name; its path on hover.
  const base = volume.name.split(/[\\/]/).pop() || volume.name;
  $("name").textContent = base;
  $("name").title = volume.name;
  document.title = `isocube view — ${base}`;
  if (!isVolume()) {
    await loadParts();
    window.isocube.ready = true;
    return;
  }
  parts.push(makePart(volume.name, [0.88, 0.66, 0.25], [0.35, 0.55, 0.85]));
  const short = (v) => String(Number(v.toPrecision(6)));
  $("dims").textContent = `${volume.dims.join(" × ")} points, values ${short(volume.min)} to ${short(volume.max)}`;
  drawHistogram();
  for (const axis of [0, 1, 2]) {
    const input = $(`index${axis}`);
    input.max = String(volume.dims[axis] - 1);
    input.value = String(Math.floor(volume.dims[axis] / 2));
    loadSlice(axis);
  }
  await setLevel(volume.level, true);
  window.isocube.ready = true;
})();
