//! The deform-terrain job through the real server: a paper example end to end, replay, jobs
//! composing, and bad input naming the field.

mod common;

use common::server::{artifact_hashes, example, TestServer};
use serde_json::{json, Value};

/// A small road job: quick in the test profile.
fn small_road() -> Value {
    json!({
        "seed": 3,
        "terrain": {"fractal": {"size": 65, "relief": 40.0, "seed": 11}},
        "constraints": [{"road": {
            "path": [{"x": 8, "z": 10}, {"x": 30, "z": 30}, {"x": 56, "z": 50}],
            "width_m": 4.0,
            "height": {"constant": 20.0}
        }}],
        "max_iterations": 60
    })
}

#[tokio::test]
async fn a_deformation_runs_streams_and_replays_to_the_same_bytes() {
    let server = TestServer::start().await;
    let job = server.run("deform-terrain", &small_road()).await;
    let id = job["id"].as_str().unwrap();
    let names: Vec<&str> = job["artifacts"].as_array().unwrap().iter().map(|a| a["name"].as_str().unwrap()).collect();
    for want in ["mesh.glb", "heightmap.png", "preview.png", "sequence.json", "fitness.json"] {
        assert!(names.contains(&want), "{want} in {names:?}");
    }
    let result = &job["result"];
    assert!(result["iterations"].as_u64().unwrap() > 0, "{result}");
    assert!(result.get("sequence_bytes").is_some() && result.get("heightmap_png_bytes").is_some(), "{result}");

    let glb = server.artifact(id, "mesh.glb").await;
    let report = common::gltf_validator::validate_glb(&glb);
    assert_eq!(report.errors, 0, "{:?}", report.messages);
    let fitness: Value = serde_json::from_slice(&server.artifact(id, "fitness.json").await).unwrap();
    assert!(fitness.is_array() || fitness.is_object(), "{fitness}");

    let (status, replay) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({})).await;
    assert_eq!(status, 202, "{replay}");
    let replay = server.wait_done(replay["id"].as_str().unwrap()).await;
    assert_eq!(replay["status"], "succeeded", "{replay}");
    let without_fitness = |j: &Value| -> Vec<(String, String)> {
        artifact_hashes(j).into_iter().filter(|(n, _)| n != "fitness.json").collect()
    };
    assert_eq!(without_fitness(&replay), without_fitness(&job), "a replay rebuilds the same terrain bytes");

    // Jobs compose: bulldoze a pad onto the deformed terrain.
    let pad = json!({
        "terrain": {"job": id},
        "operations": [{"primitive": {"shape": {"box": {"center": {"x": 32, "z": 32}, "size_x_m": 6, "size_z_m": 6, "height_m": 2}}}}]
    });
    server.run("bulldoze", &pad).await;
}

#[tokio::test]
async fn the_paper_examples_are_valid_requests() {
    let server = TestServer::start().await;
    for name in ["star-island", "s-road", "merge-edges", "star-island-roads", "tileable"] {
        let mut body = example("deform-terrain", name);
        // Accepting is what is checked here; the unit tests and benches run them.
        body["max_iterations"] = json!(1);
        let job = server.run("deform-terrain", &body).await;
        assert_eq!(job["status"], "succeeded", "{name}");
    }
}

#[tokio::test]
async fn bad_deformation_requests_name_their_field() {
    let server = TestServer::start().await;
    let with = |patch: Value| {
        let mut body = small_road();
        for (k, v) in patch.as_object().unwrap() {
            body[k] = v.clone();
        }
        body
    };
    let one_point_road = json!([{"road": {"path": [{"x": 8, "z": 10}], "width_m": 4.0, "height": {"constant": 20.0}}}]);
    let off_grid_road = json!([{"road": {"path": [{"x": 8, "z": 10}, {"x": 500, "z": 10}], "width_m": 4.0, "height": {"constant": 20.0}}}]);
    let wide_road = json!([{"road": {"path": [{"x": 8, "z": 10}, {"x": 50, "z": 10}], "width_m": 40.0, "height": {"constant": 20.0}}}]);
    let zigzag: Vec<Value> = (0..300).map(|i| json!({"x": 8 + i % 2 * 40, "z": 10 + i / 10})).collect();
    let long_road = json!([{"road": {"path": zigzag, "width_m": 4.0, "height": {"constant": 20.0}}}]);
    let cases = [
        (with(json!({"epsilon": -1.0})), 422, "epsilon"),
        (with(json!({"p": 1.5})), 422, "p"),
        (with(json!({"amplitudes": 0})), 422, "amplitudes"),
        (with(json!({"radii": 0})), 422, "radii"),
        (with(json!({"max_radius_cells": 65})), 422, "max_radius_cells"),
        // Over the cap and larger than the grid: a bad value as well as a size, so 422.
        (with(json!({"max_radius_cells": 5000})), 422, "max_radius_cells"),
        (with(json!({"max_displacement_ratio": 100.0})), 422, "max_displacement_ratio"),
        (with(json!({"constraints": vec![json!({"preserve": {}}); 33]})), 413, "constraints"),
        (
            with(json!({"constraints": [{"tileable": {"edges": "both"}}, {"edge_match": {
            "terrain": {"fractal": {"size": 65, "seed": 2}}, "edges": ["west", "east", "west"]}}]})),
            422,
            "constraints[1].edge_match.edges",
        ),
        (with(json!({"max_iterations": 10_000_000})), 413, "max_iterations"),
        (with(json!({"max_iterations": 20_000, "batch": 256})), 413, "batch"),
        (with(json!({"constraints": one_point_road})), 422, "constraints[0].road.path"),
        (with(json!({"constraints": off_grid_road})), 422, "constraints[0].road.path[1].x"),
        (with(json!({"constraints": []})), 422, "constraints"),
        (with(json!({"constraints": wide_road})), 422, "constraints[0].road.width_m"),
        (with(json!({"constraints": long_road})), 413, "constraints[0].road.path"),
    ];
    for (body, status, field) in cases {
        let (got, problem) = server.post("/v1/jobs/deform-terrain", &body).await;
        assert_eq!(got, status, "{field}: {problem}");
        let fields: Vec<&str> =
            problem["errors"].as_array().into_iter().flatten().filter_map(|e| e["field"].as_str()).collect();
        assert!(fields.contains(&field), "wanted {field:?}: {problem}");
    }
}
