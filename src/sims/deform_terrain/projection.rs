//! The last step of a limited job, after the search, in run and replay alike: hold the slope
//! limit exactly and put the held samples within their bounds — a road's cells, a point's
//! sample, a terrace's samples and a seam's edge on their targets, a mask's land above its
//! water level and its sea below.
//!
//! The search weighs the limits as penalties ([`super::bounds`]), so it ends near them, not
//! within them: on the S-road a step of 1.735 m against 1.722 m allowed, and a road graded at
//! 6 % that the slope limit kept from its cutting came out at 10.1 % along its centreline. No
//! stack of Gaussians reaches a limit exactly; a projection does, by moving only the samples
//! within reach of a violation:
//!
//! 1. U = min over y of (h(y) + L·d(x, y)) and D = max over y of (h(y) − L·d(x, y)), with d the
//!    row-and-column step count and L the steepest step allowed, are both L-Lipschitz and
//!    U ≤ h ≤ D, equal to h wherever no step within reach exceeds L. Their mean is L-Lipschitz
//!    too: spikes come down and pits come up by half their excess, symmetrically.
//! 2. The bounds' cones, min over held samples of (hi + L·d) and max of (lo − L·d), are
//!    L-Lipschitz; clamping step 1's heights between them keeps every step within L and puts
//!    each held sample within its bounds (a cutting or embankment at the limit where the
//!    search left the ground too high or too low beside a road; a shallows just under the
//!    water where it left a rock standing in a mask's sea). Bounds that themselves ask for a
//!    step steeper than L (two points 10 m apart in height one cell apart) cannot all be held:
//!    where the cones cross, the sample takes their mean and the figures report the steepest
//!    step left.
//!
//! Each envelope is two raster passes (left and up, then right and down): exact for the
//! row-and-column step count, which is the metric the limit is stated in. The bounds' cones use
//! a rounder path length (diagonal and knight's moves too), still within the limit a row or
//! column step, so a cutting beside a road at an angle to the grid has a straight face.

/// A sample the result must hold between `lo` and `hi` (equal for a target; infinite on a
/// side without a bound).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Held {
    pub sample: usize,
    pub lo: f64,
    pub hi: f64,
}

impl Held {
    pub fn at(sample: usize, target: f64) -> Self {
        Self { sample, lo: target, hi: target }
    }
}

/// `h` with every row and column step within `step_max` and each held sample within its
/// bounds (where the bounds allow both): `loose` first, then `firm`, which win where the two
/// conflict (a road asked for at a height the mask calls sea keeps its height).
pub fn hold(h: &[f64], cols: usize, rows: usize, step_max: f64, loose: &[Held], firm: &[Held]) -> Vec<f64> {
    let mut upper = h.to_vec();
    envelope(&mut upper, cols, rows, step_max);
    let mut lower: Vec<f64> = h.iter().map(|v| -v).collect();
    envelope(&mut lower, cols, rows, step_max);
    let mut out: Vec<f64> = upper.iter().zip(&lower).map(|(u, d)| 0.5 * (u - d)).collect();
    for held in [loose, firm] {
        clamp(&mut out, cols, rows, step_max, held);
    }
    out
}

/// Clamp `h` (already within the step limit) between the cones of the held samples' bounds.
fn clamp(h: &mut [f64], cols: usize, rows: usize, step_max: f64, held: &[Held]) {
    if held.is_empty() {
        return;
    }
    let mut ceiling = vec![f64::INFINITY; h.len()];
    let mut floor = vec![f64::INFINITY; h.len()];
    for b in held {
        ceiling[b.sample] = ceiling[b.sample].min(b.hi);
        floor[b.sample] = floor[b.sample].min(-b.lo);
    }
    round_envelope(&mut ceiling, cols, rows, step_max);
    round_envelope(&mut floor, cols, rows, step_max);
    for ((v, &c), &f) in h.iter_mut().zip(&ceiling).zip(&floor) {
        let lowest = -f;
        *v = if lowest <= c { v.clamp(lowest, c) } else { 0.5 * (lowest + c) };
    }
}

/// `a[x] = min over y of (a[y] + step × d(x, y))`, d the row-and-column step count.
fn envelope(a: &mut [f64], cols: usize, rows: usize, step: f64) {
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            let mut v = a[i];
            if c > 0 {
                v = v.min(a[i - 1] + step);
            }
            if r > 0 {
                v = v.min(a[i - cols] + step);
            }
            a[i] = v;
        }
    }
    for r in (0..rows).rev() {
        for c in (0..cols).rev() {
            let i = r * cols + c;
            let mut v = a[i];
            if c + 1 < cols {
                v = v.min(a[i + 1] + step);
            }
            if r + 1 < rows {
                v = v.min(a[i + cols] + step);
            }
            a[i] = v;
        }
    }
}

/// The moves of [`round_envelope`]'s forward pass (column, row offsets; the backward pass
/// takes their negatives), each weighing its Euclidean length.
const ROUND_MOVES: [(i64, i64); 6] = [(-1, 0), (0, -1), (-1, -1), (1, -1), (-2, -1), (2, -1)];
const ROUND_MOVES_2: [(i64, i64); 2] = [(-1, -2), (1, -2)];

/// `a[x] = min over y of (a[y] + step × d(x, y))`, d the shortest path over moves of one
/// cell along a row or column (length 1), diagonally (√2) and a knight's move (√5): within
/// 3 % of the Euclidean distance and never under it. Still at most `step` a row or column
/// step, so the limit holds; but a cone from a road's cells, a staircase of whole cells, no
/// longer takes the staircase's teeth up its face as the row-and-column count did (a road at
/// 20° to the rows had a comb along its cutting).
fn round_envelope(a: &mut [f64], cols: usize, rows: usize, step: f64) {
    let weight = |(dc, dr): (i64, i64)| step * ((dc * dc + dr * dr) as f64).sqrt();
    let moves: Vec<((i64, i64), f64)> = ROUND_MOVES.iter().chain(&ROUND_MOVES_2).map(|&m| (m, weight(m))).collect();
    let (c_max, r_max) = (cols as i64, rows as i64);
    let pass = |a: &mut [f64], c: i64, r: i64, sign: i64| {
        let i = (r * c_max + c) as usize;
        let mut v = a[i];
        for &((dc, dr), w) in &moves {
            let (nc, nr) = (c + sign * dc, r + sign * dr);
            if (0..c_max).contains(&nc) && (0..r_max).contains(&nr) {
                v = v.min(a[(nr * c_max + nc) as usize] + w);
            }
        }
        a[i] = v;
    };
    for r in 0..r_max {
        for c in 0..c_max {
            pass(a, c, r, 1);
        }
    }
    for r in (0..r_max).rev() {
        for c in (0..c_max).rev() {
            pass(a, c, r, -1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The steepest row or column step (the limit's own measure, not the projection's code).
    fn steepest(h: &[f64], cols: usize) -> f64 {
        super::super::bounds::steepest_step(h, cols, h.len() / cols)
    }

    #[test]
    fn a_spike_comes_down_and_its_ring_up_by_half_the_excess_and_nothing_else_moves() {
        // A plane rising 0.5 m a column, with one sample 4 m above it; 1 m steps allowed.
        let (cols, rows) = (15, 15);
        let plane = |i: usize| 0.5 * (i % cols) as f64;
        let mut h: Vec<f64> = (0..cols * rows).map(plane).collect();
        let spike = 7 * cols + 7;
        h[spike] += 4.0;
        let out = hold(&h, cols, rows, 1.0, &[], &[]);
        assert!(steepest(&out, cols) <= 1.0 + 1e-12);
        // By hand: U lowers the spike to its lowest neighbour + 1 (3.0 + 1 = 4.0 against 7.5);
        // D raises the spike's neighbours to 7.5 − 1 and so on while that is above the plane.
        // At the spike: (4.0 + 7.5) / 2.
        assert!((out[spike] - 5.75).abs() < 1e-12, "{}", out[spike]);
        // Its left neighbour (3.0): D = 6.5, U = 3.0 → 4.75.
        assert!((out[spike - 1] - 4.75).abs() < 1e-12, "{}", out[spike - 1]);
        // D's cone falls 1 m a step from 7.5, the plane rises at most 0.5 m a step: it meets
        // the plane within 8 steps, so farther samples keep their heights exactly.
        for i in 0..h.len() {
            let (c, r) = ((i % cols) as i64, (i / cols) as i64);
            if (c - 7).abs() + (r - 7).abs() > 8 {
                assert_eq!(out[i], h[i], "sample ({c}, {r}) moved");
            }
        }
    }

    #[test]
    fn pins_take_their_targets_and_the_ground_beside_them_daylights_at_the_limit() {
        // Flat ground at 10 m; one row pinned at 4 m (a road's cutting 6 m deep); 1.5 m steps.
        let (cols, rows) = (9, 21);
        let h = vec![10.0; cols * rows];
        let pins: Vec<Held> = (0..cols).map(|c| Held::at(10 * cols + c, 4.0)).collect();
        let out = hold(&h, cols, rows, 1.5, &[], &pins);
        assert!(steepest(&out, cols) <= 1.5 + 1e-12);
        for r in 0..rows {
            // The cutting's face by hand: 4 + 1.5 per row from the road, up to the ground.
            let want = (4.0 + 1.5 * (r as f64 - 10.0).abs()).min(10.0);
            for c in 0..cols {
                assert!((out[r * cols + c] - want).abs() < 1e-12, "({c}, {r}): {}", out[r * cols + c]);
            }
        }
    }

    #[test]
    fn pins_that_ask_for_a_cliff_meet_halfway() {
        let (cols, rows) = (3, 1);
        let out = hold(&[0.0, 0.0, 0.0], cols, rows, 1.0, &[], &[Held::at(0, 0.0), Held::at(2, 10.0)]);
        // The cones cross at the middle: 0 + 1 against 10 − 1 → their mean; the pins' own cones
        // cross at the pins too, so they take means there.
        assert!((out[1] - 5.0).abs() < 1e-12, "{out:?}");
        // A surface that already keeps to the limit is left exactly as it is.
        let gentle: Vec<f64> = (0..40).map(|i| (i as f64 * 0.37).sin()).collect();
        assert_eq!(hold(&gentle, 40, 1, 0.4, &[], &[]), gentle);
    }

    #[test]
    fn a_rock_in_the_sea_goes_under_as_shallows_and_the_land_stays() {
        // A 1-D coast: land (≥ 1 m) on samples 0–4 falling to a sea (≤ −1 m) at −2 m, with a
        // rock rising to 2 m at sample 10; 2.5 m steps allowed, none steeper to begin with.
        let mut h = vec![9.0, 7.0, 5.0, 3.0, 1.0, -1.4, -2.0, -2.0, -1.0, 0.5, 2.0, 0.5, -1.0, -2.0, -2.0];
        let held: Vec<Held> = (0..h.len())
            .map(|i| {
                if i < 5 {
                    Held { sample: i, lo: 1.0, hi: f64::INFINITY }
                } else {
                    Held { sample: i, lo: f64::NEG_INFINITY, hi: -1.0 }
                }
            })
            .collect();
        let out = hold(&h, h.len(), 1, 2.5, &held, &[]);
        // By hand: the rock's three samples above the sea's bound come down to it, shallows at
        // −1 m; nothing else moves (the land's cones from the sea, −1 + 2.5 per step, stay
        // above it).
        h[9] = -1.0;
        h[10] = -1.0;
        h[11] = -1.0;
        assert_eq!(out, h);
    }

    #[test]
    fn a_firm_target_wins_over_a_loose_bound() {
        // Sea (≤ −1 m) everywhere on a flat at −2 m, and a causeway sample asked for at 1 m:
        // it keeps its height, its neighbours rise to 1 − 1.5 = −0.5... then −2 again.
        let h = vec![-2.0; 7];
        let sea: Vec<Held> = (0..7).map(|i| Held { sample: i, lo: f64::NEG_INFINITY, hi: -1.0 }).collect();
        let out = hold(&h, 7, 1, 1.5, &sea, &[Held::at(3, 1.0)]);
        assert_eq!(out, vec![-2.0, -2.0, -0.5, 1.0, -0.5, -2.0, -2.0]);
    }

    #[test]
    fn a_cutting_beside_a_slanted_road_has_a_straight_face() {
        // Flat ground at 20 m; a 3-cell-wide road at 0 m along a line 20° off the rows, as whole
        // cells (a staircase). 1 m steps allowed. The cutting's face, sampled along lines
        // parallel to the road, should be as even as the Euclidean distance to the road's
        // cells allows; by hand: the height at each sample is 0 + 1 × (its distance to the
        // nearest road cell, within 3 %), and never under it.
        let (cols, rows) = (80, 60);
        let slope = (20.0f64).to_radians().tan();
        let on_road = |c: usize, r: usize| ((r as f64 - 10.0 - slope * c as f64).abs()) <= 1.5;
        let road: Vec<Held> =
            (0..cols * rows).filter(|&i| on_road(i % cols, i / cols)).map(|i| Held::at(i, 0.0)).collect();
        let out = hold(&vec![20.0; cols * rows], cols, rows, 1.0, &[], &road);
        assert!(steepest(&out, cols) <= 1.0 + 1e-12);
        for (i, &got) in out.iter().enumerate() {
            let (c, r) = ((i % cols) as f64, (i / cols) as f64);
            let d = road
                .iter()
                .map(|b| (c - (b.sample % cols) as f64).hypot(r - (b.sample / cols) as f64))
                .fold(f64::INFINITY, f64::min);
            let want = d.min(20.0);
            assert!(got >= want - 1e-9 && got <= want * 1.03 + 1e-9, "({c}, {r}): {got} for {want}");
        }
    }
}
