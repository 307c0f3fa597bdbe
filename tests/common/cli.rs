//! The real binary's offline runs (`landform run`) and three.js loading its files, for the
//! asset tests.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// An example's body, `api/<kind>/<name>.json`.
pub fn example_body(kind: &str, name: &str) -> Value {
    serde_json::from_slice(&std::fs::read(repo().join("api").join(kind).join(format!("{name}.json"))).unwrap()).unwrap()
}

/// Run `body` as a `kind` job with `landform run` into the folder `out`: the finished job, or
/// `None` when the run failed.
pub fn run_job(kind: &str, body: &Value, out: &Path) -> Option<Value> {
    let request = out.with_extension("json");
    std::fs::write(&request, body.to_string()).unwrap();
    let status = Command::new(env!("CARGO_BIN_EXE_landform"))
        .args(["run", request.to_str().unwrap(), "--kind", kind, "--out", out.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    status.success().then(|| serde_json::from_slice(&std::fs::read(out.join("job.json")).unwrap()).unwrap())
}

/// What three.js's `GLTFLoader` (with `MeshoptDecoder`) builds from each file: one JSON object
/// per file, in order (tests/gltf-validator/load_three.mjs).
pub fn load_in_three(files: &[PathBuf]) -> Vec<Value> {
    node_script("load_three.mjs", files)
}

/// What `tests/gltf-validator/<script>` prints for each file: one JSON object per file, in order.
pub fn node_script(script: &str, files: &[PathBuf]) -> Vec<Value> {
    let dir = repo().join("tests").join("gltf-validator");
    assert!(
        dir.join("node_modules").join("three").is_dir(),
        "three.js is not installed: run `npm ci --prefix tests/gltf-validator` (needs node and npm)"
    );
    let output = Command::new("node")
        .arg(dir.join(script))
        .args(files)
        .current_dir(&dir)
        .output()
        .unwrap_or_else(|e| panic!("cannot run `node` ({e}); install Node.js 18 or later"));
    assert!(output.status.success(), "three.js failed:\n{}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

/// Vertices and triangles of every mesh three.js built from one file, summed.
pub fn three_counts(loaded: &Value) -> (u64, u64) {
    let meshes = loaded["meshes"].as_array().unwrap();
    let sum = |key: &str| meshes.iter().map(|m| m[key].as_u64().unwrap()).sum::<u64>();
    (sum("vertices"), sum("triangles"))
}
