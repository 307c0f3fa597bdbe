//! `edge_match`: continue another terrain across shared edges (equation 5). The neighbour lies
//! beyond each listed edge and the two share the edge's samples, as engines' terrain tiles do
//! (the same convention as `tileable`): this terrain's edge sample is the neighbour's edge
//! sample e. Inward, a cell at distance y wants its own original height o_y blended to the
//! neighbour by cubic Hermite terms that vanish with their slopes at the band's end:
//! target(y) = o_y + (e − o₀)·f(y) + ((e − e′) − (o₁ − o₀))·g(y), f = (1 − s)²(1 + 2s),
//! g = y(1 − s)², s = y/band (e′ the neighbour's sample one step inside its edge): the seam
//! matches in height and in slope (C¹), and the terrain's own shape carries the rest. It is
//! weighted W(y) = (1 − y/band)². A linear extrapolation of the neighbour's last step over the
//! whole band would amplify its noise into ramps.

use serde_json::{json, Value};

use super::{rms, Anchors, Detail, Field, Grid, Quadratic};
use crate::sims::deform_terrain::params::{Edge, EdgeMatch};
use crate::terrain::Heightfield;

/// What the edge figures need: per shared-edge cell (this cell, the cell one step in, the
/// neighbour's edge height, its slope into the seam per step).
pub struct EdgeDetail {
    seam: Vec<(usize, usize, f64, f64)>,
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
            let own = |y: usize| grid.original[edge_cell(edge, k, y, cols, rows)];
            let (offset, kink) = (oe - own(0), (oe - on) - (own(1) - own(0)));
            for y in 0..band.min(along) {
                let i = edge_cell(edge, k, y, cols, rows);
                let s = y as f64 / band as f64;
                let fade = 1.0 - s;
                let w = fade * fade;
                let target = own(y) + offset * fade * fade * (1.0 + 2.0 * s) + kink * y as f64 * fade * fade;
                terms.push((i, w, target));
                weight_sum += w;
                if y < 2 {
                    interest[i] = true;
                }
                if y == 0 {
                    seam.push((i, edge_cell(edge, k, 1, cols, rows), oe, oe - on));
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
        anchors: Anchors::Interest,
        detail: Detail::EdgeMatch(EdgeDetail { seam }),
    }
}

/// The heights that continue the neighbour across each shared edge: (edge sample, the
/// neighbour's height there) and (the sample one step in, that height plus the neighbour's last
/// step), so the seam matches in height and slope.
pub fn seam(d: &EdgeDetail) -> impl Iterator<Item = (usize, f64)> + '_ {
    d.seam.iter().flat_map(|&(i, j, e, slope)| [(i, e), (j, e + slope)])
}

/// The 3 × 1 mean filter across the seam of each edge (Figure 7): samples 1 and 2 in from the
/// edge each become the mean of themselves and their neighbours towards and away from the
/// edge, all read before the filter; the edge samples (shared with the neighbour) stay.
pub fn seam_filter(h: &[f64], cols: usize, rows: usize, edges: &[Edge]) -> Vec<f64> {
    let mut out = h.to_vec();
    for &edge in edges {
        let along = match edge {
            Edge::West | Edge::East => rows,
            Edge::North | Edge::South => cols,
        };
        let across = match edge {
            Edge::West | Edge::East => cols,
            Edge::North | Edge::South => rows,
        };
        for k in 0..along {
            for y in 1..=2.min(across.saturating_sub(2)) {
                let at = |y: usize| edge_cell(edge, k, y, cols, rows);
                out[at(y)] = (h[at(y - 1)] + h[at(y)] + h[at(y + 1)]) / 3.0;
            }
        }
    }
    out
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
    p99_difference(h, cols, rows, cell_m, 1)
}

/// The 99th-percentile change of slope between consecutive steps along rows and columns (the
/// second difference over the cell size): how sharply the terrain's own slopes bend.
pub fn p99_kink(h: &[f64], cols: usize, rows: usize, cell_m: f64) -> f64 {
    p99_difference(h, cols, rows, cell_m, 2)
}

/// The 99th percentile of |first| (order 1) or |second| (order 2) differences along rows and
/// columns, over the cell size.
fn p99_difference(h: &[f64], cols: usize, rows: usize, cell_m: f64, order: usize) -> f64 {
    let diff = |a: f64, b: f64, c: f64| if order == 1 { b - a } else { c - 2.0 * b + a };
    let mut values = Vec::with_capacity(2 * cols * rows);
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            if c + order < cols {
                values.push(diff(h[i], h[i + 1], h[i + order]).abs() / cell_m);
            }
            if r + order < rows {
                values.push(diff(h[i], h[i + cols], h[i + order * cols]).abs() / cell_m);
            }
        }
    }
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    values[((values.len() - 1) as f64 * 0.99).round() as usize]
}

/// At the shared edge: the RMS height mismatch as a share of the relief, and the sharpest bend
/// of slope across it (this side's first step against the neighbour's last) against this
/// terrain's own 99th-percentile bend and slope.
pub fn figures(d: &EdgeDetail, h: &[f64], grid: &Grid) -> Value {
    let mismatch = rms(d.seam.iter().map(|&(i, _, oe, _)| h[i] - oe)) / grid.relief;
    let kink = d.seam.iter().fold(0.0f64, |m, &(i, j, _, slope)| m.max(((h[j] - h[i]) - slope).abs() / grid.cell_m));
    json!({
        "rms_mismatch_of_relief": mismatch,
        "max_seam_kink": kink,
        "own_p99_kink": p99_kink(h, grid.cols, grid.rows, grid.cell_m),
        "own_p99_slope": p99_slope(h, grid.cols, grid.rows, grid.cell_m),
    })
}
