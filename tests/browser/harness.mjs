// What the browser test files share: the server's address, the screenshot directory, a fresh
// headless Chromium profile, and the test runner that counts results.
import { chromium } from 'playwright-core';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';

export const URL = process.env.GANTRY_URL;
if (!URL) { console.error('error: set GANTRY_URL'); process.exit(2); }
export const SHOTS = process.argv[2] || null;
const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
if (!fs.existsSync(CHROMIUM)) { console.error(`error: ${CHROMIUM} not found (run .ci/setup: it installs chromium)`); process.exit(2); }

// The shared data (BRDF_DATA_DIR, else shared/data beside the checkout or an ancestor of it,
// as brdf::data_dir looks); the tests that read it fail when it is missing.
export function dataDir() {
  if (process.env.BRDF_DATA_DIR) return process.env.BRDF_DATA_DIR;
  let d = path.resolve(path.dirname(new globalThis.URL(import.meta.url).pathname), '../..');
  while (d !== path.dirname(d)) {
    const c = path.join(d, '../shared/data');
    if (fs.existsSync(c)) return path.resolve(c);
    d = path.dirname(d);
  }
  throw new Error('shared data not found (set BRDF_DATA_DIR)');
}

const results = [];
export async function test(name, fn) {
  const t0 = Date.now();
  try { await fn(); results.push([name, true]); console.log(`ok   ${name} (${Date.now() - t0} ms)`); }
  catch (e) { results.push([name, false]); console.log(`FAIL ${name}\n${e.stack}`); }
}

// Launches Chromium on a fresh profile with the common flags and `args`; `options` go to
// playwright (viewport, downloads).
export async function launch(args, options = {}) {
  const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'gantry-chromium-'));
  const context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: CHROMIUM,
    headless: true,
    deviceScaleFactor: 1,
    ...options,
    args: ['--headless', '--no-sandbox', ...args, '--disable-background-networking',
      '--disable-component-update', '--disable-sync', '--no-first-run'],
  });
  const page = context.pages()[0] || await context.newPage();
  page.on('pageerror', (e) => console.log(`page error: ${e.message}`));
  return { context, page, userDataDir };
}

// Closes the browser, removes its profile, prints the count and exits with the status.
export async function finish(browser, what) {
  await browser.context.close();
  fs.rmSync(browser.userDataDir, { recursive: true, force: true });
  const failed = results.filter((r) => !r[1]);
  console.log(`${results.length - failed.length}/${results.length} ${what} passed`);
  process.exit(failed.length ? 1 : 0);
}
