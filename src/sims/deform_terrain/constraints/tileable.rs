//! `tileable`: opposite edges match each other, (h(0, r) − h(N − 1, r))² and the same for
//! rows, so the tile repeats without a seam; and the slope runs on across the wrap (C¹), the
//! first step in from one edge against the last step out to the other,
//! ((h₁ − h₀) − (h_{N−1} − h_{N−2}))², so no crease shows where the tiles meet.

use serde_json::{json, Value};

use super::{rms, Anchors, Detail, Field, Grid, Pairs, NO_PARTNER};
use crate::sims::deform_terrain::params::{TileAxes, Tileable};

pub fn build(t: &Tileable, grid: &Grid) -> Field {
    let (cols, rows, n) = (grid.cols, grid.rows, grid.cells());
    let x = matches!(t.edges, TileAxes::Both | TileAxes::X);
    let z = matches!(t.edges, TileAxes::Both | TileAxes::Z);
    let mut partner_x = vec![NO_PARTNER; n];
    let mut partner_z = vec![NO_PARTNER; n];
    let mut count = 0;
    if x {
        for r in 0..rows {
            let (a, b) = (r * cols, r * cols + cols - 1);
            partner_x[a] = b as u32;
            partner_x[b] = a as u32;
            count += 1;
        }
    }
    if z {
        for c in 0..cols {
            let (a, b) = (c, (rows - 1) * cols + c);
            partner_z[a] = b as u32;
            partner_z[b] = a as u32;
            count += 1;
        }
    }
    // The slope terms reach two samples in from each edge.
    let width = (t.band_cells as usize / 8).max(2);
    let kinks_x: Vec<[usize; 4]> = if x && cols >= 2 {
        (0..rows).map(|r| [r * cols + 1, r * cols + cols - 2, r * cols, r * cols + cols - 1]).collect()
    } else {
        Vec::new()
    };
    let kinks_z: Vec<[usize; 4]> = if z && rows >= 2 {
        (0..cols).map(|c| [cols + c, (rows - 2) * cols + c, c, (rows - 1) * cols + c]).collect()
    } else {
        Vec::new()
    };
    let mut interest = vec![false; n];
    for r in 0..rows {
        for c in 0..cols {
            let near_x = x && (c < width || c + width >= cols);
            let near_z = z && (r < width || r + width >= rows);
            interest[r * cols + c] = near_x || near_z;
        }
    }
    let scale = 1.0 / (count.max(1) as f64 * grid.relief * grid.relief);
    Field {
        name: "tileable",
        weight: t.weight,
        quadratic: None,
        one_sided: None,
        pairs: Some(Pairs { partner_x, partner_z, scale, kinks_x, kinks_z, kink_scale: scale }),
        interest,
        anchors: Anchors::Interest,
        detail: Detail::Tileable { x, z },
    }
}

/// RMS mismatch of opposite edges as a share of the relief.
pub fn figures(x: bool, z: bool, h: &[f64], grid: &Grid) -> Value {
    let (cols, rows) = (grid.cols, grid.rows);
    let mut diffs = Vec::new();
    if x {
        diffs.extend((0..rows).map(|r| h[r * cols] - h[r * cols + cols - 1]));
    }
    if z {
        diffs.extend((0..cols).map(|c| h[c] - h[(rows - 1) * cols + c]));
    }
    // The bend of slope across the wrap, per step over the cell size, as edge_match measures
    // its seam.
    let mut kinks = Vec::new();
    if x && cols >= 2 {
        kinks.extend((0..rows).map(|r| {
            let i = r * cols;
            (h[i + 1] - h[i]) - (h[i + cols - 1] - h[i + cols - 2])
        }));
    }
    if z && rows >= 2 {
        kinks.extend((0..cols).map(|c| (h[cols + c] - h[c]) - (h[(rows - 1) * cols + c] - h[(rows - 2) * cols + c])));
    }
    json!({
        "rms_mismatch_of_relief": rms(diffs.iter().copied()) / grid.relief,
        "max_mismatch_of_relief": diffs.iter().fold(0.0f64, |m, d| m.max(d.abs())) / grid.relief,
        "max_wrap_kink": kinks.iter().fold(0.0f64, |m, d| m.max(d.abs())) / grid.cell_m,
        "own_p99_kink": super::edge_match::p99_kink(h, cols, rows, grid.cell_m),
    })
}
