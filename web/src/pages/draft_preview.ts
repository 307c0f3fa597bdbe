// Live preview while a form is edited: each change (debounced) asks the server for a draft —
// the same body at reduced resolution, `POST /v1/drafts/{kind}` — cancelling the draft before
// it, and shows the mesh in a viewer beside the form. Run makes the full job.

import { ApiError, drafts } from '../api';
import { Viewer } from '../viewer';
import { el } from '../ui';

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

  constructor(private kind: string, heightfield: boolean, signal: AbortSignal) {
    this.toggle.checked = true;
    this.viewer = new Viewer(this.host);
    this.viewer.aboveGround(heightfield);
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
    this.box = el('section', { class: 'draft', 'aria-labelledby': 'draft-h' }, [
      el('div', { class: 'draft-head' }, [
        el('h2', { id: 'draft-h' }, ['Preview']),
        el('label', { for: 'draft-on' }, [this.toggle, ' live draft while editing']),
      ]),
      this.host,
      this.status,
      el('p', { class: 'help' }, ['A draft runs this request at reduced resolution (the server’s draft rule for the kind); nothing is stored. Run makes the full job.']),
    ]);
    if (this.viewer.failure) this.host.append(el('p', { class: 'muted' }, [this.viewer.failure]));
  }

  /** The form changed: draft the new body after a quiet moment, dropping any draft under way. */
  edited(body: unknown): void {
    this.latest = body;
    this.editedAt = performance.now();
    if (!this.toggle.checked) return;
    clearTimeout(this.timer);
    this.timer = window.setTimeout(() => void this.draft(body, this.editedAt), DEBOUNCE_MS);
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
      const sea = body && typeof body === 'object' && typeof (body as Record<string, unknown>).sea_level === 'number' ? ((body as Record<string, unknown>).sea_level as number) : null;
      await this.viewer.show(answer.glb, sea);
      await new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));
      if (ctl.signal.aborted) return;
      const ms = performance.now() - editedAt;
      this.count++;
      this.host.dataset.drafts = String(this.count);
      this.host.dataset.editToFrameMs = ms.toFixed(0);
      this.host.dataset.serverSeconds = answer.seconds.toFixed(3);
      this.status.textContent = `Draft drawn ${(ms / 1000).toFixed(2)} s after the edit (${answer.seconds.toFixed(2)} s on the server).`;
    } catch (e) {
      if (ctl.signal.aborted) return;
      if (e instanceof ApiError) {
        const p = e.problem;
        const fields = (p.errors ?? []).map((f) => `${f.field}: ${f.message}`).join('; ');
        this.status.textContent = `No draft: ${p.status} ${p.title ?? ''}${fields ? ` — ${fields}` : p.detail ? ` — ${p.detail}` : ''}`;
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
