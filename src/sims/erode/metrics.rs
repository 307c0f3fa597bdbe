//! Measures of how much a terrain looks like eroded land, on its f32 heights with single
//! (steepest, D8) flow directions, as geomorphologists measure real DEMs:
//!
//! - **pits**: land cells a plain Priority-Flood would fill by more than 1 mm;
//! - **channel concavity θ** (Flint 1974): S ∝ A^−θ, fitted on channel cells (draining at least
//!   64 cells) binned by log-area; real rivers give 0.3–0.7, about 0.45 typically;
//! - **Hack's exponent** (Hack 1957): the longest flow path to a cell L ∝ A^h; 0.5–0.6 in nature;
//! - **hypsometric integral** (Strahler 1952): (mean − base) / (max − base) of the land.

use std::cmp::Ordering;

use super::flood::fill;
use super::grid::Grid;
use crate::terrain::Heightfield;

/// Cells a channel drains at least.
pub const CHANNEL_CELLS: f64 = 64.0;
/// Metres of fill above which a cell counts as in a pit.
pub const PIT_DEPTH_M: f64 = 1e-3;
/// Bins of log-area per decade in the θ and Hack fits.
const BINS_PER_DECADE: f64 = 10.0;
/// Fewest cells a bin needs to be fitted.
const BIN_CELLS: usize = 10;

/// Steepest-descent drainage on a surface.
pub struct D8 {
    pub grid: Grid,
    pub heights: Vec<f64>,
    /// Land cells: above the sea and off the grid's border.
    pub land: Vec<bool>,
    /// Each cell's steepest lower neighbour (for land cells that have one).
    pub receiver: Vec<Option<usize>>,
    /// Slope to it, m/m.
    pub slope: Vec<f64>,
    /// Drainage area in cells.
    pub area: Vec<f64>,
    /// Longest flow path from a divide to the cell, m.
    pub length: Vec<f64>,
}

impl D8 {
    pub fn new(hf: &Heightfield, sea_level: f32) -> Self {
        let grid = Grid::new(hf.cols, hf.rows, f64::from(hf.cell_size_m));
        let heights: Vec<f64> = hf.heights_m.iter().map(|&h| f64::from(h)).collect();
        let land: Vec<bool> = (0..grid.cells()).map(|i| !grid.on_border(i) && hf.heights_m[i] > sea_level).collect();
        let n = grid.cells();
        let mut receiver = vec![None; n];
        let mut slope = vec![0.0; n];
        for i in (0..n).filter(|&i| land[i]) {
            for k in 0..8 {
                let j = grid.inner(i, k);
                let s = (heights[i] - heights[j]) / grid.length[k];
                if s > slope[i] {
                    slope[i] = s;
                    receiver[i] = Some(j);
                }
            }
        }
        // Highest first: every donor is strictly higher than its receiver.
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| heights[b].partial_cmp(&heights[a]).unwrap_or(Ordering::Equal).then(a.cmp(&b)));
        let mut area = vec![1.0; n];
        let mut length = vec![0.0f64; n];
        for &i in &order {
            if let Some(j) = receiver[i] {
                area[j] += area[i];
                let diagonal = i % grid.cols != j % grid.cols && i / grid.cols != j / grid.cols;
                let l = length[i] + if diagonal { grid.cell * std::f64::consts::SQRT_2 } else { grid.cell };
                length[j] = length[j].max(l);
            }
        }
        Self { grid, heights, land, receiver, slope, area, length }
    }

    /// θ from the slope–area fit of channel cells: `(θ, R²)`, None with fewer than two bins.
    pub fn concavity(&self) -> Option<(f64, f64)> {
        let cells = (0..self.grid.cells()).filter(|&i| self.channel(i) && self.slope[i] >= 1e-4);
        let fit = binned_fit(cells.map(|i| (self.area[i].log10(), self.slope[i].log10())))?;
        Some((-fit.0, fit.1))
    }

    /// Hack's exponent h from the length–area fit of channel cells: `(h, R²)`.
    pub fn hack(&self) -> Option<(f64, f64)> {
        let cells = (0..self.grid.cells()).filter(|&i| self.channel(i) && self.length[i] > 0.0);
        binned_fit(cells.map(|i| (self.area[i].log10(), self.length[i].log10())))
    }

    fn channel(&self, i: usize) -> bool {
        self.land[i] && self.area[i] >= CHANNEL_CELLS
    }
}

/// Median y against median x in bins of x (tenths of a decade, at least [`BIN_CELLS`] points
/// each), fitted by least squares: `(slope, R²)`.
fn binned_fit(points: impl Iterator<Item = (f64, f64)>) -> Option<(f64, f64)> {
    let mut points: Vec<(f64, f64)> = points.collect();
    points.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(Ordering::Equal));
    let mut bins = Vec::new();
    let mut start = 0;
    while start < points.len() {
        let bin = (points[start].0 * BINS_PER_DECADE).floor();
        let end = start + points[start..].iter().take_while(|p| (p.0 * BINS_PER_DECADE).floor() == bin).count();
        if end - start >= BIN_CELLS {
            let mut ys: Vec<f64> = points[start..end].iter().map(|p| p.1).collect();
            ys.sort_by(|a, b| a.partial_cmp(b).unwrap_or(Ordering::Equal));
            bins.push((points[start + (end - start) / 2].0, ys[ys.len() / 2]));
        }
        start = end;
    }
    least_squares(&bins)
}

/// Ordinary least squares of y on x: `(slope, R²)`.
pub fn least_squares(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = points.iter().fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
    let (sxy, sxx, syy) = points.iter().fold((0.0, 0.0, 0.0), |(xy, xx, yy), p| {
        let (dx, dy) = (p.0 - mx, p.1 - my);
        (xy + dx * dy, xx + dx * dx, yy + dy * dy)
    });
    if sxx == 0.0 {
        return None;
    }
    let r2 = if syy == 0.0 { 1.0 } else { sxy * sxy / (sxx * syy) };
    Some((sxy / sxx, r2))
}

/// Share of land cells (above `sea_level`, off the border) that a plain Priority-Flood fills
/// by at most [`PIT_DEPTH_M`]; 1 with no land.
pub fn drained_share(hf: &Heightfield, sea_level: f32) -> f64 {
    let grid = Grid::new(hf.cols, hf.rows, f64::from(hf.cell_size_m));
    let before: Vec<f64> = hf.heights_m.iter().map(|&h| f64::from(h)).collect();
    let outlets: Vec<bool> = (0..grid.cells()).map(|i| grid.on_border(i) || hf.heights_m[i] <= sea_level).collect();
    let mut filled = before.clone();
    fill(&grid, &mut filled, &outlets, 0.0);
    let land = outlets.iter().filter(|&&o| !o).count();
    if land == 0 {
        return 1.0;
    }
    let drained = (0..grid.cells()).filter(|&i| !outlets[i] && filled[i] - before[i] <= PIT_DEPTH_M).count();
    drained as f64 / land as f64
}

/// Strahler's hypsometric integral of the cells `mask` selects: (mean − base) / (max − base),
/// with `base` the sea level; None when no selected cell stands above it.
pub fn hypsometric_integral(hf: &Heightfield, mask: &[bool], base: f32) -> Option<f64> {
    let (mut sum, mut count, mut max) = (0.0f64, 0usize, f64::NEG_INFINITY);
    for (&h, _) in hf.heights_m.iter().zip(mask).filter(|(_, &m)| m) {
        sum += f64::from(h);
        count += 1;
        max = max.max(f64::from(h));
    }
    let base = f64::from(base);
    (count > 0 && max > base).then(|| (sum / count as f64 - base) / (max - base))
}

/// Share of cells whose steepest drop to a neighbour is within `angle_deg`.
pub fn within_angle_share(hf: &Heightfield, angle_deg: f64) -> f64 {
    let grid = Grid::new(hf.cols, hf.rows, f64::from(hf.cell_size_m));
    let tan = libm::tan(angle_deg.to_radians());
    let within = (0..grid.cells())
        .filter(|&i| {
            (0..8).all(|k| {
                grid.neighbour(i, k)
                    .is_none_or(|j| f64::from(hf.heights_m[i]) - f64::from(hf.heights_m[j]) <= tan * grid.length[k])
            })
        })
        .count();
    within as f64 / grid.cells() as f64
}
