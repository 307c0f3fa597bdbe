// The first screen: what Landform makes, one card per kind (a picture of a finished job, the
// kind's one line from the OpenAPI document — its operation's description, the summary being
// "Submit a … job" — "Try it" which runs its quick preset (presets.ts) at
// once), and the newest jobs. The full list is at #/jobs.

import { ApiError, Job, age, jobs } from '../api';
import { quickPreset } from '../presets';
import { el, statusBadge, thumbnail } from '../ui';
import { button } from './list';

/** A picture per kind (web/src/kinds/<kind>.png: a preset's preview.png, downscaled), bundled
 * by Vite under /assets/ with a content hash. */
const pictures = Object.fromEntries(
  Object.entries(import.meta.glob('../kinds/*.png', { eager: true, import: 'default' }) as Record<string, string>).map(([path, url]) => [
    /([^/]+)\.png$/.exec(path)![1],
    url,
  ]),
);

const RECENT = 6;

export function homePage(host: HTMLElement, kinds: { kind: string; summary: string; description: string }[], signal: AbortSignal): void {
  const cards = el('ul', { class: 'kind-cards' }, kinds.map((k) => card(k.kind, k.description.split('\n')[0] || k.summary)));
  const recent = el('ul', { class: 'recent-jobs', id: 'recent-jobs' });
  const recentNote = el('p', { class: 'muted', role: 'status' });
  host.append(
    el('h1', {}, ['Landform: terrain made to order']),
    el('p', { class: 'lead intro' }, [
      'Landform shapes terrain over HTTP: heightfields with roads and terraces, islands worn by the sea, caves grown drip by drip, ' +
        'eroded ranges and weathered rock columns. Each job delivers a mesh (glb with levels of detail), height and splat maps and ' +
        'pictures, and records how it was made so any step can be replayed.',
    ]),
    el('section', { 'aria-labelledby': 'kinds-h' }, [el('h2', { id: 'kinds-h' }, ['What it makes']), cards]),
    el('section', { 'aria-labelledby': 'recent-h' }, [
      el('h2', { id: 'recent-h' }, ['Recent jobs']),
      recentNote,
      recent,
      el('p', {}, [el('a', { href: '#/jobs' }, ['All jobs'])]),
    ]),
  );

  let timer = 0;
  signal.addEventListener('abort', () => clearTimeout(timer));
  const load = async (): Promise<void> => {
    let items: Job[];
    try {
      items = (await jobs.list({ limit: RECENT, replays: false })).items;
    } catch (e) {
      recentNote.textContent = e instanceof ApiError ? `Could not list jobs: ${e.message}` : String(e);
      return;
    }
    if (signal.aborted) return;
    recentNote.textContent = items.length ? '' : 'No jobs yet: try a kind above.';
    recent.replaceChildren(...items.map(recentJob));
    // While one is under way, look again.
    if (items.some((j) => j.status === 'queued' || j.status === 'running')) timer = window.setTimeout(load, 2000);
  };
  void load();
}

function card(kind: string, line: string): HTMLElement {
  const first = quickPreset(kind);
  const status = el('p', { class: 'try-status', role: 'status' });
  const heading = `kind-${kind}-h`;
  const picture = pictures[kind]
    ? el('img', { src: pictures[kind], alt: `A ${kind} result`, width: '320', height: '200', loading: 'lazy' })
    : el('div', { class: 'kind-picture-missing', 'aria-hidden': 'true' });
  const tryIt = button('Try it', async () => {
    if (!first) return;
    tryIt.disabled = true;
    status.textContent = `Running the ${first.name} preset…`;
    try {
      const job = await jobs.submit(kind, first.body);
      location.hash = `#/jobs/${job.id}`;
    } catch (e) {
      status.textContent = e instanceof ApiError ? `The server refused it: ${e.message}` : String(e);
      tryIt.disabled = false;
    }
  }, 'primary');
  tryIt.setAttribute('aria-describedby', heading);
  tryIt.dataset.try = kind;
  tryIt.hidden = !first;
  return el('li', { class: 'kind-card', 'data-kind': kind }, [
    picture,
    el('h3', { id: heading }, [el('a', { href: `#/new/${kind}` }, [kind])]),
    el('p', {}, [line]),
    el('div', { class: 'kind-actions' }, [
      tryIt,
      el('a', { href: `#/new/${kind}`, class: 'button' }, ['Open the form']),
    ]),
    first ? el('small', { class: 'muted' }, [`Try it runs the ${first.name} preset.`]) : '',
    status,
  ]);
}

function recentJob(j: Job): HTMLElement {
  return el('li', { class: 'recent-job', 'data-job': j.id }, [
    el('a', { href: `#/jobs/${j.id}`, tabindex: '-1', 'aria-hidden': 'true' }, [thumbnail(j, '')]),
    el('div', {}, [
      el('a', { href: `#/jobs/${j.id}` }, [j.label || j.id]),
      el('div', { class: 'muted' }, [`${j.kind} · `, statusBadge(j.status), ` · ${age(j.created_at)}`]),
    ]),
  ]);
}
