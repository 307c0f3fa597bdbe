// Runs the Khronos glTF validator over one .glb file and prints its report as JSON.
//
// Usage: node validate.mjs PATH.glb
//
// Always exits 0 once a report is printed: the Rust side (tests/common/gltf_validator.rs)
// reads the counts and decides. A non-zero exit means the validator itself could not run.

import { readFile } from "node:fs/promises";
import { basename } from "node:path";
import validator from "gltf-validator";

const path = process.argv[2];
if (!path) {
  console.error("usage: node validate.mjs PATH.glb");
  process.exit(2);
}

const bytes = new Uint8Array(await readFile(path));
const report = await validator.validateBytes(bytes, {
  uri: basename(path),
  format: "glb",
  // Every issue, so a failing test can show all of them.
  maxIssues: 0,
});
process.stdout.write(JSON.stringify(report, null, 2));
process.stdout.write("\n");
