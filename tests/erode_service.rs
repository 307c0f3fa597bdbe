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
async fn a_kept_area_or_painted_map_that_does_not_fit_is_refused_naming_its_field() {
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
    // Painted maps: the shape of the terrain's, one source, values in range, an earlier job
    // on the same extent.
    let map = |m: Value| {
        let mut b = base.clone();
        b["hydraulic"] = json!({"erodibility_map": m["e"], "uplift_map": m["u"]});
        if m["e"].is_null() {
            b["hydraulic"].as_object_mut().unwrap().remove("erodibility_map");
        }
        if m["u"].is_null() {
            b["hydraulic"].as_object_mut().unwrap().remove("uplift_map");
        }
        b
    };
    let square = json!({"png_base64": painted_png(17, 17, |c, _| c > 8)});
    let flat = json!({"png_base64": painted_png(65, 20, |c, _| c > 8)});
    let cases = [
        (map(json!({"e": {"png": flat, "black": 0, "white": 1}})), 422, "hydraulic.erodibility_map.png"),
        (
            map(json!({"e": {"png": square, "splat_of": {"job": id, "channel": "a"}, "black": 0, "white": 1}})),
            422,
            "hydraulic.erodibility_map.splat_of",
        ),
        (map(json!({"e": {"black": 0, "white": 1}})), 422, "hydraulic.erodibility_map.png"),
        (map(json!({"e": {"png": square, "black": 0, "white": 101}})), 422, "hydraulic.erodibility_map.white"),
        (map(json!({"u": {"png": square, "black": -1, "white": 0}})), 422, "hydraulic.uplift_map.black"),
        (map(json!({"u": {"png": square, "black": 0, "white": 0.2}})), 422, "hydraulic.uplift_map.white"),
        (
            map(json!({"u": {"splat_of": {"job": id, "channel": "a"}, "black": 0, "white": 0.001}})),
            422,
            "hydraulic.uplift_map.splat_of.job",
        ),
        (
            map(json!({"u": {"splat_of": {"job": missing, "channel": "r"}, "black": 0, "white": 0.001}})),
            422,
            "hydraulic.uplift_map.splat_of.job",
        ),
        (
            map(json!({"u": {"splat_of": {"job": id, "channel": "x"}, "black": 0, "white": 0.001}})),
            422,
            "hydraulic.uplift_map.splat_of.channel",
        ),
        (
            map(json!({"e": {"png": {"png_sha256": "0".repeat(64)}, "black": 0, "white": 1}})),
            422,
            "hydraulic.erodibility_map.png",
        ),
        (
            with(json!([]))
                .as_object()
                .map(|o| {
                    let mut b = Value::Object(o.clone());
                    b["base_level"] = json!("coast");
                    b
                })
                .unwrap(),
            422,
            "base_level",
        ),
        (
            {
                let mut b = base.clone();
                b["base_level"] = json!("sea");
                b["hydraulic"] = json!(false);
                b
            },
            422,
            "base_level",
        ),
    ];
    assert_refused(&server, cases).await;
    // A map that fits: the sediment an earlier erosion of the same extent laid (its splat
    // map's A), read as erodibility — and a smaller PNG of the same shape, stretched.
    let earlier = server.run("erode", &base).await;
    let fits = map(json!({
        "e": {"splat_of": {"job": earlier["id"], "channel": "a"}, "black": 1, "white": 10},
        "u": {"png": square, "black": 0, "white": 0.001}
    }));
    let done = server.run("erode", &fits).await;
    assert!(done["result"]["mass_balance"]["uplift_m3"].as_f64().unwrap() > 0.0, "{done}");
}

/// Run an erode job and read its heights.
async fn run_heights(server: &TestServer, body: &Value) -> Vec<f32> {
    let job = server.run("erode", body).await;
    heights(server, job["id"].as_str().unwrap()).await
}

/// A `cols × rows` 8-bit grayscale PNG, white where `white(col, row)`, base64-encoded.
fn painted_png(cols: u32, rows: u32, white: impl Fn(u32, u32) -> bool) -> String {
    use base64::Engine as _;
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, cols, rows);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    let pixels: Vec<u8> = (0..rows)
        .flat_map(|r| (0..cols).map(move |c| (r, c)))
        .map(|(r, c)| if white(c, r) { 255 } else { 0 })
        .collect();
    encoder.write_header().unwrap().write_image_data(&pixels).unwrap();
    base64::engine::general_purpose::STANDARD.encode(out)
}

#[tokio::test]
async fn painted_erodibility_and_uplift_act_only_where_painted() {
    let server = TestServer::start().await;
    // A 65² range at 2 m, no sea (the border is the base level), rivers alone: 20 × 500 years.
    let terrain = json!({"fractal": {"size": 65, "cell_size": 2.0, "relief": 40.0, "seed": 11}});
    let body = |hydraulic: Value| {
        json!({"terrain": terrain, "sea_level": -1000.0, "iterations": 20, "time_step_years": 500.0,
               "thermal": false, "hydraulic": hydraulic})
    };
    // The east half (columns 32 on) white: the map's pixel c lies on column c.
    let east = painted_png(65, 65, |c, _| c >= 32);
    let input = run_heights(&server, &body(json!({"k": 0.0}))).await;
    let lowered = |h: &[f32], west: bool| {
        (0..h.len())
            .filter(|&i| {
                let c = i % 65;
                if west {
                    c <= 30
                } else {
                    c >= 33
                }
            })
            .filter(|&i| h[i] < input[i] - 1e-3)
            .count()
    };
    // Erodibility: k × 0 in the west, k × 1 in the east. With k = 0 everywhere nothing is
    // lowered (the input above), so a lowered cell is one the map let the rivers cut.
    let control = run_heights(&server, &body(json!({"k": 2e-4}))).await;
    let map = json!({"png": {"png_base64": east}, "black": 0.0, "white": 1.0});
    let painted = server.run("erode", &body(json!({"k": 2e-4, "erodibility_map": map}))).await;
    let after = heights(&server, painted["id"].as_str().unwrap()).await;
    let (west, east_cut, west_control) = (lowered(&after, true), lowered(&after, false), lowered(&control, true));
    eprintln!("erodibility map: {west} western cells lowered (without the map {west_control}), {east_cut} eastern");
    assert_eq!(west, 0, "cells where k was painted 0 were cut");
    assert!(west_control > 100, "without the map only {west_control} western cells were cut: the test shows nothing");
    assert!(east_cut > 100, "only {east_cut} eastern cells were cut");
    // Uplift: 2 mm/yr painted in the east over 10 000 years (k = 0, so nothing wears it):
    // 20 m on every eastern land cell, none in the west; the border stays (base level).
    let map = json!({"png": {"png_base64": east}, "black": 0.0, "white": 0.002});
    let raised = server.run("erode", &body(json!({"k": 0.0, "uplift_map": map}))).await;
    let after = heights(&server, raised["id"].as_str().unwrap()).await;
    let inner = |i: usize| (1..64).contains(&(i % 65)) && (1..64).contains(&(i / 65));
    let rise = |i: usize| f64::from(after[i] - input[i]);
    let east_ok =
        (0..after.len()).filter(|&i| inner(i) && i % 65 >= 32).filter(|&i| (rise(i) - 20.0).abs() < 0.01).count();
    // The west rises only where the rising east dams its rivers: lakes filled to their spill
    // (k = 0: nothing cuts through), which the mass balance counts as its drain raise.
    let west_lowered = (0..after.len()).filter(|&i| i % 65 < 32 && rise(i) < -1e-3).count();
    let west_raised: f64 = (0..after.len()).filter(|&i| i % 65 < 32).map(|i| rise(i).max(0.0)).sum::<f64>() * 4.0;
    let drain_raise = raised["result"]["mass_balance"]["drain_raise_m3"].as_f64().unwrap();
    eprintln!("uplift map: {east_ok} of 2016 eastern cells rose 20 m; the west raised {west_raised:.1} m³ (drain raise {drain_raise:.1} m³)");
    assert!(east_ok >= 2000, "only {east_ok} of 2016 eastern cells rose by the painted 20 m");
    assert_eq!(west_lowered, 0, "western cells were lowered with k = 0");
    assert!(
        west_raised <= drain_raise * 1.001 + 1.0,
        "the west rose by {west_raised} m³, more than the lakes' {drain_raise}"
    );
    // The mass balance's uplift by hand: 63 rows × 32 columns × 20 m × 4 m².
    let uplift = raised["result"]["mass_balance"]["uplift_m3"].as_f64().unwrap();
    assert!((uplift - 161_280.0).abs() < 1.0, "uplift_m3 {uplift}, by hand 161 280");
    // The replay reads the stored map again, to the same bytes.
    let id = raised["id"].as_str().unwrap();
    let (status, replay) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({})).await;
    assert!(status == 201 || status == 202, "{replay}");
    let replayed = server.wait_done(replay["id"].as_str().unwrap()).await;
    assert_eq!(artifact_hashes(&replayed), artifact_hashes(&raised), "the replay differs");
}

/// Volume (in metres over cells) that a Priority-Flood from `outlets` raises `h` by: zero when
/// every other cell has a way down to an outlet that never climbs.
fn flood_depth(h: &[f32], cols: usize, outlets: &[bool]) -> f64 {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let rows = h.len() / cols;
    let mut level: Vec<f64> = h.iter().map(|&x| f64::from(x)).collect();
    let mut closed = outlets.to_vec();
    let mut heap: BinaryHeap<Reverse<(i64, usize)>> =
        (0..h.len()).filter(|&i| outlets[i]).map(|i| Reverse(((level[i] * 1e6) as i64, i))).collect();
    let mut added = 0.0;
    while let Some(Reverse((_, i))) = heap.pop() {
        let (c, r) = ((i % cols) as isize, (i / cols) as isize);
        for (dc, dr) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
            let (nc, nr) = (c + dc, r + dr);
            if nc < 0 || nr < 0 || nc as usize >= cols || nr as usize >= rows {
                continue;
            }
            let n = nr as usize * cols + nc as usize;
            if closed[n] {
                continue;
            }
            closed[n] = true;
            if level[n] < level[i] {
                added += level[i] - level[n];
                level[n] = level[i];
            }
            heap.push(Reverse(((level[n] * 1e6) as i64, n)));
        }
    }
    added
}

#[tokio::test]
async fn the_base_level_is_the_border_and_sea_the_sea_or_a_closed_basin_s_floor() {
    let server = TestServer::start().await;
    // A 65² range at 2 m whose lowest fifth is sea, land on every border.
    let terrain = json!({"fractal": {"size": 65, "cell_size": 2.0, "relief": 40.0, "seed": 5}});
    let run = |base: &str, sea: f64| {
        let body = json!({"terrain": terrain, "sea_level": sea, "iterations": 30, "base_level": base,
                          "hydraulic": {"k": 2e-4}});
        let server = &server;
        async move { server.run("erode", &body).await }
    };
    let input =
        run_heights(&server, &json!({"terrain": terrain, "iterations": 1, "hydraulic": {"k": 0.0}, "thermal": false}))
            .await;
    let mut sorted = input.clone();
    sorted.sort_by(f32::total_cmp);
    let sea = f64::from(sorted[sorted.len() / 5]);
    let border = |i: usize| i % 65 == 0 || i / 65 == 0 || i % 65 == 64 || i / 65 == 64;
    // The sea only: every land cell has a way down to the sea, none to the land border.
    let mut depths = Vec::new();
    for base in ["all", "sea"] {
        let job = run(base, sea).await;
        let h = heights(&server, job["id"].as_str().unwrap()).await;
        let sea_cells: Vec<bool> = h.iter().map(|&x| f64::from(x) <= sea).collect();
        assert!(sea_cells.iter().any(|&s| s), "{base}: no sea left");
        depths.push(flood_depth(&h, 65, &sea_cells));
        let land_border_cut =
            (0..h.len()).filter(|&i| border(i) && h[i] as f64 > sea && h[i] < input[i] - 1e-3).count();
        eprintln!("base_level {base}: flooding from the sea alone adds {:.3} m over cells; {land_border_cut} land border cells cut", depths.last().unwrap());
        if base == "all" {
            assert_eq!(land_border_cut, 0, "the border is base level: rivers do not cut it");
        }
    }
    let eps_budget = 1e-3 * 65.0 * 65.0;
    assert!(depths[1] <= eps_budget, "base_level sea left {} m of depressions against the sea", depths[1]);
    assert!(
        depths[0] > 10.0 * eps_budget,
        "base_level all drains to the border too: {} m (the test shows nothing)",
        depths[0]
    );
    // A closed basin: nothing leaves, the floor gathers a level bed, everything drains to it.
    let job = run("none", -1000.0).await;
    let h = heights(&server, job["id"].as_str().unwrap()).await;
    let mass = &job["result"]["mass_balance"];
    assert_eq!(mass["exported_m3"].as_f64(), Some(0.0), "{mass}");
    assert_eq!(mass["settled_in_sea_by_rivers_m3"].as_f64(), Some(0.0), "{mass}");
    assert!(mass["eroded_m3"].as_f64().unwrap() > 100.0, "{mass}");
    let low = h.iter().copied().fold(f32::INFINITY, f32::min);
    let floor = h.iter().position(|&x| x == low).unwrap();
    let outlet: Vec<bool> = (0..h.len()).map(|i| i == floor).collect();
    let depth = flood_depth(&h, 65, &outlet);
    let bed = h.iter().filter(|&&x| x - low < 0.01).count();
    eprintln!(
        "base_level none: flooding from the floor adds {depth:.3} m; a bed of {bed} cells within 1 cm of the floor"
    );
    assert!(depth <= eps_budget, "the closed basin has {depth} m of depressions that do not drain to its floor");
    assert!(bed >= 4, "the floor holds no bed of sediment ({bed} cells)");
    // The sea only on a terrain without sea: refused, naming the field.
    let body = json!({"terrain": terrain, "sea_level": -1000.0, "iterations": 2, "base_level": "sea"});
    let job = server.submit("erode", &body).await;
    let done = server.wait_done(job["id"].as_str().unwrap()).await;
    assert_eq!(done["status"], "failed", "{done}");
    assert!(done.to_string().contains("base_level"), "{done}");
}
