//! Every example in `api/`, run by the real binary with three levels of detail and 32-bit
//! positions (`compression: none`, so positions are compared as written): no mesh of any level
//! has a zero-area triangle or two vertices at one position, which game engines' physics and
//! lightmappers reject, and every level keeps within its error bound.

mod common;

use std::path::{Path, PathBuf};

use common::cli::{repo, run_job};
use common::glb_topology::degenerate_nodes;
use serde_json::{json, Value};

fn examples() -> Vec<PathBuf> {
    let mut out = Vec::new();
    for kind in std::fs::read_dir(repo().join("api")).unwrap() {
        let kind = kind.unwrap().path();
        if !kind.is_dir() {
            continue;
        }
        for example in std::fs::read_dir(&kind).unwrap() {
            let path = example.unwrap().path();
            if path.extension().is_some_and(|e| e == "json") {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// Problems found in one example's meshes, one line each.
fn check(example: &Path, dir: &Path) -> Vec<String> {
    let kind = example.parent().unwrap().file_name().unwrap().to_str().unwrap();
    let name = format!("{kind}/{}", example.file_stem().unwrap().to_str().unwrap());
    let mut body: Value = serde_json::from_slice(&std::fs::read(example).unwrap()).unwrap();
    body["compression"] = "none".into();
    body["lods"] = json!([0.002, 0.008, 0.032]);
    let out = dir.join(name.replace('/', "_"));
    let Some(job) = run_job(kind, &body, &out) else { return vec![format!("{name}: the job failed")] };
    let levels = job["result"]["glb"]["levels"].as_array().cloned().unwrap_or_default();
    let mut problems = Vec::new();
    if levels.len() != 4 {
        problems.push(format!("{name}: {} levels in the result", levels.len()));
    }
    for level in &levels {
        let file = level["file"].as_str().unwrap();
        let (bound, deviation) = (level["error_bound_m"].as_f64().unwrap(), level["max_deviation_m"].as_f64().unwrap());
        if deviation > bound {
            problems.push(format!("{name} {file}: deviation {deviation} m over the bound {bound} m"));
        }
        for (node, zero_area, shared) in degenerate_nodes(&std::fs::read(out.join(file)).unwrap()) {
            if (zero_area, shared) != (0, 0) {
                problems.push(format!(
                    "{name} {file} node {node}: {zero_area} zero-area triangles, {shared} shared positions"
                ));
            }
        }
    }
    let _ = std::fs::remove_dir_all(&out);
    problems
}

#[test]
fn every_examples_meshes_are_clean_at_every_level() {
    let examples = examples();
    assert!(examples.len() >= 25, "{} examples", examples.len());
    let dir = tempfile::tempdir().unwrap();
    // Two at a time: each job uses every core for part of its run.
    let problems: Vec<String> = examples
        .chunks(2)
        .flat_map(|pair| {
            std::thread::scope(|s| {
                let handles: Vec<_> = pair.iter().map(|e| s.spawn(|| check(e, dir.path()))).collect();
                handles.into_iter().flat_map(|h| h.join().unwrap()).collect::<Vec<_>>()
            })
        })
        .collect();
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
