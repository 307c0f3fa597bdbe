//! A worker that runs jobs from the store's queue, so that jobs can run in processes (and on
//! machines) other than the API's: it claims the oldest job that fits its free memory budget,
//! renews the claim's lease from a tokio task while the job runs on a thread of its own (its
//! parallel work on the shared Rayon pool), reports progress and live snapshots to the store's
//! event log, and records the outcome under the claim. A lease that runs out while the worker
//! stalls makes the job another worker's: the first worker's writes are refused by the fence,
//! and its own renewal tells it to stop.

use std::collections::HashMap;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use chrono::Utc;
use parking_lot::Mutex;
use tokio::sync::Notify;

use super::live::{progress_data, StopFlag, StopReason, Throttle};
use super::remote::NOTICE_FALLBACK;
use super::runner::{compute, panic_message, problem, settle, short_id};
use super::{Job, JobKind, JobOutput, JobStatus, Progress, ProgressSink, SimError};
use crate::store::{Claim, EventLog, Notice, Renewal, StoreError};
use crate::validate::Limits;
use tokio::sync::broadcast::error::RecvError;

/// A job that took its worker down this many times (its lease ran out each time) is failed
/// instead of being claimed again.
pub const MAX_LOST_LEASES: u32 = 3;

/// How long an ended job's events stay for the streams still reading them, and how often a
/// worker deletes the older ones: the event table holds about the running jobs only.
const EVENTS_KEPT: chrono::TimeDelta = chrono::TimeDelta::seconds(60);
const PRUNE_EVERY: Duration = Duration::from_secs(30);

#[derive(Clone, Debug)]
pub struct WorkerConfig {
    /// Who holds the claims (kept with the lease, for operators).
    pub name: String,
    /// Jobs run together while the sum of their estimates fits; one job alone always runs.
    pub memory_budget: u64,
    pub concurrent_jobs: usize,
    /// How long a claim holds without renewal; renewed every third of it.
    pub lease: Duration,
    /// How often an idle worker looks at the queue when nothing wakes it sooner.
    pub poll: Duration,
    pub job_timeout: Duration,
    pub limits: Limits,
}

/// What the running jobs hold.
#[derive(Default)]
struct Held {
    running: usize,
    memory: u64,
}

struct Inner {
    store: Arc<dyn EventLog>,
    kinds: HashMap<&'static str, Arc<dyn JobKind>>,
    config: WorkerConfig,
    held: Mutex<Held>,
    wake: Notify,
    draining: AtomicBool,
    jobs: Mutex<HashMap<String, Arc<RunningJob>>>,
}

#[derive(Clone)]
pub struct Worker {
    inner: Arc<Inner>,
}

impl Worker {
    pub fn new(store: Arc<dyn EventLog>, kinds: Vec<Box<dyn JobKind>>, config: WorkerConfig) -> Self {
        let kinds = kinds.into_iter().map(|k| (k.name(), Arc::from(k))).collect();
        Worker {
            inner: Arc::new(Inner {
                store,
                kinds,
                config,
                held: Mutex::new(Held::default()),
                wake: Notify::new(),
                draining: AtomicBool::new(false),
                jobs: Mutex::new(HashMap::new()),
            }),
        }
    }

    /// Look at the queue now (a submission was seen) rather than at the next poll.
    pub fn wake(&self) {
        self.inner.wake.notify_one();
    }

    /// Claim and run jobs until `shutdown`.
    pub async fn run(&self) {
        let c = &self.inner.config;
        let mut last_prune: Option<std::time::Instant> = None;
        // Where the store sends notices, a submission wakes an idle worker at once and the
        // poll is only a fallback.
        let mut notices = self.inner.store.notices();
        let idle_for = if notices.is_some() { NOTICE_FALLBACK } else { c.poll };
        while !self.inner.draining.load(Ordering::SeqCst) {
            if last_prune.is_none_or(|at| at.elapsed() >= PRUNE_EVERY) {
                last_prune = Some(std::time::Instant::now());
                let cutoff = Utc::now() - EVENTS_KEPT;
                if let Err(e) = self.blocking(move |s| s.prune_ended(cutoff)).await {
                    tracing::warn!(error = %e, "could not prune the events of ended jobs");
                }
            }
            // A claim in flight counts as running, so shutdown waits for whatever it brings.
            let max_memory = {
                let mut held = self.inner.held.lock();
                let max = if held.running >= c.concurrent_jobs.max(1) {
                    None
                } else if held.running == 0 {
                    Some(u64::MAX)
                } else {
                    Some(c.memory_budget.saturating_sub(held.memory))
                };
                if max.is_some() {
                    held.running += 1;
                }
                max
            };
            let claimed = match max_memory {
                None => None,
                Some(max) => {
                    let (name, lease) = (c.name.clone(), c.lease);
                    match self.blocking(move |s| s.claim(&name, lease, max)).await {
                        Ok(claim) => claim,
                        Err(e) => {
                            tracing::error!(error = %e, "could not claim a job");
                            None
                        }
                    }
                }
            };
            match claimed {
                Some(claim) => {
                    let memory = claim.job.cost.as_ref().map_or(c.memory_budget, |k| k.memory_bytes);
                    {
                        let mut held = self.inner.held.lock();
                        held.memory = held.memory.saturating_add(memory);
                    }
                    let worker = self.clone();
                    tokio::spawn(async move {
                        worker.run_claim(claim).await;
                        let mut held = worker.inner.held.lock();
                        held.running -= 1;
                        held.memory = held.memory.saturating_sub(memory);
                        drop(held);
                        worker.inner.wake.notify_one();
                    });
                }
                None => {
                    if max_memory.is_some() {
                        self.inner.held.lock().running -= 1;
                    }
                    let heard = async {
                        match notices.as_mut() {
                            Some(rx) => loop {
                                tokio::select! {
                                    _ = self.inner.wake.notified() => return,
                                    notice = rx.recv() => match notice {
                                        Ok(Notice::Changed(_)) => continue,
                                        Ok(_) | Err(RecvError::Lagged(_)) => return,
                                        Err(RecvError::Closed) => std::future::pending::<()>().await,
                                    },
                                }
                            },
                            None => self.inner.wake.notified().await,
                        }
                    };
                    let _ = tokio::time::timeout(idle_for, heard).await;
                }
            }
        }
    }

    /// Graceful shutdown: claim nothing more, let running jobs finish until `deadline`, then
    /// stop the rest and give their claims back, so another worker takes them at once.
    pub async fn shutdown(&self, deadline: Duration) {
        self.inner.draining.store(true, Ordering::SeqCst);
        self.inner.wake.notify_one();
        let started = std::time::Instant::now();
        while self.inner.held.lock().running > 0 && started.elapsed() < deadline {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        // Stopped again on every look: a job claimed just as the worker began draining is
        // registered a moment after its claim.
        let stopping = std::time::Instant::now();
        while self.inner.held.lock().running > 0 && stopping.elapsed() < Duration::from_secs(10) {
            for job in self.inner.jobs.lock().values() {
                job.flag.stop(StopReason::ShuttingDown);
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    async fn blocking<T: Send + 'static>(
        &self,
        f: impl FnOnce(&dyn EventLog) -> Result<T, StoreError> + Send + 'static,
    ) -> Result<T, StoreError> {
        let store = self.inner.store.clone();
        tokio::task::spawn_blocking(move || f(store.as_ref()))
            .await
            .map_err(|e| StoreError::Backend(format!("a store call did not finish: {e}")))?
    }

    async fn run_claim(&self, claim: Claim) {
        let Claim { mut job, attempt, lost_leases } = claim;
        let id = job.id.clone();
        if lost_leases >= MAX_LOST_LEASES {
            tracing::error!(job = %id, lost_leases, "a job took its worker down too often; failing it");
            job.status = JobStatus::Failed;
            job.finished_at = Some(Utc::now());
            let detail = format!(
                "the job's worker stopped without finishing it {lost_leases} times (killed, out of memory or \
                 stalled past its lease); it is not run again"
            );
            job.error = Some(problem("worker-lost", "Job took its worker down", &detail, 500));
            job.progress.message = job.status.as_str().to_string();
            self.record(&job, attempt, &[]).await;
            return;
        }
        let running = Arc::new(RunningJob {
            id: id.clone(),
            attempt,
            store: self.inner.store.clone(),
            flag: StopFlag::default(),
            throttle: Mutex::new(Throttle::default()),
            snapshots: AtomicU64::new(0),
        });
        self.inner.jobs.lock().insert(id.clone(), running.clone());

        job.started_at = Some(Utc::now());
        job.progress = Progress { stage: "running".into(), ..Progress::default() };

        let heartbeat = tokio::spawn(heartbeat(self.inner.store.clone(), running.clone(), self.inner.config.lease));
        let timer_job = running.clone();
        let timeout = self.inner.config.job_timeout;
        let timer = tokio::spawn(async move {
            tokio::time::sleep(timeout).await;
            timer_job.flag.stop(StopReason::TimedOut);
        });

        let (tx, rx) = tokio::sync::oneshot::channel();
        let (inner, run_job, sink) = (self.inner.clone(), job.clone(), running.clone());
        let spawned = std::thread::Builder::new().name(format!("landform-job-{}", short_id(&id))).spawn(move || {
            let out = std::panic::catch_unwind(AssertUnwindSafe(|| {
                // Store calls block: they are made here, never on the async threads.
                sink.append("status", &serde_json::json!({ "status": JobStatus::Running }));
                let store: Arc<dyn crate::store::JobStore> = inner.store.clone();
                compute(&inner.kinds, store, &inner.config.limits, &run_job, &sink.flag.cancel, sink.as_ref())
            }));
            let _ = tx.send(out);
        });
        if let Err(e) = spawned {
            tracing::error!(job = %id, error = %e, "could not start a job thread");
        }
        let outcome: Result<JobOutput, SimError> = match rx.await {
            Ok(Ok(r)) => r,
            Ok(Err(panic)) => {
                tracing::error!(job = %id, panic = %panic_message(panic.as_ref()), "job panicked");
                Err(SimError::Failed("the simulation stopped on an internal error".into()))
            }
            Err(_) => Err(SimError::Failed("the simulation ended without a result".into())),
        };
        heartbeat.abort();
        timer.abort();
        self.inner.jobs.lock().remove(&id);

        match running.flag.reason() {
            Some(StopReason::LeaseLost) => {
                tracing::warn!(job = %id, attempt, "the job's lease ran out; another worker has it");
            }
            Some(StopReason::ShuttingDown) if outcome.is_err() => {
                match self.blocking(move |s| s.release(&id, attempt)).await {
                    Ok(true) => tracing::info!(job = %job.id, "returned to the queue at shutdown"),
                    Ok(false) => {}
                    Err(e) => tracing::error!(job = %job.id, error = %e, "could not return a job to the queue"),
                }
            }
            reason => {
                let timeout_s = self.inner.config.job_timeout.as_secs();
                let artifacts = settle(&mut job, outcome, reason, timeout_s);
                self.record(&job, attempt, &artifacts).await;
            }
        }
    }

    /// Record how a job ended, under its claim.
    async fn record(&self, job: &Job, attempt: u32, artifacts: &[super::Artifact]) {
        let (stored, artifacts) = (job.clone(), artifacts.to_vec());
        match self.blocking(move |s| s.finish_claimed(&stored, attempt, &artifacts)).await {
            Ok(true) => tracing::info!(job = %job.id, status = job.status.as_str(), "job ended"),
            Ok(false) => tracing::warn!(job = %job.id, attempt, "the job's claim was lost before it was recorded"),
            Err(e) => tracing::error!(job = %job.id, error = %e, "could not record how a job ended"),
        }
    }
}

/// How often a running job's worker looks for a cancel request between renewals: a cancel
/// stops the job within this and the job's own next check.
pub const CANCEL_POLL: Duration = Duration::from_millis(500);

/// Renew the claim every third of its lease, and look for a cancel request every
/// [`CANCEL_POLL`] between; a cancel request or a lost claim stops the job.
async fn heartbeat(store: Arc<dyn EventLog>, job: Arc<RunningJob>, lease: Duration) {
    let renew_every = (lease / 3).max(Duration::from_millis(1));
    let mut every = tokio::time::interval(renew_every.min(CANCEL_POLL));
    every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut renewed: Option<tokio::time::Instant> = None;
    loop {
        every.tick().await;
        let (s, id, attempt) = (store.clone(), job.id.clone(), job.attempt);
        if renewed.is_some_and(|at| at.elapsed() < renew_every) {
            if let Ok(Ok(true)) = tokio::task::spawn_blocking(move || s.cancel_requested(&id)).await {
                job.flag.stop(StopReason::Cancelled);
            }
            continue;
        }
        renewed = Some(tokio::time::Instant::now());
        match tokio::task::spawn_blocking(move || s.renew(&id, attempt, lease)).await {
            Ok(Ok(Renewal::Held { cancel_requested: false })) => {}
            Ok(Ok(Renewal::Held { cancel_requested: true })) => job.flag.stop(StopReason::Cancelled),
            Ok(Ok(Renewal::Lost)) => {
                job.flag.stop(StopReason::LeaseLost);
                return;
            }
            // The database is away: keep running, the lease may still be renewed in time.
            Ok(Err(e)) => tracing::warn!(job = %job.id, error = %e, "could not renew a lease"),
            Err(e) => tracing::warn!(job = %job.id, error = %e, "a lease renewal did not finish"),
        }
    }
}

/// A job this worker runs: its stop flag, and its progress going to the store's event log.
struct RunningJob {
    id: String,
    attempt: u32,
    store: Arc<dyn EventLog>,
    flag: StopFlag,
    throttle: Mutex<Throttle>,
    snapshots: AtomicU64,
}

impl RunningJob {
    /// Append an event under the claim; its id, or None when nothing was written.
    fn append(&self, event: &str, data: &serde_json::Value) -> Option<u64> {
        match self.store.append_event(&self.id, self.attempt, event, &data.to_string()) {
            Ok(Some(id)) => Some(id),
            Ok(None) => {
                // The claim is no longer ours: stop at the next check.
                self.flag.stop(StopReason::LeaseLost);
                None
            }
            Err(e) => {
                tracing::warn!(job = %self.id, error = %e, "could not record a job event");
                None
            }
        }
    }
}

impl ProgressSink for RunningJob {
    fn progress(&self, progress: Progress) {
        if self.throttle.lock().progress_due(&progress) {
            self.append("progress", &progress_data(&progress, None));
        }
    }

    fn snapshot_due(&self) -> bool {
        self.throttle.lock().snapshot_due()
    }

    fn snapshot(&self, png: Vec<u8>, progress: Progress) {
        self.throttle.lock().snapshot_sent();
        let n = self.snapshots.fetch_add(1, Ordering::Relaxed) + 1;
        let href = format!("/v1/jobs/{}/live.png?n={n}", self.id);
        if let Some(event) = self.append("progress", &progress_data(&progress, Some(href))) {
            if let Err(e) = self.store.put_snapshot(&self.id, self.attempt, event, &png) {
                tracing::warn!(job = %self.id, error = %e, "could not keep a live snapshot");
            }
        }
    }
}
