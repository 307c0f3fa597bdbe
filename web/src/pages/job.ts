// A job: progress from its event stream with each live snapshot, cancel; once it has succeeded,
// the mesh in 3D, the maps, the result figures, downloads, and a timeline over its sequence.

import { ApiError, Job, JobStatus, ProgressEvent, apiKey, arrayBuffer, artifact, blobUrl, humanBytes, jobs } from '../api';
import { followJob } from '../sse';
import { HYPSOMETRIC_KINDS } from '../hypsometric';
import { progressMeter } from '../progress';
import { Shading, Viewer } from '../viewer';
import { metres } from '../viewer_overlay';
import { decodeRgbaPng } from '../rgba_png';
import { el, flatten, hasHeightfield, statusBadge, waterLevel } from '../ui';
import { apiPanel } from './api_panel';
import { button } from './list';

const ENDED = ['succeeded', 'failed', 'cancelled'];

export async function jobPage(host: HTMLElement, id: string, kindNames: string[], signal: AbortSignal): Promise<void> {
  let job: Job;
  try {
    job = await jobs.get(id);
  } catch (e) {
    host.append(el('h1', {}, ['Job not found']), el('p', {}, [e instanceof ApiError ? e.message : String(e)]));
    return;
  }
  const title = el('h1', {}, [`${job.kind}: ${job.label || job.id}`]);
  const badge = el('span', { id: 'job-status' }, [statusBadge(job.status)]);
  const meter = progressMeter(signal);
  const conn = el('small', { class: 'muted', id: 'job-stream' });
  const cancel = button('Cancel', async () => {
    try {
      await jobs.cancel(id);
    } catch (e) {
      meter.note(String(e));
    }
  });
  const live = el('figure', { class: 'live', hidden: '' }, [
    el('img', { id: 'live-snapshot', alt: 'Live snapshot of the job as it runs' }),
    el('figcaption', {}, ['Live snapshot']),
  ]);
  const progressBox = el('section', { class: 'progress', 'aria-labelledby': 'progress-h' }, [
    el('h2', { id: 'progress-h' }, ['Progress']),
    el('div', { class: 'bar-row' }, [meter.bar, meter.percent, cancel]),
    meter.line,
    conn,
    live,
  ]);
  const resultBox = el('div', { class: 'result' });
  // For every job, whatever its state: the request it was made from and the document GET gives.
  const apiBox = el('div', { class: 'api-box' }, [apiPanel(job)]);
  host.append(
    title,
    el('p', { class: 'meta' }, [badge, ` ${job.id} · created ${new Date(job.created_at).toLocaleString()}`, job.replay_of ? ` · replay of ` : '', job.replay_of ? el('a', { href: `#/jobs/${job.replay_of}` }, [job.replay_of]) : '']),
    progressBox,
    resultBox,
    apiBox,
  );

  const showStatus = (s: string): void => {
    badge.replaceChildren(statusBadge(s));
    cancel.hidden = ENDED.includes(s);
  };
  meter.show(job.progress);
  showStatus(job.status);

  const ended = (j: Job): void => {
    job = j;
    showStatus(j.status);
    meter.end(j);
    // What was live while it ran is history now: the last snapshot and the stream's state.
    live.hidden = true;
    conn.hidden = true;
    if (j.status === 'succeeded') {
      void result(resultBox, j, kindNames, signal);
    } else if (j.status === 'cancelled') {
      // Asked for: a notice, not an error.
      resultBox.append(el('p', { class: 'notice', role: 'status', id: 'job-cancelled' }, [`This job was cancelled${j.finished_at ? ` at ${new Date(j.finished_at).toLocaleTimeString()}` : ''}; it made no result.`]));
    } else if (j.error) {
      const fields = (j.error.errors ?? []).map((e) => el('li', {}, [el('code', {}, [e.field]), `: ${e.message}`]));
      resultBox.append(
        el('div', { class: 'error general', role: 'alert', id: 'job-error' }, [
          `${j.error.title ?? 'Failed'}: ${j.error.detail ?? ''}`,
          ...(fields.length ? [el('ul', {}, fields)] : []),
        ]),
      );
    }
    if (!j.replay_of) {
      resultBox.append(el('p', {}, [el('a', { class: 'button', href: `#/new/${j.kind}?from=${j.id}` }, ['Edit as a new job'])]));
    }
    // The request and the answer, as curl would send and get them.
    apiBox.replaceChildren(apiPanel(j));
  };
  if (ENDED.includes(job.status)) {
    ended(job);
    return;
  }
  const img = live.querySelector('img') as HTMLImageElement;
  await followJob(id, {
    signal,
    onConnect: (last) => (conn.textContent = last === undefined ? 'following the event stream' : `reconnected after event ${last}`),
    onEvent: (e) => {
      if (e.event === 'progress') {
        const p = JSON.parse(e.data) as ProgressEvent;
        meter.show(p);
        if (p.snapshot) {
          blobUrl(p.snapshot, false).then((u) => {
            const old = img.src;
            img.src = u;
            live.hidden = ENDED.includes(job.status);
            img.dataset.count = String(Number(img.dataset.count ?? 0) + 1);
            if (old.startsWith('blob:')) URL.revokeObjectURL(old);
          }, () => {});
        }
      } else if (e.event === 'status') {
        showStatus((JSON.parse(e.data) as { status: JobStatus }).status);
      } else if (e.event === 'done') {
        ended(JSON.parse(e.data) as Job);
      }
    },
  });
}

/** A succeeded job: the viewer, the maps, the figures, the downloads, the timeline. */
async function result(host: HTMLElement, job: Job, kindNames: string[], signal: AbortSignal): Promise<void> {
  const viewerHost = el('div', { class: 'viewer', id: 'viewer' });
  const controls = el('div', { class: 'viewer-controls', role: 'group', 'aria-label': 'View' });
  const viewSection = el('section', { 'aria-labelledby': 'view-h' }, [el('h2', { id: 'view-h' }, ['Mesh']), viewerHost, controls]);
  const timeline = el('section', { class: 'timeline', 'aria-labelledby': 'timeline-h' });
  const maps = el('section', { 'aria-labelledby': 'maps-h' }, [el('h2', { id: 'maps-h' }, ['Pictures and maps'])]);
  const figures = el('section', { 'aria-labelledby': 'figures-h' }, [el('h2', { id: 'figures-h' }, ['Result'])]);
  const downloads = el('section', { 'aria-labelledby': 'downloads-h' }, [el('h2', { id: 'downloads-h' }, ['Downloads'])]);
  host.append(viewSection, timeline, maps, figures, downloads);

  const viewer = new Viewer(viewerHost);
  const water = waterLevel(job);
  viewer.configure({
    ground: hasHeightfield(job),
    water,
    // The height tint's sea: the job's water level, else 0 m (src/export/mod.rs).
    tintSea: HYPSOMETRIC_KINDS.includes(job.kind) ? (water ?? 0) : null,
  });
  signal.addEventListener('abort', () => viewer.dispose());
  if (viewer.failure) viewerHost.append(el('p', { class: 'muted' }, [viewer.failure]));

  // Levels of detail: the full mesh and each mesh_lodN.glb.
  // Ordered by level number, the full mesh (level 0) first: a name sort puts `mesh_lod1.glb`
  // before `mesh.glb` ('_' sorts before '.'), and the list then named lod1 while the full mesh
  // was shown, and a timeline move loaded lod1.
  const level = (name: string): number => Number(/_lod(\d+)\.glb$/.exec(name)?.[1] ?? 0);
  const levels = job.artifacts.filter((a) => /^mesh(_lod\d+)?\.glb$/.test(a.name)).sort((a, b) => level(a.name) - level(b.name));
  const lodSel = el('select', { id: 'lod' }) as HTMLSelectElement;
  for (const a of levels) lodSel.append(el('option', { value: a.name }, [`${a.name === 'mesh.glb' ? 'full' : a.name.replace(/^mesh_|\.glb$/g, '')} (${humanBytes(a.bytes)})`]));
  lodSel.value = 'mesh.glb';
  const load = async (j: Job, name: string): Promise<void> => {
    const a = artifact(j, name) ?? artifact(j, 'mesh.glb');
    if (!a) return;
    viewerHost.setAttribute('aria-busy', 'true');
    try {
      await viewer.show(await arrayBuffer(a.href));
      viewerHost.dataset.shown = `${j.id}/${a.name}`;
    } finally {
      viewerHost.removeAttribute('aria-busy');
    }
  };
  lodSel.addEventListener('change', () => void load(shownJob, lodSel.value));
  let shownJob = job;

  const check = (id: string, label: string, checked: boolean, f: (v: boolean) => void): HTMLElement => {
    const cb = el('input', { type: 'checkbox', id }) as HTMLInputElement;
    cb.checked = checked;
    cb.addEventListener('change', () => f(cb.checked));
    return el('label', { for: id }, [cb, ` ${label}`]);
  };
  const slider = (id: string, label: string, min: number, max: number, value: number, f: (v: number) => void): HTMLElement[] => {
    const s = el('input', { type: 'range', id, min: String(min), max: String(max), value: String(value) }) as HTMLInputElement;
    s.addEventListener('input', () => f(Number(s.value)));
    return [el('label', { for: id }, [label]), s];
  };
  const home = el('button', { type: 'button', id: 'frame-all', title: 'Frame the whole result (F or Home in the view)' }, ['Frame all']);
  home.addEventListener('click', () => viewer.frameAll());
  const shading = el('select', { id: 'shading' }, [
    el('option', { value: 'shaded' }, ['shaded']),
    el('option', { value: 'wire-over-shaded' }, ['wire over shaded']),
    el('option', { value: 'wireframe' }, ['wireframe']),
  ]) as HTMLSelectElement;
  shading.addEventListener('change', () => viewer.set({ shading: shading.value as Shading }));
  const seaBox = el('span', { class: 'sea-control' });
  controls.append(
    home,
    el('label', { for: 'shading' }, ['surface']),
    shading,
    check('vertex-colors', 'vertex colours', true, (v) => viewer.set({ vertexColors: v })),
    check('shadows', 'shadows', true, (v) => viewer.set({ shadows: v })),
    ...(hasHeightfield(job) ? [check('grid', 'grid', true, (v) => viewer.set({ grid: v }))] : []),
    seaBox,
    ...slider('sun-azimuth', 'sun azimuth', 0, 359, 315, (v) => viewer.set({ sunAzimuth: v })),
    ...slider('sun-elevation', 'sun elevation', 2, 90, 45, (v) => viewer.set({ sunElevation: v })),
    ...(levels.length > 1 ? [el('label', { for: 'lod' }, ['level of detail']), lodSel] : []),
  );
  // The water's switch, once the mesh says whether it brings its own (carve-coast's sea).
  const first = load(job, 'mesh.glb').then(() => {
    if (viewer.showsWater) seaBox.append(check('sea', `sea plane (${metres(water ?? 0)})`, true, (v) => viewer.set({ sea: v })));
  });

  // The maps and pictures beside the mesh.
  const grid = el('div', { class: 'maps' });
  maps.append(grid);
  const pictures = (j: Job): void => {
    grid.replaceChildren();
    for (const a of j.artifacts.filter((a) => a.media_type === 'image/png' && !a.name.includes('/'))) {
      const img = el('img', { alt: `${a.name} of job ${j.label || j.id}`, 'data-name': a.name }) as HTMLImageElement;
      const splat = /^splatmap/.test(a.name);
      if (splat) splatPicture(a.href).then((u) => (img.src = u), () => blobUrl(a.href).then((u) => (img.src = u), () => {}));
      else blobUrl(a.href).then((u) => (img.src = u), () => {});
      const caption = splat ? ' · shown in false colour: ground green, rock grey, deposit sand, the kind\'s own (alpha) orange' : '';
      grid.append(el('figure', {}, [img, el('figcaption', {}, [`${a.name} · ${humanBytes(a.bytes)}${caption}`])]));
    }
  };
  pictures(job);

  // The figures as a table.
  const rows = flatten(job.result ?? {});
  figures.append(
    el('table', { class: 'figures' }, [
      el('tbody', {}, rows.map(([k, v]) => el('tr', {}, [el('th', { scope: 'row' }, [k]), el('td', {}, [v])]))),
    ]),
  );

  // Downloads, with sizes; with a key, through fetch (a plain link cannot carry it).
  const list = el('ul', { class: 'downloads' });
  for (const a of job.artifacts) {
    const link = el('a', { href: a.href, download: a.name.replaceAll('/', '_') }, [a.name]);
    link.addEventListener('click', async (ev) => {
      if (!apiKey()) return;
      ev.preventDefault();
      const tmp = el('a', { href: await blobUrl(a.href), download: a.name.replaceAll('/', '_') });
      tmp.click();
    });
    list.append(el('li', {}, [link, el('small', { class: 'muted' }, [` ${humanBytes(a.bytes)} · ${a.media_type} · sha256 ${a.sha256.slice(0, 12)}…`])]));
  }
  downloads.append(list);

  // Start another job from this result.
  if (hasHeightfield(job)) {
    const targets = kindNames.filter((k) => ['bulldoze', 'deform-terrain', 'carve-coast', 'erode'].includes(k));
    host.append(
      el('section', { 'aria-labelledby': 'compose-h' }, [
        el('h2', { id: 'compose-h' }, ['Use this terrain']),
        el('p', {}, targets.map((k) => el('a', { class: 'button', href: `#/new/${k}?terrain=${job.id}` }, [`${k} on it`]))),
      ]),
    );
  }

  const steps = typeof job.result?.sequence_steps === 'number' ? (job.result.sequence_steps as number) : 0;
  if (steps > 0 && !job.replay_of) timelineSection(timeline, job, steps, async (j) => {
    shownJob = j;
    await load(j, lodSel.value || 'mesh.glb');
    pictures(j);
  }, signal);
  await first;
}

/** A slider over the recorded sequence: each position is a replay up to that step (cached). */
function timelineSection(host: HTMLElement, job: Job, steps: number, show: (j: Job) => Promise<void>, signal: AbortSignal): void {
  const s = el('input', { type: 'range', id: 'timeline', min: '0', max: String(steps), value: String(steps), step: '1' }) as HTMLInputElement;
  const label = el('output', { for: 'timeline', id: 'timeline-step' }, [`step ${steps} of ${steps} (the result)`]);
  const note = el('small', { class: 'muted', 'aria-live': 'polite', id: 'timeline-note' });
  host.append(
    el('h2', { id: 'timeline-h' }, ['Timeline']),
    el('p', { class: 'muted' }, ['Each position replays the recorded sequence up to that step: nothing is searched or sampled again.']),
    el('div', { class: 'timeline-row' }, [el('label', { for: 'timeline' }, ['step']), s, label]),
    note,
  );
  const cache = new Map<number, Promise<Job>>([[steps, Promise.resolve(job)]]);
  let timer = 0;
  let wanted = steps;
  const replayTo = (k: number): Promise<Job> => {
    let p = cache.get(k);
    if (!p) {
      p = (async () => {
        let j = await jobs.replay(job.id, k);
        while (!['succeeded', 'failed', 'cancelled'].includes(j.status) && !signal.aborted) {
          await new Promise((r) => setTimeout(r, 400));
          j = await jobs.get(j.id);
        }
        if (j.status !== 'succeeded') throw new Error(`the replay to step ${k} ${j.status}`);
        return j;
      })();
      cache.set(k, p);
      p.catch(() => cache.delete(k));
    }
    return p;
  };
  s.addEventListener('input', () => {
    const k = Number(s.value);
    wanted = k;
    label.textContent = `step ${k} of ${steps}${k === steps ? ' (the result)' : ''}`;
    clearTimeout(timer);
    timer = window.setTimeout(async () => {
      note.textContent = cache.has(k) ? '' : `replaying to step ${k}…`;
      host.setAttribute('aria-busy', 'true');
      try {
        const j = await replayTo(k);
        if (wanted !== k || signal.aborted) return;
        await show(j);
        note.textContent = k === steps ? 'the result' : `step ${k}: replay job ${j.id}`;
        host.dataset.shownStep = String(k);
      } catch (e) {
        note.textContent = e instanceof ApiError ? `${e.problem.status}: ${e.message}` : String(e);
      } finally {
        host.removeAttribute('aria-busy');
      }
    }, 350);
  });
}

/**
 * A splat map as a picture: its four channels are layer weights summing to 255 (R ground,
 * G rock, B deposit, A the kind's own material), so shown as they are the fourth layer is
 * transparency — a blank tile where it is absent, a black one where it is everything. Each
 * pixel here is the layers' colours mixed by their weights.
 */
const SPLAT_COLOURS = [
  [96, 138, 70], // ground
  [140, 140, 140], // rock
  [196, 170, 120], // deposit
  [224, 122, 40], // the kind's own
];
async function splatPicture(href: string): Promise<string> {
  const png = await decodeRgbaPng(await arrayBuffer(href));
  if (!png) throw new Error('not an 8-bit RGBA PNG');
  const canvas = document.createElement('canvas');
  canvas.width = png.width;
  canvas.height = png.height;
  const ctx = canvas.getContext('2d');
  if (!ctx) throw new Error('no 2D canvas');
  const image = ctx.createImageData(png.width, png.height);
  const [d, w] = [image.data, png.data];
  for (let k = 0; k < w.length; k += 4) {
    for (let c = 0; c < 3; c++) d[k + c] = Math.round(SPLAT_COLOURS.reduce((s, colour, i) => s + w[k + i] * colour[c], 0) / 255);
    d[k + 3] = 255;
  }
  ctx.putImageData(image, 0, 0);
  return canvas.toDataURL('image/png');
}
