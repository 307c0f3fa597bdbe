//! The last step of a limited job, after the search (and the seam filter), in run and replay
//! alike: hold the slope limit exactly and put the pinned samples (a road's cells, a point's
//! sample) exactly on their targets.
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
//! 2. The pinned samples' cones, min over pins of (t + L·d) and max of (t − L·d), are
//!    L-Lipschitz; clamping step 1's heights between them keeps every step within L and puts
//!    each pin on its target (a cutting or embankment at the limit where the search left the
//!    ground too high or too low beside a road). Pins that themselves ask for a step steeper
//!    than L (two points 10 m apart in height one cell apart) cannot all be held: where the
//!    cones cross, the sample takes their mean and the figures report the steepest step left.
//!
//! Each envelope is two raster passes (left and up, then right and down): exact for the
//! row-and-column step count, which is the metric the limit is stated in.

/// `h` with every row and column step within `step_max` and each pin `(sample, target)` on its
/// target (where the pins allow both).
pub fn hold(h: &[f64], cols: usize, rows: usize, step_max: f64, pins: &[(usize, f64)]) -> Vec<f64> {
    let mut upper = h.to_vec();
    envelope(&mut upper, cols, rows, step_max);
    let mut lower: Vec<f64> = h.iter().map(|v| -v).collect();
    envelope(&mut lower, cols, rows, step_max);
    let mut out: Vec<f64> = upper.iter().zip(&lower).map(|(u, d)| 0.5 * (u - d)).collect();
    if pins.is_empty() {
        return out;
    }
    let mut ceiling = vec![f64::INFINITY; h.len()];
    let mut floor = vec![f64::INFINITY; h.len()];
    for &(i, t) in pins {
        ceiling[i] = ceiling[i].min(t);
        floor[i] = floor[i].min(-t);
    }
    envelope(&mut ceiling, cols, rows, step_max);
    envelope(&mut floor, cols, rows, step_max);
    for ((v, &c), &f) in out.iter_mut().zip(&ceiling).zip(&floor) {
        let lowest = -f;
        *v = if lowest <= c { v.clamp(lowest, c) } else { 0.5 * (lowest + c) };
    }
    out
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The steepest row or column step, reckoned here.
    fn steepest(h: &[f64], cols: usize) -> f64 {
        let rows = h.len() / cols;
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

    #[test]
    fn a_spike_comes_down_and_its_ring_up_by_half_the_excess_and_nothing_else_moves() {
        // A plane rising 0.5 m a column, with one sample 4 m above it; 1 m steps allowed.
        let (cols, rows) = (15, 15);
        let plane = |i: usize| 0.5 * (i % cols) as f64;
        let mut h: Vec<f64> = (0..cols * rows).map(plane).collect();
        let spike = 7 * cols + 7;
        h[spike] += 4.0;
        let out = hold(&h, cols, rows, 1.0, &[]);
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
        let pins: Vec<(usize, f64)> = (0..cols).map(|c| (10 * cols + c, 4.0)).collect();
        let out = hold(&h, cols, rows, 1.5, &pins);
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
        let out = hold(&[0.0, 0.0, 0.0], cols, rows, 1.0, &[(0, 0.0), (2, 10.0)]);
        // The cones cross at the middle: 0 + 1 against 10 − 1 → their mean; the pins' own cones
        // cross at the pins too, so they take means there.
        assert!((out[1] - 5.0).abs() < 1e-12, "{out:?}");
        // A surface that already keeps to the limit is left exactly as it is.
        let gentle: Vec<f64> = (0..40).map(|i| (i as f64 * 0.37).sin()).collect();
        assert_eq!(hold(&gentle, 40, 1, 0.4, &[]), gentle);
    }
}
