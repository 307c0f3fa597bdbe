//! The bulldoze job end to end through the real server: submit, stream, download, validate,
//! replay, restart.

mod common;

use common::bodies::{small_bulldoze, small_bulldoze_first_steps};
use common::server::{artifact_hashes, example, Options, TestServer};
use common::sse::read_events;

fn decode_png16(bytes: &[u8]) -> (png::Info<'static>, Vec<u16>) {
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes.to_vec()));
    let mut reader = decoder.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size()];
    let frame = reader.next_frame(&mut buf).expect("png frame");
    let info = reader.info().clone();
    assert_eq!(frame.bit_depth, png::BitDepth::Sixteen, "heightmap must be 16-bit");
    assert_eq!(frame.color_type, png::ColorType::Grayscale, "heightmap must be grayscale");
    let values = buf[..frame.buffer_size()].chunks_exact(2).map(|c| u16::from_be_bytes([c[0], c[1]])).collect();
    (info.to_owned(), values)
}

fn text_chunk(info: &png::Info, key: &str) -> Option<f64> {
    info.uncompressed_latin1_text.iter().find(|t| t.keyword == key).and_then(|t| t.text.trim().parse().ok())
}

#[tokio::test]
async fn a_job_streams_to_done_and_its_artifacts_are_valid_and_replayable() {
    let server = TestServer::start().await;
    let job = server.submit("bulldoze", &small_bulldoze()).await;
    let id = job["id"].as_str().unwrap().to_string();
    assert_eq!(job["kind"], "bulldoze");
    assert_eq!(job["request"]["seed"], 0, "defaults are filled in");
    assert_eq!(job["request"]["operations"][0]["primitive"]["shape"]["mound"]["curvature"], 2.0);

    // SSE from the start to `done`.
    let events = read_events(&server.client, &server.url(&format!("/v1/jobs/{id}/events")), None, 10_000).await;
    let done = events.last().expect("events");
    assert_eq!(done.event, "done", "{events:?}");
    assert_eq!(done.data["status"], "succeeded", "{}", done.data);
    assert!(events.iter().any(|e| e.event == "status"), "status events");
    let ids: Vec<u64> = events.iter().filter_map(|e| e.id).collect();
    assert!(ids.windows(2).all(|w| w[0] < w[1]), "event ids increase: {ids:?}");
    let job = done.data.clone();

    // The finished job's stream sends `done` at once.
    let again = read_events(&server.client, &server.url(&format!("/v1/jobs/{id}/events")), None, 10).await;
    assert_eq!(again.len(), 1);
    assert_eq!(again[0].event, "done");

    // Artifacts: names, a valid glb, a 16-bit heightmap whose range is in the result.
    let names: Vec<&str> = job["artifacts"].as_array().unwrap().iter().map(|a| a["name"].as_str().unwrap()).collect();
    for want in ["mesh.glb", "heightmap.png", "preview.png", "sequence.json"] {
        assert!(names.contains(&want), "{want} in {names:?}");
    }
    let glb = server.artifact(&id, "mesh.glb").await;
    let gltf = gltf::Gltf::from_slice_without_validation(&glb).expect("glb parses");
    let mesh = gltf.meshes().next().expect("a mesh");
    let prim = mesh.primitives().next().expect("a primitive");
    let pos = prim.get(&gltf::Semantic::Positions).expect("POSITION");
    assert_eq!(pos.count(), 129 * 129);
    assert!(prim.get(&gltf::Semantic::Normals).is_some() && prim.get(&gltf::Semantic::TexCoords(0)).is_some());
    let report = common::gltf_validator::validate_glb(&glb);
    assert_eq!(report.errors, 0, "glTF validator: {:?}", report.messages);

    let png_bytes = server.artifact(&id, "heightmap.png").await;
    let (info, values) = decode_png16(&png_bytes);
    assert_eq!((info.width, info.height), (129, 129));
    let z_min = job["result"]["z_min"].as_f64().expect("z_min in result");
    let z_max = job["result"]["z_max"].as_f64().expect("z_max in result");
    assert!((text_chunk(&info, "z_min").expect("z_min chunk") - z_min).abs() < 1e-3);
    assert!((text_chunk(&info, "z_max").expect("z_max chunk") - z_max).abs() < 1e-3);
    assert!(values.contains(&0) && values.contains(&65535), "the range spans the full 16 bits");

    // heightmap.r16: raw little-endian steps of the range the result states, agreeing with the
    // float heights of heightfield.npy to within one step; normalmap.png at the grid's size.
    let r16 = &job["result"]["heightmap_r16"];
    assert_eq!((r16["width"].as_u64(), r16["height"].as_u64()), (Some(129), Some(129)), "{r16}");
    let (lo, range) = (r16["z_min"].as_f64().unwrap(), r16["height_range_m"].as_f64().unwrap());
    assert!((lo - z_min).abs() < 1e-3 && (lo + range - z_max).abs() < 1e-3, "{r16}");
    let raw = server.artifact(&id, "heightmap.r16").await;
    let floats = npy_heights(&server.artifact(&id, "heightfield.npy").await);
    assert_eq!(raw.len(), 2 * floats.len());
    let step = range / 65535.0;
    for (pair, &h) in raw.chunks_exact(2).zip(&floats) {
        let read = lo + f64::from(u16::from_le_bytes([pair[0], pair[1]])) * step;
        assert!((read - f64::from(h)).abs() <= step * 1.001, "{read} for {h}");
    }
    // A second reader in plain Python agrees: both maps within a step of the .npy, r16 = PNG.
    let dir = tempfile::tempdir().unwrap();
    for name in ["heightmap.r16", "heightmap.png", "heightfield.npy"] {
        std::fs::write(dir.path().join(name), server.artifact(&id, name).await).unwrap();
    }
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/read_maps.py");
    let out = std::process::Command::new("python3")
        .arg(script)
        .arg(dir.path())
        .args(["129", "129", &lo.to_string(), &(lo + range).to_string()])
        .output()
        .expect("python3 runs (scripts/test installs it)");
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{report} {}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    assert_eq!(report["samples"], 129 * 129, "{report}");
    let normals = image::load_from_memory(&server.artifact(&id, "normalmap.png").await).expect("normal map decodes");
    assert_eq!((normals.width(), normals.height(), normals.color()), (129, 129, image::ColorType::Rgb8));
    let splat = image::load_from_memory(&server.artifact(&id, "splatmap.png").await).expect("splat map decodes");
    assert_eq!((splat.width(), splat.height(), splat.color()), (129, 129, image::ColorType::Rgba8));
    let splat = splat.to_rgba8();
    assert!(splat.pixels().all(|p| p.0.iter().map(|&v| u32::from(v)).sum::<u32>() == 255), "weights sum to 255");
    // Its material is the bulldozer's work: cells moved over 1 cm, so no more than it changed.
    let shaped = splat.pixels().filter(|p| p.0[3] == 255).count() as u64;
    assert!(splat.pixels().all(|p| p.0[3] == 0 || p.0[3] == 255), "shaped or not");
    let changed = job["result"]["changed_samples"].as_u64().unwrap();
    assert!(shaped > 0 && shaped <= changed, "{shaped} cells shaped, {changed} changed");

    // The sequence endpoint serves the artifact.
    let (status, seq) = server.get_json(&format!("/v1/jobs/{id}/sequence")).await;
    assert_eq!(status, 200);
    assert_eq!(seq["steps"].as_array().map(Vec::len), Some(5), "{seq}");

    // A full replay gives the same bytes for every artifact.
    let (status, replay) = server.post(&format!("/v1/jobs/{id}/replay"), &serde_json::json!({})).await;
    assert_eq!(status, 202, "{replay}");
    assert_eq!(replay["replay_of"], id.as_str());
    let replay = server.wait_done(replay["id"].as_str().unwrap()).await;
    assert_eq!(replay["status"], "succeeded", "{replay}");
    assert_eq!(artifact_hashes(&replay), artifact_hashes(&job));

    // Replay until step k differs from the whole, and equals a direct run of those k steps.
    for k in [1u64, 3] {
        let (status, partial) =
            server.post(&format!("/v1/jobs/{id}/replay"), &serde_json::json!({ "until_step": k })).await;
        assert_eq!(status, 202, "{partial}");
        let partial = server.wait_done(partial["id"].as_str().unwrap()).await;
        assert_eq!(partial["status"], "succeeded", "{partial}");
        let direct = server.run("bulldoze", &small_bulldoze_first_steps(k as usize)).await;
        let hm = |j: &serde_json::Value| {
            artifact_hashes(j).into_iter().find(|(n, _)| n == "heightmap.png").map(|(_, h)| h).unwrap()
        };
        assert_ne!(hm(&partial), hm(&job), "until_step {k} differs from the whole");
        let hf = |j: &serde_json::Value| {
            artifact_hashes(j).into_iter().find(|(n, _)| n == "heightfield.npy").map(|(_, h)| h).unwrap()
        };
        assert_eq!(hf(&partial), hf(&direct), "until_step {k} equals a run of {k} steps");
    }

    // until_step beyond the sequence names the field.
    let (status, problem) = server.post(&format!("/v1/jobs/{id}/replay"), &serde_json::json!({"until_step": 99})).await;
    assert_eq!(status, 422);
    assert_eq!(problem["errors"][0]["field"], "until_step");
}

#[tokio::test]
async fn every_bulldoze_example_runs_and_its_mesh_passes_the_validator() {
    let server = TestServer::start().await;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("api/bulldoze");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().to_str()?.strip_suffix(".json").map(str::to_string))
        .collect();
    names.sort();
    assert!(names.len() >= 5, "examples: {names:?}");
    for name in names {
        let job = server.run("bulldoze", &example("bulldoze", &name)).await;
        let glb = server.artifact(job["id"].as_str().unwrap(), "mesh.glb").await;
        let report = common::gltf_validator::validate_glb(&glb);
        assert_eq!(report.errors, 0, "{name}: {:?}", report.messages);
    }
}

/// `compression` picks the glb form: f32 by default (the request says `none`), quantized with
/// `quantize`, the same triangles either way, both valid; anything else is a 422 naming the field.
#[tokio::test]
async fn compression_picks_the_glb_form_and_the_request_states_it() {
    let server = TestServer::start().await;
    let mut body = example("bulldoze", "ziggurat");
    let plain = server.run("bulldoze", &body).await;
    assert_eq!(plain["request"]["compression"], "none");
    body["compression"] = serde_json::json!("quantize");
    let quantized = server.run("bulldoze", &body).await;
    assert_eq!(quantized["request"]["compression"], "quantize");
    let mut counts = Vec::new();
    for (job, required) in [(&quantized, vec!["KHR_mesh_quantization"]), (&plain, vec![])] {
        let glb = server.artifact(job["id"].as_str().unwrap(), "mesh.glb").await;
        let gltf = gltf::Gltf::from_slice_without_validation(&glb).unwrap();
        assert_eq!(gltf.document.as_json().extensions_required, required);
        let prim = gltf.meshes().next().unwrap().primitives().next().unwrap();
        counts.push((
            prim.get(&gltf::Semantic::Positions).unwrap().count(),
            prim.indices().unwrap().count(),
            glb.len(),
        ));
        let report = common::gltf_validator::validate_glb(&glb);
        assert_eq!((report.errors, report.warnings), (0, 0), "{:?}", report.messages);
    }
    assert_eq!((counts[0].0, counts[0].1), (counts[1].0, counts[1].1), "the same mesh");
    assert!(counts[0].2 < counts[1].2, "quantized is smaller: {counts:?}");

    body["compression"] = serde_json::json!("zip");
    let (status, problem) = server.post("/v1/jobs/bulldoze", &body).await;
    assert_eq!(status, 422, "{problem}");
    assert_eq!(problem["errors"][0]["field"], "compression", "{problem}");
}

#[tokio::test]
async fn one_and_two_threads_give_identical_artifacts() {
    let body = example("bulldoze", "ziggurat");
    let one = TestServer::start_with(Options { workers: 1, ..Options::default() }).await;
    let a = one.run("bulldoze", &body).await;
    drop(one);
    let two = TestServer::start_with(Options { workers: 2, ..Options::default() }).await;
    let b = two.run("bulldoze", &body).await;
    assert_eq!(artifact_hashes(&a), artifact_hashes(&b));
}

#[tokio::test]
async fn a_restarted_server_keeps_jobs_and_serves_their_artifacts() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("landform.db");
    let first = TestServer::start_on(&db, &Options::default()).await;
    let job = first.run("bulldoze", &small_bulldoze()).await;
    let id = job["id"].as_str().unwrap().to_string();
    let glb = first.artifact(&id, "mesh.glb").await;
    first.kill();

    let second = TestServer::start_on(&db, &Options::default()).await;
    let (status, again) = second.get_json(&format!("/v1/jobs/{id}")).await;
    assert_eq!(status, 200);
    assert_eq!(artifact_hashes(&again), artifact_hashes(&job));
    assert_eq!(second.artifact(&id, "mesh.glb").await, glb);
}

#[tokio::test]
async fn jobs_left_running_by_a_crash_run_again_on_start() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("landform.db");
    let first = TestServer::start_on(&db, &Options { workers: 1, ..Options::default() }).await;
    let slow = first.submit("bulldoze", &common::bodies::slow_bulldoze()).await;
    let queued = first.submit("bulldoze", &small_bulldoze()).await;
    // Follow the slow one until it runs, then crash.
    let id = slow["id"].as_str().unwrap();
    let events_url = |s: &TestServer| s.url(&format!("/v1/jobs/{id}/events"));
    let seen = read_events(&first.client, &events_url(&first), None, 3).await;
    assert!(seen.iter().any(|e| e.data["status"] == "running"), "{seen:?}");
    let last_seen = seen.last().unwrap().id.unwrap();
    first.kill();

    let second = TestServer::start_on(&db, &Options::default()).await;
    // A client resuming from before the crash sees the re-run to its end.
    let resumed = read_events(&second.client, &events_url(&second), Some(last_seen), 100_000).await;
    assert_eq!(resumed.last().unwrap().event, "done", "{resumed:?}");
    assert!(resumed.iter().all(|e| e.id.unwrap() > last_seen), "ids keep growing across the restart");
    for j in [&slow, &queued] {
        let done = second.wait_done(j["id"].as_str().unwrap()).await;
        assert_eq!(done["status"], "succeeded", "{done}");
    }
}

/// Heights from a NumPy v1 `<f4` file, row-major.
fn npy_heights(bytes: &[u8]) -> Vec<f32> {
    assert_eq!(&bytes[..6], b"\x93NUMPY");
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + header_len]).unwrap();
    assert!(header.contains("'descr': '<f4'"), "{header}");
    bytes[10 + header_len..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
}

#[tokio::test]
async fn an_uploaded_16_bit_heightmap_is_read_exactly_and_jobs_compose() {
    use base64::Engine as _;
    let (w, h) = (65u32, 33u32);
    let value = |c: u32, r: u32| ((c * 1000 + r * 37) % 65536) as u16;
    let mut png_bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png_bytes, w, h);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        let data: Vec<u8> = (0..h).flat_map(|r| (0..w).flat_map(move |c| value(c, r).to_be_bytes())).collect();
        enc.write_header().unwrap().write_image_data(&data).unwrap();
    }
    let (z_min, z_max) = (10.0f32, 75.535f32);
    let body = serde_json::json!({
        "terrain": {"heightmap": {
            "png_base64": base64::engine::general_purpose::STANDARD.encode(&png_bytes),
            "cell_size": 2.0, "z_min": z_min, "z_max": z_max
        }},
        "operations": []
    });
    let server = TestServer::start().await;
    let upload = server.run("bulldoze", &body).await;
    assert_eq!(upload["result"]["grid"], serde_json::json!({"cols": 65, "rows": 33, "cell_size_m": 2.0}));
    let heights = npy_heights(&server.artifact(upload["id"].as_str().unwrap(), "heightfield.npy").await);
    for (i, got) in heights.iter().enumerate() {
        let (c, r) = (i as u32 % w, i as u32 / w);
        let want = z_min + (z_max - z_min) * value(c, r) as f32 / 65535.0;
        assert!((got - want).abs() < 1e-3, "sample ({c}, {r}): {got} vs {want}");
    }

    // The upload was stored once: the request and the sequence name it by sha256.
    use sha2::Digest;
    let sha = hex::encode(sha2::Sha256::digest(&png_bytes));
    let stored = &upload["request"]["terrain"]["heightmap"];
    assert_eq!(stored["png_sha256"], sha.as_str(), "{stored}");
    assert!(stored.get("png_base64").is_none(), "the file is not repeated in the job");
    let sequence = server.artifact(upload["id"].as_str().unwrap(), "sequence.json").await;
    assert!(sequence.len() < 1024, "the sequence is a few hundred bytes, not the file: {}", sequence.len());
    // Naming it again by sha256 reads the same heights without sending the file.
    let mut by_sha = body.clone();
    by_sha["terrain"]["heightmap"] =
        serde_json::json!({"png_sha256": sha, "cell_size": 2.0, "z_min": z_min, "z_max": z_max});
    let again = server.run("bulldoze", &by_sha).await;
    assert_eq!(
        server.artifact(again["id"].as_str().unwrap(), "heightfield.npy").await,
        server.artifact(upload["id"].as_str().unwrap(), "heightfield.npy").await
    );
    by_sha["terrain"]["heightmap"]["png_sha256"] = serde_json::json!("0".repeat(64));
    let (status, problem) = server.post("/v1/jobs/bulldoze", &by_sha).await;
    assert_eq!(status, 422);
    assert_eq!(problem["errors"][0]["field"], "terrain.heightmap.png_sha256", "{problem}");

    // A second job starts from the first one's exact heights.
    let mound = serde_json::json!({
        "terrain": {"job": upload["id"]},
        "operations": [{"primitive": {"shape": {"mound": {"center": {"x": 64, "z": 32}, "radius_m": 10, "height_m": 5}}}}]
    });
    let composed = server.run("bulldoze", &mound).await;
    let after = npy_heights(&server.artifact(composed["id"].as_str().unwrap(), "heightfield.npy").await);
    let centre = (16 * w + 32) as usize; // x = 64 m, z = 32 m at 2 m cells
    assert!((after[centre] - heights[centre] - 5.0).abs() < 1e-4, "the mound's top sits on the first job's surface");
    assert_eq!(after[0], heights[0], "outside the mound nothing changed");
}
