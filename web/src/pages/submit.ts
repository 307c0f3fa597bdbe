// A kind's page: presets from api/, a form built from the kind's schema, a raw-JSON view, the
// terrain-source picker that lets a job start from an earlier one's result, a live draft of
// the request beside the form, and the request as a curl command.

import { ApiError, Job, jobs } from '../api';
import { copyBlock, curlCommand } from '../curl';
import { SchemaForm } from '../form';
import { withPoint } from '../points';
import { presets } from '../presets';
import { Doc, Resolver, kinds, requestSchema } from '../schema';
import { el, hasHeightfield, thumbnail } from '../ui';
import { DraftPreview } from './draft_preview';
import { button } from './list';

export function submitPage(host: HTMLElement, doc: Doc, kind: string, query: URLSearchParams, signal: AbortSignal): void {
  const info = kinds(doc).find((k) => k.kind === kind);
  if (!info) {
    host.append(el('h1', {}, ['No such kind']), el('p', {}, [`The server runs no kind named “${kind}”.`]));
    return;
  }
  const r = new Resolver(doc);
  const schema = requestSchema(doc, kind);
  const list = presets(kind);
  const startTerrain = query.get('terrain');
  const fields = r.deref(schema).properties ?? {};
  const required: string[] = r.deref(schema).required ?? [];
  const initial = (p: number): unknown => {
    // "Defaults only": what the kind cannot do without (a terrain, a cave's sites, a column's
    // layers) from its first preset, every other field at its default — the schema's least
    // values alone do not run (a layer top of 0 m, a cave without a site).
    const preset = list.length ? structuredClone(list[0].body) : (r.initial(schema) as Record<string, unknown>);
    const body = p >= 0 ? structuredClone(list[p].body) : Object.fromEntries(Object.entries(preset).filter(([k]) => required.includes(k)));
    if (startTerrain && 'terrain' in fields) {
      body.terrain = { job: startTerrain };
      // A preset's sea level and label belong to its own terrain: on another job's terrain the
      // level is left to the server's default (within that terrain's heights), and the label
      // says what the job is made on.
      delete body.sea_level;
      body.label = `${kind} on job ${startTerrain}`;
    }
    return body;
  };

  const presetSel = el('select', { id: 'preset' }) as HTMLSelectElement;
  list.forEach((p, i) => presetSel.append(el('option', { value: String(i) }, [p.name])));
  // Not the schema's least values (they do not run: a layer top of 0 m, a cave without a site):
  // what the first preset cannot do without, every other field at its default.
  presetSel.append(el('option', { value: '-1' }, [list.length ? `defaults only (the required fields of ${list[0].name})` : 'defaults only']));
  const formHost = el('div', { class: 'form' });
  const status = el('p', { class: 'muted', role: 'status', 'aria-live': 'polite', id: 'submit-status' });
  const preview = new DraftPreview(kind, 'terrain' in fields, signal);
  // Declared before the curl block that reads it (its first text is made as it is built).
  let form: SchemaForm | undefined = undefined;
  const request = copyBlock('request-curl', 'as curl', () => curlCommand('POST', `/v1/jobs/${kind}`, form?.value()));
  const requestSummary = el('summary', {}, ['The request as curl']);
  const requestBox = el('details', { class: 'request-box' }, [requestSummary, request.box]) as HTMLDetailsElement;
  // Brought up to date as it is opened (the click comes before the box opens, so the text is
  // there when it shows), and at each edit while it is open.
  requestSummary.addEventListener('click', () => request.refresh());
  // A refused draft marks its fields as a refused submission would, without taking the focus
  // from the field being typed in; the next drawn draft clears them. Errors a Run attempt
  // showed stay until the next edit: a draft answering after them (it was asked for before the
  // click) neither replaces nor clears them.
  let draftMarked = false;
  let runMarked = false;
  form = new SchemaForm(r, schema, initial(list.length ? 0 : -1), formHost, {
    jobPicker: (_f, current, pick) => picker(current, pick),
    onChange: (v) => {
      runMarked = false;
      preview.edited(v);
      // Written out only while it is shown: a request of thousands of points is not turned
      // into text at every keystroke for a folded box.
      if (requestBox.open) request.refresh();
    },
  });
  // A click on the draft's terrain adds a point to the list chosen beside it (a road vertex).
  preview.onPoint = (list, x, z) => form?.setValue(withPoint(form.value(), list.path, x, z));
  preview.onProblems = (errors) => {
    if (runMarked) return;
    if (errors) form?.showErrors(errors, undefined, false);
    else if (draftMarked) form?.clearErrors();
    draftMarked = errors !== null;
  };
  preview.edited(form.value());
  presetSel.addEventListener('change', () => form.setValue(initial(Number(presetSel.value))));
  // "Edit as a new job": the form starts from an earlier job's request (defaults filled in).
  const from = query.get('from');
  if (from) {
    jobs.get(from).then(
      (j) => {
        presetSel.append(el('option', { value: '-2' }, [`from job ${j.label || j.id}`]));
        presetSel.value = '-2';
        form.setValue(j.request);
      },
      (e) => (status.textContent = `Could not read job ${from}: ${e}`),
    );
  }

  const submit = el('button', { type: 'submit', class: 'primary' }, [`Run ${kind}`]) as HTMLButtonElement;
  const f = el('form', { novalidate: '', 'aria-label': `New ${kind} job` }, [
    el('div', { class: 'preset-row' }, [el('label', { for: 'preset' }, ['Preset (from api/)']), presetSel]),
    formHost,
    requestBox,
    // Kept in view at the bottom of the window (CSS sticky), however long the form.
    el('div', { class: 'actions sticky-actions' }, [submit, status]),
  ]);
  f.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    if (!form) return;
    const body = form.value();
    runMarked = true;
    if (form.validate().length) {
      status.textContent = 'Some fields are out of bounds: see the messages beside them.';
      return;
    }
    submit.disabled = true;
    status.textContent = 'Submitting…';
    try {
      const job: Job = await jobs.submit(kind, body);
      location.hash = `#/jobs/${job.id}`;
    } catch (e) {
      if (e instanceof ApiError) {
        const p = e.problem;
        status.textContent = `${p.status} ${p.title ?? ''}: ${p.detail ?? ''}`;
        form.showErrors(p.errors ?? [], p.detail);
      } else status.textContent = String(e);
    } finally {
      submit.disabled = false;
    }
  });
  host.append(
    el('h1', {}, [kind]),
    el('p', { class: 'lead' }, [info.description || info.summary]),
    el('div', { class: 'submit-layout' }, [f, preview.box]),
  );
}

/** Thumbnails of earlier results that a terrain source can name; one click picks one. */
function picker(current: unknown, pick: (id: string) => void): HTMLElement {
  const box = el('div', { class: 'picker', role: 'group', 'aria-label': 'Start from an earlier job' }, [
    el('span', { class: 'name' }, ['…or start from an earlier result:']),
  ]);
  const grid = el('div', { class: 'picker-grid' });
  box.append(grid);
  jobs
    .list({ status: 'succeeded', limit: 50 })
    .then((page) => {
      // The newest few: a form is not the place to browse every result (the job list is).
      const usable = page.items.filter((j) => hasHeightfield(j) && !j.replay_of).slice(0, 8);
      if (!usable.length) grid.append(el('small', { class: 'muted' }, ['No finished heightfield yet.']));
      for (const j of usable) {
        const name = `${j.kind}: ${j.label || j.id}`;
        const b = button('', () => pick(j.id), 'pick');
        b.setAttribute('aria-pressed', String(current === j.id));
        b.setAttribute('aria-label', `Use ${name}`);
        b.dataset.job = j.id;
        b.append(thumbnail(j, ''), el('span', {}, [name]));
        grid.append(b);
      }
    })
    .catch((e) => grid.append(el('small', { class: 'error' }, [String(e)])));
  return box;
}
