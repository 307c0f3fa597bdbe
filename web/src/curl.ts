// A request as a curl command, so the page teaches the API: what it sends is what a script
// would send. The key is never written out: the command reads it from $LANDFORM_KEY.

import { apiKey } from './api';

export function curlCommand(method: string, path: string, body?: unknown, extraHeaders: string[] = []): string {
  const parts = [`curl -sS -X ${method} '${location.origin}${path}'`];
  if (apiKey()) parts.push(`-H "authorization: Bearer $LANDFORM_KEY"`);
  for (const h of extraHeaders) parts.push(`-H '${h}'`);
  if (body !== undefined) {
    // A quoted here-document: the JSON goes as it is, whatever quotes it holds.
    parts.push(`-H 'content-type: application/json'`, `--data-binary @- <<'JSON'\n${JSON.stringify(body, null, 2)}\nJSON`);
  }
  return parts.join(' \\\n  ');
}

/** A <pre> of text with a Copy button (the clipboard, or the text selected where it is refused). */
export function copyBlock(id: string, label: string, text: () => string): { box: HTMLElement; refresh: () => void } {
  const pre = document.createElement('pre');
  pre.className = 'copyable';
  pre.id = id;
  pre.tabIndex = 0;
  const copy = document.createElement('button');
  copy.type = 'button';
  copy.textContent = `Copy ${label}`;
  const said = document.createElement('span');
  said.className = 'muted';
  said.setAttribute('role', 'status');
  copy.addEventListener('click', async () => {
    try {
      await navigator.clipboard.writeText(pre.textContent ?? '');
      said.textContent = ' copied';
    } catch {
      const range = document.createRange();
      range.selectNodeContents(pre);
      getSelection()?.removeAllRanges();
      getSelection()?.addRange(range);
      said.textContent = ' selected: press Ctrl+C to copy';
    }
  });
  const box = document.createElement('div');
  box.className = 'copy-block';
  box.append(copy, said, pre);
  const refresh = () => {
    pre.textContent = text();
    said.textContent = '';
  };
  refresh();
  return { box, refresh };
}
