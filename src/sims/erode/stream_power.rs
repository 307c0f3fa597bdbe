//! One implicit stream-power step, E = k·A^m·S^n, solved receivers first (Braun & Willett
//! 2013, generalised to multiple flow directions), with Yuan et al. 2019's deposition term.
//!
//! With the receivers' new heights known, a cell's new height h solves
//! `h = h̃ − Ψ·(Σ_k w_k (h − h_k)/ℓ_k)^n`, Ψ = k·Δt·A^m, where h̃ is its height after uplift
//! plus the sediment that settles on it, G·V/A (V the net volume eroded upstream in the last
//! iteration). For n = 1 that is a weighted mean of h̃ and the receivers' heights, stable for
//! any time step; otherwise a monotone root, found by safeguarded Newton steps.

use rayon::prelude::*;

use super::flow::{weights, Flow};
use super::grid::Grid;

/// The step's settings, in the units the request gives them.
#[derive(Clone, Copy, Debug)]
pub struct StreamPower {
    /// k·Δt.
    pub k_dt: f64,
    pub m: f64,
    pub n: f64,
    pub deposition_g: f64,
    pub flow_exponent: f64,
}

/// Newton steps at most for n ≠ 1 (each halves the bracket at worst).
const ROOT_STEPS: usize = 60;

impl StreamPower {
    /// Ψ = k·Δt·A^m for every cell, into `psi`.
    /// Outlets (never solved) are skipped, and a cell that drains only itself (a ridge, half
    /// the land) takes the one power of a cell's area worked out once: the same bits as its own
    /// `pow` would give, for a fraction of the time.
    /// `factor`, when given, multiplies each cell's k (a painted erodibility).
    pub fn psi(&self, area: &[f64], outlets: &[bool], cell_area: f64, factor: Option<&[f32]>, psi: &mut [f64]) {
        let (k_dt, m) = (self.k_dt, self.m);
        let single = k_dt * libm::pow(cell_area, m);
        psi.par_iter_mut().zip(area).zip(outlets).enumerate().for_each(|(i, ((p, &a), &o))| {
            *p = if o {
                0.0
            } else if a == cell_area {
                single
            } else {
                k_dt * libm::pow(a, m)
            };
            if let Some(f) = factor {
                *p *= f64::from(f[i]);
            }
        });
    }

    /// Solve every cell of `heights` (after uplift) into `next`, receivers first; outlets keep
    /// their height. `psi` from [`StreamPower::psi`] on the flow's area.
    pub fn solve(&self, grid: &Grid, heights: &[f64], outlets: &[bool], flow: &Flow, psi: &[f64], next: &mut [f64]) {
        for &i in flow.order.iter().rev() {
            let i = i as usize;
            let mask = flow.receivers[i];
            if mask == 0 || outlets[i] {
                next[i] = heights[i];
                continue;
            }
            let w = weights(grid, heights, i, mask, self.flow_exponent);
            let target = self.settled(grid, heights, flow, i);
            let mut f = [0.0; 8];
            let mut lowest = f64::INFINITY;
            for k in 0..8 {
                if mask & (1 << k) != 0 {
                    f[k] = w[k] / grid.length[k];
                    lowest = lowest.min(next[grid.inner(i, k)]);
                }
            }
            next[i] = if self.n == 1.0 {
                let (mut num, mut den) = (target, 1.0);
                for k in 0..8 {
                    if mask & (1 << k) != 0 {
                        let fk = psi[i] * f[k];
                        num += fk * next[grid.inner(i, k)];
                        den += fk;
                    }
                }
                num / den
            } else {
                self.root(grid, i, mask, &f, psi[i], target, lowest, next)
            };
        }
    }

    /// The thickness of sediment that settles on cell `i` in one step: G·V/A, but never more
    /// than the volume that arrives spread on the cell (G·V/A exceeds V/dx² where A is small).
    #[inline]
    fn deposit(&self, grid: &Grid, flow: &Flow, i: usize) -> f64 {
        let v = flow.sediment[i];
        if v <= 0.0 {
            return 0.0;
        }
        (self.deposition_g * v / flow.area[i]).min(v / (grid.cell * grid.cell))
    }

    /// h̃: the height after uplift plus the sediment that settles ([`StreamPower::deposit`]),
    /// but never above the highest of its donors (the neighbours that drain into it) with their
    /// own deposits: sediment does not pile above where it came from, yet a plain that aggrades
    /// as a whole (every cell a little above the next) may rise by more than the small drops
    /// between its cells. A cell with no donors gets nothing (no sediment reaches it).
    fn settled(&self, grid: &Grid, heights: &[f64], flow: &Flow, i: usize) -> f64 {
        if self.deposition_g == 0.0 {
            return heights[i];
        }
        let d = self.deposit(grid, flow, i);
        if d <= 0.0 {
            return heights[i];
        }
        let mut cap = heights[i];
        // A land cell on the border (when the border is not base level) lacks some neighbours.
        let border = grid.on_border(i);
        for k in 0..8 {
            let n = if border {
                let Some(n) = grid.neighbour(i, k) else { continue };
                n
            } else {
                grid.inner(i, k)
            };
            // N8 is symmetric: neighbour k's neighbour 7 − k is this cell.
            if flow.receivers[n] & (1 << (7 - k)) != 0 {
                cap = cap.max(heights[n] + self.deposit(grid, flow, n));
            }
        }
        (heights[i] + d).min(cap)
    }

    /// The root of x − h̃ + Ψ·(Σ_k f_k·max(0, x − h_k))^n on [lowest receiver, h̃]: monotone,
    /// so Newton steps kept inside a shrinking bracket converge.
    #[allow(clippy::too_many_arguments)]
    fn root(
        &self,
        grid: &Grid,
        i: usize,
        mask: u8,
        f: &[f64; 8],
        psi: f64,
        target: f64,
        lowest: f64,
        next: &[f64],
    ) -> f64 {
        if target <= lowest {
            return target;
        }
        let eval = |x: f64| {
            let (mut s, mut ds) = (0.0, 0.0);
            for k in 0..8 {
                if mask & (1 << k) != 0 {
                    let d = x - next[grid.inner(i, k)];
                    if d > 0.0 {
                        s += f[k] * d;
                        ds += f[k];
                    }
                }
            }
            if s <= 0.0 {
                return (x - target, 1.0);
            }
            let sn = libm::pow(s, self.n);
            (x - target + psi * sn, 1.0 + psi * self.n * sn / s * ds)
        };
        let (mut lo, mut hi) = (lowest, target);
        let mut x = target;
        for _ in 0..ROOT_STEPS {
            let (g, dg) = eval(x);
            // Converged: within rounding of the root, or the bracket closed.
            if g.abs() < 1e-12 || hi - lo < 1e-12 {
                break;
            }
            if g > 0.0 {
                hi = x;
            } else {
                lo = x;
            }
            let newton = x - g / dg;
            x = if newton > lo && newton < hi { newton } else { 0.5 * (lo + hi) };
        }
        x
    }
}
