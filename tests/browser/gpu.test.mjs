// End-to-end tests of the real-time WebGL2 view of `gantry serve` in Debian's Chromium with
// software GL (SwiftShader), driven by playwright-core.
// Usage: GANTRY_URL=http://127.0.0.1:PORT/ node gpu.test.mjs [screenshot-dir]
// The server must serve the fixture of `make-fixture.sh OUT GANTRY 36` (46 materials, 45
// components; pink-felt, blue-acrylic and chrome among them). Prints the frame times and the slider latency; writes gpu-timing.json to the
// screenshot directory when one is given.
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { URL, SHOTS, test, launch, finish, dataDir } from './harness.mjs';

// WebGL on SwiftShader (software GL); the page itself composited in software, as a browser
// without a GPU would, so that compositing does not queue behind the WebGL work.
const browser = await launch(['--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-gpu-compositing'],
  { viewport: { width: 1440, height: 1100 } });
const { page } = browser;
const timing = {};
const PREVIEW_NOTE = 'a first frame sized to about 6 ms of work, then 512²';
const shot = async (name) => { if (SHOTS) await page.locator('#gpu-card').screenshot({ path: path.join(SHOTS, `${name}.png`) }); };
const open = async (material, frames) => {
  await page.goto(`${URL}?material=${material}`);
  await page.waitForSelector('body[data-ready="1"]', { timeout: 30000 });
  // As many jittered frames as the reference has samples per pixel: a mirror's highlight covers
  // a few pixels, and their coverage is what the sample positions decide.
  if (frames) await page.evaluate((n) => { window.gantry.gpu.pointFrames = n; window.gantry.gpu.restart(); }, frames);
  await page.waitForFunction(() => window.gantry.gpu.error || window.gantry.gpu.converged(), null, { timeout: 120000 });
  assert.equal(await page.evaluate(() => window.gantry.gpu.error), null);
};

await test('the real-time view starts with the model\'s components', async () => {
  await open('pink-felt');
  const s = await page.evaluate(() => ({ available: window.gantry.gpu.available, k: window.gantry.gpu.components, status: document.getElementById('gpu-status').textContent }));
  const info = await page.evaluate(() => window.gantry.state.info);
  assert.ok(s.available, s.status);
  assert.equal(s.k, info.model_components);
  assert.match(s.status, /half-float RGB, [\d.]+ MB/);
  console.log(`     ${s.status}`);
});

// The sphere under the point light (diffuse, glossy, metallic), read back as floats, against the offline renderer's image
// of the same scene and coefficients (direct lighting, 64 samples per pixel).
for (const material of ['pink-felt', 'blue-acrylic', 'chrome']) {
  await test(`${material}: the GPU sphere matches the offline renderer within 2 %`, async () => {
    await open(material, 64);
    const r = await page.evaluate(async () => {
      const G = window.gantry.gpu; const img = G.readLinear();
      const res = await fetch(`/api/gpu/materials/${encodeURIComponent(G.material)}/reference.bin?size=${img.width}&spp=64`);
      const ref = new Float32Array(await res.arrayBuffer());
      const mg = [0, 0, 0], mr = [0, 0, 0];
      for (let i = 0; i < ref.length; i++) { mg[i % 3] += img.pixels[i]; mr[i % 3] += ref[i]; }
      // Per-pixel relative RMS over the sphere's inner pixels (silhouette pixels are partly
      // covered, their values depend on the sample positions).
      const W = img.width, lit = (q) => ref[q] + ref[q + 1] + ref[q + 2] > 1e-3;
      let se = 0, n = 0;
      for (let p = 3 * W; p < ref.length - 3 * W; p += 3) {
        if (!(lit(p) && lit(p + 3) && lit(p - 3) && lit(p + 3 * W) && lit(p - 3 * W))) continue;
        const a = ref[p] + ref[p + 1] + ref[p + 2], b = img.pixels[p] + img.pixels[p + 1] + img.pixels[p + 2];
        se += ((b - a) / a) ** 2; n++;
      }
      return { frames: img.frames, mean: mg.map((v, c) => v / mr[c] - 1), relRms: Math.sqrt(se / n), pixels: n, refMean: mr.map((v) => v / (ref.length / 3)) };
    });
    console.log(`     ${material}: mean difference R/G/B ${r.mean.map((v) => (100 * v).toFixed(2) + ' %').join(' / ')}, per-pixel relative RMS ${(100 * r.relRms).toFixed(1)} % over ${r.pixels} pixels (${r.frames} frames)`);
    timing[`compare_${material}`] = r;
    assert.ok(r.refMean.every((v) => v > 1e-3), `reference is lit: ${r.refMean}`);
    for (const d of r.mean) assert.ok(Math.abs(d) < 0.02, `mean difference ${d}`);
    await shot(`gpu-${material}`);
  });
}

// The rust teapot (thesis fig. 5-8) and the rust bunny: every point its own BRDF, the process
// path from a steel to a brown wood at the rust field's amount, on 10 components; against the
// offline renderer's spatially varying mesh (render::figure_point_scene, direct lighting,
// shadow rays). The teapot last: the brush test paints on it.
for (const mesh of ['bunny', 'teapot']) {
  await test(`the rust ${mesh} on the GPU matches the offline renderer, rust where the texture says`, async () => {
    await open('pink-felt');
    // The bunny's 69,451 triangles make its offline reference the slower one: 32 samples.
    const [from, to, k, spp] = ['grease-covered-steel', 'colonial-maple-223', 10, mesh === 'bunny' ? 32 : 64];
    await page.evaluate(async ([mesh, from, to, k, spp]) => {
      const G = window.gantry.gpu;
      const kIn = document.getElementById('gpu-k'); kIn.value = String(k); kIn.dispatchEvent(new Event('input'));
      G.pointFrames = spp;
      await G.setScene(mesh, from, to);
    }, [mesh, from, to, k, spp]);
    await page.waitForFunction(() => window.gantry.gpu.converged(), null, { timeout: 120000 });
    const r = await page.evaluate(async ([mesh, from, to, k, spp]) => {
      const G = window.gantry.gpu, T = G.teapot, img = G.readLinear();
      const q = new URLSearchParams({ from, to, k, width: img.width, texture_width: T.tw, seed: 1, spp });
      const ref = new Float32Array(await (await fetch(`/api/gpu/meshes/${mesh}/reference.bin?${q}`)).arrayBuffer());
      const mg = [0, 0, 0], mr = [0, 0, 0];
      for (let i = 0; i < ref.length; i++) { mg[i % 3] += img.pixels[i]; mr[i % 3] += ref[i]; }
      // Pixels by the rust amount under them (uv from the GPU's pick pass, field texel at the
      // uv; u wraps).
      const cls = { clean: [[0, 0, 0], [0, 0, 0], 0], rusted: [[0, 0, 0], [0, 0, 0], 0] };
      for (let y = 0; y < img.height; y++) for (let x = 0; x < img.width; x++) {
        const p = ((img.height - 1 - y) * img.width + x) * 4;
        if (T.uv[p + 2] < 0.5) continue;
        const tx = ((Math.floor(T.uv[p] * T.tw) % T.tw) + T.tw) % T.tw, ty = Math.min(T.th - 1, Math.max(0, Math.floor(T.uv[p + 1] * T.th)));
        const f = T.field[ty * T.tw + tx];
        const c = f > 0.95 ? cls.rusted : f < 0.05 ? cls.clean : null;
        if (!c) continue;
        const i = (y * img.width + x) * 3;
        for (let ch = 0; ch < 3; ch++) { c[0][ch] += img.pixels[i + ch]; c[1][ch] += ref[i + ch]; }
        c[2]++;
      }
      const colour = (c) => ({ gpu: c[0].map((v) => v / c[2]), ref: c[1].map((v) => v / c[2]), pixels: c[2] });
      return { width: img.width, height: img.height, frames: img.frames, mean: mg.map((v, c) => v / mr[c] - 1), refMean: mr.map((v) => v / (ref.length / 3)), clean: colour(cls.clean), rusted: colour(cls.rusted) };
    }, [mesh, from, to, k, spp]);
    timing[mesh] = r;
    const pct = (v) => v.map((x) => (100 * x).toFixed(2) + ' %').join(' / ');
    const hue = (c) => (c[0] / (c[2] || 1e-9)).toFixed(2);
    console.log(`     rust ${mesh} ${r.width}×${r.height}, k = 10, ${r.frames} frames and samples per pixel: mean difference R/G/B ${pct(r.mean)}; clean pixels (${r.clean.pixels}) R/B GPU ${hue(r.clean.gpu)}, offline ${hue(r.clean.ref)}; rusted pixels (${r.rusted.pixels}) R/B GPU ${hue(r.rusted.gpu)}, offline ${hue(r.rusted.ref)}`);
    assert.ok(r.refMean.every((v) => v > 1e-3), `reference is lit: ${r.refMean}`);
    for (const d of r.mean) assert.ok(Math.abs(d) < 0.02, `mean difference ${d}`);
    assert.ok(r.clean.pixels > 1000 && r.rusted.pixels > 1000, `${r.clean.pixels} clean, ${r.rusted.pixels} rusted pixels`);
    // The rust is where the field says, on both: the rusted pixels are redder than the clean ones.
    assert.ok(r.rusted.gpu[0] / r.rusted.gpu[2] > 1.2 * (r.clean.gpu[0] / r.clean.gpu[2]), 'GPU: rusted pixels redder');
    assert.ok(r.rusted.ref[0] / r.rusted.ref[2] > 1.2 * (r.clean.ref[0] / r.clean.ref[2]), 'offline: rusted pixels redder');
    await shot(`gpu-rust-${mesh}`);
  });
}

await test('the brush paints rust onto the teapot', async () => {
  const r = await page.evaluate(async () => {
    const G = window.gantry.gpu, T = G.teapot;
    document.getElementById('gpu-brush').value = 'rust+';
    // The pixel nearest the centre that shows the teapot where the field is clean.
    let best = null;
    for (let y = 0; y < G.height; y += 4) for (let x = 0; x < G.width; x += 4) {
      const p = ((G.height - 1 - y) * G.width + x) * 4;
      if (T.uv[p + 2] < 0.5) continue;
      const i = Math.min(T.th - 1, Math.floor(T.uv[p + 1] * T.th)) * T.tw + Math.min(T.tw - 1, Math.floor(T.uv[p] * T.tw));
      if (T.field[i] < 0.05 && (!best || Math.hypot(x - 256, y - 200) < best.d)) best = { x, y, i, d: Math.hypot(x - 256, y - 200) };
    }
    const before = T.field[best.i];
    for (let n = 0; n < 10; n++) G.brushAt(best.x, best.y);
    return { before, after: T.field[best.i], strokes: G.brushStrokes };
  });
  assert.ok(r.after > r.before + 0.5, `rust ${r.before} → ${r.after}`);
  await page.waitForFunction(() => window.gantry.gpu.converged(), null, { timeout: 120000 });
  await shot('gpu-rust-teapot-brushed');
  await page.evaluate(() => window.gantry.gpu.setScene('sphere'));
});

// The oxidation progression (thesis fig. 5-7): eight spheres along the path from polished to
// black oxidized steel, one coefficient texel each, on 10 components; against the offline
// renderer's grid of the same stages (render::sphere_grid_scene, direct lighting, shadow rays),
// rendered twice with different seeds. A polished stage's highlight is a few pixels of huge
// values (the table's first θh bins), so its mean is noisy for either renderer: stages whose two
// references agree within 0.5 % must match within 2 %; the others within 2 % plus four times
// their references' own disagreement (a gross error still fails), and are reported.
await test('the oxidation progression on the GPU matches the offline renderer', async () => {
  const nodes = ['chrome-steel', 'grease-covered-steel', 'black-oxidized-steel'];
  const [k, spp] = [10, 64];
  await page.evaluate(async ([nodes, k, spp]) => {
    const G = window.gantry.gpu;
    const kIn = document.getElementById('gpu-k'); kIn.value = String(k); kIn.dispatchEvent(new Event('input'));
    G.pointFrames = spp;
    await G.setGrid(nodes);
  }, [nodes, k, spp]);
  await page.waitForFunction(() => window.gantry.gpu.converged(), null, { timeout: 120000 });
  const r = await page.evaluate(async ([nodes, k, spp]) => {
    const G = window.gantry.gpu, img = G.readLinear(), info = G.grid.info;
    const cell = img.width / info.columns;
    // Each stage's mean (its cell of the grid) of an image.
    const stages = (px) => Array.from({ length: G.grid.count }, (_, s) => {
      const x0 = (s % info.columns) * cell, y0 = Math.floor(s / info.columns) * cell;
      let a = 0;
      for (let y = y0; y < y0 + cell; y++) for (let x = x0; x < x0 + cell; x++) { const i = (y * img.width + x) * 3; a += px[i] + px[i + 1] + px[i + 2]; }
      return a / cell / cell;
    });
    const refs = [];
    for (const seed of [1, 2]) {
      const q = new URLSearchParams({ nodes: nodes.join(','), count: G.grid.count, columns: G.grid.columns, sphere_pixels: cell, k, spp, seed });
      refs.push(new Float32Array(await (await fetch(`/api/gpu/grid-reference.bin?${q}`)).arrayBuffer()));
    }
    const [g, r1, r2] = [img.pixels, ...refs].map(stages);
    return { width: img.width, height: img.height, frames: img.frames,
      stages: g.map((v, s) => ({ gpu: v, ref: 0.5 * (r1[s] + r2[s]), spread: Math.abs(r1[s] / r2[s] - 1) })) };
  }, [nodes, k, spp]);
  timing.progression = r;
  const pct = (x) => `${(100 * x).toFixed(1)} %`;
  console.log(`     oxidation progression ${r.width}×${r.height}, k = 10, ${r.frames} frames: per stage GPU − offline (offline seed-to-seed) ${r.stages.map((s) => `${pct(s.gpu / s.ref - 1)} (${pct(s.spread)})`).join(', ')}`);
  assert.ok(r.stages.every((s) => s.ref > 1e-4), 'every stage is lit');
  // The stages differ: the polished end is not the oxidized end.
  assert.ok(Math.abs(r.stages[0].ref / r.stages[7].ref - 1) > 0.1, 'the path changes the material');
  const converged = r.stages.filter((s) => s.spread < 0.005);
  assert.ok(converged.length >= 4, `${converged.length} stages with converged references`);
  for (const s of r.stages) {
    const bound = s.spread < 0.005 ? 0.02 : 0.02 + 4 * s.spread;
    assert.ok(Math.abs(s.gpu / s.ref - 1) < bound, `stage ${s.gpu} against ${s.ref} (bound ${bound})`);
  }
  // The screenshot for docs/ under the probe (64 frames), only when screenshots are asked for.
  if (SHOTS) {
    await page.evaluate(() => { const G = window.gantry.gpu; G.envFrames = 64; G.mode = 'env'; document.getElementById('gpu-mode').value = 'env'; G.restart(); });
    await page.waitForFunction(() => window.gantry.gpu.converged(), null, { timeout: 240000 });
    await shot('gpu-oxidation');
    await page.evaluate(() => { const G = window.gantry.gpu; G.envFrames = 256; G.mode = 'point'; document.getElementById('gpu-mode').value = 'point'; });
  }
});

// A probe chosen in the page (the shared Venice probe as Radiance .hdr) lights the view as the
// server's own (the same capture as OpenEXR) does; a file that is not a probe is refused and
// the view keeps its probe.
await test('a probe uploaded from the page lights the view like the server\'s', async () => {
  await page.evaluate(() => window.gantry.gpu.setScene('sphere'));
  const render = async () => {
    await page.evaluate(() => { const G = window.gantry.gpu; G.envFrames = 4; G.mode = 'env'; document.getElementById('gpu-mode').value = 'env'; G.restart(); });
    await page.waitForFunction(() => window.gantry.gpu.converged(), null, { timeout: 120000 });
    return page.evaluate(() => window.gantry.gpu.readLinear().pixels);
  };
  const means = (px) => { const m = [0, 0, 0]; px.forEach((v, i) => { m[i % 3] += v; }); return m; };
  await page.evaluate(() => { const kIn = document.getElementById('gpu-k'); kIn.value = '1'; kIn.dispatchEvent(new Event('input')); });
  const own = await render();
  const file = path.join(dataDir(), 'real/envmap/venice_sunset_1k.hdr');
  await page.setInputFiles('#gpu-probe-file', file);
  await page.waitForFunction(() => window.gantry.gpu.probe === 'venice_sunset_1k.hdr', null, { timeout: 60000 });
  const uploaded = await render();
  const [mu, mo] = [means(uploaded), means(own)];
  const diff = mu.map((v, c) => v / mo[c] - 1);
  console.log(`     uploaded .hdr probe against the server's .exr: mean difference R/G/B ${diff.map((x) => (100 * x).toFixed(2) + ' %').join(' / ')}`);
  for (const d of diff) assert.ok(Math.abs(d) < 0.02, `mean difference ${d}`);
  // A uniform grey probe written here (flat RGBE, every pixel mantissa 128, exponent 128: 0.5)
  // is the one in use afterwards: the background shows 0.5.
  const [w, h] = [64, 32];
  const grey = Buffer.concat([Buffer.from(`#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y ${h} +X ${w}\n`), Buffer.alloc(4 * w * h, 128)]);
  await page.setInputFiles('#gpu-probe-file', { name: 'grey.hdr', mimeType: 'application/octet-stream', buffer: grey });
  await page.waitForFunction(() => window.gantry.gpu.probe === 'grey.hdr', null, { timeout: 60000 });
  const flat = await render();
  const corner = flat.slice(0, 3);
  console.log(`     uniform probe uploaded: background ${corner.map((v) => v.toFixed(4)).join(' / ')}`);
  for (const v of corner) assert.ok(Math.abs(v - 0.5) < 0.005, `background ${v}`);
  await page.setInputFiles('#gpu-probe-file', { name: 'notes.hdr', mimeType: 'application/octet-stream', buffer: Buffer.from('not a probe') });
  await page.waitForFunction(() => /^probe notes\.hdr:/.test(document.getElementById('gpu-status').textContent), null, { timeout: 30000 });
  const status = await page.evaluate(() => document.getElementById('gpu-status').textContent);
  assert.match(status, /magic|probe/i, status);
  assert.equal(await page.evaluate(() => window.gantry.gpu.probe), 'grey.hdr');
  await page.evaluate(() => { const G = window.gantry.gpu; G.envFrames = 256; G.mode = 'point'; document.getElementById('gpu-mode').value = 'point'; G.restart(); });
});

await test('frame times at 512² (point light and probe, k = 1, 10 and all)', async () => {
  const K = await page.evaluate(() => window.gantry.gpu.components);
  const out = {};
  for (const mode of ['point', 'env']) {
    for (const k of [...new Set([1, Math.min(10, K), K])]) {
      const b = await page.evaluate(([mode, k]) => window.gantry.gpu.benchmark({ mode, k, frames: 5 }), [mode, k]);
      out[`${mode}_k${k}`] = b.median;
      assert.ok(b.median > 0 && Number.isFinite(b.median));
    }
  }
  timing.frame_ms = out;
  console.log(`     FRAMES 512x512 (median ms, one sample per pixel; probe: 4 rounds of probe + lobe samples): ${JSON.stringify(out)}`);
});

await test('the probe view accumulates and shows the probe behind the sphere', async () => {
  await page.selectOption('#gpu-mode', 'env');
  await page.waitForFunction(() => window.gantry.gpu.frames >= 8, null, { timeout: 120000 });
  const r = await page.evaluate(() => {
    const img = window.gantry.gpu.readLinear();
    const at = (x, y) => img.pixels.slice((y * img.width + x) * 3, (y * img.width + x) * 3 + 3);
    return { corner: at(4, 4), centre: at(img.width >> 1, img.height >> 1), frames: img.frames };
  });
  assert.ok(r.corner.some((v) => v > 0), `background shows the probe: ${r.corner}`);
  assert.ok(r.centre.every((v) => Number.isFinite(v) && v >= 0) && r.centre.some((v) => v > 0), `sphere lit: ${r.centre}`);
  await shot('gpu-probe');
  await page.selectOption('#gpu-mode', 'point');
});

await test('slider → first frame of the edited material on the GPU (p95)', async () => {
  await open('blue-acrylic');
  const k = await page.evaluate(() => window.gantry.state.session.traits.indexOf('glossiness'));
  await page.evaluate(() => { const G = window.gantry.gpu; G.latencies = []; G.fullLatencies = []; G.confirmed = 0; G.corrected = 0; });
  for (let i = 0; i < 30; i++) {
    const n = await page.evaluate(() => window.gantry.gpu.latencies.length);
    await page.evaluate(([k, d]) => {
      const el = document.getElementById(`slider-${k}`);
      el.value = String(parseFloat(el.value) + d);
      el.dispatchEvent(new Event('input', { bubbles: true }));
    }, [k, i % 2 ? -0.04 : 0.05]);
    await page.waitForFunction((n) => window.gantry.gpu.latencies.length > n, n, { timeout: 20000 });
    await page.waitForFunction(() => !window.gantry.editing, null, { timeout: 20000 });
  }
  await page.waitForFunction(() => window.gantry.gpu.pendingFull.length === 0, null, { timeout: 20000 });
  const all = await page.evaluate(() => ({ side: window.gantry.gpu.previewSide, first: window.gantry.gpu.latencies, full: window.gantry.gpu.fullLatencies, confirmed: window.gantry.gpu.confirmed, corrected: window.gantry.gpu.corrected }));
  const stats = (v) => { v = v.slice().sort((a, b) => a - b); const p = (q) => v[Math.min(v.length - 1, Math.floor(q * v.length))]; return { n: v.length, median: p(0.5), p95: p(0.95), max: v[v.length - 1] }; };
  const f = (s) => `n=${s.n} median ${s.median.toFixed(1)} ms, p95 ${s.p95.toFixed(1)} ms`;
  timing.latency = { first_frame_side: all.side, first_frame: stats(all.first), full_frame: stats(all.full), confirmed: all.confirmed, corrected: all.corrected };
  const lat = all.first;
  console.log(`     LATENCY slider→first GPU frame (${PREVIEW_NOTE}; here ${all.side}²): ${f(timing.latency.first_frame)}; slider→first 512² frame: ${f(timing.latency.full_frame)}; predicted steps the server confirmed: ${all.confirmed}, corrected: ${all.corrected}`);
  assert.ok(lat.length >= 30, `${lat.length} measurements`);
  // Every step is small and valid: the server confirms each prediction exactly.
  assert.equal(all.corrected, 0);
  assert.ok(all.confirmed >= 30, `${all.confirmed} confirmed`);
  // The goal (p95 ≤ 20 ms) is a measurement, not a pass/fail condition: a loaded machine
  // slows every frame. It is reported here and in gpu-timing.json (SHOTS).
  const p95 = timing.latency.first_frame.p95;
  console.log(`     first-frame p95 ${p95.toFixed(1)} ms against the 20 ms goal: ${p95 <= 20 ? 'met' : 'not met on this run'}`);
});

if (SHOTS) fs.writeFileSync(path.join(SHOTS, 'gpu-timing.json'), JSON.stringify(timing, null, 1));
await finish(browser, 'GPU browser tests');
