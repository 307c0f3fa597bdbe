// Makes the landing page's picture of each kind, web/src/kinds/<kind>.png: the kind's first
// preset by name is run by a real server, and its preview.png cut to the card's 8:5 and scaled
// down to 320 px wide in Chromium (no image library needed), its colours posterised just enough
// to keep the PNG under 60 KB. Run by hand when a kind or its look changes:
//   LANDFORM_BIN=target/debug/landform node web/scripts/kind-pictures.mjs [--out DIR] [kind ...]
// (scripts/playground-tests runs it for one quick kind into a temporary folder, so it keeps
// working.)
import { mkdirSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { launch, repo, startServer } from '../tests/harness.mjs';
import { finishedJob } from '../tests/jobs.mjs';

const WIDTH = 320;
const HEIGHT = 200;
const MAX_BYTES = 60000;
const args = process.argv.slice(2);
const at = args.indexOf('--out');
const dir = at >= 0 ? args.splice(at, 2)[1] : join(repo, 'web', 'src', 'kinds');
mkdirSync(dir, { recursive: true });
const server = await startServer();
const browser = await launch();
try {
  const doc = await (await fetch(`${server.url}/openapi.json`)).json();
  const all = Object.keys(doc.paths).filter((p) => /^\/v1\/jobs\/[a-z-]+$/.test(p) && doc.paths[p].post).map((p) => p.slice('/v1/jobs/'.length));
  const wanted = args.length ? args : all;
  const page = await browser.newPage();
  await page.goto(server.url);
  for (const kind of wanted) {
    const presets = (await (await fetch(`${server.url}/v1/presets?kind=${kind}`)).json()).items;
    const first = [...presets].sort((a, b) => a.name.localeCompare(b.name))[0];
    const started = Date.now();
    const job = await finishedJob(server.url, kind, first.body);
    const preview = job.artifacts.find((a) => a.name === 'preview.png');
    const bytes = Buffer.from(await (await fetch(`${server.url}${preview.href}`)).arrayBuffer());
    const png = await page.evaluate(async ({ data, width, height, max }) => {
      const img = new Image();
      img.src = `data:image/png;base64,${data}`;
      await img.decode();
      const c = document.createElement('canvas');
      [c.width, c.height] = [width, height];
      const ctx = c.getContext('2d');
      ctx.imageSmoothingQuality = 'high';
      // The middle of the preview at the card's proportions.
      const scale = Math.max(width / img.naturalWidth, height / img.naturalHeight);
      const [sw, sh] = [width / scale, height / scale];
      ctx.drawImage(img, (img.naturalWidth - sw) / 2, (img.naturalHeight - sh) / 2, sw, sh, 0, 0, width, height);
      const original = ctx.getImageData(0, 0, width, height);
      let url = '';
      for (const step of [1, 4, 6, 8, 12, 16, 24, 32]) {
        const d = new ImageData(new Uint8ClampedArray(original.data), width, height);
        for (let k = 0; k < d.data.length; k++) if (k % 4 !== 3) d.data[k] = Math.round(d.data[k] / step) * step;
        ctx.putImageData(d, 0, 0);
        url = c.toDataURL('image/png');
        if ((url.length - 22) * 0.75 <= max) break;
      }
      return url.split(',')[1];
    }, { data: bytes.toString('base64'), width: WIDTH, height: HEIGHT, max: MAX_BYTES });
    const out = Buffer.from(png, 'base64');
    if (out.length > MAX_BYTES || out.subarray(1, 4).toString() !== 'PNG') throw new Error(`${kind}: not a PNG under ${MAX_BYTES} B`);
    writeFileSync(join(dir, `${kind}.png`), out);
    console.log(`${kind}: ${first.name}, ${((Date.now() - started) / 1000).toFixed(1)} s, preview ${bytes.length} B → ${out.length} B`);
  }
} finally {
  await browser.close();
  server.stop();
}
