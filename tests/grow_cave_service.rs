//! The grow-cave job through the real server: a cave end to end (every speleothem a closed
//! node, the glTF validator, a preview, live progress), replay in full and until a pass, the
//! examples, and bad input naming the field.

mod common;

use common::glb_topology::closed_nodes;
use common::server::{artifact_hashes, example, TestServer};
use serde_json::{json, Value};

fn small_cave(rings: u32) -> Value {
    json!({
        "seed": 5,
        "chamber": {"width_m": 6, "depth_m": 5, "height_m": 3, "roof": {"relief_m": 0.4}, "floor": {"relief_m": 0.3}},
        "sites": {"scatter": {"count": 12, "min_spacing_m": 0.8}},
        "conditions": {"pluviometric_index": "random", "drip_interval": "random", "co2": "random"},
        "mineral": "random",
        "rings": rings,
        "segments": 10,
        "height_step_m": 0.05,
        "wind": {"scale": 0.3}
    })
}

#[tokio::test]
async fn a_cave_grows_streams_and_replays_to_the_same_bytes() {
    let server = TestServer::start().await;
    let job = server.submit("grow-cave", &small_cave(30)).await;
    let id = job["id"].as_str().unwrap().to_string();
    let events =
        common::sse::read_events(&server.client, &server.url(&format!("/v1/jobs/{id}/events")), None, 10_000).await;
    assert_eq!(events.last().unwrap().event, "done");
    let job = server.wait_done(&id).await;
    assert_eq!(job["status"], "succeeded", "{job}");
    let result = &job["result"];
    let count = |k: &str| result[k]["count"].as_u64().unwrap();
    assert!(count("stalactites") + count("columns") > 0, "{result}");

    let glb = server.artifact(&id, "mesh.glb").await;
    let nodes = closed_nodes(&glb);
    // The chamber is one closed surface, every speleothem another.
    assert!(nodes.iter().any(|(n, closed)| n == "chamber" && *closed), "{nodes:?}");
    let speleothems: Vec<_> = nodes.iter().filter(|(n, _)| n != "chamber").collect();
    assert!(result["neighbours"]["min_gap_m"].as_f64().unwrap() > 0.0, "{result}");
    assert_eq!(speleothems.len() as u64, count("stalactites") + count("stalagmites") + count("columns"));
    assert!(speleothems.iter().all(|(_, closed)| *closed), "{speleothems:?}");
    let report = common::gltf_validator::validate_glb(&glb);
    assert_eq!(report.errors, 0, "{:?}", report.messages);

    let (status, replay) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({})).await;
    assert_eq!(status, 202, "{replay}");
    let replay = server.wait_done(replay["id"].as_str().unwrap()).await;
    assert_eq!(artifact_hashes(&replay), artifact_hashes(&job));

    let (_, part) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({"until_step": 12})).await;
    let part = server.wait_done(part["id"].as_str().unwrap()).await;
    let short = server.run("grow-cave", &small_cave(12)).await;
    assert_eq!(artifact_hashes(&part), artifact_hashes(&short));
    assert_ne!(artifact_hashes(&part), artifact_hashes(&job));
}

#[tokio::test]
async fn the_paper_examples_run() {
    let server = TestServer::start().await;
    for name in [
        "random-stalactites",
        "stalactites-low-co2",
        "stalactites-normal-co2",
        "stalactites-high-co2",
        "stalagmites-dry",
        "columns",
        "mixed-iron",
        "mixed-malachite",
        "wind-bent-stalactites",
        "soda-straws",
        "crowded-drips",
    ] {
        let job = server.run("grow-cave", &example("grow-cave", name)).await;
        let glb = server.artifact(job["id"].as_str().unwrap(), "mesh.glb").await;
        assert!(closed_nodes(&glb).iter().all(|(_, c)| *c), "{name}");
    }
}

#[tokio::test]
async fn bad_cave_requests_name_their_field() {
    let server = TestServer::start().await;
    let with = |patch: Value| {
        let mut body = small_cave(10);
        for (k, v) in patch.as_object().unwrap() {
            body[k] = v.clone();
        }
        body
    };
    let cases = [
        (with(json!({"mineral": "gold"})), 422, "mineral"),
        (
            with(json!({"conditions": {"pluviometric_index": "3", "drip_interval": "dry", "co2": "low"}})),
            422,
            "conditions.pluviometric_index",
        ),
        (
            with(json!({"conditions": {"pluviometric_index": "1", "drip_interval": "damp", "co2": "low"}})),
            422,
            "conditions.drip_interval",
        ),
        (with(json!({"wind": {"direction": [1, 0], "intensity": 1.5}})), 422, "wind.intensity"),
        (with(json!({"wind": {"direction": [0, 0]}})), 422, "wind.direction"),
        (with(json!({"sites": {"explicit": [{"x_m": 2, "z_m": 9}]}})), 422, "sites.explicit[0].z_m"),
        (with(json!({"sites": {"explicit": [{"x_m": -1, "z_m": 1}]}})), 422, "sites.explicit[0].x_m"),
        (with(json!({"chamber": {"width_m": 0}})), 422, "chamber.width_m"),
        (with(json!({"chamber": {"height_m": -3}})), 422, "chamber.height_m"),
        (with(json!({"rings": 257})), 413, "rings"),
        (with(json!({"segments": 65})), 413, "segments"),
        (with(json!({"segments": 2})), 422, "segments"),
        (with(json!({"sites": {"scatter": {"count": 100000}}})), 413, "sites.scatter.count"),
        (
            with(
                json!({"manual": {"stalactite": [{"radius_m": 0.05, "height_m": 0.1}, {"radius_m": 0.06, "height_m": 0.1}]}}),
            ),
            422,
            "manual.stalactite[1].radius_m",
        ),
        (with(json!({"intensity": 2})), 422, "intensity"),
        (with(json!({"coating_share": 5})), 422, "coating_share"),
        (with(json!({"canal_radius_m": -0.1})), 422, "canal_radius_m"),
        (with(json!({"chamber": {"walls": {"relief_m": -1}}})), 422, "chamber.walls.relief_m"),
        (
            with(
                json!({"chamber": {"width_m": 6, "opening": {"wall": "north", "centre_m": 5.8, "width_m": 1, "height_m": 1}}}),
            ),
            422,
            "chamber.opening.centre_m",
        ),
        (
            with(
                json!({"chamber": {"height_m": 3, "opening": {"wall": "west", "centre_m": 2, "width_m": 1, "height_m": 3}}}),
            ),
            422,
            "chamber.opening.height_m",
        ),
        (
            with(json!({"conditions": {"pluviometric_index": "2", "drip_interval": "soggy", "co2": "low"}})),
            422,
            "conditions.drip_interval",
        ),
    ];
    for (body, status, field) in cases {
        let (got, problem) = server.post("/v1/jobs/grow-cave", &body).await;
        assert_eq!(got, status, "{field}: {problem}");
        let fields: Vec<&str> =
            problem["errors"].as_array().into_iter().flatten().filter_map(|e| e["field"].as_str()).collect();
        assert!(fields.contains(&field), "wanted {field:?}: {problem}");
    }
}
