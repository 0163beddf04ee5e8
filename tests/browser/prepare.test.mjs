// Editing out of the box: `gantry serve --corpus DIR` with no model. The first phase checks the
// page's offer, builds the model and trait sets from it and edits; PHASE=cached runs against a
// second server on the same corpus, which must edit at once from the cache.
// Usage: GANTRY_URL=http://127.0.0.1:PORT/ [PHASE=cached] node prepare.test.mjs [screenshot-dir]
import assert from 'node:assert/strict';
import path from 'node:path';
import { URL, SHOTS, test, launch, finish } from './harness.mjs';

const browser = await launch(['--disable-gpu', '--disable-webgl'], { viewport: { width: 1440, height: 940 } });
const { page } = browser;
const shot = async (name) => { if (SHOTS) await page.screenshot({ path: path.join(SHOTS, `${name}.png`), fullPage: true }); };
const info = () => page.evaluate(async () => (await fetch('/api/info')).json());
const openOn = async (material) => {
  await page.goto(`${URL}?material=${material}`);
  await page.waitForSelector('body[data-ready="1"]', { timeout: 30000 });
};

if (process.env.PHASE !== 'cached') {
  await test('without a model the page says what editing needs and offers to build it', async () => {
    await openOn('pink-felt');
    const i = await info();
    assert.equal(i.editing, false);
    assert.equal(i.preparation.state, 'buildable');
    assert.equal(await page.locator('#prepare').isVisible(), true);
    assert.match(await page.locator('#prepare-message').textContent(), /^Editing needs a model and a trait set/);
    assert.equal(await page.locator('#prepare-build').isVisible(), true);
    assert.equal(await page.locator('#editor-on').isVisible(), false);
    assert.match(await page.locator('#server-status').textContent(), /viewing only/);
    await shot('prepare-offer');
  });

  await test('building from the page shows progress, then the sliders of the built traits', async () => {
    // Every text the progress line shows, recorded as it changes.
    await page.evaluate(() => {
      window.prepSeen = [];
      new MutationObserver(() => window.prepSeen.push(document.getElementById('prepare-message').textContent))
        .observe(document.getElementById('prepare-message'), { childList: true, characterData: true, subtree: true });
    });
    await page.locator('#prepare-build').click();
    await page.waitForFunction(() => document.querySelectorAll('.slider').length > 0, null, { timeout: 180000 });
    const seen = await page.evaluate(() => window.prepSeen);
    assert.ok(seen.some((m) => /^Preparing editing: /.test(m)), `progress shown: ${JSON.stringify(seen)}`);
    const i = await info();
    assert.equal(i.editing, true);
    assert.equal(i.preparation.state, 'ready');
    assert.match(i.preparation.cache, /corpus\.gantry-cache\/[0-9a-f]{16}$/);
    const names = await page.locator('.slider').evaluateAll((els) => els.map((e) => e.dataset.trait));
    assert.deepEqual(names, i.spaces[0].traits.map((t) => t.name));
    // The project's labels on these ten materials carry glossiness and specularness at least.
    for (const t of ['glossiness', 'specularness']) assert.ok(names.includes(t), `${t} in ${names}`);
    assert.equal(await page.evaluate(() => window.gantry.state.session.start), 'pink-felt');
    assert.equal(await page.locator('#prepare').isVisible(), false);
    await shot('prepare-built');
  });

  await test('a slider of a built trait edits the material', async () => {
    const k = await page.evaluate(() => window.gantry.state.session.traits.indexOf('glossiness'));
    const before = await page.evaluate((j) => window.gantry.state.session.scores[j], k);
    const slider = page.locator(`#slider-${k}`);
    await slider.evaluate((el, v) => { el.value = v; el.dispatchEvent(new Event('input', { bubbles: true })); el.dispatchEvent(new Event('change', { bubbles: true })); }, before + 0.3);
    await page.waitForFunction(([j, b]) => Math.abs(window.gantry.state.session.scores[j] - b) > 1e-3, [k, before], { timeout: 30000 });
    const after = await page.evaluate((j) => window.gantry.state.session.scores[j], k);
    assert.ok(after > before, `glossiness ${before} -> ${after}`);
  });
} else {
  await test('a second start on the same corpus edits at once from the cache', async () => {
    await openOn('pink-felt');
    await page.waitForFunction(() => document.querySelectorAll('.slider').length > 0, null, { timeout: 60000 });
    const i = await info();
    assert.equal(i.editing, true);
    assert.equal(await page.locator('#prepare').isVisible(), false);
    assert.match(await page.locator('#server-status').textContent(), /model of \d+ components/);
  });
}

await finish(browser, `editing-preparation browser tests${process.env.PHASE === 'cached' ? ' (cached)' : ''}`);
