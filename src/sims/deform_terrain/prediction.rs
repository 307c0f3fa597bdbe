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
}
