// What the end-to-end tests share: a real `landform serve` on 127.0.0.1:0 with a fresh SQLite
// file, Debian's Chromium driven by playwright-core, and the artefacts folder for screenshots.
import { spawn } from 'node:child_process';
import { mkdirSync, mkdtempSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { createInterface } from 'node:readline';
import { fileURLToPath } from 'node:url';
import { after, before } from 'node:test';
import { chromium } from 'playwright-core';

export const repo = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');
export const out = process.env.LANDFORM_E2E_OUT ?? join(repo, 'target', 'playground-e2e');
mkdirSync(out, { recursive: true });

/** Start the server; resolves once it prints the address it listens on. */
export async function startServer(extraArgs = [], env = {}) {
  const bin = process.env.LANDFORM_BIN ?? join(repo, 'target', 'debug', 'landform');
  const dir = mkdtempSync(join(tmpdir(), 'landform-e2e-'));
  const child = spawn(bin, ['serve', '--addr', '127.0.0.1:0', '--database', join(dir, 'landform.db'), ...extraArgs], {
    env: { ...process.env, RUST_LOG: 'warn', ...env },
    stdio: ['ignore', 'pipe', 'inherit'],
  });
  const url = await new Promise((ok, fail) => {
    const timer = setTimeout(() => fail(new Error('the server did not start within 60 s')), 60000);
    child.on('exit', (code) => fail(new Error(`the server exited (${code})`)));
    createInterface({ input: child.stdout }).on('line', (line) => {
      const m = /^listening on (http:\/\/\S+)/.exec(line);
      if (m) {
        clearTimeout(timer);
        ok(m[1]);
      }
    });
  });
  return { url, stop: () => child.kill('SIGTERM'), dir };
}

export async function launch() {
  return chromium.launch({
    executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
    args: [
      '--headless',
      '--no-sandbox',
      '--disable-gpu',
      '--disable-background-networking',
      '--disable-component-update',
      '--disable-sync',
      '--no-first-run',
    ],
  });
}

/** A page that fails the test on any uncaught error and records console errors. */
export async function newPage(browser, base, options = {}) {
  const context = await browser.newContext({ baseURL: base, viewport: { width: 1280, height: 900 }, ...options });
  const page = await context.newPage();
  page.errors = [];
  page.on('pageerror', (e) => page.errors.push(`pageerror: ${e.message}`));
  page.on('console', (m) => {
    if (m.type() === 'error') page.errors.push(`console: ${m.text()}`);
  });
  return page;
}

export async function shot(page, name, options = {}) {
  await page.screenshot({ path: join(out, `${name}.png`), fullPage: true, ...options });
}

export function record(name, value) {
  writeFileSync(join(out, `${name}.json`), JSON.stringify(value, null, 2));
}

/**
 * A viewer's canvas (the job page's unless `selector` says another) read back in the page (it keeps its drawing buffer): the luminance
 * variance over all pixels, and a 64 × 40 grid of mean luminances to compare frames by.
 */
export async function canvasStats(page, selector = '#viewer canvas') {
  return page.evaluate((selector) => {
    const src = document.querySelector(selector);
    const w = src.width;
    const h = src.height;
    const c = document.createElement('canvas');
    c.width = w;
    c.height = h;
    const ctx = c.getContext('2d');
    ctx.drawImage(src, 0, 0);
    const px = ctx.getImageData(0, 0, w, h).data;
    let sum = 0;
    let sq = 0;
    const gw = 64;
    const gh = 40;
    const grid = new Array(gw * gh).fill(0);
    const count = new Array(gw * gh).fill(0);
    for (let y = 0; y < h; y++) {
      for (let x = 0; x < w; x++) {
        const i = (y * w + x) * 4;
        const l = 0.2126 * px[i] + 0.7152 * px[i + 1] + 0.0722 * px[i + 2];
        sum += l;
        sq += l * l;
        const g = Math.floor((y * gh) / h) * gw + Math.floor((x * gw) / w);
        grid[g] += l;
        count[g]++;
      }
    }
    const n = w * h;
    const mean = sum / n;
    return { width: w, height: h, mean, variance: sq / n - mean * mean, grid: grid.map((v, i) => v / count[i]) };
  }, selector);
}

/** Mean absolute difference of two frames' luminance grids (0–255). */
export function frameDifference(a, b) {
  let d = 0;
  for (let i = 0; i < a.grid.length; i++) d += Math.abs(a.grid[i] - b.grid[i]);
  return d / a.grid.length;
}

/** Submit the preset shown on a kind's page, after `edit` (if given) changed its fields;
 * resolves with the new job's id. */
export async function runPreset(page, kind, preset, edit) {
  await page.goto(`/#/new/${kind}`);
  await page.waitForSelector(`form[aria-label="New ${kind} job"]`);
  if (preset) await page.selectOption('#preset', { label: preset });
  if (edit) await edit(page);
  await page.click('button[type=submit].primary');
  await page.waitForURL(/#\/jobs\/[0-9a-f-]{36}$/, { timeout: 30000 });
  return page.url().split('/').pop();
}

/** Wait for the job page to show the finished result in the viewer. */
export async function waitForResult(page, timeout = 120000) {
  await page.waitForFunction(() => document.querySelector('#job-percent')?.textContent === '100 %', null, { timeout });
  await page.waitForSelector('#viewer[data-shown]', { timeout });
  // two frames after the mesh arrived
  await page.waitForFunction(() => Number(document.querySelector('#viewer canvas')?.dataset.frames ?? 0) >= 1, null, { timeout });
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
}

/**
 * A test file's server and Chromium: started before its tests and stopped after them. `url` is
 * the server's, `page(options)` a new page on it (see newPage); `setup(s)`, if given, runs once
 * they are up (a file's own `before` may run first: node:test does not order them).
 */
export function session(extraArgs = [], env = {}, setup = async () => {}) {
  const s = {
    server: null,
    browser: null,
    get url() {
      return s.server.url;
    },
    page: (options = {}) => newPage(s.browser, s.server.url, options),
  };
  before(async () => {
    s.server = await startServer(extraArgs, env);
    s.browser = await launch();
    await setup(s);
  });
  after(async () => {
    await s.browser?.close();
    s.server?.stop();
  });
  return s;
}
