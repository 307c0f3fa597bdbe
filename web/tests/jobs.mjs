// Jobs made through the API for the browser tests to look at, and reads of the drawn page.
import assert from 'node:assert/strict';

/** A kind's preset body as the server lists it (a copy, for the test to shrink). */
export async function presetBody(base, kind, name) {
  const presets = await (await fetch(`${base}/v1/presets?kind=${kind}`)).json();
  const p = presets.items.find((x) => x.name === name);
  assert.ok(p, `preset ${kind}/${name}`);
  return structuredClone(p.body);
}

/** POST a JSON body, the answer held until the job ends (at most 60 s); its JSON. */
export async function post(base, path, body, wait = true) {
  const res = await fetch(`${base}${path}`, {
    method: 'POST',
    headers: { 'content-type': 'application/json', ...(wait ? { prefer: 'wait=60' } : {}) },
    body: JSON.stringify(body),
  });
  assert.ok(res.ok, `${path}: ${res.status} ${await res.clone().text()}`);
  return res.json();
}

/** A finished job of `kind` from `body`; fails unless it succeeded. */
export async function finishedJob(base, kind, body) {
  return succeeded(base, await post(base, `/v1/jobs/${kind}`, body));
}

/** The job (a document or an id) once it has ended (at most 5 minutes); fails unless it succeeded. */
export async function succeeded(base, job) {
  if (typeof job === 'string') job = await (await fetch(`${base}/v1/jobs/${job}`)).json();
  for (let i = 0; i < 600 && !['succeeded', 'failed', 'cancelled'].includes(job.status); i++) {
    await new Promise((r) => setTimeout(r, 500));
    job = await (await fetch(`${base}/v1/jobs/${job.id}`)).json();
  }
  assert.equal(job.status, 'succeeded', JSON.stringify(job.error));
  return job;
}

/** An artifact's bytes. */
export async function artifactBytes(base, job, name) {
  const a = job.artifacts.find((x) => x.name === name);
  assert.ok(a, `${name} in ${job.artifacts.map((x) => x.name)}`);
  return new Uint8Array(await (await fetch(`${base}${a.href}`)).arrayBuffer());
}

/** Two animation frames: whatever the last change asked for is drawn. */
export function settle(page) {
  return page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
}

/** How far the page scrolls sideways: its scroll width against the viewport's. */
export function sideways(page) {
  return page.evaluate(() => ({ scrollWidth: document.scrollingElement.scrollWidth, width: window.innerWidth }));
}

/** The ziggurat at 65 × 65 samples over its full 128 m (2 m cells), no levels of detail: a
 * terrain with relief in about a second. */
export async function smallZiggurat(base, label) {
  const body = await presetBody(base, 'bulldoze', 'ziggurat');
  Object.assign(body.terrain.fractal, { size: 65, cell_size: 2.0 });
  body.lods = [];
  if (label) body.label = label;
  return finishedJob(base, 'bulldoze', body);
}
