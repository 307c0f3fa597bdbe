// Loads glb files with three.js's GLTFLoader and MeshoptDecoder, as a web client does, and
// prints for each file what three.js built: per mesh, its name, vertex and triangle counts and
// the bounding box in metres (the node's transform applied, so quantised positions come back
// in metres), its degeneracies as decoded (zero-area triangles, vertices at the position of
// another, and edges not shared by exactly two triangles once vertices at one position are
// welded), and the Khronos validator's error count and first errors for the file (one node
// process for both, so a sweep over many files stays quick). Used by the asset tests.
//
//   node load_three.mjs file.glb [...]   → one JSON line per file
import { readFile } from 'node:fs/promises';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/examples/jsm/libs/meshopt_decoder.module.js';
import { Box3 } from 'three';
import validator from 'gltf-validator';
import { basename } from 'node:path';

const loader = new GLTFLoader();

// Degeneracies of a geometry as the file's decoder hands it over: positions as stored (16- or
// 14-bit integers in the quantised forms, so a collapse onto the grid shows as it would in an
// engine), compared exactly. Cross products are exact in doubles for either: integers below
// 2^16, or f32 differences whose products need at most 48 bits.
function degeneracies(geometry) {
  const position = geometry.attributes.position;
  const n = position.count;
  const p = (i) => [position.getX(i), position.getY(i), position.getZ(i)];
  const index = geometry.index ? Array.from(geometry.index.array) : [...Array(n).keys()];
  const welded = new Map();
  const id = new Int32Array(n);
  let duplicates = 0;
  for (let i = 0; i < n; i++) {
    const key = p(i).join(',');
    if (welded.has(key)) duplicates++;
    else welded.set(key, welded.size);
    id[i] = welded.get(key);
  }
  let zeroArea = 0;
  const edges = new Map();
  for (let t = 0; t + 2 < index.length; t += 3) {
    const [a, b, c] = [p(index[t]), p(index[t + 1]), p(index[t + 2])];
    const u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    const v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    const cross = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    if (cross[0] === 0 && cross[1] === 0 && cross[2] === 0) zeroArea++;
    const w = [id[index[t]], id[index[t + 1]], id[index[t + 2]]];
    for (const [x, y] of [[w[0], w[1]], [w[1], w[2]], [w[2], w[0]]]) {
      const key = x < y ? `${x},${y}` : `${y},${x}`;
      edges.set(key, (edges.get(key) || 0) + 1);
    }
  }
  let unpaired = 0;
  for (const count of edges.values()) if (count !== 2) unpaired++;
  return { zero_area: zeroArea, duplicates, welded_unpaired_edges: unpaired };
}
loader.setMeshoptDecoder(MeshoptDecoder);

for (const path of process.argv.slice(2)) {
  const bytes = await readFile(path);
  const data = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  const gltf = await loader.parseAsync(data, '');
  gltf.scene.updateMatrixWorld(true);
  const meshes = [];
  gltf.scene.traverse((object) => {
    if (!object.isMesh) return;
    const geometry = object.geometry;
    const box = new Box3().setFromObject(object);
    meshes.push({
      name: object.name,
      vertices: geometry.attributes.position.count,
      triangles: geometry.index ? geometry.index.count / 3 : geometry.attributes.position.count / 3,
      min: box.min.toArray(),
      max: box.max.toArray(),
      ...degeneracies(geometry),
    });
  });
  const report = await validator.validateBytes(new Uint8Array(bytes), { uri: basename(path), format: 'glb', maxIssues: 0 });
  const errors = report.issues.messages.filter((m) => m.severity === 0).slice(0, 5).map((m) => `${m.code} at ${m.pointer}: ${m.message}`);
  console.log(JSON.stringify({ path, meshes, validator_errors: report.issues.numErrors, first_errors: errors }));
}
