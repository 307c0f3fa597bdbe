// Loads glb files with three.js's GLTFLoader and MeshoptDecoder, as a web client does, and
// prints for each file what three.js built: per mesh, its name, vertex and triangle counts and
// the bounding box in metres (the node's transform applied, so quantised positions come back
// in metres), its degeneracies as decoded (zero-area triangles, vertices at the position of
// another, and edges not shared by exactly two triangles once vertices at one position are
// welded; edges of three triangles or more by the file's indices), and the Khronos validator's error count and first errors for the file (one node
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
  const xyz = new Float64Array(3 * n);
  for (let i = 0; i < n; i++) {
    xyz[3 * i] = position.getX(i);
    xyz[3 * i + 1] = position.getY(i);
    xyz[3 * i + 2] = position.getZ(i);
  }
  const index = geometry.index ? geometry.index.array : Uint32Array.from({ length: n }, (_, i) => i);
  // Vertices at one position, found by sorting (numeric keys: string maps took minutes on the
  // carved coasts' millions of vertices).
  const order = Uint32Array.from({ length: n }, (_, i) => i);
  order.sort((a, b) => xyz[3 * a] - xyz[3 * b] || xyz[3 * a + 1] - xyz[3 * b + 1] || xyz[3 * a + 2] - xyz[3 * b + 2]);
  const id = new Uint32Array(n);
  let duplicates = 0;
  let next = 0;
  for (let k = 0; k < n; k++) {
    const i = order[k];
    if (k > 0) {
      const j = order[k - 1];
      if (xyz[3 * i] === xyz[3 * j] && xyz[3 * i + 1] === xyz[3 * j + 1] && xyz[3 * i + 2] === xyz[3 * j + 2]) {
        duplicates++;
        id[i] = id[j];
        continue;
      }
    }
    id[i] = next++;
  }
  let zeroArea = 0;
  const triangles = Math.floor(index.length / 3);
  const edges = new Float64Array(3 * triangles);
  // The same edges by the file's own vertex indices (the mesh's topology, unwelded).
  const indexEdges = new Float64Array(3 * triangles);
  for (let t = 0; t < triangles; t++) {
    const [a, b, c] = [index[3 * t], index[3 * t + 1], index[3 * t + 2]];
    const u = [xyz[3 * b] - xyz[3 * a], xyz[3 * b + 1] - xyz[3 * a + 1], xyz[3 * b + 2] - xyz[3 * a + 2]];
    const v = [xyz[3 * c] - xyz[3 * a], xyz[3 * c + 1] - xyz[3 * a + 1], xyz[3 * c + 2] - xyz[3 * a + 2]];
    const cross = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    if (cross[0] === 0 && cross[1] === 0 && cross[2] === 0) zeroArea++;
    const w = [id[a], id[b], id[c]];
    const raw = [a, b, c];
    for (let e = 0; e < 3; e++) {
      const [x, y] = [w[e], w[(e + 1) % 3]];
      // Welded ids stay below 2^26, so the pair is exact in a double.
      edges[3 * t + e] = Math.min(x, y) * 67108864 + Math.max(x, y);
      const [p, q] = [raw[e], raw[(e + 1) % 3]];
      indexEdges[3 * t + e] = Math.min(p, q) * 67108864 + Math.max(p, q);
    }
  }
  indexEdges.sort();
  let crowded = 0;
  for (let k = 0; k < indexEdges.length; ) {
    let run = 1;
    while (k + run < indexEdges.length && indexEdges[k + run] === indexEdges[k]) run++;
    if (run > 2) crowded++;
    k += run;
  }
  edges.sort();
  let unpaired = 0;
  for (let k = 0; k < edges.length; ) {
    let run = 1;
    while (k + run < edges.length && edges[k + run] === edges[k]) run++;
    if (run !== 2) unpaired++;
    k += run;
  }
  return { zero_area: zeroArea, duplicates, welded_unpaired_edges: unpaired, crowded_edges: crowded };
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
