// Lists of plan points in a request (a road's path, a mask's polygon, a pass's vertices): arrays
// whose items are objects with numeric `x` and `z`, in metres of the terrain. The preview adds
// to one of them where the user clicks the terrain.

import { Path, pathString } from './schema';

export interface PointList {
  path: Path;
  name: string;
  count: number;
}

export function pointLists(v: unknown, path: Path = [], out: PointList[] = []): PointList[] {
  if (Array.isArray(v)) {
    const points = v.length > 0 && v.every((p) => p && typeof p === 'object' && typeof p.x === 'number' && typeof p.z === 'number');
    if (points) out.push({ path, name: pathString(path), count: v.length });
    else v.forEach((x, i) => pointLists(x, [...path, i], out));
  } else if (v && typeof v === 'object') {
    for (const [k, x] of Object.entries(v)) pointLists(x, [...path, k], out);
  }
  return out;
}

/** `body` with a point at (x, z) (to a tenth of a metre) added at the end of the list at `path`. */
export function withPoint(body: unknown, path: Path, x: number, z: number): unknown {
  const copy = structuredClone(body) as Record<string, unknown>;
  let list: unknown = copy;
  for (const p of path) list = (list as Record<string | number, unknown>)[p];
  if (!Array.isArray(list)) return body;
  list.push({ x: Math.round(x * 10) / 10, z: Math.round(z * 10) / 10 });
  return copy;
}
