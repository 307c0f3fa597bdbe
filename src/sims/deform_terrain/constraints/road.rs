//! `road`: cells within width/2 of the path want the road's height; every other cell its
//! original height (equation 4), so the terrain makes room for the road without flattening.
//! Road cells and other cells are normalised separately (each a mean square), so a narrow
//! road is not drowned by the rest of the grid; beside the road a shoulder eases the pull back
//! to the original, so the road can sit in a cutting or on an embankment instead of at the foot
//! of a one-cell cliff that no smooth deformation can make.

use serde_json::{json, Value};

use super::{Anchors, Detail, Field, Grid, Quadratic};
use crate::sims::deform_terrain::params::{Road, RoadHeight, RoadPreserve};

/// The profile climbs this much less steeply than asked (percentage points), so the road the
/// search leaves, within a few centimetres of its cells' targets, keeps to the asked grade
/// (6.63 % for 6 % asked without it, on a 129² fractal of 2 m cells).
const GRADE_MARGIN_PERCENT: f64 = 0.25;

/// What the road's figures need.
pub struct RoadDetail {
    /// (cell, road height) of every road cell.
    cells: Vec<(usize, f64)>,
    /// Centreline samples in grid coordinates, one cell apart along the path.
    centreline: Vec<(f64, f64)>,
    /// The road's wanted height at each centreline sample.
    profile: Vec<f64>,
    /// Metres between centreline samples.
    step_m: f64,
    width_m: f64,
}

/// `combined`: the request holds other constraints too (the default preservation scope then
/// is the corridor).
pub fn build(road: &Road, grid: &Grid, combined: bool) -> Field {
    let (cols, rows, n) = (grid.cols, grid.rows, grid.cells());
    let pts: Vec<(f64, f64)> = road.path.iter().map(|p| (p.x / grid.cell_m, p.z / grid.cell_m)).collect();
    // Arc length (cells) at each vertex.
    let mut arc = vec![0.0];
    for w in pts.windows(2) {
        let len = ((w[1].0 - w[0].0).powi(2) + (w[1].1 - w[0].1).powi(2)).sqrt();
        arc.push(arc.last().unwrap() + len);
    }
    let total = *arc.last().unwrap();
    // Centreline, one cell apart.
    let samples = (total.ceil() as usize).max(1) + 1;
    let centreline: Vec<(f64, f64)> = (0..samples).map(|k| at_arc(&pts, &arc, (k as f64).min(total))).collect();
    let step_m = if samples > 1 { total / (samples - 1) as f64 * grid.cell_m } else { grid.cell_m };
    let step_cells = step_m / grid.cell_m;
    let profile: Vec<f64> = match &road.height {
        RoadHeight::Constant(h) => vec![*h; samples],
        RoadHeight::Profile(p) => {
            // The original ground along the path, limited to the gradient from the start, less
            // a margin the search's last residual cannot take past the limit.
            let grade = (p.max_gradient_percent - GRADE_MARGIN_PERCENT).max(0.5 * p.max_gradient_percent);
            let rise = grade / 100.0 * step_m;
            let mut out: Vec<f64> =
                centreline.iter().map(|&(x, z)| bilinear(grid.original, cols, rows, x, z)).collect();
            for k in 1..out.len() {
                out[k] = out[k].clamp(out[k - 1] - rise, out[k - 1] + rise);
            }
            out
        }
    };
    let height_at = |s: f64| {
        let f = (s / step_cells).clamp(0.0, (samples - 1) as f64);
        let k = (f.floor() as usize).min(samples.saturating_sub(2));
        if samples < 2 {
            return profile[0];
        }
        let t = f - k as f64;
        profile[k] * (1.0 - t) + profile[k + 1] * t
    };

    // Nearest point on the path for every cell within half the width (first segment wins ties).
    let half = road.width_m / 2.0 / grid.cell_m;
    let shoulder = road.shoulder_m.unwrap_or(4.0 * road.width_m) / grid.cell_m;
    let reach = half + shoulder;
    let mut best: Vec<(f64, f64)> = vec![(f64::INFINITY, 0.0); n];
    for (s, w) in pts.windows(2).enumerate() {
        let ((x0, z0), (x1, z1)) = (w[0], w[1]);
        let c0 = (x0.min(x1) - reach).floor().max(0.0) as usize;
        let c1 = ((x0.max(x1) + reach).ceil().max(0.0) as usize).min(cols - 1);
        let r0 = (z0.min(z1) - reach).floor().max(0.0) as usize;
        let r1 = ((z0.max(z1) + reach).ceil().max(0.0) as usize).min(rows - 1);
        let (dx, dz) = (x1 - x0, z1 - z0);
        let len2 = dx * dx + dz * dz;
        for r in r0..=r1 {
            for c in c0..=c1 {
                let (px, pz) = (c as f64 - x0, r as f64 - z0);
                let t = if len2 > 0.0 { ((px * dx + pz * dz) / len2).clamp(0.0, 1.0) } else { 0.0 };
                let d2 = (px - t * dx).powi(2) + (pz - t * dz).powi(2);
                let i = r * cols + c;
                if d2 <= reach * reach && d2 < best[i].0 {
                    best[i] = (d2, arc[s] + t * len2.sqrt());
                }
            }
        }
    }
    let cells: Vec<(usize, f64)> =
        best.iter().enumerate().filter(|(_, b)| b.0 <= half * half).map(|(i, b)| (i, height_at(b.1))).collect();
    // Share of the full pull back to the original: 0 at the road's edge, 1 past the shoulder.
    let pull = |i: usize| {
        let d = best[i].0.sqrt();
        if shoulder > 0.0 && d.is_finite() {
            ((d - half) / shoulder).clamp(0.0, 1.0)
        } else {
            1.0
        }
    };
    let relief2 = grid.relief * grid.relief;
    let w_road = 1.0 / (cells.len().max(1) as f64 * relief2);
    let w_other = road.preserve_weight / ((n - cells.len()).max(1) as f64 * relief2);
    let scope = road.preserve.unwrap_or(if combined { RoadPreserve::Corridor } else { RoadPreserve::Everywhere });
    // The corridor: cells within the shoulder's reach of the path (pull below 1 or at its edge).
    let kept = |i: usize| scope == RoadPreserve::Everywhere || best[i].0.is_finite();
    let mut interest = vec![false; n];
    let mut target: Vec<Option<f64>> = vec![None; n];
    for &(i, t) in &cells {
        interest[i] = true;
        target[i] = Some(t);
    }
    let terms = (0..n).filter_map(|i| match target[i] {
        Some(t) => Some((i, w_road, t)),
        None if kept(i) && w_other > 0.0 => Some((i, w_other * pull(i), grid.original[i])),
        None => None,
    });
    Field {
        name: "road",
        weight: road.weight,
        quadratic: Some(Quadratic::from_terms(n, terms)),
        one_sided: None,
        pairs: None,
        interest,
        anchors: Anchors::Interest,
        detail: Detail::Road(RoadDetail { cells, centreline, profile, step_m, width_m: road.width_m }),
    }
}

/// (cell, road height) of every road cell.
pub fn cells(d: &RoadDetail) -> &[(usize, f64)] {
    &d.cells
}

/// Mark the road's cells in a per-cell material weight.
pub fn mark(d: &RoadDetail, material: &mut [u8]) {
    for &(i, _) in &d.cells {
        material[i] = 255;
    }
}

/// The point at arc length `s` (cells) along the polyline.
fn at_arc(pts: &[(f64, f64)], arc: &[f64], s: f64) -> (f64, f64) {
    // The first segment whose end reaches s: a binary search, as the arc lengths only grow.
    let k = arc.partition_point(|&a| a < s).max(1).min(arc.len().saturating_sub(1)) - 1;
    let len = arc[k + 1] - arc[k];
    let t = if len > 0.0 { ((s - arc[k]) / len).clamp(0.0, 1.0) } else { 0.0 };
    (pts[k].0 + t * (pts[k + 1].0 - pts[k].0), pts[k].1 + t * (pts[k + 1].1 - pts[k].1))
}

/// Bilinear height at grid coordinates.
pub fn bilinear(h: &[f64], cols: usize, rows: usize, x: f64, z: f64) -> f64 {
    let x = x.clamp(0.0, (cols - 1) as f64);
    let z = z.clamp(0.0, (rows - 1) as f64);
    let c0 = (x.floor() as usize).min(cols.saturating_sub(2));
    let r0 = (z.floor() as usize).min(rows.saturating_sub(2));
    let (c1, r1) = ((c0 + 1).min(cols - 1), (r0 + 1).min(rows - 1));
    let (tx, tz) = (x - c0 as f64, z - r0 as f64);
    let top = h[r0 * cols + c0] * (1.0 - tx) + h[r0 * cols + c1] * tx;
    let bottom = h[r1 * cols + c0] * (1.0 - tx) + h[r1 * cols + c1] * tx;
    top * (1.0 - tz) + bottom * tz
}

/// A road as a game places it (`road.json`): the centreline one cell apart in metres (x along
/// columns, z along rows) with the terrain's height there after the deformation (`y`, bilinear)
/// and the height the road wanted (`target_y`), its width, its length, and the gradient it
/// actually reached (steepest over runs of four widths, as the figures measure it, and between
/// neighbouring samples).
pub fn centreline(d: &RoadDetail, h: &[f64], grid: &Grid) -> Value {
    let along: Vec<f64> = d.centreline.iter().map(|&(x, z)| bilinear(h, grid.cols, grid.rows, x, z)).collect();
    let points: Vec<Value> = d
        .centreline
        .iter()
        .zip(&along)
        .zip(&d.profile)
        .map(|((&(x, z), &y), &t)| json!({"x": x * grid.cell_m, "z": z * grid.cell_m, "y": y, "target_y": t}))
        .collect();
    let step = along.windows(2).map(|w| (w[1] - w[0]).abs() / d.step_m * 100.0).fold(0.0f64, f64::max);
    let figures = figures(d, h, grid);
    json!({
        "width_m": d.width_m,
        "length_m": d.step_m * (d.centreline.len().saturating_sub(1)) as f64,
        "max_gradient_percent": figures["max_gradient_percent"],
        "max_step_gradient_percent": step,
        "max_error_m": d.cells.iter().fold(0.0f64, |m, &(i, t)| m.max((h[i] - t).abs())),
        "centreline": points,
    })
}

/// The largest miss of a road cell as a share of the relief, and the steepest centreline
/// gradient in percent, measured over runs of four road widths (at least 2 samples) so that a
/// cell's own residual (within the error above) does not pose as a gradient.
pub fn figures(d: &RoadDetail, h: &[f64], grid: &Grid) -> Value {
    let worst = d.cells.iter().fold(0.0f64, |m, &(i, t)| m.max((h[i] - t).abs()));
    let along: Vec<f64> = d.centreline.iter().map(|&(x, z)| bilinear(h, grid.cols, grid.rows, x, z)).collect();
    let run = ((4.0 * d.width_m / d.step_m).round() as usize).max(2);
    let steepest =
        along.windows(run + 1).map(|w| (w[run] - w[0]).abs() / (run as f64 * d.step_m) * 100.0).fold(0.0f64, f64::max);
    json!({
        "road_cells": d.cells.len(),
        "max_error_of_relief": worst / grid.relief,
        "max_gradient_percent": steepest,
    })
}
