//! A 513 × 513 fractal island carved with 3 passes of the default settings, voxel = cell size
//! (target ≤ 3 s), the same at 1025 × 1025 (target ≤ 12 s), and the 513 case sampled densely
//! over the whole box instead of the narrow band, to show what the band saves. Each case prints
//! its figures first. Run with `cargo bench --bench carve_coast`.

use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use serde_json::json;

use landform::jobs::Simulation;
use landform::sims::carve_coast::{CarveCoast, CarveCoastParams};
use landform::validate::Limits;

#[path = "support/mod.rs"]
mod support;

fn island(size: u32) -> CarveCoastParams {
    serde_json::from_value(json!({
        "terrain": {"fractal": {"size": size, "cell_size": 1.0, "relief": 120.0, "seed": 11, "island": true}},
        "sea_level": 0.0,
        "passes": 3,
    }))
    .expect("parses")
}

fn limits() -> Limits {
    Limits { max_voxels: 1 << 30, ..Limits::default() }
}

fn once(label: &str, p: &CarveCoastParams) {
    let started = Instant::now();
    let out = support::with_limits(&limits(), |ctx| CarveCoast::run(p, 1, ctx).expect("runs"));
    eprintln!(
        "{label}: {:.2} s — spheres {}, triangles {}, voxels {}, overhang share {:.3}, through-holes {}, fragments {}",
        started.elapsed().as_secs_f64(),
        out.result["spheres"]["per_pass"],
        out.result["mesh"]["triangles"],
        out.result["voxels"],
        out.result["overhangs"]["share"].as_f64().unwrap_or(0.0),
        out.result["through_holes"],
        out.result["fragments_removed"],
    );
}

fn carve(c: &mut Criterion) {
    once("513² island, 3 passes, narrow band", &island(513));
    once("1025² island, 3 passes, narrow band", &island(1025));
    for dense in [false, true] {
        let (seconds, triangles) =
            landform::sims::carve_coast::meshing_seconds(&island(513), 1, dense).expect("meshes");
        let how = if dense { "densely over the whole box" } else { "in the narrow band" };
        eprintln!("513² island, field sampled and meshed {how}: {seconds:.2} s, {triangles} triangles");
    }
    let p = island(513);
    let mut group = c.benchmark_group("carve-coast");
    group.sample_size(10);
    group.bench_function("513² island, 3 passes, voxel = cell", |b| {
        b.iter(|| support::with_limits(&limits(), |ctx| CarveCoast::run(&p, 1, ctx).expect("runs")))
    });
    group.finish();
}

criterion_group!(benches, carve);
criterion_main!(benches);
