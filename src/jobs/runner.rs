//! Taking jobs off the queue and running them on the Rayon pool.

use std::panic::AssertUnwindSafe;
use std::sync::Arc;
use std::time::Instant;

use chrono::Utc;
use serde_json::{json, Value};

use super::engine::Engine;
use super::live::{LiveJob, StopReason};
use super::store_terrain::StoreTerrain;
use super::{Job, JobOutput, JobStatus, RunContext, SimError};

/// Problem `type` URIs of job failures.
const PROBLEM_BASE: &str = "https://landform.dev/problems";

impl Engine {
    pub(super) async fn dispatch_loop(&self) {
        loop {
            let next = {
                let mut q = self.inner.queue.lock();
                let id = q.pop_front();
                self.inner.metrics.set_queue_depth(q.len());
                id
            };
            match next {
                Some(id) => {
                    if let Err(e) = self.run_job(&id).await {
                        tracing::error!(job = %id, error = %e, "job bookkeeping failed");
                    }
                }
                None => self.inner.queue_notify.notified().await,
            }
        }
    }

    async fn run_job(&self, id: &str) -> Result<(), super::engine::EngineError> {
        let Some(live) = self.live_job(id) else { return Ok(()) };
        let sid = id.to_string();
        let Some(mut job) = self.blocking(move |s| s.get(&sid)).await? else {
            self.forget(id);
            return Ok(());
        };
        if job.status != JobStatus::Queued {
            self.forget(id);
            return Ok(());
        }
        if live.cancel.load(std::sync::atomic::Ordering::Relaxed) {
            return self.end(job, &live, Err(SimError::Cancelled), 0.0).await;
        }

        job.status = JobStatus::Running;
        job.started_at = Some(Utc::now());
        job.progress.stage = "running".into();
        let stored = job.clone();
        self.blocking(move |s| s.update(&stored)).await?;
        live.emit_status(JobStatus::Running);
        self.inner.metrics.running_delta(1);

        let started = Instant::now();
        let (tx, rx) = tokio::sync::oneshot::channel();
        let engine = self.clone();
        let run_job = job.clone();
        let run_live = live.clone();
        self.inner.pool.spawn(move || {
            let out = std::panic::catch_unwind(AssertUnwindSafe(|| engine.compute(&run_job, &run_live)));
            let _ = tx.send(out);
        });

        let timeout = self.inner.config.job_timeout;
        let timer_live = live.clone();
        let timer = tokio::spawn(async move {
            tokio::time::sleep(timeout).await;
            timer_live.stop(StopReason::TimedOut);
        });
        let outcome = match rx.await {
            Ok(Ok(r)) => r,
            Ok(Err(panic)) => {
                let msg = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                tracing::error!(job = %id, panic = %msg, "job panicked");
                Err(SimError::Failed("the simulation stopped on an internal error".into()))
            }
            Err(_) => Err(SimError::Failed("the simulation ended without a result".into())),
        };
        timer.abort();
        self.inner.metrics.running_delta(-1);
        self.end(job, &live, outcome, started.elapsed().as_secs_f64()).await
    }

    /// The CPU work of one job, on a pool thread.
    fn compute(&self, job: &Job, live: &Arc<LiveJob>) -> Result<JobOutput, SimError> {
        let kind = self
            .inner
            .kinds
            .get(job.kind.as_str())
            .ok_or_else(|| SimError::Failed(format!("no job kind named {}", job.kind)))?;
        let lookup = StoreTerrain(self.inner.store.clone());
        let ctx = RunContext {
            cancel: &live.cancel,
            sink: live.as_ref(),
            terrain: &lookup,
            limits: &self.inner.config.limits,
        };
        let params = job.params();
        match job.replay_spec() {
            None => kind.run(&params, job.seed(), &ctx),
            Some(spec) => {
                let (_, sequence) = self
                    .inner
                    .store
                    .artifact(&spec.of, "sequence.json")
                    .map_err(|e| SimError::Failed(e.to_string()))?
                    .ok_or_else(|| SimError::Failed(format!("job {} and its sequence are gone", spec.of)))?;
                kind.replay(&params, &sequence, spec.until_step, &ctx)
            }
        }
    }

    /// Record how a job ended and tell everyone waiting.
    pub(super) async fn end(
        &self,
        mut job: Job,
        live: &Arc<LiveJob>,
        outcome: Result<JobOutput, SimError>,
        seconds: f64,
    ) -> Result<(), super::engine::EngineError> {
        if live.stop_reason() == Some(StopReason::Deleted) {
            self.forget(&job.id);
            live.emit_done(json!({ "id": job.id, "status": "cancelled", "deleted": true }));
            return Ok(());
        }
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
            Err(SimError::Cancelled) if live.stop_reason() == Some(StopReason::TimedOut) => {
                job.status = JobStatus::Failed;
                job.error = Some(problem(
                    "timeout",
                    "Job time limit exceeded",
                    &format!("the job ran longer than {} s", self.inner.config.job_timeout.as_secs()),
                ));
            }
            Err(SimError::Cancelled) => {
                job.status = JobStatus::Cancelled;
                job.error = Some(problem("cancelled", "Job cancelled", "the job was cancelled on request"));
            }
            Err(e) => {
                job.status = JobStatus::Failed;
                let mut p = problem("job-failed", "Job failed", &e.to_string());
                if let SimError::Invalid { field, message } = &e {
                    p["errors"] = json!([{ "field": field, "message": message }]);
                }
                job.error = Some(p);
            }
        }
        job.progress.message = job.status.as_str().to_string();
        let stored = job.clone();
        self.blocking(move |s| s.finish(&stored, &artifacts)).await?;
        if seconds > 0.0 {
            self.inner.metrics.observe_duration(&job.kind, job.status, seconds);
        }
        let id = job.id.clone();
        let finished = self.blocking(move |s| s.get(&id)).await?.map(Job::with_hrefs).unwrap_or(job);
        live.emit_status(finished.status);
        live.emit_done(serde_json::to_value(&finished).unwrap_or(Value::Null));
        self.forget(&finished.id);
        tracing::info!(job = %finished.id, kind = %finished.kind, status = finished.status.as_str(), seconds, "job ended");
        Ok(())
    }

    /// Drop the in-memory state of a job that has ended.
    fn forget(&self, id: &str) {
        self.inner.live.lock().remove(id);
        self.inner.queue.lock().retain(|q| q != id);
    }
}

/// An RFC 9457 problem object for a job's `error`.
pub fn problem(kind: &str, title: &str, detail: &str) -> Value {
    json!({ "type": format!("{PROBLEM_BASE}/{kind}"), "title": title, "status": 422, "detail": detail })
}
