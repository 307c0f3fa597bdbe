//! The last step of a limited job, after the search, in run and replay alike: hold the slope
//! limit exactly and put the held samples within their bounds — a road's cells, a point's
//! sample, a terrace's samples and a seam's edge on their targets, a mask's land above its
//! water level and its sea below.
//!
//! The search only pulls free samples back to their input ([`super::bounds`]); it once
//! weighed the limits as penalties too, and ended near them, not within them (on the S-road a
//! step of 1.735 m against 1.722 m allowed). No stack of Gaussians reaches a limit exactly; a
//! projection does, by moving only the samples within reach of a violation:
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
//! Each envelope is raster passes (left and up, then right and down) until nothing changes:
//! two when every step's limit is the same, a few more where the input's own steeper steps
//! raise theirs. A tileable terrain's wrap counts as one sample. Where the request bounds how
//! far free samples may move (`max_free_change`), that band and the slope limit take turns. The bounds' cones use
//! a rounder path length (diagonal and knight's moves too), still within the limit a row or
//! column step, so a cutting beside a road at an angle to the grid has a straight face.

use super::bounds::EdgeLimits;

/// A sample the result must hold between `lo` and `hi` (equal for a target; infinite on a
/// side without a bound), for constraint `source`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Held {
    pub sample: usize,
    pub lo: f64,
    pub hi: f64,
    pub source: u32,
}

impl Held {
    pub fn at(sample: usize, target: f64) -> Self {
        Self { sample, lo: target, hi: target, source: 0 }
    }

    pub fn between(sample: usize, lo: f64, hi: f64) -> Self {
        Self { sample, lo, hi, source: 0 }
    }

    /// The same, held for constraint `source`.
    pub fn of(self, source: usize) -> Self {
        Self { source: source as u32, ..self }
    }
}

/// Held samples of one priority, and the faces built from them: the ground above a
/// sample's `hi` is cut down to a face rising `cut` metres a cell, the ground below its `lo`
/// filled up to one falling `fill` metres a cell.
pub struct Tier<'a> {
    pub held: &'a [Held],
    pub cut: f64,
    pub fill: f64,
    /// Set each held sample within its own bounds last, even where the tier's own faces cross
    /// (a road's two legs at a hairpin, a seam's two rows): such a tier's targets are its
    /// shape, not wishes to meet halfway.
    pub pin: bool,
    /// Samples the tier's faces leave as they are (a terrace's apron is built around the
    /// regions, not across the riser between two of them).
    pub skip: Option<&'a [bool]>,
}

/// `h` with every row and column step within `limits`, within `band` where it is given (each
/// sample's lowest and highest height), and each held sample within its bounds (where the
/// bounds allow both), tier by tier: a later tier wins where two conflict (a road asked for at
/// a height the mask calls sea keeps its height). The faces from the held samples are at
/// their tier's slopes, which may be steeper than `limits` (an embankment a designer asked for
/// on a plain).
pub fn hold(
    h: &[f64],
    cols: usize,
    rows: usize,
    limits: &EdgeLimits,
    band: Option<(&[f64], &[f64])>,
    tiers: &[Tier],
) -> Vec<f64> {
    let mut out = lipschitz(h, cols, rows, limits);
    // The band and the slope limit by turns (the input meets both, so there is a surface that
    // does): the band's clamp only lowers or raises a sample towards its input, and the next
    // envelope lays back what that steepened; the last word is the slope limit's.
    if let Some((lo, hi)) = band {
        for _ in 0..BAND_ROUNDS {
            let mut clamped = false;
            for ((v, &lo), &hi) in out.iter_mut().zip(lo).zip(hi) {
                let c = v.clamp(lo, hi);
                clamped |= c != *v;
                *v = c;
            }
            if !clamped {
                break;
            }
            out = lipschitz(&out, cols, rows, limits);
        }
    }
    for tier in tiers {
        clamp(&mut out, cols, rows, tier);
    }
    out
}

/// How many times the band and the slope limit take turns at most.
const BAND_ROUNDS: usize = 8;

/// The mean of the upper and lower envelopes: spikes come down and pits come up by half their
/// excess, and a surface within the limits is returned as it is.
fn lipschitz(h: &[f64], cols: usize, rows: usize, limits: &EdgeLimits) -> Vec<f64> {
    let mut upper = h.to_vec();
    envelope(&mut upper, cols, rows, limits);
    let mut lower: Vec<f64> = h.iter().map(|v| -v).collect();
    envelope(&mut lower, cols, rows, limits);
    upper.iter().zip(&lower).map(|(u, d)| 0.5 * (u - d)).collect()
}

/// Clamp `h` between the cones of the held samples' bounds.
fn clamp(h: &mut [f64], cols: usize, rows: usize, tier: &Tier) {
    if tier.held.is_empty() {
        return;
    }
    let mut ceiling = vec![f64::INFINITY; h.len()];
    let mut floor = vec![f64::INFINITY; h.len()];
    for b in tier.held {
        ceiling[b.sample] = ceiling[b.sample].min(b.hi);
        floor[b.sample] = floor[b.sample].min(-b.lo);
    }
    round_envelope(&mut ceiling, cols, rows, tier.cut);
    round_envelope(&mut floor, cols, rows, tier.fill);
    for (i, ((v, &c), &f)) in h.iter_mut().zip(&ceiling).zip(&floor).enumerate() {
        if tier.skip.is_some_and(|skip| skip[i]) {
            continue;
        }
        let lowest = -f;
        *v = if lowest <= c { v.clamp(lowest, c) } else { 0.5 * (lowest + c) };
    }
    if tier.pin {
        for b in tier.held {
            h[b.sample] = h[b.sample].clamp(b.lo, b.hi);
        }
    }
}

/// A held sample's constraint the result could not meet there: the worst miss of each
/// constraint, and the constraint whose face held it off (of the same or a later tier).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conflict {
    pub source: u32,
    pub sample: usize,
    /// The result's height less the nearest bound (negative: below it).
    pub missed_m: f64,
    pub target_lo: f64,
    pub target_hi: f64,
    pub by: u32,
    pub by_sample: usize,
}

/// Every constraint whose held samples `out` misses by more than `tolerance` metres.
pub fn conflicts(out: &[f64], cols: usize, tiers: &[Tier], tolerance: f64) -> Vec<Conflict> {
    let mut worst: Vec<(usize, Held, f64)> = Vec::new();
    for (t, tier) in tiers.iter().enumerate() {
        for b in tier.held {
            let v = out[b.sample];
            let miss = if v < b.lo {
                v - b.lo
            } else if v > b.hi {
                v - b.hi
            } else {
                0.0
            };
            if miss.abs() <= tolerance {
                continue;
            }
            match worst.iter_mut().find(|w| w.1.source == b.source) {
                Some(w) if w.2.abs() < miss.abs() => *w = (t, *b, miss),
                Some(_) => {}
                None => worst.push((t, *b, miss)),
            }
        }
    }
    let at = |i: usize| ((i % cols) as f64, (i / cols) as f64);
    worst
        .into_iter()
        .map(|(t, b, miss)| {
            let (x, z) = at(b.sample);
            // The face that bound it: the lowest ceiling over it (it came out too low) or the
            // highest floor under it (too high), from the samples of its own tier on.
            let mut by = (b.source, b.sample, if miss < 0.0 { f64::INFINITY } else { f64::NEG_INFINITY });
            for tier in &tiers[t..] {
                for o in tier.held.iter().filter(|o| o.sample != b.sample) {
                    let (ox, oz) = at(o.sample);
                    let d = (x - ox).hypot(z - oz);
                    if miss < 0.0 {
                        let c = o.hi + tier.cut * d;
                        if c < by.2 {
                            by = (o.source, o.sample, c);
                        }
                    } else {
                        let f = o.lo - tier.fill * d;
                        if f > by.2 {
                            by = (o.source, o.sample, f);
                        }
                    }
                }
            }
            Conflict {
                source: b.source,
                sample: b.sample,
                missed_m: miss,
                target_lo: b.lo,
                target_hi: b.hi,
                by: by.0,
                by_sample: by.1,
            }
        })
        .collect()
}

/// `a[x] = min over y of (a[y] + the cost of the path from y to x)`, a path's cost the sum of
/// its row and column steps' limits: sweeps both ways until nothing changes (two suffice when
/// every limit is the same; the input's own steeper steps bend the paths, a few more).
fn envelope(a: &mut [f64], cols: usize, rows: usize, limits: &EdgeLimits) {
    loop {
        let mut changed = false;
        let mut lower = |a: &mut [f64], i: usize, v: f64| {
            if v < a[i] {
                a[i] = v;
                changed = true;
            }
        };
        for r in 0..rows {
            for c in 0..cols {
                let i = r * cols + c;
                if c > 0 {
                    lower(a, i, a[i - 1] + limits.right[i - 1]);
                }
                if r > 0 {
                    lower(a, i, a[i - cols] + limits.down[i - cols]);
                }
            }
        }
        for r in (0..rows).rev() {
            for c in (0..cols).rev() {
                let i = r * cols + c;
                if c + 1 < cols {
                    lower(a, i, a[i + 1] + limits.right[i]);
                }
                if r + 1 < rows {
                    lower(a, i, a[i + cols] + limits.down[i]);
                }
            }
        }
        // A tileable terrain's first and last columns (rows) are the same samples.
        if limits.wrap_x {
            for r in 0..rows {
                let (i, j) = (r * cols, r * cols + cols - 1);
                let m = a[i].min(a[j]);
                changed |= a[i] != m || a[j] != m;
                a[i] = m;
                a[j] = m;
            }
        }
        if limits.wrap_z {
            for c in 0..cols {
                let (i, j) = (c, (rows - 1) * cols + c);
                let m = a[i].min(a[j]);
                changed |= a[i] != m || a[j] != m;
                a[i] = m;
                a[j] = m;
            }
        }
        if !changed {
            return;
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

    /// The projection with every step limited to `step` and two tiers, `loose` then `firm`,
    /// whose faces are at the same slope.
    fn hold_uniform(h: &[f64], cols: usize, rows: usize, step: f64, loose: &[Held], firm: &[Held]) -> Vec<f64> {
        let limits = EdgeLimits::new(&vec![0.0; h.len()], cols, rows, step);
        let tiers = [
            Tier { held: loose, cut: step, fill: step, pin: false, skip: None },
            Tier { held: firm, cut: step, fill: step, pin: false, skip: None },
        ];
        hold(h, cols, rows, &limits, None, &tiers)
    }

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
        let out = hold_uniform(&h, cols, rows, 1.0, &[], &[]);
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
        let out = hold_uniform(&h, cols, rows, 1.5, &[], &pins);
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
        let out = hold_uniform(&[0.0, 0.0, 0.0], cols, rows, 1.0, &[], &[Held::at(0, 0.0), Held::at(2, 10.0)]);
        // The cones cross at the middle: 0 + 1 against 10 − 1 → their mean; the pins' own cones
        // cross at the pins too, so they take means there.
        assert!((out[1] - 5.0).abs() < 1e-12, "{out:?}");
        // A surface that already keeps to the limit is left exactly as it is.
        let gentle: Vec<f64> = (0..40).map(|i| (i as f64 * 0.37).sin()).collect();
        assert_eq!(hold_uniform(&gentle, 40, 1, 0.4, &[], &[]), gentle);
    }

    #[test]
    fn a_rock_in_the_sea_goes_under_as_shallows_and_the_land_stays() {
        // A 1-D coast: land (≥ 1 m) on samples 0–4 falling to a sea (≤ −1 m) at −2 m, with a
        // rock rising to 2 m at sample 10; 2.5 m steps allowed, none steeper to begin with.
        let mut h = vec![9.0, 7.0, 5.0, 3.0, 1.0, -1.4, -2.0, -2.0, -1.0, 0.5, 2.0, 0.5, -1.0, -2.0, -2.0];
        let held: Vec<Held> =
            (0..h.len())
                .map(|i| {
                    if i < 5 {
                        Held::between(i, 1.0, f64::INFINITY)
                    } else {
                        Held::between(i, f64::NEG_INFINITY, -1.0)
                    }
                })
                .collect();
        let out = hold_uniform(&h, h.len(), 1, 2.5, &held, &[]);
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
        let sea: Vec<Held> = (0..7).map(|i| Held::between(i, f64::NEG_INFINITY, -1.0)).collect();
        let out = hold_uniform(&h, 7, 1, 1.5, &sea, &[Held::at(3, 1.0)]);
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
        let out = hold_uniform(&vec![20.0; cols * rows], cols, rows, 1.0, &[], &road);
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

    #[test]
    fn a_cutting_rises_at_the_cut_slope_and_an_embankment_falls_at_the_fill_slope() {
        // A road row at 5 m across ground at 12 m north of it (rows 0–9) and at 0 m south of it
        // (rows 11–20); steps up to 3 m allowed, faces at 1 m a cell cut and 0.5 m fill.
        let (cols, rows) = (7, 21);
        let h: Vec<f64> = (0..cols * rows).map(|i| if i / cols < 10 { 12.0 } else { 0.0 }).collect();
        let road: Vec<Held> = (0..cols).map(|c| Held::at(10 * cols + c, 5.0)).collect();
        let limits = EdgeLimits::new(&vec![0.0; h.len()], cols, rows, 3.0);
        let out =
            hold(&h, cols, rows, &limits, None, &[Tier { held: &road, cut: 1.0, fill: 0.5, pin: false, skip: None }]);
        // By hand: the envelope first lays the 12 m step at the road's row back to 3 m steps
        // on both sides (the mean of U and D), then the road's cones bound it.
        let mut env = vec![0.0; rows];
        for (r, e) in env.iter_mut().enumerate() {
            // U: min over rows of h + 3·d; D: max of h − 3·d; mean.
            let u = (0..rows).map(|y| h[y * cols] + 3.0 * (r as f64 - y as f64).abs()).fold(f64::INFINITY, f64::min);
            let d =
                (0..rows).map(|y| h[y * cols] - 3.0 * (r as f64 - y as f64).abs()).fold(f64::NEG_INFINITY, f64::max);
            *e = 0.5 * (u + d);
        }
        for r in 0..rows {
            let d = (r as f64 - 10.0).abs();
            let want = env[r].clamp(5.0 - 0.5 * d, 5.0 + 1.0 * d);
            for c in 0..cols {
                assert!((out[r * cols + c] - want).abs() < 1e-12, "({c}, {r}): {} for {want}", out[r * cols + c]);
            }
        }
        // The cutting's face: 1 m a row above the road until it meets the ground at 12 m.
        assert_eq!(out[9 * cols], 6.0);
        assert_eq!(out[5 * cols], 10.0);
        assert_eq!(out[2 * cols], 12.0);
        // The embankment's: 0.5 m a row below it, meeting the ground at 0 m ten rows on.
        assert_eq!(out[11 * cols], 4.5);
        assert_eq!(out[16 * cols], 2.0);
        assert_eq!(out[20 * cols], 0.0);
    }

    #[test]
    fn the_inputs_own_steeper_steps_are_left_and_no_step_grows_past_its_limit() {
        // A ramp rising 1 m a column with a 6 m cliff between columns 9 and 10; the limit 1.5 m,
        // the cliff's own step allowed where it is. The input is kept exactly; a spike added on
        // the ramp comes down to the limit while the cliff stays.
        let (cols, rows) = (20, 5);
        let o: Vec<f64> =
            (0..cols * rows).map(|i| (i % cols) as f64 + if i % cols >= 10 { 6.0 } else { 0.0 }).collect();
        let limits = EdgeLimits::new(&o, cols, rows, 1.5);
        assert_eq!(hold(&o, cols, rows, &limits, None, &[]), o);
        let mut h = o.clone();
        h[2 * cols + 4] += 5.0;
        let out = hold(&h, cols, rows, &limits, None, &[]);
        for r in 0..rows {
            for c in 0..cols - 1 {
                let i = r * cols + c;
                assert!((out[i + 1] - out[i]).abs() <= limits.right[i] + 1e-12, "({c}, {r})");
            }
            // The cliff keeps its 7 m step and the ramp beyond the spike's reach its heights.
            assert_eq!(out[r * cols + 10] - out[r * cols + 9], 7.0);
            assert_eq!(out[r * cols + 15], o[r * cols + 15]);
        }
        // The spike: U = its neighbours + 1.5 = 3 + 1.5 + ... by hand: 4.5 against 9 → mean
        // with D (9) is 6.75.
        assert!((out[2 * cols + 4] - 6.75).abs() < 1e-12, "{}", out[2 * cols + 4]);
    }

    #[test]
    fn a_point_high_above_a_road_beside_it_is_named_and_the_road_holds() {
        // Flat ground at 0 m; a road row at 0 m (tier 2) and a point (tier 1) 6 rows away asked
        // at 40 m; faces at 1 m a cell. The road keeps its height; the point gets what the cut
        // face from the road allows, 6 m, and is reported missed by 34 m because of the road.
        let (cols, rows) = (15, 15);
        let road: Vec<Held> = (0..cols).map(|c| Held::at(4 * cols + c, 0.0).of(0)).collect();
        let point = [Held::at(10 * cols + 7, 40.0).of(1)];
        let limits = EdgeLimits::new(&vec![0.0; cols * rows], cols, rows, 1.0);
        let tiers = [
            Tier { held: &point, cut: 1.0, fill: 1.0, pin: false, skip: None },
            Tier { held: &road, cut: 1.0, fill: 1.0, pin: true, skip: None },
        ];
        let out = hold(&vec![0.0; cols * rows], cols, rows, &limits, None, &tiers);
        assert!(road.iter().all(|b| out[b.sample] == 0.0));
        assert!((out[10 * cols + 7] - 6.0).abs() < 1e-12, "{}", out[10 * cols + 7]);
        let found = conflicts(&out, cols, &tiers, 1e-6);
        assert_eq!(found.len(), 1, "{found:?}");
        let c = found[0];
        assert_eq!((c.source, c.sample, c.by, c.by_sample), (1, 10 * cols + 7, 0, 4 * cols + 7));
        assert!((c.missed_m + 34.0).abs() < 1e-12, "{}", c.missed_m);
    }

    #[test]
    fn free_samples_keep_to_their_band_and_the_slope_limit_has_the_last_word() {
        // A plane at 0 m with a 10 m block on columns 8–11 of a 20 × 3 grid; every sample may
        // move 2 m from its input (the band), steps up to 1.5 m. By hand: the block comes down
        // to the band's 2 m, and the steps at its sides are then within the limit.
        let (cols, rows) = (20, 3);
        let o = vec![0.0; cols * rows];
        let h: Vec<f64> = (0..cols * rows).map(|i| if (8..12).contains(&(i % cols)) { 10.0 } else { 0.0 }).collect();
        let (lo, hi): (Vec<f64>, Vec<f64>) = o.iter().map(|v| (v - 2.0, v + 2.0)).unzip();
        let limits = EdgeLimits::new(&o, cols, rows, 1.5);
        let out = hold(&h, cols, rows, &limits, Some((&lo, &hi)), &[]);
        for r in 0..rows {
            for c in 0..cols {
                let i = r * cols + c;
                assert!((-2.0..=2.0).contains(&out[i]), "({c}, {r}): {}", out[i]);
                if c + 1 < cols {
                    assert!((out[i + 1] - out[i]).abs() <= 1.5 + 1e-12, "({c}, {r})");
                }
            }
            assert_eq!(out[r * cols + 9], 2.0);
        }
    }

    #[test]
    fn a_tileable_terrains_wrap_is_one_sample_for_the_slope_limit() {
        // One row of 10, a plateau at 5 m over samples 0, 1 and 9 (9 is 0 across the wrap),
        // 0 m elsewhere; 1 m steps. Unwrapped, sample 0 comes to (2 + 5) / 2 = 3.5 m and sample
        // 9 to (1 + 5) / 2 = 3 m: the two ends of the tile differ. Wrapped, they are one sample,
        // U = min(2, 1) = 1, D = 5: both 3 m, and the steps across the wrap within the limit.
        let cols = 10;
        let mut h = vec![0.0; cols];
        for i in [0, 1, 9] {
            h[i] = 5.0;
        }
        let mut limits = EdgeLimits::new(&vec![0.0; cols], cols, 1, 1.0);
        let apart = hold(&h, cols, 1, &limits, None, &[]);
        assert_eq!((apart[0], apart[9]), (3.5, 3.0));
        limits.wrap_x = true;
        let out = hold(&h, cols, 1, &limits, None, &[]);
        assert_eq!((out[0], out[9]), (3.0, 3.0));
        assert!((out[8] - out[9]).abs() <= 1.0 && (out[1] - out[0]).abs() <= 1.0, "{out:?}");
    }
}
