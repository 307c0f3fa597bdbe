//! Talus-angle relaxation (Musgrave, Kolb & Mace 1989; Olsen 2004): wherever the drop to a
//! neighbour exceeds the talus slope, `rate` of the excess moves down to it.
//!
//! Each sweep gathers from the old heights into a second buffer, so no cell sees another's
//! update and the result does not depend on the thread count. A drop computed from either
//! side is the same number negated (IEEE subtraction is antisymmetric), so each edge's flux
//! leaves one cell exactly as it enters the other: the material is conserved to rounding.
//! With rate ≤ 1/8 no cell gives away more than its excess over all eight neighbours, so a
//! sweep never overshoots. With the fluvial step on, the grid's border is a sink: it keeps its
//! height (the rivers' base level) and what slides into it leaves the grid.

use rayon::prelude::*;

use super::grid::Grid;

/// Sweep settings: the talus drop to each neighbour of [`super::grid::N8`] and the rate.
#[derive(Clone, Copy, Debug)]
pub struct Talus {
    pub drop: [f64; 8],
    pub rate: f64,
}

impl Talus {
    pub fn new(grid: &Grid, talus_angle_deg: f64, rate: f64) -> Self {
        let tan = libm::tan(talus_angle_deg.to_radians());
        Self { drop: grid.length.map(|l| tan * l), rate }
    }

    /// One sweep from `from` into `to`. With `open_border` (the fluvial step on, whose base level
    /// the border is) the grid's border cells keep their height: material that slides into one
    /// leaves the grid, as sediment does, and none slides out of one. Sea cells take what slides
    /// into them either way, so a collapsing coast builds its own slope under the water.
    pub fn sweep(&self, grid: &Grid, from: &[f64], to: &mut [f64], open_border: bool) {
        let cols = grid.cols;
        to.par_chunks_mut(cols).enumerate().for_each(|(r, out)| {
            for (c, h) in out.iter_mut().enumerate() {
                let i = r * cols + c;
                let hi = from[i];
                let inner = r > 0 && r + 1 < grid.rows && c > 0 && c + 1 < cols;
                if open_border && !inner {
                    *h = hi;
                    continue;
                }
                let mut flux = 0.0;
                for k in 0..8 {
                    // Inner cells (nearly all) skip the bounds checks.
                    let n = if inner {
                        grid.inner(i, k)
                    } else {
                        match grid.neighbour(i, k) {
                            Some(n) => n,
                            None => continue,
                        }
                    };
                    let d = from[n] - hi;
                    let t = self.drop[k];
                    if d > t {
                        if open_border && grid.on_border(n) {
                            continue;
                        }
                        flux += d - t;
                    } else if d < -t {
                        flux += d + t;
                    }
                }
                *h = hi + self.rate * flux;
            }
        });
    }

    /// The largest drop beyond the talus slope between any two neighbours, metres.
    pub fn max_excess(&self, grid: &Grid, heights: &[f64]) -> f64 {
        heights
            .par_chunks(grid.cols)
            .enumerate()
            .map(|(r, row)| {
                let mut worst = 0.0f64;
                for c in 0..row.len() {
                    let i = r * grid.cols + c;
                    for k in 0..8 {
                        if let Some(n) = grid.neighbour(i, k) {
                            worst = worst.max(heights[i] - heights[n] - self.drop[k]);
                        }
                    }
                }
                worst
            })
            .reduce(|| 0.0, f64::max)
    }
}
