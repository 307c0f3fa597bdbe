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
    let side: Vec<i8> = land.iter().map(|&l| if l { 1 } else { -1 }).collect();
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
    let shore = shore(m, &land, &interest, grid);
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
        detail: Detail::ShapeMask { water_level, margin, shore },
    }
}

/// Per sample, the share of the margin its bound keeps when the projection holds the mask
/// ([`super::held`]): its distance to the coast in cells, up to 1 (and at least a hundredth, so
/// each side stays strictly on its side). The bounds then cross the water level on the
/// coast itself, so where the projection sets the samples beside it on their bounds the
/// shoreline runs along the polygon between them, not along a staircase of whole cells.
/// Polygons: the distance to their outlines; an image: to the nearest sample of the other
/// side, less half a cell.
fn shore(m: &ShapeMask, land: &[bool], band: &[bool], grid: &Grid) -> Vec<f64> {
    let (cols, rows) = (grid.cols, grid.rows);
    let reach = BOUNDARY_BAND_CELLS as i64;
    (0..land.len())
        .map(|i| {
            if !band[i] {
                return 1.0;
            }
            let (c, r) = ((i % cols) as f64, (i / cols) as f64);
            let d = match &m.mask {
                MaskShape::PolygonsM(polys) => {
                    polys.iter().map(|p| to_outline(p, c * grid.cell_m, r * grid.cell_m)).fold(f64::INFINITY, f64::min)
                        / grid.cell_m
                }
                MaskShape::Image(_) => {
                    let mut d = f64::INFINITY;
                    for dr in -reach..=reach {
                        for dc in -reach..=reach {
                            let (cc, rr) = (c as i64 + dc, r as i64 + dr);
                            if (0..cols as i64).contains(&cc)
                                && (0..rows as i64).contains(&rr)
                                && land[rr as usize * cols + cc as usize] != land[i]
                            {
                                d = d.min(((dc * dc + dr * dr) as f64).sqrt() - 0.5);
                            }
                        }
                    }
                    d
                }
            };
            d.clamp(0.01, 1.0)
        })
        .collect()
}

/// Distance from (x, z) to a closed polygon's outline, metres.
fn to_outline(poly: &[PlanPoint], x: f64, z: f64) -> f64 {
    let mut best = f64::INFINITY;
    for k in 0..poly.len() {
        let (a, b) = (&poly[k], &poly[(k + 1) % poly.len()]);
        let (dx, dz) = (b.x - a.x, b.z - a.z);
        let len2 = dx * dx + dz * dz;
        let t = if len2 > 0.0 { (((x - a.x) * dx + (z - a.z) * dz) / len2).clamp(0.0, 1.0) } else { 0.0 };
        best = best.min((x - a.x - t * dx).hypot(z - a.z - t * dz));
    }
    best
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
