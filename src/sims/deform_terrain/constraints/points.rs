//! `points`: the terrain passes through given points; the nearest vertex is penalised by
//! (h − height)².

use serde_json::{json, Value};

use super::{Anchors, Detail, Field, Grid, Quadratic};
use crate::sims::deform_terrain::params::Points;

pub fn build(p: &Points, grid: &Grid) -> Field {
    let n = grid.cells();
    let w = 1.0 / (p.points.len() as f64 * grid.relief * grid.relief);
    let targets: Vec<(usize, f64)> = p
        .points
        .iter()
        .map(|pt| {
            let (c, r) = grid.nearest(pt.x, pt.z);
            (r * grid.cols + c, pt.height)
        })
        .collect();
    let mut interest = vec![false; n];
    for &(i, _) in &targets {
        interest[i] = true;
    }
    Field {
        name: "points",
        weight: p.weight,
        quadratic: Some(Quadratic::from_terms(n, targets.iter().map(|&(i, t)| (i, w, t)))),
        one_sided: None,
        pairs: None,
        interest,
        anchors: Anchors::Interest,
        detail: Detail::Points(targets),
    }
}

/// The largest miss as a share of the relief.
pub fn figures(targets: &[(usize, f64)], h: &[f64], grid: &Grid) -> Value {
    let worst = targets.iter().fold(0.0f64, |m, &(i, t)| m.max((h[i] - t).abs()));
    json!({ "max_error_of_relief": worst / grid.relief })
}
