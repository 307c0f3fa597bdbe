//! Taking jobs off the queue as the memory budget allows and running each on a thread of its own.

use std::collections::HashMap;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use chrono::Utc;
use serde_json::{json, Value};

use super::engine::Engine;
use super::live::{LiveJob, StopReason};
use super::store_terrain::StoreTerrain;
use super::{Artifact, Job, JobKind, JobOutput, JobStatus, ProgressSink, RunContext, SimError};
use crate::export::{GlbForm, MeshSettings};
use crate::store::JobStore;
use crate::validate::Limits;

/// Base of the `type` URI of every problem this service reports.
pub const PROBLEM_TYPE_BASE: &str = "https://landform.dev/problems";

/// An RFC 9457 problem object, for a job's `error`.
pub fn problem(slug: &str, title: &str, detail: &str, status: u16) -> Value {
    json!({ "type": format!("{PROBLEM_TYPE_BASE}/{slug}"), "title": title, "status": status, "detail": detail })
}

impl Engine {
    /// Take jobs off the queue in order while the next one fits: the sum of the running jobs'
    /// estimated memory stays within the budget (a job alone always runs) and at most
    /// `concurrent_jobs` run at once. The rest wait in order, so a large job is not passed over.
    pub(super) async fn dispatch_loop(&self) {
        let cap = self.inner.config.concurrent_jobs.max(1);
        let budget = self.inner.config.memory_budget;
        loop {
            if self.inner.draining.load(Ordering::SeqCst) {
                return;
            }
            let next = {
                let mut q = self.inner.queue.lock();
                let fits = q.items.front().is_some_and(|w| {
                    q.running < cap && (q.running == 0 || q.memory_reserved.saturating_add(w.memory) <= budget)
                });
                let next = if fits { q.items.pop_front() } else { None };
                if let Some(w) = &next {
                    q.running += 1;
                    q.memory_reserved = q.memory_reserved.saturating_add(w.memory);
                }
                self.inner.metrics.set_queue_depth(q.items.len());
                self.inner.metrics.set_memory_reserved(q.memory_reserved);
                next
            };
            match next {
                Some(w) => {
                    self.inner.metrics.observe_queue_wait(w.since.elapsed().as_secs_f64());
                    let engine = self.clone();
                    tokio::spawn(async move {
                        engine.run_job(&w.id).await;
                        engine.release(w.memory);
                    });
                }
                None => self.inner.queue_notify.notified().await,
            }
        }
    }

    /// A dispatched job has ended: give back its memory and let the dispatcher look again.
    fn release(&self, memory: u64) {
        let mut q = self.inner.queue.lock();
        q.running -= 1;
        q.memory_reserved = q.memory_reserved.saturating_sub(memory);
        self.inner.metrics.set_memory_reserved(q.memory_reserved);
        drop(q);
        self.inner.queue_notify.notify_one();
    }

    async fn run_job(&self, id: &str) {
        let Some(live) = self.live_job(id) else { return };
        let sid = id.to_string();
        let mut job = match self.blocking(move |s| s.get(&sid)).await {
            Ok(Some(job)) if job.status == JobStatus::Queued => job,
            Ok(_) => {
                // Deleted, or ended by someone else, while it waited.
                self.forget(id);
                live.emit_done(json!({ "id": id, "status": JobStatus::Cancelled }));
                return;
            }
            Err(e) => {
                tracing::error!(job = %id, error = %e, "could not load a queued job");
                self.forget(id);
                live.emit_done(json!({ "id": id, "status": JobStatus::Failed }));
                return;
            }
        };
        if live.flag.cancel.load(Ordering::Relaxed) {
            return self.end(job, &live, Err(SimError::Cancelled), 0.0).await;
        }

        job.status = JobStatus::Running;
        job.started_at = Some(Utc::now());
        job.progress.stage = "running".into();
        let stored = job.clone();
        if let Err(e) = self.blocking(move |s| s.update(&stored)).await {
            tracing::error!(job = %id, error = %e, "could not mark a job running");
            return self.end(job, &live, Err(SimError::Failed(STORE_FAILED.into())), 0.0).await;
        }
        live.emit_status(JobStatus::Running);
        self.inner.metrics.running_delta(1);

        let started = Instant::now();
        let (tx, rx) = tokio::sync::oneshot::channel();
        let engine = self.clone();
        let run_job = job.clone();
        let run_live = live.clone();
        // A thread of its own: the job's serial parts run beside other jobs', and its parallel
        // iterators share the global Rayon pool with theirs.
        let spawned = std::thread::Builder::new().name(format!("landform-job-{}", short_id(id))).spawn(move || {
            let out = std::panic::catch_unwind(AssertUnwindSafe(|| engine.compute(&run_job, &run_live)));
            let _ = tx.send(out);
        });
        if let Err(e) = spawned {
            tracing::error!(job = %id, error = %e, "could not start a job thread");
        }

        let timeout = self.inner.config.job_timeout;
        let timer_live = live.clone();
        let timer = tokio::spawn(async move {
            tokio::time::sleep(timeout).await;
            timer_live.stop(StopReason::TimedOut);
        });
        let outcome = match rx.await {
            Ok(Ok(r)) => r,
            Ok(Err(panic)) => {
                let msg = panic_message(panic.as_ref());
                tracing::error!(job = %id, panic = %msg, "job panicked");
                Err(SimError::Failed("the simulation stopped on an internal error".into()))
            }
            Err(_) => Err(SimError::Failed("the simulation ended without a result".into())),
        };
        timer.abort();
        self.inner.metrics.running_delta(-1);
        self.end(job, &live, outcome, started.elapsed().as_secs_f64()).await
    }

    /// The CPU work of one job, on its own thread.
    fn compute(&self, job: &Job, live: &Arc<LiveJob>) -> Result<JobOutput, SimError> {
        let c = &self.inner;
        compute(&c.kinds, c.store.clone(), &c.config.limits, job, &live.flag.cancel, live.as_ref())
    }

    /// Record how a job ended and tell everyone waiting. Whatever the store does, the job's
    /// stream gets its `done` and the engine lets go of it.
    pub(super) async fn end(
        &self,
        mut job: Job,
        live: &Arc<LiveJob>,
        outcome: Result<JobOutput, SimError>,
        seconds: f64,
    ) {
        if live.stop_reason() == Some(StopReason::ShuttingDown) && outcome.is_err() {
            // Back to the queue, as it was before it started: the next start runs it again.
            job.status = JobStatus::Queued;
            job.started_at = None;
            job.progress = super::Progress { stage: "queued".into(), ..super::Progress::default() };
            let stored = job.clone();
            if let Err(e) = self.blocking(move |s| s.update(&stored)).await {
                tracing::error!(job = %job.id, error = %e, "could not return a job to the queue");
            }
            tracing::info!(job = %job.id, "returned to the queue at shutdown");
            live.emit_status(JobStatus::Queued);
            self.forget(&job.id);
            return;
        }
        if live.stop_reason() == Some(StopReason::Deleted) {
            self.forget(&job.id);
            job.status = JobStatus::Cancelled;
            job.error = Some(problem("deleted", "Job deleted", "the job was deleted", 410));
            live.emit_done(serde_json::to_value(job.with_hrefs().summarised()).unwrap_or(Value::Null));
            return;
        }
        let artifacts = settle(&mut job, outcome, live.stop_reason(), self.inner.config.job_timeout.as_secs());
        let stored = job.clone();
        let finished = match self.blocking(move |s| s.finish(&stored, &artifacts)).await {
            Ok(()) => {
                let id = job.id.clone();
                match self.blocking(move |s| s.get(&id)).await {
                    Ok(Some(j)) => j,
                    _ => job,
                }
            }
            Err(e) => {
                tracing::error!(job = %job.id, error = %e, "could not record how a job ended");
                job.status = JobStatus::Failed;
                job.result = None;
                job.error = Some(problem("store-failed", "Job not recorded", STORE_FAILED, 500));
                let stored = job.clone();
                if let Err(e) = self.blocking(move |s| s.finish(&stored, &[])).await {
                    tracing::error!(job = %job.id, error = %e, "could not record the failure either");
                }
                job
            }
        };
        if seconds > 0.0 {
            self.inner.metrics.observe_duration(&finished.kind, finished.status, seconds);
        }
        tracing::info!(job = %finished.id, kind = %finished.kind, status = finished.status.as_str(), seconds, "job ended");
        let finished = finished.with_hrefs();
        live.emit_status(finished.status);
        live.emit_done(serde_json::to_value(&finished).unwrap_or(Value::Null));
        self.forget(&finished.id);
    }

    /// Drop the in-memory state of a job that has ended.
    fn forget(&self, id: &str) {
        self.inner.live.lock().remove(id);
        self.dequeue(id);
    }
}

/// Run a job's kind, or replay its original's sequence, reporting to `sink` and stopping
/// when `cancel` is raised. Shared by the engine and the store-queue worker.
pub(super) fn compute(
    kinds: &HashMap<&'static str, Arc<dyn JobKind>>,
    store: Arc<dyn JobStore>,
    limits: &Limits,
    job: &Job,
    cancel: &AtomicBool,
    sink: &dyn ProgressSink,
) -> Result<JobOutput, SimError> {
    let kind =
        kinds.get(job.kind.as_str()).ok_or_else(|| SimError::Failed(format!("no job kind named {}", job.kind)))?;
    let lookup = StoreTerrain { store: store.clone(), owner: job.owner.clone() };
    let ctx = RunContext { cancel, sink, terrain: &lookup, limits, mesh: mesh_settings(job), draft: false };
    let params = job.params();
    match job.replay_spec() {
        None => kind.run(&params, job.seed(), &ctx),
        Some(spec) => {
            let sequence = store.artifact(&spec.of, "sequence.json").map_err(|e| {
                tracing::error!(job = %job.id, error = %e, "could not read the sequence to replay");
                SimError::Failed(STORE_FAILED.into())
            })?;
            let (_, sequence) =
                sequence.ok_or_else(|| SimError::Failed(format!("job {} and its sequence are gone", spec.of)))?;
            kind.replay(&params, &sequence, spec.until_step, &ctx)
        }
    }
}

/// How the job's glbs are written: its request's `compression` and `lods`. A job stored before
/// a field existed has none of it and wrote f32 glbs without levels of detail, which its replays
/// must give again byte for byte.
fn mesh_settings(job: &Job) -> MeshSettings {
    let form = job.request.get("compression").and_then(Value::as_str).and_then(GlbForm::parse).unwrap_or(GlbForm::None);
    let lods = job.request.get("lods").and_then(|l| MeshSettings::parse_lods(l).ok()).unwrap_or_default();
    MeshSettings { form, lods }
}

/// The message of a panic caught around a job.
pub(super) fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_default()
}

/// The end of a job id (UUIDv7's random part), to name its thread.
pub(super) fn short_id(id: &str) -> &str {
    &id[id.len().saturating_sub(8)..]
}

pub(super) const STORE_FAILED: &str = "the job store failed; the server's log has the details";

/// Fill in the job's final status, result and error; returns the artifacts to store.
pub(super) fn settle(
    job: &mut Job,
    outcome: Result<JobOutput, SimError>,
    stop: Option<StopReason>,
    timeout_s: u64,
) -> Vec<Artifact> {
    job.finished_at = Some(Utc::now());
    let mut artifacts = Vec::new();
    match outcome {
        Ok(out) => {
            job.status = JobStatus::Succeeded;
            job.result = Some(out.result);
            job.progress.fraction = 1.0;
            job.progress.stage = "done".into();
            artifacts = out.artifacts;
        }
        Err(SimError::Cancelled) if stop == Some(StopReason::TimedOut) => {
            job.status = JobStatus::Failed;
            let detail = format!("the job ran longer than {timeout_s} s");
            job.error = Some(problem("timeout", "Job time limit exceeded", &detail, 504));
        }
        Err(SimError::Cancelled) => {
            job.status = JobStatus::Cancelled;
            job.error = Some(problem("cancelled", "Job cancelled", "the job was cancelled on request", 409));
        }
        Err(e) => {
            job.status = JobStatus::Failed;
            let mut p = problem("job-failed", "Job failed", &e.to_string(), 422);
            if let SimError::Invalid { field, message } = &e {
                p["errors"] = json!([{ "field": field, "message": message }]);
            }
            job.error = Some(p);
        }
    }
    job.progress.message = job.status.as_str().to_string();
    artifacts
}
