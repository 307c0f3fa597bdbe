//! Issue 50's bay: a fractal island (1 m cells, 120 m relief) held to a rough outline of its
//! own at 0 m, with a bay 60 m wide cut 70 m into its south coast. Shared by
//! `benches/deform_terrain.rs` and `examples/deform_measures.rs`.

use serde_json::{json, Value};

/// The request body at `size`² samples (257 in the bench; the outline scales with the grid).
pub fn bay_body(size: u32) -> Value {
    let k = (size - 1) as f64 / 256.0;
    let outline: Vec<Value> = (0..48)
        .map(|i| {
            let t = i as f64 / 48.0 * std::f64::consts::TAU;
            let r = 92.0 + 8.0 * (3.0 * t).sin() + 5.0 * (7.0 * t + 1.0).cos();
            let (x, z) = (128.0 + r * t.cos(), 128.0 + r * t.sin());
            // The bay: the outline's points in the south (z > 128) between x 98 and 158 are
            // pulled in by 70 m.
            let z = if z > 128.0 && (98.0..=158.0).contains(&x) { z - 70.0 } else { z };
            json!({"x": x * k, "z": z * k})
        })
        .collect();
    json!({
        "seed": 5,
        "terrain": {"fractal": {"size": size, "cell_size": 1.0, "relief": 120.0, "island": true, "seed": 5}},
        "constraints": [{"shape_mask": {"mask": {"polygons_m": [outline]}, "water_level": 0.0}}]
    })
}
