//! What a limited job's result must not do, whatever the constraints' fitness says: move a
//! sample no constraint needs by more than `max_free_change` of the relief, or make any step
//! between neighbouring samples steeper than a high percentile of the input's steps (times
//! `max_slope_ratio`) or than the input's own step there.
//!
//! The paper limits each operation's displacement to a share of its radius "to avoid
//! unwanted spikes" (§3.4), but nothing limits operations stacked on one another: a kernel
//! centred on a sample no constraint looks at fixes a constrained sample in its tail for free
//! and moves its own centre by the residual over the tail's weight, again and again. Free
//! terrain drifted by more than its whole relief, past seam bands it rose in 20 m steps, and
//! the sea beside a mask's coast was dug in round pits.
//!
//! What a constraint needs at a sample is read off the constraints: its samples' targets (a
//! quadratic target, a mask's side of the water, a tiled edge's partner) are the sources of
//! an earthwork whose faces climb or fall from them until they meet the input ground, as a
//! road's cutting daylights: a target's at the request's cut and fill slopes (the faces the
//! projection builds), a mask's or a seam's at 0.8 × the slope limit. That change, with
//! headroom, spreads as a cone falling by half the steepest allowed step per cell, so
//! transitions have room; the cone is a constraint's footprint. Inside a footprint only the
//! slope is limited; outside every footprint a sample may move by `max_free_change` of the
//! relief. A seam band's wants do not spread: the band is the transition, and samples past it
//! keep to the smaller of the free limit and the band's own largest wanted change.
//!
//! The search pulls the samples outside every footprint back to their input heights (the
//! request's `keep_weight`, a quadratic term on its fast path); the projection after it holds
//! the slope limit and the band exactly ([`super::projection`]). The search once weighed the
//! limits as penalties on every sample and step of each deformation's window: 1.7–5.8 times
//! the cost of an evaluation without them, and the examples ran 2–10 times longer than the
//! search without limits. Holding each operation to them (clamping its displacement) stalled
//! it, as a wide kernel over a shoulder already at the slope limit could then never move the
//! way that steepens it.

use super::constraints::{Detail, Field, Grid, NO_PARTNER};

/// A footprint's allowance over its wanted change: room for the kernels' overshoot.
const HEADROOM: f64 = 1.25;
/// And a floor, as a share of the relief, so a target the input meets can still be fitted.
const HEADROOM_OF_RELIEF: f64 = 0.02;
/// The earthworks' faces, as a share of the steepest step allowed: room for the search to lay
/// them back under the limit.
const EARTHWORK_SLOPE: f64 = 0.8;
/// The slope limit on a flat input, metres per metre.
const FLAT_SLOPE: f64 = 0.05;

pub struct Bounds {
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

/// The steepest slope a result of `original` may have, metres per metre: the input's steps'
/// `percentile` (100: its steepest) times `max_slope_ratio`, and at least 5 % (a flat input).
/// A percentile rather than the single steepest step: on a fractal that one step is 57–60°,
/// and every face built to it was a wall.
pub fn slope_limit(
    original: &[f64],
    cols: usize,
    rows: usize,
    cell_m: f64,
    max_slope_ratio: f64,
    percentile: f64,
) -> f64 {
    (step_percentile(original, cols, rows, percentile) / cell_m * max_slope_ratio).max(FLAT_SLOPE)
}

/// The `percentile` of the steps between row or column neighbours (nearest rank), metres.
pub fn step_percentile(h: &[f64], cols: usize, rows: usize, percentile: f64) -> f64 {
    let mut steps = Vec::with_capacity(2 * h.len());
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            if c + 1 < cols {
                steps.push((h[i + 1] - h[i]).abs());
            }
            if r + 1 < rows {
                steps.push((h[i + cols] - h[i]).abs());
            }
        }
    }
    if steps.is_empty() {
        return 0.0;
    }
    let k = ((percentile / 100.0).clamp(0.0, 1.0) * (steps.len() - 1) as f64).round() as usize;
    *steps.select_nth_unstable_by(k, f64::total_cmp).1
}

/// Per sample, the largest step allowed to its right and to the row below (infinite past the
/// grid's edge): `step`, or the input's own step there where that is steeper — the limit keeps
/// the result from growing steeper than it or than the input was, and leaves the input's own
/// crags alone.
pub struct EdgeLimits {
    pub right: Vec<f64>,
    pub down: Vec<f64>,
    /// A tileable terrain's first and last columns (rows) are one: the limit holds across the
    /// wrap as everywhere else.
    pub wrap_x: bool,
    pub wrap_z: bool,
}

impl EdgeLimits {
    pub fn new(original: &[f64], cols: usize, rows: usize, step: f64) -> Self {
        let n = cols * rows;
        let (mut right, mut down) = (vec![f64::INFINITY; n], vec![f64::INFINITY; n]);
        for r in 0..rows {
            for c in 0..cols {
                let i = r * cols + c;
                if c + 1 < cols {
                    right[i] = step.max((original[i + 1] - original[i]).abs());
                }
                if r + 1 < rows {
                    down[i] = step.max((original[i + cols] - original[i]).abs());
                }
            }
        }
        Self { right, down, wrap_x: false, wrap_z: false }
    }
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
///
/// A spreading constraint's samples are the sources of an earthwork: around each, the heights
/// a slope of `slope` metres a cell from its target allows, so the change it needs beside it is
/// what reaches from the original ground to that cone — as a road's cutting daylights where its
/// face meets the hillside, far up a slope nearly as steep as the face and at once on the flat.
fn wanted(fields: &[Field], grid: &Grid, slope: f64) -> (Vec<f64>, Vec<f64>) {
    let n = grid.cells();
    let o = grid.original;
    // The lowest and highest heights the sources' cones allow (NEG_INFINITY: none): a target's
    // (a road's, a point's, a terrace's) fall at the fill and cut slopes, the projection's
    // embankments and cuttings ([`super::projection`]); a mask's and a seam's at `slope`.
    let (mut floor, mut ceiling) = (vec![f64::NEG_INFINITY; n], vec![f64::NEG_INFINITY; n]);
    let (mut target_floor, mut target_ceiling) = (vec![f64::NEG_INFINITY; n], vec![f64::NEG_INFINITY; n]);
    let mut own = vec![0.0f64; n];
    // A target summed from several terms that equals the input comes back a rounding away
    // from it: that is no change wanted.
    let least = 1e-6 * grid.relief;
    let mut source = |i: usize, lowest: Option<f64>, highest: Option<f64>, target: bool| {
        let (floor, ceiling) =
            if target { (&mut target_floor, &mut target_ceiling) } else { (&mut floor, &mut ceiling) };
        if let Some(t) = lowest.filter(|&t| t - o[i] > least) {
            floor[i] = floor[i].max(t);
        }
        if let Some(t) = highest.filter(|&t| o[i] - t > least) {
            // Negated, so one cone of maxima serves both.
            ceiling[i] = ceiling[i].max(-t);
        }
    };
    for f in fields {
        if let Detail::EdgeMatch(_) = f.detail {
            // A seam band's wants do not spread: the band is the transition.
            if let Some(q) = &f.quadratic {
                for i in 0..n {
                    if q.w[i] > 0.0 {
                        own[i] = own[i].max((q.t[i] - o[i]).abs());
                    }
                }
            }
            continue;
        }
        if let Some(q) = &f.quadratic {
            for i in 0..n {
                if q.w[i] > 0.0 {
                    source(i, Some(q.t[i]), Some(q.t[i]), true);
                }
            }
        }
        if let Some(m) = &f.one_sided {
            for i in 0..n {
                match m.side[i] {
                    1 => source(i, Some(m.lo), None, false),
                    -1 => source(i, None, Some(m.hi), false),
                    _ => {}
                }
            }
        }
        if let Some(p) = &f.pairs {
            for i in 0..n {
                for j in [p.partner_x[i], p.partner_z[i]] {
                    if j != NO_PARTNER {
                        // Either side may move by the mismatch: the heights between are unknown.
                        let w = (o[i] - o[j as usize]).abs();
                        source(i, Some(o[i] + w), Some(o[i] - w), false);
                    }
                }
            }
        }
    }
    cone(&mut floor, grid.cols, grid.rows, slope);
    cone(&mut ceiling, grid.cols, grid.rows, slope);
    cone(&mut target_floor, grid.cols, grid.rows, grid.fill * grid.cell_m);
    cone(&mut target_ceiling, grid.cols, grid.rows, grid.cut * grid.cell_m);
    let mut spread: Vec<f64> = (0..n)
        .map(|i| {
            let raise = floor[i].max(target_floor[i]) - o[i];
            let lower = o[i] + ceiling[i].max(target_ceiling[i]);
            raise.max(lower).max(0.0)
        })
        .collect();
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
        let (mut spread, own) = wanted(fields, grid, EARTHWORK_SLOPE * step_max);
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
        // Inside a footprint only the slope is limited: a kernel that lowers one sample of a
        // mask's sea lowers its neighbours with it, and a band there held the mask at 96 % on
        // its side (99.5 % without).
        let allow: Vec<f64> =
            (0..n).map(|i| if spread[i] > 0.0 { f64::INFINITY } else { grow(own[i]).max(free) }).collect();
        Self {
            lo: (0..n).map(|i| o[i] - allow[i]).collect(),
            hi: (0..n).map(|i| o[i] + allow[i]).collect(),
            step_max,
            footprint,
            asked,
        }
    }

    /// Per sample, the lowest and highest height allowed: infinite inside a footprint, the
    /// input ± `max_free_change` of the relief outside every one.
    pub fn band(&self) -> (&[f64], &[f64]) {
        (&self.lo, &self.hi)
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
}
