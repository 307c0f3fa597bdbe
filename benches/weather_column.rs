//! The paper's timings (section 6) on this machine: per-step time of a 1M-voxel cube (100³)
//! with bubble radius 4 while about 100,000 voxels are active (paper: up to ~1 s), and a
//! 10M-voxel column weathered to nothing with radius 4, in all and at peak memory (paper:
//! 12 min 33 s and 793 MB). Run with `cargo bench --bench weather_column`.

use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use serde_json::json;

use landform::jobs::Simulation;
use landform::sims::weather_column::{Stepper, WeatherColumn, WeatherColumnParams};

#[path = "support/counting_alloc.rs"]
mod counting_alloc;

#[global_allocator]
static ALLOCATOR: counting_alloc::Counting = counting_alloc::Counting;

#[path = "support/mod.rs"]
mod support;

fn params(x: u32, y: u32, z: u32, rate: f32, steps: u32) -> WeatherColumnParams {
    serde_json::from_value(json!({
        "grid": {"x": x, "y": y, "z": z},
        "voxel_size_m": 0.1,
        "column": {"profile": {"box": {}}},
        "layers": [{"top_m": 1000.0, "resistance": 1.0, "bubble": {"sphere": {"radius": 4.0}}}],
        "rate": rate,
        "steps": steps,
    }))
    .expect("parses")
}

/// The 100³ cube weathered until about 100,000 voxels are active.
fn cube_at_100k_active() -> Stepper {
    let mut s = Stepper::new(&params(100, 100, 100, 0.25, 1000), 1).expect("builds");
    eprintln!("cube 100³: {} active voxels at the start", s.active_voxels());
    while s.active_voxels() > 100_000 && s.rock_voxels() > 0 {
        s.step();
    }
    s
}

fn cube_step(c: &mut Criterion) {
    let base = cube_at_100k_active();
    let mut probe = base.clone();
    let started = Instant::now();
    let removed = probe.step();
    eprintln!(
        "cube 100³ step at {} active voxels: {:.2} ms, {removed} removed",
        base.active_voxels(),
        started.elapsed().as_secs_f64() * 1e3
    );
    c.bench_function("weather 100³ cube, radius 4, one step at ~100k active", |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                let mut s = base.clone();
                let t = Instant::now();
                s.step();
                total += t.elapsed();
            }
            total
        })
    });
}

/// 160 × 400 × 160 = 10.24M voxels standing on the ground, weathered to nothing.
fn column_to_nothing(c: &mut Criterion) {
    let p = params(160, 400, 160, 0.5, 65_000);
    let run = || support::with_context(|ctx| WeatherColumn::run(&p, 1, ctx).expect("runs"));
    let before = counting_alloc::start();
    let started = Instant::now();
    let out = run();
    let elapsed = started.elapsed();
    let peak = counting_alloc::peak_since(before);
    eprintln!(
        "column 10.24M voxels to nothing: {:.2} s, {} steps, active max {} min {}, peak heap {:.1} MB, sequence {} KB",
        elapsed.as_secs_f64(),
        out.result["steps_run"],
        out.result["active_voxels"]["max"],
        out.result["active_voxels"]["min"],
        peak as f64 / 1e6,
        out.sequence.removal_steps.len() / 1024,
    );
    let mut group = c.benchmark_group("weather 10M column");
    group.sample_size(10);
    group.bench_function("160×400×160 box, radius 4, to nothing", |b| b.iter(run));
    group.finish();
}

criterion_group!(benches, cube_step, column_to_nothing);
criterion_main!(benches);
