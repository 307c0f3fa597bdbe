//! The erode job through the real server: composition both ways (a deform-terrain result
//! eroded, a road bulldozed on an eroded mountainside) from `api/erode/chains/`, progress with
//! live snapshots, replay to the same bytes and up to a step, the single-body examples, and
//! bad input naming the field.

mod common;

use common::server::{artifact_hashes, example, TestServer};
use serde_json::{json, Value};

/// A chain from api/erode/chains/<name>.json: `{"steps": [{"kind", "body"}, …]}`, where a
/// string "$k" in a body stands for the id of step k's job.
fn chain(name: &str) -> Vec<(String, Value)> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("api/erode/chains/{name}.json"));
    let chain: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    chain["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| (s["kind"].as_str().unwrap().to_string(), s["body"].clone()))
        .collect()
}

fn substitute(body: &mut Value, ids: &[String]) {
    match body {
        Value::String(s) if s.starts_with('$') => {
            let k: usize = s[1..].parse().unwrap();
            *s = ids[k].clone();
        }
        Value::Array(items) => items.iter_mut().for_each(|v| substitute(v, ids)),
        Value::Object(map) => map.values_mut().for_each(|v| substitute(v, ids)),
        _ => {}
    }
}

async fn run_chain(server: &TestServer, name: &str) -> Vec<Value> {
    let mut ids = Vec::new();
    let mut jobs = Vec::new();
    for (kind, mut body) in chain(name) {
        substitute(&mut body, &ids);
        let job = server.run(&kind, &body).await;
        ids.push(job["id"].as_str().unwrap().to_string());
        jobs.push(job);
    }
    jobs
}

/// The heights of a job's `heightfield.npy` (little-endian f32 after the header).
async fn heights(server: &TestServer, id: &str) -> Vec<f32> {
    let npy = server.artifact(id, "heightfield.npy").await;
    let header = u16::from_le_bytes([npy[8], npy[9]]) as usize + 10;
    npy[header..].chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

#[tokio::test]
async fn a_deform_terrain_result_is_eroded_and_replayed() {
    let server = TestServer::start().await;
    let jobs = run_chain(&server, "deform-then-erode").await;
    let (deformed, eroded) = (&jobs[0], &jobs[1]);
    let result = &eroded["result"];
    let landform = &result["landform"];
    assert_eq!(landform["output"]["drained_share"], 1.0, "{landform}");
    assert!(
        landform["output"]["hypsometric_integral"].as_f64() < landform["input"]["hypsometric_integral"].as_f64(),
        "{landform}"
    );
    let (before, after) = (
        heights(&server, deformed["id"].as_str().unwrap()).await,
        heights(&server, eroded["id"].as_str().unwrap()).await,
    );
    assert_eq!(before.len(), after.len());
    let top = before.iter().copied().fold(f32::MIN, f32::max);
    assert!(after.iter().all(|&h| h <= top), "no cell rises above the input's highest point");
    // Every map is a 16-bit grayscale image of the grid.
    let id = eroded["id"].as_str().unwrap();
    for name in ["flow.png", "wear.png", "deposition.png", "heightmap.png"] {
        let png = server.artifact(id, name).await;
        let reader = png::Decoder::new(png.as_slice()).read_info().unwrap();
        let info = reader.info();
        assert_eq!((info.width, info.height, info.bit_depth), (129, 129, png::BitDepth::Sixteen), "{name}");
    }

    let (_, replay) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({})).await;
    let replay = server.wait_done(replay["id"].as_str().unwrap()).await;
    assert_eq!(replay["status"], "succeeded", "{replay}");
    assert_eq!(artifact_hashes(&replay), artifact_hashes(eroded));
    let (_, part) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({"until_step": 10})).await;
    let part = server.wait_done(part["id"].as_str().unwrap()).await;
    assert_eq!(part["result"]["iterations"], 10, "{}", part["result"]);
    let sequence: Value = serde_json::from_slice(&server.artifact(id, "sequence.json").await).unwrap();
    let recorded: Value =
        serde_json::from_slice(&server.artifact(part["id"].as_str().unwrap(), "sequence.json").await).unwrap();
    assert_eq!(recorded["checksums"].as_array().unwrap()[..], sequence["checksums"].as_array().unwrap()[..10]);
}

#[tokio::test]
async fn a_road_is_bulldozed_on_an_eroded_mountainside() {
    let server = TestServer::start().await;
    // Progress of the erosion comes as "eroding" events, with live snapshots.
    let (kind, body) = chain("road-on-eroded-mountainside").remove(0);
    let job = server.submit(&kind, &body).await;
    let id = job["id"].as_str().unwrap().to_string();
    let events =
        common::sse::read_events(&server.client, &server.url(&format!("/v1/jobs/{id}/events")), None, 10_000).await;
    assert_eq!(events.last().unwrap().event, "done");
    assert!(events.iter().any(|e| e.event == "progress" && e.data["stage"] == "eroding"), "erosion progress");

    let jobs = run_chain(&server, "road-on-eroded-mountainside").await;
    let (eroded, road) = (&jobs[0], &jobs[1]);
    assert!(road["result"]["changed_samples"].as_u64().unwrap() > 500, "{}", road["result"]);
    let (before, after) =
        (heights(&server, eroded["id"].as_str().unwrap()).await, heights(&server, road["id"].as_str().unwrap()).await);
    // The road's bed is flat across (a level blade whose base follows the ground along the
    // path): at the middle of a segment, the two sides 3 m either side of the centre line agree
    // to within what the nearest samples (2 m apart) shift along a graded road.
    let path = chain("road-on-eroded-mountainside")[1].1["operations"][0]["pass"]["path"].clone();
    let vertex = |k: usize| (path[k]["x"].as_f64().unwrap() as f32, path[k]["z"].as_f64().unwrap() as f32);
    let ((x0, z0), (x1, z1)) = (vertex(5), vertex(6));
    let (mx, mz, len) = ((x0 + x1) / 2.0, (z0 + z1) / 2.0, ((x1 - x0).powi(2) + (z1 - z0).powi(2)).sqrt());
    let (nx, nz) = (-(z1 - z0) / len, (x1 - x0) / len);
    let cols = 129;
    let at = |h: &[f32], x: f32, z: f32| h[(z / 2.0).round() as usize * cols + (x / 2.0).round() as usize];
    let (l, r) = (at(&after, mx - 3.0 * nx, mz - 3.0 * nz), at(&after, mx + 3.0 * nx, mz + 3.0 * nz));
    let (l0, r0) = (at(&before, mx - 3.0 * nx, mz - 3.0 * nz), at(&before, mx + 3.0 * nx, mz + 3.0 * nz));
    assert!((l - r).abs() < 0.75, "the road's bed tilts across: {l} vs {r} (the slope before: {l0} vs {r0})");
    // Far from the road the eroded terrain is left as it was.
    assert_eq!(at(&after, 240.0, 20.0), at(&before, 240.0, 20.0));
}

#[tokio::test]
async fn rivers_leaving_a_mountain_range_bury_the_plain_s_foot_in_fans() {
    let server = TestServer::start().await;
    let jobs = run_chain(&server, "mountain-front-fans").await;
    let (cut, eroded) = (&jobs[0], &jobs[1]);
    let (before, after) =
        (heights(&server, cut["id"].as_str().unwrap()).await, heights(&server, eroded["id"].as_str().unwrap()).await);
    let cols = 257;
    // The plain is what the blade left at −40 m to −41 m. Per column, rows counted from the
    // first plain row (the foot of the ramp): mean change at 0–10, 10–40 and 40–90 rows out.
    let mut bands = [(0.0f64, 0usize); 3];
    for c in 1..cols - 1 {
        let Some(foot) = (0..cols).find(|&r| before[r * cols + c] <= -39.9) else { continue };
        for (b, (lo, hi)) in [(0, 10), (10, 40), (40, 90)].into_iter().enumerate() {
            for r in (foot + lo..foot + hi).filter(|&r| r < cols - 1) {
                bands[b].0 += f64::from(after[r * cols + c] - before[r * cols + c]);
                bands[b].1 += 1;
            }
        }
    }
    let bands = bands.map(|(sum, n)| sum / n as f64);
    assert!(bands[0] > 4.0 && bands[0] > bands[1] && bands[1] > bands[2], "the plain's bands changed by {bands:?}");
    // What settled from the rivers: the deposition map less the lakes filled and the drain
    // raise (both counted in it, neither carried there).
    let result = &eroded["result"];
    let figure = |k: &str| result[k].as_f64().unwrap();
    let settled = figure("deposited_m3") - figure("lake_fill_m3") - figure("drain_raise_m3");
    let eroded_m3 = figure("eroded_m3");
    assert!(settled > 0.03 * eroded_m3 && settled < eroded_m3, "{result}");
    assert!(figure("drain_raise_m3") < 0.02 * settled, "{result}");
    eprintln!("fans: bands {bands:?}, settled {settled} of {eroded_m3} m³");
}

#[tokio::test]
async fn the_examples_run() {
    let server = TestServer::start().await;
    for name in ["eroded-island", "scree-slopes", "uplift-range"] {
        let job = server.run("erode", &example("erode", name)).await;
        let names: Vec<&str> =
            job["artifacts"].as_array().unwrap().iter().map(|a| a["name"].as_str().unwrap()).collect();
        for want in
            ["mesh.glb", "flow.png", "wear.png", "deposition.png", "splatmap.png", "heightmap.r16", "sequence.json"]
        {
            assert!(names.contains(&want), "{name}: {want} in {names:?}");
        }
        let output = &job["result"]["landform"]["output"];
        if name == "scree-slopes" {
            assert!(output["within_talus_2deg_share"].as_f64().unwrap() > 0.98, "{name}: {output}");
        } else {
            assert_eq!(output["drained_share"], 1.0, "{name}: {output}");
        }
    }
}

/// Each body is answered with its status and a problem naming a field that starts with its
/// field.
async fn assert_refused<const N: usize>(server: &TestServer, cases: [(Value, u16, &str); N]) {
    for (body, status, field) in cases {
        let (got, problem) = server.post("/v1/jobs/erode", &body).await;
        assert_eq!(got, status, "{field}: {problem}");
        let fields: Vec<&str> =
            problem["errors"].as_array().into_iter().flatten().filter_map(|e| e["field"].as_str()).collect();
        assert!(fields.iter().any(|f| f.starts_with(field)), "wanted {field:?}: {problem}");
    }
}

#[tokio::test]
async fn bad_erode_requests_name_their_field() {
    let server = TestServer::start().await;
    let base = json!({"terrain": {"fractal": {"size": 33}}});
    let with = |patch: Value| {
        let mut body = base.clone();
        for (k, v) in patch.as_object().unwrap() {
            body[k] = v.clone();
        }
        body
    };
    let cases = [
        (with(json!({"iterations": 0})), 422, "iterations"),
        (with(json!({"iterations": 10001})), 413, "iterations"),
        (with(json!({"time_step_years": 0.0})), 422, "time_step_years"),
        (with(json!({"sea_level": 1e9})), 422, "sea_level"),
        (with(json!({"hydraulic": {"n": 3.0}})), 422, "hydraulic.n"),
        (with(json!({"hydraulic": {"k": -1.0}})), 422, "hydraulic.k"),
        (with(json!({"hydraulic": {"uplift_m_per_yr": 1.0}})), 422, "hydraulic.uplift_m_per_yr"),
        (with(json!({"thermal": {"diffusivity_m2_per_yr": 11.0}})), 422, "thermal.diffusivity_m2_per_yr"),
        (with(json!({"thermal": {"talus_angle_deg": 90.0}})), 422, "thermal.talus_angle_deg"),
        (with(json!({"thermal": {"diffusivity_m2_per_yr": -1.0}})), 422, "thermal.diffusivity_m2_per_yr"),
        (with(json!({"thermal": {"sweeps": 2}})), 422, "thermal.sweeps"),
        (with(json!({"hydraulic": null, "thermal": false})), 422, "hydraulic"),
        (with(json!({"hydraulic": {"kay": 1.0}})), 422, "hydraulic.kay"),
    ];
    assert_refused(&server, cases).await;
    // A grid × iterations past the time limit (the test server's 120 s) is refused before it
    // runs: 1025² cells × 10 000 iterations × 1.5 updates at 1e8 a second is 158 s.
    let (got, problem) =
        server.post("/v1/jobs/erode", &json!({"terrain": {"fractal": {"size": 1025}}, "iterations": 10000})).await;
    assert_eq!(got, 422, "{problem}");
    assert!(problem.to_string().contains("iterations"), "{problem}");
}

/// The material channel (A) of a job's splat map: what the job itself worked.
async fn worked(server: &TestServer, id: &str) -> Vec<bool> {
    let png = server.artifact(id, "splatmap.png").await;
    let mut reader = png::Decoder::new(std::io::Cursor::new(png)).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    reader.next_frame(&mut buf).unwrap();
    buf.chunks_exact(4).map(|px| px[3] >= 128).collect()
}

/// Erode `shaped` (a road-building job's result) with and without keeping what it worked, and
/// measure the road cells against the heights the road job left: (RMS kept, RMS not kept,
/// mean |change| off the road and its shoulders when kept).
async fn keep_the_road(server: &TestServer, shaped: &str) -> (f64, f64, f64) {
    let road = worked(server, shaped).await;
    let before = heights(server, shaped).await;
    let base = json!({"terrain": {"job": shaped}, "sea_level": -1000.0, "hydraulic": {"k": 2e-4}});
    let mut kept = base.clone();
    kept["keep"] = json!([{"worked_by": {"job": shaped, "shoulder_m": 4.0}}]);
    let with = server.run("erode", &kept).await;
    let without = server.run("erode", &base).await;
    let (after, control) =
        (heights(server, with["id"].as_str().unwrap()).await, heights(server, without["id"].as_str().unwrap()).await);
    let rms = |h: &[f32]| {
        let (sum, n) = road
            .iter()
            .zip(h.iter().zip(&before))
            .filter(|(&r, _)| r)
            .fold((0.0, 0usize), |(s, n), (_, (&a, &b))| (s + f64::from(a - b).powi(2), n + 1));
        assert!(n > 50, "only {n} road cells");
        (sum / n as f64).sqrt()
    };
    // Off the road: every cell more than 10 samples from a road cell (beyond any shoulder).
    let cols = (before.len() as f64).sqrt() as usize;
    let near = |i: usize| {
        let (c, r) = ((i % cols) as isize, (i / cols) as isize);
        (-10..=10).any(|dr| {
            (-10..=10).any(|dc| {
                let (cc, rr) = (c + dc, r + dr);
                cc >= 0
                    && rr >= 0
                    && (cc as usize) < cols
                    && (rr as usize) < cols
                    && road[rr as usize * cols + cc as usize]
            })
        })
    };
    let off: Vec<f64> =
        (0..before.len()).filter(|&i| !near(i)).map(|i| f64::from(after[i] - before[i]).abs()).collect();
    let mean_off = off.iter().sum::<f64>() / off.len() as f64;
    let mass = &with["result"]["mass_balance"];
    assert!(mass["held_m3"].is_number(), "{mass}");
    (rms(&after), rms(&control), mean_off)
}

#[tokio::test]
async fn what_a_bulldozer_and_a_road_designer_laid_down_is_kept_and_the_rest_erodes() {
    let server = TestServer::start().await;
    // A road bulldozed across a range (the example's hillside road).
    let dozed = server.run("bulldoze", &example("bulldoze", "hillside-road")).await;
    let (kept, loose, off) = keep_the_road(&server, dozed["id"].as_str().unwrap()).await;
    eprintln!("bulldozed road: RMS {kept:.3} m kept, {loose:.3} m not; off the road {off:.3} m");
    assert!(kept <= 0.25, "the kept road moved {kept} m RMS");
    assert!(loose > 1.0, "without keeping it the road moved only {loose} m RMS: the test shows nothing");
    assert!(off > 0.2, "off the road the terrain changed by {off} m on average: not eroded");
    // A road laid by deform-terrain.
    let body = json!({
        "seed": 3,
        "terrain": {"fractal": {"size": 65, "cell_size": 2.0, "relief": 40.0, "seed": 11}},
        "constraints": [{"road": {
            "path": [{"x": 16, "z": 20}, {"x": 60, "z": 60}, {"x": 112, "z": 100}],
            "width_m": 6.0,
            "height": {"constant": 20.0}
        }}],
        "max_iterations": 60
    });
    let laid = server.run("deform-terrain", &body).await;
    let (kept, loose, off) = keep_the_road(&server, laid["id"].as_str().unwrap()).await;
    eprintln!("deform-terrain road: RMS {kept:.3} m kept, {loose:.3} m not; off the road {off:.3} m");
    assert!(kept <= 0.25, "the kept road moved {kept} m RMS");
    assert!(loose > kept + 0.2, "without keeping it the road moved only {loose} m RMS: the test shows nothing");
    assert!(off > 0.05, "off the road the terrain changed by {off} m on average: not eroded");
}

#[tokio::test]
async fn a_kept_area_that_does_not_fit_is_refused_naming_its_field() {
    let server = TestServer::start().await;
    let small = server.run("erode", &json!({"terrain": {"fractal": {"size": 33}}, "iterations": 2})).await;
    let id = small["id"].as_str().unwrap();
    let base = json!({"terrain": {"fractal": {"size": 65}}, "iterations": 2});
    let with = |keep: Value| {
        let mut b = base.clone();
        b["keep"] = keep;
        b
    };
    let missing = "01890000-0000-7000-8000-000000000000";
    let cases = [
        (with(json!([{"worked_by": {"job": id}}])), 422, "keep[0].worked_by.job"),
        (with(json!([{"worked_by": {"job": missing}}])), 422, "keep[0].worked_by.job"),
        (with(json!([{"worked_by": {"job": "road"}}])), 422, "keep[0].worked_by.job"),
        (
            with(json!([{"polygon": {"points_m": [{"x": 1, "z": 1}, {"x": 5, "z": 1}]}}])),
            422,
            "keep[0].polygon.points_m",
        ),
        (
            with(
                json!([{"polygon": {"points_m": [{"x": 1, "z": 1}, {"x": 5, "z": 1}, {"x": 3, "z": 4}], "shoulder_m": -1}}]),
            ),
            422,
            "keep[0].polygon.shoulder_m",
        ),
        (
            with(json!((0..17)
                .map(|_| json!({"polygon": {"points_m": [{"x": 1, "z": 1}, {"x": 5, "z": 1}, {"x": 3, "z": 4}]}}))
                .collect::<Vec<_>>())),
            413,
            "keep",
        ),
    ];
    assert_refused(&server, cases).await;
}
