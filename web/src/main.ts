// The playground's shell: the header, the key dialog and a hash router over the pages.

import './style.css';
import { ProblemLike, apiKey, setApiKey, whenUnauthorized } from './api';
import { prose } from './form';
import { homePage } from './pages/home';
import { jobPage } from './pages/job';
import { listPage } from './pages/list';
import { submitPage } from './pages/submit';
import { kinds, openapi } from './schema';
import { el } from './ui';

const main = document.getElementById('main')!;
const nav = document.getElementById('nav')!;
const dialog = document.getElementById('key-dialog') as HTMLDialogElement;
const keyInput = document.getElementById('key-input') as HTMLInputElement;
const keyReason = document.getElementById('key-reason')!;
let current = new AbortController();

/**
 * The key dialog, saying why it opened: the server refused the key given, or wants one and none
 * was given (its problem's detail after), or the user opened it.
 */
function askForKey(problem?: ProblemLike): void {
  const detail = problem ? prose(problem.detail || problem.title || `HTTP ${problem.status}`) : [];
  const why = !problem
    ? [apiKey() ? 'This tab has a key; change it or forget it here.' : 'This tab has no key; give one if this server asks for it.']
    : apiKey()
      ? ['The server refused the key you gave: ', ...detail]
      : ['This server needs a key: ', ...detail];
  keyReason.replaceChildren(...why);
  keyReason.dataset.reason = !problem ? 'asked' : apiKey() ? 'refused' : 'needed';
  if (dialog.open) return;
  keyInput.value = apiKey() ?? '';
  dialog.showModal();
}
whenUnauthorized(askForKey);
document.getElementById('key-button')!.addEventListener('click', () => askForKey());
dialog.addEventListener('close', () => {
  if (dialog.returnValue === 'save') setApiKey(keyInput.value.trim() || null);
  if (dialog.returnValue === 'forget') setApiKey(null);
  if (dialog.returnValue) void route();
});

async function route(): Promise<void> {
  try {
    await show();
  } catch (e) {
    main.replaceChildren(el('p', { class: 'error', role: 'alert' }, [`The playground could not load this page: ${(e as Error).message ?? e}`]));
  }
}

async function show(): Promise<void> {
  current.abort();
  current = new AbortController();
  const signal = current.signal;
  const doc = await openapi();
  const names = kinds(doc).map((k) => k.kind);
  const [path, q] = location.hash.replace(/^#/, '').split('?');
  const parts = path.split('/').filter(Boolean);
  nav.replaceChildren(
    navLink('#/jobs', 'Jobs', parts[0] === 'jobs' && !parts[1]),
    ...names.map((k) => navLink(`#/new/${k}`, k, parts[0] === 'new' && parts[1] === k)),
    el('a', { href: '/docs/' }, ['API docs']),
  );
  main.replaceChildren();
  if (parts[0] === 'new' && parts[1]) {
    document.title = `New ${parts[1]} job — Landform`;
    submitPage(main, doc, parts[1], new URLSearchParams(q ?? ''), signal);
  } else if (parts[0] === 'jobs' && parts[1]) {
    document.title = `Job ${parts[1]} — Landform`;
    await jobPage(main, parts[1], names, signal);
  } else if (parts[0] === 'jobs') {
    document.title = 'Jobs — Landform';
    listPage(main, names, signal);
  } else {
    document.title = 'Landform playground';
    homePage(main, kinds(doc), signal);
  }
}

function navLink(href: string, text: string, active: boolean): HTMLElement {
  return el('a', { href, ...(active ? { 'aria-current': 'page' } : {}) }, [text]);
}

window.addEventListener('hashchange', () => {
  void route();
  main.focus({ preventScroll: true });
});
void route();
