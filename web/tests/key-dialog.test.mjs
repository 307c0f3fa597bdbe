// The key dialog says why it opens (issue 32, defect 10): the server needs a key and none was
// given, or it refused the key given; it does not just open again with nothing said.
import assert from 'node:assert/strict';
import { test } from 'node:test';
import { session, shot } from './harness.mjs';

const KEY = 'e2e-key-5c8e2a90d1';
const s = session([], { LANDFORM_API_KEYS: `tester ${KEY}` });

test('the key dialog: "needs a key" first, "refused the key you gave" after a wrong one, then the page', async () => {
  const page = await s.page();
  await page.goto('/');
  const dialog = page.locator('#key-dialog');
  const reason = page.locator('#key-reason');
  await dialog.waitFor({ state: 'visible' });
  assert.equal(await reason.getAttribute('data-reason'), 'needed');
  assert.match(await reason.textContent(), /^This server needs a key: this server needs an API key/);
  // The server's detail, its Markdown code span shown as code.
  assert.equal(await reason.locator('code').count(), 1);
  await page.locator('#key-input').fill('not-the-key');
  await page.getByRole('button', { name: 'Use this key' }).click();
  await page.waitForFunction(() => document.querySelector('#key-reason')?.dataset.reason === 'refused');
  await dialog.waitFor({ state: 'visible' });
  assert.match(await reason.textContent(), /^The server refused the key you gave: the API key is not known to this server/);
  await shot(page, 'key-dialog-refused');
  await page.locator('#key-input').fill(KEY);
  await page.getByRole('button', { name: 'Use this key' }).click();
  await page.waitForSelector('.kind-card');
  assert.ok(await dialog.isHidden());
  // Opened by hand: it says what the tab holds.
  await page.click('#key-button');
  assert.equal(await reason.getAttribute('data-reason'), 'asked');
  assert.match(await reason.textContent(), /This tab has a key/);
  // The console errors are the refused calls' 401s, nothing else.
  assert.deepEqual(page.errors.filter((e) => !/401/.test(e)), []);
});
