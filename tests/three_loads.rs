//! A web client's view: an example of every kind, run by the real binary in each compression
//! form, and every glb it writes (`mesh.glb` and each level of detail) loaded by three.js's
//! `GLTFLoader` with `MeshoptDecoder` in Node (npm `three`, pinned in
//! tests/gltf-validator/package-lock.json). The vertex and triangle counts three.js builds must
//! be the ones the job's result states for that level, the Khronos validator must find no error
//! in any file, and every level must keep within its error bound.
//!
//! Needs `npm ci --prefix tests/gltf-validator` first (as tests/glb_valid.rs does).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::glb_topology::degenerate_nodes;
use common::gltf_validator::validate_glb;
use serde_json::Value;

const FORMS: [&str; 3] = ["none", "quantize", "meshopt"];

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Run `api/<kind>/<example>.json` with `compression: form` into `out`; the job's result.
fn run(kind: &str, example: &str, form: &str, out: &Path) -> Value {
    let mut body: Value =
        serde_json::from_slice(&std::fs::read(repo().join("api").join(kind).join(format!("{example}.json"))).unwrap())
            .unwrap();
    body["compression"] = form.into();
    body["lods"] = serde_json::json!([0.002, 0.008, 0.032]);
    let request = out.with_extension("json");
    std::fs::write(&request, body.to_string()).unwrap();
    let status = Command::new(env!("CARGO_BIN_EXE_landform"))
        .args(["run", request.to_str().unwrap(), "--kind", kind, "--out", out.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success(), "{kind}/{example} in form {form}");
    let job: Value = serde_json::from_slice(&std::fs::read(out.join("job.json")).unwrap()).unwrap();
    job["result"].clone()
}

/// What three.js built from each file: one JSON object per file, in order.
fn load_in_three(files: &[PathBuf]) -> Vec<Value> {
    let dir = repo().join("tests").join("gltf-validator");
    assert!(
        dir.join("node_modules").join("three").is_dir(),
        "three.js is not installed: run `npm ci --prefix tests/gltf-validator` (needs node and npm)"
    );
    let output = Command::new("node")
        .arg(dir.join("load_three.mjs"))
        .args(files)
        .current_dir(&dir)
        .output()
        .unwrap_or_else(|e| panic!("cannot run `node` ({e}); install Node.js 18 or later"));
    assert!(output.status.success(), "three.js failed:\n{}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

fn check_example(kind: &str, example: &str) {
    let dir = tempfile::tempdir().unwrap();
    for form in FORMS {
        let out = dir.path().join(form);
        let result = run(kind, example, form, &out);
        let glb = &result["glb"];
        assert_eq!(glb["form"], form);
        let levels = glb["levels"].as_array().unwrap();
        assert_eq!(levels.len(), 4, "mesh.glb and the three levels asked for");
        let files: Vec<PathBuf> = levels.iter().map(|l| out.join(l["file"].as_str().unwrap())).collect();
        let loaded = load_in_three(&files);
        for ((level, file), three) in levels.iter().zip(&files).zip(&loaded) {
            let what = format!("{kind}/{example} {form} {}", level["file"]);
            let meshes = three["meshes"].as_array().unwrap();
            let sum = |key: &str| meshes.iter().map(|m| m[key].as_u64().unwrap()).sum::<u64>();
            assert_eq!(sum("vertices"), level["vertices"].as_u64().unwrap(), "{what}: vertices");
            assert_eq!(sum("triangles"), level["triangles"].as_u64().unwrap(), "{what}: triangles");
            let (bound, deviation) =
                (level["error_bound_m"].as_f64().unwrap(), level["max_deviation_m"].as_f64().unwrap());
            assert!(deviation <= bound, "{what}: deviation {deviation} m over the bound {bound} m");
            let bytes = std::fs::read(file).unwrap();
            let report = validate_glb(&bytes);
            assert_eq!(report.errors, 0, "{what}: {}", report.summary());
            if form == "none" {
                // Clean meshes at every level: no zero-area triangle, no shared position.
                for (node, zero_area, shared) in degenerate_nodes(&bytes) {
                    assert_eq!(
                        (zero_area, shared),
                        (0, 0),
                        "{what}, node {node}: zero-area triangles, shared positions"
                    );
                }
            }
        }
        // Coarser levels have no more triangles (a simple shape may reach its fewest early: the
        // ramp's first level is already its planes and locked border), and the first has fewer
        // than the full mesh.
        for pair in levels.windows(2) {
            assert!(
                pair[1]["triangles"].as_u64() <= pair[0]["triangles"].as_u64(),
                "{kind}/{example} {form}: {pair:?}"
            );
        }
        assert!(levels[1]["triangles"].as_u64() < levels[0]["triangles"].as_u64());
    }
}

#[test]
fn bulldoze_glbs_load_in_three_js() {
    check_example("bulldoze", "ramp-7-percent");
}

#[test]
fn deform_terrain_glbs_load_in_three_js() {
    check_example("deform-terrain", "merge-edges");
}

#[test]
fn carve_coast_glbs_load_in_three_js() {
    check_example("carve-coast", "small-island-one-pass");
}

#[test]
fn grow_cave_glbs_load_in_three_js() {
    check_example("grow-cave", "stalagmites-dry");
}

#[test]
fn weather_column_glbs_load_in_three_js() {
    check_example("weather-column", "cube-to-sphere");
}
