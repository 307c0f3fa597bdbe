// A job's progress on its page (issue 32, defect 9): the stage, and a moving "still working"
// state with the seconds while the server's fraction stands still (never a made-up fraction);
// after success no stale snapshot or stream line; a cancelled job is a neutral notice.
import assert from 'node:assert/strict';
import { test } from 'node:test';
import { session, shot, waitForResult } from './harness.mjs';
import { post, presetBody } from './jobs.mjs';

const s = session();

/** Sample the progress block every 100 ms from the page's start. */
async function watch(page) {
  await page.addInitScript(() => {
    window.__seen = [];
    setInterval(() => {
      const bar = document.querySelector('#job-progress');
      if (!bar) return;
      const waiting = document.querySelector('#job-waiting');
      window.__seen.push({
        t: performance.now(),
        value: bar.value,
        percent: document.querySelector('#job-percent')?.textContent,
        stage: document.querySelector('#job-stage')?.textContent,
        waiting: waiting && !waiting.hidden ? waiting.textContent : null,
        moving: bar.classList.contains('waiting') && getComputedStyle(bar).animationName !== 'none',
      });
    }, 100);
  });
}

/** A job submitted from its page's form (the body as given), followed on its page. */
async function submitAndFollow(page, kind, body) {
  // Submitted by the API, then opened at once: the page follows it from its first events.
  const job = await post(s.url, `/v1/jobs/${kind}`, body, false);
  await page.goto(`/#/jobs/${job.id}`);
  return job.id;
}

test('a stage that holds its fraction shows the stage, a moving bar and the seconds; nothing stale stays after success', async () => {
  const page = await s.page();
  await watch(page);
  // The coast's meshing reports one fraction (passes of passes + 1) through all its chunks, then
  // extracts the surface and writes the mesh for seconds without a word (at 129² samples).
  const body = await presetBody(s.url, 'carve-coast', 'small-island-one-pass');
  body.terrain.fractal.size = 193;
  await submitAndFollow(page, 'carve-coast', body);
  await page.waitForSelector('#job-waiting:not([hidden])', { timeout: 60000 });
  await shot(page, 'progress-coast-meshing-working', { fullPage: false });
  await waitForResult(page);
  const seen = await page.evaluate(() => window.__seen);
  const running = seen.filter((s) => s.value < 1 && s.percent !== '100 %');
  assert.ok(running.length > 5, `sampled ${running.length} times while running`);
  // Fractions only as the server sent them: never backwards.
  for (let i = 1; i < seen.length; i++) assert.ok(seen[i].value >= seen[i - 1].value, `fraction went back: ${seen[i - 1].value} → ${seen[i].value}`);
  const meshing = running.filter((s) => /meshing/.test(s.stage));
  assert.ok(meshing.length > 0, `the meshing stage named: ${[...new Set(running.map((s) => s.stage))].join(' | ')}`);
  const waited = running.filter((s) => s.waiting && s.moving);
  assert.ok(waited.length > 0, `a moving state while the fraction stood: ${JSON.stringify(running.slice(-5))}`);
  assert.match(waited[waited.length - 1].waiting, /\d+ s since the last step/);
  // After success: no live snapshot, no "following the event stream", the bar at 100 %.
  assert.equal(await page.locator('#job-percent').textContent(), '100 %');
  assert.equal(await page.locator('#job-stage').textContent(), 'done');
  assert.ok(await page.locator('#job-stream').isHidden(), 'the stream line is gone');
  assert.ok(await page.locator('figure.live').isHidden(), 'the live snapshot is gone');
  assert.ok(await page.locator('#job-waiting').isHidden());
  assert.deepEqual(page.errors, []);
});

test('deform-terrain: a search that meets its goal early ends short of its limit; the page says so and shows only the server\'s fractions', async () => {
  const page = await s.page();
  await watch(page);
  // The tileable preset's search stops at its epsilon after some 80 of its 1500 iterations.
  const body = await presetBody(s.url, 'deform-terrain', 'tileable');
  const stream = page.waitForResponse((r) => /\/v1\/jobs\/[^/]+\/events$/.test(r.url()), { timeout: 60000 });
  const id = await submitAndFollow(page, 'deform-terrain', body);
  const sent = (await (await stream).text()).split('\n').filter((l) => l.startsWith('data: {"fraction"')).map((l) => JSON.parse(l.slice(6)));
  await waitForResult(page, 120000);
  const job = await (await fetch(`${s.url}/v1/jobs/${id}`)).json();
  assert.equal(job.result.stopped, 'epsilon');
  const last = sent[sent.length - 1];
  assert.ok(last.step < last.steps, JSON.stringify(last));
  // Every value the bar showed is one the server sent (or the start and the end): none made up.
  const fractions = new Set([0, 1, ...sent.map((p) => p.fraction)]);
  const seen = await page.evaluate(() => window.__seen);
  assert.deepEqual(seen.map((s) => s.value).filter((v) => !fractions.has(v)), []);
  assert.equal(await page.locator('#job-stage').textContent(), `done — the search stopped at step ${last.step} of ${last.steps} (epsilon: its goal was met)`);
  await shot(page, 'progress-deform-ended-early');
  assert.deepEqual(page.errors, []);
});

test('a cancelled job says cancelled: no 0 %, no "running: cancelled", no error box', async () => {
  const page = await s.page();
  const body = await presetBody(s.url, 'deform-terrain', 's-road');
  body.max_iterations = 6000;
  const id = await submitAndFollow(page, 'deform-terrain', body);
  await page.waitForFunction(() => /running/.test(document.querySelector('#job-status')?.textContent ?? ''), null, { timeout: 60000 });
  await page.getByRole('button', { name: 'Cancel' }).click();
  await page.waitForFunction(() => /cancelled/.test(document.querySelector('#job-status')?.textContent ?? ''), null, { timeout: 30000 });
  await page.locator('#job-cancelled').waitFor();
  const job = await (await fetch(`${s.url}/v1/jobs/${id}`)).json();
  assert.equal(job.status, 'cancelled');
  assert.equal(await page.locator('#job-stage').textContent(), 'cancelled');
  assert.equal(await page.locator('#job-percent').textContent(), '');
  assert.ok(await page.locator('#job-progress').isHidden(), 'no bar for a cancelled job');
  assert.equal(await page.locator('#job-error').count(), 0, 'no error box');
  assert.equal(await page.locator('main [role=alert], main .error').count(), 0, 'no alert, nothing in red');
  assert.match(await page.locator('#job-cancelled').textContent(), /cancelled/);
  await shot(page, 'job-cancelled');
  // The same page opened afresh (the job ended before the page): the same.
  await page.reload();
  await page.locator('#job-cancelled').waitFor();
  assert.equal(await page.locator('#job-stage').textContent(), 'cancelled');
  assert.equal(await page.locator('#job-error').count(), 0);
  assert.deepEqual(page.errors, []);
});
