//! `shape_mask`: land where the mask says land, sea elsewhere (equation 3). With a margin so
//! the result holds after rounding: land wants h ≥ water_level + margin, sea h ≤ water_level −
//! margin; the penalty is the squared shortfall, 0 once satisfied.

use serde_json::{json, Value};

use super::{Anchors, Detail, Field, Grid, OneSided};
use crate::sims::deform_terrain::params::{MaskShape, PlanPoint, ShapeMask};
use crate::terrain::Heightfield;

/// Cells within this many (Chebyshev) of a land/sea change are refined around.
const BOUNDARY_BAND_CELLS: usize = 2;

pub fn build(m: &ShapeMask, image: Option<&Heightfield>, grid: &Grid) -> Field {
    let (cols, rows, n) = (grid.cols, grid.rows, grid.cells());
    let land: Vec<bool> = match (&m.mask, image) {
        (MaskShape::Image(_), Some(img)) => {
            let (lo, hi) = img.min_max();
            let mid = (lo as f64 + hi as f64) / 2.0;
            img.heights_m.iter().map(|&v| v as f64 > mid).collect()
        }
        (MaskShape::PolygonsM(polys), _) => {
            let at = |i: usize| ((i % cols) as f64 * grid.cell_m, (i / cols) as f64 * grid.cell_m);
            (0..n).map(|i| inside_any(polys, at(i))).collect()
        }
        (MaskShape::Image(_), None) => vec![false; n],
    };
    let water_level = m.water_level.unwrap_or_else(|| median(grid.original));
    let margin = m.margin.unwrap_or(0.01 * grid.relief);
    let side = land.iter().map(|&l| if l { 1 } else { -1 }).collect();
    let mut interest = vec![false; n];
    let b = BOUNDARY_BAND_CELLS;
    for r in 0..rows {
        for c in 0..cols {
            let here = land[r * cols + c];
            let (c0, c1, r0, r1) =
                (c.saturating_sub(b), (c + b).min(cols - 1), r.saturating_sub(b), (r + b).min(rows - 1));
            interest[r * cols + c] = (r0..=r1).any(|rr| (c0..=c1).any(|cc| land[rr * cols + cc] != here));
        }
    }
    Field {
        name: "shape_mask",
        weight: m.weight,
        quadratic: None,
        one_sided: Some(OneSided {
            side,
            lo: water_level + margin,
            hi: water_level - margin,
            scale: 1.0 / (n as f64 * grid.relief * grid.relief),
        }),
        pairs: None,
        interest,
        anchors: Anchors::None,
        detail: Detail::ShapeMask { water_level, margin },
    }
}

/// Even-odd test of a point (x, z), metres, against every polygon.
pub(super) fn inside_any(polys: &[Vec<PlanPoint>], (x, z): (f64, f64)) -> bool {
    let mut inside = false;
    for poly in polys {
        let mut j = poly.len() - 1;
        for i in 0..poly.len() {
            let ((xi, zi), (xj, zj)) = ((poly[i].x, poly[i].z), (poly[j].x, poly[j].z));
            if (zi > z) != (zj > z) && x < (xj - xi) * (z - zi) / (zj - zi) + xi {
                inside = !inside;
            }
            j = i;
        }
    }
    inside
}

fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2]
}

/// The share of cells on the correct side of the water level (margin not counted).
pub fn figures(field: &Field, h: &[f64], water_level: f64, margin: f64) -> Value {
    let side = &field.one_sided.as_ref().expect("one-sided").side;
    let correct =
        side.iter().zip(h).filter(|(&s, &v)| (s > 0 && v > water_level) || (s < 0 && v < water_level)).count();
    json!({
        "water_level_m": water_level,
        "margin_m": margin,
        "land_cells": side.iter().filter(|&&s| s > 0).count(),
        "correct_side_share": correct as f64 / side.len() as f64,
    })
}
