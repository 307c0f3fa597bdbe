// A form built at run time from a kind's request schema: every field with its default, bounds and
// description, nested objects and lists, one-of choices as a select; a raw-JSON view kept in
// sync; errors (the schema's own checks, or the server's problem+json) shown beside the field
// they name.

import { FieldError } from './api';
import { Path, Resolver, Schema, isObject, num, pathString } from './schema';

export interface FormHooks {
  /** Extra controls under a one-of field that can name an earlier job (terrain sources). */
  jobPicker?: (field: string, current: unknown, pick: (id: string) => void) => HTMLElement;
  /** After every change of the value (a field, a structural change, the raw JSON). */
  onChange?: (value: unknown) => void;
}

let ids = 0;
const nextId = () => `f${++ids}`;

export class SchemaForm {
  private root: unknown;
  private fields = new Map<string, HTMLElement>();
  private formHost = el('div', { class: 'form-fields' });
  private raw = el('textarea', {
    class: 'raw',
    spellcheck: 'false',
    'aria-label': 'Request body as JSON',
    rows: '24',
  }) as HTMLTextAreaElement;
  private rawError = el('div', { class: 'error', role: 'alert', hidden: '' });
  private general = el('div', { class: 'error general', role: 'alert', hidden: '' });
  private rerenderTimer = 0;
  /** The "more settings" boxes the user opened, by their object's path (kept over re-renders). */
  private openMore = new Set<string>();
  private rawBox: HTMLDetailsElement;

  constructor(
    private r: Resolver,
    private schema: Schema,
    initial: unknown,
    host: HTMLElement,
    private hooks: FormHooks = {},
  ) {
    this.root = structuredClone(initial);
    this.rawBox = el('details', { class: 'raw-box' }, [el('summary', {}, ['Raw JSON (kept in sync with the form)']), this.raw, this.rawError]) as HTMLDetailsElement;
    host.append(this.general, this.formHost, this.rawBox);
    this.raw.addEventListener('input', () => this.fromRaw());
    this.render();
  }

  value(): unknown {
    return structuredClone(this.root);
  }

  setValue(v: unknown): void {
    this.root = structuredClone(v);
    this.render();
    this.hooks.onChange?.(this.value());
  }

  /** The schema's checks, shown beside their fields; the problems found. */
  validate(): FieldError[] {
    const errors: FieldError[] = [];
    this.r.check(this.schema, this.root, [], errors);
    this.showErrors(errors);
    return errors;
  }

  /** Show each error beside the field it names, or the nearest enclosing field shown. */
  showErrors(errors: FieldError[], detail?: string, focus = true): void {
    this.clearErrors();
    const general: string[] = [];
    const raw: string[] = [];
    if (detail && !errors.length) general.push(detail);
    for (const e of errors) {
      const box = this.nearest(e.field);
      // A field the form has no box for (an unknown key typed in the raw JSON): said under the
      // raw JSON, where it was typed, as well as at the top.
      if (!box || (box.dataset.path === '' && e.field !== '')) raw.push(`${e.field}: ${e.message}`);
      if (!box) {
        general.push(`${e.field}: ${e.message}`);
        continue;
      }
      for (let d = box.closest('details.more'); d; d = d.parentElement?.closest('details.more') ?? null) (d as HTMLDetailsElement).open = true;
      const err = box.querySelector(':scope > .error') as HTMLElement;
      const own = box.dataset.path === e.field;
      err.textContent = (err.textContent ? `${err.textContent}; ` : '') + (own ? e.message : `${e.field}: ${e.message}`);
      err.hidden = false;
      box.classList.add('invalid');
      box.querySelector(':scope > input, :scope > select, :scope > textarea, :scope > span > input:not([type=range])')?.setAttribute('aria-invalid', 'true');
    }
    if (general.length) {
      this.general.textContent = general.join('\n');
      this.general.hidden = false;
    }
    if (raw.length) {
      this.rawError.textContent = raw.join('\n');
      this.rawError.hidden = false;
      this.rawBox.open = true;
      this.raw.setAttribute('aria-invalid', 'true');
      if (focus) this.raw.focus();
      return;
    }
    if (!focus) return;
    const first = this.formHost.querySelector('.invalid');
    (first?.querySelector('input, select, textarea, button') as HTMLElement | null)?.focus();
  }

  clearErrors(): void {
    this.rawError.hidden = true;
    this.raw.removeAttribute('aria-invalid');
    this.general.hidden = true;
    this.general.textContent = '';
    for (const box of this.fields.values()) {
      box.classList.remove('invalid');
      const err = box.querySelector(':scope > .error') as HTMLElement | null;
      if (err) {
        err.hidden = true;
        err.textContent = '';
      }
      box.querySelector('[aria-invalid]')?.removeAttribute('aria-invalid');
    }
  }

  private nearest(field: string): HTMLElement | undefined {
    let f = field;
    for (;;) {
      const hit = this.fields.get(f);
      if (hit) return hit;
      const cut = Math.max(f.lastIndexOf('.'), f.lastIndexOf('['));
      if (cut <= 0) return this.fields.get('');
      f = f.slice(0, cut);
    }
  }

  private fromRaw(): void {
    try {
      const v = JSON.parse(this.raw.value);
      this.rawError.hidden = true;
      this.root = v;
      this.rawProblems();
      this.hooks.onChange?.(this.value());
      clearTimeout(this.rerenderTimer);
      this.rerenderTimer = window.setTimeout(() => this.renderFields(), 250);
    } catch (e) {
      this.rawError.textContent = `Not JSON yet: ${(e as Error).message}`;
      this.rawError.hidden = false;
    }
  }

  private syncRaw(): void {
    if (document.activeElement !== this.raw) this.raw.value = JSON.stringify(this.root, null, 2);
  }

  private changed(): void {
    this.syncRaw();
    this.hooks.onChange?.(this.value());
  }

  private render(): void {
    this.renderFields();
    this.syncRaw();
  }

  /** Rebuild the fields (after a structural change), keeping the focus where it was. */
  private renderFields(): void {
    const focused = (document.activeElement as HTMLElement | null)?.dataset?.focus;
    this.fields.clear();
    this.formHost.replaceChildren(this.node(this.schema, [], 'request', true));
    if (focused) (this.formHost.querySelector(`[data-focus="${CSS.escape(focused)}"]`) as HTMLElement | null)?.focus();
  }

  private get(path: Path): unknown {
    let v: any = this.root;
    for (const p of path) {
      if (v === null || v === undefined) return undefined;
      v = v[p as any];
    }
    return v;
  }

  private set(path: Path, value: unknown): void {
    if (!path.length) {
      this.root = value;
      return;
    }
    let v: any = this.root;
    for (let i = 0; i < path.length - 1; i++) {
      const p = path[i];
      if (v[p] === null || typeof v[p] !== 'object') v[p] = typeof path[i + 1] === 'number' ? [] : {};
      v = v[p];
    }
    const last = path[path.length - 1];
    if (value === undefined && !Array.isArray(v)) delete v[last];
    else v[last] = value;
    this.changed();
  }

  private structural(path: Path, value: unknown): void {
    this.set(path, value);
    this.renderFields();
    this.syncRaw();
  }

  /**
   * The raw JSON's problems shown under it, where the user is typing (an unknown key is named
   * with the nearest field the object has): the form's own boxes may be far up the page.
   */
  private rawProblems(): void {
    const errors: FieldError[] = [];
    this.r.check(this.schema, this.root, [], errors);
    const unknown = errors.filter((e) => e.message.startsWith('is not a field'));
    if (!unknown.length) {
      this.rawError.hidden = true;
      return;
    }
    this.rawError.textContent = unknown.map((e) => `${e.field}: ${e.message}`).join('\n');
    this.rawError.hidden = false;
  }

  /** One field: a box with a label, the control, help text and an error line. */
  private node(raw: Schema, path: Path, name: string, required: boolean): HTMLElement {
    const { schema: s, nullable } = this.r.unwrapNullable(raw);
    const field = pathString(path);
    const value = this.get(path);
    const type = this.r.typeOf(s);
    const en = this.r.enumOf(s);
    const tags = this.r.tags(s);
    const composite = !en && (tags || Array.isArray(s.oneOf) || type === 'object' || type === 'array');
    const absent = value === undefined || value === null;
    const optional = !required || nullable;

    // An optional object, list or choice that is not set: one button sets it.
    if (composite && absent && optional && path.length) {
      const box = this.box('field unset', field);
      const id = nextId();
      const add = el('button', { type: 'button', class: 'add', id, 'data-focus': `${field}#add` }, [`Set ${name}`]);
      add.addEventListener('click', () => this.structural(path, this.r.initial(s)));
      box.append(el('span', { class: 'name' }, [name]), add, this.help(s, id), this.errorLine());
      return box;
    }

    if (composite) {
      const box = this.box(path.length ? 'group' : 'group top', field) as HTMLFieldSetElement;
      const legend = el('legend', {}, [path.length ? name : 'Parameters']);
      box.append(legend);
      if (path.length && optional) {
        const rm = el('button', { type: 'button', class: 'remove', 'data-focus': `${field}#rm`, 'aria-label': `Unset ${name}` }, ['Unset']);
        rm.addEventListener('click', () => this.structural(path, undefined));
        legend.append(' ', rm);
      }
      if (s.description && path.length) box.append(el('small', { class: 'help' }, prose(s.description)));
      if (tags) this.choice(box, s, path, tags, value, name);
      else if (Array.isArray(s.oneOf)) this.untagged(box, s, path, value, name);
      else if (type === 'object') this.object(box, s, path);
      else this.list(box, s, path, name);
      box.append(this.errorLine());
      return box;
    }
    return this.leaf(s, path, name, required && !nullable, en);
  }

  /**
   * An object's fields: those required or set to something other than their default shown,
   * the rest (optional, at their defaults) in a "more settings" box, closed until opened.
   */
  private object(box: HTMLElement, s: Schema, path: Path): void {
    const req: string[] = s.required ?? [];
    const entries = Object.entries<Schema>(s.properties ?? {});
    if (path.length && entries.length <= 4 && entries.every(([, ps]) => this.isLeaf(ps))) box.classList.add('compact');
    const more: HTMLElement[] = [];
    for (const [k, ps] of entries) {
      const node = this.node(ps, [...path, k], k, req.includes(k));
      if (this.atDefault(ps, [...path, k], req.includes(k))) more.push(node);
      else box.append(node);
    }
    if (!more.length) return;
    const key = pathString(path);
    const details = el('details', { class: 'more', 'data-more': key }) as HTMLDetailsElement;
    details.open = this.openMore.has(key);
    details.addEventListener('toggle', () => (details.open ? this.openMore.add(key) : this.openMore.delete(key)));
    details.append(el('summary', {}, [`More settings (${more.length}, at their defaults)`]), ...more);
    box.append(details);
  }

  /** An optional field that is unset or holds its default. */
  private atDefault(raw: Schema, path: Path, required: boolean): boolean {
    if (required) return false;
    const v = this.get(path);
    if (v === undefined || v === null) return true;
    const d = this.r.unwrapNullable(raw).schema.default;
    return d !== undefined && JSON.stringify(d) === JSON.stringify(v);
  }

  /** A number, text, boolean or enumeration: no fields of its own. */
  private isLeaf(raw: Schema): boolean {
    const s = this.r.unwrapNullable(raw).schema;
    const t = this.r.typeOf(s);
    return Boolean(this.r.enumOf(s)) || t === 'number' || t === 'integer' || t === 'string' || t === 'boolean';
  }

  private choice(box: HTMLElement, s: Schema, path: Path, tags: string[], value: unknown, name: string): void {
    const current = isObject(value) ? Object.keys(value)[0] : undefined;
    const id = nextId();
    const sel = el('select', { id, 'data-focus': `${pathString(path)}#choice` }) as HTMLSelectElement;
    for (const t of tags) sel.append(el('option', { value: t }, [t]));
    sel.value = current ?? tags[0];
    sel.addEventListener('change', () => this.structural(path, this.r.variantValue(s, sel.value)));
    box.append(el('label', { for: id, class: 'choice' }, [`${name}: kind`]), sel);
    if (tags.includes('job') && this.hooks.jobPicker) {
      box.append(
        this.hooks.jobPicker(pathString(path), isObject(value) ? value.job : undefined, (jobId) =>
          this.structural(path, { job: jobId }),
        ),
      );
    }
    if (current && tags.includes(current)) box.append(this.node(this.r.variantSchema(s, current), [...path, current], current, true));
  }

  private untagged(box: HTMLElement, s: Schema, path: Path, value: unknown, name: string): void {
    const i = this.r.variantIndex(s, value);
    const id = nextId();
    const sel = el('select', { id, 'data-focus': `${pathString(path)}#variant` }) as HTMLSelectElement;
    s.oneOf.forEach((raw: Schema, k: number) => {
      const v = this.r.deref(raw);
      sel.append(el('option', { value: String(k) }, [v.title ?? firstLine(v.description) ?? this.r.typeOf(v) ?? `choice ${k + 1}`]));
    });
    sel.value = String(i);
    sel.addEventListener('change', () => this.structural(path, this.r.initial(s.oneOf[Number(sel.value)])));
    box.append(el('label', { for: id, class: 'choice' }, [`${name}: form`]), sel);
    const inner = this.r.deref(s.oneOf[i]);
    const t = this.r.typeOf(inner);
    if (t === 'object') this.object(box, inner, path);
    else if (t === 'array') this.list(box, inner, path, name);
    else box.append(this.leaf(inner, path, name, true, this.r.enumOf(inner), false));
  }

  private list(box: HTMLElement, s: Schema, path: Path, name: string): void {
    const items = (this.get(path) as unknown[]) ?? [];
    const fixed = s.minItems !== undefined && s.minItems === s.maxItems;
    const ol = el('ol', { class: fixed ? 'list inline' : 'list' });
    items.forEach((_, i) => {
      const li = el('li');
      // A pair's items are named by their own schema (`u`, `height_m`), a list's by their place.
      const own = Array.isArray(s.prefixItems) ? /^(\w+):/.exec(this.r.itemSchema(s, i).description ?? '')?.[1] : undefined;
      li.append(this.node(this.r.itemSchema(s, i), [...path, i], own ?? `${name}[${i}]`, true));
      if (!fixed && (s.minItems === undefined || items.length > s.minItems)) {
        const rm = el('button', { type: 'button', class: 'remove', 'data-focus': `${pathString(path)}[${i}]#rm`, 'aria-label': `Remove ${name} ${i + 1}` }, ['Remove']);
        rm.addEventListener('click', () => {
          const next = [...items];
          next.splice(i, 1);
          this.structural(path, next);
        });
        li.append(rm);
      }
      ol.append(li);
    });
    box.append(ol);
    if (!fixed && (s.maxItems === undefined || items.length < s.maxItems)) {
      const add = el('button', { type: 'button', class: 'add', 'data-focus': `${pathString(path)}#add` }, [`Add to ${name}`]);
      add.addEventListener('click', () => this.structural(path, [...items, this.r.initial(this.r.itemSchema(s, items.length))]));
      box.append(add);
    }
  }

  /** A number, text, boolean or enumeration. */
  private leaf(
    s: Schema,
    path: Path,
    name: string,
    required: boolean,
    en: { value: unknown; description?: string }[] | null,
    labelled = true,
  ): HTMLElement {
    const field = pathString(path);
    const box = this.box('field', field);
    const id = nextId();
    const value = this.get(path);
    const type = this.r.typeOf(s);
    let control: HTMLElement;
    if (en) {
      const sel = el('select', { id, 'data-focus': field }) as HTMLSelectElement;
      if (!required) sel.append(el('option', { value: '' }, [s.default !== undefined ? `default (${s.default})` : '(not set)']));
      en.forEach((e, k) => sel.append(el('option', { value: String(k), title: e.description ?? '' }, [String(e.value)])));
      const k = en.findIndex((e) => e.value === value);
      sel.value = k >= 0 ? String(k) : required ? '0' : '';
      sel.addEventListener('change', () => this.set(path, sel.value === '' ? undefined : en[Number(sel.value)].value));
      control = sel;
    } else if (type === 'boolean') {
      const cb = el('input', { id, type: 'checkbox', 'data-focus': field }) as HTMLInputElement;
      cb.checked = Boolean(value ?? s.default ?? false);
      cb.addEventListener('change', () => this.set(path, cb.checked));
      control = cb;
    } else if (type === 'integer' || type === 'number') {
      const input = el('input', { id, type: 'number', 'data-focus': field, step: type === 'integer' ? '1' : 'any', inputmode: type === 'integer' ? 'numeric' : 'decimal' }) as HTMLInputElement;
      const lo = num(s.minimum);
      const hi = num(s.maximum);
      if (lo !== undefined) input.min = String(lo);
      if (hi !== undefined && Math.abs(hi) < 1e15) input.max = String(hi);
      if (s.default !== undefined) input.placeholder = String(s.default);
      if (typeof value === 'number') input.value = String(value);
      input.addEventListener('input', () => {
        const t = input.value.trim();
        this.set(path, t === '' ? (required ? null : undefined) : Number(t));
      });
      control = input;
      const range = slider(s, type, input, name);
      if (range) control = el('span', { class: 'number-slider', id: `${id}-wrap` }, [input, range]);
    } else {
      const input = el('input', { id, type: 'text', 'data-focus': field, autocomplete: 'off' }) as HTMLInputElement;
      if (s.maxLength !== undefined) input.maxLength = s.maxLength;
      if (s.default !== undefined) input.placeholder = String(s.default);
      if (typeof value === 'string') input.value = value;
      input.addEventListener('input', () => this.set(path, input.value === '' && !required ? undefined : input.value));
      control = input;
      if (/png_base64$/.test(field)) control = this.upload(input, path, id);
    }
    const helpId = `${id}-help`;
    // The labelled control itself, inside a wrapper (a slider, a file picker) if there is one.
    const own = (control.id === id ? control : control.querySelector(`#${CSS.escape(id)}`)) ?? control;
    own.setAttribute('aria-describedby', `${helpId} ${id}-err`);
    if (labelled) {
      box.append(el('label', { for: id }, [name, required ? el('span', { class: 'req', 'aria-hidden': 'true' }, [' *']) : '']));
      if (required) own.setAttribute('aria-required', 'true');
    } else own.setAttribute('aria-label', name);
    box.append(control, this.help(s, id), this.errorLine(`${id}-err`));
    return box;
  }

  /** A base64 field: a file picker beside the text. */
  private upload(input: HTMLInputElement, path: Path, id: string): HTMLElement {
    const file = el('input', { type: 'file', accept: 'image/png', 'aria-label': 'PNG file' }) as HTMLInputElement;
    file.addEventListener('change', async () => {
      const f = file.files?.[0];
      if (!f) return;
      const bytes = new Uint8Array(await f.arrayBuffer());
      let bin = '';
      for (let i = 0; i < bytes.length; i += 0x8000) bin += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
      input.value = btoa(bin);
      this.set(path, input.value);
    });
    return el('span', { class: 'upload', id: `${id}-wrap` }, [input, file]);
  }

  private box(cls: string, field: string): HTMLElement {
    const box = el(cls.startsWith('group') ? 'fieldset' : 'div', { class: cls, 'data-path': field });
    this.fields.set(field, box);
    return box;
  }

  private help(s: Schema, id: string): HTMLElement {
    const bits: string[] = [];
    if (s.description) bits.push(s.description);
    // What the description already says (a label's "at most 200 characters") is not said twice.
    const b = bounds(s)
      .split(', ')
      .filter((part) => part && !(s.description ?? '').includes(part))
      .join(', ');
    if (b) bits.push(b);
    return el('small', { class: 'help', id: `${id}-help` }, prose(bits.join(' — ')));
  }

  private errorLine(id?: string): HTMLElement {
    return el('div', { class: 'error', role: 'alert', hidden: '', ...(id ? { id } : {}) });
  }
}

/**
 * A slider beside a bounded number's box (both ends stated, a span a slider can step through):
 * the two kept together, typing in the box moving the slider and dragging it writing the box.
 */
function slider(s: Schema, type: string | undefined, input: HTMLInputElement, name: string): HTMLInputElement | null {
  const lo = num(s.minimum) ?? num(s.exclusiveMinimum);
  const hi = num(s.maximum) ?? num(s.exclusiveMaximum);
  if (lo === undefined || hi === undefined || !(hi > lo) || hi - lo > 1e4) return null;
  if (type === 'integer' && hi - lo < 2) return null;
  const step = type === 'integer' ? 1 : Number(((hi - lo) / 200).toPrecision(1));
  const range = el('input', { type: 'range', min: String(lo), max: String(hi), step: String(step), 'aria-label': `${name} (slider)`, tabindex: '-1' }) as HTMLInputElement;
  const fromBox = () => {
    const v = input.value === '' ? Number(input.placeholder) : Number(input.value);
    if (Number.isFinite(v)) range.value = String(v);
  };
  fromBox();
  input.addEventListener('input', fromBox);
  range.addEventListener('input', () => {
    input.value = range.value;
    input.dispatchEvent(new Event('input'));
  });
  return range;
}

/** What the schema states about a value's range, for the help text. */
function bounds(s: Schema): string {
  const parts: string[] = [];
  if (s.default !== undefined) parts.push(`default ${JSON.stringify(s.default)}`);
  const lo = num(s.minimum);
  const hi = num(s.maximum);
  const xlo = num(s.exclusiveMinimum);
  const xhi = num(s.exclusiveMaximum);
  // The smallest positive f32 as a minimum is how the schema says "above 0" for an f32.
  if (lo !== undefined) parts.push(lo > 0 && lo < 1e-30 ? '> 0' : `≥ ${readable(lo)}`);
  if (xlo !== undefined) parts.push(`> ${readable(xlo)}`);
  if (hi !== undefined) parts.push(`≤ ${readable(hi)}`);
  if (xhi !== undefined) parts.push(`< ${readable(xhi)}`);
  if (s.maxLength !== undefined) parts.push(`at most ${s.maxLength} characters`);
  if (s.minItems !== undefined || s.maxItems !== undefined) parts.push(`${s.minItems ?? 0}–${s.maxItems ?? '∞'} items`);
  return parts.join(', ');
}

/**
 * A bound as people read it. JSON numbers past 2⁵³ arrive rounded (u64::MAX, a seed's maximum,
 * reads 18446744073709552000): the integer limits are named, other large numbers shortened.
 */
export function readable(n: number): string {
  if (n >= 2 ** 64 - 2 ** 11) return '2⁶⁴ − 1';
  if (n >= 2 ** 63 - 2 ** 10 && n <= 2 ** 63) return '2⁶³ − 1';
  if (n >= 2 ** 32 - 1 && n <= 2 ** 32) return '2³² − 1';
  if (Math.abs(n) >= 1e9) return n.toExponential().replace(/e\+?/, ' × 10^');
  return String(n);
}

/** Help text with its Markdown `code` spans as <code> (the schema's descriptions use them). */
export function prose(text: string): (Node | string)[] {
  return text.split('`').map((part, k) => (k % 2 === 1 ? el('code', {}, [part]) : part)).filter((p) => p !== '');
}

function firstLine(s?: string): string | undefined {
  return s ? s.replaceAll('`', '').split(/[.\n]/)[0].slice(0, 60) : undefined;
}

export function el(tag: string, attrs: Record<string, string> = {}, children: (Node | string)[] = []): HTMLElement {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  e.append(...children);
  return e;
}
