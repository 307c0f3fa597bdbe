//! `edge_match`: continue another terrain across shared edges (equation 5). The neighbour lies
//! beyond each listed edge. The edge cell wants the neighbour's edge height e continued by one
//! step, s = e + ((e − e′) + (o₁ − o₀))/2 (e′ the neighbour's sample inside its edge, o this
//! terrain's original heights in from the edge: the mean of the two sides' slopes); a cell at
//! distance y wants its own original height shifted by that offset, faded over the band,
//! target(y) = o_y + (s − o₀)(1 − y/band), weighted W(y) = (1 − y/band)². A linear extrapolation
//! of the neighbour's last step over the whole band would amplify its noise into ramps.

use serde_json::{json, Value};

use super::{rms, Detail, Field, Grid, Quadratic};
use crate::sims::deform_terrain::params::{Edge, EdgeMatch};
use crate::terrain::Heightfield;

/// What the edge figures need: per shared-edge cell (this cell, the neighbour's edge height,
/// the extrapolated target).
pub struct EdgeDetail {
    seam: Vec<(usize, f64, f64)>,
}

pub fn build(e: &EdgeMatch, other: &Heightfield, grid: &Grid) -> Field {
    let (cols, rows, n) = (grid.cols, grid.rows, grid.cells());
    let o = |c: usize, r: usize| other.heights_m[r * cols + c] as f64;
    let band = (e.band_cells as usize).max(1);
    let mut terms = Vec::new();
    let mut seam = Vec::new();
    let mut interest = vec![false; n];
    let mut weight_sum = 0.0;
    let mut edges = e.edges.clone();
    edges.dedup();
    for edge in edges {
        let along = match edge {
            Edge::West | Edge::East => rows,
            Edge::North | Edge::South => cols,
        };
        for k in 0..along {
            // (neighbour's edge sample, the one inside it)
            let (oe, on) = match edge {
                Edge::West => (o(cols - 1, k), o(cols - 2, k)),
                Edge::East => (o(0, k), o(1, k)),
                Edge::North => (o(k, rows - 1), o(k, rows - 2)),
                Edge::South => (o(k, 0), o(k, 1)),
            };
            for y in 0..band.min(along) {
                let i = edge_cell(edge, k, y, cols, rows);
                let fade = 1.0 - y as f64 / band as f64;
                let w = fade * fade;
                // The seam step is the mean of the two sides' last steps; inward, this
                // terrain's own shape carries the offset, fading over the band.
                let own = |y: usize| grid.original[edge_cell(edge, k, y, cols, rows)];
                let seam_target = oe + 0.5 * ((oe - on) + (own(1) - own(0)));
                let target = own(y) + (seam_target - own(0)) * fade;
                terms.push((i, w, target));
                weight_sum += w;
                if y < 2 {
                    interest[i] = true;
                }
                if y == 0 {
                    seam.push((i, oe, target));
                }
            }
        }
    }
    let scale = 1.0 / (weight_sum.max(1e-12) * grid.relief * grid.relief);
    let quadratic = Quadratic::from_terms(n, terms.into_iter().map(|(i, w, t)| (i, w * scale, t)));
    Field {
        name: "edge_match",
        weight: e.weight,
        quadratic: Some(quadratic),
        one_sided: None,
        pairs: None,
        interest,
        anchors: true,
        detail: Detail::EdgeMatch(EdgeDetail { seam }),
    }
}

/// The cell `y` in from `edge` at position `k` along it.
fn edge_cell(edge: Edge, k: usize, y: usize, cols: usize, rows: usize) -> usize {
    match edge {
        Edge::West => k * cols + y,
        Edge::East => k * cols + cols - 1 - y,
        Edge::North => y * cols + k,
        Edge::South => (rows - 1 - y) * cols + k,
    }
}

/// The 99th-percentile slope (rise over run between neighbouring samples) of a grid.
pub fn p99_slope(h: &[f64], cols: usize, rows: usize, cell_m: f64) -> f64 {
    let mut slopes = Vec::with_capacity(2 * cols * rows);
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            if c + 1 < cols {
                slopes.push((h[i + 1] - h[i]).abs() / cell_m);
            }
            if r + 1 < rows {
                slopes.push((h[i + cols] - h[i]).abs() / cell_m);
            }
        }
    }
    if slopes.is_empty() {
        return 0.0;
    }
    slopes.sort_by(f64::total_cmp);
    slopes[((slopes.len() - 1) as f64 * 0.99).round() as usize]
}

/// RMS mismatch at the seam (against the continued neighbour) as a share of the relief, and
/// the steepest step across the seam against this terrain's own 99th-percentile slope.
pub fn figures(d: &EdgeDetail, h: &[f64], grid: &Grid) -> Value {
    let mismatch = rms(d.seam.iter().map(|&(i, _, t)| h[i] - t)) / grid.relief;
    let seam_slope = d.seam.iter().fold(0.0f64, |m, &(i, oe, _)| m.max((h[i] - oe).abs() / grid.cell_m));
    json!({
        "rms_mismatch_of_relief": mismatch,
        "max_seam_slope": seam_slope,
        "own_p99_slope": p99_slope(h, grid.cols, grid.rows, grid.cell_m),
    })
}
