//! Prediction (paper §3.5): a confidence per candidate that it will rank among the top next
//! time. An invalidated candidate is recomputed only when its confidence is at least one half;
//! otherwise its confidence rises by C, so every candidate is recomputed eventually. The rule
//! is deterministic: no draw decides what to recompute.

/// Recompute an invalidated candidate at or above this confidence.
pub const THRESHOLD: f64 = 0.5;

/// conf = clamp((maxF − F_i)/(maxF − minF) + C, 0, 1), with maxF and minF the worst and best
/// changes in the table.
pub fn confidence(change: f64, best: f64, worst: f64, c: f64) -> f64 {
    let span = worst - best;
    let rank = if span > 0.0 { (worst - change) / span } else { 1.0 };
    (rank + c).clamp(0.0, 1.0)
}

/// Candidates prediction lets wait, by the iteration they fall due. A candidate below the
/// threshold gains C an iteration, so it is due after ⌈(THRESHOLD − conf) / C⌉ of them; a ring
/// of slots, one an iteration, holds it until then rather than every waiting candidate being
/// looked at every iteration. Its confidence on the way is never read: it is computed afresh
/// when the candidate is.
pub struct Waiting {
    slots: Vec<Vec<usize>>,
    c: f64,
}

impl Waiting {
    /// For a search of `iterations` with constant `c`: the longest wait is ⌈THRESHOLD / C⌉,
    /// and none longer than the search matters.
    pub fn new(c: f64, iterations: u64) -> Self {
        let longest = (THRESHOLD / c).ceil().min(iterations as f64) as usize;
        Self { slots: vec![Vec::new(); longest + 2], c }
    }

    /// Let candidate `i`, at confidence `conf` (below the threshold), wait from iteration
    /// `now`. One that would fall due after the search is not kept: it is recomputed only if
    /// the whole table is.
    pub fn wait(&mut self, i: usize, conf: f64, now: u64) {
        let n = ((THRESHOLD - conf) / self.c).ceil().max(1.0);
        if n < (self.slots.len() - 1) as f64 {
            let len = self.slots.len() as u64;
            self.slots[((now + n as u64) % len) as usize].push(i);
        }
    }

    /// Move the candidates due at iteration `now` into `out`.
    pub fn take_due(&mut self, now: u64, out: &mut Vec<usize>) {
        let len = self.slots.len() as u64;
        out.append(&mut self.slots[(now % len) as usize]);
    }

    pub fn clear(&mut self) {
        self.slots.iter_mut().for_each(Vec::clear);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_best_is_certain_and_the_worst_gets_only_the_constant() {
        assert_eq!(confidence(-5.0, -5.0, 1.0, 0.1), 1.0);
        assert!((confidence(1.0, -5.0, 1.0, 0.1) - 0.1).abs() < 1e-12);
        assert!(confidence(0.0, -5.0, 1.0, 0.1) < THRESHOLD);
        assert!(confidence(-2.0, -5.0, 1.0, 0.1) >= THRESHOLD);
    }

    #[test]
    fn a_candidate_falls_due_when_its_confidence_would_reach_the_threshold() {
        // C = 0.1: from 0.25, three raises reach 0.55 ≥ 0.5; from 0.45, one.
        let mut w = Waiting::new(0.1, 100);
        w.wait(7, 0.25, 10);
        w.wait(8, 0.45, 10);
        let mut out = Vec::new();
        for now in 11..=12 {
            w.take_due(now, &mut out);
        }
        assert_eq!(out, [8]);
        w.take_due(13, &mut out);
        assert_eq!(out, [8, 7]);
        // Past the search's end: not kept.
        let mut short = Waiting::new(0.001, 5);
        short.wait(1, 0.0, 1);
        let mut out = Vec::new();
        (0..20).for_each(|now| short.take_due(now, &mut out));
        assert!(out.is_empty());
    }
}
