// Small DOM helpers shared by the pages.

import { Job, blobUrl } from './api';

export { el } from './form';

/** The picture that stands for a job: its preview, once it has one. */
export function thumbnail(job: Job, alt: string): HTMLElement {
  const img = document.createElement('img');
  img.className = 'thumb';
  img.alt = alt;
  img.width = 96;
  img.height = 96;
  const preview = job.artifacts.find((a) => a.name === 'preview.png');
  if (preview) {
    img.loading = 'lazy';
    blobUrl(preview.href).then((u) => (img.src = u)).catch(() => (img.alt = `${alt} (no preview)`));
  } else img.classList.add('empty');
  return img;
}

/** Jobs whose result is a heightfield another job can start from. */
export function hasHeightfield(job: Job): boolean {
  return job.status === 'succeeded' && job.artifacts.some((a) => a.name === 'heightfield.npy');
}

/**
 * The water level a result has, in metres: the level the server used as its result reports it
 * (carve-coast's `sea_level_m`, which the request may leave out), else the request's `sea_level`
 * (erode), else the level a shape mask held the land above (deform-terrain; optional in the
 * request, the server's choice is in the constraint's figures as `water_level_m`).
 */
export function waterLevel(job: Pick<Job, 'request' | 'result'>): number | null {
  if (typeof job.result?.sea_level_m === 'number') return job.result.sea_level_m;
  if (typeof job.request?.sea_level === 'number') return job.request.sea_level;
  const figures = job.result?.constraints;
  if (Array.isArray(figures)) {
    for (const f of figures) {
      if (f && typeof f === 'object' && typeof (f as Record<string, unknown>).water_level_m === 'number') return (f as Record<string, number>).water_level_m;
    }
  }
  return null;
}

export function statusBadge(status: string): HTMLElement {
  const s = document.createElement('span');
  s.className = `badge ${status}`;
  s.textContent = status;
  return s;
}

export function formatValue(v: unknown): string {
  if (typeof v === 'number') {
    if (Number.isInteger(v)) return v.toLocaleString('en');
    return Math.abs(v) >= 1e5 || (Math.abs(v) < 1e-3 && v !== 0) ? v.toExponential(3) : String(Number(v.toPrecision(5)));
  }
  if (Array.isArray(v)) {
    if (v.length <= 6 && v.every((x) => typeof x !== 'object')) return `[${v.map(formatValue).join(', ')}]`;
    return `${v.length} items`;
  }
  if (v === null || v === undefined) return '—';
  if (typeof v === 'object') return JSON.stringify(v);
  return String(v);
}

/** A nested result as rows of (dotted name, value), lists of objects summarised. */
export function flatten(v: unknown, prefix = '', out: [string, string][] = []): [string, string][] {
  if (v && typeof v === 'object' && !Array.isArray(v)) {
    for (const [k, x] of Object.entries(v)) flatten(x, prefix ? `${prefix}.${k}` : k, out);
  } else if (Array.isArray(v) && v.length <= 8 && v.some((x) => x && typeof x === 'object')) {
    v.forEach((x, i) => flatten(x, `${prefix}[${i}]`, out));
  } else out.push([prefix, formatValue(v)]);
  return out;
}
