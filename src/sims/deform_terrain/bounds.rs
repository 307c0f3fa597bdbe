//! What the search may never do, whatever the fitness says: move a sample further from its
//! input height than a constraint can need, or make any step between neighbouring samples
//! steeper than the input's steepest (times `max_slope_ratio`).
//!
//! The paper limits each operation's displacement to a share of its radius "to avoid
//! unwanted spikes" (§3.4), but nothing limits operations stacked on one another: a kernel
//! centred on a sample no constraint looks at fixes a constrained sample in its tail for free
//! and moves its own centre by the residual over the tail's weight, again and again. Free
//! terrain drifted by more than its whole relief, past seam bands it rose in 20 m steps, and
//! the sea beside a mask's coast was dug in round pits. These limits are the paper's, kept
//! over the whole sequence: the input satisfies them, and every operation is clamped to the
//! displacements that keep them (a convex fitness still improves along a shortened step).
//!
//! What a constraint can need at a sample (its "wanted" change) is read off the constraints:
//! a quadratic target's distance from the input, a mask's shortfall, a tiled edge's mismatch
//! with its partner. Each spreads as a cone, falling by half the steepest allowed step per
//! cell of distance, so transitions have room; the cone is a constraint's footprint. Outside
//! every footprint a sample may move by `max_free_change` of the relief. A seam band's wants
//! do not spread: the band is the transition, and samples past it keep to the smaller of the
//! free limit and the band's own largest wanted change.

use super::constraints::{Detail, Field, Grid, NO_PARTNER};
use super::kernel::{Kernel, Rect};

/// A footprint's allowance over its wanted change: room for the kernels' overshoot.
const HEADROOM: f64 = 1.25;
/// And a floor, as a share of the relief, so a target the input meets can still be fitted.
const HEADROOM_OF_RELIEF: f64 = 0.02;
/// The slope limit on a flat input, metres per metre.
const FLAT_SLOPE: f64 = 0.05;

pub struct Bounds {
    cols: usize,
    rows: usize,
    /// Per sample, the lowest and highest height allowed.
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// The largest height difference allowed between row or column neighbours, metres.
    pub step_max: f64,
    /// Samples some constraint needs to move, or the transitions around them.
    pub footprint: Vec<bool>,
    /// Samples some constraint needs to move.
    pub asked: Vec<bool>,
}

/// The steepest slope a result of `original` may have, metres per metre: the input's steepest
/// step times `max_slope_ratio`, and at least 5 % (a flat input).
pub fn slope_limit(original: &[f64], cols: usize, rows: usize, cell_m: f64, max_slope_ratio: f64) -> f64 {
    (steepest_step(original, cols, rows) / cell_m * max_slope_ratio).max(FLAT_SLOPE)
}

/// The steepest step between row or column neighbours, metres.
pub fn steepest_step(h: &[f64], cols: usize, rows: usize) -> f64 {
    let mut m = 0.0f64;
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            if c + 1 < cols {
                m = m.max((h[i + 1] - h[i]).abs());
            }
            if r + 1 < rows {
                m = m.max((h[i + cols] - h[i]).abs());
            }
        }
    }
    m
}

/// Per sample, the change the constraints can need: (spreading, not spreading).
fn wanted(fields: &[Field], grid: &Grid) -> (Vec<f64>, Vec<f64>) {
    let n = grid.cells();
    let o = grid.original;
    let (mut spread, mut own) = (vec![0.0f64; n], vec![0.0f64; n]);
    // A target summed from several terms that equals the input comes back a rounding away
    // from it: that is no change wanted.
    let least = 1e-6 * grid.relief;
    for f in fields {
        let into = if matches!(f.detail, Detail::EdgeMatch(_)) { &mut own } else { &mut spread };
        if let Some(q) = &f.quadratic {
            for i in 0..n {
                if q.w[i] > 0.0 {
                    into[i] = into[i].max((q.t[i] - o[i]).abs());
                }
            }
        }
        if let Some(m) = &f.one_sided {
            for i in 0..n {
                let short = match m.side[i] {
                    1 => m.lo - o[i],
                    -1 => o[i] - m.hi,
                    _ => 0.0,
                };
                into[i] = into[i].max(short);
            }
        }
        if let Some(p) = &f.pairs {
            for i in 0..n {
                for j in [p.partner_x[i], p.partner_z[i]] {
                    if j != NO_PARTNER {
                        into[i] = into[i].max((o[i] - o[j as usize]).abs());
                    }
                }
            }
        }
    }
    for w in spread.iter_mut().chain(own.iter_mut()) {
        if *w <= least {
            *w = 0.0;
        }
    }
    (spread, own)
}

/// `a[i] = max over j of (a[j] − fall × distance(i, j))` by two chamfer passes (steps of 1 and
/// √2 cells): a distance at least the Euclidean one, so the cone is never wider than asked.
fn cone(a: &mut [f64], cols: usize, rows: usize, fall: f64) {
    let diagonal = fall * std::f64::consts::SQRT_2;
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            let mut v = a[i];
            if c > 0 {
                v = v.max(a[i - 1] - fall);
            }
            if r > 0 {
                v = v.max(a[i - cols] - fall);
                if c > 0 {
                    v = v.max(a[i - cols - 1] - diagonal);
                }
                if c + 1 < cols {
                    v = v.max(a[i - cols + 1] - diagonal);
                }
            }
            a[i] = v;
        }
    }
    for r in (0..rows).rev() {
        for c in (0..cols).rev() {
            let i = r * cols + c;
            let mut v = a[i];
            if c + 1 < cols {
                v = v.max(a[i + 1] - fall);
            }
            if r + 1 < rows {
                v = v.max(a[i + cols] - fall);
                if c + 1 < cols {
                    v = v.max(a[i + cols + 1] - diagonal);
                }
                if c > 0 {
                    v = v.max(a[i + cols - 1] - diagonal);
                }
            }
            a[i] = v;
        }
    }
}

impl Bounds {
    /// `max_free_change`: share of the relief a sample outside every footprint may move. Steps
    /// are held to the grid's slope limit ([`slope_limit`]).
    pub fn new(fields: &[Field], grid: &Grid, max_free_change: f64) -> Self {
        let (cols, rows, n) = (grid.cols, grid.rows, grid.cells());
        let o = grid.original;
        let step_max = grid.slope_limit * grid.cell_m;
        let (mut spread, own) = wanted(fields, grid);
        let asked = (0..n).map(|i| spread[i] > 0.0 || own[i] > 0.0).collect();
        let pad = HEADROOM_OF_RELIEF * grid.relief;
        let grow = |w: f64| if w > 0.0 { w * HEADROOM + pad } else { 0.0 };
        for w in spread.iter_mut() {
            *w = grow(*w);
        }
        cone(&mut spread, cols, rows, 0.5 * step_max);
        let band_max = own.iter().fold(0.0f64, |m, &w| m.max(w));
        let mut free = max_free_change * grid.relief;
        if band_max > 0.0 {
            free = free.min(band_max);
        }
        let footprint: Vec<bool> = (0..n).map(|i| spread[i] > 0.0 || own[i] > 0.0).collect();
        let allow: Vec<f64> = (0..n).map(|i| spread[i].max(grow(own[i])).max(free)).collect();
        Self {
            cols,
            rows,
            lo: (0..n).map(|i| o[i] - allow[i]).collect(),
            hi: (0..n).map(|i| o[i] + allow[i]).collect(),
            step_max,
            footprint,
            asked,
        }
    }

    /// The displacements `d` of the centre of a deformation at (col, row) with `kernel` (every
    /// sample moving by d·K) that keep every limit from heights `h`: an interval, holding 0
    /// when `h` keeps them. Samples beyond the window have K = 0, as do those on its rim, so the
    /// steps inside it are all that can change.
    pub fn range(&self, h: &[f64], col: usize, row: usize, kernel: &Kernel) -> (f64, f64) {
        self.range_on(h, col, row, kernel, 1)
    }

    /// [`Bounds::range`] estimated from the samples of the window's lattice through its
    /// centre every `stride` cells (and the steps from each to its next neighbours), as the
    /// search estimates a wide window's change; 1 is exact.
    pub fn range_on(&self, h: &[f64], col: usize, row: usize, kernel: &Kernel, stride: usize) -> (f64, f64) {
        let (cols, rows) = (self.cols, self.rows);
        let rect = Rect::around(col, row, kernel.radius, cols, rows);
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        let at = |c: usize, r: usize| kernel.at(c as i64 - col as i64, r as i64 - row as i64);
        // The first lattice line at or after `from`: lattice lines pass through the centre.
        let first = |from: usize, centre: usize| from + (centre - from) % stride;
        for r in (first(rect.r0, row)..=rect.r1).step_by(stride) {
            for c in (first(rect.c0, col)..=rect.c1).step_by(stride) {
                let i = r * cols + c;
                let k = at(c, r);
                if k > 0.0 {
                    lo = lo.max((self.lo[i] - h[i]) / k);
                    hi = hi.min((self.hi[i] - h[i]) / k);
                }
                let right = (c + 1 < cols).then(|| (i + 1, at(c + 1, r)));
                let down = (r + 1 < rows).then(|| (i + cols, at(c, r + 1)));
                for (j, kj) in right.into_iter().chain(down) {
                    let e = k - kj;
                    if e != 0.0 {
                        let s = h[i] - h[j];
                        let (a, b) = ((-self.step_max - s) / e, (self.step_max - s) / e);
                        lo = lo.max(a.min(b));
                        hi = hi.min(a.max(b));
                    }
                }
            }
        }
        (lo, hi)
    }

    /// Whether `h` keeps every limit (within `slack` metres).
    #[cfg(test)]
    pub fn kept(&self, h: &[f64], slack: f64) -> bool {
        let heights = (0..h.len()).all(|i| h[i] >= self.lo[i] - slack && h[i] <= self.hi[i] + slack);
        heights && steepest_step(h, self.cols, self.rows) <= self.step_max + slack
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cone_falls_by_the_chamfer_distance_and_never_faster_than_euclid() {
        let (cols, rows) = (21, 21);
        let mut a = vec![0.0; cols * rows];
        a[10 * cols + 10] = 10.0;
        cone(&mut a, cols, rows, 1.0);
        assert_eq!(a[10 * cols + 13], 7.0);
        assert!((a[13 * cols + 13] - (10.0 - 3.0 * std::f64::consts::SQRT_2)).abs() < 1e-12);
        for r in 0..rows {
            for c in 0..cols {
                let d = ((r as f64 - 10.0).powi(2) + (c as f64 - 10.0).powi(2)).sqrt();
                assert!(a[r * cols + c] <= (10.0 - d).max(0.0) + 1e-12, "({c}, {r})");
            }
        }
    }

    #[test]
    fn a_range_keeps_every_sample_and_step_it_reaches() {
        // A ramp 0.5 m a step along x; limits ±1 m everywhere (no constraint): a deformation's
        // displacement is held to what keeps both, checked by applying the ends.
        let (cols, rows) = (15, 11);
        let o: Vec<f64> = (0..cols * rows).map(|i| (i % cols) as f64 * 0.5).collect();
        let grid = Grid { cols, rows, cell_m: 1.0, original: &o, relief: 7.0, slope_limit: 0.6 };
        let b = Bounds::new(&[], &grid, 1.0 / 7.0);
        assert!((b.step_max - 0.6).abs() < 1e-12);
        let k = Kernel::new(3);
        let (lo, hi) = b.range(&o, 7, 5, &k);
        assert!(lo < 0.0 && hi > 0.0 && hi <= 1.0 + 1e-12 && lo >= -1.0 - 1e-12, "{lo} {hi}");
        for d in [lo, hi] {
            let mut h = o.clone();
            super::super::kernel::apply(&mut h, cols, rows, 7, 5, o[5 * cols + 7] + d, &k);
            assert!(b.kept(&h, 1e-9), "{d}");
            // A little beyond the end breaks a limit.
            let mut h = o.clone();
            super::super::kernel::apply(&mut h, cols, rows, 7, 5, o[5 * cols + 7] + d * 1.01, &k);
            assert!(!b.kept(&h, 1e-9), "{d}");
        }
    }
}
