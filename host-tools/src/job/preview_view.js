// The viewer of host-tools' preview page: decodes the embedded moves, builds the tube
// instances, and runs the camera, the colour scale over the visible layers with its legend, the
// hover readout, the annotations and the URL parameters (inlined after preview_gl.js).
//
// URL parameters (after `?` or `#`, for a shared view or a test): color=speed|feed|width|cross|
// layer|time|plain, layers=A,B (the firmware's layer numbers shown), yaw=, pitch= (radians),
// zoom= (× closer), travels=1, notes=0, hover=line:N (point at the move on source line N) or
// hover=X,Y (CSS pixels), bench=N (time N frames).

const MF = 12;
const NM = Math.floor(MOVES.length / MF);
// Marks of the start code (a purge line the firmware counts before its first layer): shown
// as the start, as `stats` counts them.
const PRELUDE = META.prelude || 0;
const unprelude = k => (k > PRELUDE ? k - PRELUDE : 0);
const mv = {
  print: new Uint8Array(NM), layer: new Uint32Array(NM), line: new Uint32Array(NM),
  s: new Float32Array(3 * NM), e: new Float32Array(3 * NM), t: new Float64Array(NM),
  speed: new Float32Array(NM), feed: new Float32Array(NM), de: new Float32Array(NM),
  w: new Float32Array(NM), h: new Float32Array(NM), jump: new Uint8Array(NM),
};
const tubeMove = [], travelMove = [];
{
  let ji = 0, px = 0, py = 0, pz = 0;
  for (let i = 0; i < NM; i++) {
    const o = i * MF, f = MOVES[o];
    if (f & 2) { px = JUMPS[ji]; py = JUMPS[ji + 1]; pz = JUMPS[ji + 2]; ji += 3; mv.jump[i] = 1; }
    mv.print[i] = f & 1;
    mv.layer[i] = unprelude(MOVES[o + 1]);
    mv.line[i] = MOVES[o + 2];
    mv.s[3 * i] = px; mv.s[3 * i + 1] = py; mv.s[3 * i + 2] = pz;
    px = mv.e[3 * i] = MOVES[o + 3]; py = mv.e[3 * i + 1] = MOVES[o + 4]; pz = mv.e[3 * i + 2] = MOVES[o + 5];
    mv.t[i] = MOVES[o + 6]; mv.speed[i] = MOVES[o + 7]; mv.feed[i] = MOVES[o + 8];
    mv.de[i] = MOVES[o + 9]; mv.w[i] = MOVES[o + 10]; mv.h[i] = MOVES[o + 11];
    (f & 1 ? tubeMove : travelMove).push(i);
  }
}
const NT = tubeMove.length, NTR = travelMove.length;
let maxLayer = LAYERS.length;
for (let i = 0; i < NM; i++) maxLayer = Math.max(maxLayer, mv.layer[i]);

for (const n of NOTES) n[5] = unprelude(n[5]);
// The layer as the firmware numbers it (what `stats` and M761 L<n> call it); a job without
// layer marks is one piece ("all").
function layerName(k) {
  if (LAYERS.length === 0) return "all";
  if (k === 0) return "start";
  const l = LAYERS[k - 1];
  return l ? String(l[0]) : "#" + k;
}
// First position in `list` (move indices in file order) whose layer is ≥ k.
function lowerBound(list, k) {
  let a = 0, b = list.length;
  while (a < b) { const m = (a + b) >> 1; if (mv.layer[list[m]] < k) a = m + 1; else b = m; }
  return a;
}

// Tube instances: joined to the neighbour when the two are consecutive printing moves that
// meet and turn by less than 120°; the ring where they meet takes the mean width.
function tubeInstances() {
  const S = TUBE_STRIDE, inst = new Float32Array((NT + 2) * S);
  const dir = i => {
    const dx = mv.e[3 * i] - mv.s[3 * i], dy = mv.e[3 * i + 1] - mv.s[3 * i + 1],
          dz = mv.e[3 * i + 2] - mv.s[3 * i + 2], l = Math.hypot(dx, dy, dz);
    return l > 1e-6 ? [dx / l, dy / l, dz / l] : null;
  };
  const joins = new Uint8Array(NT + 1);   // joins[j]: tube j - 1 joins tube j
  let prevDir = null;
  for (let j = 0; j < NT; j++) {
    const i = tubeMove[j], d = dir(i);
    if (j > 0 && tubeMove[j - 1] === i - 1 && !mv.jump[i] && d && prevDir &&
        d[0] * prevDir[0] + d[1] * prevDir[1] + d[2] * prevDir[2] > -0.5) joins[j] = 1;
    prevDir = d;
  }
  for (let j = 0; j < NT; j++) {
    const i = tubeMove[j], o = (j + 1) * S, w = mv.w[i];
    inst.set(mv.s.subarray(3 * i, 3 * i + 3), o);
    inst[o + 3] = joins[j] ? 0.5 * (w + mv.w[tubeMove[j - 1]]) : w;
    inst.set(mv.e.subarray(3 * i, 3 * i + 3), o + 4);
    inst[o + 7] = joins[j + 1] ? 0.5 * (w + mv.w[tubeMove[j + 1]]) : w;
    inst[o + 8] = mv.h[i];
    inst[o + 9] = joins[j] + 2 * joins[j + 1];
  }
  return inst;
}

// Framing: the printing moves between the 1st and 99th percentile of each coordinate, so a
// purge line at the bed's edge does not pull the part out of the middle.
const lo3 = [0, 0, 0], hi3 = [1, 1, 1];
{
  const step = Math.max(1, Math.floor(NT / 200000));
  const xs = [[], [], []];
  for (let j = 0; j < NT; j += step) for (let k = 0; k < 3; k++) xs[k].push(mv.e[3 * tubeMove[j] + k]);
  for (let k = 0; k < 3; k++) {
    const v = Float64Array.from(xs[k]).sort();
    if (v.length > 0) { lo3[k] = v[Math.floor(0.01 * (v.length - 1))]; hi3[k] = v[Math.ceil(0.99 * (v.length - 1))]; }
  }
}
const center = [0, 1, 2].map(k => (lo3[k] + hi3[k]) / 2);
const radius = Math.max(1, Math.hypot(hi3[0] - lo3[0], hi3[1] - lo3[1], hi3[2] - lo3[2]) / 2);
const sceneR = Math.max(radius, ...[[0, 1], [2, 1], [2, 3], [0, 3]].map(
  ([a, b]) => Math.hypot(META.bed[a] - center[0], META.bed[b] - center[1], center[2])));
const cam = { yaw: -0.6, pitch: 0.75, dist: radius * 3.2, pan: [0, 0] };

const canvas = document.getElementById("view");
const $ = id => document.getElementById(id);
const ui = { mode: $("mode"), travel: $("travel"), notes: $("show-notes"), lo: $("lo"), hi: $("hi") };
// null without WebGL 2 (or if its shaders do not compile there): the page says so.
const gfx = (() => {
  try { return makeRenderer(canvas); } catch (e) { console.error(e); return null; }
})();

const COLOUR = {
  speed: { name: "speed (peak)", unit: "mm/s", dec: 1, of: i => mv.speed[i] },
  feed: { name: "commanded feed", unit: "mm/s", dec: 1, of: i => mv.feed[i] },
  width: { name: "line width", unit: "mm", dec: 3, of: i => mv.w[i] },
  cross: { name: "cross-section", unit: "mm²", dec: 4,
           of: i => (mv.w[i] - mv.h[i]) * mv.h[i] + Math.PI * mv.h[i] * mv.h[i] / 4 },
  layer: { name: "layer", unit: "", dec: 0, of: i => mv.layer[i] },
  time: { name: "time", unit: "", dec: 1, of: i => mv.t[i] },
  plain: { name: "plain", unit: "", dec: 0, of: () => 0 },
};
// Per layer index: the lowest and highest value of the current colour mode.
let layerMin = null, layerMax = null, colourMode = "";
function setColourMode(mode) {
  const c = COLOUR[mode] || COLOUR.speed, vals = new Float32Array(Math.max(1, NT));
  layerMin = new Float64Array(maxLayer + 1).fill(Infinity);
  layerMax = new Float64Array(maxLayer + 1).fill(-Infinity);
  for (let j = 0; j < NT; j++) {
    const i = tubeMove[j], v = c.of(i), l = mv.layer[i];
    vals[j] = v;
    if (v < layerMin[l]) layerMin[l] = v;
    if (v > layerMax[l]) layerMax[l] = v;
  }
  colourMode = mode;
  if (gfx) gfx.setValues(vals);
}
// The colour scale of the visible layers: [min, max] of the mode's value over them.
function visibleRange(l0, l1) {
  let a = Infinity, b = -Infinity;
  for (let k = l0; k <= l1; k++) { a = Math.min(a, layerMin[k]); b = Math.max(b, layerMax[k]); }
  return [a, b];
}

// h:mm:ss.s or m:ss.s.
function fmtTime(s) {
  const tenths = Math.round(s * 10), h = Math.floor(tenths / 36000);
  const m = Math.floor((tenths % 36000) / 600), sec = (tenths % 600) / 10;
  const ss = (sec < 10 ? "0" : "") + sec.toFixed(1);
  return h > 0 ? h + ":" + (m < 10 ? "0" : "") + m + ":" + ss : m + ":" + ss;
}
function fmtValue(mode, v) {
  if (mode === "layer") return layerName(Math.round(v));
  if (mode === "time") return fmtTime(v);
  const c = COLOUR[mode];
  return v.toFixed(c.dec) + (c.unit ? " " + c.unit : "");
}
function ramp(u) {
  u = Math.min(1, Math.max(0, u));
  const stops = [[0, 40, 200], [0, 190, 220], [30, 180, 40], [240, 200, 0], [220, 30, 20]];
  const x = u * 4, i = Math.min(3, Math.floor(x)), f = x - i, a = stops[i], b = stops[i + 1];
  return "rgb(" + [0, 1, 2].map(k => Math.round(a[k] + (b[k] - a[k]) * f)).join(",") + ")";
}

function layerRange() {
  const a = +ui.lo.value, b = +ui.hi.value;
  return [Math.min(a, b), Math.max(a, b)];
}

// Camera: an orbit about the print's centre, Z up; view and projection as column-major 4 × 4.
function matrices() {
  const w = canvas.width, h = canvas.height;
  const cy = Math.cos(cam.yaw), sy = Math.sin(cam.yaw), cp = Math.cos(cam.pitch), sp = Math.sin(cam.pitch);
  const R = [cy, -sy, 0], U = [sp * sy, sp * cy, cp], F = [cp * sy, cp * cy, -sp];
  const eye = [0, 1, 2].map(k => center[k] - cam.dist * F[k] - cam.pan[0] * R[k] - cam.pan[1] * U[k]);
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const view = new Float32Array([R[0], U[0], -F[0], 0, R[1], U[1], -F[1], 0, R[2], U[2], -F[2], 0,
                                 -dot(R, eye), -dot(U, eye), dot(F, eye), 1]);
  const f = 0.9 * Math.min(w, h) / (2 * Math.tan(0.35));
  const near = Math.max(0.01 * cam.dist, cam.dist - 2 * sceneR), far = cam.dist + 2 * sceneR;
  const proj = new Float32Array([2 * f / w, 0, 0, 0, 0, 2 * f / h, 0, 0,
                                 0, 0, (far + near) / (near - far), -1, 0, 0, 2 * far * near / (near - far), 0]);
  const mvp = new Float32Array(16);
  for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) {
    let s = 0;
    for (let k = 0; k < 4; k++) s += proj[k * 4 + r] * view[c * 4 + k];
    mvp[c * 4 + r] = s;
  }
  // Device pixels of a point (and whether it is in front of the camera).
  const project = (x, y, z) => {
    const xv = view[0] * x + view[4] * y + view[8] * z + view[12];
    const yv = view[1] * x + view[5] * y + view[9] * z + view[13];
    const zv = view[2] * x + view[6] * y + view[10] * z + view[14];
    return [w / 2 + f * xv / -zv, h / 2 - f * yv / -zv, -zv > near];
  };
  return { view, mvp, project, pxPerMm: f / cam.dist };
}

const COARSE_ABOVE = 250000, COARSE_DRAGGING_ABOVE = 60000, COARSE_BELOW_PX = 4;
const SLOW_FRAME_MS = 150, SLOW_FIRST_FRAME_MS = 1000;
// The median bead width, mm (sampled).
const beadMm = (() => {
  const step = Math.max(1, Math.floor(NT / 10000)), w = [];
  for (let j = 0; j < NT; j += step) w.push(mv.w[tubeMove[j]]);
  return w.length ? Float64Array.from(w).sort()[w.length >> 1] : 0.4;
})();
// Set for the session when the first frame (shaders compiled, data uploaded) took over
// SLOW_FIRST_FRAME_MS, or a frame drawn while turning over SLOW_FRAME_MS (software WebGL, a big
// job). Then the view turns with the printing moves as lines, picks on lines when the beads
// are thin on screen, and does not redraw to highlight the move pointed at.
let slowRenderer = false;
function setSlow() {
  slowRenderer = true;
  document.body.dataset.slowRenderer = "1";
}
let dragging = false, hoverId = -1, lastFrame = null;
function frame() {
  const [l0, l1] = layerRange();
  const t0 = lowerBound(tubeMove, l0), t1 = lowerBound(tubeMove, l1 + 1);
  const r0 = lowerBound(travelMove, l0), r1 = lowerBound(travelMove, l1 + 1);
  const m = matrices(), range = visibleRange(l0, l1);
  const visible = t1 - t0;
  return Object.assign(m, {
    l0, l1, range,
    tubes: [t0, t1 - t0], travels: ui.travel.checked ? [r0, r1 - r0] : null,
    plain: colourMode === "plain", hover: hoverId,
    // Level of detail: 4-sided tubes (half the triangles) for big ranges, while turning, and
    // when a typical bead is under COARSE_BELOW_PX wide on screen at the view's centre.
    coarse: visible > COARSE_ABOVE || (dragging && visible > COARSE_DRAGGING_ABOVE) ||
            beadMm * m.pxPerMm < COARSE_BELOW_PX,
    // A slow renderer turns the view with lines; the tubes come back when the mouse is let go.
    lines: dragging && slowRenderer,
  });
}

function drawNow() {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  const f = frame();
  lastFrame = f;
  const [a, b] = isFinite(f.range[0]) ? f.range : [0, 0];
  gfx.draw(Object.assign({}, f, { range: [a, b > a ? b : a + 1] }));
  $("range").textContent = LAYERS.length === 0 ? "whole job (no layer marks)"
    : layerName(f.l0) + "–" + layerName(f.l1) + " of " + layerName(maxLayer);
  legend(f);
  placeNotes(f, dpr);
}
let pending = false;
function requestDraw() {
  if (pending) return;
  pending = true;
  requestAnimationFrame(() => {
    pending = false;
    if (dragging && !slowRenderer) {
      // Time a turning frame to its end (a real GPU waits a few ms once).
      const t = performance.now();
      drawNow();
      gfx.finish();
      if (performance.now() - t > SLOW_FRAME_MS) setSlow();
      else return;
    }
    drawNow();
  });
}

function legend(f) {
  const mode = colourMode, bar = $("legend-bar").getContext("2d");
  for (let x = 0; x < 220; x++) {
    bar.fillStyle = mode === "plain" ? "rgb(237,143,51)" : ramp(x / 219);
    bar.fillRect(x, 0, 1, 10);
  }
  const [a, b] = f.range, ok = isFinite(a) && mode !== "plain";
  for (const [id, v] of [["legend-min", a], ["legend-max", b]]) {
    const el = $(id);
    el.textContent = ok ? fmtValue(mode, v) : "–";
    el.dataset.value = ok ? (mode === "layer" ? layerName(Math.round(v)) : String(v)) : "";
  }
  $("legend-name").textContent = COLOUR[mode].name + (ok ? "" : " (nothing shown)");
}

// Annotation labels: HTML over the canvas at their projected points.
const noteEls = NOTES.map(n => {
  const el = document.createElement("div");
  el.className = "note";
  el.textContent = n[0];
  el.title = "line " + n[1];
  el.style.display = "none";
  $("notes").appendChild(el);
  return el;
});
function placeNotes(f, dpr) {
  NOTES.forEach((n, k) => {
    const el = noteEls[k], p = f.project(n[2], n[3], n[4]);
    const show = ui.notes.checked && n[5] >= f.l0 && n[5] <= f.l1 && p[2] &&
                 p[0] >= 0 && p[1] >= 0 && p[0] < canvas.width && p[1] < canvas.height;
    el.style.display = show ? "block" : "none";
    if (show) { el.style.left = Math.round(p[0] / dpr) + "px"; el.style.top = Math.round(p[1] / dpr) + "px"; }
  });
}

// Hover readout of the move drawn under device pixel (x, y). A slow renderer picks among
// lines when the beads are thin on screen, unless `exact` (the URL's hover).
function hoverAt(x, y, exact) {
  const f = lastFrame || frame();
  const id = gfx.pick(Object.assign({}, f, { lines: !exact && slowRenderer && f.coarse }), x, y);
  const i = id < 0 ? -1 : id < NT ? tubeMove[id] : travelMove[id - NT];
  hoverId = i === undefined ? -1 : id;
  showReadout(i === undefined ? -1 : i);
  if (!slowRenderer) requestDraw();
}
function showReadout(i) {
  const box = $("readout");
  if (i < 0) { box.style.display = "none"; return; }
  const k = mv.layer[i], l = LAYERS[k - 1], print = mv.print[i] === 1;
  const set = (id, text) => { $(id).textContent = text; };
  set("ro-line", String(mv.line[i]));
  set("ro-kind", print ? "printing" : "travel");
  set("ro-layer", layerName(k) + (l && l[1] !== null ? " (Z " + l[1].toFixed(2) + " mm)" : ""));
  set("ro-feed", mv.feed[i].toFixed(1) + " mm/s (F" + Math.round(mv.feed[i] * 60) + ")");
  set("ro-speed", mv.speed[i].toFixed(1) + " mm/s peak");
  set("ro-e", (mv.de[i] >= 0 ? "+" : "") + mv.de[i].toFixed(5) + " mm");
  set("ro-bead", print ? mv.w[i].toFixed(3) + " × " + mv.h[i].toFixed(3) + " mm" : "–");
  set("ro-time", fmtTime(mv.t[i]));
  box.dataset.move = String(i);
  box.style.display = "block";
}

function start() {
  if (!gfx) { $("nogl").style.display = "block"; return; }
  const asLines = list => {
    const p = new Float32Array(6 * list.length);
    list.forEach((i, j) => { p.set(mv.s.subarray(3 * i, 3 * i + 3), 6 * j); p.set(mv.e.subarray(3 * i, 3 * i + 3), 6 * j + 3); });
    return p;
  };
  gfx.setTubes(tubeInstances(), NT, asLines(tubeMove));
  gfx.setTravels(asLines(travelMove));
  const b = META.bed;
  gfx.setBed(new Float32Array([b[0], b[1], 0, b[2], b[1], 0, b[2], b[1], 0, b[2], b[3], 0,
                               b[2], b[3], 0, b[0], b[3], 0, b[0], b[3], 0, b[0], b[1], 0]));
  ui.lo.max = ui.hi.max = String(maxLayer);
  ui.hi.value = String(maxLayer);
  const q = new URLSearchParams(location.search.slice(1) || location.hash.slice(1));
  if (COLOUR[q.get("color")]) ui.mode.value = q.get("color");
  if (q.get("travels") === "1") ui.travel.checked = true;
  if (q.get("notes") === "0") ui.notes.checked = false;
  if (q.has("yaw")) cam.yaw = +q.get("yaw") || 0;
  if (q.has("pitch")) cam.pitch = Math.max(-1.57, Math.min(1.57, +q.get("pitch") || 0));
  if (q.has("zoom")) cam.dist /= Math.max(0.02, +q.get("zoom") || 1);
  if (q.has("layers")) {
    // By the numbers shown: the first layer called A to the last called B.
    const [a, z] = q.get("layers").split(",");
    const names = Array.from({ length: maxLayer + 1 }, (_, k) => layerName(k));
    const lo = names.indexOf(a), hi = names.lastIndexOf(z);
    if (lo >= 0) ui.lo.value = String(lo);
    if (hi >= 0) ui.hi.value = String(hi);
  }
  setColourMode(ui.mode.value);
  const t0 = performance.now();
  drawNow();
  gfx.finish();
  const firstMs = performance.now() - t0;
  if (firstMs > SLOW_FIRST_FRAME_MS) setSlow();
  document.body.dataset.loadMs = performance.now().toFixed(0);
  document.body.dataset.firstFrameMs = firstMs.toFixed(0);
  const hv = q.get("hover");
  if (hv) {
    const f = lastFrame;
    let x = NaN, y = NaN;
    if (hv.startsWith("line:")) {
      const n = +hv.slice(5), hits = [];
      for (let i = 0; i < NM; i++) if (mv.line[i] === n) hits.push(i);
      const i = hits.find(j => mv.print[j]) ?? hits[0];
      if (i !== undefined) {
        // Aim at the middle of the bead's top (where the nozzle passed): nothing in the layer
        // is higher, so from above that point is the move's own.
        const m = [0, 1, 2].map(k => (mv.s[3 * i + k] + mv.e[3 * i + k]) / 2);
        [x, y] = f.project(m[0], m[1], m[2]);
      }
    } else {
      const dpr = window.devicePixelRatio || 1;
      [x, y] = hv.split(",").map(v => +v * dpr);
    }
    if (isFinite(x) && isFinite(y)) { hoverAt(x, y, true); drawNow(); }
  }
  const bench = +q.get("bench") || 0;
  let info = NT + " printing moves · " + NTR + " travels · " +
    (LAYERS.length ? LAYERS.length + " layers · " : "no layer marks · ") +
    fmtTime(META.time) + " · " + NOTES.length + " notes" +
    (META.notes_dropped > 0 ? " (" + META.notes_dropped + " more left out)" : "") +
    " · profile " + META.profile;
  if (bench > 0) {
    // Frame times, waiting for the GPU after each: the still view, then turning (dragging)
    // with tubes and with lines.
    const time = () => {
      const t = performance.now();
      for (let k = 0; k < bench; k++) { cam.yaw += 0.05; drawNow(); gfx.finish(); }
      return (performance.now() - t) / bench;
    };
    const slow = slowRenderer;
    const still = time();
    dragging = true;
    slowRenderer = false;
    const turning = time();
    slowRenderer = true;
    const turningLines = time();
    dragging = false;
    slowRenderer = slow;
    drawNow();
    $("info").dataset.frameMs = still.toFixed(1);
    info += " · load " + document.body.dataset.loadMs + " ms (first frame " + firstMs.toFixed(0) +
      " ms) · frame " + still.toFixed(1) + " ms; turning " + turning.toFixed(1) + " ms, as lines " +
      turningLines.toFixed(1) + " ms";
  }
  $("info").textContent = info;
  document.body.dataset.ready = "1";
}

let drag = null, hoverTimer = 0;
canvas.addEventListener("contextmenu", e => e.preventDefault());
canvas.addEventListener("mousedown", e => {
  drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2 };
  dragging = true;
});
window.addEventListener("mouseup", () => { if (drag) { drag = null; dragging = false; requestDraw(); } });
window.addEventListener("mousemove", e => {
  if (!gfx) return;
  if (!drag) {
    // Point at a line: pick once the pointer rests (a pick draws the visible layers once).
    clearTimeout(hoverTimer);
    if (e.target !== canvas) return;
    const dpr = window.devicePixelRatio || 1, r = canvas.getBoundingClientRect();
    const x = (e.clientX - r.left) * dpr, y = (e.clientY - r.top) * dpr;
    hoverTimer = setTimeout(() => hoverAt(x, y), 40);
    return;
  }
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  drag.x = e.clientX; drag.y = e.clientY;
  if (drag.pan) {
    const k = cam.dist / 800;
    cam.pan[0] += dx * k; cam.pan[1] -= dy * k;
  } else {
    cam.yaw += dx * 0.01;
    cam.pitch = Math.max(-1.5, Math.min(1.5, cam.pitch + dy * 0.01));
  }
  requestDraw();
});
canvas.addEventListener("mouseleave", () => {
  clearTimeout(hoverTimer);
  if (hoverId >= 0) { hoverId = -1; showReadout(-1); if (!slowRenderer) requestDraw(); }
});
canvas.addEventListener("wheel", e => {
  e.preventDefault();
  cam.dist = Math.max(radius * 0.05, Math.min(radius * 50, cam.dist * Math.exp(e.deltaY * 0.001)));
  requestDraw();
}, { passive: false });
window.addEventListener("keydown", e => {
  if (e.key === "+" || e.key === "=") cam.dist = Math.max(radius * 0.05, cam.dist / 1.2);
  else if (e.key === "-") cam.dist = Math.min(radius * 50, cam.dist * 1.2);
  else return;
  requestDraw();
});
ui.mode.addEventListener("input", () => { setColourMode(ui.mode.value); requestDraw(); });
for (const el of [ui.travel, ui.notes, ui.lo, ui.hi]) el.addEventListener("input", requestDraw);
window.addEventListener("resize", requestDraw);
start();
