// Loads glb files with three.js's GLTFLoader and MeshoptDecoder, as a web client does, and
// prints for each file what three.js built: per mesh, its name, vertex and triangle counts and
// the bounding box in metres (the node's transform applied, so quantised positions come back
// in metres), and the Khronos validator's error count and first errors for the file (one node
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
    });
  });
  const report = await validator.validateBytes(new Uint8Array(bytes), { uri: basename(path), format: 'glb', maxIssues: 0 });
  const errors = report.issues.messages.filter((m) => m.severity === 0).slice(0, 5).map((m) => `${m.code} at ${m.pointer}: ${m.message}`);
  console.log(JSON.stringify({ path, meshes, validator_errors: report.issues.numErrors, first_errors: errors }));
}
