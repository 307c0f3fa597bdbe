//! The carve-coast job through the real server: an island a deform-terrain job made, carved
//! through `terrain: {"job": id}` (closed mesh, validator, heightmap, replay), the examples,
//! and bad input naming the field.

mod common;

use common::server::{artifact_hashes, example, TestServer};
use serde_json::{json, Value};

#[tokio::test]
async fn a_deformed_island_is_carved_and_replayed_to_the_same_bytes() {
    let server = TestServer::start().await;
    let island = json!({
        "seed": 4,
        "terrain": {"fractal": {"size": 65, "relief": 40.0, "seed": 9, "island": true}},
        "constraints": [{"preserve": {}}],
        "max_iterations": 5
    });
    let deformed = server.run("deform-terrain", &island).await;
    let carve = json!({
        "seed": 7,
        "terrain": {"job": deformed["id"]},
        "sea_level": 0.0,
        "passes": 2,
        "erosion": {"seed_acceptance_probability": 0.15, "radius_range": [1.2, 2.5]}
    });
    let job = server.submit("carve-coast", &carve).await;
    let id = job["id"].as_str().unwrap().to_string();
    let events =
        common::sse::read_events(&server.client, &server.url(&format!("/v1/jobs/{id}/events")), None, 10_000).await;
    assert_eq!(events.last().unwrap().event, "done");
    assert!(events.iter().any(|e| e.event == "progress" && e.data["stage"] == "carving"), "pass progress");
    let job = server.wait_done(&id).await;
    assert_eq!(job["status"], "succeeded", "{job}");
    let result = &job["result"];
    assert_eq!(result["mesh"]["closed"], true, "{result}");
    assert_eq!(result["pieces"], 1, "{result}");
    assert!(result["spheres"]["total"].as_u64().unwrap() > 0, "{result}");
    let names: Vec<&str> = job["artifacts"].as_array().unwrap().iter().map(|a| a["name"].as_str().unwrap()).collect();
    for want in
        ["mesh.glb", "preview.png", "heightmap.png", "heightmap.r16", "normalmap.png", "splatmap.png", "sequence.json"]
    {
        assert!(names.contains(&want), "{want} in {names:?}");
    }
    let glb = server.artifact(&id, "mesh.glb").await;
    let report = common::gltf_validator::validate_glb(&glb);
    assert_eq!(report.errors, 0, "{:?}", report.messages);
    let gltf = gltf::Gltf::from_slice_without_validation(&glb).unwrap();
    // The scene's nodes (their levels of detail are nodes outside it, named by MSFT_lod).
    let scene = gltf.default_scene().unwrap();
    let nodes: Vec<_> = scene.nodes().map(|n| n.name().unwrap_or_default().to_string()).collect();
    assert_eq!(nodes, ["terrain", "sea"]);
    assert!(common::glb_topology::closed_nodes(&glb).iter().any(|(n, closed)| n == "terrain" && *closed));

    let (_, replay) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({})).await;
    let replay = server.wait_done(replay["id"].as_str().unwrap()).await;
    assert_eq!(replay["status"], "succeeded", "{replay}");
    assert_eq!(artifact_hashes(&replay), artifact_hashes(&job));
    let (_, part) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({"until_step": 3})).await;
    let part = server.wait_done(part["id"].as_str().unwrap()).await;
    assert_eq!(part["result"]["spheres"]["total"], 3, "{}", part["result"]);

    // The carved topmost surface feeds the next job.
    server.run("bulldoze", &json!({"terrain": {"job": id}, "operations": []})).await;
}

#[tokio::test]
async fn the_quick_example_runs() {
    let server = TestServer::start().await;
    let job = server.run("carve-coast", &example("carve-coast", "small-island-one-pass")).await;
    assert_eq!(job["result"]["mesh"]["closed"], true);
    for name in ["island-defaults", "cliff-strata"] {
        let mut body = example("carve-coast", name);
        // Accepting is what is checked here; the bench and the quick example run the real thing.
        body["terrain"]["fractal"]["size"] = json!(33);
        body["passes"] = json!(1);
        server.run("carve-coast", &body).await;
    }
}

#[tokio::test]
async fn bad_carving_requests_name_their_field() {
    let server = TestServer::start().await;
    let base = example("carve-coast", "small-island-one-pass");
    let with = |path: &[&str], value: Value| {
        let mut body = base.clone();
        let mut at = &mut body;
        for seg in &path[..path.len() - 1] {
            at = &mut at[*seg];
        }
        at[path[path.len() - 1]] = value;
        body
    };
    let cases = [
        (with(&["erosion", "radius_range"], json!([3.0, 1.0])), 422, "erosion.radius_range"),
        (with(&["erosion", "seed_elevation_range"], json!([5.0, -5.0])), 422, "erosion.seed_elevation_range"),
        (with(&["erosion", "growth_step_range"], json!([4, 2])), 422, "erosion.growth_step_range"),
        (with(&["erosion", "seed_acceptance_probability"], json!(1.5)), 422, "erosion.seed_acceptance_probability"),
        (with(&["erosion", "seed_acceptance_probability"], json!(-0.1)), 422, "erosion.seed_acceptance_probability"),
        (with(&["erosion", "radius_range"], json!([0.0, 1.0])), 422, "erosion.radius_range"),
        (with(&["passes"], json!(0)), 422, "passes"),
        (with(&["passes"], json!(17)), 422, "passes"),
        (with(&["voxel_size_m"], json!(0.01)), 413, "voxel_size_m"),
        (with(&["voxel_size_m"], json!(-1.0)), 422, "voxel_size_m"),
    ];
    for (body, status, field) in cases {
        let (got, problem) = server.post("/v1/jobs/carve-coast", &body).await;
        assert_eq!(got, status, "{field}: {problem}");
        let fields: Vec<&str> =
            problem["errors"].as_array().into_iter().flatten().filter_map(|e| e["field"].as_str()).collect();
        assert!(fields.contains(&field), "wanted {field:?}: {problem}");
    }
    // A sea level above the whole terrain fails the job, naming the field.
    let job = server.submit("carve-coast", &with(&["sea_level"], json!(500.0))).await;
    let job = server.wait_done(job["id"].as_str().unwrap()).await;
    assert_eq!(job["status"], "failed", "{job}");
    assert!(job["error"].to_string().contains("sea_level"), "{job}");
}

/// A 129² island at 2 m of our own, in every compression form, read back by three.js as a web
/// client decodes it: no zero-area triangle and no two vertices at one position in the
/// positions as stored (the quantised forms' integers), and the carved solid still closed
/// once vertices at one position are welded (every edge shared by exactly two triangles).
#[test]
fn an_islands_mesh_is_clean_and_closed_in_every_compression_form() {
    let dir = tempfile::tempdir().unwrap();
    let body = |form: &str| {
        json!({
            "seed": 12,
            "terrain": {"fractal": {"size": 129, "cell_size": 2.0, "relief": 70.0, "seed": 31, "island": true}},
            "sea_level": 4.0,
            "passes": 3,
            "compression": form,
        })
    };
    let mut files = Vec::new();
    for form in ["none", "quantize", "meshopt"] {
        let out = dir.path().join(form);
        let job = common::cli::run_job("carve-coast", &body(form), &out).expect("the job runs");
        assert_eq!(job["result"]["mesh"]["closed"], true, "{form}: {}", job["result"]);
        assert!(job["result"]["spheres"]["total"].as_u64().unwrap() > 50, "{form}: {}", job["result"]);
        files.push(out.join("mesh.glb"));
    }
    let loaded = common::cli::load_in_three(&files);
    for (form, file) in ["none", "quantize", "meshopt"].iter().zip(&loaded) {
        let terrain = file["meshes"].as_array().unwrap().iter().find(|m| m["name"] == "terrain").expect("terrain");
        assert!(terrain["triangles"].as_u64().unwrap() > 50_000, "{form}: {terrain}");
        for key in ["zero_area", "duplicates", "welded_unpaired_edges"] {
            assert_eq!(terrain[key], 0, "{form}: {key} in {terrain}");
        }
    }
}

/// The heights of a `heightfield.npy` (`<f4`, C order), read here from the file's own header.
fn npy_heights(bytes: &[u8]) -> Vec<f32> {
    assert_eq!(&bytes[..6], b"\x93NUMPY");
    let (start, header) = match bytes[6] {
        1 => (10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize, &bytes[10..]),
        _ => (12 + u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize, &bytes[12..]),
    };
    assert!(String::from_utf8_lossy(&header[..start.min(header.len())]).contains("'<f4'"));
    bytes[start..].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect()
}

/// Without `sea_level`, the coast is carved at the height a quarter of the terrain lies below:
/// on a terrain from another job whose heights do not reach 0 m (the old default), it runs.
#[tokio::test]
async fn without_a_sea_level_the_coast_is_a_quarter_of_the_way_up_its_terrain() {
    let server = TestServer::start().await;
    let raised = json!({
        "terrain": {"fractal": {"size": 65, "cell_size": 1.0, "relief": 30.0, "seed": 5, "island": false}},
        "operations": [{"primitive": {
            "shape": {"box": {"center": {"x": 32.0, "z": 32.0}, "size_x_m": 200.0, "size_z_m": 200.0, "height_m": 60.0}},
            "operator": "add"
        }}],
    });
    let raised = match server.submit_waiting("bulldoze", &raised, 60).await {
        (200, job) => job,
        other => panic!("{other:?}"),
    };
    let id = raised["id"].as_str().unwrap();
    let mut heights = npy_heights(&server.artifact(id, "heightfield.npy").await);
    heights.sort_by(f32::total_cmp);
    assert!(heights[0] > 0.0, "the terrain is above 0 m: {}", heights[0]);
    let expected = heights[heights.len() / 4];

    let carve = json!({"seed": 2, "terrain": {"job": id}, "passes": 1});
    let job = server.run("carve-coast", &carve).await;
    assert_eq!(job["result"]["sea_level_m"].as_f64().unwrap() as f32, expected, "{}", job["result"]);
    // The stored request keeps the field absent (the level is the terrain's), and the old
    // default, 0 m, is refused on this terrain as before.
    assert!(job["request"].get("sea_level").is_none(), "{}", job["request"]);
    let mut at_zero = carve.clone();
    at_zero["sea_level"] = json!(0.0);
    let failed = server.submit("carve-coast", &at_zero).await;
    let failed = server.wait_done(failed["id"].as_str().unwrap()).await;
    assert_eq!(failed["status"], "failed", "{failed}");
    assert_eq!(failed["error"]["errors"][0]["field"], "sea_level", "{failed}");
}
