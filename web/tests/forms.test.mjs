// End-to-end: the kind pages as people edit them — a live draft beside the form, forms that fit
// (more settings folded, sliders, pairs, Run in view), defaults that run, typos named where
// they are typed, phone width, and the request as a curl command that works.
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { test } from 'node:test';
import { canvasStats, record, session, shot } from './harness.mjs';
import { post, succeeded } from './jobs.mjs';

const KINDS = ['bulldoze', 'carve-coast', 'deform-terrain', 'erode', 'grow-cave', 'weather-column'];

const s = session();

/** Wait until the preview has drawn more than `n` drafts; the last one's timing. */
async function draftsAfter(page, n, timeout = 60000) {
  await page.waitForFunction((k) => Number(document.querySelector('#draft-viewer')?.dataset.drafts ?? 0) > k, n, { timeout });
  return page.evaluate(() => {
    const d = document.querySelector('#draft-viewer').dataset;
    return { drafts: Number(d.drafts), edit_to_frame_ms: Number(d.editToFrameMs), server_s: Number(d.serverSeconds) };
  });
}

/** The draft viewer's canvas: luminance variance (a lit mesh, not a blank background). */
async function draftVariance(page) {
  return (await canvasStats(page, '#draft-viewer canvas')).variance;
}

test('live preview: every kind draws its draft, and again after an edit; the times from edit to frame', async () => {
  const page = await s.page();
  const posts = [];
  page.on('request', (r) => r.method() === 'POST' && posts.push(new URL(r.url()).pathname));
  const timing = {};
  for (const kind of KINDS) {
    await page.goto(`/#/new/${kind}`);
    const first = await draftsAfter(page, 0);
    const variance = await draftVariance(page);
    assert.ok(variance > 20, `${kind}: the draft is drawn (variance ${variance})`);
    // An edit: the seed, in the raw JSON (every kind has one); a new draft is drawn.
    await page.locator('.raw-box summary').click();
    const raw = JSON.parse(await page.locator('textarea.raw').inputValue());
    raw.seed = (raw.seed ?? 0) + 1;
    await page.locator('textarea.raw').fill(JSON.stringify(raw, null, 2));
    const edited = await draftsAfter(page, first.drafts);
    timing[kind] = { first_draft: first, after_edit: edited };
    assert.ok(edited.edit_to_frame_ms > 0 && edited.server_s > 0, JSON.stringify(edited));
    await shot(page, `draft-${kind}`);
  }
  record('draft-timing', timing);
  // Drafts only: a preview stores no job.
  assert.ok(posts.length >= 2 * KINDS.length && posts.every((p) => p.startsWith('/v1/drafts/')), posts.join(' '));
  const list = await (await fetch(`${s.url}/v1/jobs`)).json();
  assert.equal(list.items.length, 0);
  assert.deepEqual(page.errors, []);
});

test('a live-edited bulldoze road: moving the road redraws the draft, the draft before is dropped', async () => {
  const page = await s.page();
  const aborted = [];
  page.on('requestfailed', (r) => r.url().includes('/v1/drafts/') && aborted.push(r.url()));
  await page.goto('/#/new/bulldoze');
  await page.selectOption('#preset', { label: 'contour-road' });
  const before = await draftsAfter(page, 0);
  const frame0 = await page.locator('#draft-viewer canvas').screenshot();
  await page.locator('#draft-viewer').screenshot({ path: `${process.env.LANDFORM_E2E_OUT ?? 'target/playground-e2e'}/live-edited-road-before.png` });
  // The road follows the 20 m contour round the hill; it is moved up to 32 m, typed key by key
  // as a person would: one draft for the lot (debounced), any draft under way cancelled.
  const height = page.locator('[data-path="operations[1].pass.contour.height_m"] input[type=number]');
  assert.equal(await height.inputValue(), '20');
  await height.fill('');
  await height.pressSequentially('32', { delay: 30 });
  const after1 = await draftsAfter(page, before.drafts);
  const frame1 = await page.locator('#draft-viewer canvas').screenshot();
  assert.ok(!frame0.equals(frame1), 'the draft changed with the road');
  const raw = JSON.parse(await page.locator('textarea.raw').inputValue());
  assert.equal(raw.operations[1].pass.contour.height_m, 32);
  await page.locator('#draft-viewer').screenshot({ path: `${process.env.LANDFORM_E2E_OUT ?? 'target/playground-e2e'}/live-edited-road-after.png` });
  await shot(page, 'live-edited-bulldoze-road', { fullPage: false });
  record('draft-road-edit', { ...after1, aborted: aborted.length });
  assert.deepEqual(page.errors, []);
});

test('drawing on the draft: a click on the terrain adds a road vertex where it lands', async () => {
  const page = await s.page();
  await page.goto('/#/new/bulldoze');
  await page.selectOption('#preset', { label: 'contour-road' });
  const before = await draftsAfter(page, 0);
  // The ditch's path (three vertices across a 256 m terrain) takes the clicks.
  await page.selectOption('#pick-target', 'operations[2].pass.path');
  // Nothing under way (a draft landing mid-click would not matter, but the test reads a still view).
  await page.waitForFunction(() => !document.querySelector('#draft-viewer').hasAttribute('aria-busy'));
  await page.locator('.raw-box summary').click();
  const canvas = page.locator('#draft-viewer canvas');
  const box = await canvas.boundingBox();
  // The middle of the view: the camera looks at the middle of the terrain's box, so the click
  // lands on the hill near the terrain's centre (128, 128), not near the origin.
  await page.mouse.click(box.x + box.width / 2, box.y + box.height / 2);
  await page.waitForFunction(() => JSON.parse(document.querySelector('textarea.raw').value).operations[2].pass.path.length === 4, null, { timeout: 10000 });
  const after = await draftsAfter(page, before.drafts);
  const path = JSON.parse(await page.locator('textarea.raw').inputValue()).operations[2].pass.path;
  assert.equal(path.length, 4, JSON.stringify(path));
  const added = path[3];
  assert.ok(Math.hypot(added.x - 128, added.z - 128) < 60, `the vertex lands near the centre: ${JSON.stringify(added)}`);
  // A drag orbits and adds nothing.
  await page.mouse.move(box.x + 50, box.y + 50);
  await page.mouse.down();
  await page.mouse.move(box.x + 150, box.y + 80, { steps: 5 });
  await page.mouse.up();
  await page.waitForTimeout(600);
  assert.equal(JSON.parse(await page.locator('textarea.raw').inputValue()).operations[2].pass.path.length, 4);
  assert.equal(await page.locator('#pick-target').inputValue(), 'operations[2].pass.path');
  await shot(page, 'draft-click-adds-a-vertex', { fullPage: false });
  record('draft-click-vertex', { added, drafts: after.drafts });
  assert.deepEqual(page.errors, []);
});

test('forms that fit: more settings folded, Run always in view, sliders, pairs with their own bounds', async () => {
  const page = await s.page();
  const heights = {};
  for (const kind of KINDS) {
    await page.goto(`/#/new/${kind}`);
    await page.waitForSelector(`form[aria-label="New ${kind} job"] .form-fields`);
    heights[kind] = await page.evaluate(() => document.querySelector('form[aria-label]').scrollHeight);
    assert.ok((await page.locator('details.more:not([open])').count()) > 0, `${kind}: settings at their defaults are folded`);
    // Run is in the window at the top of the form and at its end.
    for (const where of ['top', 'bottom']) {
      await page.evaluate((w) => window.scrollTo(0, w === 'top' ? 0 : document.body.scrollHeight), where);
      const box = await page.locator('button[type=submit].primary').boundingBox();
      const vh = page.viewportSize().height;
      assert.ok(box && box.y >= 0 && box.y + box.height <= vh, `${kind}: Run in view at the ${where}: ${JSON.stringify(box)}`);
    }
  }
  record('form-heights', heights);
  for (const [kind, h] of Object.entries(heights)) assert.ok(h < 6000, `${kind}: form ${h} px tall`);

  // A bounded number has a slider kept with its box and the request.
  await page.goto('/#/new/weather-column');
  await page.waitForSelector('form[aria-label="New weather-column job"] .form-fields');
  await page.evaluate(() => document.querySelectorAll('details.more').forEach((d) => (d.open = true)));
  const rate = page.locator('[data-path="rate"]');
  await rate.locator('input[type=range]').fill('2');
  assert.equal(await rate.locator('input[type=number]').inputValue(), '2');
  await page.locator('.raw-box summary').click();
  assert.equal(JSON.parse(await page.locator('textarea.raw').inputValue()).rate, 2);
  await rate.locator('input[type=number]').fill('0.5');
  assert.equal(await rate.locator('input[type=range]').inputValue(), '0.5');

  // A blade's profile: points as pairs, u bounded by [-1, 1] and the height by metres.
  await page.goto('/#/new/bulldoze');
  await page.selectOption('#preset', { label: 'mound-box-add' });
  await page.evaluate(() => document.querySelectorAll('details.more').forEach((d) => (d.open = true)));
  const u = page.locator('[data-path="operations[1].pass.blade.profile[0][0]"] input[type=number]');
  const h = page.locator('[data-path="operations[1].pass.blade.profile[0][1]"] input[type=number]');
  assert.equal(await u.getAttribute('min'), '-1');
  assert.equal(await u.getAttribute('max'), '1');
  assert.equal(await h.getAttribute('min'), '-1000000');
  assert.match(await page.locator('[data-path="operations[1].pass.blade.profile[0][0]"] label').textContent(), /^u/);
  await shot(page, 'form-blade-profile-pairs');
  assert.deepEqual(page.errors, []);
});

test('defaults that run: "defaults only" drafts for every kind, and carve-coast on another job runs', async () => {
  const page = await s.page();
  for (const kind of KINDS) {
    await page.goto(`/#/new/${kind}`);
    const first = await draftsAfter(page, 0);
    await page.selectOption('#preset', '-1');
    await draftsAfter(page, first.drafts);
    assert.doesNotMatch(await page.locator('#draft-status').textContent(), /No draft/, kind);
  }
  // A full job from defaults only (weather-column's own default layer top failed before).
  await page.goto('/#/new/weather-column');
  await page.selectOption('#preset', '-1');
  await page.click('button[type=submit].primary');
  await page.waitForURL(/#\/jobs\/[0-9a-f-]{36}$/);
  const job = await succeeded(s.url, page.url().split('/').pop());
  // …and leaves a rock (with every step it weathered away entirely before).
  assert.ok(job.result.mesh.triangles > 1000, JSON.stringify(job.result.mesh));

  // carve-coast on a terrain whose heights do not reach the preset's sea level of 0 m.
  const raised = await post(s.url, '/v1/jobs/bulldoze', {
    terrain: { fractal: { size: 65, cell_size: 1.0, relief: 30.0, seed: 5 } },
    operations: [{ primitive: { shape: { box: { center: { x: 32, z: 32 }, size_x_m: 200, size_z_m: 200, height_m: 60 } }, operator: 'add' } }],
  });
  assert.equal(raised.status, 'succeeded');
  await page.goto(`/#/new/carve-coast?terrain=${raised.id}`);
  await draftsAfter(page, 0);
  assert.match(await page.locator('#draft-status').textContent(), /Draft drawn/);
  await page.locator('.raw-box summary').click();
  const body = JSON.parse(await page.locator('textarea.raw').inputValue());
  assert.deepEqual(body.terrain, { job: raised.id });
  assert.equal(body.sea_level, undefined, 'the preset’s sea level is not carried onto another terrain');
  assert.match(body.label, /^carve-coast on job /);
  // The water drawn is the level the server chose on this terrain (above 60 m: it was raised
  // by 60 m), not the 0 m of an absent field.
  const water = Number(/water (-?[\d.]+) m/.exec(await page.locator('#draft-viewer #legend-water').textContent())?.[1]);
  assert.ok(water > 60, `water at ${water} m`);
  await shot(page, 'carve-coast-on-a-raised-terrain');
  assert.deepEqual(page.errors, []);
});

test('a refused draft marks its field beside it, keeps the focus, dims the last mesh; the next draft clears it', async () => {
  const page = await s.page();
  await page.goto('/#/new/weather-column');
  const first = await draftsAfter(page, 0);
  await page.evaluate(() => document.querySelectorAll('details.more').forEach((d) => (d.open = true)));
  const steps = page.locator('[data-path="steps"] input[type=number]');
  await steps.fill('0');
  const error = page.locator('[data-path="steps"] > .error');
  await error.waitFor();
  assert.match(await error.textContent(), /at least 1/);
  assert.ok(await page.locator('#draft-viewer.stale').count(), 'the last mesh is dimmed');
  assert.equal(await steps.evaluate((e) => e === document.activeElement), true, 'the focus stays where the user types');
  assert.match(await page.locator('#draft-status').textContent(), /No draft: 422/);
  await steps.fill('150');
  await draftsAfter(page, first.drafts);
  assert.ok(await error.isHidden(), 'cleared by the next drawn draft');
  assert.equal(await page.locator('#draft-viewer.stale').count(), 0);
});

test('a typo in the raw JSON is named under it, with the field meant', async () => {
  const page = await s.page();
  await page.goto('/#/new/weather-column');
  await page.locator('.raw-box summary').click();
  const raw = JSON.parse(await page.locator('textarea.raw').inputValue());
  raw.stepz = 3;
  const area = page.locator('textarea.raw');
  await area.fill(JSON.stringify(raw, null, 2));
  const said = page.locator('.raw-box .error');
  await said.waitFor();
  assert.match(await said.textContent(), /stepz: is not a field of this object — did you mean “steps”\?/);
  const a = await area.boundingBox();
  const under = await said.boundingBox();
  assert.ok(under.y - (a.y + a.height) < 80, `said right under the JSON: ${JSON.stringify({ a, under })}`);
  // The server says the same when the request is sent anyway (the form checks first: bypass it).
  const res = await fetch(`${s.url}/v1/jobs/weather-column`, { method: 'POST', headers: { 'content-type': 'application/json' }, body: JSON.stringify(raw) });
  const problem = await res.json();
  assert.equal(problem.errors[0].field, 'stepz');
  assert.match(problem.errors[0].message, /did you mean `steps`\?/);
  await shot(page, 'raw-json-typo');
});

test('copy as curl: the command shown runs, and makes the job the form would', async () => {
  const page = await s.page();
  await page.goto('/#/new/grow-cave');
  await page.selectOption('#preset', { label: 'soda-straws' });
  await page.locator('details.request-box summary').click();
  const command = await page.locator('#request-curl').textContent();
  assert.match(command, new RegExp(`^curl -sS -X POST '${s.url}/v1/jobs/grow-cave'`));
  const answer = JSON.parse(execFileSync('bash', ['-c', command], { encoding: 'utf8', timeout: 30000 }));
  assert.equal(answer.kind, 'grow-cave');
  assert.match(answer.id, /^[0-9a-f-]{36}$/);
  const form = JSON.parse(await page.locator('textarea.raw').inputValue());
  const job = await (await fetch(`${s.url}/v1/jobs/${answer.id}`)).json();
  assert.equal(job.request.seed, form.seed ?? 0);
  assert.deepEqual(job.request.sites, form.sites);
  await shot(page, 'copy-as-curl');

  // The job's page shows the request and the answer, each with commands that do the same.
  await page.goto(`/#/jobs/${answer.id}`);
  await page.locator('#job-request summary').click();
  const shownRequest = JSON.parse(await page.locator('#job-request pre.json').textContent());
  assert.deepEqual(shownRequest, job.request);
  await page.locator('#job-response summary').click();
  const read = (await page.locator('#job-read-curl').textContent()).split('\n\n')[0];
  const got = JSON.parse(execFileSync('bash', ['-c', read], { encoding: 'utf8', timeout: 30000 }));
  assert.equal(got.id, answer.id);
  // Posting the shown request again makes the same kind of job from the same body.
  const again = JSON.parse(execFileSync('bash', ['-c', await page.locator('#job-request-curl').textContent()], { encoding: 'utf8', timeout: 30000 }));
  assert.equal(again.kind, 'grow-cave');
  assert.notEqual(again.id, answer.id);
  await shot(page, 'job-request-and-response');
  assert.deepEqual(page.errors, []);
});

test('phone width: every kind’s form at 390 px scrolls only downwards', async () => {
  const page = await s.page({ viewport: { width: 390, height: 844 }, isMobile: true, hasTouch: true });
  const widths = {};
  for (const kind of KINDS) {
    await page.goto(`/#/new/${kind}`);
    await page.waitForSelector(`form[aria-label="New ${kind} job"] .form-fields`);
    await page.evaluate(() => document.querySelectorAll('details').forEach((d) => (d.open = true)));
    widths[kind] = await page.evaluate(() => document.scrollingElement.scrollWidth);
    if (kind === 'bulldoze') await shot(page, 'phone-form-bulldoze', { fullPage: false });
    // Deep in the form, the draft is still in sight at the top of the window.
    await page.evaluate(() => window.scrollTo(0, document.body.scrollHeight / 2));
    // Measured in the page (the layout viewport): a mobile context's visual viewport may lag.
    const view = await page.evaluate(() => {
      const r = document.querySelector('#draft-viewer canvas').getBoundingClientRect();
      return { top: r.top, bottom: r.bottom, height: window.innerHeight };
    });
    assert.ok(view.top >= 0 && view.bottom <= view.height, `${kind}: the draft in view while editing: ${JSON.stringify(view)}`);
    if (kind === 'bulldoze') await shot(page, 'phone-form-bulldoze-editing', { fullPage: false });
  }
  record('phone-form-widths', widths);
  for (const [kind, w] of Object.entries(widths)) assert.ok(w <= 390, `${kind}: ${w} px wide`);
  assert.deepEqual(page.errors, []);
});
