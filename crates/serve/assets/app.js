// gantry serve — the page. Plain JavaScript, no framework, no network but this server.
'use strict';

const $ = (id) => document.getElementById(id);
const state = {
  info: null,
  materials: [],
  current: null,      // material name shown (a corpus name, an upload, or edit:<id>)
  base: null,         // the material picked in the browser
  session: null,      // edit session state from the server
  light: { x: -0.35, y: 0.4 },
  exposure: 0,
  tab: 'view',
  polarLog: false,
  lastStop: null,
  space: 0,           // the trait set the sliders edit with (index into info.spaces)
};
// Measurements the browser tests read: slider input → sphere drawn, in ms.
window.gantry = { latencies: [], sphereDraws: 0, plots: {}, lastError: null, state };

async function api(path, options = {}) {
  const r = await fetch(path, options);
  if (!r.ok) {
    let msg = `${r.status} ${r.statusText}`;
    try { const j = await r.json(); msg = j.error || msg; } catch (_) { /* not JSON */ }
    const e = new Error(msg); e.status = r.status; throw e;
  }
  const type = r.headers.get('content-type') || '';
  if (type.includes('json')) return r.json();
  return r.blob();
}
const enc = encodeURIComponent;
const fmt = (v, d = 2) => (Math.abs(v) < 1e-3 && v !== 0 ? v.toExponential(1) : v.toFixed(d));

// ---------- drawing helpers ----------
async function drawBlob(canvas, blob) {
  const bmp = await createImageBitmap(blob);
  if (canvas.width !== bmp.width || canvas.height !== bmp.height) {
    canvas.width = bmp.width; canvas.height = bmp.height;
  }
  const ctx = canvas.getContext('2d');
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.drawImage(bmp, 0, 0);
  bmp.close();
}

// Coalesces requests: at most one in flight, the latest wanted one runs next.
function coalesced(run) {
  let busy = false, again = false;
  const go = async () => {
    if (busy) { again = true; return; }
    busy = true;
    try { await run(); } catch (e) { window.gantry.lastError = String(e); console.warn(e); }
    busy = false;
    if (again) { again = false; go(); }
  };
  return go;
}

// ---------- material browser ----------
let listGeneration = 0;
async function loadMaterials() {
  const gen = ++listGeneration;
  const params = new URLSearchParams();
  const q = $('search').value.trim();
  if (q) params.set('q', q);
  const t = $('filter-trait').value;
  if (t) {
    params.set('trait', t);
    const min = parseFloat($('filter-min').value);
    if (Number.isFinite(min)) params.set('min', String(min));
    if ($('sort-score').checked) params.set('sort', 'score');
  }
  const r = await api('/api/materials?' + params);
  if (gen !== listGeneration) return; // a newer query is on its way
  state.materials = r.materials;
  renderList(r.traits || []);
}

function renderList(traits) {
  const list = $('material-list');
  list.textContent = '';
  const t = $('filter-trait').value;
  const k = traits.indexOf(t);
  for (const m of state.materials) {
    const el = document.createElement('div');
    el.className = 'mat' + (m.name === state.base ? ' selected' : '');
    el.setAttribute('role', 'option');
    el.dataset.name = m.name;
    const img = document.createElement('img');
    img.loading = 'lazy';
    img.alt = '';
    img.src = `/api/materials/${enc(m.name)}/thumbnail.png`;
    const name = document.createElement('div');
    name.className = 'name'; name.textContent = m.name;
    el.append(img, name);
    if (m.origin !== 'corpus') {
      const o = document.createElement('div'); o.className = 'origin'; o.textContent = m.origin; el.append(o);
    }
    if (k >= 0 && m.scores) {
      const s = document.createElement('div'); s.className = 'score'; s.textContent = `${t} ${fmt(m.scores[k])}`; el.append(s);
    }
    el.addEventListener('click', () => pick(m.name));
    list.append(el);
  }
  if (!state.materials.length) {
    const e = document.createElement('div'); e.className = 'muted'; e.textContent = 'No material matches.'; list.append(e);
  }
  fillSelect($('compare-b'), true);
  fillSelect($('interp-other'), false);
}

function fillSelect(sel, keep) {
  const old = sel.value;
  sel.textContent = '';
  for (const m of allNames()) {
    const o = document.createElement('option'); o.value = m; o.textContent = m; sel.append(o);
  }
  if (keep && old && allNames().includes(old)) sel.value = old;
}
let everyName = [];
function allNames() { return everyName; }
async function loadAllNames() {
  const r = await api('/api/materials');
  everyName = r.materials.map((m) => m.name);
}

async function pick(name) {
  state.base = name;
  state.current = name;
  state.session = null;
  document.querySelectorAll('.mat').forEach((el) => el.classList.toggle('selected', el.dataset.name === name));
  $('current-title').textContent = name;
  setStop(null);
  await startEditing();
  if (state.base === name) refreshAll();
}

// ---------- lit sphere ----------
let pendingInputs = [];
const refreshSphere = coalesced(async () => {
  if (!state.current) return;
  const inputs = pendingInputs; pendingInputs = [];
  const q = `size=256&lx=${state.light.x.toFixed(4)}&ly=${state.light.y.toFixed(4)}&exposure=${state.exposure}`;
  const url = state.session
    ? `/api/sessions/${state.session.id}/sphere.png?${q}`
    : `/api/materials/${enc(state.current)}/sphere.png?${q}`;
  const t0 = performance.now();
  const blob = await api(url);
  await drawBlob($('sphere'), blob);
  const now = performance.now();
  for (const t of inputs) window.gantry.latencies.push(now - t);
  window.gantry.sphereDraws++;
  $('sphere-time').textContent = `${Math.round(now - t0)} ms`;
  const l = state.light;
  const z = Math.sqrt(Math.max(0, 1 - l.x * l.x - l.y * l.y));
  $('light-out').textContent = `light (${l.x.toFixed(2)}, ${l.y.toFixed(2)}, ${z.toFixed(2)})`;
  updateExports();
});

function setupSphereDrag() {
  const c = $('sphere');
  let down = false;
  const move = (ev) => {
    const r = c.getBoundingClientRect();
    let x = ((ev.clientX - r.left) / r.width) * 2 - 1;
    let y = 1 - ((ev.clientY - r.top) / r.height) * 2;
    const n = Math.hypot(x, y);
    if (n > 0.995) { x *= 0.995 / n; y *= 0.995 / n; }
    state.light = { x, y };
    refreshSphere();
  };
  c.addEventListener('pointerdown', (ev) => { down = true; c.setPointerCapture(ev.pointerId); move(ev); });
  c.addEventListener('pointermove', (ev) => { if (down) move(ev); });
  c.addEventListener('pointerup', () => { down = false; refreshCompare(); });
  $('exposure').addEventListener('input', () => {
    state.exposure = parseFloat($('exposure').value);
    $('exposure-out').textContent = `${state.exposure > 0 ? '+' : ''}${state.exposure} EV`;
    refreshSphere();
  });
}

// ---------- environment map (progressive) ----------
let envGeneration = 0;
let envAbort = null;
async function refreshEnv() {
  if (!state.current || state.tab !== 'view') return;
  const gen = ++envGeneration;
  if (envAbort) envAbort.abort();
  envAbort = new AbortController();
  const shape = $('env-shape').value;
  const exposure = $('env-exposure').value;
  const passes = [1, 4, 16, 32];
  const started = performance.now();
  for (let i = 0; i < passes.length; i++) {
    const url = `/api/materials/${enc(state.current)}/environment.png?shape=${shape}&size=224&spp=${passes[i]}&seed=${i + 1}&exposure=${exposure}`;
    $('env-progress').textContent = `rendering pass ${i + 1}/${passes.length} (${passes[i]} samples per pixel)…`;
    let blob;
    try { blob = await api(url, { signal: envAbort.signal }); } catch (e) {
      if (gen === envGeneration && e.name !== 'AbortError') $('env-progress').textContent = e.message;
      return;
    }
    if (gen !== envGeneration) return;
    await drawBlob($('envmap'), blob);
    const secs = ((performance.now() - started) / 1000).toFixed(1);
    $('env-progress').textContent = `pass ${i + 1}/${passes.length}: ${passes[i]} samples per pixel, path traced (${secs} s)`;
  }
}

// ---------- plots ----------
const CH = ['#d64541', '#2e9d57', '#2f6fde'];
const CHN = ['R', 'G', 'B'];

// Records a finished plot (which material, how many draws so far) for tests and tools.
function plotted(id, material) {
  const p = window.gantry.plots[id] || { draws: 0 };
  window.gantry.plots[id] = { draws: p.draws + 1, material, log: state.polarLog };
}

function axisFont(ctx) { ctx.font = '11px system-ui, sans-serif'; ctx.fillStyle = '#6b7280'; ctx.strokeStyle = '#e3e5ea'; }

async function refreshPolar() {
  if (!state.current) return;
  const material = state.current;
  const ti = parseFloat($('theta-i').value);
  const d = await api(`/api/materials/${enc(state.current)}/incidence?theta_i=${ti}&n=361`);
  const c = $('polar'), ctx = c.getContext('2d');
  const W = c.width, H = c.height, cx = W / 2, cy = H - 28, R = Math.min(W / 2 - 40, H - 50);
  ctx.clearRect(0, 0, W, H);
  let max = 0, minPos = Infinity;
  for (const v of d.rgb) for (const x of v) { max = Math.max(max, x); if (x > 0) minPos = Math.min(minPos, x); }
  if (max <= 0) max = 1;
  const decades = 4;
  const lo = Math.log10(max) - decades;
  const radius = (v) => {
    if (state.polarLog) return v > 0 ? Math.max(0, (Math.log10(v) - lo) / decades) * R : 0;
    return (v / max) * R;
  };
  axisFont(ctx);
  // Rings with their values.
  ctx.lineWidth = 1;
  for (let k = 1; k <= 4; k++) {
    const r = (k / 4) * R;
    ctx.beginPath(); ctx.arc(cx, cy, r, Math.PI, 2 * Math.PI); ctx.stroke();
    const val = state.polarLog ? Math.pow(10, lo + (k / 4) * decades) : (k / 4) * max;
    ctx.fillText(fmt(val, val < 10 ? 2 : 0), cx + 3, cy - r - 2);
  }
  // Spokes every 30°.
  for (let a = -90; a <= 90; a += 30) {
    const t = (a * Math.PI) / 180;
    ctx.beginPath(); ctx.moveTo(cx, cy); ctx.lineTo(cx + R * Math.sin(t), cy - R * Math.cos(t)); ctx.stroke();
    ctx.textAlign = 'center';
    ctx.fillText(`${a}°`, cx + (R + 14) * Math.sin(t), cy - (R + 14) * Math.cos(t) + 4);
  }
  ctx.textAlign = 'left';
  // Incident and mirror directions.
  const tir = (ti * Math.PI) / 180;
  ctx.strokeStyle = '#e0a030'; ctx.lineWidth = 2;
  ctx.beginPath(); ctx.moveTo(cx - R * Math.sin(tir), cy - R * Math.cos(tir)); ctx.lineTo(cx, cy); ctx.stroke();
  ctx.fillStyle = '#e0a030'; ctx.fillText('light', cx - (R + 4) * Math.sin(tir) - 28, cy - (R + 4) * Math.cos(tir));
  ctx.setLineDash([4, 4]); ctx.strokeStyle = '#9aa3b2'; ctx.lineWidth = 1;
  ctx.beginPath(); ctx.moveTo(cx, cy); ctx.lineTo(cx + R * Math.sin(tir), cy - R * Math.cos(tir)); ctx.stroke();
  ctx.setLineDash([]);
  // Curves.
  for (let ch = 0; ch < 3; ch++) {
    ctx.strokeStyle = CH[ch]; ctx.lineWidth = 1.8; ctx.beginPath();
    d.theta_o_deg.forEach((a, i) => {
      const t = (a * Math.PI) / 180, r = radius(d.rgb[i][ch]);
      const x = cx + r * Math.sin(t), y = cy - r * Math.cos(t);
      if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
    });
    ctx.stroke();
  }
  ctx.strokeStyle = '#1f2430'; ctx.lineWidth = 1.5;
  ctx.beginPath(); ctx.moveTo(cx - R - 6, cy); ctx.lineTo(cx + R + 6, cy); ctx.stroke();
  // Legend.
  ctx.font = '11.5px system-ui, sans-serif';
  CHN.forEach((n, i) => { ctx.fillStyle = CH[i]; ctx.fillRect(10, 10 + i * 16, 14, 3); ctx.fillStyle = '#3b4252'; ctx.fillText(n, 28, 15 + i * 16); });
  ctx.fillStyle = '#6b7280';
  ctx.fillText(`f (1/sr), ${state.polarLog ? 'log, 4 decades' : 'linear'}; peak ${fmt(max)}`, 10, H - 8);
  ctx.textAlign = 'right'; ctx.fillText('θo, dashed: mirror direction', W - 10, H - 8); ctx.textAlign = 'left';
  plotted('polar', material);
}

// Perceptual ramp (dark blue → purple → orange → pale yellow), t in [0, 1].
const RAMP = [[13, 8, 26], [64, 26, 115], [178, 51, 102], [250, 140, 38], [252, 242, 153]];
function ramp(t) {
  t = Math.min(1, Math.max(0, t)) * (RAMP.length - 1);
  const i = Math.min(RAMP.length - 2, Math.floor(t)), f = t - i;
  return RAMP[i].map((a, k) => Math.round(a * (1 - f) + RAMP[i + 1][k] * f));
}

async function refreshSlice() {
  if (!state.current) return;
  const material = state.current;
  const phi = parseFloat($('phi-d').value);
  const d = await api(`/api/materials/${enc(state.current)}/slice?phi_d=${phi}`);
  const nh = d.theta_h_deg.length, nd = d.theta_d_deg.length;
  const lum = d.rgb.map((p) => Math.log10((p[0] + p[1] + p[2]) / 3 + 1e-4));
  let lo = Infinity, hi = -Infinity;
  for (const v of lum) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (hi - lo < 1e-6) hi = lo + 1;
  const off = document.createElement('canvas'); off.width = nh; off.height = nd;
  const octx = off.getContext('2d'), img = octx.createImageData(nh, nd);
  for (let j = 0; j < nd; j++) for (let i = 0; i < nh; i++) {
    const rgb = ramp((lum[j * nh + i] - lo) / (hi - lo));
    const p = ((nd - 1 - j) * nh + i) * 4; // θd grows upwards
    img.data[p] = rgb[0]; img.data[p + 1] = rgb[1]; img.data[p + 2] = rgb[2]; img.data[p + 3] = 255;
  }
  octx.putImageData(img, 0, 0);
  const c = $('slice'), ctx = c.getContext('2d');
  const L = 44, T = 10, S = Math.min(c.width - L - 70, c.height - 50);
  ctx.clearRect(0, 0, c.width, c.height);
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(off, L, T, S, S);
  axisFont(ctx);
  ctx.textAlign = 'center';
  for (const deg of [0, 2, 10, 25, 50, 90]) { // columns on the MERL grid's square-root spacing
    const x = L + Math.sqrt(deg / 90) * S;
    ctx.fillText(`${deg}°`, x, T + S + 14);
    ctx.beginPath(); ctx.moveTo(x, T + S); ctx.lineTo(x, T + S + 4); ctx.stroke();
  }
  ctx.fillText('θh (square-root axis)', L + S / 2, T + S + 30);
  ctx.textAlign = 'right';
  for (const deg of [0, 30, 60, 90]) ctx.fillText(`${deg}°`, L - 6, T + S - (deg / 90) * S + 4);
  ctx.save(); ctx.translate(12, T + S / 2); ctx.rotate(-Math.PI / 2); ctx.textAlign = 'center'; ctx.fillText('θd', 0, 0); ctx.restore();
  // Colour bar.
  const bx = L + S + 16, bw = 12;
  for (let y = 0; y < S; y++) { const rgb = ramp(1 - y / S); ctx.fillStyle = `rgb(${rgb})`; ctx.fillRect(bx, T + y, bw, 1); }
  axisFont(ctx); ctx.textAlign = 'left';
  for (let k = 0; k <= 4; k++) {
    const v = hi - (k / 4) * (hi - lo);
    ctx.fillText(fmt(Math.pow(10, v)), bx + bw + 4, T + (k / 4) * S + 4);
  }
  ctx.fillText('1/sr', bx, T + S + 14);
  plotted('slice', material);
}

async function refreshAlbedo() {
  if (!state.current) return;
  const material = state.current;
  const d = await api(`/api/materials/${enc(state.current)}/albedo`);
  const c = $('albedo'), ctx = c.getContext('2d');
  const W = c.width, H = c.height, L = 44, R = 14, T = 14, B = 40;
  ctx.clearRect(0, 0, W, H);
  let ymax = 1.1;
  for (const v of d.albedo) for (const x of v) ymax = Math.max(ymax, x * 1.05);
  const X = (t) => L + (t / 90) * (W - L - R), Y = (v) => T + (1 - v / ymax) * (H - T - B);
  axisFont(ctx);
  ctx.textAlign = 'right';
  const step = ymax > 2.5 ? 0.5 : 0.2;
  for (let v = 0; v <= ymax + 1e-9; v += step) {
    ctx.beginPath(); ctx.moveTo(L, Y(v)); ctx.lineTo(W - R, Y(v)); ctx.stroke();
    ctx.fillText(v.toFixed(1), L - 6, Y(v) + 4);
  }
  ctx.textAlign = 'center';
  for (let t = 0; t <= 90; t += 15) ctx.fillText(`${t}°`, X(t), H - B + 16);
  ctx.fillText('θi', L + (W - L - R) / 2, H - 8);
  // The albedo = 1 line.
  ctx.strokeStyle = '#b42318'; ctx.setLineDash([6, 4]); ctx.lineWidth = 1.4;
  ctx.beginPath(); ctx.moveTo(L, Y(1)); ctx.lineTo(W - R, Y(1)); ctx.stroke(); ctx.setLineDash([]);
  ctx.fillStyle = '#b42318'; ctx.textAlign = 'right'; ctx.fillText('albedo = 1', W - R - 4, Y(1) - 5);
  for (let ch = 0; ch < 3; ch++) {
    ctx.strokeStyle = CH[ch]; ctx.fillStyle = CH[ch]; ctx.lineWidth = 1.8; ctx.beginPath();
    d.theta_i_deg.forEach((t, i) => { const x = X(t), y = Y(d.albedo[i][ch]); if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y); });
    ctx.stroke();
    d.theta_i_deg.forEach((t, i) => { ctx.beginPath(); ctx.arc(X(t), Y(d.albedo[i][ch]), 2.2, 0, 7); ctx.fill(); });
  }
  ctx.textAlign = 'left'; ctx.font = '11.5px system-ui, sans-serif';
  CHN.forEach((n, i) => { ctx.fillStyle = CH[i]; ctx.fillRect(L + 10 + i * 34, T + 6, 14, 3); ctx.fillStyle = '#3b4252'; ctx.fillText(n, L + 28 + i * 34, T + 11); });
  plotted('albedo', material);
}

// ---------- compare ----------
const refreshCompare = coalesced(async () => {
  if (!state.current || state.tab !== 'compare') return;
  const b = $('compare-b').value;
  if (!b) return;
  $('compare-a').textContent = state.current;
  $('cap-a').textContent = `A: ${state.current}`;
  $('cap-b').textContent = `B: ${b}`;
  const l = `lx=${state.light.x.toFixed(4)}&ly=${state.light.y.toFixed(4)}`;
  const q = `a=${enc(state.current)}&b=${enc(b)}&size=256&${l}`;
  const [ia, ib, id, stats] = await Promise.all([
    api(`/api/materials/${enc(state.current)}/sphere.png?size=256&${l}&exposure=${state.exposure}`),
    api(`/api/materials/${enc(b)}/sphere.png?size=256&${l}&exposure=${state.exposure}`),
    api(`/api/compare/difference.png?${q}`),
    api(`/api/compare?${q}`),
  ]);
  await Promise.all([drawBlob($('cmp-a'), ia), drawBlob($('cmp-b'), ib), drawBlob($('cmp-d'), id)]);
  const s = stats.comparison;
  $('compare-stats').textContent =
    `${state.current} vs ${b}: RMS log-radiance difference ${fmt(s.rms_log, 3)} · relative RMS ${(100 * s.relative).toFixed(1)} % · largest |A − B| ${fmt(s.max_abs, 3)}`;
});

// ---------- editing ----------
const CHECKS = [
  ['non-negativity', 'non-negativity', 'f ≥ 0 in every bin'],
  ['reciprocity', 'reciprocity', 'f(ωi, ωo) = f(ωo, ωi)'],
  ['energy-conservation', 'energy conservation', 'albedo ≤ 1 at every θi'],
];

async function startEditing() {
  $('stop-message').textContent = '';
  if (!state.info.editing) {
    $('editor-off').textContent = state.info.preparation.state === 'unavailable'
      ? 'Editing needs a model and a trait set: gantry serve --model model.bin --traits traits.json' : '';
    $('editor-off').hidden = false; $('editor-on').hidden = true; updateExports(); return;
  }
  // A material picked while this session was being opened supersedes it: its answer is dropped.
  const base = state.base;
  try {
    const session = await api('/api/sessions', {
      method: 'POST', headers: { 'content-type': 'application/json' },
      body: JSON.stringify({ material: base, space: state.space }),
    });
    if (state.base !== base) return;
    state.session = session;
    state.current = state.session.material;
    state.lastStop = null;
    $('editor-off').hidden = true; $('editor-on').hidden = false;
    buildSliders();
    renderSession();
  } catch (e) {
    if (state.base !== base) return;
    state.session = null;
    $('editor-off').hidden = false; $('editor-on').hidden = true;
    $('editor-off').textContent = `Cannot edit ${state.base}: ${e.message}`;
  }
  updateExports();
}

function sliderRange(score) {
  return [Math.min(-1.5, Math.floor(score - 2)), Math.max(2.5, Math.ceil(score + 2))];
}

function buildSliders() {
  const box = $('sliders');
  box.textContent = '';
  const sp = state.info.spaces[state.space];
  state.session.traits.forEach((t, k) => {
    const cv = sp.traits[k].cross_validated;
    const score = state.session.scores[k];
    const [lo, hi] = sliderRange(score);
    const wrap = document.createElement('div');
    wrap.className = 'slider'; wrap.dataset.trait = t;
    wrap.innerHTML = `<div class="head"><label for="slider-${k}">${t}${cv != null ? `<span class="cv" title="${sp.method === 'ridge' ? 'leave-one-out Spearman ρ with the human ratings' : 'leave-one-out accuracy of the sign of the score'}">${sp.method === 'ridge' ? `ρ ${cv.toFixed(2)}` : `agreement ${(100 * cv).toFixed(0)} %`}</span>` : ''}</label><span class="val" id="slider-${k}-val"></span></div>
      <input id="slider-${k}" type="range" min="${lo}" max="${hi}" step="0.01" value="${score}" aria-label="${t} score">`;
    box.append(wrap);
    const input = wrap.querySelector('input');
    input.addEventListener('input', (ev) => {
      pendingInputs.push(performance.now());
      const target = parseFloat(input.value);
      predictOnGpu(k, target, ev.timeStamp);
      wanted.set(t, target); sendNudges();
    });
    input.addEventListener('change', () => { afterEdit(); });
  });
}

// In the linear space a step moves the coefficients by (target − score) · w/‖w‖²: the real-time
// view draws that at once; the server's answer (which may stop the step at a validity check)
// replaces it.
function predictOnGpu(k, target, at) {
  const g = window.gantry;
  if (!g.gpuShow || !state.session || !state.session.coefficients) return;
  const step = state.info.spaces[state.space].traits[k].unit_step;
  if (g.gpuInput) g.gpuInput(at);
  if (!step) return;
  const amount = target - state.session.scores[k];
  g.gpuShow(state.session.material, state.session.coefficients.map((c, j) => c + amount * (step[j] || 0)), true);
}

const wanted = new Map();
const sendNudges = coalesced(async () => {
  window.gantry.editing = true;
  try { await nudgeLoop(); } finally { window.gantry.editing = wanted.size > 0; }
});
async function nudgeLoop() {
  while (wanted.size) {
    const [t, target] = wanted.entries().next().value;
    wanted.delete(t);
    const r = await api(`/api/sessions/${state.session.id}/nudge`, {
      method: 'POST', headers: { 'content-type': 'application/json' },
      body: JSON.stringify({ trait: t, target }),
    });
    state.session = r.state;
    showOnGpu();
    state.lastStop = r.stopped_by ? { trait: t, check: r.stopped_by, message: r.message } : null;
    setStop(state.lastStop);
    renderSession(t);
    await refreshSphere();
  }
}

function setStop(s) {
  const m = $('stop-message');
  m.className = 'message' + (s ? ' stop' : '');
  m.textContent = s ? `${s.trait}: ${s.message}` : '';
  document.querySelectorAll('.slider').forEach((el) => el.classList.toggle('stopped', !!s && el.dataset.trait === s.trait));
  renderChecks();
}

function renderChecks() {
  const ul = $('checks');
  ul.textContent = '';
  const stop = state.lastStop && state.lastStop.check;
  for (const [key, name, what] of CHECKS) {
    const li = document.createElement('li');
    const stopper = stop === key;
    li.className = stopper ? 'stopper' : 'pass';
    li.dataset.check = key;
    li.innerHTML = `<span title="${what}">${name}</span><span class="st">${stopper ? 'stopped the last step' : '✓ holds'}</span>`;
    ul.append(li);
  }
}

function renderSession(dragging) {
  const s = state.session;
  if (!s) return;
  s.traits.forEach((t, k) => {
    const input = $(`slider-${k}`);
    if (!input) return;
    const v = s.scores[k];
    if (t !== dragging || state.lastStop) {
      if (v < parseFloat(input.min)) input.min = Math.floor(v - 1);
      if (v > parseFloat(input.max)) input.max = Math.ceil(v + 1);
      input.value = v;
    }
    $(`slider-${k}-val`).textContent = fmt(v);
  });
  $('undo').disabled = !s.undo;
  $('redo').disabled = !s.redo;
  const h = $('history');
  h.textContent = '';
  for (const [t, a] of s.edits) {
    const li = document.createElement('li');
    li.textContent = t.startsWith('interpolate:') ? `toward ${t.slice(12)} (${(100 * a).toFixed(0)} % of the step)` : `${t} ${a >= 0 ? '+' : ''}${fmt(a)}`;
    h.append(li);
  }
  if (!s.edits.length) { const li = document.createElement('li'); li.className = 'muted'; li.textContent = `start: ${s.start}`; h.append(li); }
  $('current-title').textContent = s.edits.length ? `${s.start} (edited, ${s.edits.length} step${s.edits.length > 1 ? 's' : ''})` : s.start;
  renderChecks();
  updateExports();
}

function afterEdit() { refreshOthers(); }

async function historyStep(which) {
  if (!state.session) return;
  state.session = await api(`/api/sessions/${state.session.id}/${which}`, { method: 'POST' });
  state.lastStop = null; setStop(null);
  renderSession();
  refreshAll();
}

const sendInterp = coalesced(async () => {
  if (!state.session) return;
  const t = parseFloat($('interp-t').value);
  const r = await api(`/api/sessions/${state.session.id}/interpolate`, {
    method: 'POST', headers: { 'content-type': 'application/json' },
    body: JSON.stringify({ other: $('interp-other').value, t }),
  });
  state.session = r.state;
  showOnGpu();
  state.lastStop = r.stopped_by ? { trait: 'interpolation', check: r.stopped_by, message: r.message } : null;
  setStop(state.lastStop);
  renderSession();
  await refreshSphere();
});

function updateExports() {
  const name = state.current;
  const b = $('export-binary'), r = $('export-bsdf'), s = $('export-spec'), p = $('export-png');
  const l = `lx=${state.light.x.toFixed(4)}&ly=${state.light.y.toFixed(4)}&exposure=${state.exposure}`;
  if (!name) { [b, r, s, p].forEach((a) => a.setAttribute('aria-disabled', 'true')); return; }
  [b, r, p].forEach((a) => a.removeAttribute('aria-disabled'));
  b.href = `/api/materials/${enc(name)}/export.binary`;
  r.href = `/api/materials/${enc(name)}/export.bsdf`;
  const file = name.replace(':', '-');
  b.download = `${file}.binary`;
  r.download = `${file}.bsdf`;
  p.href = state.session ? `/api/sessions/${state.session.id}/sphere.png?size=512&${l}` : `/api/materials/${enc(name)}/sphere.png?size=512&${l}`;
  p.download = `${file}.png`;
  if (state.session) { s.removeAttribute('aria-disabled'); s.href = `/api/sessions/${state.session.id}/spec.json`; s.download = `${file}.json`; } else s.setAttribute('aria-disabled', 'true');
}

// ---------- uploads ----------
async function uploadFile(file) {
  const msg = $('upload-message');
  msg.className = 'message'; msg.textContent = `reading ${file.name}…`;
  try {
    const r = await api(`/api/uploads?name=${enc(file.name)}`, { method: 'POST', headers: { 'content-type': 'application/octet-stream' }, body: file });
    msg.className = 'message ok'; msg.textContent = `opened ${file.name} as ${r.name}`;
    await loadAllNames();
    await loadMaterials();
    await pick(r.name);
  } catch (e) {
    msg.className = 'message error';
    msg.textContent = `${file.name}: ${e.message}`;
  }
}

function setupDrop() {
  const z = $('drop-zone');
  const over = (on) => (ev) => { ev.preventDefault(); z.classList.toggle('over', on); };
  z.addEventListener('dragenter', over(true));
  z.addEventListener('dragover', over(true));
  z.addEventListener('dragleave', over(false));
  z.addEventListener('drop', (ev) => { over(false)(ev); const f = ev.dataTransfer.files[0]; if (f) uploadFile(f); });
  document.addEventListener('dragover', (ev) => ev.preventDefault());
  document.addEventListener('drop', (ev) => { ev.preventDefault(); const f = ev.dataTransfer && ev.dataTransfer.files[0]; if (f && !z.contains(ev.target)) uploadFile(f); });
  $('file-input').addEventListener('change', (ev) => { const f = ev.target.files[0]; if (f) uploadFile(f); ev.target.value = ''; });
}

// ---------- orchestration ----------
function refreshOthers() {
  if (state.tab === 'view') refreshEnv();
  if (state.tab === 'plots') { refreshPolar(); refreshSlice(); refreshAlbedo(); }
  if (state.tab === 'compare') refreshCompare();
}
function refreshAll() { refreshSphere(); refreshOthers(); showOnGpu(); }
// The real-time view (gpu.js) draws the current material from its model coefficients.
function showOnGpu() {
  if (!window.gantry.gpuShow || !state.current) return;
  window.gantry.gpuShow(state.current, state.session ? state.session.coefficients : null);
}

// ---------- editing out of the box ----------
const spaceLabel = (s) => `${s.method === 'ridge' ? 'human ratings' : `thesis traits (${s.method})`} · ${s.space} ${s.dim}-D · ${s.traits.length}`;

// The status line, the trait filter, the trait-set choice and the build offer, from state.info.
function showEditingInfo() {
  const i = state.info;
  const p = i.preparation;
  $('server-status').textContent = `${i.materials} materials · ${i.editing
    ? `model of ${i.model_components} components, ${i.spaces.map((s) => `${s.traits.length} traits (${s.space})`).join(', ')}`
    : (p.state === 'running' ? 'preparing editing' : 'viewing only (no model)')}`;
  const ft = $('filter-trait');
  if (ft.options.length <= 1 && i.spaces.length) {
    for (const t of i.spaces[0].traits) { const o = document.createElement('option'); o.value = t.name; o.textContent = t.name; ft.append(o); }
  }
  ft.disabled = !i.spaces.length;
  const sel = $('edit-space');
  if (sel.options.length !== i.spaces.length) {
    sel.textContent = '';
    i.spaces.forEach((s, k) => { const o = document.createElement('option'); o.value = k; o.textContent = spaceLabel(s); sel.append(o); });
  }
  $('space-row').hidden = i.spaces.length < 2;
  const box = $('prepare');
  box.hidden = i.editing || p.state === 'unavailable';
  const msg = p.message.charAt(0).toUpperCase() + p.message.slice(1);
  $('prepare-message').textContent = p.state === 'running'
    ? `Preparing editing: ${p.message}… ${Math.round(p.elapsed_s || 0)} s` : `${msg}.`;
  $('prepare-build').hidden = p.state === 'running';
}

async function buildEditing() {
  $('prepare-build').disabled = true;
  try {
    state.info.preparation = await api('/api/editing/prepare', { method: 'POST' });
    showEditingInfo();
    await pollPreparation();
  } catch (e) {
    $('prepare-message').textContent = `Cannot build: ${e.message}`;
  } finally { $('prepare-build').disabled = false; }
}

// Follows a running preparation; when editing becomes possible, the editor opens on the
// material shown.
async function pollPreparation() {
  for (;;) {
    state.info = await api('/api/info');
    showEditingInfo();
    if (state.info.editing) { if (state.base) await startEditing(); return; }
    if (state.info.preparation.state !== 'running') return;
    await new Promise((r) => setTimeout(r, 1000));
  }
}

function setupTabs() {
  document.querySelectorAll('.tab').forEach((b) => b.addEventListener('click', () => {
    state.tab = b.dataset.tab;
    document.querySelectorAll('.tab').forEach((x) => x.classList.toggle('active', x === b));
    document.querySelectorAll('.tab-panel').forEach((p) => p.classList.toggle('active', p.id === `tab-${state.tab}`));
    refreshOthers();
  }));
}

async function main() {
  state.info = await api('/api/info');
  const i = state.info;
  showEditingInfo();
  $('env-name').textContent = `— ${i.environment}`;
  $('prepare-build').addEventListener('click', buildEditing);
  $('edit-space').addEventListener('change', () => { state.space = parseInt($('edit-space').value, 10); startEditing(); });
  setupTabs(); setupSphereDrag(); setupDrop();
  let searchTimer = null;
  $('search').addEventListener('input', () => { clearTimeout(searchTimer); searchTimer = setTimeout(loadMaterials, 150); });
  for (const id of ['filter-trait', 'filter-min', 'sort-score']) $(id).addEventListener('change', loadMaterials);
  $('theta-i').addEventListener('input', () => { $('theta-i-out').textContent = `${$('theta-i').value}°`; refreshPolar(); });
  $('phi-d').addEventListener('input', () => { $('phi-d-out').textContent = `${$('phi-d').value}°`; refreshSlice(); });
  $('polar-linear').addEventListener('click', () => { state.polarLog = false; $('polar-linear').classList.add('active'); $('polar-log').classList.remove('active'); refreshPolar(); });
  $('polar-log').addEventListener('click', () => { state.polarLog = true; $('polar-log').classList.add('active'); $('polar-linear').classList.remove('active'); refreshPolar(); });
  $('env-shape').addEventListener('change', refreshEnv);
  $('env-exposure').addEventListener('change', refreshEnv);
  $('env-exposure').addEventListener('input', () => { const v = $('env-exposure').value; $('env-exposure-out').textContent = `${v > 0 ? '+' : ''}${v} EV`; });
  $('compare-b').addEventListener('change', refreshCompare);
  $('undo').addEventListener('click', () => historyStep('undo'));
  $('redo').addEventListener('click', () => historyStep('redo'));
  $('reset').addEventListener('click', () => pick(state.base));
  $('interp-t').addEventListener('input', () => { $('interp-t-out').textContent = parseFloat($('interp-t').value).toFixed(2); sendInterp(); });
  $('interp-t').addEventListener('change', afterEdit);
  $('interp-other').addEventListener('change', () => { $('interp-t').value = 0; $('interp-t-out').textContent = '0.00'; });
  document.addEventListener('keydown', (ev) => {
    if ((ev.ctrlKey || ev.metaKey) && ev.key.toLowerCase() === 'z' && ev.target.tagName !== 'INPUT') {
      ev.preventDefault(); historyStep(ev.shiftKey ? 'redo' : 'undo');
    }
  });
  await loadAllNames();
  await loadMaterials();
  if (everyName.length > 1) $('compare-b').value = everyName[1];
  updateExports();
  renderChecks();
  const first = new URLSearchParams(location.search).get('material') || everyName[0];
  if (first) await pick(first);
  document.body.dataset.ready = '1';
  if (i.preparation.state === 'running') pollPreparation();
}

main().catch((e) => { window.gantry.lastError = String(e); $('server-status').textContent = `error: ${e.message}`; });
