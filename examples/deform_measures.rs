//! deform-terrain measured as issue 50 asks, in release, on the examples and requests of our
//! own: `cargo run --release --example deform_measures -- [what]`, `what` one of
//! `earthworks`, `pits` (and the coast), `conflict`, `examples`, `all`. Figures for people; the same checks, smaller, are
//! `tests/deform_earthworks.rs`.

use std::time::Instant;

use serde_json::{json, Value};

use landform::jobs::Simulation;
use landform::sims::deform_terrain::{DeformTerrain, DeformTerrainParams};
use landform::terrain::resolve;
use landform::validate::Limits;

#[path = "../tests/deform_support/bay.rs"]
mod bay;
#[path = "../tests/deform_support/measures.rs"]
mod measures;
#[path = "../benches/support/mod.rs"]
mod support;
use measures::*;

fn example(name: &str) -> Value {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("api/deform-terrain").join(name);
    serde_json::from_str(&std::fs::read_to_string(path).expect("example")).expect("json")
}

struct Run {
    input: Vec<f64>,
    out: Vec<f64>,
    cols: usize,
    rows: usize,
    cell_m: f64,
    result: Value,
    secs: f64,
}

impl Run {
    fn grids(&self) -> (Grid<'_>, Grid<'_>) {
        let g = |h| Grid { h, cols: self.cols, rows: self.rows, cell_m: self.cell_m };
        (g(&self.input), g(&self.out))
    }
}

fn run(mut body: Value) -> Run {
    let obj = body.as_object_mut().expect("object");
    let seed = obj.remove("seed").and_then(|s| s.as_u64()).unwrap_or(0);
    obj.remove("label");
    let p: DeformTerrainParams = serde_json::from_value(body).expect("parses");
    let input = resolve(&p.terrain, &support::NoStore, &Limits::default()).expect("terrain");
    let t = Instant::now();
    let outcome = support::with_context(|ctx| DeformTerrain::run(&p, seed, ctx).expect("runs"));
    let secs = t.elapsed().as_secs_f64();
    let npy = outcome.artifacts.iter().find(|a| a.name == "heightfield.npy").expect("npy");
    let hf = landform::export::read_heightfield_npy(&npy.bytes, input.cell_size_m).expect("npy");
    Run {
        input: input.heights_m.iter().map(|&v| v as f64).collect(),
        out: hf.heights_m.iter().map(|&v| v as f64).collect(),
        cols: hf.cols,
        rows: hf.rows,
        cell_m: hf.cell_size_m as f64,
        result: outcome.result,
        secs,
    }
}

fn points(v: &Value) -> Vec<(f64, f64)> {
    v.as_array().unwrap().iter().map(|p| (p["x"].as_f64().unwrap(), p["z"].as_f64().unwrap())).collect()
}

/// The S-road, a switchback graded 8 % and a building pad beside a road.
fn earthwork_cases() -> Vec<(&'static str, Value)> {
    let s_road = example("s-road.json");
    let hill =
        json!({"fractal": {"size": 257, "cell_size": 1.0, "relief": 120.0, "octaves": 8, "roughness": 0.5, "seed": 7}});
    let switchback = json!({
        "seed": 3, "terrain": hill.clone(),
        "constraints": [{"road": {
            "path": [{"x": 40, "z": 40}, {"x": 210, "z": 60}, {"x": 60, "z": 110}, {"x": 210, "z": 160}, {"x": 50, "z": 215}],
            "width_m": 5.0, "height": {"profile": {"max_gradient_percent": 8.0}}}}]
    });
    let pad = json!({
        "seed": 4, "terrain": hill.clone(),
        "constraints": [
            {"road": {"path": [{"x": 20, "z": 128}, {"x": 236, "z": 128}], "width_m": 6.0,
                      "height": {"profile": {"max_gradient_percent": 6.0}}}},
            {"terraces": {"regions": [{"polygon_m": [{"x": 100, "z": 145}, {"x": 150, "z": 145}, {"x": 150, "z": 180}, {"x": 100, "z": 180}], "level_m": 60.0}]}}
        ]
    });
    // The pad at the input's height on the road beside it, so both can be met.
    let mut pad = pad;
    let input = resolve(&serde_json::from_value(hill).unwrap(), &support::NoStore, &Limits::default()).unwrap();
    let middle = input.heights_m[128 * input.cols + 125] as f64;
    pad["constraints"][1]["terraces"]["regions"][0]["level_m"] = json!(middle.round());
    vec![("s-road", s_road), ("switchback-8%", switchback), ("pad-beside-road", pad)]
}

fn earthwork_figures() {
    let (cut, fill) = (degrees_of(1.5), degrees_of(2.0));
    for (name, body) in earthwork_cases() {
        let mut roads = Vec::new();
        let mut pads = Vec::new();
        for c in body["constraints"].as_array().unwrap() {
            if let Some(r) = c.get("road") {
                roads.push((points(&r["path"]), r["width_m"].as_f64().unwrap()));
            }
            if let Some(t) = c.get("terraces") {
                for region in t["regions"].as_array().unwrap() {
                    pads.push(points(&region["polygon_m"]));
                }
            }
        }
        let r = run(body);
        let (a, b) = r.grids();
        let distance = |x: f64, z: f64| {
            let road = roads.iter().map(|(p, w)| (to_path(p, x, z) - w / 2.0).max(0.0));
            let pad = pads.iter().map(|p| to_polygon(p, x, z));
            road.chain(pad).fold(f64::INFINITY, f64::min)
        };
        let e = earthworks(&a, &b, distance, 25.0, 1.0, cut, fill, 5.0);
        println!(
            "{name}: {:.2} s, {} iterations, stopped {}; moved within 25 m: {}, steeper than cut {cut:.1}°/fill {fill:.1}° + 5°: {:.1} % (cut {}, fill {}), steepest {:.1}°; limits {}",
            r.secs,
            r.result["iterations"],
            r.result["stopped"],
            e.moved,
            100.0 * e.steep_share(),
            e.steep_cut,
            e.steep_fill,
            e.steepest_deg,
            r.result["limits"]
        );
        println!("    constraints {}", r.result["constraints"]);
        if let Some(c) = r.result.get("conflicts") {
            println!("    conflicts {c}");
        }
    }
}

fn pits() {
    for name in ["star-island.json", "star-island-roads.json", "bay"] {
        let body = if name == "bay" { bay::bay_body(257) } else { example(name) };
        let r = run(body);
        let (a, b) = r.grids();
        let level = r.result["constraints"]
            .as_array()
            .unwrap()
            .iter()
            .find_map(|c| c["water_level_m"].as_f64())
            .expect("a mask's water level");
        let (ra, na) = coast_roughness(&a, level, 2.0);
        let (rb, nb) = coast_roughness(&b, level, 2.0);
        println!(
            "{name}: {:.2} s; sea in closed pits deeper than 0.5 m: input {:.2} %, result {:.2} % (level {level:.2} m); coast high-pass roughness (±2 cells) input {ra:.3} cells over {na} points, result {rb:.3} over {nb} ({:.2} ×)",
            r.secs,
            100.0 * sea_pit_share(&a, level, 0.5),
            100.0 * sea_pit_share(&b, level, 0.5),
            rb / ra
        );
    }
}

fn conflict() {
    let hill = json!({"fractal": {"size": 129, "cell_size": 1.0, "relief": 40.0, "seed": 11}});
    let body = json!({
        "seed": 1, "terrain": hill,
        "constraints": [
            {"road": {"path": [{"x": 10, "z": 64}, {"x": 118, "z": 64}], "width_m": 6.0, "height": {"constant": 20.0}}},
            {"points": {"points": [{"x": 64, "z": 73, "height": 60.0}]}}
        ]
    });
    let r = run(body);
    let (_, b) = r.grids();
    let road_err = (0..r.cols)
        .filter(|&c| (10..=118).contains(&c))
        .flat_map(|c| (61..=67).map(move |z| (c, z)))
        .map(|(c, z)| (b.h[z * r.cols + c] - 20.0).abs())
        .fold(0.0f64, f64::max);
    println!(
        "conflict: {:.2} s; road's largest error {road_err:.3} m; point at {:.2} m (asked 60); conflicts {}",
        r.secs,
        b.h[73 * r.cols + 64],
        r.result.get("conflicts").unwrap_or(&Value::Null)
    );
}

/// Every example: time, where the search stopped, how much the projection moved, spikes.
fn examples() {
    for name in ["star-island", "s-road", "merge-edges", "star-island-roads", "tileable", "terraces"] {
        let r = run(example(&format!("{name}.json")));
        let (a, b) = r.grids();
        println!(
            "{name}: {:.2} s, {} iterations, stopped {}; projection moved {} samples, up to {:.1} m; spikes (4 m off the 5 × 5 median) input {}, result {}; conflicts {}",
            r.secs,
            r.result["iterations"],
            r.result["stopped"],
            r.result["limits"]["held"]["samples_moved"],
            r.result["limits"]["held"]["max_change_m"].as_f64().unwrap_or(0.0),
            spikes(&a, 4.0),
            spikes(&b, 4.0),
            r.result["conflicts"].as_array().map_or(0, |c| c.len())
        );
    }
}

fn main() {
    let what = std::env::args().nth(1).unwrap_or_else(|| "all".into());
    if what == "earthworks" || what == "all" {
        earthwork_figures();
    }
    if what == "pits" || what == "all" {
        pits();
    }
    if what == "conflict" || what == "all" {
        conflict();
    }
    if what == "examples" || what == "all" {
        examples();
    }
}
