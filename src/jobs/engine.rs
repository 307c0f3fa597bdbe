//! The engine: accepts jobs into a bounded queue, admits them by their estimated memory against
//! a budget, runs each on a thread of its own whose parallel work shares the one Rayon pool
//! (never on tokio's threads), publishes progress, and records outcomes in the store.

use std::collections::{HashMap, VecDeque};
use std::sync::Arc;
use std::time::{Duration, Instant};

use chrono::Utc;
use parking_lot::Mutex;
use serde_json::{Map, Value};
use tokio::sync::Notify;

use super::live::{LiveJob, StopReason};
use super::metrics::Metrics;
use super::store_terrain::StoreTerrain;
use super::{Job, JobEvent, JobKind, JobStatus, Progress, RequestError, SimError};
use crate::export::{lod_cost, GlbForm, MeshSettings};
use crate::store::{EventLog, IdempotentInsert, JobInputs, ListFilter, StoreError};
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
    /// Most jobs run at the same time (their parallel work shares the pool).
    pub concurrent_jobs: usize,
    /// Jobs run together while the sum of their estimated peak memory fits this many bytes;
    /// a request whose estimate alone exceeds it is refused (413).
    pub memory_budget: u64,
    /// A job still running after this long is stopped and fails.
    pub job_timeout: Duration,
    pub limits: Limits,
    /// Whether this engine runs jobs itself (`--role all`, in one process); when false
    /// (`--role api`) it only queues them in the store, and workers elsewhere run them.
    pub runs_jobs: bool,
}

/// Size the global Rayon pool that every job's parallel work shares, once per process: a
/// second engine or worker in the same process (tests) finds it built and uses it as it is.
pub fn build_pool(threads: usize) {
    if let Err(e) = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .thread_name(|i| format!("landform-sim-{i}"))
        .build_global()
    {
        tracing::debug!(error = %e, "the Rayon pool was already built");
    }
}

/// Default `--concurrent-jobs`: enough for many small jobs side by side on a small machine; the
/// memory budget is what bounds them.
pub const DEFAULT_CONCURRENT_JOBS: usize = 16;

/// Half the memory this process may use: the machine's physical memory (`/proc/meminfo`), or
/// the container's limit when a cgroup sets a smaller one (a container sees the host's
/// `MemTotal`); 4 GiB where neither can be read.
pub fn default_memory_budget() -> u64 {
    let total = std::fs::read_to_string("/proc/meminfo").ok().and_then(|text| {
        text.lines()
            .find_map(|l| l.strip_prefix("MemTotal:"))
            .and_then(|rest| rest.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            .map(|kib| kib.saturating_mul(1024))
    });
    // cgroup v2, then v1; "max" (or v1's huge sentinel) means no limit.
    let limit = ["/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"]
        .iter()
        .find_map(|path| std::fs::read_to_string(path).ok()?.trim().parse::<u64>().ok())
        .filter(|&bytes| bytes < 1 << 60);
    let usable = match (total, limit) {
        (Some(t), Some(l)) => t.min(l),
        (Some(t), None) => t,
        (None, Some(l)) => l,
        (None, None) => 8 << 30,
    };
    usable / 2
}

impl Default for EngineConfig {
    fn default() -> Self {
        Self {
            workers: std::thread::available_parallelism().map(|n| n.get()).unwrap_or(2),
            queue_capacity: DEFAULT_QUEUE_CAPACITY,
            concurrent_jobs: DEFAULT_CONCURRENT_JOBS,
            memory_budget: default_memory_budget(),
            job_timeout: Duration::from_secs(DEFAULT_JOB_TIMEOUT_S),
            limits: Limits::default(),
            runs_jobs: true,
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
    /// Over an API key's quota of jobs or memory at once (429).
    #[error("{0}")]
    OverQuota(String),
    /// The job's estimated peak memory exceeds the budget (413).
    #[error("{field}: the job would need about {needed} bytes of memory; the budget is {budget}")]
    OverBudget { field: String, needed: u64, budget: u64 },
    /// The job's work can't be done within the time limit (422).
    #[error("{field}: the job would take at least {seconds:.0} s; the time limit is {limit} s")]
    OverTime { field: String, seconds: f64, limit: u64 },
    #[error("the request body is not valid JSON: {0}")]
    Malformed(String),
    #[error("the request has invalid fields")]
    Invalid { errors: Vec<FieldError>, too_large: bool },
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("internal error: {0}")]
    Internal(String),
    /// Too much running to start a draft now (503, try again in a moment).
    #[error("{0}")]
    Busy(String),
    /// A draft ran and failed, or ran past its time limit (422 / 504).
    #[error("{message}")]
    DraftFailed { message: String, timed_out: bool },
}

impl EngineError {
    pub(super) fn field(field: &str, message: impl Into<String>) -> Self {
        EngineError::Invalid {
            errors: vec![FieldError { field: field.into(), message: message.into() }],
            too_large: false,
        }
    }
}

impl EngineError {
    /// A simulation's error about the request (a field, or its terrain) as the client's 422;
    /// any other through `otherwise` (an estimate's is the server's fault, a draft's its run's).
    pub(super) fn from_sim(e: SimError, otherwise: impl FnOnce(SimError) -> EngineError) -> Self {
        match e {
            SimError::Invalid { field, message } => EngineError::field(&field, message),
            SimError::Terrain(t) => EngineError::field("terrain", t.to_string()),
            other => otherwise(other),
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
    Live {
        backlog: Vec<JobEvent>,
        rx: tokio::sync::broadcast::Receiver<JobEvent>,
        live: Arc<LiveJob>,
    },
    Ended(Box<Job>),
    /// The job runs in another process: its events are read from the store, after this id.
    Stored {
        after: u64,
    },
}

/// Who submits a job: the API key name that will own it, and what that key may hold at once.
#[derive(Clone, Debug, Default)]
pub struct Submitter {
    pub owner: Option<String>,
    pub max_active_jobs: Option<u32>,
    pub max_memory_bytes: Option<u64>,
}

/// What a submission did.
pub enum Submitted {
    Created(Job),
    /// The idempotency key was used before with the same body: the job it created.
    Existing(Job),
}

/// A job waiting to run, with the memory it will reserve.
pub(super) struct Waiting {
    pub id: String,
    pub memory: u64,
    pub since: Instant,
}

/// Jobs waiting, places promised to submissions still being stored, and what running jobs hold.
#[derive(Default)]
pub(super) struct Queue {
    pub items: VecDeque<Waiting>,
    reserved: usize,
    /// Jobs taken off the queue and not yet ended.
    pub running: usize,
    /// The sum of their estimated memory.
    pub memory_reserved: u64,
}

pub(super) struct Inner {
    pub store: Arc<dyn EventLog>,
    pub kinds: HashMap<&'static str, Arc<dyn JobKind>>,
    pub queue: Mutex<Queue>,
    pub queue_notify: Notify,
    pub live: Mutex<HashMap<String, Arc<LiveJob>>>,
    /// Jobs that ended up to here are in the metrics (see `observe_stored`).
    pub metrics_since: Mutex<chrono::DateTime<Utc>>,
    /// Set on shutdown: the dispatcher takes no more jobs.
    pub draining: std::sync::atomic::AtomicBool,
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
        store: Arc<dyn EventLog>,
        kinds: Vec<Box<dyn JobKind>>,
        config: EngineConfig,
    ) -> Result<Self, EngineError> {
        // Each job runs on a thread of its own and its parallel iterators use the global pool,
        // so jobs running side by side share its threads. Sized once per process: a second
        // engine in the same process (tests) finds it built and uses it as it is.
        build_pool(config.workers);
        let kinds = kinds.into_iter().map(|k| (k.name(), Arc::from(k))).collect();
        let metrics = Metrics::new();
        metrics.set_memory_budget(config.memory_budget);
        Ok(Engine {
            inner: Arc::new(Inner {
                store,
                kinds,
                queue: Mutex::new(Queue::default()),
                queue_notify: Notify::new(),
                live: Mutex::new(HashMap::new()),
                metrics_since: Mutex::new(Utc::now()),
                draining: std::sync::atomic::AtomicBool::new(false),
                metrics,
                config,
            }),
        })
    }

    /// At-least-once: whatever a previous process accepted and did not finish runs again,
    /// unless it has already been interrupted [`MAX_ATTEMPTS`] times.
    pub fn recover(&self) -> Result<(), EngineError> {
        if !self.inner.config.runs_jobs {
            // Workers take unfinished jobs over when their leases run out.
            return Ok(());
        }
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
            self.enqueue_with(&job, None);
        }
        Ok(())
    }

    /// Graceful shutdown: take no more jobs, let the running ones finish until `deadline`,
    /// then stop the rest and put them back in the queue (stored as queued), so the next start
    /// (or another worker) runs them at once. Queued jobs stay queued in the store.
    pub async fn shutdown(&self, deadline: Duration) {
        self.inner.draining.store(true, std::sync::atomic::Ordering::SeqCst);
        self.inner.queue_notify.notify_one();
        let started = Instant::now();
        while self.inner.queue.lock().running > 0 && started.elapsed() < deadline {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let running: Vec<Arc<LiveJob>> = {
            let q = self.inner.queue.lock();
            if q.running == 0 {
                return;
            }
            let waiting: std::collections::HashSet<&str> = q.items.iter().map(|w| w.id.as_str()).collect();
            self.inner.live.lock().values().filter(|l| !waiting.contains(l.id.as_str())).cloned().collect()
        };
        tracing::info!(jobs = running.len(), "shutdown deadline passed; returning running jobs to the queue");
        for live in &running {
            live.stop(StopReason::ShuttingDown);
        }
        // Each stops at its next check and is stored as queued.
        let stopped = Instant::now();
        while self.inner.queue.lock().running > 0 && stopped.elapsed() < Duration::from_secs(10) {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    /// Spawn the dispatcher that takes jobs off the queue as the budget allows.
    pub fn start(&self) {
        if !self.inner.config.runs_jobs {
            return;
        }
        let engine = self.clone();
        tokio::spawn(async move { engine.dispatch_loop().await });
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
    fn enqueue_with(&self, job: &Job, slot: Option<Slot<'_>>) {
        let (id, owner) = (job.id.as_str(), job.owner.clone());
        let memory = job.cost.as_ref().map_or(self.inner.config.memory_budget, |c| c.memory_bytes);
        let live = self
            .inner
            .live
            .lock()
            .entry(id.to_string())
            .or_insert_with(|| Arc::new(LiveJob::for_job(id.to_string(), owner, memory)))
            .clone();
        live.emit_status(JobStatus::Queued);
        let depth = {
            let mut q = self.inner.queue.lock();
            if let Some(slot) = slot {
                q.reserved -= 1;
                slot.used();
            }
            q.items.push_back(Waiting { id: id.to_string(), memory, since: Instant::now() });
            q.items.len()
        };
        self.inner.metrics.set_queue_depth(depth);
        self.inner.queue_notify.notify_one();
    }

    /// Jobs queued or running for `owner`, and the memory their estimates reserve: from this
    /// process's own jobs when it runs them, else from the store (workers run them elsewhere).
    pub async fn usage(&self, owner: Option<&str>) -> Result<(u32, u64), EngineError> {
        if !self.inner.config.runs_jobs {
            let owner = owner.map(str::to_string);
            return self.blocking(move |s| s.active(owner.as_deref())).await;
        }
        Ok(self
            .inner
            .live
            .lock()
            .values()
            .filter(|l| l.owner.as_deref() == owner)
            .fold((0, 0), |(n, m), l| (n + 1, m.saturating_add(l.memory))))
    }

    /// Take a job off the queue if it is still there; true when it was.
    pub(super) fn dequeue(&self, id: &str) -> bool {
        let mut q = self.inner.queue.lock();
        let before = q.items.len();
        q.items.retain(|w| w.id != id);
        let removed = before != q.items.len();
        self.inner.metrics.set_queue_depth(q.items.len());
        removed
    }

    /// Run blocking store work off the async threads.
    pub(super) async fn blocking<T: Send + 'static>(
        &self,
        f: impl FnOnce(&dyn EventLog) -> Result<T, StoreError> + Send + 'static,
    ) -> Result<T, EngineError> {
        let store = self.inner.store.clone();
        tokio::task::spawn_blocking(move || f(store.as_ref()))
            .await
            .map_err(|e| EngineError::Internal(e.to_string()))?
            .map_err(EngineError::from)
    }

    /// Validate a body for `kind` and queue it. `idempotency` is (key, sha256 of the body).
    /// `body_bytes`: the size of the body as sent, which the stored request may not outgrow
    /// (see [`stored_size_allowed`]).
    pub async fn submit(
        &self,
        kind: &str,
        body: Value,
        body_bytes: usize,
        idempotency: Option<(String, String)>,
        who: &Submitter,
    ) -> Result<Submitted, EngineError> {
        let owner = who.owner.clone();
        let kind_impl =
            self.inner.kinds.get(kind).cloned().ok_or_else(|| EngineError::UnknownKind(kind.to_string()))?;
        let mut body = body_object(body)?;
        let lods_named = body.get("lods").is_some_and(|l| !l.is_null());
        let (seed, label, mesh) = take_common_fields(&mut body)?;
        let limits = self.inner.config.limits.clone();
        let prepared = tokio::task::spawn_blocking(move || kind_impl.prepare(Value::Object(body), &limits))
            .await
            .map_err(|e| EngineError::Internal(e.to_string()))??;
        // The common fields (seed, compression, lods, label) add at most a few hundred bytes.
        let stored = crate::model::json_len(&prepared.params) + 128 + label.as_ref().map_or(0, |l| 2 * l.len());
        let allowed = stored_size_allowed(body_bytes);
        if stored > allowed {
            return Err(EngineError::Invalid {
                errors: vec![FieldError {
                    field: String::new(),
                    message: format!(
                        "with its defaults filled in and its numbers written out, this request would be stored as \
                         about {stored} bytes, more than the {allowed} bytes allowed for a body of {body_bytes}; \
                         write numbers in full (100000 rather than 1e5) or send a smaller request"
                    ),
                }],
                too_large: true,
            });
        }
        self.check_references(&prepared.references, owner.clone()).await?;
        let lods = (mesh.lods.len(), lods_named);
        let (cost, params, uploads) =
            self.estimate(kind, prepared.params, seed, prepared.references.uploads, owner.clone(), lods).await?;
        self.check_quota(who, &cost).await?;
        let named: Vec<String> = prepared.references.inputs.into_iter().map(|(_, sha)| sha).collect();

        let mut request = match params {
            Value::Object(m) => m,
            _ => Map::new(),
        };
        request.insert("seed".into(), Value::from(seed));
        request.insert("compression".into(), Value::from(mesh.form.name()));
        request.insert("lods".into(), Value::from(mesh.lods));
        if let Some(l) = &label {
            request.insert("label".into(), Value::String(l.clone()));
        }
        let mut job = new_job(kind, label, Value::Object(request), None);
        job.cost = Some(cost);
        job.owner = owner;
        self.admit(job, idempotency, uploads, named).await
    }

    /// A key's jobs at once: how many are queued or running, and the memory they reserve.
    async fn check_quota(&self, who: &Submitter, cost: &super::Cost) -> Result<(), EngineError> {
        if who.max_active_jobs.is_none() && who.max_memory_bytes.is_none() {
            // No limits to hold this submitter to: nothing to count.
            return Ok(());
        }
        let (jobs, memory) = self.usage(who.owner.as_deref()).await?;
        if let Some(max) = who.max_active_jobs {
            if jobs >= max {
                return Err(EngineError::OverQuota(format!(
                    "this key has {jobs} jobs queued or running, its limit; submit again when one ends"
                )));
            }
        }
        if let Some(max) = who.max_memory_bytes {
            if memory.saturating_add(cost.memory_bytes) > max {
                return Err(EngineError::OverQuota(format!(
                    "this key's queued and running jobs reserve {memory} bytes; with this job's {} the key's \
                     limit of {max} bytes would be exceeded",
                    cost.memory_bytes
                )));
            }
        }
        Ok(())
    }

    /// The cost of a prepared request, checked against the memory budget and the time limit.
    /// Uploads sent with the request (not stored yet) are sized from `uploads`. The request and
    /// the uploads are handed back: moved, not copied, as a copy of a request of many
    /// megabytes would be its size many times over in memory.
    pub(super) async fn estimate(
        &self,
        kind: &str,
        params: Value,
        seed: u64,
        uploads: Vec<(String, Vec<u8>)>,
        owner: Option<String>,
        (lods, lods_named): (usize, bool),
    ) -> Result<(super::Cost, Value, Vec<(String, Vec<u8>)>), EngineError> {
        let kind_impl = self.inner.kinds.get(kind).cloned().ok_or_else(|| EngineError::UnknownKind(kind.into()))?;
        let store = self.inner.store.clone();
        let (cost, params, uploads) = tokio::task::spawn_blocking(move || {
            let lookup = PendingUploads { uploads: &uploads, store: StoreTerrain { store, owner: owner.clone() } };
            let cost = kind_impl.estimate(&params, seed, &lookup);
            (cost, params, uploads)
        })
        .await
        .map_err(|e| EngineError::Internal(e.to_string()))?;
        let cost = cost.map_err(|e| EngineError::from_sim(e, |other| EngineError::Internal(other.to_string())))?;
        // Levels of detail run after the rest, from the meshes the kind counted. Their cost
        // grows with the kind's own mesh, so the kind's field is named for it unless the
        // request named `lods` itself (the default levels are not the client's choice).
        let (bytes, seconds) = lod_cost(&cost, lods);
        let cost = if lods_named {
            cost.with_stage("lods", bytes, seconds)
        } else {
            let (memory_field, work_field) = (cost.memory_field.clone(), cost.work_field.clone());
            let mut cost = cost.with_stage("lods", bytes, seconds);
            (cost.memory_field, cost.work_field) = (memory_field, work_field);
            cost
        };
        self.check_cost(&cost)?;
        Ok((cost, params, uploads))
    }

    fn check_cost(&self, cost: &super::Cost) -> Result<(), EngineError> {
        let budget = self.inner.config.memory_budget;
        if cost.memory_bytes > budget {
            return Err(EngineError::OverBudget {
                field: cost.memory_field.clone(),
                needed: cost.memory_bytes,
                budget,
            });
        }
        let limit = self.inner.config.job_timeout.as_secs();
        if cost.min_seconds > self.inner.config.job_timeout.as_secs_f64() {
            return Err(EngineError::OverTime { field: cost.work_field.clone(), seconds: cost.min_seconds, limit });
        }
        Ok(())
    }

    /// A new job that rebuilds `id`'s result from its recorded sequence, up to `until_step`.
    pub async fn replay(&self, id: &str, until_step: Option<u64>, who: &Submitter) -> Result<Job, EngineError> {
        let original = self.get(id, who.owner.as_deref()).await?;
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
        let steps = kind.sequence_steps(&sequence).map_err(|e| match e {
            SimError::Invalid { message, .. } => {
                EngineError::Conflict(format!("job {id} cannot be replayed: {message}"))
            }
            other => EngineError::Internal(other.to_string()),
        })?;
        if let Some(k) = until_step {
            if k > steps {
                return Err(EngineError::field("until_step", format!("the sequence has {steps} steps (got {k})")));
            }
        }
        // The earlier jobs the original read must still be there to read again.
        let prepared = kind.prepare(original.params(), &self.inner.config.limits)?;
        self.check_references(&prepared.references, original.owner.clone()).await.map_err(|e| match e {
            EngineError::Invalid { errors, .. } => EngineError::Conflict(format!(
                "job {id} can no longer be replayed: {}",
                errors.into_iter().map(|e| e.message).collect::<Vec<_>>().join("; ")
            )),
            other => other,
        })?;
        let lods = (original.request.get("lods").and_then(Value::as_array).map_or(0, Vec::len), false);
        let seed = original.request.get("seed").and_then(Value::as_u64).unwrap_or(0);
        let (cost, _, _) =
            self.estimate(&original.kind, prepared.params, seed, Vec::new(), original.owner.clone(), lods).await?;
        self.check_quota(who, &cost).await?;
        let replay_of = Some((id.to_string(), until_step));
        let mut job = new_job(&original.kind, original.label.clone(), original.request.clone(), replay_of);
        job.cost = Some(cost);
        job.owner = original.owner.clone();
        // The replay reads the original's uploads: they stay as long as it does.
        let named: Vec<String> = prepared.references.inputs.into_iter().map(|(_, sha)| sha).collect();
        match self.admit(job, None, Vec::new(), named).await? {
            Submitted::Created(j) | Submitted::Existing(j) => Ok(j),
        }
    }

    /// Every earlier job and upload the request names must be there.
    pub(super) async fn check_references(
        &self,
        refs: &super::References,
        owner: Option<String>,
    ) -> Result<(), EngineError> {
        if refs.jobs.is_empty() && refs.inputs.is_empty() {
            return Ok(());
        }
        let store = self.inner.store.clone();
        let (jobs, inputs) = (refs.jobs.clone(), refs.inputs.clone());
        let errors = tokio::task::spawn_blocking(move || {
            let mut errors = Vec::new();
            for (field, sha) in inputs {
                // Another key's upload answers as one that does not exist.
                match store.has_input(&sha, owner.as_deref()) {
                    Ok(true) => {}
                    Ok(false) => errors.push(FieldError { field, message: format!("no upload with sha256 {sha}") }),
                    Err(e) => {
                        tracing::error!(error = %e, "store failure while checking an upload");
                        errors.push(FieldError { field, message: "the job store failed".into() })
                    }
                }
            }
            let lookup = StoreTerrain { store, owner: owner.clone() };
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

    /// Store the job (with the uploads it sent and names, see `JobInputs`) and queue it.
    async fn admit(
        &self,
        job: Job,
        idempotency: Option<(String, String)>,
        sent: Vec<(String, Vec<u8>)>,
        named: Vec<String>,
    ) -> Result<Submitted, EngineError> {
        let capacity = self.inner.config.queue_capacity;
        // Where the job will wait: a place in this process's queue, or (`Some(None)`) the
        // store's queue, which workers elsewhere claim from; `None` when it is full.
        // Without a queue here, the store's is counted and the job stored in one trip to a
        // blocking thread: each trip is a wake-up that waits its turn for a core under load.
        let in_store = !self.inner.config.runs_jobs;
        let slot = if in_store { Some(None) } else { self.reserve_slot().map(Some) };
        // An idempotent retry must still find its job when the queue is full.
        if slot.is_none() && idempotency.is_none() {
            return Err(EngineError::QueueFull(capacity));
        }
        // The job goes to the blocking thread and comes back: a request may be megabytes.
        let (job, full, outcome) = self
            .blocking(move |s| {
                let full = in_store && s.queued()? >= capacity as u64;
                if full && idempotency.is_none() {
                    return Ok((job, true, None));
                }
                let key = idempotency.as_ref().map(|(k, h)| (k.as_str(), h.as_str()));
                let inputs = JobInputs { sent: &sent, named: &named };
                let outcome = s.insert_with_inputs(&job, key, inputs)?;
                Ok((job, full, Some(outcome)))
            })
            .await?;
        let Some(outcome) = outcome else { return Err(EngineError::QueueFull(capacity)) };
        let slot = if full { None } else { slot };
        match outcome {
            IdempotentInsert::Existing { job, same_body: true } => Ok(Submitted::Existing(*job)),
            IdempotentInsert::Existing { job, same_body: false } => Err(EngineError::Conflict(format!(
                "the Idempotency-Key was already used with a different body (job {})",
                job.id
            ))),
            IdempotentInsert::Inserted => match slot {
                Some(Some(slot)) => {
                    self.enqueue_with(&job, Some(slot));
                    Ok(Submitted::Created(job))
                }
                Some(None) => Ok(Submitted::Created(job)),
                None => {
                    let id = job.id.clone();
                    self.blocking(move |s| s.delete(&id)).await?;
                    Err(EngineError::QueueFull(capacity))
                }
            },
        }
    }

    /// The job, if `owner` may see it: a job made with an API key is visible to that key only
    /// (and one made without keys to callers without keys); to anyone else it does not exist.
    pub async fn get(&self, id: &str, owner: Option<&str>) -> Result<Job, EngineError> {
        let job = self.get_any(id).await?;
        if job.owner.as_deref() != owner {
            return Err(EngineError::NotFound(id.to_string()));
        }
        Ok(job)
    }

    /// The job whoever owns it, with live progress when it is running.
    pub(super) async fn get_any(&self, id: &str) -> Result<Job, EngineError> {
        let sid = id.to_string();
        let mut job =
            self.blocking(move |s| s.get(&sid)).await?.ok_or_else(|| EngineError::NotFound(id.to_string()))?;
        if job.status == JobStatus::Running {
            match self.live_job(id) {
                Some(live) => job.progress = live.progress(),
                None => self.stored_progress(&mut job).await,
            }
        }
        Ok(job.with_hrefs())
    }

    pub async fn list(&self, filter: ListFilter) -> Result<Vec<Job>, EngineError> {
        let mut jobs = self.blocking(move |s| s.list(&filter)).await?;
        // A job running here has its progress in memory (the store has it at the start): the
        // list says what GET says.
        for job in jobs.iter_mut().filter(|j| j.status == JobStatus::Running) {
            if let Some(live) = self.live_job(&job.id) {
                job.progress = live.progress();
            }
        }
        Ok(jobs.into_iter().map(Job::with_hrefs).collect())
    }

    pub async fn artifact(&self, id: &str, name: &str) -> Result<Option<(String, Vec<u8>)>, EngineError> {
        let (id, name) = (id.to_string(), name.to_string());
        self.blocking(move |s| s.artifact(&id, &name)).await
    }

    /// At most `len` bytes of an artifact from `offset` (see `ArtifactStore::read_artifact`).
    pub async fn artifact_piece(
        &self,
        id: &str,
        name: &str,
        offset: u64,
        len: usize,
    ) -> Result<Option<Vec<u8>>, EngineError> {
        let (id, name) = (id.to_string(), name.to_string());
        self.blocking(move |s| s.read_artifact(&id, &name, offset, len)).await
    }

    /// Stop a queued or running job. Returns the job as it is after the request.
    pub async fn cancel(&self, id: &str, owner: Option<&str>) -> Result<Job, EngineError> {
        let job = self.get(id, owner).await?;
        let ended = || EngineError::Conflict(format!("job {id} has already ended"));
        if job.status.is_terminal() {
            return Err(ended());
        }
        let Some(live) = self.live_job(id) else {
            if !self.inner.config.runs_jobs {
                return self.cancel_stored(job).await;
            }
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
        self.get_any(id).await
    }

    /// Cancel if needed, then remove the job and its artifacts.
    pub async fn delete(&self, id: &str, owner: Option<&str>) -> Result<(), EngineError> {
        let job = self.get(id, owner).await?;
        if let Some(live) = self.live_job(id) {
            live.stop(StopReason::Deleted);
            if self.dequeue(id) {
                self.end(job, &live, Err(super::SimError::Cancelled), 0.0).await;
            }
        } else if !job.status.is_terminal() {
            // Its worker stops at its next renewal, finding the claim gone with the row.
            let sid = id.to_string();
            self.blocking(move |s| s.request_cancel(&sid)).await?;
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
        match self.live_job(id) {
            Some(live) => {
                let mut done = live.done_receiver();
                let _ = tokio::time::timeout(timeout, done.wait_for(|d| *d)).await;
                self.get_any(id).await
            }
            None => self.wait_stored(id, timeout).await,
        }
    }

    /// A job's event stream from after `last_event_id`: live events while it runs, or just the
    /// finished job once it has ended.
    /// Another owner's job is not there (`NotFound`).
    pub async fn events(
        &self,
        id: &str,
        last_event_id: Option<u64>,
        owner: Option<&str>,
    ) -> Result<EventFeed, EngineError> {
        let mine = |l: &Arc<LiveJob>| l.owner.as_deref() == owner;
        if let Some(live) = self.live_job(id).filter(mine) {
            let (backlog, rx) = live.subscribe(last_event_id);
            return Ok(EventFeed::Live { backlog, rx, live });
        }
        // The status alone first: a stream of an ended job reads its summary, never its whole
        // request (many clients opening streams of a large job must not each parse it).
        let (status, job_owner) = self.status_of(id).await?;
        if job_owner.as_deref() != owner {
            return Err(EngineError::NotFound(id.to_string()));
        }
        if status.is_terminal() {
            return Ok(EventFeed::Ended(Box::new(self.summary(id).await?)));
        }
        if !self.inner.config.runs_jobs {
            return Ok(EventFeed::Stored { after: last_event_id.unwrap_or(0) });
        }
        // Ended between the two looks: the store has its final state by now.
        match self.live_job(id).filter(mine) {
            Some(live) => {
                let (backlog, rx) = live.subscribe(last_event_id);
                Ok(EventFeed::Live { backlog, rx, live })
            }
            None => Ok(EventFeed::Ended(Box::new(self.summary(id).await?))),
        }
    }

    /// The job as a summary (a request over `SUMMARY_REQUEST_BYTES` left unread), whoever owns it.
    pub async fn summary(&self, id: &str) -> Result<Job, EngineError> {
        let sid = id.to_string();
        let job =
            self.blocking(move |s| s.get_summary(&sid)).await?.ok_or_else(|| EngineError::NotFound(id.to_string()))?;
        Ok(job.with_hrefs())
    }

    /// The latest live snapshot of a running job `owner` may see: from memory when this
    /// process runs it (no store read on this often-polled path), else from the store.
    pub async fn live_snapshot(
        &self,
        id: &str,
        owner: Option<&str>,
    ) -> Result<Option<(u64, bytes::Bytes)>, EngineError> {
        if self.inner.config.runs_jobs {
            return Ok(self.live_job(id).filter(|l| l.owner.as_deref() == owner).and_then(|l| l.snapshot()));
        }
        self.stored_snapshot(id, owner).await
    }

    /// Prometheus text for `/metrics`.
    pub async fn metrics_text(&self) -> Result<String, EngineError> {
        let counts = self.blocking(|s| s.counts()).await?;
        let depth = if self.inner.config.runs_jobs {
            self.queue_depth()
        } else {
            self.observe_stored().await?;
            // Jobs wait in the store for workers elsewhere.
            counts.iter().filter(|(_, status, _)| *status == JobStatus::Queued).map(|(_, _, n)| *n as usize).sum()
        };
        self.inner.metrics.set_queue_depth(depth);
        Ok(self.inner.metrics.render(&self.kind_names(), &counts))
    }

    /// Whether the store answers.
    pub async fn ready(&self) -> bool {
        self.blocking(|s| s.counts()).await.is_ok()
    }
}

/// The common fields of every body: `seed`, `label`, `compression` and `lods` (checked here;
/// the caller puts the seed and the mesh settings, defaults filled in, back into the request).
/// The most bytes a request of `body_bytes` may take stored, its defaults filled in: 1.5 × the
/// body, and for small bodies 64 KiB more (a body of a few fields gains every default of its
/// kind). Numbers are stored as short as they were sent or shorter (see `stored_form`), so
/// what grows is the defaults: a list of mounds that leaves out each one's two defaults is
/// stored at about 1.25 × its size, a path of points at under 1 ×.
pub fn stored_size_allowed(body_bytes: usize) -> usize {
    (body_bytes + body_bytes / 2).max(body_bytes + (64 << 10))
}

/// A request body's members: it must be a JSON object.
pub(super) fn body_object(body: Value) -> Result<Map<String, Value>, EngineError> {
    match body {
        Value::Object(members) => Ok(members),
        _ => Err(EngineError::field("", "the body must be a JSON object")),
    }
}

pub(super) fn take_common_fields(
    body: &mut Map<String, Value>,
) -> Result<(u64, Option<String>, MeshSettings), EngineError> {
    // None of the common fields is nullable in the schema: `null` is refused like any other
    // wrong type (left out, each has its default).
    let seed = match body.remove("seed") {
        None => 0,
        Some(v) => v.as_u64().ok_or_else(|| EngineError::field("seed", "must be an unsigned 64-bit integer"))?,
    };
    let label = match body.remove("label") {
        None => None,
        Some(Value::String(s)) if s.chars().count() <= MAX_LABEL_CHARS => Some(s),
        Some(Value::String(_)) => {
            return Err(EngineError::field("label", format!("must be at most {MAX_LABEL_CHARS} characters")))
        }
        Some(_) => return Err(EngineError::field("label", "must be a string")),
    };
    let compression = match body.remove("compression") {
        None => GlbForm::default(),
        Some(v) => v.as_str().and_then(GlbForm::parse).ok_or_else(|| {
            EngineError::field("compression", format!("must be one of {}", GlbForm::NAMES.join(", ")))
        })?,
    };
    let lods = match body.remove("lods") {
        None => MeshSettings::default().lods,
        Some(v) => MeshSettings::parse_lods(&v).map_err(|e| EngineError::field("lods", e))?,
    };
    Ok((seed, label, MeshSettings { form: compression, lods }))
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
        request_omitted: false,
        result: None,
        artifacts: Vec::new(),
        error: None,
        replay_of,
        replay_until_step,
        cost: None,
        owner: None,
    }
}

/// The store's terrain, with the uploads a request sent inline (not stored yet) in front.
pub(super) struct PendingUploads<'a> {
    pub uploads: &'a [(String, Vec<u8>)],
    pub store: StoreTerrain,
}

impl crate::terrain::TerrainLookup for PendingUploads<'_> {
    fn job_heightfield(&self, job_id: &str) -> Result<crate::terrain::Heightfield, String> {
        self.store.job_heightfield(job_id)
    }

    fn job_artifact(&self, job_id: &str, name: &str) -> Result<Vec<u8>, String> {
        self.store.job_artifact(job_id, name)
    }

    fn input(&self, sha256: &str) -> Result<Vec<u8>, String> {
        match self.uploads.iter().find(|(sha, _)| sha == sha256) {
            Some((_, png)) => Ok(png.clone()),
            None => self.store.input(sha256),
        }
    }

    fn job_extent(&self, job_id: &str) -> Result<crate::terrain::TerrainExtent, String> {
        self.store.job_extent(job_id)
    }
}
