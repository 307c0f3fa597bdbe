//! `mesh.glb` carries its levels of detail as `MSFT_lod`, and a web client picks them by
//! distance: three.js's GLTFLoader with a 60-line plugin (`tests/gltf-validator/msft_lod.mjs`,
//! which builds a `THREE.LOD` per node from the extension's ids and screen-coverage hints) shows
//! level 0 near, each coarser level farther away and the coarsest past the last switch, for a
//! cave of many pieces and a carved island, in every compression form. Each level holds the
//! triangles the result states for it.
//!
//! Needs `npm ci --prefix tests/gltf-validator` first.

mod common;

use common::cli::{example_body, node_script, run_job};

fn picks_levels_by_distance(kind: &str, example: &str, form: &str) {
    let dir = tempfile::tempdir().unwrap();
    let mut body = example_body(kind, example);
    body.as_object_mut().unwrap().remove("lods");
    body["compression"] = form.into();
    let out = dir.path().join("job");
    let job = run_job(kind, &body, &out).expect("the job runs");
    let levels = job["result"]["glb"]["levels"].as_array().unwrap().clone();
    assert_eq!(levels.len(), 4, "three levels by default");
    let loaded = node_script("msft_lod.mjs", &[out.join("mesh.glb")]);
    let nodes = loaded[0]["nodes"].as_array().unwrap();
    assert!(!nodes.is_empty(), "{kind}/{example} {form}: no node carries MSFT_lod");
    let mut per_level = [0u64; 4];
    for node in nodes {
        let picks: Vec<u64> = node["picks"].as_array().unwrap().iter().map(|p| p.as_u64().unwrap()).collect();
        let expected: Vec<u64> = (0..picks.len() as u64).collect();
        assert_eq!(picks, expected, "{kind}/{example} {form} node {}: {node}", node["name"]);
        let distances: Vec<f64> = node["distances"].as_array().unwrap().iter().map(|d| d.as_f64().unwrap()).collect();
        assert!(distances.windows(2).all(|w| w[0] < w[1]), "{node}");
        let triangles: Vec<u64> = node["triangles"].as_array().unwrap().iter().map(|t| t.as_u64().unwrap()).collect();
        assert_eq!(triangles.len(), 4, "every node here keeps a mesh at every level: {node}");
        for (sum, t) in per_level.iter_mut().zip(&triangles) {
            *sum += t;
        }
    }
    let stated: Vec<u64> = levels.iter().map(|l| l["triangles"].as_u64().unwrap()).collect();
    assert_eq!(per_level.to_vec(), stated, "{kind}/{example} {form}");
}

#[test]
fn three_js_picks_a_caves_levels_by_distance_in_every_form() {
    for form in ["none", "quantize", "meshopt"] {
        picks_levels_by_distance("grow-cave", "columns", form);
    }
}

#[test]
fn three_js_picks_a_carved_islands_levels_by_distance() {
    picks_levels_by_distance("carve-coast", "small-island-one-pass", "quantize");
}
