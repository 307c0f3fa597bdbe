//! The API's view of jobs that run in other processes (`--role api`, workers elsewhere): the
//! queue's room, progress, events, waiting, cancelling and live snapshots, all read from the
//! store, so every API replica answers the same for every job.

use std::time::{Duration, Instant};

use chrono::Utc;
use tokio::sync::broadcast;

use super::engine::{Engine, EngineError};
use super::runner::problem;
use super::{Job, JobStatus, Progress};
use crate::store::{Notice, StoredEvent};

/// How often a waiting request or an event stream looks at the store again when the store
/// sends no notices (SQLite).
pub const STORE_POLL: Duration = Duration::from_millis(100);
/// With notices (PostgreSQL), how often it looks all the same, in case one was missed.
pub const NOTICE_FALLBACK: Duration = Duration::from_secs(1);

/// Wait until job `id` may have changed: a notice for it or a reconnect of the listener, or
/// the fallback look; without notices, one poll interval.
pub async fn until_changed(id: &str, notices: &mut Option<broadcast::Receiver<Notice>>) {
    let Some(rx) = notices else {
        return tokio::time::sleep(STORE_POLL).await;
    };
    let heard = async {
        loop {
            match rx.recv().await {
                Ok(Notice::Changed(job) | Notice::Queued(job)) if job != id => continue,
                Ok(_) | Err(broadcast::error::RecvError::Lagged(_)) => return,
                Err(broadcast::error::RecvError::Closed) => return std::future::pending().await,
            }
        }
    };
    let _ = tokio::time::timeout(NOTICE_FALLBACK, heard).await;
}
/// How long a cancel request waits for the job's worker to stop it.
const CANCEL_WAIT: Duration = Duration::from_secs(5);

impl Engine {
    /// A running job's progress: its latest progress event.
    pub(super) async fn stored_progress(&self, job: &mut Job) {
        let id = job.id.clone();
        match self.blocking(move |s| s.last_event(&id, "progress")).await {
            Ok(Some(event)) => {
                if let Ok(progress) = serde_json::from_str::<Progress>(&event.data) {
                    job.progress = progress;
                }
            }
            Ok(None) => {}
            Err(e) => tracing::warn!(job = %job.id, error = %e, "could not read a job's progress"),
        }
    }

    /// A job's events after `after`, for a stream that follows it from this replica.
    pub async fn stored_events(&self, id: &str, after: u64) -> Result<Vec<StoredEvent>, EngineError> {
        let id = id.to_string();
        self.blocking(move |s| s.events_after(&id, after, 256)).await
    }

    /// Wait up to `timeout` for a job running elsewhere to end; returns it either way. Polls
    /// the status alone: a job's row (its request may be megabytes) is read once, at the end.
    pub(super) async fn wait_stored(&self, id: &str, timeout: Duration) -> Result<Job, EngineError> {
        let started = Instant::now();
        let mut notices = self.notices();
        loop {
            let (status, _) = self.status_of(id).await?;
            let left = timeout.saturating_sub(started.elapsed());
            if status.is_terminal() || left.is_zero() {
                return self.get_any(id).await;
            }
            let _ = tokio::time::timeout(left, until_changed(id, &mut notices)).await;
        }
    }

    /// A job's status and owner, without reading the rest of it.
    pub async fn status_of(&self, id: &str) -> Result<(JobStatus, Option<String>), EngineError> {
        let sid = id.to_string();
        self.blocking(move |s| s.status(&sid)).await?.ok_or_else(|| EngineError::NotFound(id.to_string()))
    }

    /// Notices of changes from any process, where the store sends them.
    pub fn notices(&self) -> Option<broadcast::Receiver<Notice>> {
        self.inner.store.notices()
    }

    /// Cancel a job that runs (or waits) for a worker elsewhere: a queued job ends here, under
    /// the fence of its attempt count so a worker claiming it at that moment wins or loses
    /// cleanly; a running one is asked to stop, and its worker sees that at its next renewal.
    pub(super) async fn cancel_stored(&self, mut job: Job) -> Result<Job, EngineError> {
        let id = job.id.clone();
        if job.status == JobStatus::Queued {
            let sid = id.clone();
            let attempts = self.blocking(move |s| s.attempts(&sid)).await?.unwrap_or(0);
            job.status = JobStatus::Cancelled;
            job.finished_at = Some(Utc::now());
            job.error = Some(problem("cancelled", "Job cancelled", "the job was cancelled on request", 409));
            job.progress.message = job.status.as_str().to_string();
            let stored = job.clone();
            if self.blocking(move |s| s.update_claimed(&stored, attempts)).await? {
                return self.get_any(&id).await;
            }
            // A worker claimed it meanwhile: ask that worker to stop it.
        }
        let sid = id.clone();
        if !self.blocking(move |s| s.request_cancel(&sid)).await? {
            return Err(EngineError::Conflict(format!("job {id} has already ended")));
        }
        self.wait_stored(&id, CANCEL_WAIT).await
    }

    /// Count in this process's metrics what its workers did since the last look: each job that
    /// ended (its run time and its wait in the queue), and the memory running jobs reserve.
    pub(super) async fn observe_stored(&self) -> Result<(), EngineError> {
        let since = *self.inner.metrics_since.lock();
        let (ended, reserved) = self.blocking(move |s| Ok((s.ended_after(since, 10_000)?, s.reserved()?))).await?;
        let metrics = &self.inner.metrics;
        for job in &ended {
            if let (Some(started), Some(finished)) = (job.started_at, job.finished_at) {
                let run = (finished - started).to_std().unwrap_or_default().as_secs_f64();
                metrics.observe_duration(&job.kind, job.status, run);
                metrics.observe_queue_wait((started - job.created_at).to_std().unwrap_or_default().as_secs_f64());
            }
        }
        if let Some(last) = ended.last().and_then(|j| j.finished_at) {
            *self.inner.metrics_since.lock() = last;
        }
        metrics.set_memory_reserved(reserved);
        Ok(())
    }

    /// The latest live snapshot of a job running elsewhere, if `owner` may see it.
    pub(super) async fn stored_snapshot(
        &self,
        id: &str,
        owner: Option<&str>,
    ) -> Result<Option<(u64, bytes::Bytes)>, EngineError> {
        let job = match self.get(id, owner).await {
            Ok(job) => job,
            Err(EngineError::NotFound(_)) => return Ok(None),
            Err(e) => return Err(e),
        };
        if job.status.is_terminal() {
            return Ok(None);
        }
        let sid = id.to_string();
        Ok(self.blocking(move |s| s.snapshot(&sid)).await?.map(|(n, png)| (n, bytes::Bytes::from(png))))
    }
}
