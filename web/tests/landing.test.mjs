// The landing page (issue 32, defect 10) and phone width (defect 4): what Landform makes, a card
// per kind with a picture, its summary and "Try it", the recent jobs; and at 390 px wide no page
// of the list, the landing page or a job's result scrolls sideways.
import assert from 'node:assert/strict';
import { createRequire } from 'node:module';
import { test } from 'node:test';
import { session, shot, waitForResult } from './harness.mjs';
import { post, sideways, smallZiggurat } from './jobs.mjs';

const axePath = createRequire(import.meta.url).resolve('axe-core/axe.min.js');
let terrain;
const s = session([], {}, async (up) => {
  // A finished job with a long label, and replays of it (which the recent jobs leave out).
  terrain = await smallZiggurat(up.url, 'a ziggurat with a label long enough to wrap on a phone screen');
  for (let k = 0; k < 3; k++) await post(up.url, `/v1/jobs/${terrain.id}/replay`, { until_step: k });
});

test('the landing page: an introduction, a card per kind with its picture and one line from the API document, the recent jobs', async () => {
  const doc = await (await fetch(`${s.url}/openapi.json`)).json();
  const kinds = Object.entries(doc.paths)
    .filter(([p, item]) => /^\/v1\/jobs\/[a-z-]+$/.test(p) && item.post)
    .map(([p, item]) => ({ kind: p.slice('/v1/jobs/'.length), line: item.post.description.split('\n')[0] }));
  assert.ok(kinds.length >= 6);
  const page = await s.page();
  await page.goto('/');
  await page.waitForSelector('.kind-card');
  assert.match(await page.locator('main h1').textContent(), /Landform/);
  assert.match(await page.locator('main .intro').textContent(), /terrain/);
  const cards = page.locator('.kind-card');
  assert.equal(await cards.count(), kinds.length);
  for (const { kind, line } of kinds) {
    const card = page.locator(`.kind-card[data-kind="${kind}"]`);
    assert.equal(await card.locator('p').first().textContent(), line);
    assert.equal(await card.locator('button[data-try]').textContent(), 'Try it');
    // A real picture, served from the bundle's assets.
    const img = card.locator('img');
    await img.scrollIntoViewIfNeeded();
    await page.waitForFunction((k) => {
      const i = document.querySelector(`.kind-card[data-kind="${k}"] img`);
      return i?.complete && i.naturalWidth > 0;
    }, kind);
    assert.match(await img.getAttribute('src'), /^(\/assets\/|data:image\/png)/);
    assert.ok((await img.getAttribute('alt')).includes(kind));
  }
  // The recent jobs: newest first, replays left out, with their pictures.
  await page.waitForSelector('#recent-jobs li');
  const listed = await page.locator('#recent-jobs li').evaluateAll((li) => li.map((x) => x.dataset.job));
  const newest = (await (await fetch(`${s.url}/v1/jobs?limit=6&replays=false`)).json()).items.map((j) => j.id);
  assert.deepEqual(listed, newest);
  assert.ok(listed.includes(terrain.id));
  await page.waitForFunction(() => [...document.querySelectorAll('#recent-jobs img.thumb:not(.empty)')].every((i) => i.complete && i.naturalWidth > 0));
  assert.ok((await page.locator('#recent-jobs img.thumb:not(.empty)').count()) >= 1);
  await shot(page, 'landing');
  // The brand goes home; Jobs is the full list.
  await page.goto('/#/jobs');
  await page.waitForSelector('table.jobs');
  await page.click('header a.brand');
  await page.waitForSelector('.kind-card');
  assert.ok(page.url().endsWith('#/'));
  assert.deepEqual(page.errors, []);
});

test('Try it runs the kind\'s quick preset at once and opens its job', async () => {
  const page = await s.page();
  const bodies = [];
  page.on('request', (r) => r.method() === 'POST' && r.url().includes('/v1/jobs/') && bodies.push({ url: r.url(), body: r.postDataJSON() }));
  await page.goto('/');
  const kind = 'weather-column';
  const presets = (await (await fetch(`${s.url}/v1/presets?kind=${kind}`)).json()).items;
  // weather-column's quick preset (web/src/presets.ts): the goblin cap.
  const first = presets.find((p) => p.name === 'goblin-cap');
  assert.ok(first, presets.map((p) => p.name).join(' '));
  await page.locator(`button[data-try="${kind}"]`).click();
  await page.waitForURL(/#\/jobs\/[0-9a-f-]{36}$/, { timeout: 30000 });
  assert.equal(bodies.length, 1);
  assert.ok(bodies[0].url.endsWith(`/v1/jobs/${kind}`));
  assert.deepEqual(bodies[0].body, first.body);
  const id = page.url().split('/').pop();
  const job = await (await fetch(`${s.url}/v1/jobs/${id}`)).json();
  assert.equal(job.kind, kind);
  await waitForResult(page, 180000);
  assert.deepEqual(page.errors, []);
});

test('phone width (390 px): the landing page, the job list and a job\'s result do not scroll sideways', async () => {
  const page = await s.page({ viewport: { width: 390, height: 844 }, deviceScaleFactor: 1, isMobile: true, hasTouch: true });
  // Every page is measured, then the test fails with all that scroll sideways.
  const wide = [];
  const check = async (name) => {
    // Lazy pictures drawn before the full-page screenshot.
    await page.evaluate(async () => {
      for (const i of document.images) {
        i.scrollIntoView();
        await i.decode().catch(() => {});
      }
      window.scrollTo(0, 0);
    });
    const side = await sideways(page);
    await shot(page, `phone-${name}`);
    if (side.scrollWidth > 390) wide.push(`${name}: scroll width ${side.scrollWidth} at ${side.width} px`);
  };
  await page.goto('/');
  await page.waitForSelector('main h1');
  await page.waitForFunction(() => !document.querySelector('main [role=status]')?.textContent && document.querySelector('main img'));
  await check('landing');
  await page.goto('/#/jobs');
  await page.waitForSelector('table.jobs tbody tr');
  await page.waitForFunction(() => [...document.querySelectorAll('table.jobs img.thumb:not(.empty)')].every((i) => i.complete));
  await check('jobs');
  // The list's rows as cards: every cell within the screen.
  const widest = await page.locator('table.jobs tbody tr').evaluateAll((rows) => Math.max(...rows.map((r) => r.getBoundingClientRect().right)));
  if (widest > 390) wide.push(`job list rows reach ${widest} px`);
  await page.goto(`/#/jobs/${terrain.id}`);
  await waitForResult(page);
  await check('job');
  await page.locator('#view-h').scrollIntoViewIfNeeded();
  await shot(page, 'phone-job-viewer', { fullPage: false });
  // Long values wrap: the figures table stays within the screen.
  const right = await page.locator('table.figures').evaluate((t) => t.getBoundingClientRect().right);
  if (right > 390) wide.push(`figures reach ${right} px`);
  assert.deepEqual(wide, []);
  assert.deepEqual(page.errors, []);
});

test('accessibility: no serious or critical axe-core violations on the landing page, light and dark, wide and narrow', async () => {
  // The page's CSP refuses injected scripts; the audit needs one.
  const page = await s.page({ bypassCSP: true });
  await page.goto('/');
  await page.waitForSelector('#recent-jobs li');
  for (const [scheme, width] of [['light', 1280], ['dark', 1280], ['dark', 390]]) {
    await page.emulateMedia({ colorScheme: scheme });
    await page.setViewportSize({ width, height: 844 });
    await page.addScriptTag({ path: axePath });
    const result = await page.evaluate(() => window.axe.run(document, { resultTypes: ['violations'] }));
    const bad = result.violations.filter((v) => v.impact === 'serious' || v.impact === 'critical');
    assert.deepEqual(bad.map((v) => `${v.id}: ${v.nodes.map((n) => n.target.join(' ')).slice(0, 3).join(', ')}`), [], `${scheme} ${width}`);
  }
});
