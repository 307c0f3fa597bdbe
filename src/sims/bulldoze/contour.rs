//! Paths a designer means (paper §2.1: "a spiral curve along the hillside, following the 20
//! metre contour"): a pass's path traced along a contour of the terrain as the pass starts.
//!
//! The contour is the level set of the bilinear surface through the samples, traced cell by
//! cell (marching squares; a saddle cell is split the way its centre value says) from the
//! crossing nearest `start`, in the direction that keeps the higher ground on the requested
//! side, until `length_m`, the grid's edge or the loop's close; then resampled every
//! `spacing_m` along its length.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::params::{metres, PathVertex, PlanPoint, Sign};
use crate::terrain::Heightfield;
use crate::validate::{Limits, Validator};

fn default_spacing() -> f32 {
    1.0
}

/// A path along a contour.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeContourPath)]
pub struct ContourPath {
    /// The contour's height, metres; the path's vertices carry it as their height.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub height_m: f32,
    /// The path starts at the contour's crossing nearest this point.
    pub start: PlanPoint,
    /// The longest the path may be, metres (shorter where the contour leaves the grid or
    /// closes on itself). `length_m / spacing_m` at most the server's operation cap.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub length_m: f32,
    /// Metres between the path's vertices.
    #[serde(default = "default_spacing")]
    // 1e6 = MAX_METRES
    #[schema(default = 1.0, exclusive_minimum = 0.0, maximum = 1e6)]
    pub spacing_m: f32,
    /// Which side of the direction of travel the higher ground lies on.
    #[serde(default)]
    pub higher_on: Side,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = BulldozeSide)]
pub enum Side {
    #[default]
    Left,
    Right,
}

impl ContourPath {
    /// The most vertices the path can have.
    /// (A spacing that is not positive, or a length that is not finite, counts as without
    /// bound; validation refuses both.)
    pub fn max_vertices(&self) -> u64 {
        let n = self.length_m as f64 / self.spacing_m as f64;
        if n.is_finite() && n >= 0.0 {
            (n.ceil().min(1e18) as u64).saturating_add(1)
        } else {
            u64::MAX
        }
    }

    pub fn validate(&self, v: &mut Validator, limits: &Limits) {
        metres(v, "height_m", self.height_m, Sign::Any);
        v.field("start", |v| {
            metres(v, "x", self.start.x, Sign::Any);
            metres(v, "z", self.start.z, Sign::Any);
        });
        let fine = metres(v, "length_m", self.length_m, Sign::Positive)
            & metres(v, "spacing_m", self.spacing_m, Sign::Positive);
        if fine && self.max_vertices() > limits.max_operations {
            v.too_large(
                "length_m",
                format!(
                    "{} vertices (length_m / spacing_m) is more than the cap of {}",
                    self.max_vertices(),
                    limits.max_operations
                ),
            );
        }
    }
}

/// An edge between two neighbouring samples: horizontal (c, r)–(c + 1, r) or vertical
/// (c, r)–(c, r + 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Edge {
    H(usize, usize),
    V(usize, usize),
}

struct Level<'a> {
    hf: &'a Heightfield,
    level: f64,
}

impl Level<'_> {
    fn f(&self, c: usize, r: usize) -> f64 {
        self.hf.get(c, r) as f64 - self.level
    }

    fn ends(&self, e: Edge) -> ((usize, usize), (usize, usize)) {
        match e {
            Edge::H(c, r) => ((c, r), (c + 1, r)),
            Edge::V(c, r) => ((c, r), (c, r + 1)),
        }
    }

    /// Where the level crosses the edge (metres), if it does.
    fn crossing(&self, e: Edge) -> Option<(f64, f64)> {
        let ((c0, r0), (c1, r1)) = self.ends(e);
        let (a, b) = (self.f(c0, r0), self.f(c1, r1));
        if (a >= 0.0) == (b >= 0.0) {
            return None;
        }
        let t = a / (a - b);
        let cell = self.hf.cell_size_m as f64;
        Some(((c0 as f64 + t * (c1 as f64 - c0 as f64)) * cell, (r0 as f64 + t * (r1 as f64 - r0 as f64)) * cell))
    }

    /// The cells on either side of an edge that lie on the grid.
    fn cells(&self, e: Edge) -> Vec<(usize, usize)> {
        let (cols, rows) = (self.hf.cols, self.hf.rows);
        let mut out = Vec::with_capacity(2);
        match e {
            Edge::H(c, r) => {
                if r > 0 {
                    out.push((c, r - 1));
                }
                if r + 1 < rows {
                    out.push((c, r));
                }
            }
            Edge::V(c, r) => {
                if c > 0 {
                    out.push((c - 1, r));
                }
                if c + 1 < cols {
                    out.push((c, r));
                }
            }
        }
        out
    }

    /// The edge by which the contour leaves cell (c, r) having entered by `entry`.
    fn exit(&self, (c, r): (usize, usize), entry: Edge) -> Option<Edge> {
        // Edges and the corners at their ends: top a–b, right b–d, bottom e–d, left a–e.
        let (top, right, bottom, left) = (Edge::H(c, r), Edge::V(c + 1, r), Edge::H(c, r + 1), Edge::V(c, r));
        // The other edges the contour crosses, without allocating per cell.
        let (mut crossing, mut n) = ([top; 4], 0);
        for e in [top, right, bottom, left] {
            if e != entry && self.crossing(e).is_some() {
                crossing[n] = e;
                n += 1;
            }
        }
        match n {
            1 => Some(crossing[0]),
            3 => {
                // A saddle: the corners on the other side of the centre are cut off, each by
                // the segment joining its two edges.
                let corners = [
                    ((c, r), [top, left]),
                    ((c + 1, r), [top, right]),
                    ((c + 1, r + 1), [right, bottom]),
                    ((c, r + 1), [left, bottom]),
                ];
                let centre = corners.iter().map(|&((cc, rr), _)| self.f(cc, rr)).sum::<f64>() / 4.0 >= 0.0;
                corners.iter().filter(|&&((cc, rr), _)| (self.f(cc, rr) >= 0.0) != centre).find_map(|(_, edges)| {
                    match edges {
                        [a, b] if *a == entry => Some(*b),
                        [a, b] if *b == entry => Some(*a),
                        _ => None,
                    }
                })
            }
            _ => None,
        }
    }

    /// The contour from `start` into `cell` onwards, as points (metres), at most `length`
    /// long.
    fn trace(&self, start: Edge, cell: (usize, usize), length: f64) -> Vec<(f64, f64)> {
        let mut points = vec![self.crossing(start).expect("a crossing edge")];
        let (mut edge, mut cell, mut walked) = (start, cell, 0.0);
        let limit = 2 * self.hf.cols * self.hf.rows;
        for _ in 0..limit {
            let Some(exit) = self.exit(cell, edge) else { break };
            let p = self.crossing(exit).expect("a crossing edge");
            let last = *points.last().expect("the start");
            walked += (p.0 - last.0).hypot(p.1 - last.1);
            points.push(p);
            if exit == start || walked >= length {
                break;
            }
            let Some(&next) = self.cells(exit).iter().find(|&&n| n != cell) else { break };
            (edge, cell) = (exit, next);
        }
        points
    }

    /// The surface's uphill direction at a point (central differences of the bilinear surface).
    fn gradient(&self, (x, z): (f64, f64)) -> (f64, f64) {
        let d = self.hf.cell_size_m as f64 / 2.0;
        let h = |x: f64, z: f64| self.hf.sample(x as f32, z as f32) as f64;
        ((h(x + d, z) - h(x - d, z)) / (2.0 * d), (h(x, z + d) - h(x, z - d)) / (2.0 * d))
    }
}

/// The path's vertices on `hf` as the pass starts (at least 2), or why there are none.
pub fn contour_vertices(hf: &Heightfield, c: &ContourPath) -> Result<Vec<PathVertex>, String> {
    let level = Level { hf, level: c.height_m as f64 };
    let (sx, sz) = (c.start.x as f64, c.start.z as f64);
    let mut best: Option<(f64, Edge)> = None;
    for r in 0..hf.rows {
        for col in 0..hf.cols {
            let mut edges = Vec::with_capacity(2);
            if col + 1 < hf.cols {
                edges.push(Edge::H(col, r));
            }
            if r + 1 < hf.rows {
                edges.push(Edge::V(col, r));
            }
            for e in edges {
                if let Some((x, z)) = level.crossing(e) {
                    let d = (x - sx).hypot(z - sz);
                    if best.is_none_or(|(b, _)| d < b) {
                        best = Some((d, e));
                    }
                }
            }
        }
    }
    let Some((_, start)) = best else {
        return Err(format!("the terrain does not cross the {} m contour", c.height_m));
    };
    let length = c.length_m as f64;
    // Try each way from the start; keep the first that has the higher ground on the asked side.
    let mut traced: Vec<Vec<(f64, f64)>> =
        level.cells(start).into_iter().map(|cell| level.trace(start, cell, length)).filter(|t| t.len() > 1).collect();
    let wanted = |t: &[(f64, f64)]| {
        let (p0, p1) = (t[0], t[1]);
        let (tx, tz) = (p1.0 - p0.0, p1.1 - p0.1);
        let (gx, gz) = level.gradient(((p0.0 + p1.0) / 2.0, (p0.1 + p1.1) / 2.0));
        // Left of travel (tx, tz) is (tz, −tx) (right is +Z when travelling +X).
        let left = gx * tz - gz * tx;
        (left > 0.0) == (c.higher_on == Side::Left)
    };
    let pick = traced.iter().position(|t| wanted(t)).unwrap_or(0);
    if traced.is_empty() {
        return Err(format!("the {} m contour is a single point near the start", c.height_m));
    }
    let line = traced.swap_remove(pick);
    let vertices = resample(&line, c.spacing_m as f64, length);
    if vertices.len() < 2 {
        return Err(format!("the {} m contour near the start is shorter than spacing_m", c.height_m));
    }
    Ok(vertices.into_iter().map(|(x, z)| PathVertex { x: x as f32, z: z as f32, height: Some(c.height_m) }).collect())
}

/// Points every `spacing` along a polyline, from its start, up to `length` (and its end).
fn resample(line: &[(f64, f64)], spacing: f64, length: f64) -> Vec<(f64, f64)> {
    let mut out = vec![line[0]];
    let (mut next, mut walked) = (spacing, 0.0);
    for w in line.windows(2) {
        let seg = (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1);
        while next <= walked + seg && next <= length {
            let t = (next - walked) / seg;
            out.push((w[0].0 + t * (w[1].0 - w[0].0), w[0].1 + t * (w[1].1 - w[0].1)));
            next += spacing;
        }
        walked += seg;
    }
    out
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::super::{apply_operations, Operation, Step};
    use super::*;

    fn contour(v: serde_json::Value) -> ContourPath {
        serde_json::from_value(v).unwrap()
    }

    #[test]
    fn on_a_plane_the_contour_is_its_straight_line_with_the_higher_ground_on_the_asked_side() {
        // h = 5 + 0.1 x: the 20 m contour is the line x = 150 m; higher ground lies towards +x,
        // which is on the left when travelling +z (right is +z when travelling +x).
        let hf = Heightfield::from_fn(201, 101, 1.0, |x, _| 5.0 + 0.1 * x);
        let c =
            contour(json!({"height_m": 20.0, "start": {"x": 140.0, "z": 30.0}, "length_m": 40.0, "spacing_m": 2.5}));
        let v = contour_vertices(&hf, &c).unwrap();
        assert_eq!(v.len(), 17, "40 m every 2.5 m");
        for (k, p) in v.iter().enumerate() {
            assert!((p.x - 150.0).abs() < 1e-4, "{p:?}");
            assert!((p.z - (30.0 + 2.5 * k as f32)).abs() < 1e-4, "{p:?}");
            assert_eq!(p.height, Some(20.0));
        }
        let right = contour_vertices(&hf, &ContourPath { higher_on: Side::Right, ..c }).unwrap();
        assert!((right[1].z - 27.5).abs() < 1e-4, "travelling −z: {:?}", right[1]);
        let none = contour_vertices(&hf, &ContourPath { height_m: 500.0, ..c });
        assert!(none.unwrap_err().contains("does not cross"));
    }

    #[test]
    fn a_contour_path_on_a_hillside_stays_within_half_a_cell_of_its_contour() {
        // A rough hill: every vertex's height misses the contour's by no more than the slope
        // there allows over half a cell, and the path keeps the summit on its left.
        let hf = Heightfield::from_fn(129, 129, 2.0, |x, z| {
            let d = ((x - 128.0).powi(2) + (z - 128.0).powi(2)).sqrt();
            60.0 - 0.4 * d + 3.0 * (x * 0.11).sin() * (z * 0.07).cos()
        });
        let c =
            contour(json!({"height_m": 20.0, "start": {"x": 40.0, "z": 128.0}, "length_m": 600.0, "spacing_m": 3.0}));
        let v = contour_vertices(&hf, &c).unwrap();
        assert!(v.len() > 150, "{}", v.len());
        let level = Level { hf: &hf, level: 20.0 };
        for p in &v {
            let (gx, gz) = level.gradient((p.x as f64, p.z as f64));
            let slack = gx.hypot(gz) * hf.cell_size_m as f64 / 2.0;
            let miss = (hf.sample(p.x, p.z) as f64 - 20.0).abs();
            assert!(miss <= slack, "{p:?}: {miss} > {slack}");
        }
        // Summit on the left all the way: (tz, −tx) points towards the centre.
        for w in v.windows(2) {
            let (tx, tz) = ((w[1].x - w[0].x) as f64, (w[1].z - w[0].z) as f64);
            let (cx, cz) = (128.0 - w[0].x as f64, 128.0 - w[0].z as f64);
            assert!(tz * cx - tx * cz > 0.0, "{w:?}");
        }
        // As a pass: the job records the traced vertices as moves at the contour's height.
        let mut edited = hf.clone();
        let ops: Vec<Operation> = serde_json::from_value(json!([{"pass": {
            "contour": {"height_m": 20.0, "start": {"x": 40.0, "z": 128.0}, "length_m": 600.0, "spacing_m": 3.0},
            "blade": {"width_m": 6.0}}}]))
        .unwrap();
        let steps = apply_operations(&mut edited, &ops, None);
        assert_eq!(steps.len(), v.len() - 1);
        assert!(steps.iter().all(|s| matches!(s, Step::Move(m) if m.from.height == 20.0 && m.to.height == 20.0)));
    }

    #[test]
    fn a_zero_or_vanishing_spacing_is_refused_not_counted_to_overflow() {
        use crate::jobs::{JobKind, Kind, RequestError};
        // Found by schemathesis: 5e-324 / 0 made the vertex count overflow.
        for (length, spacing) in [(5e-324, 0.0), (10.0, 0.0), (1e6, 1e-30)] {
            let body = json!({"terrain": {"fractal": {}}, "operations": [{"pass": {
                "contour": {"height_m": 0.0, "start": {"x": 0.0, "z": 0.0}, "length_m": length, "spacing_m": spacing},
                "blade": {"width_m": 2.0}}}]});
            match Kind::<super::super::Bulldoze>::default().prepare(body, &Limits::default()) {
                Err(RequestError::Invalid { errors, .. }) => {
                    assert!(errors.iter().any(|e| e.field.starts_with("operations")), "{errors:?}")
                }
                Err(RequestError::Malformed(m)) => panic!("{m}"),
                Ok(_) => panic!("{length} / {spacing} accepted"),
            }
        }
    }
}
