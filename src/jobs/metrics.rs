//! Prometheus figures about jobs: counts by kind and status, queue depth, run durations.

use prometheus::{Encoder, HistogramOpts, HistogramVec, IntGauge, IntGaugeVec, Opts, Registry, TextEncoder};

use super::JobStatus;

pub struct Metrics {
    /// Scrapes refill the job gauges from the store; one at a time, so none reads a half-filled set.
    render_lock: parking_lot::Mutex<()>,
    registry: Registry,
    jobs: IntGaugeVec,
    queue_depth: IntGauge,
    running: IntGauge,
    duration: HistogramVec,
    memory_reserved: IntGauge,
    memory_budget: IntGauge,
    queue_wait: prometheus::Histogram,
}

impl Default for Metrics {
    fn default() -> Self {
        Self::new()
    }
}

impl Metrics {
    pub fn new() -> Self {
        let registry = Registry::new();
        let jobs =
            IntGaugeVec::new(Opts::new("landform_jobs", "Jobs in the store by kind and status"), &["kind", "status"])
                .expect("metric");
        let queue_depth = IntGauge::new("landform_queue_depth", "Jobs waiting in the queue").expect("metric");
        let running = IntGauge::new("landform_jobs_running", "Jobs running now").expect("metric");
        let duration = HistogramVec::new(
            HistogramOpts::new("landform_job_duration_seconds", "Wall time of finished job runs")
                .buckets(vec![0.01, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 120.0, 300.0, 600.0]),
            &["kind", "status"],
        )
        .expect("metric");
        let memory_reserved = IntGauge::new(
            "landform_memory_reserved_bytes",
            "Estimated peak memory of the jobs running now, reserved against the budget",
        )
        .expect("metric");
        let memory_budget =
            IntGauge::new("landform_memory_budget_bytes", "Memory the running jobs' estimates may add up to")
                .expect("metric");
        let queue_wait = prometheus::Histogram::with_opts(
            HistogramOpts::new("landform_queue_wait_seconds", "Time jobs waited in the queue before they ran")
                .buckets(vec![0.001, 0.01, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 300.0, 600.0]),
        )
        .expect("metric");
        for c in [
            Box::new(jobs.clone()) as Box<dyn prometheus::core::Collector>,
            Box::new(queue_depth.clone()),
            Box::new(running.clone()),
            Box::new(duration.clone()),
            Box::new(memory_reserved.clone()),
            Box::new(memory_budget.clone()),
            Box::new(queue_wait.clone()),
        ] {
            registry.register(c).expect("register metric");
        }
        Self {
            render_lock: parking_lot::Mutex::new(()),
            registry,
            jobs,
            queue_depth,
            running,
            duration,
            memory_reserved,
            memory_budget,
            queue_wait,
        }
    }

    pub fn set_memory_reserved(&self, bytes: u64) {
        self.memory_reserved.set(i64::try_from(bytes).unwrap_or(i64::MAX));
    }

    pub fn set_memory_budget(&self, bytes: u64) {
        self.memory_budget.set(i64::try_from(bytes).unwrap_or(i64::MAX));
    }

    pub fn observe_queue_wait(&self, seconds: f64) {
        self.queue_wait.observe(seconds);
    }

    pub fn set_queue_depth(&self, n: usize) {
        self.queue_depth.set(n as i64);
    }

    pub fn running_delta(&self, d: i64) {
        self.running.add(d);
    }

    pub fn observe_duration(&self, kind: &str, status: JobStatus, seconds: f64) {
        self.duration.with_label_values(&[kind, status.as_str()]).observe(seconds);
    }

    /// Prometheus text exposition, with job counts refreshed from `counts`.
    pub fn render(&self, kinds: &[&str], counts: &[(String, JobStatus, u64)]) -> String {
        let _one_at_a_time = self.render_lock.lock();
        for kind in kinds {
            for st in JobStatus::ALL {
                self.jobs.with_label_values(&[kind, st.as_str()]).set(0);
            }
        }
        for (kind, st, n) in counts {
            self.jobs.with_label_values(&[kind.as_str(), st.as_str()]).set(*n as i64);
        }
        let mut out = Vec::new();
        TextEncoder::new().encode(&self.registry.gather(), &mut out).expect("text encoding");
        String::from_utf8(out).unwrap_or_default()
    }
}
