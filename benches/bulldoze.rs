//! Applying a bulldoze request's operations to a 4097 × 4097 grid: a 200-vertex winding
//! road cut with a 12 m blade on relative heights, and 50 primitives of every shape.
//! Run with `cargo bench --bench bulldoze`.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use serde_json::{json, Value};

use landform::sims::bulldoze::{apply_operations, Operation};
use landform::terrain::Heightfield;

const SIZE: usize = 4097;
const CELL_M: f32 = 1.0;

/// Cheap analytic hills over the whole grid.
fn terrain() -> Heightfield {
    Heightfield::from_fn(SIZE, SIZE, CELL_M, |x, z| {
        40.0 + 25.0 * (x * 0.0031).sin() * (z * 0.0027).cos() + 8.0 * (x * 0.011 + z * 0.007).sin()
    })
}

/// A winding road across the grid: 200 vertices, no heights (it rides on the terrain).
fn road() -> Value {
    let path: Vec<Value> = (0..200)
        .map(|i| {
            let t = i as f32 / 199.0;
            let x = 100.0 + 3896.0 * t;
            let z = 2048.0 + 1200.0 * (t * 9.0).sin() + 300.0 * (t * 31.0).sin();
            json!({"x": x, "z": z})
        })
        .collect();
    json!({"pass": {
        "path": path,
        "blade": {"width_m": 12.0, "profile": [[-1.0, 0.5], [-0.8, -0.5], [0.8, -0.5], [1.0, 0.5]]},
        "operator": "replace"
    }})
}

/// 50 primitives of mixed shapes and sizes, spread over the grid.
fn primitives() -> Vec<Value> {
    let operators = ["add", "subtract", "max", "min", "average", "replace"];
    (0..50)
        .map(|i| {
            // A low-discrepancy spread of centres and sizes.
            let fx = (i as f32 * 0.618_034).fract();
            let fz = (i as f32 * 0.754_878).fract();
            let (x, z) = (200.0 + 3700.0 * fx, 200.0 + 3700.0 * fz);
            let size = 40.0 + 160.0 * (i as f32 * 0.569_840).fract();
            let center = json!({"x": x, "z": z});
            let shape = match i % 8 {
                0 => json!({"mound": {"center": center, "radius_m": size, "height_m": size * 0.3, "curvature": 2.5}}),
                1 => json!({"berm": {"start": center, "direction_deg": i as f32 * 37.0, "l": size * 3.0,
                                     "h1": 6.0, "r1": 20.0, "h2": 12.0, "r2": 35.0, "c": 0.002, "c2": 3.0}}),
                2 => json!({"swale": {"start": center, "direction_deg": i as f32 * 23.0, "l": size * 2.0,
                                      "h1": 3.0, "r1": 10.0, "h2": 5.0, "r2": 15.0}}),
                3 => json!({"torus": {"center": center, "major_radius_m": size, "minor_radius_m": size * 0.2,
                                      "height_m": 8.0}}),
                4 => json!({"box": {"center": center, "size_x_m": size, "size_z_m": size * 0.6, "height_m": 10.0,
                                    "rotation_deg": i as f32 * 11.0, "base_m": 45.0}}),
                5 => json!({"cone": {"center": center, "radius_m": size, "height_m": size * 0.25,
                                     "top_radius_m": size * 0.3}}),
                6 => {
                    json!({"half_cylinder": {"start": center, "direction_deg": i as f32 * 17.0, "length_m": size * 2.0,
                                              "radius_m": 15.0}})
                }
                _ => json!({"ramp": {"start": center, "direction_deg": i as f32 * 29.0, "length_m": size * 2.0,
                                     "width_m": 20.0, "end_width_m": 40.0, "start_height_m": 0.0,
                                     "end_height_m": size * 0.14, "base_m": 40.0}}),
            };
            json!({"primitive": {"shape": shape, "operator": operators[i % operators.len()]}})
        })
        .collect()
}

fn operations() -> Vec<Operation> {
    let mut ops = primitives();
    ops.insert(25, road());
    serde_json::from_value(Value::Array(ops)).expect("valid operations")
}

fn bench(c: &mut Criterion) {
    let hf = terrain();
    let ops = operations();
    let mut group = c.benchmark_group("bulldoze");
    group.sample_size(10);
    group.bench_function("4097x4097 road of 200 vertices + 50 primitives", |b| {
        b.iter_batched_ref(|| hf.clone(), |hf| apply_operations(hf, &ops, None), BatchSize::LargeInput)
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
