// End-to-end tests of `gantry serve` in Debian's Chromium (headless), driven by playwright-core.
// Usage: GANTRY_URL=http://127.0.0.1:PORT/ node serve.test.mjs [screenshot-dir]
// The server must serve the fixture of make-fixture.sh (pink-felt and blue-acrylic among them).
import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { URL, SHOTS, test, launch, finish } from './harness.mjs';

const downloads = fs.mkdtempSync(path.join(os.tmpdir(), 'gantry-downloads-'));
// No WebGL here: these tests see the page as a browser without WebGL2 does (the CPU previews
// alone); gpu.test.mjs tests the real-time view.
const browser = await launch(['--disable-gpu', '--disable-webgl'], {
  acceptDownloads: true,
  downloadsPath: downloads,
  viewport: { width: 1440, height: 940 },
});
const { page } = browser;
const offsite = [];
page.on('request', (r) => { if (!r.url().startsWith(URL)) offsite.push(r.url()); });

const shot = async (name) => { if (SHOTS) await page.screenshot({ path: path.join(SHOTS, `${name}.png`), fullPage: true }); };
const draws = () => page.evaluate(() => window.gantry.sphereDraws);
const waitDraw = async (after) => page.waitForFunction((n) => window.gantry.sphereDraws > n, after, { timeout: 20000 });
// Peak of the green channel on the sphere canvas and the area above half of it.
const highlight = () => page.evaluate(() => {
  const c = document.getElementById('sphere');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let m = 0;
  for (let i = 1; i < d.length; i += 4) m = Math.max(m, d[i]);
  let area = 0;
  for (let i = 1; i < d.length; i += 4) if (2 * d[i] > m) area++;
  return { peak: m, area };
});
const sliderIndex = (name) => page.evaluate((n) => window.gantry.state.session.traits.indexOf(n), name);
const score = (k) => page.evaluate((i) => window.gantry.state.session.scores[i], k);

await test('page opens with the corpus and picks a material', async () => {
  await page.goto(URL);
  await page.waitForSelector('body[data-ready="1"]', { timeout: 30000 });
  const n = await page.locator('.mat').count();
  assert.ok(n >= 10, `${n} materials listed`);
  const before = await draws();
  await page.locator('.mat[data-name="pink-felt"]').click();
  await waitDraw(before);
  await page.waitForFunction(() => window.gantry.state.session && window.gantry.state.session.start === 'pink-felt');
  assert.equal(await page.locator('#current-title').textContent(), 'pink-felt');
  assert.equal(await page.locator('.slider').count(), 3);
});

await test('without WebGL2 the page says so and keeps the CPU previews', async () => {
  await page.waitForFunction(() => window.gantry.gpu && window.gantry.gpu.reason, null, { timeout: 10000 });
  const s = await page.evaluate(() => ({ available: window.gantry.gpu.available, status: document.getElementById('gpu-status').textContent, hidden: getComputedStyle(document.getElementById('gpu-canvas')).display }));
  assert.equal(s.available, false);
  assert.match(s.status, /WebGL2 is not available.*CPU previews/);
  assert.equal(s.hidden, 'none');
  assert.ok((await draws()) > 0, 'the CPU sphere was drawn');
});

await test('search by name and by trait score', async () => {
  await page.fill('#search', 'phenolic');
  await page.waitForFunction(() => document.querySelectorAll('.mat').length === 2);
  await page.fill('#search', '');
  await page.selectOption('#filter-trait', 'glossiness');
  await page.fill('#filter-min', '0.5');
  await page.dispatchEvent('#filter-min', 'change');
  await page.check('#sort-score');
  await page.waitForFunction(() => {
    const v = [...document.querySelectorAll('.mat .score')].map((e) => parseFloat(e.textContent.split(' ')[1]));
    return v.length > 0 && v.every((x, i) => i === 0 || x <= v[i - 1]);
  }, null, { timeout: 20000 });
  const names = await page.locator('.mat .name').allTextContents();
  assert.ok(names.length >= 3 && names.length <= 6, names.join(','));
  assert.ok(!names.includes('pink-felt'));
  const scores = (await page.locator('.mat .score').allTextContents()).map((s) => parseFloat(s.split(' ')[1]));
  assert.ok(scores.every((s, i) => s >= 0.5 && (i === 0 || s <= scores[i - 1])), scores.join(','));
  await shot('browser-search');
  await page.selectOption('#filter-trait', '');
  await page.uncheck('#sort-score');
  await page.waitForFunction(() => document.querySelectorAll('.mat').length >= 10);
});

await test('environment view refines pass by pass', async () => {
  await page.waitForFunction(() => /pass 2\/4/.test(document.getElementById('env-progress').textContent) || /pass [34]\/4/.test(document.getElementById('env-progress').textContent), null, { timeout: 60000 });
  await page.waitForFunction(() => /^pass 4\/4/.test(document.getElementById('env-progress').textContent), null, { timeout: 120000 }).catch(() => {});
  await shot('view-sphere-environment');
});

await test('dragging the glossiness slider gives a higher, narrower highlight', async () => {
  // Exposure low enough that the highlight does not clip.
  await page.locator('#exposure').fill('-1');
  let n = await draws();
  await page.dispatchEvent('#exposure', 'input');
  await waitDraw(n);
  const before = await highlight();
  const k = await sliderIndex('glossiness');
  const s0 = await score(k);
  const box = await page.locator(`#slider-${k}`).boundingBox();
  const min = parseFloat(await page.locator(`#slider-${k}`).getAttribute('min'));
  const max = parseFloat(await page.locator(`#slider-${k}`).getAttribute('max'));
  const xOf = (v) => box.x + 8 + ((v - min) / (max - min)) * (box.width - 16);
  // A real mouse drag from the current score to +1.
  await page.mouse.move(xOf(s0), box.y + box.height / 2);
  await page.mouse.down();
  for (let i = 1; i <= 10; i++) await page.mouse.move(xOf(s0 + i * 0.1), box.y + box.height / 2);
  await page.mouse.up();
  await page.waitForTimeout(500);
  await page.waitForFunction(() => !window.gantry.editing, null, { timeout: 30000 });
  await page.waitForTimeout(300);
  assert.ok((await score(k)) > s0 + 0.5, `score ${s0} → ${await score(k)}`);
  const after = await highlight();
  assert.ok(after.peak > before.peak, `peak ${before.peak} → ${after.peak}`);
  assert.ok(after.area < before.area, `area above half peak ${before.area} → ${after.area}`);
  console.log(`     glossiness ${s0.toFixed(2)} → ${(await score(k)).toFixed(2)}: peak ${before.peak} → ${after.peak}, area above half peak ${before.area} → ${after.area} px`);
});

await test('slider → new 256×256 sphere latency (p95)', async () => {
  const k = await sliderIndex('glossiness');
  await page.evaluate(() => { window.gantry.latencies = []; });
  for (let i = 0; i < 40; i++) {
    const n = await draws();
    await page.evaluate(([k, d]) => {
      const el = document.getElementById(`slider-${k}`);
      el.value = String(parseFloat(el.value) + d);
      el.dispatchEvent(new Event('input', { bubbles: true }));
    }, [k, i % 2 ? -0.04 : 0.05]);
    await waitDraw(n);
  }
  const lat = (await page.evaluate(() => window.gantry.latencies)).sort((a, b) => a - b);
  assert.ok(lat.length >= 40, `${lat.length} measurements`);
  const p = (q) => lat[Math.min(lat.length - 1, Math.floor(q * lat.length))];
  console.log(`     LATENCY slider→sphere 256x256: n=${lat.length} median ${p(0.5).toFixed(1)} ms, p95 ${p(0.95).toFixed(1)} ms, max ${lat[lat.length - 1].toFixed(1)} ms`);
  fs.writeFileSync(path.join(downloads, 'latency.json'), JSON.stringify({ n: lat.length, median: p(0.5), p95: p(0.95) }));
});

await test('a step past the valid set is stopped and the page names the check', async () => {
  const k = await sliderIndex('glossiness');
  const n = await draws();
  await page.evaluate((k) => {
    const el = document.getElementById(`slider-${k}`);
    el.value = el.max;
    el.dispatchEvent(new Event('input', { bubbles: true }));
    el.dispatchEvent(new Event('change', { bubbles: true }));
  }, k);
  await waitDraw(n);
  await page.waitForSelector('#stop-message.stop', { timeout: 20000 });
  const msg = await page.locator('#stop-message').textContent();
  assert.match(msg, /stopped by (energy conservation|non-negativity)/);
  const stopper = await page.locator('#checks li.stopper').getAttribute('data-check');
  assert.ok(['energy-conservation', 'non-negativity'].includes(stopper), stopper);
  const shown = await page.locator('#checks li.stopper span').first().textContent();
  assert.ok(msg.includes(shown), `${msg} / ${shown}`);
  await shot('edit-stopped');
});

await test('undo and redo', async () => {
  const k = await sliderIndex('glossiness');
  const now = await score(k);
  const steps = await page.evaluate(() => window.gantry.state.session.edits.length);
  await page.click('#undo');
  await page.waitForFunction((n) => window.gantry.state.session.edits.length === n - 1, steps);
  const undone = await score(k);
  assert.ok(undone < now - 1e-6, `${now} → ${undone}`);
  await page.click('#redo');
  await page.waitForFunction((n) => window.gantry.state.session.edits.length === n, steps);
  assert.ok(Math.abs((await score(k)) - now) < 1e-9);
  await page.click('#undo');
  await page.waitForFunction((n) => window.gantry.state.session.edits.length === n - 1, steps);
});

await test('export an RGL .bsdf file of the edit', async () => {
  const [dl] = await Promise.all([page.waitForEvent('download'), page.click('#export-bsdf')]);
  const file = path.join(downloads, 'exported.bsdf');
  await dl.saveAs(file);
  const buf = fs.readFileSync(file);
  assert.equal(buf.subarray(0, 12).toString('latin1'), 'tensor_file\0');
  assert.deepEqual([buf[12], buf[13]], [1, 0]);
  assert.ok(buf.readUInt32LE(14) >= 9);
});

await test('export a .binary and read it back', async () => {
  const id = await page.evaluate(() => window.gantry.state.session.id);
  const [dl] = await Promise.all([page.waitForEvent('download'), page.click('#export-binary')]);
  const file = path.join(downloads, 'exported.binary');
  await dl.saveAs(file);
  const buf = fs.readFileSync(file);
  assert.equal(buf.length, 34992012);
  assert.deepEqual([buf.readInt32LE(0), buf.readInt32LE(4), buf.readInt32LE(8)], [90, 90, 180]);
  for (let i = 12; i < buf.length; i += 8 * 997) assert.ok(Number.isFinite(buf.readDoubleLE(i)));
  // Read back: open the file in the page; its sphere is the edited sphere.
  await page.setInputFiles('#file-input', file);
  await page.waitForSelector('#upload-message.ok', { timeout: 30000 });
  const up = (await page.locator('#upload-message').textContent()).split(' as ')[1];
  assert.match(up, /^upload-\d+-exported$/);
  const worst = await page.evaluate(async ([up, id]) => {
    const q = 'size=256&lx=-0.35&ly=0.4&exposure=-1';
    const px = async (u) => {
      const b = await createImageBitmap(await (await fetch(u)).blob());
      const c = new OffscreenCanvas(b.width, b.height); const x = c.getContext('2d'); x.drawImage(b, 0, 0);
      return x.getImageData(0, 0, b.width, b.height).data;
    };
    const [a, b] = [await px(`/api/materials/${up}/sphere.png?${q}`), await px(`/api/sessions/${id}/sphere.png?${q}`)];
    let w = 0; for (let i = 0; i < a.length; i++) w = Math.max(w, Math.abs(a[i] - b[i]));
    return w;
  }, [up, id]);
  assert.ok(worst <= 1, `exported sphere differs by ${worst} levels`);
});

await test('a malformed file dropped on the page gives a clear message', async () => {
  const drop = async (bytes, name) => {
    await page.evaluate(([bytes, name]) => {
      const dt = new DataTransfer();
      dt.items.add(new File([new Uint8Array(bytes)], name));
      document.getElementById('drop-zone').dispatchEvent(new DragEvent('drop', { dataTransfer: dt, bubbles: true, cancelable: true }));
    }, [bytes, name]);
  };
  const wrongSize = new Array(4000).fill(0);
  [90, 0, 0, 0, 90, 0, 0, 0, 180, 0, 0, 0].forEach((b, i) => { wrongSize[i] = b; });
  await drop(wrongSize, 'truncated.binary');
  await page.waitForSelector('#upload-message.error', { timeout: 20000 });
  assert.match(await page.locator('#upload-message').textContent(), /truncated\.binary: wrong size: the header announces 34992012 bytes, the file has 4000/);
  const badHeader = new Array(64).fill(0);
  [7, 0, 0, 0].forEach((b, i) => { badHeader[i] = b; });
  await drop(badHeader, 'header.binary');
  await page.waitForFunction(() => /bad header/.test(document.getElementById('upload-message').textContent));
  assert.match(await page.locator('#upload-message').textContent(), /bad header: dimensions 7 × 0 × 0/);
  await shot('upload-error');
});

await test('a material picked while another is still opening wins', async () => {
  // The session for pink-felt answers late (as a slow projection on a loaded server would);
  // blue-acrylic, picked after it, must stay the one shown.
  const slow = async (route) => {
    const body = route.request().postData() || '';
    if (route.request().method() === 'POST' && body.includes('"pink-felt"')) await new Promise((r) => setTimeout(r, 1500));
    await route.continue();
  };
  await page.route('**/api/sessions', slow);
  try {
    await page.locator('.mat[data-name="pink-felt"]').click();
    await page.locator('.mat[data-name="blue-acrylic"]').click();
    await page.waitForFunction(() => window.gantry.state.session && window.gantry.state.session.start === 'blue-acrylic');
    await page.waitForTimeout(2500);
    const shown = await page.evaluate(() => [window.gantry.state.session.start, window.gantry.state.base, document.getElementById('current-title').textContent]);
    assert.deepEqual(shown, ['blue-acrylic', 'blue-acrylic', 'blue-acrylic']);
  } finally {
    await page.unroute('**/api/sessions', slow);
  }
});

await test('plots: incidence plane (linear, log), slice, albedo with the albedo = 1 line', async () => {
  await page.locator('.mat[data-name="blue-acrylic"]').click();
  await page.waitForFunction(() => window.gantry.state.session && window.gantry.state.session.start === 'blue-acrylic');
  await page.click('.tab[data-tab="plots"]');
  // Each plot reports when it has drawn, and for which material: the one shown (the edit
  // session opened on blue-acrylic).
  const drawn = (ids, after = {}) => page.waitForFunction(([ids, after]) => ids.every((id) => {
    const p = window.gantry.plots[id];
    return p && p.material === window.gantry.state.current && p.draws > (after[id] || 0);
  }), [ids, after], { timeout: 30000 }).catch(async (e) => {
    // What the page had drawn, for which material, and its last error, to tell a slow server
    // from a plot that never draws.
    const seen = await page.evaluate(() => JSON.stringify({
      current: window.gantry.state.current, tab: window.gantry.state.tab,
      plots: window.gantry.plots, lastError: window.gantry.lastError,
    }));
    throw new Error(`${e.message}\npage state: ${seen}`);
  });
  await drawn(['polar', 'slice', 'albedo']);
  const ink = (id) => page.evaluate((id) => {
    const c = document.getElementById(id); const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let n = 0; for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++; return n;
  }, id);
  for (const id of ['polar', 'slice', 'albedo']) assert.ok((await ink(id)) > 1000, `${id} is empty`);
  const linear = await page.evaluate(() => window.gantry.plots.polar.draws);
  await page.click('#polar-log');
  await drawn(['polar'], { polar: linear });
  assert.equal(await page.evaluate(() => window.gantry.plots.polar.log), true);
  await shot('plots');
});

await test('compare two materials with a difference image', async () => {
  await page.click('.tab[data-tab="compare"]');
  await page.selectOption('#compare-b', 'pink-felt');
  await page.waitForFunction(() => /vs pink-felt: RMS log-radiance difference/.test(document.getElementById('compare-stats').textContent), null, { timeout: 20000 });
  const rms = parseFloat((await page.locator('#compare-stats').textContent()).match(/difference ([0-9.e-]+)/)[1]);
  assert.ok(rms > 0.01, `rms ${rms}`);
  await shot('compare');
});

await test('the page makes no request outside the server', async () => {
  assert.deepEqual(offsite, []);
});

await finish(browser, 'browser tests');
