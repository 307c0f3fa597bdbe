// Talking to the service: typed JSON calls (openapi-fetch over the types openapi-typescript
// generates from openapi.yaml: `npm run gen:api`, checked by `npm run check:api`) with the tab's
// API key, problem+json errors, and artifacts fetched as blobs (an <img> cannot send an
// Authorization header).
//
// Left on plain fetch, through `call`: artifact and snapshot downloads (binary bodies read as a
// blob or an ArrayBuffer, named by the `href` the server hands out rather than by a route here),
// `/openapi.json` (not a route of the document itself), and the event stream (sse.ts: read
// incrementally with Last-Event-ID resumption, which openapi-fetch's parse-the-whole-body model
// does not fit).

import createClient from 'openapi-fetch';
import type { components, paths } from './generated/openapi';

type Schemas = components['schemas'];

const KEY = 'landform-api-key';

export type FieldError = Schemas['FieldError'];
export type Problem = Schemas['Problem'];
export type JobStatus = Schemas['JobStatus'];
export type JobPage = Schemas['JobPage'];
export type Artifact = Schemas['ArtifactMeta'];
export type Job = Schemas['Job'];

export type Progress = Schemas['Progress'];

/** A progress event's data on the event stream: the progress, and a new live snapshot's href. */
export type ProgressEvent = Progress & { snapshot?: string };

/** The request path of each kind (the POST routes that take a JSON body), and the kinds' names. */
type SubmitPath = {
  [P in keyof paths]: paths[P]['post'] extends { requestBody: { content: { 'application/json': unknown } } } ? P : never;
}[keyof paths];
// Distributed over the paths (a type parameter): the drafts' `/v1/drafts/…` are not kinds' submissions.
type KindOf<P> = P extends `/v1/jobs/${infer K}` ? K : never;
export type Kind = KindOf<SubmitPath>;
/** The request body each kind takes. */
export type SubmitBody<K extends Kind> = NonNullable<paths[`/v1/jobs/${K}`]['post']>['requestBody']['content']['application/json'];
type ListQuery = NonNullable<paths['/v1/jobs']['get']['parameters']['query']>;

/**
 * A problem as the page handles it: the server's problem+json, or, for an answer that is not
 * one (a proxy's error page, say), the status and its text.
 */
export type ProblemLike = Partial<Problem> & { status: number; [k: string]: unknown };

export class ApiError extends Error {
  constructor(public problem: ProblemLike) {
    super(problem.detail || problem.title || `HTTP ${problem.status}`);
  }
}

/** The key this tab uses: kept in session storage only, never in local storage or a cookie. */
export function apiKey(): string | null {
  return sessionStorage.getItem(KEY);
}

export function setApiKey(key: string | null): void {
  if (key) sessionStorage.setItem(KEY, key);
  else sessionStorage.removeItem(KEY);
}

/**
 * Called when the server refuses a call for its key (401, or 403): the page asks for a key,
 * saying why from the server's problem.
 */
let onUnauthorized: (problem: ProblemLike) => void = () => {};
export function whenUnauthorized(f: (problem: ProblemLike) => void): void {
  onUnauthorized = f;
}
const refused = (status: number): boolean => status === 401 || status === 403;

export function authHeaders(extra: Record<string, string> = {}): Record<string, string> {
  const key = apiKey();
  return key ? { ...extra, authorization: `Bearer ${key}` } : extra;
}

/** A failed answer's problem: its JSON object body with the HTTP status, else the status line. */
function problemOf(res: Response, body: unknown): ProblemLike {
  if (body && typeof body === 'object') return { status: res.status, ...body };
  return { status: res.status, title: res.statusText || `HTTP ${res.status}` };
}

/** The typed client: the key is added to each request as it is sent (it can change any time). */
const client = createClient<paths>();
client.use({
  onRequest({ request }) {
    const key = apiKey();
    if (key) request.headers.set('authorization', `Bearer ${key}`);
    return request;
  },
});

/** An openapi-fetch answer's data, or an ApiError with its problem (401 first asks for a key). */
async function ok<D>(call: Promise<{ data?: D; error?: unknown; response: Response }>): Promise<D> {
  const { data, error, response } = await call;
  if (!response.ok) {
    const problem = problemOf(response, error);
    if (refused(response.status)) onUnauthorized(problem);
    throw new ApiError(problem);
  }
  return data as D;
}

/** A plain fetch with the key, for what is not a typed JSON route (see the top of this file). */
export async function call(path: string, init: RequestInit = {}): Promise<Response> {
  const headers = authHeaders((init.headers as Record<string, string>) || {});
  const res = await fetch(path, { ...init, headers });
  if (!res.ok) {
    let body: unknown;
    try {
      body = await res.json();
    } catch {
      // not JSON: the status line
    }
    const problem = problemOf(res, body);
    if (refused(res.status)) onUnauthorized(problem);
    throw new ApiError(problem);
  }
  return res;
}

export async function getJson<T>(path: string): Promise<T> {
  return (await call(path)).json() as Promise<T>;
}

export const jobs = {
  get: async (id: string): Promise<Job> => (await ok(client.GET('/v1/jobs/{id}', { params: { path: { id } } }))) as Job,
  list: async (q: { kind?: string; status?: string; limit?: number; cursor?: string | null; replays?: boolean }): Promise<JobPage> => {
    const query: ListQuery = {
      kind: (q.kind || undefined) as ListQuery['kind'],
      status: (q.status || undefined) as ListQuery['status'],
      limit: q.limit ?? 20,
      cursor: q.cursor || undefined,
      // Replays are filtered by the server: a page filtered here after fetching could be empty
      // while older jobs exist (a timeline makes a replay for each position).
      ...(q.replays === false ? { replays: false } : {}),
    };
    return (await ok(client.GET('/v1/jobs', { params: { query } }))) as JobPage;
  },
  /** A new job of `kind` (a kind the server's document names; the body as the form made it). */
  submit: async (kind: string, body: unknown): Promise<Job> =>
    (await ok(client.POST(`/v1/jobs/${kind as Kind}`, { body: body as SubmitBody<Kind> }))) as Job,
  cancel: async (id: string): Promise<Job> => (await ok(client.POST('/v1/jobs/{id}/cancel', { params: { path: { id } } }))) as Job,
  remove: async (id: string): Promise<void> => {
    await ok(client.DELETE('/v1/jobs/{id}', { params: { path: { id } } }));
  },
  /** A replay up to `step`, held until it ends (the server waits at most 60 s). */
  replay: async (id: string, step: number): Promise<Job> =>
    (await ok(
      client.POST('/v1/jobs/{id}/replay', {
        params: { path: { id }, header: { Prefer: 'wait=60' } },
        body: { until_step: step },
      }),
    )) as Job,
};

/** A draft's answer: the mesh, the server's time for it, and the kind's result figures. */
export interface DraftAnswer {
  glb: ArrayBuffer;
  seconds: number;
  result: Record<string, unknown> | null;
}

export const drafts = {
  /**
   * A draft of `kind` (`POST /v1/drafts/{kind}`): the body run at once at reduced resolution,
   * answered with its mesh, nothing stored. On plain fetch: the answer is a glb, not JSON.
   */
  run: async (kind: string, body: unknown, signal: AbortSignal): Promise<DraftAnswer> => {
    const res = await call(`/v1/drafts/${encodeURIComponent(kind)}`, {
      method: 'POST',
      headers: { 'content-type': 'application/json' },
      body: JSON.stringify(body),
      signal,
    });
    let result: Record<string, unknown> | null = null;
    try {
      result = JSON.parse(res.headers.get('landform-draft-result') ?? 'null');
    } catch {
      // a result too large for a header is left out
    }
    return { glb: await res.arrayBuffer(), seconds: Number(res.headers.get('landform-draft-seconds') ?? NaN), result };
  },
};

const blobs = new Map<string, Promise<string>>();

/** An object URL for an artifact or snapshot; artifacts are immutable, so each is fetched once. */
export function blobUrl(href: string, cache = true): Promise<string> {
  const hit = cache ? blobs.get(href) : undefined;
  if (hit) return hit;
  const p = call(href)
    .then((r) => r.blob())
    .then((b) => URL.createObjectURL(b));
  if (cache) {
    blobs.set(href, p);
    p.catch(() => blobs.delete(href));
  }
  return p;
}

export async function arrayBuffer(href: string): Promise<ArrayBuffer> {
  return (await call(href)).arrayBuffer();
}

export function artifact(job: Job, name: string): Artifact | undefined {
  return job.artifacts.find((a) => a.name === name);
}

export function humanBytes(n: number): string {
  if (n < 1024) return `${n} B`;
  const units = ['KiB', 'MiB', 'GiB'];
  let v = n / 1024;
  let i = 0;
  while (v >= 1024 && i < units.length - 1) {
    v /= 1024;
    i++;
  }
  return `${v.toFixed(v < 10 ? 1 : 0)} ${units[i]}`;
}

export function age(iso: string, now = Date.now()): string {
  const s = Math.max(0, Math.round((now - Date.parse(iso)) / 1000));
  if (s < 60) return `${s} s ago`;
  if (s < 3600) return `${Math.floor(s / 60)} min ago`;
  if (s < 86400) return `${Math.floor(s / 3600)} h ago`;
  return `${Math.floor(s / 86400)} d ago`;
}
