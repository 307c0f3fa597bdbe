//! `terraces`: regions at their own levels — terraces and plateaus, the paper's "masks for
//! more than one height threshold". A sample inside a region wants its level (the last region
//! containing it wins), penalised by (h − level)² normalised over the regions' samples; the
//! regions' samples anchor small deformations — those on a region's edge every small radius,
//! so the steps come out sharp, the rest the smallest few.

use serde_json::{json, Value};

use super::shape_mask::inside_any;
use super::{Anchors, Detail, Field, Grid, Quadratic};
use crate::sims::deform_terrain::params::Terraces;

/// (sample, level) of every sample in a region, and each region's samples.
pub struct TerraceDetail {
    targets: Vec<(usize, f64)>,
    regions: Vec<(f64, Vec<usize>)>,
}

pub fn build(t: &Terraces, grid: &Grid) -> Field {
    let n = grid.cells();
    let mut level: Vec<Option<usize>> = vec![None; n];
    for (k, region) in t.regions.iter().enumerate() {
        let poly = std::slice::from_ref(&region.polygon_m);
        for (i, l) in level.iter_mut().enumerate() {
            let at = ((i % grid.cols) as f64 * grid.cell_m, (i / grid.cols) as f64 * grid.cell_m);
            if inside_any(poly, at) {
                *l = Some(k);
            }
        }
    }
    let targets: Vec<(usize, f64)> =
        level.iter().enumerate().filter_map(|(i, l)| l.map(|k| (i, t.regions[k].level_m))).collect();
    let mut regions: Vec<(f64, Vec<usize>)> = t.regions.iter().map(|r| (r.level_m, Vec::new())).collect();
    for (i, l) in level.iter().enumerate() {
        if let Some(k) = l {
            regions[*k].1.push(i);
        }
    }
    let w = 1.0 / (targets.len().max(1) as f64 * grid.relief * grid.relief);
    let mut interest = vec![false; n];
    for &(i, _) in &targets {
        interest[i] = true;
    }
    // A sample is on an edge where a neighbour along a row or column wants another level or
    // none: there the terrain steps, and the small kernels fit the step cell by cell.
    let want = |i: usize| level[i].map(|k| t.regions[k].level_m);
    let (cols, rows) = (grid.cols, grid.rows);
    let edges: Vec<bool> = (0..n)
        .map(|i| {
            let (c, r) = (i % cols, i / cols);
            let neighbours = [
                (c > 0).then(|| i - 1),
                (c + 1 < cols).then(|| i + 1),
                (r > 0).then(|| i - cols),
                (r + 1 < rows).then(|| i + cols),
            ];
            level[i].is_some() && neighbours.into_iter().flatten().any(|j| want(j) != want(i))
        })
        .collect();
    Field {
        name: "terraces",
        weight: t.weight,
        quadratic: Some(Quadratic::from_terms(n, targets.iter().map(|&(i, l)| (i, w, l)))),
        one_sided: None,
        pairs: None,
        interest,
        anchors: Anchors::Edges(edges),
        detail: Detail::Terraces(TerraceDetail { targets, regions }),
    }
}

/// (sample, level) of every sample in a region.
pub fn targets(d: &TerraceDetail) -> &[(usize, f64)] {
    &d.targets
}

/// Per region: its level, its samples and their largest and RMS miss (metres); overall the
/// largest miss as a share of the relief.
pub fn figures(d: &TerraceDetail, h: &[f64], grid: &Grid) -> Value {
    let worst = d.targets.iter().fold(0.0f64, |m, &(i, t)| m.max((h[i] - t).abs()));
    let regions: Vec<Value> = d
        .regions
        .iter()
        .map(|(level, cells)| {
            let miss = cells.iter().fold(0.0f64, |m, &i| m.max((h[i] - level).abs()));
            let ss: f64 = cells.iter().map(|&i| (h[i] - level).powi(2)).sum();
            let rms = if cells.is_empty() { 0.0 } else { (ss / cells.len() as f64).sqrt() };
            json!({"level_m": level, "cells": cells.len(), "max_error_m": miss, "rms_error_m": rms})
        })
        .collect();
    json!({ "max_error_of_relief": worst / grid.relief, "regions": regions })
}
