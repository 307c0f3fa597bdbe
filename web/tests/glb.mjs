// A glb read here, independently of three.js, for the tests to check the viewer against: the
// scene's meshes with their triangle and vertex counts and their bounds in world space, from
// the JSON chunk alone (accessor counts and POSITION min/max; quantised positions decoded;
// node transforms applied). Compressed buffers (meshopt) are never needed.

/** The glb's JSON chunk. */
export function glbJson(bytes) {
  const b = Buffer.from(bytes);
  if (b.readUInt32LE(0) !== 0x46546c67) throw new Error('not a glb');
  const length = b.readUInt32LE(12);
  if (b.readUInt32LE(16) !== 0x4e4f534a) throw new Error('the first chunk is not JSON');
  return JSON.parse(b.subarray(20, 20 + length).toString('utf8'));
}

/** A normalised integer component back to [-1, 1] or [0, 1], as glTF defines it. */
function dequantise(v, componentType, normalized) {
  if (!normalized) return v;
  switch (componentType) {
    case 5120: return Math.max(v / 127, -1);
    case 5121: return v / 255;
    case 5122: return Math.max(v / 32767, -1);
    case 5123: return v / 65535;
    default: return v;
  }
}

const multiply = (a, b) => {
  const out = new Array(16).fill(0);
  for (let r = 0; r < 4; r++) for (let c = 0; c < 4; c++) for (let k = 0; k < 4; k++) out[c * 4 + r] += a[k * 4 + r] * b[c * 4 + k];
  return out;
};

/** A node's local matrix (column-major), from `matrix` or translation · rotation · scale. */
function local(node) {
  if (node.matrix) return node.matrix;
  const [tx, ty, tz] = node.translation ?? [0, 0, 0];
  const [x, y, z, w] = node.rotation ?? [0, 0, 0, 1];
  const [sx, sy, sz] = node.scale ?? [1, 1, 1];
  return [
    (1 - 2 * (y * y + z * z)) * sx, 2 * (x * y + z * w) * sx, 2 * (x * z - y * w) * sx, 0,
    2 * (x * y - z * w) * sy, (1 - 2 * (x * x + z * z)) * sy, 2 * (y * z + x * w) * sy, 0,
    2 * (x * z + y * w) * sz, 2 * (y * z - x * w) * sz, (1 - 2 * (x * x + y * y)) * sz, 0,
    tx, ty, tz, 1,
  ];
}

const apply = (m, [x, y, z]) => [0, 1, 2].map((i) => m[i] * x + m[4 + i] * y + m[8 + i] * z + m[12 + i]);

/**
 * Each primitive of the default scene: its node's and material's names, triangles, vertices and
 * world-space bounds ({ min: [x, y, z], max: [x, y, z] }).
 */
export function glbPrimitives(bytes) {
  const gltf = glbJson(bytes);
  const out = [];
  const visit = (index, parent) => {
    const node = gltf.nodes[index];
    const m = multiply(parent, local(node));
    if (node.mesh !== undefined) {
      for (const p of gltf.meshes[node.mesh].primitives) {
        const pos = gltf.accessors[p.attributes.POSITION];
        const q = (v) => v.map((c) => dequantise(c, pos.componentType, pos.normalized));
        const [lo, hi] = [q(pos.min), q(pos.max)];
        const corners = [];
        for (const x of [lo[0], hi[0]]) for (const y of [lo[1], hi[1]]) for (const z of [lo[2], hi[2]]) corners.push(apply(m, [x, y, z]));
        out.push({
          node: node.name,
          material: p.material === undefined ? null : gltf.materials[p.material].name,
          triangles: Math.floor((p.indices === undefined ? pos.count : gltf.accessors[p.indices].count) / 3),
          vertices: pos.count,
          min: [0, 1, 2].map((i) => Math.min(...corners.map((c) => c[i]))),
          max: [0, 1, 2].map((i) => Math.max(...corners.map((c) => c[i]))),
        });
      }
    }
    for (const c of node.children ?? []) visit(c, m);
  };
  const identity = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
  for (const n of gltf.scenes[gltf.scene ?? 0].nodes) visit(n, identity);
  return out;
}
