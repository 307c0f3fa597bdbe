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

/**
 * The preset a first look runs ("Try it" on the landing page): one that finishes within seconds
 * here and shows what the kind does, rather than the first by name (carve-coast's cliff-strata
 * took over two minutes on two cores beside another job).
 */
const QUICK: Record<string, string> = {
  bulldoze: 'ziggurat',
  'carve-coast': 'small-island-one-pass',
  'deform-terrain': 'tileable',
  erode: 'eroded-island',
  'grow-cave': 'columns',
  'weather-column': 'goblin-cap',
};

export function quickPreset(kind: string): Preset | undefined {
  const all = presets(kind);
  return all.find((p) => p.name === QUICK[kind]) ?? all[0];
}
