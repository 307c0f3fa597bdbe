//! Sediment that a river carries into the sea settles there as a delta: it runs from the
//! mouth down the sea floor's steepest way, filling each cell it crosses up to a shoreface
//! surface just under the sea level that deepens away from the mouth ([`SHOREFACE_SLOPE`]), but
//! never more than [`FRONT_SLOPE`] above the deepest cell beside it, until it is spent — the
//! mouth's marine deposition to base level, in the manner of FastScape's marine component
//! (Yuan et al. 2019), without a separate marine transport law. A path that has filled its way
//! blocks itself, so the next step's sediment takes another and the deposit spreads as lobes;
//! the front slope keeps the delta's edge a ramp down to the sea floor, not a wall.
//!
//! Each step of the path goes to the lowest sea neighbour not yet crossed (ties to the lower
//! index), so the result depends on nothing but the heights. What cannot settle within
//! [`MAX_CELLS`] cells of the mouth, or where the path meets the grid's border or a dead end,
//! leaves the grid.

use super::grid::Grid;

/// The deposit's top near the mouth stands this far under the sea level, m: it stays sea.
pub const TOP_DEPTH_M: f64 = 0.05;
/// How fast the shoreface the deposit builds deepens away from the mouth, m/m (shorefaces and
/// delta fronts slope 0.5–2 %).
pub const SHOREFACE_SLOPE: f64 = 0.01;
/// Steepest the deposit stands above the sea floor beside it, m/m (about 17°: delta foresets
/// dip 10–25°), so the delta's front is a slope down to the sea floor and not a wall.
pub const FRONT_SLOPE: f64 = 0.3;
/// Most sea cells one mouth's sediment crosses in one step (a bound on the work).
pub const MAX_CELLS: usize = 1 << 14;

/// The delta builder's reusable buffer.
pub struct Marine {
    /// The path each cell was last crossed by, so nothing is cleared between paths.
    stamp: Vec<u32>,
    visit: u32,
}

impl Marine {
    pub fn new(cells: usize) -> Self {
        Self { stamp: vec![0; cells], visit: 0 }
    }

    /// Settle `volume_m3` arriving at sea cell `mouth` along its path down the sea floor (`sea`
    /// cells off the grid's border). Returns the volume left over, which leaves the grid.
    pub fn settle(
        &mut self,
        grid: &Grid,
        heights: &mut [f64],
        sea: impl Fn(usize) -> bool,
        sea_level: f64,
        mouth: usize,
        volume_m3: f64,
    ) -> f64 {
        let area = grid.cell * grid.cell;
        let mut left = volume_m3 / area;
        if left <= 0.0 {
            return 0.0;
        }
        self.visit = self.visit.wrapping_add(1);
        if self.visit == 0 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.visit = 1;
        }
        let visit = self.visit;
        let (mut at, mut d) = (mouth, 0.0);
        let (cols, rows) = (grid.cols, grid.rows);
        for _ in 0..MAX_CELLS {
            self.stamp[at] = visit;
            // One look at the neighbours: the lowest of them all (the front's foot), and the
            // lowest sea cell off the border not yet crossed (ties to the lower index: the first
            // in N8's order), where the path goes next. Filling `at` changes neither.
            let (c, r) = (at % cols, at / cols);
            let inside = c > 0 && r > 0 && c + 1 < cols && r + 1 < rows;
            // No neighbour of a cell two in from every edge lies on the border.
            let clear_of_border = c > 1 && r > 1 && c + 2 < cols && r + 2 < rows;
            let mut lowest = f64::INFINITY;
            let mut next: Option<(usize, usize)> = None;
            for k in 0..8 {
                let n = if inside {
                    grid.inner(at, k)
                } else {
                    let Some(n) = grid.neighbour(at, k) else { continue };
                    n
                };
                let hn = heights[n];
                lowest = lowest.min(hn);
                if self.stamp[n] == visit || !sea(n) || (!clear_of_border && grid.on_border(n)) {
                    continue;
                }
                if next.is_none_or(|(m, _)| hn < heights[m]) {
                    next = Some((n, k));
                }
            }
            let front = lowest + FRONT_SLOPE * grid.cell;
            let top = (sea_level - TOP_DEPTH_M - SHOREFACE_SLOPE * d).min(front);
            if heights[at] < top {
                let fill = (top - heights[at]).min(left);
                heights[at] += fill;
                left -= fill;
                if left <= 0.0 {
                    return 0.0;
                }
            }
            let Some((n, k)) = next else { break };
            d += grid.length[k];
            at = n;
        }
        left * area
    }
}
