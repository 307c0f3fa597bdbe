// The OpenAPI document, read at run time: each kind's request schema, $refs resolved, and the
// checks the schema states (bounds, lengths, patterns, required fields, one-of choices), so a
// request is checked before it is sent.

import { getJson } from './api';

export type Schema = Record<string, any>;
export type Path = (string | number)[];

export interface Doc {
  paths: Record<string, any>;
  components: { schemas: Record<string, Schema> };
}

let docPromise: Promise<Doc> | null = null;

/** The document (fetched once; again after a failure, e.g. once a key has been given). */
export function openapi(): Promise<Doc> {
  docPromise ??= getJson<Doc>('/openapi.json');
  docPromise.catch(() => (docPromise = null));
  return docPromise;
}

/** The kinds the server runs, with their summaries, in the document's order. */
export function kinds(doc: Doc): { kind: string; summary: string; description: string }[] {
  return Object.entries(doc.paths)
    .filter(([p, item]) => /^\/v1\/jobs\/[a-z-]+$/.test(p) && item.post)
    .map(([p, item]) => ({
      kind: p.slice('/v1/jobs/'.length),
      summary: item.post.summary ?? '',
      description: item.post.description ?? '',
    }));
}

export function requestSchema(doc: Doc, kind: string): Schema {
  const op = doc.paths[`/v1/jobs/${kind}`]?.post;
  const s = op?.requestBody?.content?.['application/json']?.schema;
  if (!s) throw new Error(`no request schema for ${kind}`);
  return s;
}

export class Resolver {
  constructor(private doc: Doc) {}

  /** The schema a `$ref` names, keeping the description written beside the `$ref`. */
  deref(s: Schema): Schema {
    let out = s;
    let guard = 0;
    while (out && out.$ref && guard++ < 32) {
      const name = String(out.$ref).replace('#/components/schemas/', '');
      const target = this.doc.components.schemas[name] ?? {};
      const { $ref: _ignored, ...beside } = out;
      out = { ...target, ...beside, description: beside.description ?? target.description, title: target.title ?? name };
    }
    return out ?? {};
  }

  /** `oneOf: [null, X]` or `type: [T, "null"]`: X or T, and that null is allowed. */
  unwrapNullable(raw: Schema): { schema: Schema; nullable: boolean } {
    const s = this.deref(raw);
    if (Array.isArray(s.oneOf)) {
      const rest = s.oneOf.filter((v: Schema) => v.type !== 'null');
      if (rest.length === 1 && rest.length < s.oneOf.length) {
        const inner = this.deref(rest[0]);
        return { schema: { ...inner, description: s.description ?? inner.description }, nullable: true };
      }
    }
    if (Array.isArray(s.type) && s.type.includes('null')) {
      const types = s.type.filter((t: string) => t !== 'null');
      return { schema: { ...s, type: types.length === 1 ? types[0] : types }, nullable: true };
    }
    return { schema: s, nullable: false };
  }

  /** A one-of whose variants are objects of one required key each: the keys. */
  tags(s: Schema): string[] | null {
    if (!Array.isArray(s.oneOf)) return null;
    const tags: string[] = [];
    for (const raw of s.oneOf) {
      const v = this.deref(raw);
      if (v.type !== 'object' || !Array.isArray(v.required) || v.required.length !== 1) return null;
      if (Object.keys(v.properties ?? {}).length !== 1) return null;
      tags.push(v.required[0]);
    }
    return tags;
  }

  /** A one-of of single-value enums (a documented enumeration): the values. */
  enumOf(s: Schema): { value: unknown; description?: string }[] | null {
    if (Array.isArray(s.enum)) return s.enum.map((value: unknown) => ({ value }));
    if (!Array.isArray(s.oneOf)) return null;
    const out: { value: unknown; description?: string }[] = [];
    for (const raw of s.oneOf) {
      const v = this.deref(raw);
      if (!Array.isArray(v.enum)) return null;
      for (const value of v.enum) out.push({ value, description: v.description });
    }
    return out;
  }

  /** The schema of a list's item `i`: its own (`prefixItems`, a pair's u and height), else the list's. */
  itemSchema(s: Schema, i: number): Schema {
    const own = Array.isArray(s.prefixItems) ? s.prefixItems[i] : undefined;
    return this.deref(own ?? (s.items && typeof s.items === 'object' ? s.items : {}));
  }

  typeOf(s: Schema): string | undefined {
    if (typeof s.type === 'string') return s.type;
    if (s.properties) return 'object';
    if (s.items || s.prefixItems) return 'array';
    return undefined;
  }

  /** A value to start a field with: its default, else the least the schema accepts. */
  initial(raw: Schema): unknown {
    const { schema: s, nullable } = this.unwrapNullable(raw);
    if (s.default !== undefined) return structuredClone(s.default);
    if (nullable) return null;
    const en = this.enumOf(s);
    if (en) return en[0]?.value;
    const tags = this.tags(s);
    if (tags) return this.variantValue(s, tags[0]);
    if (Array.isArray(s.oneOf)) return this.initial(s.oneOf[0]);
    switch (this.typeOf(s)) {
      case 'object': {
        const o: Record<string, unknown> = {};
        for (const k of s.required ?? []) o[k] = this.initial(s.properties?.[k] ?? {});
        return o;
      }
      case 'array': {
        const n = s.minItems ?? 0;
        return Array.from({ length: n }, (_, i) => this.initial(this.itemSchema(s, i)));
      }
      case 'integer':
      case 'number': {
        const lo = num(s.minimum) ?? num(s.exclusiveMinimum);
        const hi = num(s.maximum);
        if (lo !== undefined && lo > 0) return s.exclusiveMinimum !== undefined ? Math.min(1, hi ?? 1) : lo;
        return 0;
      }
      case 'boolean':
        return false;
      case 'string':
        return '';
      default:
        return null;
    }
  }

  variantSchema(s: Schema, tag: string): Schema {
    for (const raw of s.oneOf) {
      const v = this.deref(raw);
      if (v.required?.[0] === tag) return v.properties[tag];
    }
    return {};
  }

  variantValue(s: Schema, tag: string): Record<string, unknown> {
    return { [tag]: this.initial(this.variantSchema(s, tag)) };
  }

  /** Which variant of an untagged one-of `value` is: the first with no errors, else the first. */
  variantIndex(s: Schema, value: unknown): number {
    const i = s.oneOf.findIndex((v: Schema) => this.check(v, value, [], []) === 0);
    return i < 0 ? 0 : i;
  }

  /** Check `value` against `raw`, pushing each problem with its JSON path; the count found. */
  check(raw: Schema, value: unknown, path: Path, out: { field: string; message: string }[]): number {
    const before = out.length;
    const { schema: s, nullable } = this.unwrapNullable(raw);
    if (value === null || value === undefined) {
      if (!nullable && value === null) out.push({ field: pathString(path), message: 'must be set' });
      return out.length - before;
    }
    const en = this.enumOf(s);
    if (en) {
      if (!en.some((e) => e.value === value)) {
        out.push({ field: pathString(path), message: `must be one of ${en.map((e) => JSON.stringify(e.value)).join(', ')}` });
      }
      return out.length - before;
    }
    const tags = this.tags(s);
    if (tags) {
      const keys = isObject(value) ? Object.keys(value) : [];
      if (keys.length !== 1 || !tags.includes(keys[0])) {
        out.push({ field: pathString(path), message: `must be exactly one of: ${tags.join(', ')}` });
      } else {
        this.check(this.variantSchema(s, keys[0]), (value as any)[keys[0]], [...path, keys[0]], out);
      }
      return out.length - before;
    }
    if (Array.isArray(s.oneOf)) {
      const tries: { field: string; message: string }[][] = s.oneOf.map((v: Schema) => {
        const errs: { field: string; message: string }[] = [];
        this.check(v, value, path, errs);
        return errs;
      });
      if (!tries.some((e) => e.length === 0)) {
        out.push(...tries.reduce((a, b) => (b.length < a.length ? b : a)));
      }
      return out.length - before;
    }
    const field = pathString(path);
    const type = this.typeOf(s);
    if (type === 'integer' || type === 'number') {
      if (typeof value !== 'number' || !Number.isFinite(value)) {
        out.push({ field, message: 'must be a number' });
      } else {
        if (type === 'integer' && !Number.isInteger(value)) out.push({ field, message: 'must be a whole number' });
        const min = num(s.minimum);
        const max = num(s.maximum);
        const xmin = num(s.exclusiveMinimum);
        const xmax = num(s.exclusiveMaximum);
        if (min !== undefined && value < min) out.push({ field, message: `must be at least ${min}` });
        if (max !== undefined && value > max) out.push({ field, message: `must be at most ${max}` });
        if (xmin !== undefined && value <= xmin) out.push({ field, message: `must be more than ${xmin}` });
        if (xmax !== undefined && value >= xmax) out.push({ field, message: `must be less than ${xmax}` });
      }
    } else if (type === 'string') {
      if (typeof value !== 'string') out.push({ field, message: 'must be text' });
      else {
        const len = [...value].length;
        if (s.minLength !== undefined && len < s.minLength) out.push({ field, message: `must have at least ${s.minLength} characters` });
        if (s.maxLength !== undefined && len > s.maxLength) out.push({ field, message: `must have at most ${s.maxLength} characters` });
        if (s.pattern && !new RegExp(s.pattern, 'u').test(value)) out.push({ field, message: `must match ${s.pattern}` });
      }
    } else if (type === 'boolean') {
      if (typeof value !== 'boolean') out.push({ field, message: 'must be true or false' });
    } else if (type === 'array') {
      if (!Array.isArray(value)) out.push({ field, message: 'must be a list' });
      else {
        if (s.minItems !== undefined && value.length < s.minItems) out.push({ field, message: `must have at least ${s.minItems} items` });
        if (s.maxItems !== undefined && value.length > s.maxItems) out.push({ field, message: `must have at most ${s.maxItems} items` });
        value.forEach((v, i) => this.check(this.itemSchema(s, i), v, [...path, i], out));
      }
    } else if (type === 'object') {
      if (!isObject(value)) out.push({ field, message: 'must be an object' });
      else {
        for (const k of s.required ?? []) {
          if ((value as any)[k] === undefined) out.push({ field: pathString([...path, k]), message: 'is required' });
        }
        for (const [k, v] of Object.entries(value)) {
          const ps = s.properties?.[k];
          if (ps) this.check(ps, v, [...path, k], out);
          else if (s.additionalProperties === false) {
            const near = nearest(k, Object.keys(s.properties ?? {}));
            out.push({ field: pathString([...path, k]), message: `is not a field of this object${near ? ` — did you mean “${near}”?` : ''}` });
          }
        }
      }
    }
    return out.length - before;
  }
}

/** The name among `names` closest to `word` (edit distance at most a third of its length, and 3). */
export function nearest(word: string, names: string[]): string | undefined {
  let best: string | undefined;
  let bestD = Math.min(3, Math.max(1, Math.floor(word.length / 3)));
  for (const n of names) {
    const d = editDistance(word.toLowerCase(), n.toLowerCase());
    if (d <= bestD) {
      best = n;
      bestD = d - 1;
    }
  }
  return best;
}

function editDistance(a: string, b: string): number {
  let prev = Array.from({ length: b.length + 1 }, (_, j) => j);
  for (let i = 1; i <= a.length; i++) {
    const row = [i];
    for (let j = 1; j <= b.length; j++) row[j] = Math.min(prev[j] + 1, row[j - 1] + 1, prev[j - 1] + (a[i - 1] === b[j - 1] ? 0 : 1));
    prev = row;
  }
  return prev[b.length];
}

export function num(v: unknown): number | undefined {
  if (v === undefined || v === null) return undefined;
  const n = Number(v);
  return Number.isFinite(n) ? n : undefined;
}

export function isObject(v: unknown): v is Record<string, unknown> {
  return typeof v === 'object' && v !== null && !Array.isArray(v);
}

/** A path the way the server names fields: `operations[2].pass.blade.width_m`. */
export function pathString(path: Path): string {
  let s = '';
  for (const p of path) {
    if (typeof p === 'number') s += `[${p}]`;
    else s += s ? `.${p}` : p;
  }
  return s;
}
