//! The report: per-request latency percentiles from goose's metrics, throughput against the
//! floor, the end checks; as JSON and as a short Markdown table.

use std::collections::BTreeMap;

use goose::metrics::GooseMetrics;
use serde::Serialize;

#[derive(Serialize, Clone, Debug)]
pub struct RequestFigures {
    pub count: usize,
    pub failed: usize,
    pub p50_ms: f64,
    pub p90_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
    pub statuses: BTreeMap<u16, usize>,
}

/// Figures per request name (`submit`, `poll`, …) of one attack.
pub fn requests(metrics: &GooseMetrics) -> BTreeMap<String, RequestFigures> {
    let mut out = BTreeMap::new();
    for (key, agg) in metrics.requests.iter() {
        // Keys are "METHOD name".
        let name = key.split_once(' ').map_or(key.as_str(), |(_, n)| n).to_string();
        let buckets: Vec<(u64, usize)> = agg.raw_data.times_us.iter().map(|(&t, &n)| (t, n)).collect();
        let pct = |p: f64| percentile_ms(&buckets, p);
        out.insert(
            name,
            RequestFigures {
                count: agg.raw_data.counter,
                failed: agg.fail_count,
                p50_ms: pct(0.50),
                p90_ms: pct(0.90),
                p99_ms: pct(0.99),
                max_ms: agg.raw_data.maximum_time_us as f64 / 1000.0,
                statuses: agg.status_code_counts.iter().map(|(&s, &n)| (s, n)).collect(),
            },
        );
    }
    out
}

/// The time at or below which a fraction `p` of the requests finished, from buckets of
/// (fastest time in µs, count) sorted fastest first.
fn percentile_ms(buckets: &[(u64, usize)], p: f64) -> f64 {
    let total: usize = buckets.iter().map(|b| b.1).sum();
    if total == 0 {
        return 0.0;
    }
    let want = ((p * total as f64).ceil() as usize).max(1);
    let mut seen = 0;
    for &(t, n) in buckets {
        seen += n;
        if seen >= want {
            return t as f64 / 1000.0;
        }
    }
    buckets.last().map_or(0.0, |b| b.0 as f64 / 1000.0)
}

#[derive(Serialize, Clone, Debug)]
pub struct FloorKind {
    pub kind: String,
    pub jobs: usize,
    pub cpu_ms_per_job: f64,
    pub wall_ms_per_job: f64,
}

#[derive(Serialize, Clone, Debug)]
pub struct Floor {
    pub cores: usize,
    pub kinds: Vec<FloorKind>,
    /// The mean CPU time of a small job, the kinds in equal turns.
    pub mean_cpu_ms: f64,
    /// cores / mean CPU time: the most small jobs per second the machine could complete.
    pub jobs_per_s: f64,
}

#[derive(Serialize, Clone, Debug)]
pub struct Phase {
    pub name: String,
    pub clients: usize,
    pub seconds: f64,
    pub accepted: usize,
    /// Jobs of this phase that finished (succeeded) inside the phase's window.
    pub completed_in_window: usize,
    pub jobs_per_s: f64,
    pub fraction_of_floor: f64,
    /// CPU seconds all processes of the deployment used, over cores × seconds.
    pub cpu_utilisation: f64,
    pub burst_503: u64,
    pub requests: BTreeMap<String, RequestFigures>,
}

#[derive(Serialize, Clone, Debug, Default)]
pub struct Checks {
    pub accepted: usize,
    pub succeeded: usize,
    pub failed: usize,
    /// Accepted jobs not found at the end, or not ended within the drain time.
    pub lost: usize,
    pub artifacts_checked: usize,
    pub artifact_mismatches: usize,
    pub problems: Vec<String>,
}

#[derive(Serialize, Clone, Debug)]
pub struct Report {
    pub setup: String,
    pub deployment: String,
    pub command: String,
    pub started: String,
    pub floor: Floor,
    pub phases: Vec<Phase>,
    pub checks: Checks,
    pub verdicts: BTreeMap<String, bool>,
}

impl Report {
    pub fn markdown(&self) -> String {
        let mut s =
            format!("## Load test: {} — {}\n\n`{}` ({})\n\n", self.setup, self.deployment, self.command, self.started);
        s += &format!(
            "Floor ({} cores): {}; mean {:.1} ms CPU per small job → **{:.1} jobs/s**.\n\n",
            self.floor.cores,
            self.floor
                .kinds
                .iter()
                .map(|k| format!("{} {:.1} ms", k.kind, k.cpu_ms_per_job))
                .collect::<Vec<_>>()
                .join(", "),
            self.floor.mean_cpu_ms,
            self.floor.jobs_per_s
        );
        s += "| phase | clients | s | accepted | done in window | jobs/s | of floor | CPU used | submit p50 / p99 ms | poll p99 | events p99 | download p99 | failed requests | 503 (burst) |\n";
        s += "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
        for p in &self.phases {
            let r = |n: &str| p.requests.get(n);
            let submit = r("submit").or(r("burst submit"));
            let p99 = |n: &str| r(n).map_or("–".to_string(), |f| format!("{:.1}", f.p99_ms));
            let failed: usize = p.requests.values().map(|f| f.failed).sum();
            s += &format!(
                "| {} | {} | {:.0} | {} | {} | {:.1} | {:.0} % | {:.0} % | {} | {} | {} | {} | {} | {} |\n",
                p.name,
                p.clients,
                p.seconds,
                p.accepted,
                p.completed_in_window,
                p.jobs_per_s,
                100.0 * p.fraction_of_floor,
                100.0 * p.cpu_utilisation,
                submit.map_or("–".into(), |f| format!("{:.1} / {:.1}", f.p50_ms, f.p99_ms)),
                p99("poll"),
                p99("events"),
                p99("download"),
                failed,
                p.burst_503
            );
        }
        let c = &self.checks;
        s += &format!(
            "\nEnd checks: {} accepted, {} succeeded, {} failed, **{} lost**; {} artifacts downloaded, {} not matching their sha256; {} other problems.\n\n",
            c.accepted, c.succeeded, c.failed, c.lost, c.artifacts_checked, c.artifact_mismatches, c.problems.len()
        );
        for (what, ok) in &self.verdicts {
            s += &format!("- {} {what}\n", if *ok { "✔" } else { "✘" });
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::percentile_ms;

    #[test]
    fn percentiles_read_the_cumulative_counts() {
        // 100 requests: 90 at 1 ms, 9 at 5 ms, 1 at 40 ms.
        let b = [(1000, 90), (5000, 9), (40_000, 1)];
        assert_eq!(percentile_ms(&b, 0.5), 1.0);
        assert_eq!(percentile_ms(&b, 0.9), 1.0);
        assert_eq!(percentile_ms(&b, 0.91), 5.0);
        assert_eq!(percentile_ms(&b, 0.99), 5.0);
        assert_eq!(percentile_ms(&b, 1.0), 40.0);
        assert_eq!(percentile_ms(&[], 0.99), 0.0);
    }
}
