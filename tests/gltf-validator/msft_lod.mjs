// Loads glb files with three.js's GLTFLoader and a plugin that reads MSFT_lod (three.js core
// does not), as a web client would: each node with the extension becomes a THREE.LOD whose
// levels are that node and the nodes its `ids` name, switched at the distances where the node's
// screen coverage falls below each `MSFT_screencoverage` hint (a 50° vertical field of view).
// For each such node it prints which level `LOD.update(camera)` shows with the camera before the
// first switch, between each pair of switches, and past the last, and each level's triangles.
//
//   node msft_lod.mjs file.glb [...]   → one JSON line per file
import { readFile } from 'node:fs/promises';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/examples/jsm/libs/meshopt_decoder.module.js';
import { Box3, LOD, PerspectiveCamera, Vector3 } from 'three';

const FOV_DEGREES = 50;

// The distance at which a node of bounding diameter `diameter` covers `coverage` of the
// screen's area (its height squared): diameter / (2 d tan(fov / 2)) = sqrt(coverage).
function switchDistance(diameter, coverage) {
  return diameter / (2 * Math.tan((FOV_DEGREES * Math.PI) / 360) * Math.sqrt(coverage));
}

class MsftLodPlugin {
  constructor(parser) {
    this.parser = parser;
    this.name = 'MSFT_lod';
    this.lods = [];
  }

  async afterRoot(result) {
    const nodes = this.parser.json.nodes || [];
    for (const [index, def] of nodes.entries()) {
      const ids = def.extensions && def.extensions.MSFT_lod && def.extensions.MSFT_lod.ids;
      if (!ids) continue;
      const coverage = (def.extras && def.extras.MSFT_screencoverage) || [];
      const base = await this.parser.getDependency('node', index);
      const levels = [base, ...(await Promise.all(ids.map((id) => this.parser.getDependency('node', id))))];
      base.updateMatrixWorld(true);
      const box = new Box3().setFromObject(base);
      const centre = box.getCenter(new Vector3());
      const diameter = box.getSize(new Vector3()).length();
      const lod = new LOD();
      lod.name = def.name || `node ${index}`;
      lod.position.copy(centre);
      const parent = base.parent;
      if (parent) parent.remove(base);
      const distances = [0];
      for (let k = 0; k < levels.length; k++) {
        const distance = k === 0 ? 0 : switchDistance(diameter, coverage[k - 1]);
        distances[k] = distance;
        levels[k].position.sub(centre);
        lod.addLevel(levels[k], distance);
      }
      (parent || result.scene).add(lod);
      this.lods.push({ lod, distances, levels });
    }
  }
}

const triangles = (object) => {
  let count = 0;
  object.traverse((o) => {
    if (o.isMesh) count += o.geometry.index ? o.geometry.index.count / 3 : o.geometry.attributes.position.count / 3;
  });
  return count;
};

for (const path of process.argv.slice(2)) {
  const bytes = await readFile(path);
  const data = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  let plugin;
  const loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);
  loader.register((parser) => (plugin = new MsftLodPlugin(parser)));
  const gltf = await loader.parseAsync(data, '');
  gltf.scene.updateMatrixWorld(true);
  const camera = new PerspectiveCamera(FOV_DEGREES, 16 / 9, 0.01, 1e7);
  const nodes = plugin.lods.map(({ lod, distances, levels }) => {
    // Before the first switch, between each pair (their geometric mean), past the last.
    const at = distances.map((d, k) =>
      k + 1 < distances.length ? (k === 0 ? 0.5 * distances[1] : Math.sqrt(d * distances[k + 1])) : 2 * d,
    );
    const picks = at.map((d) => {
      camera.position.copy(lod.getWorldPosition(new Vector3())).add(new Vector3(0, 0, d));
      camera.updateMatrixWorld(true);
      lod.update(camera);
      return lod.getCurrentLevel();
    });
    return { name: lod.name, distances, picks, triangles: levels.map(triangles) };
  });
  console.log(JSON.stringify({ path, nodes }));
}
