// The hash of everything the bundle is built from, written beside the bundle (dist/source.sha256)
// by `npm run build`. tests/web_bundle.rs computes the same hash in Rust and fails when the two
// differ: the committed bundle is stale against web/src (or the presets in api/).
//
// The hash: sha256 over, for each file in repository-relative path order, the line
// "<path>\n<sha256 of its bytes in hex>\n". The files: every file under web/src,
// web/index.html, web/vite.config.ts, web/tsconfig.json, web/package-lock.json and api/*/*.json.
import { createHash } from 'node:crypto';
import { readFileSync, readdirSync, statSync, writeFileSync } from 'node:fs';
import { dirname, join, relative } from 'node:path';
import { fileURLToPath } from 'node:url';

const repo = join(dirname(fileURLToPath(import.meta.url)), '..', '..');

function walk(dir) {
  return readdirSync(dir).flatMap((n) => {
    const p = join(dir, n);
    return statSync(p).isDirectory() ? walk(p) : [p];
  });
}

export function sourceFiles() {
  const files = [
    ...walk(join(repo, 'web', 'src')),
    ...['index.html', 'vite.config.ts', 'tsconfig.json', 'package-lock.json'].map((n) => join(repo, 'web', n)),
    ...readdirSync(join(repo, 'api'))
      .filter((d) => statSync(join(repo, 'api', d)).isDirectory())
      .flatMap((d) => readdirSync(join(repo, 'api', d)).filter((n) => n.endsWith('.json')).map((n) => join(repo, 'api', d, n))),
  ];
  return files.map((f) => relative(repo, f).split('\\').join('/')).sort();
}

export function sourceHash() {
  const h = createHash('sha256');
  for (const rel of sourceFiles()) {
    h.update(`${rel}\n${createHash('sha256').update(readFileSync(join(repo, rel))).digest('hex')}\n`);
  }
  return h.digest('hex');
}

const out = join(repo, 'web', 'dist', 'source.sha256');
if (process.argv.includes('--write')) {
  writeFileSync(out, `${sourceHash()}\n`);
} else if (process.argv.includes('--check')) {
  const want = sourceHash();
  const have = readFileSync(out, 'utf8').trim();
  if (want !== have) {
    console.error(`web/dist is stale: built from ${have}, sources are ${want}; run npm run build in web/`);
    process.exit(1);
  }
}
