//! Penalties of the form w·max(0, g + c·d)², summed over a deformation's window for every
//! sampled displacement d at once: the shape mask's one-sided margin. (The limits were weighed
//! here too, as penalties on every sample and step of a window; the projection now holds them
//! after the search, which keeps the search on its fast path: [`super::super::projection`].)
//!
//! Each term is a quadratic in d on one side of its breakpoint −g/c and zero on the other. The
//! sampled displacements are sorted, so a term adds its quadratic's coefficients to one run of
//! them — those below the breakpoint when c < 0, those above it when c > 0 — marked at the run's
//! end and summed once, instead of evaluating every displacement at every sample.

use super::MAX_DELTAS;

/// The runs of one window's terms over the sorted displacements `sampled`, and their sums
/// before any displacement and at `optimum` (a displacement outside the order).
pub struct Hinges<'a> {
    sampled: &'a [f64],
    optimum: Option<f64>,
    /// The largest |d| tried: a term that stays at zero over ±d_abs adds nothing.
    d_abs: f64,
    /// Coefficients [1, d, d²] of the terms active below their breakpoint (c < 0), at the index
    /// their run ends (exclusive), and of those active above it (c > 0), at the index it starts.
    below: [[f64; 3]; MAX_DELTAS],
    above: [[f64; 3]; MAX_DELTAS],
    before: f64,
    at_optimum: f64,
}

impl<'a> Hinges<'a> {
    pub fn new(sampled: &'a [f64], optimum: Option<f64>) -> Self {
        let d_abs = sampled.iter().chain(&optimum).fold(0.0f64, |acc, d| acc.max(d.abs()));
        Self {
            sampled,
            optimum,
            d_abs,
            below: [[0.0; 3]; MAX_DELTAS],
            above: [[0.0; 3]; MAX_DELTAS],
            before: 0.0,
            at_optimum: 0.0,
        }
    }

    /// Add w·max(0, g + c·d)².
    #[inline]
    pub fn add(&mut self, w: f64, g: f64, c: f64) {
        if c == 0.0 || g + c.abs() * self.d_abs <= 0.0 {
            // No displacement changes it (c = 0), or none tried takes it past zero.
            return;
        }
        let now = g.max(0.0);
        self.before += w * now * now;
        if let Some(d) = self.optimum {
            let after = (g + c * d).max(0.0);
            self.at_optimum += w * after * after;
        }
        // (g + c·d)² = g² + 2gc·d + c²·d²
        let coefficients = [w * g * g, 2.0 * w * g * c, w * c * c];
        let breakpoint = -g / c;
        let run = if c < 0.0 {
            &mut self.below[self.sampled.partition_point(|&d| d < breakpoint)]
        } else {
            &mut self.above[self.sampled.partition_point(|&d| d <= breakpoint)]
        };
        for (r, k) in run.iter_mut().zip(coefficients) {
            *r += k;
        }
    }

    /// Each sampled displacement's change in the terms, times `scale`, into `out`; and the
    /// optimum's.
    pub fn changes(&self, scale: f64, out: &mut [f64; MAX_DELTAS]) -> Option<f64> {
        let (s, n) = (self.sampled, self.sampled.len());
        let mut covering = [0.0f64; 3];
        let mut penalty = [0.0f64; MAX_DELTAS];
        for t in (0..n).rev() {
            for (c, l) in covering.iter_mut().zip(self.below[t + 1]) {
                *c += l;
            }
            penalty[t] = covering[0] + covering[1] * s[t] + covering[2] * s[t] * s[t];
        }
        covering = [0.0; 3];
        for t in 0..n {
            for (c, a) in covering.iter_mut().zip(self.above[t]) {
                *c += a;
            }
            penalty[t] += covering[0] + covering[1] * s[t] + covering[2] * s[t] * s[t];
        }
        for t in 0..n {
            out[t] = scale * (penalty[t] - self.before);
        }
        self.optimum.map(|_| scale * (self.at_optimum - self.before))
    }
}
