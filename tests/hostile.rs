//! Requests built to blow up each derived size and each long loop within today's caps, sent to
//! a server with a 1 GiB memory budget and a short time limit. Each must be refused at
//! submission (413 or 422 naming a field) or end within its time limit, and the server must
//! answer throughout. Add to it whenever a new way to hurt the service is found.

mod common;

use std::time::{Duration, Instant};

use base64::Engine as _;
use common::server::{Options, TestServer};
use serde_json::{json, Value};

const BUDGET: u64 = 1 << 30;
const TIME_LIMIT_S: u64 = 10;
/// A stopped job ends at its next check: well within this of its limit.
const GRACE_S: f64 = 4.0;

enum Expect {
    /// Refused at submission with this status, naming a field that starts with this.
    Refused(u16, &'static str),
    /// Refused at submission, or accepted and ended within the time limit.
    Bounded,
}

struct Case {
    kind: &'static str,
    name: &'static str,
    body: Value,
    expect: Expect,
}

fn case(kind: &'static str, name: &'static str, body: Value, expect: Expect) -> Case {
    Case { kind, name, body, expect }
}

fn mounds(n: usize, radius_m: f64) -> Vec<Value> {
    (0..n)
        .map(|i| {
            json!({"primitive": {"shape": {"mound": {"center": {"x": (i * 37) % 1000, "z": (i * 53) % 1000},
                "radius_m": radius_m, "height_m": 0.1}}, "operator": "add"}})
        })
        .collect()
}

fn png_base64(width: u32, height: u32, pixel: impl Fn(u32, u32) -> u8) -> String {
    let mut out = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut out, width, height);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Eight);
        let data: Vec<u8> =
            (0..height).flat_map(|y| (0..width).map(move |x| (x, y))).map(|(x, y)| pixel(x, y)).collect();
        encoder.write_header().unwrap().write_image_data(&data).unwrap();
    }
    base64::engine::general_purpose::STANDARD.encode(out)
}

fn bulldoze_cases() -> Vec<Case> {
    let zigzag: Vec<Value> =
        (0..2000).map(|i| json!({"x": if i % 2 == 0 { 0 } else { 1024 }, "z": i % 1024})).collect();
    vec![
        case(
            "bulldoze",
            "the most primitives, each over the whole grid",
            json!({"terrain": {"fractal": {"size": 1025}}, "operations": mounds(60_000, 1e6)}),
            Expect::Refused(422, "operations"),
        ),
        case(
            "bulldoze",
            "a blade profile of 5000 points",
            json!({"terrain": {"fractal": {"size": 65}}, "operations": [{"pass": {
                "path": [{"x": 0, "z": 0}, {"x": 60, "z": 60}],
                "blade": {"width_m": 4, "profile": (0..5000).map(|i| json!([-1.0 + 2.0 * i as f64 / 4999.0, 0.0])).collect::<Vec<_>>()},
                "operator": "replace"}}]}),
            Expect::Refused(422, "operations[0].pass.blade.profile"),
        ),
        case(
            "bulldoze",
            "a resolution that resamples past the grid cap",
            json!({"terrain": {"fractal": {"size": 1025}}, "resolution": 0.01, "operations": []}),
            Expect::Refused(413, "resolution"),
        ),
        case(
            "bulldoze",
            "corner-to-corner zig-zag with a blade as wide as the terrain",
            json!({"terrain": {"fractal": {"size": 1025}}, "operations": [{"pass": {
                "path": zigzag, "blade": {"width_m": 5000, "angle_deg": 79}, "operator": "replace"}}]}),
            Expect::Bounded,
        ),
    ]
}

fn deform_cases() -> Vec<Case> {
    let preserve: Vec<Value> = (0..32).map(|_| json!({"preserve": {}})).collect();
    let roads: Vec<Value> = (0..32)
        .map(|r| {
            let path: Vec<Value> =
                (0..256).map(|i| json!({"x": if i % 2 == 0 { 0 } else { 1024 }, "z": (i * 4 + r) % 1024})).collect();
            json!({"road": {"path": path, "width_m": 400, "height": {"constant": 10}}})
        })
        .collect();
    vec![
        case(
            "deform-terrain",
            "32 constraints, each with full-grid arrays, on the largest grid",
            json!({"terrain": {"fractal": {"size": 1025}}, "constraints": preserve}),
            Expect::Refused(413, "constraints"),
        ),
        case(
            "deform-terrain",
            "a candidate vertex on every cell",
            json!({"terrain": {"fractal": {"size": 1025}}, "constraints": [{"preserve": {}}], "coarse_spacing_cells": 1, "min_spacing_cells": 1, "radii": 32}),
            Expect::Refused(422, "coarse_spacing_cells"),
        ),
        case(
            "deform-terrain",
            "32 zig-zag roads as wide as the terrain",
            json!({"terrain": {"fractal": {"size": 1025}}, "constraints": roads}),
            Expect::Bounded,
        ),
        case(
            "deform-terrain",
            "the most iterations and the largest batch with the widest kernels",
            json!({"terrain": {"fractal": {"size": 1025}}, "constraints": [{"preserve": {}}],
                "max_iterations": 3900, "batch": 256, "radii": 32, "min_radius_cells": 480, "max_radius_cells": 512}),
            Expect::Bounded,
        ),
        case(
            "deform-terrain",
            "the largest grid searched for up to 2000 iterations of 16",
            json!({"terrain": {"fractal": {"size": 1025}}, "constraints": [{"points": {"points": [{"x": 500, "z": 500, "height": 300}]}}],
                "max_iterations": 2000, "batch": 16, "epsilon": 0}),
            Expect::Bounded,
        ),
    ]
}

fn weather_cases() -> Vec<Case> {
    let checkerboard = png_base64(1024, 1024, |x, y| if (x + y) % 2 == 0 { 255 } else { 0 });
    let comb: Vec<Value> = (0..1024)
        .map(|i| {
            let x = -50.0 + 100.0 * (i / 2) as f64 / 511.0;
            json!([x, if (i / 2) % 2 == 0 { -50.0 } else { 50.0 } * if i % 2 == 0 { 1.0 } else { -1.0 }])
        })
        .collect();
    vec![
        case(
            "weather-column",
            "a grid at the voxel cap",
            json!({"grid": {"x": 4096, "y": 12, "z": 4096}, "column": {"profile": {"box": {}}}, "layers": [{"top_m": 1.0}]}),
            // The column fills the grid: its surface (the mesh) is what would not fit.
            Expect::Refused(413, "column"),
        ),
        case(
            "weather-column",
            "a checkerboard joint map: a surface on every voxel",
            json!({"grid": {"x": 1024, "y": 48, "z": 1024}, "voxel_size_m": 0.1,
                "column": {"profile": {"joint_map": {"png_base64": checkerboard}}}, "layers": [{"top_m": 100.0}]}),
            Expect::Refused(413, "column"),
        ),
        case(
            "weather-column",
            "event-based weathering with the largest bubble to half the volume",
            json!({"grid": {"x": 200, "y": 200, "z": 200}, "column": {"profile": {"box": {}}, "floating": true},
                "layers": [{"top_m": 100.0, "bubble": {"sphere": {"radius": 8.0}}}],
                "update": "event_based", "stop_at_fraction": 0.01, "steps": 65000}),
            Expect::Bounded,
        ),
        case(
            "weather-column",
            "a comb-shaped polygon of 1024 points",
            json!({"grid": {"x": 1024, "y": 64, "z": 1024}, "voxel_size_m": 0.1,
                "column": {"profile": {"polygon": {"points_m": comb}}}, "layers": [{"top_m": 100.0}],
                "mesh": {"smoothing_iterations": 200}}),
            Expect::Refused(413, "column"),
        ),
        case(
            "weather-column",
            "a large column weathered for the most steps, smoothed the most",
            json!({"grid": {"x": 400, "y": 64, "z": 400}, "column": {"profile": {"box": {}}},
                "layers": [{"top_m": 100.0, "bubble": {"sphere": {"radius": 4.0}}}], "steps": 65000,
                "stop_at_fraction": 0.0, "mesh": {"smoothing_iterations": 200}}),
            Expect::Bounded,
        ),
    ]
}

fn cave_cases() -> Vec<Case> {
    vec![
        case(
            "grow-cave",
            "a chamber a millimetre wide and ten kilometres deep",
            json!({"chamber": {"width_m": 0.001, "depth_m": 10000, "height_m": 5, "samples": 513,
                "roof": {"relief_m": 1}, "floor": {"relief_m": 1}}, "sites": {"scatter": {"count": 10}}}),
            Expect::Bounded,
        ),
        case(
            "grow-cave",
            "the most sites, rings and segments",
            json!({"chamber": {"width_m": 10000, "depth_m": 10000, "height_m": 100},
                "sites": {"scatter": {"count": 5000}}, "rings": 256, "segments": 64}),
            Expect::Refused(413, "rings"),
        ),
        case(
            "grow-cave",
            "5000 sites that cannot keep their spacing",
            json!({"chamber": {"width_m": 10, "depth_m": 10, "height_m": 3},
                "sites": {"scatter": {"count": 5000, "min_spacing_m": 1000}}, "rings": 8, "segments": 3}),
            Expect::Bounded,
        ),
    ]
}

fn coast_cases() -> Vec<Case> {
    let island = json!({"fractal": {"size": 257, "island": true, "relief": 120}});
    vec![
        case(
            "carve-coast",
            "a warp as tall as the cap allows",
            json!({"terrain": island, "sea_level": 0, "warp": {"amplitude_m": 10000, "frequency_per_m": 1}}),
            Expect::Refused(413, "voxel_size_m"),
        ),
        case(
            "carve-coast",
            "a voxel too small to count",
            json!({"terrain": island, "sea_level": 0, "voxel_size_m": 1e-20}),
            Expect::Refused(413, "voxel_size_m"),
        ),
        case(
            "carve-coast",
            "a seed scan of 200 km in millimetre steps",
            json!({"terrain": {"fractal": {"size": 33, "cell_size": 0.001, "relief": 0.0}}, "sea_level": 0,
                "erosion": {"seed_elevation_range": [-100000, 100000]}}),
            Expect::Refused(422, "erosion"),
        ),
        case(
            "carve-coast",
            "every column a seed, each growing the most spheres",
            json!({"terrain": island, "sea_level": 0, "erosion": {"seed_min_slope": 0, "seed_acceptance_probability": 1,
                "seed_elevation_range": [-200, 200], "growth_step_range": [64, 64], "growth_sphere_range": [64, 64]}}),
            Expect::Bounded,
        ),
        case(
            "carve-coast",
            "spheres as large as allowed, so every bin holds them all",
            json!({"terrain": island, "sea_level": 0, "erosion": {"seed_min_slope": 0, "seed_acceptance_probability": 1,
                "seed_elevation_range": [-200, 200], "growth_step_range": [64, 64], "growth_sphere_range": [64, 64],
                "radius_range": [0.5, 1000]}}),
            Expect::Bounded,
        ),
        case(
            "carve-coast",
            "a large island carved with the most passes",
            json!({"terrain": {"fractal": {"size": 385, "island": true, "relief": 120}}, "sea_level": 0, "passes": 16}),
            Expect::Bounded,
        ),
    ]
}

async fn alive(server: &TestServer) {
    let res = server.client.get(server.url("/healthz")).timeout(Duration::from_secs(5)).send().await;
    assert!(res.is_ok_and(|r| r.status() == 200), "the server stopped answering");
}

async fn check(cases: Vec<Case>) {
    let server = TestServer::start_with(Options {
        job_timeout_secs: TIME_LIMIT_S,
        max_grid_cells: 4097 * 4097,
        max_body_bytes: 64 << 20,
        extra: vec!["--memory-budget".into(), BUDGET.to_string(), "--max-voxels".into(), (192u64 << 20).to_string()],
        ..Options::default()
    })
    .await;
    let mut accepted = Vec::new();
    for c in cases {
        let (status, body) = server.post(&format!("/v1/jobs/{}", c.kind), &c.body).await;
        let field = body["errors"][0]["field"].as_str().unwrap_or_default().to_string();
        println!("{} / {}: {status} {field}", c.kind, c.name);
        match (&c.expect, status) {
            (Expect::Refused(want, prefix), got) => {
                assert_eq!(got, *want, "{} / {}: {body}", c.kind, c.name);
                assert!(field.starts_with(prefix), "{} / {}: field {field:?}, wanted {prefix}…", c.kind, c.name);
            }
            (Expect::Bounded, 202) => accepted.push((c.name, body["id"].as_str().unwrap().to_string())),
            (Expect::Bounded, 413 | 422) => assert!(!field.is_empty(), "{} / {}: {body}", c.kind, c.name),
            (Expect::Bounded, other) => panic!("{} / {}: {other} {body}", c.kind, c.name),
        }
        alive(&server).await;
    }
    // Every accepted job ends within its limit, whatever it is; the server answers meanwhile.
    let started = Instant::now();
    for (name, id) in accepted {
        loop {
            alive(&server).await;
            let (_, job) = server.get_json(&format!("/v1/jobs/{id}")).await;
            if matches!(job["status"].as_str(), Some("succeeded" | "failed" | "cancelled")) {
                let ran = seconds_between(&job["started_at"], &job["finished_at"]);
                println!("{name}: {} after {ran:.1} s", job["status"]);
                assert!(ran <= TIME_LIMIT_S as f64 + GRACE_S, "{name} ran {ran:.1} s: {job}");
                break;
            }
            assert!(started.elapsed() < Duration::from_secs(600), "{name} never ended");
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    }
}

fn seconds_between(a: &Value, b: &Value) -> f64 {
    let t = |v: &Value| chrono::DateTime::parse_from_rfc3339(v.as_str().unwrap_or_default()).ok();
    match (t(a), t(b)) {
        (Some(a), Some(b)) => (b - a).num_milliseconds() as f64 / 1000.0,
        _ => 0.0,
    }
}

#[tokio::test]
async fn hostile_bulldoze_requests_are_refused_or_bounded() {
    check(bulldoze_cases()).await;
}

#[tokio::test]
async fn hostile_deform_requests_are_refused_or_bounded() {
    check(deform_cases()).await;
}

#[tokio::test]
async fn hostile_weathering_requests_are_refused_or_bounded() {
    check(weather_cases()).await;
}

#[tokio::test]
async fn hostile_cave_requests_are_refused_or_bounded() {
    check(cave_cases()).await;
}

#[tokio::test]
async fn hostile_coast_requests_are_refused_or_bounded() {
    check(coast_cases()).await;
}

/// Levels of detail and tiles stop at the job's limit or a cancel like every other stage: a
/// carved island with three levels (which took 28–76 s under a 5 s limit before) ends within
/// 2 s of its limit, and within 2 s of a cancel during its levels (meshoptimizer's simplifier,
/// which cannot be interrupted, runs on a thread the cancel leaves behind).
#[tokio::test]
async fn levels_of_detail_stop_at_the_time_limit_and_on_cancel() {
    const LIMIT_S: u64 = 5;
    let body = json!({"terrain": {"fractal": {"size": 257, "island": true, "relief": 120}}, "sea_level": 0,
        "lods": [0.002, 0.008, 0.032]});
    let server = TestServer::start_with(Options { job_timeout_secs: LIMIT_S, ..Options::default() }).await;
    let job = server.submit("carve-coast", &body).await;
    let done = server.wait_done(job["id"].as_str().unwrap()).await;
    let ran = seconds_between(&done["started_at"], &done["finished_at"]);
    println!("carve-coast with levels under a {LIMIT_S} s limit: {} after {ran:.1} s", done["status"]);
    assert_eq!(done["status"], "failed", "{done}");
    assert!(ran <= LIMIT_S as f64 + 2.0, "ran {ran:.1} s past a {LIMIT_S} s limit");

    let server = TestServer::start_with(Options { job_timeout_secs: 300, ..Options::default() }).await;
    let id = server.submit("carve-coast", &body).await["id"].as_str().unwrap().to_string();
    // Into its levels of detail: past the stage's report, and past writing the full mesh
    // (1.4 s on this machine, 4 s under load), well inside the first level (tens of seconds).
    let started = Instant::now();
    loop {
        let (_, job) = server.get_json(&format!("/v1/jobs/{id}")).await;
        if job["progress"]["message"].as_str().is_some_and(|m| m.contains("levels of detail")) {
            break;
        }
        assert!(!job["status"].as_str().is_some_and(|s| s != "queued" && s != "running"), "{job}");
        assert!(started.elapsed() < Duration::from_secs(240), "never reached its levels of detail: {job}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    tokio::time::sleep(Duration::from_secs(4)).await;
    let asked = Instant::now();
    let res = server.client.post(server.url(&format!("/v1/jobs/{id}/cancel"))).send().await.unwrap();
    assert_eq!(res.status(), 200);
    let done = server.wait_done(&id).await;
    let waited = asked.elapsed().as_secs_f64();
    println!("cancelled in its levels of detail: {} {waited:.2} s after the cancel", done["status"]);
    assert_eq!(done["status"], "cancelled", "{done}");
    assert!(waited <= 2.0, "ended {waited:.2} s after the cancel");
}
