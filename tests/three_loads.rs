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

use common::cli::{example_body, load_in_three, run_job, three_counts};
use common::glb_topology::degenerate_nodes;
use common::gltf_validator::validate_glb;
use serde_json::Value;

const FORMS: [&str; 3] = ["none", "quantize", "meshopt"];

/// Run `api/<kind>/<example>.json` with `compression: form` and three levels into `out`; the
/// job's result.
fn run(kind: &str, example: &str, form: &str, out: &Path) -> Value {
    let mut body = example_body(kind, example);
    body["compression"] = form.into();
    body["lods"] = serde_json::json!([0.002, 0.008, 0.032]);
    let job = run_job(kind, &body, out).unwrap_or_else(|| panic!("{kind}/{example} in form {form}"));
    job["result"].clone()
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
            let (vertices, triangles) = three_counts(three);
            assert_eq!(vertices, level["vertices"].as_u64().unwrap(), "{what}: vertices");
            assert_eq!(triangles, level["triangles"].as_u64().unwrap(), "{what}: triangles");
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
