//! The erode kind's speed and memory: a 1025² terrain, 100 iterations of hydraulic + thermal
//! (target ≤ 10 s on a 2-core machine), and the 257² island with the defaults (target ≤ 1 s),
//! each as the erosion alone and as the whole job (maps, measures, meshes and images), with the
//! erosion's peak heap per cell (target ≤ 64 B). Run with `cargo bench --bench erode`.

use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use serde_json::json;

use landform::jobs::Simulation;
use landform::sims::erode::{Erode, ErodeParams, Erosion};
use landform::terrain::{resolve, Heightfield};

#[path = "support/mod.rs"]
mod support;

#[path = "support/counting_alloc.rs"]
mod counting_alloc;

#[global_allocator]
static ALLOCATOR: counting_alloc::Counting = counting_alloc::Counting;

fn params(size: u32, iterations: u32) -> ErodeParams {
    serde_json::from_value(json!({
        "terrain": {"fractal": {"size": size, "cell_size": 2.0, "relief": 120.0, "seed": 11, "island": true}},
        "iterations": iterations,
    }))
    .expect("parses")
}

fn terrain(p: &ErodeParams) -> Heightfield {
    support::with_context(|ctx| resolve(&p.terrain, ctx.terrain, ctx.limits).expect("terrain"))
}

/// The erosion alone: its seconds and its peak heap per cell.
fn erosion(p: &ErodeParams, hf: &Heightfield) -> (f64, f64) {
    let before = counting_alloc::start();
    let started = Instant::now();
    let mut e = Erosion::new(hf, p);
    for _ in 0..p.iterations {
        e.step();
    }
    let seconds = started.elapsed().as_secs_f64();
    let peak = counting_alloc::peak_since(before) as f64;
    (seconds, peak / (hf.cols * hf.rows) as f64)
}

fn once(label: &str, p: &ErodeParams) {
    let hf = terrain(p);
    let (seconds, per_cell) = erosion(p, &hf);
    let started = Instant::now();
    let out = support::with_context(|ctx| Erode::run(p, 1, ctx).expect("runs"));
    eprintln!(
        "{label}: erosion {seconds:.2} s, {per_cell:.1} B a cell at the peak; whole job {:.2} s; landform {}",
        started.elapsed().as_secs_f64(),
        out.result["landform"]["output"],
    );
}

fn erode(c: &mut Criterion) {
    once("1025² island, 100 iterations, hydraulic + thermal", &params(1025, 100));
    once("257² island, defaults", &params(257, 100));
    let small = params(257, 100);
    let hf = terrain(&small);
    let mut group = c.benchmark_group("erode");
    group.sample_size(10);
    group.bench_function("257² island, defaults, erosion alone", |b| b.iter(|| erosion(&small, &hf)));
    group.bench_function("257² island, defaults, whole job", |b| {
        b.iter(|| support::with_context(|ctx| Erode::run(&small, 1, ctx).expect("runs")))
    });
    let big = params(1025, 100);
    let hf = terrain(&big);
    group.bench_function("1025² island, 100 iterations, erosion alone", |b| b.iter(|| erosion(&big, &hf)));
    group.finish();
}

criterion_group!(benches, erode);
criterion_main!(benches);
