//! Where water goes: each land cell sends its flow to all its lower neighbours, split by slope
//! to a power times the contour length crossed (multiple flow directions, Quinn et al. 1991),
//! and the cells in an order where
//! every cell comes after all the cells that drain into it.
//!
//! The order is built by Kahn's algorithm over the donor counts (one sequential pass, O(n));
//! drainage area and the sediment carried from upstream are accumulated in the same pass.

use rayon::prelude::*;

use super::grid::Grid;

/// The drainage graph of one iteration.
pub struct Flow {
    /// Bit k set when neighbour k of [`super::grid::N8`] is lower: the cell's receivers.
    /// Outlets have none.
    pub receivers: Vec<u8>,
    /// Every cell, donors before receivers.
    pub order: Vec<u32>,
    /// Drainage area, m²: the cell's own and all it receives.
    pub area: Vec<f64>,
    /// Net volume eroded upstream that reaches the cell, m³ (Yuan et al. 2019's ∫(U − ∂h/∂t)dA,
    /// over the previous iteration), the cell's own excluded.
    pub sediment: Vec<f64>,
    donors: Vec<u8>,
}

impl Flow {
    pub fn new(cells: usize) -> Self {
        Self {
            receivers: vec![0; cells],
            order: Vec::with_capacity(cells),
            area: vec![0.0; cells],
            sediment: vec![0.0; cells],
            donors: vec![0; cells],
        }
    }

    /// Build the graph on `heights` and accumulate area and the sediment from `eroded` (each
    /// cell's net loss in the previous iteration, m³).
    pub fn route(&mut self, grid: &Grid, heights: &[f64], outlets: &[bool], eroded: &[f64], exponent: f64) {
        let cols = grid.cols;
        self.receivers.par_chunks_mut(cols).zip(self.donors.par_chunks_mut(cols)).enumerate().for_each(
            |(r, (receivers, donors))| {
                let inner_row = r > 0 && r + 1 < grid.rows;
                for c in 0..cols {
                    let i = r * cols + c;
                    let h = heights[i];
                    let mut mask = 0u8;
                    let mut count = 0u8;
                    let mut visit = |k: usize, n: usize| {
                        if heights[n] < h {
                            mask |= 1 << k;
                        } else if heights[n] > h && !outlets[n] {
                            count += 1;
                        }
                    };
                    // Inner cells (nearly all) skip the bounds checks; the order is the same.
                    if inner_row && c > 0 && c + 1 < cols {
                        (0..8).for_each(|k| visit(k, grid.inner(i, k)));
                    } else {
                        (0..8).for_each(|k| {
                            if let Some(n) = grid.neighbour(i, k) {
                                visit(k, n)
                            }
                        });
                    }
                    receivers[c] = if outlets[i] { 0 } else { mask };
                    donors[c] = count;
                }
            },
        );
        let area0 = grid.cell * grid.cell;
        self.area.par_iter_mut().for_each(|a| *a = area0);
        self.sediment.par_iter_mut().for_each(|v| *v = 0.0);
        self.order.clear();
        let mut stack: Vec<u32> = (0..grid.cells() as u32).filter(|&i| self.donors[i as usize] == 0).rev().collect();
        while let Some(j) = stack.pop() {
            let j = j as usize;
            self.order.push(j as u32);
            let mask = self.receivers[j];
            if mask == 0 {
                continue;
            }
            let w = weights(grid, heights, j, mask, exponent);
            let (a, v) = (self.area[j], self.sediment[j] + eroded[j]);
            for (k, &wk) in w.iter().enumerate() {
                if mask & (1 << k) == 0 {
                    continue;
                }
                let n = grid.inner(j, k);
                self.area[n] += a * wk;
                self.sediment[n] += v * wk;
                self.donors[n] -= 1;
                if self.donors[n] == 0 {
                    stack.push(n as u32);
                }
            }
        }
        debug_assert_eq!(self.order.len(), grid.cells(), "the drainage graph has a cycle");
    }

    /// Raise every land cell to at least `epsilon` above its lowest receiver, receivers first,
    /// so each keeps a lower neighbour whatever moved since the graph was built. Returns the
    /// volume added, m³.
    pub fn raise_to_drain(&self, grid: &Grid, heights: &mut [f64], epsilon: f64) -> f64 {
        let mut added = 0.0;
        for &i in self.order.iter().rev() {
            let i = i as usize;
            let mask = self.receivers[i];
            if mask == 0 {
                continue;
            }
            let lowest = (0..8)
                .filter(|k| mask & (1 << k) != 0)
                .map(|k| heights[grid.inner(i, k)])
                .fold(f64::INFINITY, f64::min);
            let floor = lowest + epsilon;
            if heights[i] < floor {
                added += floor - heights[i];
                heights[i] = floor;
            }
        }
        added * grid.cell * grid.cell
    }
}

/// The share of cell `i`'s flow each receiver in `mask` takes: slope to the `exponent` times
/// the contour length towards it (Quinn et al. 1991), normalised (zero for neighbours that are
/// not receivers).
#[inline]
pub fn weights(grid: &Grid, heights: &[f64], i: usize, mask: u8, exponent: f64) -> [f64; 8] {
    let mut w = [0.0; 8];
    let mut sum = 0.0;
    for k in 0..8 {
        if mask & (1 << k) != 0 {
            let s = (heights[i] - heights[grid.inner(i, k)]) / grid.length[k];
            w[k] = grid.contour[k] * if exponent == 1.0 { s } else { libm::pow(s, exponent) };
            sum += w[k];
        }
    }
    for x in &mut w {
        *x /= sum;
    }
    w
}
