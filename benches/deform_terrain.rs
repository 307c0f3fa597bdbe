//! The seed paper's four results at 257 × 257 (its Figures 6, 1, 7 and 4: the paper took 45,
//! 25, 6 and 75 minutes) with prediction on and off, and the star island at 1025 × 1025. Each
//! configuration first prints its final figures (fitness, iterations, operations, evaluations), so speed
//! and quality can be read side by side. Run with `cargo bench --bench deform_terrain`.
//!
//! First, every example with the limits at their defaults and off (`max_free_change` 1,
//! `max_slope_ratio` 100, `keep_weight` 0), interleaved three times, the median of each and
//! their ratio (issue 50: the defaults ≤ 1.5 × the limits off, the bay mask ≤ 2 ×), then a bay
//! cut into a fractal island's coast the same way. `-- nothing-matches` prints only these and
//! the figures.

use criterion::{criterion_group, criterion_main, Criterion};
use serde_json::Value;

use landform::jobs::Simulation;
use landform::sims::deform_terrain::{DeformTerrain, DeformTerrainParams};

#[path = "../tests/deform_support/bay.rs"]
mod bay;
#[path = "support/mod.rs"]
mod support;

fn example(name: &str) -> (DeformTerrainParams, u64) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("api/deform-terrain").join(name);
    let mut body: Value = serde_json::from_str(&std::fs::read_to_string(path).expect("example")).expect("json");
    let obj = body.as_object_mut().expect("object");
    let seed = obj.remove("seed").and_then(|s| s.as_u64()).unwrap_or(0);
    obj.remove("label");
    (serde_json::from_value(body).expect("parses"), seed)
}

/// The star island scaled to a 1025-sample grid.
fn star_1025() -> (DeformTerrainParams, u64) {
    let (mut p, seed) = example("star-island.json");
    let mut v = serde_json::to_value(&p).unwrap();
    v["terrain"]["fractal"]["size"] = 1025.into();
    for poly in v["constraints"][0]["shape_mask"]["mask"]["polygons_m"].as_array_mut().unwrap() {
        for pt in poly.as_array_mut().unwrap() {
            for axis in ["x", "z"] {
                pt[axis] = (pt[axis].as_f64().unwrap() * 4.0).into();
            }
        }
    }
    p = serde_json::from_value(v).unwrap();
    (p, seed)
}

const EXAMPLES: [&str; 6] =
    ["star-island.json", "s-road.json", "merge-edges.json", "star-island-roads.json", "tileable.json", "terraces.json"];

fn run(p: &DeformTerrainParams, seed: u64) -> Value {
    support::with_context(|ctx| DeformTerrain::run(p, seed, ctx).expect("runs").result)
}

fn report(label: &str, p: &DeformTerrainParams, seed: u64) {
    let started = std::time::Instant::now();
    let r = run(p, seed);
    let figures: Vec<Value> = r["constraints"].as_array().unwrap().to_vec();
    eprintln!(
        "{label}: {:.2} s, fitness {:.3e} (from {:.3e}), {} iterations, {} operations, {} evaluations, stopped {}, sequence.bin {} B vs png {} B, {}",
        started.elapsed().as_secs_f64(),
        r["fitness"].as_f64().unwrap(),
        r["fitness_initial"].as_f64().unwrap(),
        r["iterations"],
        r["operations"],
        r["evaluations"],
        r["stopped"],
        r["sequence_bin"]["bytes"],
        r["heightmap_png_bytes"],
        serde_json::to_string(&figures).unwrap()
    );
}

/// Issue 50's bay, at 257².
fn bay() -> (DeformTerrainParams, u64) {
    let mut body = bay::bay_body(257);
    body.as_object_mut().expect("object").remove("seed");
    (serde_json::from_value(body).expect("parses"), 5)
}

/// The median wall time of three runs of each, interleaved so that a busy moment hits both.
fn limits_on_and_off(name: &str) {
    let (on, seed) = if name == "bay" { bay() } else { example(name) };
    let mut off = on.clone();
    off.max_free_change = 1.0;
    off.max_slope_ratio = 100.0;
    off.keep_weight = 0.0;
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for _ in 0..3 {
        for (p, times) in [(&on, &mut a), (&off, &mut b)] {
            let started = std::time::Instant::now();
            run(p, seed);
            times.push(started.elapsed().as_secs_f64());
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[1]
    };
    let (a, b) = (median(&mut a), median(&mut b));
    eprintln!("{name}: limits at their defaults {a:.2} s, off {b:.2} s, {:.1} ×", a / b);
}

fn bench(c: &mut Criterion) {
    for name in EXAMPLES.iter().chain(&["bay"]) {
        limits_on_and_off(name);
    }
    let mut group = c.benchmark_group("deform_terrain_257");
    group.sample_size(10);
    for name in EXAMPLES {
        for prediction in [true, false] {
            let (mut p, seed) = example(name);
            p.prediction = prediction;
            let label =
                format!("{}/prediction_{}", name.trim_end_matches(".json"), if prediction { "on" } else { "off" });
            report(&label, &p, seed);
            group.bench_function(&label, |b| b.iter(|| run(&p, seed)));
        }
    }
    group.finish();
    let mut group = c.benchmark_group("deform_terrain_1025");
    group.sample_size(10);
    let (p, seed) = star_1025();
    report("star-island-1025", &p, seed);
    group.bench_function("star-island", |b| b.iter(|| run(&p, seed)));
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
