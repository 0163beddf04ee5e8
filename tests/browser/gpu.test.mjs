// End-to-end tests of the real-time WebGL2 view of `gantry serve` in Debian's Chromium with
// software GL (SwiftShader), driven by playwright-core.
// Usage: GANTRY_URL=http://127.0.0.1:PORT/ node gpu.test.mjs [screenshot-dir]
// The server must serve the fixture of `make-fixture.sh OUT GANTRY 36` (46 materials, 45
// components; pink-felt, blue-acrylic and chrome among them). Prints the frame times and the slider latency; writes gpu-timing.json to the
// screenshot directory when one is given.
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { URL, SHOTS, test, launch, finish } from './harness.mjs';

// WebGL on SwiftShader (software GL); the page itself composited in software, as a browser
// without a GPU would, so that compositing does not queue behind the WebGL work.
const browser = await launch(['--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-gpu-compositing'],
  { viewport: { width: 1440, height: 1100 } });
const { page } = browser;
const timing = {};
const PREVIEW_NOTE = 'a first frame sized to about 8 ms of work, then 512²';
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
  assert.ok(timing.latency.first_frame.p95 <= 20, `p95 ${timing.latency.first_frame.p95} ms (goal 20 ms)`);
});

if (SHOTS) fs.writeFileSync(path.join(SHOTS, 'gpu-timing.json'), JSON.stringify(timing, null, 1));
await finish(browser, 'GPU browser tests');
