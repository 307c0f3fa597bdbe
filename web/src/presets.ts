// The examples of api/ (one complete request body each), bundled at build time as presets.

const files = import.meta.glob('../../api/*/*.json', { eager: true, import: 'default' }) as Record<string, unknown>;

export interface Preset {
  name: string;
  body: Record<string, unknown>;
}

export function presets(kind: string): Preset[] {
  return Object.entries(files)
    .map(([path, body]) => {
      const m = /api\/([^/]+)\/([^/]+)\.json$/.exec(path);
      return m && m[1] === kind ? { name: m[2], body: body as Record<string, unknown> } : null;
    })
    .filter((p): p is Preset => p !== null)
    .sort((a, b) => a.name.localeCompare(b.name));
}
