//! 500 speleothems of up to 64 rings × 24 segments, grown and written to glb (target ≤ 300 ms
//! on this 2-core machine). Run with `cargo bench --bench grow_cave`.

use criterion::{criterion_group, criterion_main, Criterion};
use serde_json::json;

use landform::export::write_glb;
use landform::jobs::Simulation;
use landform::sims::grow_cave::{GrowCave, GrowCaveParams};

#[path = "support/mod.rs"]
mod support;

/// 500 drip sites in a tall chamber; level 1 at normal CO₂ with a tiny radius step, so each
/// stalactite grows all 64 rings.
fn params() -> GrowCaveParams {
    serde_json::from_value(json!({
        "chamber": {"width_m": 40, "depth_m": 40, "height_m": 20, "roof": {"relief_m": 1.0}, "floor": {"relief_m": 0.5}},
        "sites": {"scatter": {"count": 500, "min_spacing_m": 1.0}},
        "conditions": {"pluviometric_index": "1", "drip_interval": "standard", "co2": "normal"},
        "mineral": "iron",
        "rings": 64,
        "segments": 24,
        "radius_step_m": 0.0008,
        "height_step_m": 0.05,
        "wind": {"scale": 0.3}
    }))
    .expect("parses")
}

fn grow_and_write(c: &mut Criterion) {
    let p = params();
    let started = std::time::Instant::now();
    let out = support::with_context(|ctx| GrowCave::run(&p, 1, ctx).expect("runs"));
    let glb = out.artifacts.iter().find(|a| a.name == "mesh.glb").expect("glb");
    eprintln!(
        "grow-cave 500 × 64 × 24 (run with preview): {:.0} ms, {} passes, {} triangles, glb {:.1} MB",
        started.elapsed().as_secs_f64() * 1e3,
        out.result["passes"],
        out.result["triangles"]["total"],
        glb.bytes.len() as f64 / 1e6,
    );
    c.bench_function("grow 500 speleothems × 64 rings × 24 segments and write the glb", |b| {
        b.iter(|| {
            let sequence = landform::sims::grow_cave::grow(&p, 1, &mut |_, _| Ok(())).expect("grows");
            write_glb(&landform::sims::grow_cave::scene(&p, &sequence), landform::export::GlbForm::Quantize)
        })
    });
}

criterion_group!(benches, grow_and_write);
criterion_main!(benches);
