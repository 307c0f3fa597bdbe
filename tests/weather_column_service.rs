//! The weather-column job through the real server: a goblin end to end (closed mesh that
//! passes the glTF validator, lit preview, live progress), replay in full and until a step, a
//! joint map uploaded once and named by its sha256, the examples, and bad input naming the
//! field.

mod common;

use base64::Engine as _;
use common::glb_topology::closed_nodes;
use common::server::{artifact_hashes, example, TestServer};
use serde_json::{json, Value};

/// A small goblin: a cylinder with a hard cap over a soft base; quick in the test profile.
fn small_goblin(steps: u32) -> Value {
    json!({
        "seed": 4,
        "grid": {"x": 20, "y": 26, "z": 20},
        "voxel_size_m": 0.1,
        "column": {"profile": {"cylinder": {"radius_m": 0.9}}},
        "layers": [
            {"top_m": 1.6, "resistance": 0.5, "noise": {"amplitude": 0.3, "frequency_per_m": 2.0}, "bubble": {"sphere": {"radius": 3}}},
            {"top_m": 2.6, "resistance": 3.0, "bubble": {"gumdrop": {"radius": 3}}}
        ],
        "rate": 0.05,
        "steps": steps
    })
}

/// The rock node of the glb is closed.
fn glb_is_closed(glb: &[u8]) -> bool {
    closed_nodes(glb).iter().any(|(name, closed)| name == "rock" && *closed)
}

fn png_size(bytes: &[u8]) -> (u32, u32) {
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let reader = decoder.read_info().expect("png");
    (reader.info().width, reader.info().height)
}

/// Weathering long enough for live snapshots (the first comes a quarter second into the steps):
/// a 2.3 M-voxel column for 150 steps, about a second in the test profile. A snapshot shows the
/// rock as it is (once the job ends, live.png is the final preview).
#[tokio::test]
async fn a_long_weathering_publishes_live_snapshots() {
    let server = TestServer::start().await;
    let body = json!({
        "seed": 4,
        "grid": {"x": 120, "y": 160, "z": 120},
        "voxel_size_m": 0.1,
        "column": {"profile": {"cylinder": {"radius_m": 5.5}}},
        "layers": [{"top_m": 20, "resistance": 1.0, "bubble": {"sphere": {"radius": 3}}}],
        "rate": 0.3,
        "steps": 150
    });
    let id = server.submit("weather-column", &body).await["id"].as_str().unwrap().to_string();
    let events =
        common::sse::read_events(&server.client, &server.url(&format!("/v1/jobs/{id}/events")), None, 100_000).await;
    assert_eq!(events.last().unwrap().event, "done");
    let snapshot = events
        .iter()
        .find_map(|e| (e.event == "progress").then(|| e.data["snapshot"].as_str()).flatten())
        .expect("a progress event announces a live snapshot");
    let live = server.client.get(server.url(snapshot)).send().await.unwrap();
    assert_eq!(live.status(), 200);
    assert!(png_size(&live.bytes().await.unwrap()).0 >= 256);
}

#[tokio::test]
async fn a_goblin_weathers_streams_and_replays_to_the_same_bytes() {
    let server = TestServer::start().await;
    let job = server.submit("weather-column", &small_goblin(40)).await;
    let id = job["id"].as_str().unwrap().to_string();
    let events =
        common::sse::read_events(&server.client, &server.url(&format!("/v1/jobs/{id}/events")), None, 10_000).await;
    assert_eq!(events.last().unwrap().event, "done");
    let progress: Vec<&Value> = events.iter().filter(|e| e.event == "progress").map(|e| &e.data).collect();
    assert!(
        progress.iter().any(|p| p["stage"] == "weathering" && p["message"].as_str().unwrap().contains("active voxels")),
        "{progress:?}"
    );
    let job = server.wait_done(&id).await;
    assert_eq!(job["status"], "succeeded", "{job}");
    let result = &job["result"];
    assert_eq!(result["steps_run"], 40, "{result}");
    assert!(result["voxels"]["removed"].as_u64().unwrap() > 0, "{result}");
    assert!(result["active_voxels"]["max"].as_u64().unwrap() >= result["active_voxels"]["min"].as_u64().unwrap());
    assert_eq!(result["mesh"]["closed"], true, "{result}");

    let glb = server.artifact(&id, "mesh.glb").await;
    assert!(glb_is_closed(&glb), "every edge of the goblin's mesh is shared by two triangles");
    let report = common::gltf_validator::validate_glb(&glb);
    assert_eq!(report.errors, 0, "{:?}", report.messages);
    assert_eq!(png_size(&server.artifact(&id, "preview.png").await), (1024, 768));
    let sequence: Value = serde_json::from_slice(&server.artifact(&id, "sequence.json").await).unwrap();
    assert_eq!(sequence["steps"], 40);
    assert_eq!(sequence["removed_per_step"].as_array().unwrap().len(), 40);

    // Full replay: the same bytes.
    let (status, replay) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({})).await;
    assert_eq!(status, 202, "{replay}");
    let replay = server.wait_done(replay["id"].as_str().unwrap()).await;
    assert_eq!(replay["status"], "succeeded", "{replay}");
    assert_eq!(artifact_hashes(&replay), artifact_hashes(&job));
    assert_eq!(replay["result"], job["result"]);

    // Replay until step 15 is a run of 15 steps.
    let (status, part) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({"until_step": 15})).await;
    assert_eq!(status, 202, "{part}");
    let part = server.wait_done(part["id"].as_str().unwrap()).await;
    let short = server.run("weather-column", &small_goblin(15)).await;
    assert_eq!(artifact_hashes(&part), artifact_hashes(&short));
    assert_ne!(artifact_hashes(&part), artifact_hashes(&job));
}

fn joint_map_png() -> Vec<u8> {
    // Two blocks split by a joint (a black line), on a 16 × 16 map.
    let pixels: Vec<u8> = (0..256).map(|i| if (i % 16) == 7 || (i % 16) == 8 { 0 } else { 255 }).collect();
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, 16, 16);
        enc.set_color(png::ColorType::Grayscale);
        enc.write_header().unwrap().write_image_data(&pixels).unwrap();
    }
    out
}

#[tokio::test]
async fn a_joint_map_is_uploaded_once_and_named_by_its_sha256() {
    let server = TestServer::start().await;
    let png = joint_map_png();
    let body = |profile: Value| {
        let mut b = small_goblin(5);
        b["column"]["profile"] = profile;
        b
    };
    let b64 = base64::engine::general_purpose::STANDARD.encode(&png);
    let first = server.run("weather-column", &body(json!({"joint_map": {"png_base64": b64}}))).await;
    let sha = first["request"]["column"]["profile"]["joint_map"]["png_sha256"].as_str().expect("stored by sha256");
    assert!(first["request"]["column"]["profile"]["joint_map"].get("png_base64").is_none());
    let second = server.run("weather-column", &body(json!({"joint_map": {"png_sha256": sha}}))).await;
    assert_eq!(artifact_hashes(&first), artifact_hashes(&second));
    // The joint splits the column in two: no rock in the joint's voxel columns.
    let glb = server.artifact(first["id"].as_str().unwrap(), "mesh.glb").await;
    assert!(glb_is_closed(&glb));
    let unknown = "0".repeat(64);
    let (status, problem) =
        server.post("/v1/jobs/weather-column", &body(json!({"joint_map": {"png_sha256": unknown}}))).await;
    assert_eq!(status, 422, "{problem}");
}

#[tokio::test]
async fn the_paper_examples_run() {
    let server = TestServer::start().await;
    for name in ["cube-to-sphere", "gumdrop", "goblin-cap", "twin-goblins", "joint-map"] {
        let mut body = example("weather-column", name);
        // Accepting and running are what is checked here; the unit tests measure the shapes.
        body["steps"] = json!(3);
        let job = server.run("weather-column", &body).await;
        assert_eq!(job["result"]["mesh"]["closed"], true, "{name}: {}", job["result"]);
    }
    // Gravity's example in full: the cap falls, and the sequence says when and how far.
    let job = server.run("weather-column", &example("weather-column", "toppled-cap")).await;
    assert_eq!(job["result"]["mesh"]["closed"], true, "{}", job["result"]);
    let sequence: Value =
        serde_json::from_slice(&server.artifact(job["id"].as_str().unwrap(), "sequence.json").await).unwrap();
    let falls = sequence["falls"].as_array().expect("falls");
    assert!(!falls.is_empty() && falls.iter().all(|f| f["dy"].as_u64().unwrap() > 0), "{falls:?}");
}

#[tokio::test]
async fn bad_weathering_requests_name_their_field() {
    let server = TestServer::start().await;
    let with = |path: &[&str], value: Value| {
        let mut body = small_goblin(5);
        let mut at = &mut body;
        for seg in &path[..path.len() - 1] {
            at = match seg.parse::<usize>() {
                Ok(i) => &mut at[i],
                Err(_) => &mut at[*seg],
            };
        }
        at[path[path.len() - 1]] = value;
        body
    };
    let black = {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, 4, 4);
            enc.set_color(png::ColorType::Grayscale);
            enc.write_header().unwrap().write_image_data(&[0u8; 16]).unwrap();
        }
        base64::engine::general_purpose::STANDARD.encode(out)
    };
    let not_png = base64::engine::general_purpose::STANDARD.encode(b"GIF89a not a png at all");
    let mut falling_events = with(&["gravity"], json!(true));
    falling_events["update"] = json!("event_based");
    let cases = [
        (falling_events, 422, "gravity"),
        (
            with(&["column", "profile"], json!({"joint_map": {"png_base64": black}})),
            422,
            "column.profile.joint_map.png_base64",
        ),
        (
            with(&["column", "profile"], json!({"joint_map": {"png_base64": not_png}})),
            422,
            "column.profile.joint_map.png_base64",
        ),
        (with(&["layers", "1", "top_m"], json!(1.0)), 422, "layers[1].top_m"),
        (with(&["layers", "1", "top_m"], json!(1.6)), 422, "layers[1].top_m"),
        (with(&["layers", "0", "resistance"], json!(0.0)), 422, "layers[0].resistance"),
        (with(&["layers", "0", "resistance"], json!(-2.0)), 422, "layers[0].resistance"),
        (with(&["layers", "0", "bubble"], json!({"sphere": {"radius": 9}})), 422, "layers[0].bubble.sphere.radius"),
        (with(&["layers", "0", "bubble"], json!({"sphere": {"radius": 0.5}})), 422, "layers[0].bubble.sphere.radius"),
        (
            with(&["layers", "0", "bubble"], json!({"ellipsoid": {"radii": [2, 12, 2]}})),
            422,
            "layers[0].bubble.ellipsoid.radii[1]",
        ),
        (with(&["layers"], json!([])), 422, "layers"),
        (with(&["grid"], json!({"x": 4096, "y": 4096, "z": 16})), 413, "grid"),
        (with(&["grid", "x"], json!(5000)), 413, "grid.x"),
        (with(&["steps"], json!(65_001)), 422, "steps"),
        (with(&["steps"], json!(0)), 422, "steps"),
        (with(&["rate"], json!(-1.0)), 422, "rate"),
        (with(&["column", "height_m"], json!(30.0)), 422, "column.height_m"),
        (
            with(&["column", "profile"], json!({"polygon": {"points_m": [[0, 0], [1, 1]]}})),
            422,
            "column.profile.polygon.points_m",
        ),
        (with(&["layers", "0", "noise", "amplitude"], json!(2.0)), 422, "layers[0].noise.amplitude"),
        (with(&["update"], json!("sometimes")), 422, "update"),
    ];
    for (body, status, field) in cases {
        let (got, problem) = server.post("/v1/jobs/weather-column", &body).await;
        assert_eq!(got, status, "{field}: {problem}");
        let fields: Vec<&str> =
            problem["errors"].as_array().into_iter().flatten().filter_map(|e| e["field"].as_str()).collect();
        assert!(fields.contains(&field), "wanted {field:?}: {problem}");
    }
    // A profile that covers no voxel centre is refused at submission (the estimate sizes the
    // footprint), with a problem naming the field.
    let tiny = with(&["column", "profile"], json!({"box": {"width_m": 0.01, "depth_m": 0.01}}));
    let (status, problem) = server.post("/v1/jobs/weather-column", &tiny).await;
    assert_eq!(status, 422, "{problem}");
    assert_eq!(problem["errors"][0]["field"], "column.profile", "{problem}");
}

/// `stop_at_fraction` left out stops at 30 % of the rock (what the default keeps); set to 0 it
/// runs as before, every step or until nothing is left.
#[tokio::test]
async fn the_default_stop_keeps_a_rock_and_zero_still_runs_every_step() {
    let server = TestServer::start().await;
    let mut body = example("weather-column", "cube-to-ellipsoid");
    let obj = body.as_object_mut().unwrap();
    obj.retain(|k, _| ["grid", "column", "layers"].contains(&k.as_str()));
    let kept = server.run("weather-column", &body).await;
    let left = kept["result"]["remaining_fraction"].as_f64().unwrap();
    assert!((0.25..=0.3).contains(&left), "{}", kept["result"]);
    assert!(kept["result"]["mesh"]["triangles"].as_u64().unwrap() > 1000, "{}", kept["result"]);
    assert_eq!(kept["request"]["stop_at_fraction"], json!(0.3));

    body["stop_at_fraction"] = json!(0.0);
    let all = server.run("weather-column", &body).await;
    let (run, steps) = (all["result"]["steps_run"].as_u64().unwrap(), all["request"]["steps"].as_u64().unwrap());
    let gone = all["result"]["remaining_fraction"].as_f64().unwrap();
    assert!(run == steps || gone == 0.0, "{}", all["result"]);
    assert!(gone < left, "{gone} vs {left}");
}

/// `null` for a common field is refused naming it, as the schema has none of them nullable;
/// left out, each still has its default (every other test).
#[tokio::test]
async fn null_common_fields_are_refused_by_name() {
    let server = TestServer::start().await;
    for field in ["seed", "label", "compression", "lods"] {
        let mut body = example("weather-column", "cube-to-sphere");
        body[field] = Value::Null;
        let (status, problem) = server.post("/v1/jobs/weather-column", &body).await;
        assert_eq!(status, 422, "{field}: {problem}");
        assert_eq!(problem["errors"][0]["field"], field, "{problem}");
    }
}
