// The playground's API types, generated from the committed OpenAPI document (openapi.yaml, which
// tests/service_api.rs keeps equal to what the server prints) by openapi-typescript:
//
//   --write (npm run gen:api, and the first step of npm run build): regenerate
//           web/src/generated/openapi.d.ts
//   --check (npm run check:api, and scripts/playground-tests): fail when that file is not what
//           the document generates now (the drift check)
//
// Both run the same command, so the committed file is exactly what `--write` makes. `--check`
// generates into a temporary folder and compares byte for byte: a field changed in the server's
// schema (and openapi.yaml regenerated) without the types regenerated fails it.
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, relative } from 'node:path';
import { fileURLToPath } from 'node:url';

const web = join(dirname(fileURLToPath(import.meta.url)), '..');
const spec = join(web, '..', 'openapi.yaml');
const target = join(web, 'src', 'generated', 'openapi.d.ts');
const cli = join(web, 'node_modules', 'openapi-typescript', 'bin', 'cli.js');
// --empty-objects-unknown: `request`, `result` and `error` of a job are free-form objects, so
//   `Record<string, unknown>` rather than openapi-typescript's default `Record<string, never>`.
// --default-non-nullable=false: a member with a `default` stays optional. The schemas with
//   defaults are request bodies, where the server fills in what a client leaves out; none of
//   the response schemas (Job, JobPage, Problem, Progress, ArtifactMeta) has a default.
const options = ['--empty-objects-unknown', '--default-non-nullable=false'];

function generate(out) {
  execFileSync(process.execPath, [cli, spec, ...options, '--output', out], { cwd: web, stdio: ['ignore', 'ignore', 'inherit'] });
}

if (process.argv.includes('--write')) {
  generate(target);
} else if (process.argv.includes('--check')) {
  const dir = mkdtempSync(join(tmpdir(), 'landform-api-types-'));
  try {
    const fresh = join(dir, 'openapi.d.ts');
    generate(fresh);
    const want = readFileSync(fresh, 'utf8');
    let have = null;
    try {
      have = readFileSync(target, 'utf8');
    } catch {
      // missing: reported below
    }
    if (have !== want) {
      const rel = relative(join(web, '..'), target);
      let where = 'it is missing';
      if (have !== null) {
        const a = have.split('\n');
        const b = want.split('\n');
        let i = 0;
        while (i < a.length && i < b.length && a[i] === b[i]) i++;
        const line = (l, k) => (k >= l.length || (k === l.length - 1 && l[k] === '') ? '(end of file)' : l[k]);
        where = `first difference at line ${i + 1}:\n  committed: ${line(a, i)}\n  generated: ${line(b, i)}`;
      }
      console.error(`${rel} is stale against openapi.yaml (${where})\nrun \`npm run build\` in web/ (its first step is \`npm run gen:api\`) and commit web/src/generated and web/dist`);
      process.exit(1);
    }
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
} else {
  console.error('usage: node scripts/api-types.mjs --write | --check');
  process.exit(2);
}
