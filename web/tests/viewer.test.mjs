// The viewer (issue 32, "a viewer people know", defect 8): ground grid and scale, axis gizmo,
// shadows, wire over shaded, full screen, the triangle count and the height legend checked
// against the glb read here, and water for every result with a water level.
import assert from 'node:assert/strict';
import { test } from 'node:test';
import { glbPrimitives } from './glb.mjs';
import { canvasStats, frameDifference, out, session, shot, waitForResult } from './harness.mjs';
import { artifactBytes, finishedJob, presetBody, settle, smallZiggurat } from './jobs.mjs';

const s = session();


/**
 * Pixels of the viewer's canvas (or of its bottom-right `corner` CSS px square) counted by
 * class: the gizmo's axis hues, the bare background (#1d2733, a wireframe's holes), and a pale
 * glare (light, not warmer than blue: the sun on water, not a peak's white or the sand).
 */
function pixelCounts(page, corner = 0) {
  return page.evaluate((corner) => {
    const src = document.querySelector('#viewer canvas');
    const side = corner ? Math.round(corner * (src.width / src.clientWidth)) : 0;
    const c = document.createElement('canvas');
    [c.width, c.height] = [src.width, src.height];
    const ctx = c.getContext('2d');
    ctx.drawImage(src, 0, 0);
    const d = side ? ctx.getImageData(src.width - side, src.height - side, side, side).data : ctx.getImageData(0, 0, c.width, c.height).data;
    const n = { all: d.length / 4, red: 0, green: 0, blue: 0, background: 0, glare: 0 };
    for (let k = 0; k < d.length; k += 4) {
      const [r, g, b] = [d[k], d[k + 1], d[k + 2]];
      if (r > 180 && g < 120 && b < 140) n.red++;
      if (g > 180 && r < 190 && b < 120) n.green++;
      if (b > 180 && r < 120 && g < 170) n.blue++;
      if (Math.abs(r - 0x1d) < 4 && Math.abs(g - 0x27) < 4 && Math.abs(b - 0x33) < 4) n.background++;
      if ((r + g + b) / 3 > 170 && b >= r) n.glare++;
    }
    return n;
  }, corner);
}

/** The gizmo's square (128 CSS px) by hue: red, green, blue. */
const gizmoColours = (page) => pixelCounts(page, 128);

/** The share of the canvas showing the bare background: the wireframe's holes. */
const backgroundShare = async (page) => {
  const n = await pixelCounts(page);
  return n.background / n.all;
};

/**
 * Turn the view to look straight down by clicking the gizmo's Y (above its centre), set a high
 * sun, and measure the share of the view that is a pale glare (light, not warmer than blue: the
 * sun's reflection on water, not the white of a peak or the sand).
 */
async function glareFromAbove(page) {
  const canvas = page.locator('#viewer canvas');
  const box = await canvas.boundingBox();
  await page.mouse.click(box.x + box.width - 64, box.y + box.height - 64 - 28);
  await page.waitForFunction(() => Number(document.querySelector('#viewer canvas').dataset.polar) < 0.05, null, { timeout: 5000 });
  await setSlider(page, 'sun-elevation', 70);
  const n = await pixelCounts(page);
  return n.glare / n.all;
}

async function setSlider(page, id, value) {
  await page.locator(`#${id}`).fill(String(value));
  await settle(page);
}

test('the viewer on a terrain: triangle count and legend from the glb, grid and scale, gizmo, shadows, wire over shaded, full screen', async () => {
  const job = await smallZiggurat(s.url);
  const prims = glbPrimitives(await artifactBytes(s.url, job, 'mesh.glb'));
  const page = await s.page();
  await page.goto(`/#/jobs/${job.id}`);
  await waitForResult(page);
  const canvas = page.locator('#viewer canvas');

  // Triangles and vertices of what is shown, as the glb counts them.
  const triangles = prims.reduce((s, p) => s + p.triangles, 0);
  const vertices = prims.reduce((s, p) => s + p.vertices, 0);
  assert.equal(Number(await canvas.getAttribute('data-triangles')), triangles);
  assert.equal(Number(await canvas.getAttribute('data-vertices')), vertices);
  assert.equal(await page.locator('#viewer-stats').textContent(), `${triangles.toLocaleString('en')} triangles · ${vertices.toLocaleString('en')} vertices`);

  // The legend: the model's lowest and highest points, read from the POSITION bounds here.
  const lo = Math.min(...prims.map((p) => p.min[1]));
  const hi = Math.max(...prims.map((p) => p.max[1]));
  const legend = page.locator('#viewer-legend');
  assert.ok(await legend.isVisible());
  assert.ok(Math.abs(Number(await legend.getAttribute('data-min')) - lo) < 0.01, `legend min ${await legend.getAttribute('data-min')} vs glb ${lo}`);
  assert.ok(Math.abs(Number(await legend.getAttribute('data-max')) - hi) < 0.01, `legend max ${await legend.getAttribute('data-max')} vs glb ${hi}`);
  assert.equal(await page.locator('#legend-max').textContent(), `${hi.toFixed(1)} m`);
  assert.equal(await page.locator('#legend-min').textContent(), `${lo.toFixed(1)} m`);
  // The colour ramp the vertex colours use (a gradient from the hypsometric stops).
  assert.match(await page.locator('.legend-bar').evaluate((b) => getComputedStyle(b).backgroundImage), /linear-gradient/);

  // The grid's scale: a round spacing, about a tenth of the terrain's side.
  const spacing = Number(await page.locator('#grid-scale').getAttribute('data-spacing'));
  const side = Math.max(...prims.map((p) => p.max[0] - p.min[0]));
  assert.ok(spacing >= side / 25 && spacing <= side / 4, `grid ${spacing} m over ${side} m`);
  assert.match(String(spacing / 10 ** Math.floor(Math.log10(spacing))), /^(1|2|5)$/);
  assert.equal(await page.locator('#grid-scale').textContent(), `grid ${spacing} m squares`);

  // The axis gizmo in the bottom-right corner: X red, Y green, Z blue drawn.
  const gizmo = await gizmoColours(page);
  assert.ok(gizmo.red > 30 && gizmo.green > 30 && gizmo.blue > 30, JSON.stringify(gizmo));

  // Shadows: on, with a 2048 map; the ziggurat's shadow on the plain changes the picture.
  assert.equal(await canvas.getAttribute('data-shadows'), '2048');
  await setSlider(page, 'sun-elevation', 30);
  const shadowed = await canvasStats(page);
  await page.locator('#viewer').screenshot({ path: `${out}/viewer-shadows-on.png` });
  await page.locator('#shadows').uncheck();
  await settle(page);
  assert.equal(await canvas.getAttribute('data-shadows'), 'off');
  const unshadowed = await canvasStats(page);
  assert.ok(frameDifference(shadowed, unshadowed) > 0.3, `shadows changed the frame by ${frameDifference(shadowed, unshadowed)}`);
  await page.locator('#shadows').check();
  await setSlider(page, 'sun-elevation', 45);

  // The grid drawn around the terrain, off with its switch.
  const withGrid = await canvasStats(page);
  await page.locator('#grid').uncheck();
  await settle(page);
  const noGrid = await canvasStats(page);
  assert.ok(frameDifference(withGrid, noGrid) > 0.05, `the grid changed the frame by ${frameDifference(withGrid, noGrid)}`);
  await page.locator('#grid').check();
  await settle(page);
  await page.locator('#viewer').screenshot({ path: `${out}/viewer-grid-gizmo-legend-shadows.png` });

  // Wire over shaded: the shaded surface with its edges on top; neither plain shading nor the
  // bare wireframe.
  const shaded = await canvasStats(page);
  await page.selectOption('#shading', 'wire-over-shaded');
  await settle(page);
  const over = await canvasStats(page);
  const overHoles = await backgroundShare(page);
  await page.locator('#viewer').screenshot({ path: `${out}/viewer-wire-over-shaded.png` });
  await page.selectOption('#shading', 'wireframe');
  await settle(page);
  const wire = await canvasStats(page);
  const wireHoles = await backgroundShare(page);
  assert.ok(frameDifference(shaded, over) > 0.5, `wire over shaded vs shaded: ${frameDifference(shaded, over)}`);
  assert.ok(frameDifference(over, wire) > 2, `wire over shaded vs wireframe: ${frameDifference(over, wire)}`);
  assert.ok(wireHoles > overHoles + 0.03, `the shaded surface under the wires: background ${overHoles} there, ${wireHoles} in the bare wireframe`);
  assert.equal(Number(await canvas.getAttribute('data-triangles')), triangles, 'the wires are not counted as triangles');
  await page.selectOption('#shading', 'shaded');

  // Full screen: the viewer fills the window, its canvas resized; and back.
  const before = await canvas.boundingBox();
  await page.click('#fullscreen');
  await page.waitForFunction(() => document.fullscreenElement?.id === 'viewer');
  await page.waitForFunction(() => Math.abs(document.querySelector('#viewer canvas').clientHeight - window.innerHeight) <= 2);
  const full = await canvas.boundingBox();
  assert.ok(full.height > before.height + 100, `full screen ${full.height} px high, ${before.height} before`);
  assert.equal(await page.locator('#fullscreen').textContent(), 'Exit full screen');
  await shot(page, 'viewer-full-screen', { fullPage: false });
  await page.click('#fullscreen');
  await page.waitForFunction(() => document.fullscreenElement === null);
  await page.waitForFunction((h) => Math.abs(document.querySelector('#viewer canvas').clientHeight - h) <= 2, before.height);
  assert.deepEqual(page.errors, []);
});

test('water for every result with a water level: the star island plane, the coast\'s own sea hidden with its switch, matte at high sun', async () => {
  // The star island at half the samples over the same 256 m (the mask is in metres).
  const body = await presetBody(s.url, 'deform-terrain', 'star-island');
  Object.assign(body.terrain.fractal, { size: 129, cell_size: 2.0 });
  body.max_iterations = 300;
  const island = await finishedJob(s.url, 'deform-terrain', body);
  const level = island.result.constraints.find((c) => typeof c.water_level_m === 'number').water_level_m;
  assert.equal(island.request.constraints[0].shape_mask.water_level, undefined, 'the level is the server\'s choice');
  const page = await s.page();
  await page.goto(`/#/jobs/${island.id}`);
  await waitForResult(page);
  const sea = page.locator('#sea');
  await sea.waitFor();
  assert.ok(await sea.isChecked());
  assert.match(await page.locator('label[for="sea"]').textContent(), new RegExp(`${level.toFixed(1)} m`));
  assert.equal(await page.locator('#legend-water').textContent(), `water ${level.toFixed(1)} m`);
  const wet = await canvasStats(page);
  await shot(page, 'star-island-water');
  await page.locator('#viewer').screenshot({ path: `${out}/star-island-water-view.png` });
  await sea.uncheck();
  await settle(page);
  const dry = await canvasStats(page);
  assert.ok(frameDifference(wet, dry) > 1, `the water plane changed the frame by ${frameDifference(wet, dry)}`);
  await sea.check();
  const islandGlare = await glareFromAbove(page);
  await page.locator('#viewer').screenshot({ path: `${out}/star-island-from-above-high-sun.png` });
  assert.ok(islandGlare < 0.003, `a white glare over ${(islandGlare * 100).toFixed(2)} % of the island's view`);
  assert.deepEqual(page.errors, []);

  // carve-coast: its mesh has a sea of its own (node `sea`, material `water`); the switch hides
  // it, so what is shown loses its triangles.
  const coastBody = await presetBody(s.url, 'carve-coast', 'small-island-one-pass');
  const coast = await finishedJob(s.url, 'carve-coast', coastBody);
  const prims = glbPrimitives(await artifactBytes(s.url, coast, 'mesh.glb'));
  const water = prims.filter((p) => p.material === 'water');
  assert.ok(water.length > 0, JSON.stringify(prims.map((p) => [p.node, p.material])));
  const all = prims.reduce((s, p) => s + p.triangles, 0);
  const land = all - water.reduce((s, p) => s + p.triangles, 0);
  await page.goto(`/#/jobs/${coast.id}`);
  await waitForResult(page);
  const canvas = page.locator('#viewer canvas');
  assert.equal(Number(await canvas.getAttribute('data-triangles')), all);
  // Looking straight down (the gizmo's Y) with a high sun: the sea stays a matte blue, not a
  // white glare (the mirror image of the sun the glossy plane showed).
  const glare = await glareFromAbove(page);
  await page.locator('#viewer').screenshot({ path: `${out}/carve-coast-from-above-high-sun.png` });
  const withSea = await canvasStats(page);
  await shot(page, 'carve-coast-high-sun');
  await page.locator('#sea').uncheck();
  await settle(page);
  assert.equal(Number(await canvas.getAttribute('data-triangles')), land);
  const withoutSea = await canvasStats(page);
  assert.ok(frameDifference(withSea, withoutSea) > 1, `the coast's own sea hidden: ${frameDifference(withSea, withoutSea)}`);
  await shot(page, 'carve-coast-sea-off');
  assert.ok(glare < 0.003, `a white glare over ${(glare * 100).toFixed(2)} % of the view`);
  assert.deepEqual(page.errors, []);
});

test('a cave: framed whole (F), lit through its cut-away walls, free to orbit', async () => {
  const body = await presetBody(s.url, 'grow-cave', 'columns');
  const job = await finishedJob(s.url, 'grow-cave', body);
  const page = await s.page();
  await page.goto(`/#/jobs/${job.id}`);
  await waitForResult(page);
  const canvas = page.locator('#viewer canvas');
  await canvas.focus();
  await page.keyboard.press('f');
  await settle(page);
  const stats = await canvasStats(page);
  assert.ok(stats.variance > 100, `variance ${stats.variance}`);
  // Not a dark box: the sun reaches the inside through the walls the eye sees through.
  assert.ok(stats.mean > 40, `mean luminance ${stats.mean}`);
  assert.equal(await page.locator('#grid').count(), 0, 'no ground grid in a cave');
  assert.ok(Number(await canvas.getAttribute('data-triangles')) > 1000);
  await page.locator('#viewer').screenshot({ path: `${out}/grow-cave-framed.png` });
  assert.deepEqual(page.errors, []);
});
