// End-to-end: the playground in headless Chromium against a real server started here.
import assert from 'node:assert/strict';
import { createRequire } from 'node:module';
import { test } from 'node:test';
import { canvasStats, frameDifference, record, runPreset, session, shot, waitForResult } from './harness.mjs';

const axePath = createRequire(import.meta.url).resolve('axe-core/axe.min.js');
const s = session();

/** Every value the progress bar showed, sampled in the page. */
async function watchProgress(page) {
  await page.addInitScript(() => {
    window.__progress = [];
    setInterval(() => {
      const bar = document.querySelector('#job-progress');
      if (bar && window.__progress[window.__progress.length - 1] !== bar.value) window.__progress.push(bar.value);
    }, 20);
  });
}

test('first paint and the shipped page', async () => {
  const page = await s.page();
  await page.goto('/');
  await page.waitForSelector('table.jobs, main p.muted[role=status]');
  await page.waitForFunction(() => document.querySelector('nav#nav a[href="#/new/bulldoze"]'));
  const timing = await page.evaluate(() => {
    const paint = Object.fromEntries(performance.getEntriesByType('paint').map((e) => [e.name, e.startTime]));
    const nav = performance.getEntriesByType('navigation')[0];
    const transferred = performance.getEntriesByType('resource').reduce((s, r) => s + (r.transferSize || 0), nav.transferSize || 0);
    return { ...paint, dom_content_loaded: nav.domContentLoadedEventEnd, jobs_list_shown: performance.now(), transferred };
  });
  record('first-paint', timing);
  assert.ok(timing['first-contentful-paint'] > 0, JSON.stringify(timing));
  assert.deepEqual(page.errors, []);
});

test('a bulldoze job from its preset: progress to 100 %, a drawn 3D frame, and the timeline', async () => {
  const page = await s.page();
  await watchProgress(page);
  const id = await runPreset(page, 'bulldoze', 'ziggurat');
  await waitForResult(page);
  assert.equal(await page.locator('#job-percent').textContent(), '100 %');
  assert.equal(await page.locator('#job-progress').evaluate((b) => b.value), 1);
  assert.match(await page.locator('#job-status').textContent(), /succeeded/);
  const seen = await page.evaluate(() => window.__progress);
  assert.equal(seen[seen.length - 1], 1, `progress values ${seen}`);

  // A drawn frame: a terrain lit by the sun, not a flat background.
  const full = await canvasStats(page);
  assert.ok(full.variance > 100, `luminance variance ${full.variance}`);
  await shot(page, 'bulldoze-job');
  await page.locator('#viewer canvas').screenshot({ path: `${process.env.LANDFORM_E2E_OUT ?? '../target/playground-e2e'}/bulldoze-canvas.png` });

  // The level-of-detail list names what is shown: the full mesh, listed first.
  assert.equal(await page.locator('#lod').inputValue(), 'mesh.glb');
  assert.match(await page.locator('#lod option').first().textContent(), /^full /);
  assert.equal(await page.locator('#viewer').getAttribute('data-shown'), `${id}/mesh.glb`);

  // The timeline: step 0 of the ziggurat is the mound before the spiral is cut.
  const steps = Number(await page.locator('#timeline').getAttribute('max'));
  assert.ok(steps > 10, `steps ${steps}`);
  await page.locator('#timeline').fill('0');
  await page.waitForFunction(() => document.querySelector('.timeline')?.dataset.shownStep === '0', null, { timeout: 60000 });
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  const early = await canvasStats(page);
  const moved = frameDifference(full, early);
  assert.ok(moved > 1.0, `frame difference between step ${steps} and step 0: ${moved}`);
  const shown = await page.locator('#viewer').getAttribute('data-shown');
  assert.ok(!shown.startsWith(id), `the viewer shows a replay, not ${shown}`);
  assert.ok(shown.endsWith('/mesh.glb'), `a timeline move keeps the full mesh, not ${shown}`);
  assert.equal(await page.locator('#lod').inputValue(), 'mesh.glb');
  // The replay is the original's operations up to step 0, made by the server.
  const replay = await (await fetch(`${s.url}/v1/jobs/${shown.split('/')[0]}`)).json();
  assert.equal(replay.replay_of, id);
  assert.equal(replay.replay_until_step, 0);
  await shot(page, 'bulldoze-timeline-step-0');

  // Back to the end: the cached result, the first frame again.
  await page.locator('#timeline').fill(String(steps));
  await page.waitForFunction((s) => document.querySelector('.timeline')?.dataset.shownStep === String(s), steps, { timeout: 60000 });
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  const back = await canvasStats(page);
  assert.ok(frameDifference(full, back) < 0.5, `back at the end: ${frameDifference(full, back)}`);
  assert.deepEqual(page.errors, []);
});

test('composition: carve-coast on a deform-terrain result picked from the thumbnails', async () => {
  const page = await s.page();
  const island = await runPreset(page, 'deform-terrain', 'star-island');
  await waitForResult(page);
  await page.goto('/#/new/carve-coast');
  await page.selectOption('#preset', { label: 'small-island-one-pass' });
  const pick = page.locator(`button.pick[data-job="${island}"]`);
  await pick.waitFor();
  await pick.click();
  await page.locator(`button.pick[data-job="${island}"][aria-pressed="true"]`).waitFor();
  // The star island stands 27–95 m high: the sea goes to 50 m, set in the form.
  await page.locator('[data-path="sea_level"] input').fill('50');
  const raw = JSON.parse(await page.locator('textarea.raw').inputValue());
  assert.deepEqual(raw.terrain, { job: island });
  assert.equal(raw.sea_level, 50);
  await page.click('button[type=submit].primary');
  await page.waitForURL(/#\/jobs\/[0-9a-f-]{36}$/);
  const coast = page.url().split('/').pop();
  await waitForResult(page);
  const job = await (await fetch(`${s.url}/v1/jobs/${coast}`)).json();
  assert.equal(job.status, 'succeeded');
  assert.deepEqual(job.request.terrain, { job: island });
  assert.ok(await page.locator('#sea').isChecked(), 'the sea plane is offered');
  const stats = await canvasStats(page);
  assert.ok(stats.variance > 100, `variance ${stats.variance}`);
  await shot(page, 'carve-coast-on-deform-terrain');
  assert.deepEqual(page.errors, []);
});

test('bad fields: the schema bound is checked before sending, the server 422 is shown beside its field', async () => {
  const page = await s.page();
  const posts = [];
  // Submissions only: the live draft posts to /v1/drafts/ as the form changes.
  page.on('request', (r) => r.method() === 'POST' && r.url().includes('/v1/jobs/') && posts.push(r.url()));
  await page.goto('/#/new/grow-cave');
  await page.selectOption('#preset', { label: 'columns' });
  // The field is at its default: among the settings folded under "More settings".
  await page.locator('details.more[data-more=""] > summary').click();
  const field = page.locator('[data-path="stalactite_radius_m"]');
  const input = field.locator('input[type=number]');
  // Beyond the schema's maximum: refused in the page, nothing sent.
  await input.fill('20000');
  await page.click('button[type=submit].primary');
  await field.locator('.error').waitFor();
  assert.match(await field.locator('.error').textContent(), /at most 10000/);
  assert.equal(await input.getAttribute('aria-invalid'), 'true');
  assert.deepEqual(posts, []);
  // Within the schema's bound but taller than the chamber: the server's 422 names the field.
  await input.fill('9000');
  await page.click('button[type=submit].primary');
  await page.waitForFunction(() => /422/.test(document.querySelector('.actions [role=status]')?.textContent ?? ''));
  assert.equal(posts.length, 1);
  const message = await field.locator('.error').textContent();
  assert.match(message, /height/i, message);
  assert.ok(await field.locator('.error').isVisible());
  assert.ok(page.url().endsWith('#/new/grow-cave'), 'still on the form');
  // The raw JSON drives the form too.
  await page.locator('.raw-box summary').click();
  const raw = JSON.parse(await page.locator('textarea.raw').inputValue());
  assert.equal(raw.stalactite_radius_m, 9000);
  raw.rings = 7;
  await page.locator('textarea.raw').fill(JSON.stringify(raw, null, 2));
  await page.waitForFunction(() => document.querySelector('[data-path="rings"] input[type=number]')?.value === '7');
  await shot(page, 'grow-cave-422');
});

test('every kind: a finished job on its page', async () => {
  const page = await s.page();
  const presets = { 'weather-column': 'goblin-cap', 'grow-cave': 'columns', 'deform-terrain': 'tileable', 'carve-coast': 'small-island-one-pass', bulldoze: 'hillside-road', erode: 'eroded-island' };
  for (const [kind, preset] of Object.entries(presets)) {
    await runPreset(page, kind, preset);
    await waitForResult(page);
    const stats = await canvasStats(page);
    assert.ok(stats.variance > 50, `${kind}: variance ${stats.variance}`);
    await page.waitForFunction(() => [...document.querySelectorAll('.maps img')].every((i) => i.complete && i.naturalWidth > 0));
    await shot(page, `kind-${kind}`);
  }
  // The list: newest first, every kind there, with thumbnails.
  await page.goto('/#/jobs');
  await page.waitForSelector('table.jobs tbody tr');
  const kinds = await page.locator('table.jobs tbody tr td:nth-child(2)').allTextContents();
  for (const k of Object.keys(presets)) assert.ok(kinds.includes(k), `${k} in ${kinds}`);
  await page.waitForFunction(() => [...document.querySelectorAll('table.jobs img.thumb:not(.empty)')].every((i) => i.complete && i.naturalWidth > 0));
  await shot(page, 'job-list');
  await page.selectOption('#filter-kind', 'grow-cave');
  await page.waitForFunction(() => [...document.querySelectorAll('table.jobs tbody tr td:nth-child(2)')].every((td) => td.textContent === 'grow-cave'));
  await shot(page, 'job-list-grow-cave');
  // First meaningful paint with a populated list: a fresh tab (cold cache) until the rows, and
  // until every thumbnail has drawn.
  const fresh = await s.page();
  await fresh.goto('/#/jobs');
  await fresh.waitForSelector('table.jobs tbody tr');
  const rows = await fresh.evaluate(() => performance.now());
  await fresh.waitForFunction(() => [...document.querySelectorAll('table.jobs img.thumb:not(.empty)')].every((i) => i.complete && i.naturalWidth > 0));
  const thumbs = await fresh.evaluate(() => performance.now());
  const fcp = await fresh.evaluate(() => performance.getEntriesByName('first-contentful-paint')[0]?.startTime);
  record('first-paint-populated', { first_contentful_paint: fcp, rows_shown: rows, thumbnails_drawn: thumbs, jobs: kinds.length });
  assert.deepEqual(page.errors, []);
});

test('a dropped event stream is resumed with Last-Event-ID', async () => {
  const page = await s.page();
  const resumed = [];
  let cut = null;
  // The first stream is cut after its first two events (no `done`): the page must reconnect and
  // say which event it saw last.
  await page.route('**/v1/jobs/*/events', async (route) => {
    if (cut === null) {
      const res = await route.fetch();
      const events = (await res.text()).split('\n\n').filter((e) => /^id:/m.test(e));
      const kept = events.slice(0, 2);
      cut = /^id: ?(\S+)/m.exec(kept[kept.length - 1])[1];
      await route.fulfill({ status: 200, headers: { 'content-type': 'text/event-stream' }, body: `${kept.join('\n\n')}\n\n` });
    } else {
      resumed.push(route.request().headers()['last-event-id'] ?? null);
      await route.continue();
    }
  });
  await runPreset(page, 'weather-column', 'gumdrop');
  await waitForResult(page);
  assert.ok(cut !== null);
  assert.deepEqual(resumed.slice(0, 1), [cut]);
  assert.match(await page.locator('#job-stream').textContent(), new RegExp(`reconnected after event ${cut}`));
  assert.deepEqual(page.errors, []);
});

test('accessibility: no serious or critical axe-core violations on the form, job and list pages', async () => {
  // The page's CSP refuses injected scripts; the audit needs one.
  const page = await s.page({ bypassCSP: true });
  const audit = async (name) => {
    await page.addScriptTag({ path: axePath });
    const result = await page.evaluate(() => window.axe.run(document, { resultTypes: ['violations'] }));
    const bad = result.violations.filter((v) => v.impact === 'serious' || v.impact === 'critical');
    record(`axe-${name}`, result.violations.map((v) => ({ id: v.id, impact: v.impact, nodes: v.nodes.length })));
    assert.deepEqual(bad.map((v) => `${v.id}: ${v.nodes.map((n) => n.target.join(' ')).slice(0, 3).join(', ')}`), [], name);
  };
  await page.goto('/#/new/bulldoze');
  await page.waitForSelector('form[aria-label="New bulldoze job"]');
  await audit('bulldoze-form');
  await runPreset(page, 'grow-cave', 'columns');
  await waitForResult(page);
  await audit('grow-cave-job');
  await page.goto('/#/jobs');
  await page.waitForSelector('table.jobs tbody tr');
  await audit('job-list');
  // The dark scheme too (the page follows prefers-color-scheme).
  await page.emulateMedia({ colorScheme: 'dark' });
  await audit('job-list-dark');
  await page.goto('/#/new/carve-coast');
  await page.waitForSelector('form[aria-label="New carve-coast job"]');
  await audit('carve-coast-form-dark');
  await page.emulateMedia({ colorScheme: 'light' });
  // Keyboard: the form's fields and the submit button are reached with Tab alone.
  await page.goto('/#/new/weather-column');
  await page.waitForSelector('form[aria-label="New weather-column job"]');
  const reached = new Set();
  for (let i = 0; i < 400 && !reached.has('submit'); i++) {
    await page.keyboard.press('Tab');
    reached.add(await page.evaluate(() => (document.activeElement?.type === 'submit' ? 'submit' : document.activeElement?.tagName)));
  }
  assert.ok(reached.has('submit') && reached.has('INPUT') && reached.has('SELECT'), [...reached].join());
});

test('live snapshots appear as the job runs, and cancel stops it', async () => {
  const page = await s.page();
  // The S-road converges in about a second now: six times its iterations (96 000 operations,
  // within the server's cap) keep it running long enough to be watched and cancelled.
  const id = await runPreset(page, 'deform-terrain', 's-road', (p) =>
    p.locator('[data-path="max_iterations"] input').fill('6000'),
  );
  await page.waitForFunction(() => {
    const img = document.querySelector('#live-snapshot');
    return Number(img?.dataset.count ?? 0) >= 1 && img.complete && img.naturalWidth > 0;
  }, null, { timeout: 60000 });
  assert.match(await page.locator('#job-status').textContent(), /running/);
  await shot(page, 'deform-terrain-live-snapshot');
  await page.getByRole('button', { name: 'Cancel' }).click();
  await page.waitForFunction(() => /cancelled/.test(document.querySelector('#job-status')?.textContent ?? ''), null, { timeout: 30000 });
  const job = await (await fetch(`${s.url}/v1/jobs/${id}`)).json();
  assert.equal(job.status, 'cancelled');
  // Cancelled is a notice, not an error (progress.test.mjs checks it further).
  assert.ok(await page.locator('#job-cancelled').isVisible());
  assert.deepEqual(page.errors, []);
});

test('help text: readable bounds and code spans, no raw Markdown', async () => {
  const page = await s.page();
  await page.goto('/#/new/bulldoze');
  await page.selectOption('#preset', { label: 'ziggurat' });
  const seedHelp = await page.locator('[data-path="seed"] small.help').textContent();
  // u64::MAX arrives as 18446744073709552000 (a JSON number past 2^53): shown by its name.
  assert.ok(!/18446744073709552000/.test(seedHelp), seedHelp);
  assert.match(seedHelp, /≤ 2⁶⁴ − 1/);
  const helps = await page.locator('small.help').allTextContents();
  assert.ok(helps.length > 10, `${helps.length} help texts`);
  assert.deepEqual(helps.filter((h) => h.includes('`')), [], 'no raw backticks');
  assert.ok((await page.locator('small.help code').count()) > 0, 'code spans shown as <code>');
  assert.deepEqual(page.errors, []);
});

test('the job list: replays are filtered by the server, so a page of them hides no job behind it', async () => {
  // A job, then 25 replays of it, as a timeline makes them (one per position): newer than it.
  const post = async (path, body) => {
    const res = await fetch(`${s.url}${path}`, {
      method: 'POST',
      headers: { 'content-type': 'application/json', prefer: 'wait=60' },
      body: JSON.stringify(body),
    });
    assert.ok(res.ok, `${path}: ${res.status}`);
    return res.json();
  };
  const presets = await (await fetch(`${s.url}/v1/presets?kind=bulldoze`)).json();
  const body = structuredClone(presets.items.find((p) => p.name === 'ziggurat').body);
  body.terrain.fractal.size = 65;
  body.lods = [];
  body.label = 'behind its replays';
  const job = await post('/v1/jobs/bulldoze', body);
  assert.equal(job.status, 'succeeded');
  for (let k = 0; k < 25; k++) await post(`/v1/jobs/${job.id}/replay`, { until_step: k });

  const page = await s.page();
  await page.goto('/#/jobs');
  await page.waitForSelector('table.jobs');
  const row = page.locator(`table.jobs a[href="#/jobs/${job.id}"]`).first();
  await row.waitFor();
  assert.ok(!/No jobs here yet/.test(await page.locator('main').textContent()));
  assert.equal(await page.locator('table.jobs tbody tr', { hasText: 'replay to step' }).count(), 0);
  // With replays shown, the newest page is the replays.
  await page.locator('#filter-replays').check();
  await page.waitForFunction(() => document.querySelectorAll('table.jobs tbody tr').length > 0 && /replay to step/.test(document.querySelector('table.jobs').textContent));
  assert.ok((await page.locator('table.jobs tbody tr', { hasText: 'replay to step' }).count()) >= 10);
  await shot(page, 'job-list-without-replays');
  assert.deepEqual(page.errors, []);
});

test('the viewer: a terrain cannot be orbited under, and Frame all (button, F) brings it back', async () => {
  const presets = await (await fetch(`${s.url}/v1/presets?kind=bulldoze`)).json();
  const body = structuredClone(presets.items.find((p) => p.name === 'ziggurat').body);
  body.terrain.fractal.size = 65;
  body.lods = [];
  const res = await fetch(`${s.url}/v1/jobs/bulldoze`, {
    method: 'POST',
    headers: { 'content-type': 'application/json', prefer: 'wait=60' },
    body: JSON.stringify(body),
  });
  const job = await res.json();
  assert.equal(job.status, 'succeeded');
  const page = await s.page();
  await page.goto(`/#/jobs/${job.id}`);
  await waitForResult(page);
  const canvas = page.locator('#viewer canvas');
  const polar = async () => {
    await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
    return Number(await canvas.getAttribute('data-polar'));
  };
  const framed = await polar();
  assert.ok(framed > 0.3 && framed < 1.4, `framed at ${framed} rad from straight up`);
  // Drag upwards far: an unlimited orbit swings the camera under the terrain (polar near π).
  const drag = async (dy) => {
    const box = await canvas.boundingBox();
    const [x, y] = [box.x + box.width / 2, box.y + box.height / 2];
    await page.mouse.move(x, y);
    await page.mouse.down();
    for (let k = 1; k <= 20; k++) await page.mouse.move(x, y + (dy * k) / 20);
    await page.mouse.up();
  };
  await drag(-400);
  await drag(-400);
  const under = await polar();
  assert.ok(under <= Math.PI / 2, `the camera went ${under} rad from straight up: under the ground`);
  assert.ok(under > framed + 0.1, `the drag moved the camera (${framed} → ${under})`);
  await shot(page, 'viewer-orbit-limited');
  // The splat map's picture is not a blank tile: its weights mixed into opaque colours.
  const splat = page.locator('img[data-name="splatmap.png"]');
  await page.waitForFunction(() => document.querySelector('img[data-name="splatmap.png"]')?.src.startsWith('data:'));
  await page.waitForFunction(() => document.querySelector('img[data-name="splatmap.png"]')?.complete);
  const stats = await splat.evaluate((img) => {
    const c = document.createElement('canvas');
    c.width = img.naturalWidth;
    c.height = img.naturalHeight;
    const ctx = c.getContext('2d');
    ctx.drawImage(img, 0, 0);
    const d = ctx.getImageData(0, 0, c.width, c.height).data;
    let opaque = 0;
    let coloured = 0;
    for (let k = 0; k < d.length; k += 4) {
      opaque += d[k + 3] === 255;
      coloured += d[k] + d[k + 1] + d[k + 2] > 30;
    }
    return { pixels: d.length / 4, opaque, coloured };
  });
  assert.equal(stats.opaque, stats.pixels, JSON.stringify(stats));
  assert.ok(stats.coloured > stats.pixels / 2, JSON.stringify(stats));
  assert.match(await page.locator('figure', { has: splat }).locator('figcaption').textContent(), /false colour/);
  await page.click('#frame-all');
  assert.ok(Math.abs((await polar()) - framed) < 0.01, 'Frame all puts the camera back');
  await drag(300);
  assert.ok(Math.abs((await polar()) - framed) > 0.1, 'dragged away again');
  await canvas.focus();
  await page.keyboard.press('f');
  assert.ok(Math.abs((await polar()) - framed) < 0.01, 'F frames it all');
  assert.deepEqual(page.errors, []);
});
