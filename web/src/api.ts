// Talking to the service: JSON calls with the tab's API key, problem+json errors, and artifacts
// fetched as blobs (an <img> cannot send an Authorization header).

const KEY = 'landform-api-key';

export interface FieldError {
  field: string;
  message: string;
}

export interface Problem {
  type?: string;
  title?: string;
  status: number;
  detail?: string;
  errors?: FieldError[];
  [k: string]: unknown;
}

export interface Artifact {
  name: string;
  media_type: string;
  bytes: number;
  sha256: string;
  href: string;
}

export interface Progress {
  fraction: number;
  step: number;
  steps: number;
  stage: string;
  message: string;
  snapshot?: string;
}

export interface Job {
  id: string;
  kind: string;
  status: 'queued' | 'running' | 'succeeded' | 'failed' | 'cancelled';
  label?: string | null;
  created_at: string;
  started_at?: string | null;
  finished_at?: string | null;
  progress: Progress;
  request: Record<string, unknown>;
  result?: Record<string, unknown> | null;
  artifacts: Artifact[];
  error?: Problem | null;
  replay_of?: string | null;
  replay_until_step?: number | null;
}

export interface JobPage {
  items: Job[];
  next_cursor?: string | null;
}

export class ApiError extends Error {
  constructor(public problem: Problem) {
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

/** Called when the server answers 401: the page asks for a key. */
let onUnauthorized: () => void = () => {};
export function whenUnauthorized(f: () => void): void {
  onUnauthorized = f;
}

export function authHeaders(extra: Record<string, string> = {}): Record<string, string> {
  const key = apiKey();
  return key ? { ...extra, authorization: `Bearer ${key}` } : extra;
}

async function problemOf(res: Response): Promise<Problem> {
  try {
    const body = await res.json();
    if (body && typeof body === 'object') return { status: res.status, ...body };
  } catch {
    // not JSON: fall through
  }
  return { status: res.status, title: res.statusText || `HTTP ${res.status}` };
}

export async function call(path: string, init: RequestInit = {}): Promise<Response> {
  const headers = authHeaders((init.headers as Record<string, string>) || {});
  const res = await fetch(path, { ...init, headers });
  if (res.status === 401) onUnauthorized();
  if (!res.ok) throw new ApiError(await problemOf(res));
  return res;
}

export async function getJson<T>(path: string): Promise<T> {
  return (await call(path)).json() as Promise<T>;
}

export async function postJson<T>(path: string, body: unknown, headers: Record<string, string> = {}): Promise<T> {
  const res = await call(path, {
    method: 'POST',
    headers: { 'content-type': 'application/json', ...headers },
    body: JSON.stringify(body),
  });
  return res.json() as Promise<T>;
}

export const jobs = {
  get: (id: string) => getJson<Job>(`/v1/jobs/${id}`),
  list: (q: { kind?: string; status?: string; limit?: number; cursor?: string | null }) => {
    const p = new URLSearchParams();
    if (q.kind) p.set('kind', q.kind);
    if (q.status) p.set('status', q.status);
    p.set('limit', String(q.limit ?? 20));
    if (q.cursor) p.set('cursor', q.cursor);
    return getJson<JobPage>(`/v1/jobs?${p}`);
  },
  submit: (kind: string, body: unknown) => postJson<Job>(`/v1/jobs/${kind}`, body),
  cancel: (id: string) => call(`/v1/jobs/${id}/cancel`, { method: 'POST' }),
  remove: (id: string) => call(`/v1/jobs/${id}`, { method: 'DELETE' }),
  /** A replay up to `step`, held until it ends (the server waits at most 60 s). */
  replay: (id: string, step: number) =>
    postJson<Job>(`/v1/jobs/${id}/replay`, { until_step: step }, { prefer: 'wait=60' }),
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
