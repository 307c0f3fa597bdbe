// A server that requires API keys: the page asks for one, keeps it in the tab's session storage
// only, and every call it makes then carries it.
import assert from 'node:assert/strict';
import { test } from 'node:test';
import { session, shot } from './harness.mjs';

const KEY = 'e2e-key-7f3a9c1d5b';
const s = session([], { LANDFORM_API_KEYS: `tester ${KEY}` });

test('the page asks for a key, keeps it in session storage only, and sends it', async () => {
  const page = await s.page();
  const auth = [];
  page.on('request', (r) => r.url().includes('/v1/') && auth.push(r.headers().authorization ?? null));
  await page.goto('/#/jobs');
  const dialog = page.locator('#key-dialog');
  await dialog.waitFor({ state: 'visible' });
  assert.equal(auth[0], null, 'the first call had no key');
  await shot(page, 'keys-dialog');
  await page.locator('#key-input').fill(KEY);
  await page.getByRole('button', { name: 'Use this key' }).click();
  await page.waitForSelector('table.jobs');
  assert.equal(auth[auth.length - 1], `Bearer ${KEY}`);
  const stored = await page.evaluate(() => ({
    session: sessionStorage.getItem('landform-api-key'),
    local: Object.keys(localStorage).length,
    cookies: document.cookie,
  }));
  assert.deepEqual(stored, { session: KEY, local: 0, cookies: '' });

  // A job runs with the key: submit, stream (fetch-based SSE carries the header), artifacts.
  await page.goto('/#/new/bulldoze');
  await page.selectOption('#preset', { label: 'mound-box-add' });
  await page.click('button[type=submit].primary');
  await page.waitForURL(/#\/jobs\/[0-9a-f-]{36}$/);
  await page.waitForFunction(() => document.querySelector('#job-percent')?.textContent === '100 %', null, { timeout: 60000 });
  await page.waitForSelector('#viewer[data-shown]', { timeout: 60000 });
  assert.ok(auth.every((a, i) => i === 0 || a === `Bearer ${KEY}`), `every call after the first carried the key: ${auth}`);

  // Another tab has no key: session storage is the tab's own.
  const other = await s.page();
  await other.goto('/#/jobs');
  await other.locator('#key-dialog').waitFor({ state: 'visible' });
  assert.equal(await other.evaluate(() => sessionStorage.getItem('landform-api-key')), null);
});
