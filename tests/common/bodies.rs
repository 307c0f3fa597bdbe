//! Request bodies shared by the service tests.

use serde_json::{json, Value};

/// A small bulldoze job (129² fractal, a mound, a box, a 3-segment pass): 5 steps.
pub fn small_bulldoze() -> Value {
    json!({
        "terrain": {"fractal": {"size": 129, "relief": 40.0, "seed": 3}},
        "operations": [
            {"primitive": {"shape": {"mound": {"center": {"x": 64, "z": 64}, "radius_m": 30, "height_m": 15}}, "operator": "add"}},
            {"primitive": {"shape": {"box": {"center": {"x": 40, "z": 90}, "size_x_m": 20, "size_z_m": 10, "height_m": 5}}, "operator": "subtract"}},
            {"pass": {
                "path": [{"x": 10, "z": 10}, {"x": 60, "z": 20, "height": 12.0}, {"x": 110, "z": 60}, {"x": 120, "z": 120}],
                "blade": {"width_m": 8, "profile": [[-1, 0.5], [-0.5, 0], [0.5, 0], [1, 0.5]]},
                "operator": "replace"
            }}
        ]
    })
}

/// The same request keeping only its first `k` operations' worth of steps, for comparing with
/// `replay until_step = k` (k counts primitives and moves).
pub fn small_bulldoze_first_steps(k: usize) -> Value {
    let mut body = small_bulldoze();
    let ops = body["operations"].as_array().unwrap().clone();
    let mut kept = Vec::new();
    let mut left = k;
    for op in ops {
        if left == 0 {
            break;
        }
        if let Some(path) = op["pass"]["path"].as_array() {
            let moves = path.len() - 1;
            let mut op = op.clone();
            if left < moves {
                op["pass"]["path"] = Value::Array(path[..left + 1].to_vec());
            }
            left -= left.min(moves);
            kept.push(op);
        } else {
            left -= 1;
            kept.push(op);
        }
    }
    body["operations"] = Value::Array(kept);
    body
}

/// A job that runs for seconds and checks for cancellation often: many large mounds over a
/// 1025² grid.
pub fn slow_bulldoze() -> Value {
    let ops: Vec<Value> = (0..2000)
        .map(|i| {
            json!({"primitive": {"shape": {"mound": {
                "center": {"x": 100 + (i * 37) % 800, "z": 100 + (i * 53) % 800},
                "radius_m": 400, "height_m": 1.0
            }}, "operator": "add"}})
        })
        .collect();
    json!({"terrain": {"fractal": {"size": 1025, "relief": 50.0, "octaves": 4}}, "operations": ops})
}

/// A bulldoze job of a few seconds on a small grid that reports progress often: many mounds,
/// each over the whole grid.
pub fn seconds_bulldoze(seed: u64) -> Value {
    let ops: Vec<Value> = (0..1500)
        .map(|i| {
            json!({"primitive": {"shape": {"mound": {
                "center": {"x": 20 + (i * 37) % 220, "z": 20 + (i * 53) % 220},
                "radius_m": 200, "height_m": 0.5
            }}, "operator": "add"}})
        })
        .collect();
    json!({"terrain": {"fractal": {"size": 257, "relief": 50.0, "seed": seed}}, "operations": ops})
}
