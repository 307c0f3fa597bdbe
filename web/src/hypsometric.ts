// The height colours the heightfield kinds (bulldoze, deform-terrain, erode) bake into their
// meshes' vertex colours and previews, as a CSS gradient for the viewer's legend. The stops are
// those of src/export/hypsometric.rs (LAND and WATER); a test there reads this file and fails
// when the two differ.

/** Land colours (sRGB) at fractions of the land's relief, lowest to highest. */
const LAND: [number, [number, number, number]][] = [
  [0.0, [56, 118, 64]],
  [0.12, [100, 150, 80]],
  [0.3, [170, 180, 105]],
  [0.48, [196, 166, 110]],
  [0.64, [158, 116, 78]],
  [0.8, [135, 125, 118]],
  [0.92, [190, 190, 190]],
  [1.0, [250, 250, 250]],
];

/** Water colours (sRGB) at fractions of the depth below the sea level, shore to deepest. */
const WATER: [number, [number, number, number]][] = [
  [0.0, [140, 196, 230]],
  [0.4, [60, 128, 190]],
  [1.0, [24, 62, 130]],
];

/** The kinds whose vertex colours are this tint (the others colour by material or not at all). */
export const HYPSOMETRIC_KINDS = ['bulldoze', 'deform-terrain', 'erode'];

const rgb = ([r, g, b]: [number, number, number]): string => `rgb(${r} ${g} ${b})`;

/**
 * A bottom-to-top CSS gradient over heights `min..max` metres, as the server tints them with
 * the sea at `sea` (Tint::with_sea_level): water below the sea when any height lies below it,
 * land from the sea (or the lowest height) to the highest.
 */
export function tintGradient(min: number, max: number, sea: number): string {
  const span = max - min || 1;
  const at = (h: number): string => `${(((h - min) / span) * 100).toFixed(2)}%`;
  const stops: string[] = [];
  const landLo = min < sea ? sea : min;
  const landHi = Math.max(max, landLo);
  if (min < sea) {
    // Deepest at the bottom: walk the water ramp from its deep end up to the shore.
    for (const [t, c] of [...WATER].reverse()) stops.push(`${rgb(c)} ${at(sea - t * (sea - min))}`);
  }
  for (const [t, c] of LAND) stops.push(`${rgb(c)} ${at(landLo + t * (landHi - landLo))}`);
  return `linear-gradient(to top, ${stops.join(', ')})`;
}
