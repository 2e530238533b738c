"""The page template of a standalone episode export (:mod:`policies.recording.export`).

One HTML file with the episode data inline (``<script type="application/json" id="rodlab-data">``) and a small
canvas renderer: orthographic view of the rod, tip trail, target and obstacle outlines; drag to orbit, wheel to
zoom; play/pause, a timeline slider, speed and view presets; keys: space play/pause, arrows step. The page
requests nothing (no network, no side files), so it opens from ``file://``.
"""
from __future__ import annotations

PAGE = r"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src data:">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>__TITLE__</title>
<style>
html,body{margin:0;height:100%;font:13px system-ui,sans-serif;background:#f4f5f7;color:#222}
#wrap{display:flex;flex-direction:column;height:100%}
#view{flex:1;min-height:200px;position:relative}
#cv{width:100%;height:100%;display:block;cursor:grab;background:#ffffff}
#hud{position:absolute;left:8px;top:6px;pointer-events:none;white-space:pre;line-height:1.35;
  background:rgba(255,255,255,.8);padding:4px 6px;border-radius:4px}
#bar{display:flex;gap:8px;align-items:center;padding:6px 8px;background:#e8eaee;border-top:1px solid #ccd}
#frame{flex:1}
button,select{font:inherit}
#flabel{white-space:nowrap;min-width:6.5em}
#legend{color:#555}
</style></head>
<body><div id="wrap">
<div id="view"><canvas id="cv"></canvas><div id="hud"></div>
<div id="legend" style="position:absolute;right:8px;bottom:4px">rod: base dark &rarr; tip light &middot; orange: tip trail &middot; red: target &middot; grey: obstacles &middot; drag: orbit, wheel: zoom</div></div>
<div id="bar">
<button id="play" title="play / pause (space)">Play</button>
<input id="frame" type="range" min="0" max="0" step="1" value="0" title="timeline (arrow keys step)">
<span id="flabel"></span>
<label>speed <select id="speed" title="playback speed relative to simulated time">
<option value="0.25">0.25x</option><option value="0.5">0.5x</option><option value="1" selected>1x</option>
<option value="2">2x</option><option value="4">4x</option></select></label>
<label title="start again at the end"><input id="loop" type="checkbox" checked> loop</label>
<button id="v-iso" title="oblique view">iso</button><button id="v-front" title="look along +y (x-z plane)">front</button>
<button id="v-side" title="look along -x (y-z plane)">side</button><button id="v-top" title="look down -z">top</button>
</div></div>
<script type="application/json" id="rodlab-data">__DATA__</script>
<script>
"use strict";
(function () {
const D = JSON.parse(document.getElementById("rodlab-data").textContent);
function f32(b64) {
  if (b64 === null || b64 === undefined) return null;
  const s = atob(b64), u = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) u[i] = s.charCodeAt(i);
  return new Float32Array(u.buffer);
}
const S = D.n_frames, N = D.n_nodes, P = f32(D.positions), T = D.time, TG = f32(D.target);
// several rods: the edge from one rod's last node to the next rod's first joins them and is not drawn
const ROD0 = new Set((D.rod_offsets || [0, N]).slice(1, -1));
const OB = D.obstacles, MESH = (OB.meshes || []).map(m => ({v: f32(m.v), e: m.e}));
const cv = document.getElementById("cv"), ctx = cv.getContext("2d");
const slider = document.getElementById("frame"), playBtn = document.getElementById("play");
const hud = document.getElementById("hud"), flabel = document.getElementById("flabel");
slider.max = String(S - 1);
let frame = 0, playing = false, tPlay = 0, lastWall = 0, drawn = 0;
const cam = {az: 0, el: 0, zoom: 1};
// bounds of everything drawn: the fit of the default view
let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
function grow(x, y, z) { const p = [x, y, z]; for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], p[k]); hi[k] = Math.max(hi[k], p[k]); } }
for (let i = 0; i < P.length; i += 3) grow(P[i], P[i + 1], P[i + 2]);
if (TG) for (let i = 0; i < TG.length; i += 3) if (isFinite(TG[i])) grow(TG[i], TG[i + 1], TG[i + 2]);
const CTR = [0, 1, 2].map(k => 0.5 * (lo[k] + hi[k]));
const RAD = Math.max(0.05, 0.5 * Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2])) + 2 * D.rod_radius;
function preset(name) {
  const v = {iso: [-60, 22], front: [-90, 0], side: [0, 0], top: [-90, 90]}[name];
  cam.az = v[0] * Math.PI / 180; cam.el = v[1] * Math.PI / 180; cam.zoom = 1; draw();
}
function basis() {
  const ca = Math.cos(cam.az), sa = Math.sin(cam.az), ce = Math.cos(cam.el), se = Math.sin(cam.el);
  const e = [ce * ca, ce * sa, se], r = [-sa, ca, 0];
  const u = [e[1] * r[2] - e[2] * r[1], e[2] * r[0] - e[0] * r[2], e[0] * r[1] - e[1] * r[0]];
  return {e, r, u};
}
let B = basis(), W = 1, H = 1, SC = 1;
function proj(x, y, z) {
  const dx = x - CTR[0], dy = y - CTR[1], dz = z - CTR[2];
  return [W / 2 + SC * (dx * B.r[0] + dy * B.r[1] + dz * B.r[2]),
          H / 2 - SC * (dx * B.u[0] + dy * B.u[1] + dz * B.u[2]),
          dx * B.e[0] + dy * B.e[1] + dz * B.e[2]];
}
function line(a, b, w, col) {
  ctx.strokeStyle = col; ctx.lineWidth = w; ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke();
}
function quatRot(q, v) { // q = x y z w
  const [x, y, z, w] = q, tx = 2 * (y * v[2] - z * v[1]), ty = 2 * (z * v[0] - x * v[2]), tz = 2 * (x * v[1] - y * v[0]);
  return [v[0] + w * tx + (y * tz - z * ty), v[1] + w * ty + (z * tx - x * tz), v[2] + w * tz + (x * ty - y * tx)];
}
function drawObstacles() {
  const col = "rgba(110,115,130,0.45)", edge = "rgba(70,75,90,0.9)";
  ctx.lineCap = "round";
  for (const c of OB.capsules || []) {
    const a = proj(c[0], c[1], c[2]), b = proj(c[3], c[4], c[5]), w = Math.max(2, 2 * c[6] * SC);
    if (Math.hypot(b[0] - a[0], b[1] - a[1]) < 0.25 * w) { // seen end-on: a disc
      ctx.fillStyle = col; ctx.beginPath(); ctx.arc(a[0], a[1], w / 2, 0, 2 * Math.PI); ctx.fill();
    } else line(a, b, w, col);
  }
  for (const s of OB.spheres || []) {
    const a = proj(s[0], s[1], s[2]);
    ctx.fillStyle = col; ctx.beginPath(); ctx.arc(a[0], a[1], Math.max(2, s[3] * SC), 0, 2 * Math.PI); ctx.fill();
  }
  for (const bx of OB.boxes || []) {
    const q = bx.slice(6, 10), cs = [];
    for (let i = 0; i < 8; i++) {
      const v = quatRot(q, [(i & 1 ? 1 : -1) * bx[3], (i & 2 ? 1 : -1) * bx[4], (i & 4 ? 1 : -1) * bx[5]]);
      cs.push(proj(bx[0] + v[0], bx[1] + v[1], bx[2] + v[2]));
    }
    for (let i = 0; i < 8; i++) for (const bit of [1, 2, 4]) if (!(i & bit)) line(cs[i], cs[i | bit], 1.5, edge);
  }
  for (const m of MESH) {
    ctx.strokeStyle = edge; ctx.lineWidth = 1; ctx.beginPath();
    for (let k = 0; k < m.e.length; k += 2) {
      const i = 3 * m.e[k], j = 3 * m.e[k + 1];
      const a = proj(m.v[i], m.v[i + 1], m.v[i + 2]), b = proj(m.v[j], m.v[j + 1], m.v[j + 2]);
      ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]);
    }
    ctx.stroke();
  }
}
function axes() {
  const o = proj(0, 0, 0), L = 0.1;
  const cols = ["#d33", "#2a2", "#33d"], ends = [[L, 0, 0], [0, L, 0], [0, 0, L]];
  ctx.lineCap = "butt";
  for (let k = 0; k < 3; k++) line(o, proj(...ends[k]), 2, cols[k]);
}
function rodColor(t) { // base dark blue -> tip light teal
  const a = [24, 54, 140], b = [60, 190, 210];
  return "rgb(" + a.map((x, k) => Math.round(x + t * (b[k] - x))).join(",") + ")";
}
function draw() {
  const dpr = window.devicePixelRatio || 1, rect = cv.getBoundingClientRect();
  W = Math.max(1, Math.round(rect.width * dpr)); H = Math.max(1, Math.round(rect.height * dpr));
  if (cv.width !== W || cv.height !== H) { cv.width = W; cv.height = H; }
  B = basis(); SC = cam.zoom * 0.45 * Math.min(W, H) / RAD;
  ctx.setTransform(1, 0, 0, 1, 0, 0); ctx.fillStyle = "#ffffff"; ctx.fillRect(0, 0, W, H);
  axes(); drawObstacles();
  const base = frame * N * 3;
  // tip trail up to the current frame
  ctx.strokeStyle = "rgba(230,140,30,0.55)"; ctx.lineWidth = Math.max(1, 1.5 * dpr); ctx.lineJoin = "round"; ctx.beginPath();
  for (let k = 0; k <= frame; k++) {
    const i = (k * N + N - 1) * 3, p = proj(P[i], P[i + 1], P[i + 2]);
    if (k === 0) ctx.moveTo(p[0], p[1]); else ctx.lineTo(p[0], p[1]);
  }
  ctx.stroke();
  const w = Math.max(3 * dpr, 2 * D.rod_radius * SC);
  ctx.lineCap = "round";
  const pts = [];
  for (let n = 0; n < N; n++) pts.push(proj(P[base + 3 * n], P[base + 3 * n + 1], P[base + 3 * n + 2]));
  for (let n = 0; n + 1 < N; n++) if (!ROD0.has(n + 1)) line(pts[n], pts[n + 1], w, rodColor(n / Math.max(1, N - 2)));
  ctx.fillStyle = "#111"; ctx.fillRect(pts[0][0] - 4 * dpr, pts[0][1] - 4 * dpr, 8 * dpr, 8 * dpr);
  if (TG) {
    const i = 3 * frame;
    if (isFinite(TG[i])) {
      const p = proj(TG[i], TG[i + 1], TG[i + 2]);
      ctx.strokeStyle = "#d62728"; ctx.lineWidth = 2 * dpr; ctx.beginPath();
      ctx.arc(p[0], p[1], Math.max(4 * dpr, 0.03 * SC), 0, 2 * Math.PI); ctx.stroke();
      line([p[0] - 6 * dpr, p[1]], [p[0] + 6 * dpr, p[1]], 1.5 * dpr, "#d62728");
      line([p[0], p[1] - 6 * dpr], [p[0], p[1] + 6 * dpr], 1.5 * dpr, "#d62728");
    }
  }
  const t = T[frame];
  let txt = D.title + "\nframe " + frame + " / " + (S - 1) + "   t = " + t.toFixed(3) + " s";
  for (const [name, arr] of Object.entries(D.series)) {
    const v = arr[frame];
    txt += "\n" + name + " = " + (v === null ? "-" : Number(v).toPrecision(4));
  }
  hud.textContent = txt; flabel.textContent = "t = " + t.toFixed(2) + " s";
  drawn++; document.body.dataset.drawn = String(drawn); document.body.dataset.frame = String(frame);
}
function setFrame(k) {
  frame = Math.max(0, Math.min(S - 1, k | 0)); slider.value = String(frame); draw();
}
function setPlaying(on) {
  playing = on && S > 1; playBtn.textContent = playing ? "Pause" : "Play";
  if (playing) { if (frame >= S - 1) setFrame(0); tPlay = T[frame]; lastWall = performance.now(); requestAnimationFrame(tick); }
}
function tick(now) {
  if (!playing) return;
  const speed = Number(document.getElementById("speed").value);
  tPlay += Math.min(0.25, (now - lastWall) / 1000) * speed; lastWall = now;
  let k = frame;
  while (k + 1 < S && T[k + 1] <= tPlay) k++;
  if (k >= S - 1 && tPlay > T[S - 1]) {
    if (document.getElementById("loop").checked) { k = 0; tPlay = T[0]; } else { setFrame(S - 1); setPlaying(false); return; }
  }
  if (k !== frame) setFrame(k);
  requestAnimationFrame(tick);
}
slider.addEventListener("input", () => { setFrame(Number(slider.value)); tPlay = T[frame]; });
playBtn.addEventListener("click", () => setPlaying(!playing));
for (const v of ["iso", "front", "side", "top"]) document.getElementById("v-" + v).addEventListener("click", () => preset(v));
window.addEventListener("keydown", (ev) => {
  if (ev.target === slider && ev.key !== " ") return; // the slider handles its own arrow keys
  if (ev.key === " ") { ev.preventDefault(); setPlaying(!playing); }
  else if (ev.key === "ArrowRight") { setPlaying(false); setFrame(frame + 1); }
  else if (ev.key === "ArrowLeft") { setPlaying(false); setFrame(frame - 1); }
});
let drag = null;
cv.addEventListener("pointerdown", (ev) => { drag = [ev.clientX, ev.clientY]; cv.setPointerCapture(ev.pointerId); });
cv.addEventListener("pointerup", () => { drag = null; });
cv.addEventListener("pointermove", (ev) => {
  if (!drag) return;
  cam.az -= (ev.clientX - drag[0]) * 0.01;
  cam.el = Math.max(-1.55, Math.min(1.55, cam.el + (ev.clientY - drag[1]) * 0.01));
  drag = [ev.clientX, ev.clientY]; draw();
});
cv.addEventListener("wheel", (ev) => { ev.preventDefault(); cam.zoom *= Math.exp(-ev.deltaY * 0.001); draw(); }, {passive: false});
window.addEventListener("resize", draw);
window.rodlabExport = {nFrames: S, setFrame, getFrame: () => frame, setPlaying};
preset(D.planar ? "front" : "iso");
document.body.dataset.ready = "1";
})();
</script></body></html>
"""
