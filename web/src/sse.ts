// The job's event stream, read with fetch rather than EventSource so that it can carry the API key.
// A dropped connection is resumed with Last-Event-ID, so no progress event is missed or repeated.

import { authHeaders } from './api';

export interface StreamEvent {
  event: string;
  id?: string;
  data: string;
}

export interface StreamOptions {
  onEvent: (e: StreamEvent) => void;
  /** Each (re)connection, with the id resumed after (undefined on the first). */
  onConnect?: (lastEventId: string | undefined) => void;
  signal: AbortSignal;
}

/** Follow `/v1/jobs/{id}/events` until `done` arrives or `signal` aborts. */
export async function followJob(id: string, opts: StreamOptions): Promise<void> {
  let lastId: string | undefined;
  let delay = 500;
  while (!opts.signal.aborted) {
    try {
      opts.onConnect?.(lastId);
      const headers = authHeaders({ accept: 'text/event-stream' });
      if (lastId !== undefined) headers['last-event-id'] = lastId;
      const res = await fetch(`/v1/jobs/${id}/events`, { headers, signal: opts.signal });
      if (!res.ok || !res.body) {
        if (res.status >= 400 && res.status < 500) return; // gone or not ours: nothing to resume
        throw new Error(`HTTP ${res.status}`);
      }
      delay = 500;
      let done = false;
      for await (const e of parse(res.body)) {
        if (e.id !== undefined) lastId = e.id;
        opts.onEvent(e);
        if (e.event === 'done') done = true;
      }
      if (done) return;
    } catch (err) {
      if (opts.signal.aborted) return;
      console.warn('event stream dropped; resuming', err);
    }
    await new Promise((r) => setTimeout(r, delay));
    delay = Math.min(delay * 2, 5000);
  }
}

async function* parse(body: ReadableStream<Uint8Array>): AsyncGenerator<StreamEvent> {
  const reader = body.getReader();
  const decoder = new TextDecoder();
  let buf = '';
  let event = 'message';
  let id: string | undefined;
  let data: string[] = [];
  for (;;) {
    const { value, done } = await reader.read();
    if (done) return;
    buf += decoder.decode(value, { stream: true });
    let nl: number;
    while ((nl = buf.search(/\r\n|\n|\r/)) >= 0) {
      const line = buf.slice(0, nl);
      buf = buf.slice(nl + (buf.startsWith('\r\n', nl) ? 2 : 1));
      if (line === '') {
        if (data.length) yield { event, id, data: data.join('\n') };
        event = 'message';
        id = undefined;
        data = [];
        continue;
      }
      if (line.startsWith(':')) continue; // keep-alive comment
      const colon = line.indexOf(':');
      const field = colon < 0 ? line : line.slice(0, colon);
      let value2 = colon < 0 ? '' : line.slice(colon + 1);
      if (value2.startsWith(' ')) value2 = value2.slice(1);
      if (field === 'event') event = value2;
      else if (field === 'data') data.push(value2);
      else if (field === 'id') id = value2;
    }
  }
}
