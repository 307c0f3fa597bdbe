// Live preview while a form is edited: each change (debounced) asks the server for a draft —
// the same body at reduced resolution, `POST /v1/drafts/{kind}` — cancelling the draft before
// it, and shows the mesh in a viewer beside the form. Run makes the full job.

import { ApiError, Job, drafts } from '../api';
import { PointList, pointLists } from '../points';
import { Viewer } from '../viewer';
import { HYPSOMETRIC_KINDS } from '../hypsometric';
import { el, waterLevel } from '../ui';
import type { FieldError } from '../api';

/** Quiet time after an edit before a draft is asked for, ms. */
const DEBOUNCE_MS = 250;

export class DraftPreview {
  readonly box: HTMLElement;
  private viewer: Viewer;
  private host = el('div', { class: 'viewer draft-viewer', id: 'draft-viewer' });
  private status = el('p', { class: 'muted draft-status', id: 'draft-status', role: 'status', 'aria-live': 'polite' });
  private toggle = el('input', { type: 'checkbox', id: 'draft-on' }) as HTMLInputElement;
  private timer = 0;
  private inFlight: AbortController | null = null;
  private latest: unknown = null;
  /** When the newest edit was made (performance.now()), for the edit-to-picture time. */
  private editedAt = 0;
  private count = 0;
  /** Where a click on the draft adds a point: the request's point lists, by path. */
  private target = el('select', { id: 'pick-target' }) as HTMLSelectElement;
  private lists: PointList[] = [];
  /** Set by the page: add a point at (x, z) to the list at `list`. */
  onPoint: ((list: PointList, x: number, z: number) => void) | null = null;
  /** Set by the page: a draft refused these fields (shown beside them), or (null) was drawn. */
  onProblems: ((errors: FieldError[] | null) => void) | null = null;
  /**
   * Meshes are shown one after another, in the order their drafts were asked for: a large
   * draft's parse finishing after a newer one's must not replace it.
   */
  private showing: Promise<void> = Promise.resolve();

  constructor(private kind: string, private heightfield: boolean, signal: AbortSignal) {
    this.toggle.checked = true;
    this.viewer = new Viewer(this.host);
    this.viewer.configure({ ground: heightfield, water: null, tintSea: null });
    signal.addEventListener('abort', () => {
      this.inFlight?.abort();
      clearTimeout(this.timer);
      this.viewer.dispose();
    });
    this.toggle.addEventListener('change', () => {
      if (this.toggle.checked) this.edited(this.latest);
      else {
        this.inFlight?.abort();
        this.status.textContent = 'Live preview off.';
      }
    });
    this.viewer.onPick = (p) => {
      const list = this.lists.find((l) => l.name === this.target.value);
      if (list) this.onPoint?.(list, p.x, p.z);
    };
    this.box = el('section', { class: 'draft', 'aria-labelledby': 'draft-h' }, [
      el('div', { class: 'draft-head' }, [
        el('h2', { id: 'draft-h' }, ['Preview']),
        el('label', { for: 'draft-on' }, [this.toggle, ' live draft while editing']),
      ]),
      this.host,
      el('div', { class: 'pick-row', hidden: '' }, [el('label', { for: 'pick-target' }, ['A click on the terrain adds a point to']), this.target]),
      this.status,
      el('p', { class: 'help' }, ['A draft runs this request at reduced resolution (the server’s draft rule for the kind); nothing is stored. Run makes the full job.']),
    ]);
    if (this.viewer.failure) this.host.append(el('p', { class: 'muted' }, [this.viewer.failure]));
  }

  /** The form changed: draft the new body after a quiet moment, dropping any draft under way. */
  edited(body: unknown): void {
    this.latest = body;
    this.editedAt = performance.now();
    clearTimeout(this.timer);
    // After the quiet moment, not at each keystroke: the lists (a walk of the whole request)
    // and the draft.
    this.timer = window.setTimeout(() => {
      this.offerLists(body);
      if (this.toggle.checked) void this.draft(body, this.editedAt);
    }, DEBOUNCE_MS);
  }

  /** The point lists a click can add to, the choice kept while its list is there. */
  private offerLists(body: unknown): void {
    this.lists = pointLists(body);
    const keep = this.target.value;
    this.target.replaceChildren(el('option', { value: '' }, ['(nothing: clicks only orbit)']));
    for (const l of this.lists) this.target.append(el('option', { value: l.name }, [`${l.name} (${l.count} points)`]));
    this.target.value = this.lists.some((l) => l.name === keep) ? keep : '';
    (this.target.parentElement as HTMLElement).hidden = this.lists.length === 0;
  }

  private async draft(body: unknown, editedAt: number): Promise<void> {
    this.inFlight?.abort();
    const ctl = new AbortController();
    this.inFlight = ctl;
    this.host.setAttribute('aria-busy', 'true');
    this.status.textContent = 'Drafting…';
    try {
      // Drafts travel meshopt-compressed (a sixth of the bytes; three.js decodes it), whatever
      // the form asks of the full job's files.
      const answer = await drafts.run(this.kind, { ...(body as Record<string, unknown>), compression: 'meshopt' }, ctl.signal);
      if (ctl.signal.aborted) return;
      // The level the server used (carve-coast's default is the terrain's), else the request's.
      const request = (body && typeof body === 'object' ? body : {}) as Job['request'];
      const water = waterLevel({ request, result: answer.result });
      const shown = this.showing.then(() => {
        if (ctl.signal.aborted) return undefined;
        // As the job page shows a result (job.ts): the legend in the height tint of the kinds
        // that colour by height, tinted with the sea at the water level.
        this.viewer.configure({ ground: this.heightfield, water, tintSea: HYPSOMETRIC_KINDS.includes(this.kind) ? (water ?? 0) : null });
        return this.viewer.show(answer.glb);
      });
      this.showing = shown.catch(() => undefined);
      await shown;
      await new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));
      if (ctl.signal.aborted) return;
      const ms = performance.now() - editedAt;
      this.count++;
      this.host.dataset.drafts = String(this.count);
      this.host.dataset.editToFrameMs = ms.toFixed(0);
      this.host.dataset.serverSeconds = answer.seconds.toFixed(3);
      this.host.classList.remove('stale');
      this.onProblems?.(null);
      this.status.textContent = `Draft drawn ${(ms / 1000).toFixed(2)} s after the edit (${answer.seconds.toFixed(2)} s on the server).`;
    } catch (e) {
      if (ctl.signal.aborted) return;
      if (e instanceof ApiError) {
        const p = e.problem;
        const fields = (p.errors ?? []).map((f) => `${f.field}: ${f.message}`).join('; ');
        this.status.textContent = `No draft: ${p.status} ${p.title ?? ''}${fields ? ` — ${fields}` : p.detail ? ` — ${p.detail}` : ''}`;
        // The mesh shown is the last good one: dimmed, and the fields refused marked in the form.
        this.host.classList.add('stale');
        if (p.errors?.length) this.onProblems?.(p.errors);
        // Busy: ask again in a moment unless another edit came first.
        if (p.status === 503) this.timer = window.setTimeout(() => this.editedAt === editedAt && void this.draft(body, editedAt), 1000);
      } else this.status.textContent = `No draft: ${String(e)}`;
    } finally {
      if (this.inFlight === ctl) {
        this.inFlight = null;
        this.host.removeAttribute('aria-busy');
      }
    }
  }
}
