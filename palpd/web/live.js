// palpd live view: draws the daemon's snapshot and follows its server-sent events (no libraries).
"use strict";
const view = { status: null, estimate: null, probes: [], map: null, faults: [], tissue_size_mm: [60, 60] };
let mode = "p";  // "p": P(lump), "k": posterior mean stiffness
const MIN_CONTRAST = 0.3;  // a stiffness colour scale spans at least this fraction of the median: noise stays one colour
const canvas = document.getElementById("map"), ctx = canvas.getContext("2d");
const PURPLES = [[247, 244, 249], [212, 185, 218], [201, 148, 199], [223, 101, 176], [152, 0, 67], [63, 0, 125]];
const VIRIDIS = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];

function colour(stops, u) {
  u = Math.min(1, Math.max(0, u)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(u)), f = u - i;
  const c = stops[i].map((v, k) => Math.round(v + f * (stops[i + 1][k] - v)));
  return `rgb(${c[0]},${c[1]},${c[2]})`;
}

function frame() {
  const [w, h] = view.tissue_size_mm, margin = 5;
  const scale = Math.min((canvas.width - 20) / (w + 2 * margin), (canvas.height - 20) / (h + 2 * margin));
  const x0 = canvas.width / 2, y0 = canvas.height / 2;
  return { scale, px: (x) => x0 + x * scale, py: (y) => y0 - y * scale, w, h };
}

function stiffnessScale(values) {
  const sorted = values.filter((v) => v != null && isFinite(v)).sort((a, b) => a - b);
  if (!sorted.length) return [0, 1];
  const median = sorted[Math.floor(sorted.length / 2)];
  let lo = sorted[0], hi = sorted[sorted.length - 1];
  const span = Math.max(hi - lo, MIN_CONTRAST * median);
  const mid = (hi - lo) >= MIN_CONTRAST * median ? (lo + hi) / 2 : median;
  return [mid - span / 2, mid + span / 2];
}

function drawMap(f, kScale) {
  const m = view.map;
  if (!m) { canvas.dataset.mapCells = "0"; return; }
  const nx = m.xs_mm.length, ny = m.ys_mm.length;
  const dx = (m.xs_mm[nx - 1] - m.xs_mm[0]) / (nx - 1), dy = (m.ys_mm[ny - 1] - m.ys_mm[0]) / (ny - 1);
  const c = m.confidence;
  for (let r = 0; r < ny; r++) for (let q = 0; q < nx; q++) {
    const p = m.p_lump[r][q], k = m.stiffness_n_per_mm[r][q];
    ctx.fillStyle = mode === "p" ? colour(PURPLES, p) : colour(VIRIDIS, (k - kScale[0]) / (kScale[1] - kScale[0]));
    const x = f.px(m.xs_mm[q] - dx / 2), y = f.py(m.ys_mm[r] + dy / 2);
    ctx.fillRect(x, y, dx * f.scale + 1, dy * f.scale + 1);
    if (p > 1 - c && p < c) hatch(x, y, dx * f.scale + 1, dy * f.scale + 1);
  }
  canvas.dataset.mapCells = String(nx * ny);
  contour(f, m, 0.5);
}

function hatch(x, y, w, h) {
  ctx.save(); ctx.beginPath(); ctx.rect(x, y, w, h); ctx.clip();
  ctx.strokeStyle = "rgba(60,60,60,0.45)"; ctx.lineWidth = 1; ctx.beginPath();
  for (let s = -h; s < w; s += 5) { ctx.moveTo(x + s, y + h); ctx.lineTo(x + s + h, y); }
  ctx.stroke(); ctx.restore();
}

// Marching squares on P(lump): the learner's 50 % boundary.
function contour(f, m, level) {
  const nx = m.xs_mm.length, ny = m.ys_mm.length, P = m.p_lump;
  const lerp = (a, b, pa, pb) => a + (level - pa) / (pb - pa) * (b - a);
  ctx.strokeStyle = "#000"; ctx.lineWidth = 1.5; ctx.beginPath();
  for (let r = 0; r < ny - 1; r++) for (let q = 0; q < nx - 1; q++) {
    const x0 = m.xs_mm[q], x1 = m.xs_mm[q + 1], y0 = m.ys_mm[r], y1 = m.ys_mm[r + 1];
    const a = P[r][q], b = P[r][q + 1], cc = P[r + 1][q + 1], d = P[r + 1][q];
    const pts = [];
    if ((a > level) !== (b > level)) pts.push([lerp(x0, x1, a, b), y0]);
    if ((b > level) !== (cc > level)) pts.push([x1, lerp(y0, y1, b, cc)]);
    if ((cc > level) !== (d > level)) pts.push([lerp(x1, x0, cc, d), y1]);
    if ((d > level) !== (a > level)) pts.push([x0, lerp(y1, y0, d, a)]);
    for (let i = 0; i + 1 < pts.length; i += 2) {
      ctx.moveTo(f.px(pts[i][0]), f.py(pts[i][1])); ctx.lineTo(f.px(pts[i + 1][0]), f.py(pts[i + 1][1]));
    }
  }
  ctx.stroke();
}

function drawLumps(f) {
  const lumps = (view.estimate && view.estimate.lumps) || [];
  for (const lump of lumps) {
    const [cx, cy] = lump.center_mm;
    ctx.strokeStyle = "#d0009c"; ctx.lineWidth = 2.5; ctx.beginPath();
    lump.boundary_mm.forEach(([x, y], i) => (i ? ctx.lineTo(f.px(x), f.py(y)) : ctx.moveTo(f.px(x), f.py(y))));
    ctx.closePath(); ctx.stroke();
    // radius ± 1 sd: the boundary scaled about the centre (an ellipse's, or a lump's part on the tissue, as drawn)
    ctx.setLineDash([5, 4]); ctx.lineWidth = 1;
    const spread = lump.radius_sd_mm / Math.max(lump.radius_mm, 1e-9);
    for (const scale of [1 - spread, 1 + spread]) {
      if (scale <= 0) continue;
      ctx.beginPath();
      lump.boundary_mm.forEach(([x, y], i) => {
        const px = f.px(cx + (x - cx) * scale), py = f.py(cy + (y - cy) * scale);
        if (i) ctx.lineTo(px, py); else ctx.moveTo(px, py);
      });
      ctx.closePath(); ctx.stroke();
    }
    ctx.setLineDash([]);
    ctx.fillStyle = "rgba(208,0,156,0.35)"; ctx.beginPath();
    ctx.arc(f.px(cx), f.py(cy), Math.max(2, lump.center_sd_mm * f.scale), 0, 2 * Math.PI); ctx.fill();
    ctx.beginPath(); ctx.moveTo(f.px(cx) - 6, f.py(cy)); ctx.lineTo(f.px(cx) + 6, f.py(cy));
    ctx.moveTo(f.px(cx), f.py(cy) - 6); ctx.lineTo(f.px(cx), f.py(cy) + 6); ctx.stroke();
  }
  canvas.dataset.lumps = String(lumps.length);
  // tissue softer there (model none+soft:1 or circles:K+soft:1): no lump, dashed as the plot draws it
  const softs = (view.estimate && view.estimate.model && view.estimate.model.soft_regions) || [];
  ctx.strokeStyle = "#1f77b4"; ctx.lineWidth = 1.5; ctx.setLineDash([6, 4]);
  for (const soft of softs) {
    ctx.beginPath();
    soft.boundary_mm.forEach(([x, y], i) => (i ? ctx.lineTo(f.px(x), f.py(y)) : ctx.moveTo(f.px(x), f.py(y))));
    ctx.closePath(); ctx.stroke();
  }
  ctx.setLineDash([]);
}

function drawProbes(f, kScale) {
  ctx.font = "bold 11px sans-serif"; ctx.textBaseline = "bottom";
  view.probes.forEach((probe, order) => {
    const failed = probe.stiffness_n_per_mm == null;
    const [x, y] = failed ? probe.target_xy_mm : probe.xy_mm;
    const X = f.px(x), Y = f.py(y);
    if (failed) {
      ctx.strokeStyle = "#000"; ctx.lineWidth = 2; ctx.beginPath();
      ctx.moveTo(X - 4, Y - 4); ctx.lineTo(X + 4, Y + 4); ctx.moveTo(X - 4, Y + 4); ctx.lineTo(X + 4, Y - 4); ctx.stroke();
    } else {
      ctx.fillStyle = colour(VIRIDIS, (probe.stiffness_n_per_mm - kScale[0]) / (kScale[1] - kScale[0]));
      ctx.strokeStyle = "#000"; ctx.lineWidth = 0.8; ctx.beginPath(); ctx.arc(X, Y, 4, 0, 2 * Math.PI);
      ctx.fill(); ctx.stroke();
    }
    // a white halo: the number stays readable over the dark middle of a lump
    ctx.lineWidth = 3; ctx.strokeStyle = "#fff"; ctx.strokeText(String(order + 1), X + 4, Y - 3);
    ctx.fillStyle = "#000"; ctx.fillText(String(order + 1), X + 4, Y - 3);
  });
  // the learner's next probe: the daemon names one only when the learner chooses the probes (an active scan)
  const next = view.estimate && view.estimate.next_probe_mm;
  const ring = Boolean(next && view.status && view.status.state === "scanning");
  if (ring) {
    ctx.strokeStyle = "#0b6e4f"; ctx.lineWidth = 2; ctx.beginPath();
    ctx.arc(f.px(next[0]), f.py(next[1]), 7, 0, 2 * Math.PI); ctx.stroke();
  }
  canvas.dataset.nextProbe = ring ? "1" : "0";
  canvas.dataset.probes = String(view.probes.length);
}

// Tick marks every `step` mm (10 on a 60 mm tissue), from the origin out, so 0 is always one of them.
function tickValues(half) {
  const step = [1, 2, 5, 10, 20, 50, 100].find((s) => half / s <= 4) || 200;
  const ticks = [];
  for (let v = -Math.floor(half / step) * step; v <= half + 1e-9; v += step) ticks.push(v);
  return ticks;
}

// mm ticks along the tissue's bottom and left edges: where a probe or a lump is can be read off the map.
function drawTicks(f) {
  const xs = tickValues(f.w / 2), ys = tickValues(f.h / 2);
  const bottom = f.py(-f.h / 2), left = f.px(-f.w / 2);
  ctx.strokeStyle = "#555"; ctx.fillStyle = "#333"; ctx.lineWidth = 1; ctx.font = "10px sans-serif";
  ctx.beginPath();
  for (const x of xs) { ctx.moveTo(f.px(x), bottom); ctx.lineTo(f.px(x), bottom + 5); }
  for (const y of ys) { ctx.moveTo(left, f.py(y)); ctx.lineTo(left - 5, f.py(y)); }
  ctx.stroke();
  ctx.textAlign = "center"; ctx.textBaseline = "top";
  for (const x of xs) ctx.fillText(String(x), f.px(x), bottom + 6);
  ctx.textAlign = "right"; ctx.textBaseline = "middle";
  for (const y of ys) ctx.fillText(String(y), left - 7, f.py(y));
  ctx.textAlign = "left";
  canvas.dataset.ticksX = xs.join(","); canvas.dataset.ticksY = ys.join(",");
}

function draw() {
  const f = frame();
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const kValues = view.probes.map((p) => p.stiffness_n_per_mm);
  const kScale = stiffnessScale(mode === "k" && view.map ? view.map.stiffness_n_per_mm.flat().concat(kValues) : kValues);
  drawMap(f, kScale);
  ctx.strokeStyle = "#999"; ctx.setLineDash([3, 3]); ctx.lineWidth = 1;
  ctx.strokeRect(f.px(-f.w / 2), f.py(f.h / 2), f.w * f.scale, f.h * f.scale); ctx.setLineDash([]);
  drawTicks(f);
  ctx.fillStyle = "#555"; ctx.font = "11px sans-serif"; ctx.textBaseline = "top";
  ctx.fillText(`${f.w} × ${f.h} mm, ticks in mm (tissue frame: origin at the centre, x right, y up)`, 8, 4);
  drawLumps(f); drawProbes(f, kScale); drawColourbar(kScale);
}

function drawColourbar(kScale) {
  const bar = document.getElementById("colorbar"), b = bar.getContext("2d");
  for (let i = 0; i < bar.width; i++) {
    b.fillStyle = mode === "p" ? colour(PURPLES, i / bar.width) : colour(VIRIDIS, i / bar.width);
    b.fillRect(i, 0, 1, bar.height);
  }
  const [lo, hi] = mode === "p" ? [0, 1] : kScale;
  document.getElementById("mode-label").textContent = mode === "p" ? "P(lump)" : "stiffness (N/mm)";
  document.getElementById("scale-low").textContent = mode === "p" ? "0" : lo.toFixed(3);
  document.getElementById("scale-high").textContent = mode === "p" ? "1" : hi.toFixed(3);
}

function text(id, value) { document.getElementById(id).textContent = value; }

function list(id, items, empty) {
  const ul = document.getElementById(id);
  ul.replaceChildren(...(items.length ? items : [empty]).map((t) => {
    const li = document.createElement("li"); li.textContent = t; if (!items.length) li.className = "muted"; return li;
  }));
}

function panel() {
  const s = view.status;
  if (s) {
    const el = document.getElementById("state"); el.textContent = s.state; el.className = "state " + s.state;
    text("message", s.message); text("palpations", String(s.palpations)); text("session", s.session || "—");
    text("expected", s.expected_total ? ` of up to ${s.expected_total}` : "");
  }
  const e = view.estimate;
  text("ambiguous", e && e.ambiguous_area_mm2 != null ? `${e.ambiguous_area_mm2.toFixed(0)} mm²` : "—");
  const m = e && e.model;  // the hypothesis the evidence chose, and why it does not stand yet
  text("model", m ? `${m.chosen} (weight ${m.weight.toFixed(2)}${m.runner_up ? `, runner-up ${m.runner_up}` : ""})` : "—");
  const notYet = m && (m.undecided || m.boundary_doubt);  // the count first, then the boundary's tolerance
  text("undecided", notYet ? `not yet: ${notYet}` : "");
  list("lumps", ((e && e.lumps) || []).map((l, i) =>
    `lump ${i + 1}: centre (${l.center_mm[0].toFixed(1)}, ${l.center_mm[1].toFixed(1)}) ± ${l.center_sd_mm.toFixed(2)} mm, ` +
    `radius ${l.radius_mm.toFixed(1)} ± ${l.radius_sd_mm.toFixed(2)} mm` +
    (l.depth_mm != null ? `, top ${l.depth_mm.toFixed(1)} ± ${l.depth_sd_mm.toFixed(1)} mm deep` : "")).concat(((m && m.soft_regions) || []).map((r) =>
    `no lump: tissue ${r.softer}× softer around (${r.center_mm[0].toFixed(1)}, ${r.center_mm[1].toFixed(1)}), ` +
    `radius ${r.radius_mm.toFixed(1)} mm`)), e && e.points ? "no lump" : "none yet");
  list("faults", view.faults.map((x) => `${x.code}: ${x.message}`), "none");
  text("updated", new Date().toLocaleTimeString());
}

function render() { panel(); draw(); }

// ?snapshot=1: draw the state once and keep no stream open, so a headless browser's virtual time can run out
// (`chromium --headless --screenshot --virtual-time-budget=...`: an open event stream never lets it idle).
async function snapshotOnce() {
  const answer = await fetch("state" + location.search);
  Object.assign(view, await answer.json());
  text("connection", "(snapshot)"); render();
  document.body.dataset.ready = "1";
}

function connect() {
  const source = new EventSource("events" + location.search);
  source.addEventListener("open", () => text("connection", "(live)"));
  source.addEventListener("error", () => text("connection", "(reconnecting…)"));
  source.addEventListener("snapshot", (m) => { Object.assign(view, JSON.parse(m.data)); render(); });
  for (const key of ["status", "estimate", "probes", "map", "faults"]) {
    source.addEventListener(key, (m) => { view[key] = JSON.parse(m.data); render(); });
  }
}

document.getElementById("mode").addEventListener("click", (ev) => {
  mode = mode === "p" ? "k" : "p";
  ev.target.textContent = mode === "p" ? "show stiffness" : "show P(lump)";
  draw();
});
render();
if (new URLSearchParams(location.search).get("snapshot") === "1") snapshotOnce(); else connect();
