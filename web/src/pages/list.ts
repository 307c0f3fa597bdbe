// The job list: newest first, paged with the cursor, filtered by kind and status, with delete.

import { ApiError, Job, age, jobs } from '../api';
import { el, statusBadge, thumbnail } from '../ui';

const STATUSES = ['queued', 'running', 'succeeded', 'failed', 'cancelled'];

export function listPage(host: HTMLElement, kindNames: string[], signal: AbortSignal): void {
  const params = new URLSearchParams(location.hash.split('?')[1] ?? '');
  const state = {
    kind: params.get('kind') ?? '',
    status: params.get('status') ?? '',
    replays: params.get('replays') === '1',
    cursors: [null] as (string | null)[],
  };
  const kindSel = select('filter-kind', 'Kind', ['', ...kindNames], state.kind);
  const statusSel = select('filter-status', 'Status', ['', ...STATUSES], state.status);
  const replays = el('input', { type: 'checkbox', id: 'filter-replays' }) as HTMLInputElement;
  replays.checked = state.replays;
  const table = el('table', { class: 'jobs' });
  const pager = el('nav', { class: 'pager', 'aria-label': 'Pages of jobs' });
  const note = el('p', { class: 'muted', role: 'status' });
  host.append(
    el('h1', {}, ['Jobs']),
    el('form', { class: 'filters', role: 'search' }, [
      kindSel.label, kindSel.select, statusSel.label, statusSel.select,
      el('label', { for: 'filter-replays' }, [replays, ' show replays']),
    ]),
    note,
    table,
    pager,
  );
  let timer = 0;
  signal.addEventListener('abort', () => clearTimeout(timer));

  const load = async (): Promise<void> => {
    clearTimeout(timer);
    const cursor = state.cursors[state.cursors.length - 1];
    let page;
    try {
      page = await jobs.list({ kind: state.kind || undefined, status: state.status || undefined, cursor, limit: 20, replays: state.replays });
    } catch (e) {
      note.textContent = e instanceof ApiError ? `Could not list jobs: ${e.message}` : String(e);
      return;
    }
    if (signal.aborted) return;
    const items = page.items;
    note.textContent = items.length ? '' : 'No jobs here yet. Start one from a kind above.';
    table.replaceChildren(
      el('thead', {}, [
        el('tr', {}, ['Preview', 'Kind', 'Label', 'Status', 'Age', 'Actions'].map((h, i) => el('th', { scope: 'col' }, [i === 0 || i === 5 ? el('span', { class: 'sr-only' }, [h]) : h]))),
      ]),
      el('tbody', {}, items.map((j) => row(j, load))),
    );
    pager.replaceChildren();
    if (state.cursors.length > 1) pager.append(button('Newer', () => { state.cursors.pop(); void load(); }));
    if (page.next_cursor) {
      const next = page.next_cursor;
      pager.append(button('Older', () => { state.cursors.push(next); void load(); }));
    }
    // While anything on the page is under way, look again.
    if (page.items.some((j) => j.status === 'queued' || j.status === 'running')) timer = window.setTimeout(load, 2000);
  };
  const refilter = () => {
    state.kind = kindSel.select.value;
    state.status = statusSel.select.value;
    state.replays = replays.checked;
    state.cursors = [null];
    const q = new URLSearchParams();
    if (state.kind) q.set('kind', state.kind);
    if (state.status) q.set('status', state.status);
    if (state.replays) q.set('replays', '1');
    history.replaceState(null, '', `#/jobs${q.size ? `?${q}` : ''}`);
    void load();
  };
  for (const c of [kindSel.select, statusSel.select, replays]) c.addEventListener('change', refilter);
  void load();
}

function row(j: Job, reload: () => Promise<void>): HTMLElement {
  const link = el('a', { href: `#/jobs/${j.id}` }, [j.label || j.id]);
  const del = button('Delete', async () => {
    if (!confirm(`Delete job ${j.label || j.id} and its artifacts?`)) return;
    await jobs.remove(j.id);
    await reload();
  });
  del.setAttribute('aria-label', `Delete ${j.label || j.id}`);
  const title = new Date(j.created_at).toLocaleString();
  return el('tr', { 'data-job': j.id }, [
    el('td', {}, [el('a', { href: `#/jobs/${j.id}`, tabindex: '-1', 'aria-hidden': 'true' }, [thumbnail(j, '')])]),
    el('td', {}, [j.kind]),
    el('td', {}, [link, j.replay_of ? el('small', { class: 'muted' }, [` replay to step ${j.replay_until_step ?? 'end'}`]) : '']),
    el('td', {}, [statusBadge(j.status)]),
    el('td', { title }, [age(j.created_at)]),
    el('td', {}, [del]),
  ]);
}

function select(id: string, label: string, options: string[], value: string) {
  const s = el('select', { id }) as HTMLSelectElement;
  for (const o of options) s.append(el('option', { value: o }, [o || 'any']));
  s.value = value;
  return { label: el('label', { for: id }, [label]), select: s };
}

export function button(text: string, onClick: () => unknown, cls = ''): HTMLButtonElement {
  const b = el('button', { type: 'button', class: cls }, [text]) as HTMLButtonElement;
  b.addEventListener('click', () => void onClick());
  return b;
}
