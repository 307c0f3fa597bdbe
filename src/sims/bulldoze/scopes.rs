//! The paper's narrowest and widest scopes of action (§2): `local` — one vertex, or a listed
//! few, set or offset exactly — and `global` — one height transform of every vertex
//! (exaggerate, offset, clamp, or remap by a curve). Both act only inside the window, as every
//! operation does.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::apply::{cells_within, Bounds};
use super::params::{metres, Sign, Window};
use crate::terrain::Heightfield;
use crate::validate::{Limits, Validate, Validator};

/// Most points a `curve` may have.
pub const MAX_CURVE_POINTS: usize = 256;
/// Largest |factor| of an exaggeration.
pub const MAX_FACTOR: f32 = 1000.0;

/// Set or offset the listed vertices, each exactly: the grid sample nearest to (x, z) (x along
/// columns, z along rows, metres; sample (col, row) at (col × resolution, row × resolution)).
/// Nothing else changes. A vertex off the grid or outside the window changes nothing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeLocal)]
pub struct LocalOp {
    /// At least 1; together with every other operation's points at most the server's
    /// operation cap (100 000 by default; more is answered with 413). Applied in order, so a
    /// vertex listed twice takes both edits.
    #[schema(min_items = 1)]
    pub vertices: Vec<LocalVertex>,
}

/// One vertex and its edit: exactly one of `set_m` and `offset_m`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeLocalVertex)]
pub struct LocalVertex {
    /// Metres along X.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub x: f32,
    /// Metres along Z.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub z: f32,
    /// The vertex's new height, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub set_m: Option<f32>,
    /// Metres added to the vertex's height.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub offset_m: Option<f32>,
}

/// One height transform of every vertex inside the window: exactly one of the four.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
#[schema(as = BulldozeGlobal)]
pub enum GlobalOp {
    /// h ← about_m + factor × (h − about_m): relief stretched (factor > 1) or flattened about
    /// a height.
    Exaggerate(Exaggerate),
    /// h ← h + metres.
    OffsetM(f32),
    /// h ← min(max(h, min_m), max_m); either bound may be absent.
    Clamp(Clamp),
    /// h ← the piecewise-linear curve through `[input, output]` points at h (inputs strictly
    /// increasing, 2 to 256 points); below the first input the first output, above the last
    /// the last — terracing, levelling, remapping a range.
    Curve(Vec<[f32; 2]>),
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeExaggerate)]
pub struct Exaggerate {
    /// Within ±1000.
    #[schema(minimum = -1000.0, maximum = 1000.0)]
    pub factor: f32,
    /// The height that stays put, metres.
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(default = 0.0, minimum = -1e6, maximum = 1e6)]
    pub about_m: f32,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeClamp)]
pub struct Clamp {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub min_m: Option<f32>,
    /// Not below `min_m`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub max_m: Option<f32>,
}

impl Validate for LocalOp {
    fn validate(&self, v: &mut Validator, _limits: &Limits) {
        if self.vertices.is_empty() {
            v.error("vertices", "needs at least one vertex");
        }
        v.field("vertices", |v| {
            for (i, p) in self.vertices.iter().enumerate() {
                v.index(i, |v| {
                    metres(v, "x", p.x, Sign::Any);
                    metres(v, "z", p.z, Sign::Any);
                    match (p.set_m, p.offset_m) {
                        (Some(h), None) => _ = metres(v, "set_m", h, Sign::Any),
                        (None, Some(d)) => _ = metres(v, "offset_m", d, Sign::Any),
                        _ => v.error("", "needs exactly one of set_m and offset_m"),
                    }
                });
            }
        });
    }
}

impl Validate for GlobalOp {
    fn validate(&self, v: &mut Validator, _limits: &Limits) {
        match self {
            GlobalOp::Exaggerate(e) => v.field("exaggerate", |v| {
                if !e.factor.is_finite() || e.factor.abs() > MAX_FACTOR {
                    v.error("factor", format!("must be between -{MAX_FACTOR} and {MAX_FACTOR}"));
                }
                metres(v, "about_m", e.about_m, Sign::Any);
            }),
            GlobalOp::OffsetM(d) => _ = metres(v, "offset_m", *d, Sign::Any),
            GlobalOp::Clamp(c) => v.field("clamp", |v| {
                let lo = c.min_m.is_none_or(|h| metres(v, "min_m", h, Sign::Any));
                let hi = c.max_m.is_none_or(|h| metres(v, "max_m", h, Sign::Any));
                if let (true, true, Some(a), Some(b)) = (lo, hi, c.min_m, c.max_m) {
                    if b < a {
                        v.error("max_m", "must not be below min_m");
                    }
                }
            }),
            GlobalOp::Curve(points) => {
                if !(2..=MAX_CURVE_POINTS).contains(&points.len()) {
                    v.error("curve", format!("needs 2 to {MAX_CURVE_POINTS} points (got {})", points.len()));
                }
                v.field("curve", |v| {
                    for (i, p) in points.iter().enumerate() {
                        v.index(i, |v| {
                            let fine = metres(v, "", p[0], Sign::Any) && metres(v, "", p[1], Sign::Any);
                            if fine && i > 0 && points[i - 1][0] >= p[0] {
                                v.error("", "inputs must increase strictly");
                            }
                        });
                    }
                });
            }
        }
    }
}

/// Apply a local edit: each listed vertex's nearest sample, inside the grid and the window.
pub fn apply_local(hf: &mut Heightfield, op: &LocalOp, window: Option<&Window>) {
    for p in &op.vertices {
        let Some(i) = vertex_index(hf, p.x, p.z, window) else {
            continue;
        };
        let h = &mut hf.heights_m[i];
        match (p.set_m, p.offset_m) {
            (Some(s), _) => *h = s,
            (None, Some(d)) => *h += d,
            (None, None) => {}
        }
    }
}

/// The sample nearest to (x, z), if it is on the grid and inside the window.
pub fn vertex_index(hf: &Heightfield, x: f32, z: f32, window: Option<&Window>) -> Option<usize> {
    let cell = hf.cell_size_m as f64;
    let (col, row) = ((x as f64 / cell).round(), (z as f64 / cell).round());
    let on_grid = (0.0..hf.cols as f64).contains(&col) && (0.0..hf.rows as f64).contains(&row);
    let (col, row) = (col as usize, row as usize);
    let at = Bounds {
        min_x: col as f64 * cell,
        min_z: row as f64 * cell,
        max_x: col as f64 * cell,
        max_z: row as f64 * cell,
    };
    let inside = cells_within(hf.cols, hf.rows, cell, at, window).is_some();
    (on_grid && inside).then_some(row * hf.cols + col)
}

/// Apply a global transform to every sample inside the window, rows in parallel.
pub fn apply_global(hf: &mut Heightfield, op: &GlobalOp, window: Option<&Window>) {
    let all = Bounds { min_x: f64::NEG_INFINITY, min_z: f64::NEG_INFINITY, max_x: f64::INFINITY, max_z: f64::INFINITY };
    let Some(((c0, c1), (r0, r1))) = cells_within(hf.cols, hf.rows, hf.cell_size_m as f64, all, window) else {
        return;
    };
    let cols = hf.cols;
    hf.heights_m[r0 * cols..(r1 + 1) * cols].par_chunks_mut(cols).for_each(|row| {
        for h in &mut row[c0..=c1] {
            *h = transform(op, *h);
        }
    });
}

/// One height through a global transform.
pub fn transform(op: &GlobalOp, h: f32) -> f32 {
    match op {
        GlobalOp::Exaggerate(e) => e.about_m + e.factor * (h - e.about_m),
        GlobalOp::OffsetM(d) => h + d,
        GlobalOp::Clamp(c) => {
            let h = c.min_m.map_or(h, |lo| h.max(lo));
            c.max_m.map_or(h, |hi| h.min(hi))
        }
        GlobalOp::Curve(points) => curve(points, h),
    }
}

fn curve(points: &[[f32; 2]], h: f32) -> f32 {
    let (first, last) = (points[0], points[points.len() - 1]);
    if h <= first[0] {
        return first[1];
    }
    if h >= last[0] {
        return last[1];
    }
    // The segment whose inputs hold h: the first point above it and the one before.
    let k = points.partition_point(|p| p[0] <= h);
    let ([x0, y0], [x1, y1]) = (points[k - 1], points[k]);
    let t = (h as f64 - x0 as f64) / (x1 as f64 - x0 as f64);
    (y0 as f64 + t * (y1 as f64 - y0 as f64)) as f32
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::super::{apply_operations, Operation, Step};
    use super::*;

    fn hills() -> Heightfield {
        Heightfield::from_fn(41, 33, 2.0, |x, z| 12.0 + 6.0 * (x * 0.07).sin() * (z * 0.05).cos() + 0.04 * x)
    }

    fn ops(v: serde_json::Value) -> Vec<Operation> {
        serde_json::from_value(v).unwrap()
    }

    #[test]
    fn a_local_edit_changes_exactly_the_named_vertices() {
        let before = hills();
        let mut hf = before.clone();
        // 2 m cells: (10, 20) m is sample (5, 10); (31.2, 4.9) m rounds to (16, 2); (500, 0) is
        // off the grid and changes nothing.
        let steps = apply_operations(
            &mut hf,
            &ops(json!([{"local": {"vertices": [
                {"x": 10.0, "z": 20.0, "set_m": 55.5},
                {"x": 31.2, "z": 4.9, "offset_m": -2.25},
                {"x": 500.0, "z": 0.0, "set_m": 1.0}
            ]}}])),
            None,
        );
        assert!(matches!(steps.as_slice(), [Step::Local(_)]));
        let (a, b) = (10 * 41 + 5, 2 * 41 + 16);
        for (i, (&h0, &h1)) in before.heights_m.iter().zip(&hf.heights_m).enumerate() {
            match i {
                _ if i == a => assert_eq!(h1, 55.5),
                _ if i == b => assert_eq!(h1, h0 - 2.25),
                _ => assert_eq!(h1.to_bits(), h0.to_bits(), "sample {i}"),
            }
        }
        // Inside a window only: the same edit with the window away from (5, 10) leaves it.
        let mut windowed = before.clone();
        let w = Window { min_x: 20.0, min_z: 0.0, max_x: 80.0, max_z: 64.0 };
        apply_operations(
            &mut windowed,
            &ops(
                json!([{"local": {"vertices": [{"x": 10.0, "z": 20.0, "set_m": 55.5}, {"x": 32.0, "z": 4.0, "offset_m": 1.0}]}}]),
            ),
            Some(&w),
        );
        assert_eq!(windowed.heights_m[a], before.heights_m[a]);
        assert_eq!(windowed.heights_m[b], before.heights_m[b] + 1.0);
    }

    #[test]
    fn a_global_exaggeration_multiplies_every_height_and_the_others_transform_by_hand() {
        let before = hills();
        let mut hf = before.clone();
        apply_operations(&mut hf, &ops(json!([{"global": {"exaggerate": {"factor": 2.5}}}])), None);
        for (&h0, &h1) in before.heights_m.iter().zip(&hf.heights_m) {
            assert_eq!(h1, h0 * 2.5);
        }
        let mut hf = before.clone();
        apply_operations(
            &mut hf,
            &ops(json!([
                {"global": {"exaggerate": {"factor": 0.5, "about_m": 12.0}}},
                {"global": {"offset_m": 3.0}}
            ])),
            None,
        );
        for (&h0, &h1) in before.heights_m.iter().zip(&hf.heights_m) {
            assert!((h1 as f64 - (12.0 + 0.5 * (h0 as f64 - 12.0) + 3.0)).abs() < 1e-5);
        }
        let mut hf = before.clone();
        apply_operations(&mut hf, &ops(json!([{"global": {"clamp": {"min_m": 10.0, "max_m": 14.0}}}])), None);
        for (&h0, &h1) in before.heights_m.iter().zip(&hf.heights_m) {
            assert_eq!(h1, h0.clamp(10.0, 14.0));
        }
        // A curve by hand: 0→0, 10→20, 20→20 (a terrace from 10 m up), constant beyond.
        let c = GlobalOp::Curve(vec![[0.0, 0.0], [10.0, 20.0], [20.0, 20.0]]);
        for (h, want) in [(-5.0, 0.0), (0.0, 0.0), (2.5, 5.0), (7.5, 15.0), (10.0, 20.0), (15.0, 20.0), (99.0, 20.0)] {
            assert_eq!(transform(&c, h), want, "h = {h}");
        }
        // Inside the window only.
        let mut hf = before.clone();
        let w = Window { min_x: 20.0, min_z: 10.0, max_x: 40.0, max_z: 30.0 };
        apply_operations(&mut hf, &ops(json!([{"global": {"offset_m": 1.0}}])), Some(&w));
        for (i, (&h0, &h1)) in before.heights_m.iter().zip(&hf.heights_m).enumerate() {
            let (x, z) = ((i % 41) as f32 * 2.0, (i / 41) as f32 * 2.0);
            let inside = (20.0..=40.0).contains(&x) && (10.0..=30.0).contains(&z);
            assert_eq!(h1, if inside { h0 + 1.0 } else { h0 }, "({x}, {z})");
        }
    }

    #[test]
    fn bad_scoped_operations_name_their_field() {
        use crate::jobs::{JobKind, Kind, RequestError};
        let fields = |op: serde_json::Value| {
            let body = json!({"terrain": {"fractal": {"size": 33}}, "operations": [op]});
            match Kind::<super::super::Bulldoze>::default().prepare(body, &Limits::default()) {
                Ok(_) => Vec::new(),
                Err(RequestError::Invalid { errors, .. }) => errors.into_iter().map(|e| e.field).collect(),
                Err(RequestError::Malformed(m)) => vec![m],
            }
        };
        let cases = [
            (
                json!({"local": {"vertices": [{"x": 1, "z": 1, "set_m": 1, "offset_m": 1}]}}),
                "operations[0].local.vertices[0]",
            ),
            (json!({"local": {"vertices": [{"x": 1, "z": 1}]}}), "operations[0].local.vertices[0]"),
            (json!({"local": {"vertices": []}}), "operations[0].local.vertices"),
            (json!({"local": {"vertices": [{"x": 1e9, "z": 1, "set_m": 1}]}}), "operations[0].local.vertices[0].x"),
            (json!({"global": {"exaggerate": {"factor": 1e4}}}), "operations[0].global.exaggerate.factor"),
            (json!({"global": {"offset_m": 2e6}}), "operations[0].global.offset_m"),
            (json!({"global": {"clamp": {"min_m": 5, "max_m": 1}}}), "operations[0].global.clamp.max_m"),
            (json!({"global": {"curve": [[0, 0]]}}), "operations[0].global.curve"),
            (json!({"global": {"curve": [[0, 0], [5, 1], [5, 2]]}}), "operations[0].global.curve[2]"),
        ];
        for (op, want) in cases {
            assert_eq!(fields(op.clone()), vec![want.to_string()], "{op}");
        }
        assert_eq!(fields(json!({"global": {"curve": [[0, 0], [5, 1]]}})), Vec::<String>::new());
    }
}
