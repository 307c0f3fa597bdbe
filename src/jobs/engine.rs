//! The engine: accepts jobs into a bounded queue, runs them on a Rayon pool (never on tokio's
//! threads), publishes progress, and records outcomes in the store.

use std::collections::{HashMap, VecDeque};
use std::sync::Arc;
use std::time::Duration;

use chrono::Utc;
use parking_lot::Mutex;
use serde_json::{Map, Value};
use tokio::sync::Notify;

use super::live::{LiveJob, StopReason};
use super::metrics::Metrics;
use super::store_terrain::StoreTerrain;
use super::{Job, JobEvent, JobKind, JobStatus, Progress, RequestError};
use crate::store::{IdempotentInsert, JobStore, ListFilter, StoreError};
use crate::validate::{FieldError, Limits};

pub const DEFAULT_QUEUE_CAPACITY: usize = 64;
pub const DEFAULT_JOB_TIMEOUT_S: u64 = 600;
/// A job interrupted by this many process stops is failed instead of run again, so one job
/// that brings the process down cannot do so for ever.
pub const MAX_ATTEMPTS: u32 = 3;
/// Longest label accepted.
const MAX_LABEL_CHARS: usize = 200;

#[derive(Clone, Debug)]
pub struct EngineConfig {
    /// Threads of the Rayon pool the simulations run on.
    pub workers: usize,
    /// Jobs that may wait in the queue; beyond it submissions get 503.
    pub queue_capacity: usize,
    /// Jobs run at the same time (each uses the whole pool).
    pub concurrent_jobs: usize,
    /// A job still running after this long is stopped and fails.
    pub job_timeout: Duration,
    pub limits: Limits,
}

impl Default for EngineConfig {
    fn default() -> Self {
        Self {
            workers: std::thread::available_parallelism().map(|n| n.get()).unwrap_or(2),
            queue_capacity: DEFAULT_QUEUE_CAPACITY,
            concurrent_jobs: 1,
            job_timeout: Duration::from_secs(DEFAULT_JOB_TIMEOUT_S),
            limits: Limits::default(),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    #[error("no job kind named {0}")]
    UnknownKind(String),
    #[error("no job with id {0}")]
    NotFound(String),
    #[error("{0}")]
    Conflict(String),
    #[error("the queue is full ({0} jobs waiting)")]
    QueueFull(usize),
    #[error("the request body is not valid JSON: {0}")]
    Malformed(String),
    #[error("the request has invalid fields")]
    Invalid { errors: Vec<FieldError>, too_large: bool },
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("internal error: {0}")]
    Internal(String),
}

impl EngineError {
    fn field(field: &str, message: impl Into<String>) -> Self {
        EngineError::Invalid {
            errors: vec![FieldError { field: field.into(), message: message.into() }],
            too_large: false,
        }
    }
}

impl From<RequestError> for EngineError {
    fn from(e: RequestError) -> Self {
        match e {
            RequestError::Malformed(m) => EngineError::Malformed(m),
            RequestError::Invalid { errors, too_large } => EngineError::Invalid { errors, too_large },
        }
    }
}

/// Where a job's events come from.
pub enum EventFeed {
    Live { backlog: Vec<JobEvent>, rx: tokio::sync::broadcast::Receiver<JobEvent>, live: Arc<LiveJob> },
    Ended(Box<Job>),
}

/// What a submission did.
pub enum Submitted {
    Created(Job),
    /// The idempotency key was used before with the same body: the job it created.
    Existing(Job),
}

/// Jobs waiting, and places promised to submissions still being stored.
#[derive(Default)]
pub(super) struct Queue {
    pub items: VecDeque<String>,
    reserved: usize,
}

pub(super) struct Inner {
    pub store: Arc<dyn JobStore>,
    pub kinds: HashMap<&'static str, Arc<dyn JobKind>>,
    pub pool: rayon::ThreadPool,
    pub queue: Mutex<Queue>,
    pub queue_notify: Notify,
    pub live: Mutex<HashMap<String, Arc<LiveJob>>>,
    pub metrics: Metrics,
    pub config: EngineConfig,
}

#[derive(Clone)]
pub struct Engine {
    pub(super) inner: Arc<Inner>,
}

/// A place in the queue held while a submission is stored; given back unless used.
struct Slot<'a>(Option<&'a Engine>);

impl Slot<'_> {
    fn used(mut self) {
        self.0 = None;
    }
}

impl Drop for Slot<'_> {
    fn drop(&mut self) {
        if let Some(engine) = self.0 {
            engine.inner.queue.lock().reserved -= 1;
        }
    }
}

impl Engine {
    /// Build the engine. A server then calls [`Engine::recover`] and, inside a tokio runtime,
    /// [`Engine::start`].
    pub fn new(
        store: Arc<dyn JobStore>,
        kinds: Vec<Box<dyn JobKind>>,
        config: EngineConfig,
    ) -> Result<Self, EngineError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(config.workers.max(1))
            .thread_name(|i| format!("landform-sim-{i}"))
            .build()
            .map_err(|e| EngineError::Internal(e.to_string()))?;
        let kinds = kinds.into_iter().map(|k| (k.name(), Arc::from(k))).collect();
        Ok(Engine {
            inner: Arc::new(Inner {
                store,
                kinds,
                pool,
                queue: Mutex::new(Queue::default()),
                queue_notify: Notify::new(),
                live: Mutex::new(HashMap::new()),
                metrics: Metrics::new(),
                config,
            }),
        })
    }

    /// At-least-once: whatever a previous process accepted and did not finish runs again,
    /// unless it has already been interrupted [`MAX_ATTEMPTS`] times.
    pub fn recover(&self) -> Result<(), EngineError> {
        for mut job in self.inner.store.unfinished()? {
            if job.status == JobStatus::Running {
                let attempts = self.inner.store.attempts(&job.id)?.unwrap_or(0);
                if attempts >= MAX_ATTEMPTS {
                    tracing::warn!(job = %job.id, attempts, "interrupted too often; failing it");
                    job.status = JobStatus::Failed;
                    job.finished_at = Some(Utc::now());
                    job.error = Some(super::runner::problem(
                        "interrupted",
                        "Job interrupted repeatedly",
                        &format!("the service stopped while this job ran, {attempts} times; it is not run again"),
                        500,
                    ));
                    self.inner.store.finish(&job, &[])?;
                    continue;
                }
                job.status = JobStatus::Queued;
                job.started_at = None;
                job.progress = Progress { stage: "queued".into(), ..Progress::default() };
                self.inner.store.update(&job)?;
            }
            tracing::info!(job = %job.id, kind = %job.kind, "re-queued after restart");
            self.enqueue(&job.id);
        }
        Ok(())
    }

    /// Spawn the dispatchers that take jobs off the queue.
    pub fn start(&self) {
        for _ in 0..self.inner.config.concurrent_jobs.max(1) {
            let engine = self.clone();
            tokio::spawn(async move { engine.dispatch_loop().await });
        }
    }

    pub fn config(&self) -> &EngineConfig {
        &self.inner.config
    }

    pub fn kind_names(&self) -> Vec<&'static str> {
        let mut names: Vec<_> = self.inner.kinds.keys().copied().collect();
        names.sort_unstable();
        names
    }

    pub fn kinds(&self) -> Vec<Arc<dyn JobKind>> {
        let mut kinds: Vec<_> = self.inner.kinds.values().cloned().collect();
        kinds.sort_by_key(|k| k.name());
        kinds
    }

    pub fn has_kind(&self, kind: &str) -> bool {
        self.inner.kinds.contains_key(kind)
    }

    pub fn queue_depth(&self) -> usize {
        self.inner.queue.lock().items.len()
    }

    pub(super) fn live_job(&self, id: &str) -> Option<Arc<LiveJob>> {
        self.inner.live.lock().get(id).cloned()
    }

    fn reserve_slot(&self) -> Option<Slot<'_>> {
        let mut q = self.inner.queue.lock();
        if q.items.len() + q.reserved < self.inner.config.queue_capacity {
            q.reserved += 1;
            Some(Slot(Some(self)))
        } else {
            None
        }
    }

    /// Put a stored job on the queue (using `slot` when one was reserved for it).
    fn enqueue_with(&self, id: &str, slot: Option<Slot<'_>>) {
        let live = self
            .inner
            .live
            .lock()
            .entry(id.to_string())
            .or_insert_with(|| Arc::new(LiveJob::new(id.to_string())))
            .clone();
        live.emit_status(JobStatus::Queued);
        let depth = {
            let mut q = self.inner.queue.lock();
            if let Some(slot) = slot {
                q.reserved -= 1;
                slot.used();
            }
            q.items.push_back(id.to_string());
            q.items.len()
        };
        self.inner.metrics.set_queue_depth(depth);
        self.inner.queue_notify.notify_one();
    }

    fn enqueue(&self, id: &str) {
        self.enqueue_with(id, None);
    }

    /// Take a job off the queue if it is still there; true when it was.
    pub(super) fn dequeue(&self, id: &str) -> bool {
        let mut q = self.inner.queue.lock();
        let before = q.items.len();
        q.items.retain(|q| q != id);
        let removed = before != q.items.len();
        self.inner.metrics.set_queue_depth(q.items.len());
        removed
    }

    /// Run blocking store work off the async threads.
    pub(super) async fn blocking<T: Send + 'static>(
        &self,
        f: impl FnOnce(&dyn JobStore) -> Result<T, StoreError> + Send + 'static,
    ) -> Result<T, EngineError> {
        let store = self.inner.store.clone();
        tokio::task::spawn_blocking(move || f(store.as_ref()))
            .await
            .map_err(|e| EngineError::Internal(e.to_string()))?
            .map_err(EngineError::from)
    }

    /// Validate a body for `kind` and queue it. `idempotency` is (key, sha256 of the body).
    pub async fn submit(
        &self,
        kind: &str,
        body: Value,
        idempotency: Option<(String, String)>,
    ) -> Result<Submitted, EngineError> {
        let kind_impl =
            self.inner.kinds.get(kind).cloned().ok_or_else(|| EngineError::UnknownKind(kind.to_string()))?;
        let Value::Object(mut body) = body else {
            return Err(EngineError::field("", "the body must be a JSON object"));
        };
        let (seed, label) = take_common_fields(&mut body)?;
        let limits = self.inner.config.limits.clone();
        let prepared = tokio::task::spawn_blocking(move || kind_impl.prepare(Value::Object(body), &limits))
            .await
            .map_err(|e| EngineError::Internal(e.to_string()))??;
        self.check_references(&prepared.references).await?;
        self.store_uploads(prepared.references.uploads).await?;

        let mut request = match prepared.params {
            Value::Object(m) => m,
            _ => Map::new(),
        };
        request.insert("seed".into(), Value::from(seed));
        if let Some(l) = &label {
            request.insert("label".into(), Value::String(l.clone()));
        }
        let job = new_job(kind, label, Value::Object(request), None);
        self.admit(job, idempotency).await
    }

    /// A new job that rebuilds `id`'s result from its recorded sequence, up to `until_step`.
    pub async fn replay(&self, id: &str, until_step: Option<u64>) -> Result<Job, EngineError> {
        let original = self.get(id).await?;
        if original.status != JobStatus::Succeeded {
            return Err(EngineError::Conflict(format!(
                "job {id} is {}; only a succeeded job can be replayed",
                original.status.as_str()
            )));
        }
        let kind = self
            .inner
            .kinds
            .get(original.kind.as_str())
            .cloned()
            .ok_or_else(|| EngineError::UnknownKind(original.kind.clone()))?;
        let sid = id.to_string();
        let sequence = self
            .blocking(move |s| s.artifact(&sid, "sequence.json"))
            .await?
            .ok_or_else(|| EngineError::Conflict(format!("job {id} has no recorded sequence")))?
            .1;
        let steps = kind.sequence_steps(&sequence).map_err(|e| EngineError::Internal(e.to_string()))?;
        if let Some(k) = until_step {
            if k > steps {
                return Err(EngineError::field("until_step", format!("the sequence has {steps} steps (got {k})")));
            }
        }
        // The earlier jobs the original read must still be there to read again.
        let prepared = kind.prepare(original.params(), &self.inner.config.limits)?;
        self.check_references(&prepared.references).await.map_err(|e| match e {
            EngineError::Invalid { errors, .. } => EngineError::Conflict(format!(
                "job {id} can no longer be replayed: {}",
                errors.into_iter().map(|e| e.message).collect::<Vec<_>>().join("; ")
            )),
            other => other,
        })?;
        let replay_of = Some((id.to_string(), until_step));
        let job = new_job(&original.kind, original.label.clone(), original.request.clone(), replay_of);
        match self.admit(job, None).await? {
            Submitted::Created(j) | Submitted::Existing(j) => Ok(j),
        }
    }

    /// Every earlier job and upload the request names must be there.
    async fn check_references(&self, refs: &super::References) -> Result<(), EngineError> {
        if refs.jobs.is_empty() && refs.inputs.is_empty() {
            return Ok(());
        }
        let store = self.inner.store.clone();
        let (jobs, inputs) = (refs.jobs.clone(), refs.inputs.clone());
        let errors = tokio::task::spawn_blocking(move || {
            let mut errors = Vec::new();
            for (field, sha) in inputs {
                match store.has_input(&sha) {
                    Ok(true) => {}
                    Ok(false) => errors.push(FieldError { field, message: format!("no upload with sha256 {sha}") }),
                    Err(e) => {
                        tracing::error!(error = %e, "store failure while checking an upload");
                        errors.push(FieldError { field, message: "the job store failed".into() })
                    }
                }
            }
            let lookup = StoreTerrain(store);
            for (field, id) in jobs {
                match lookup.unusable_reason(&id) {
                    Ok(None) => {}
                    Ok(Some(message)) | Err(message) => errors.push(FieldError { field, message }),
                }
            }
            errors
        })
        .await
        .map_err(|e| EngineError::Internal(e.to_string()))?;
        if errors.is_empty() {
            Ok(())
        } else {
            Err(EngineError::Invalid { errors, too_large: false })
        }
    }

    async fn store_uploads(&self, uploads: Vec<(String, Vec<u8>)>) -> Result<(), EngineError> {
        if uploads.is_empty() {
            return Ok(());
        }
        self.blocking(move |s| uploads.iter().try_for_each(|(sha, png)| s.put_input(sha, png))).await
    }

    async fn admit(&self, job: Job, idempotency: Option<(String, String)>) -> Result<Submitted, EngineError> {
        let capacity = self.inner.config.queue_capacity;
        let slot = self.reserve_slot();
        // An idempotent retry must still find its job when the queue is full.
        if slot.is_none() && idempotency.is_none() {
            return Err(EngineError::QueueFull(capacity));
        }
        let stored = job.clone();
        let outcome = self
            .blocking(move |s| s.insert(&stored, idempotency.as_ref().map(|(k, h)| (k.as_str(), h.as_str()))))
            .await?;
        match outcome {
            IdempotentInsert::Existing { job, same_body: true } => Ok(Submitted::Existing(*job)),
            IdempotentInsert::Existing { job, same_body: false } => Err(EngineError::Conflict(format!(
                "the Idempotency-Key was already used with a different body (job {})",
                job.id
            ))),
            IdempotentInsert::Inserted => match slot {
                Some(slot) => {
                    self.enqueue_with(&job.id, Some(slot));
                    Ok(Submitted::Created(job))
                }
                None => {
                    let id = job.id.clone();
                    self.blocking(move |s| s.delete(&id)).await?;
                    Err(EngineError::QueueFull(capacity))
                }
            },
        }
    }

    /// The job, with live progress when it is running.
    pub async fn get(&self, id: &str) -> Result<Job, EngineError> {
        let sid = id.to_string();
        let mut job =
            self.blocking(move |s| s.get(&sid)).await?.ok_or_else(|| EngineError::NotFound(id.to_string()))?;
        if job.status == JobStatus::Running {
            if let Some(live) = self.live_job(id) {
                job.progress = live.progress();
            }
        }
        Ok(job.with_hrefs())
    }

    pub async fn list(&self, filter: ListFilter) -> Result<Vec<Job>, EngineError> {
        let jobs = self.blocking(move |s| s.list(&filter)).await?;
        Ok(jobs.into_iter().map(Job::with_hrefs).collect())
    }

    pub async fn artifact(&self, id: &str, name: &str) -> Result<Option<(String, Vec<u8>)>, EngineError> {
        let (id, name) = (id.to_string(), name.to_string());
        self.blocking(move |s| s.artifact(&id, &name)).await
    }

    /// Stop a queued or running job. Returns the job as it is after the request.
    pub async fn cancel(&self, id: &str) -> Result<Job, EngineError> {
        let job = self.get(id).await?;
        let ended = || EngineError::Conflict(format!("job {id} has already ended"));
        if job.status.is_terminal() {
            return Err(ended());
        }
        let Some(live) = self.live_job(id) else {
            // It ended between the two looks.
            return Err(ended());
        };
        live.stop(StopReason::Cancelled);
        if self.dequeue(id) {
            // Taken off the queue before a dispatcher saw it: it ends here.
            self.end(job, &live, Err(super::SimError::Cancelled), 0.0).await;
        } else {
            // A running job stops at its next step; give it a moment so the answer shows it.
            let mut done = live.done_receiver();
            let _ = tokio::time::timeout(Duration::from_secs(5), done.wait_for(|d| *d)).await;
        }
        self.get(id).await
    }

    /// Cancel if needed, then remove the job and its artifacts.
    pub async fn delete(&self, id: &str) -> Result<(), EngineError> {
        let job = self.get(id).await?;
        if let Some(live) = self.live_job(id) {
            live.stop(StopReason::Deleted);
            if self.dequeue(id) {
                self.end(job, &live, Err(super::SimError::Cancelled), 0.0).await;
            }
        }
        let sid = id.to_string();
        if self.blocking(move |s| s.delete(&sid)).await? {
            Ok(())
        } else {
            Err(EngineError::NotFound(id.to_string()))
        }
    }

    /// Wait up to `timeout` for the job to end; returns it either way.
    pub async fn wait(&self, id: &str, timeout: Duration) -> Result<Job, EngineError> {
        if let Some(live) = self.live_job(id) {
            let mut done = live.done_receiver();
            let _ = tokio::time::timeout(timeout, done.wait_for(|d| *d)).await;
        }
        self.get(id).await
    }

    /// A job's event stream from after `last_event_id`: live events while it runs, or just the
    /// finished job once it has ended.
    pub async fn events(&self, id: &str, last_event_id: Option<u64>) -> Result<EventFeed, EngineError> {
        if let Some(live) = self.live_job(id) {
            let (backlog, rx) = live.subscribe(last_event_id);
            return Ok(EventFeed::Live { backlog, rx, live });
        }
        let job = self.get(id).await?;
        if job.status.is_terminal() {
            return Ok(EventFeed::Ended(Box::new(job)));
        }
        // Ended between the two looks: the store has its final state by now.
        match self.live_job(id) {
            Some(live) => {
                let (backlog, rx) = live.subscribe(last_event_id);
                Ok(EventFeed::Live { backlog, rx, live })
            }
            None => Ok(EventFeed::Ended(Box::new(self.get(id).await?))),
        }
    }

    /// The latest live snapshot of a running job.
    pub fn live_snapshot(&self, id: &str) -> Option<(u64, bytes::Bytes)> {
        self.live_job(id).and_then(|l| l.snapshot())
    }

    /// Prometheus text for `/metrics`.
    pub async fn metrics_text(&self) -> Result<String, EngineError> {
        let counts = self.blocking(|s| s.counts()).await?;
        self.inner.metrics.set_queue_depth(self.queue_depth());
        Ok(self.inner.metrics.render(&self.kind_names(), &counts))
    }

    /// Whether the store answers.
    pub async fn ready(&self) -> bool {
        self.blocking(|s| s.counts()).await.is_ok()
    }
}

fn take_common_fields(body: &mut Map<String, Value>) -> Result<(u64, Option<String>), EngineError> {
    let seed = match body.remove("seed") {
        None | Some(Value::Null) => 0,
        Some(v) => v.as_u64().ok_or_else(|| EngineError::field("seed", "must be an unsigned 64-bit integer"))?,
    };
    let label = match body.remove("label") {
        None | Some(Value::Null) => None,
        Some(Value::String(s)) if s.chars().count() <= MAX_LABEL_CHARS => Some(s),
        Some(Value::String(_)) => {
            return Err(EngineError::field("label", format!("must be at most {MAX_LABEL_CHARS} characters")))
        }
        Some(_) => return Err(EngineError::field("label", "must be a string")),
    };
    Ok((seed, label))
}

fn new_job(kind: &str, label: Option<String>, request: Value, replay_of: Option<(String, Option<u64>)>) -> Job {
    let (replay_of, replay_until_step) = match replay_of {
        Some((of, until)) => (Some(of), until),
        None => (None, None),
    };
    Job {
        id: uuid::Uuid::now_v7().to_string(),
        kind: kind.to_string(),
        status: JobStatus::Queued,
        label,
        created_at: Utc::now(),
        started_at: None,
        finished_at: None,
        progress: Progress { stage: "queued".into(), ..Progress::default() },
        request,
        result: None,
        artifacts: Vec::new(),
        error: None,
        replay_of,
        replay_until_step,
    }
}
