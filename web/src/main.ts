// The playground's shell: the header, the key dialog and a hash router over the three pages.

import './style.css';
import { apiKey, setApiKey, whenUnauthorized } from './api';
import { jobPage } from './pages/job';
import { listPage } from './pages/list';
import { submitPage } from './pages/submit';
import { kinds, openapi } from './schema';
import { el } from './ui';

const main = document.getElementById('main')!;
const nav = document.getElementById('nav')!;
const dialog = document.getElementById('key-dialog') as HTMLDialogElement;
const keyInput = document.getElementById('key-input') as HTMLInputElement;
let current = new AbortController();

function askForKey(): void {
  if (dialog.open) return;
  keyInput.value = apiKey() ?? '';
  dialog.showModal();
}
whenUnauthorized(askForKey);
document.getElementById('key-button')!.addEventListener('click', askForKey);
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
    navLink('#/jobs', 'Jobs', parts[0] !== 'new' && parts[0] !== 'jobs' ? true : parts[0] === 'jobs' && !parts[1]),
    ...names.map((k) => navLink(`#/new/${k}`, k, parts[0] === 'new' && parts[1] === k)),
    el('a', { href: '/docs/' }, ['API docs']),
  );
  main.replaceChildren();
  if (parts[0] === 'new' && parts[1]) {
    document.title = `New ${parts[1]} job — Landform`;
    submitPage(main, doc, parts[1], new URLSearchParams(q ?? ''));
  } else if (parts[0] === 'jobs' && parts[1]) {
    document.title = `Job ${parts[1]} — Landform`;
    await jobPage(main, parts[1], names, signal);
  } else {
    document.title = 'Jobs — Landform';
    listPage(main, names, signal);
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
