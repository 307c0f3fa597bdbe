//! Drafts (`POST /v1/drafts/{kind}`): a request run at once at the kind's reduced resolution
//! and answered with its mesh, nothing stored — what a page shows while its user edits. A draft
//! is checked like a job (fields, references, cost), shares the memory budget with the jobs
//! running beside it, stops when its client goes away, and has a time limit of its own.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde_json::Value;

use super::engine::{body_object, take_common_fields, PendingUploads};
use super::store_terrain::StoreTerrain;
use super::{Engine, EngineError, RunContext, SilentProgress, Submitter};
use crate::export::MeshSettings;

/// A draft running longer than this is stopped (504): a draft is for answers within seconds.
pub const DRAFT_TIMEOUT: Duration = Duration::from_secs(30);

/// Most work a draft may be estimated at, seconds at the fastest this server runs (422 beyond,
/// naming the field that makes it): a draft that big would hold a core for many seconds and
/// slow every other draft beside it; the job is the way to run it.
pub const DRAFT_MAX_WORK_S: f64 = 2.0;

/// A draft's answer: the full mesh as glb, the kind's result figures, and its time.
#[derive(Debug)]
pub struct Draft {
    pub glb: Vec<u8>,
    pub result: Value,
    pub seconds: f64,
}

/// Raised when dropped: the draft's run stops at its next check once its client has gone
/// (the handler's future is dropped) or its time is up.
struct StopOnDrop(Arc<AtomicBool>);

impl Drop for StopOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// Memory a draft holds in the engine's budget, given back when dropped.
struct Reservation<'a> {
    engine: &'a Engine,
    bytes: u64,
}

impl Drop for Reservation<'_> {
    fn drop(&mut self) {
        let mut q = self.engine.inner.queue.lock();
        q.memory_reserved = q.memory_reserved.saturating_sub(self.bytes);
        drop(q);
        // A job held back by this draft's memory may start now.
        self.engine.inner.queue_notify.notify_one();
    }
}

impl Engine {
    /// Run `body` as a draft of `kind`: validated as a submission is, then the kind's draft rule
    /// (see [`super::Simulation::draft`]), without levels of detail, and run at once.
    pub async fn draft(&self, kind: &str, body: Value, who: &Submitter) -> Result<Draft, EngineError> {
        let owner = who.owner.clone();
        let kind_impl =
            self.inner.kinds.get(kind).cloned().ok_or_else(|| EngineError::UnknownKind(kind.to_string()))?;
        let mut body = body_object(body)?;
        let (seed, _label, mesh) = take_common_fields(&mut body)?;
        let limits = self.inner.config.limits.clone();
        let (k, l) = (kind_impl.clone(), limits.clone());
        let (prepared, drafted) = tokio::task::spawn_blocking(move || {
            let prepared = k.prepare(Value::Object(body), &l)?;
            let drafted = k.draft(&prepared.params, &l);
            Ok::<_, EngineError>((prepared.references, drafted))
        })
        .await
        .map_err(|e| EngineError::Internal(e.to_string()))??;
        let params = drafted.map_err(|e| EngineError::Internal(e.to_string()))?;
        self.check_references(&prepared, owner.clone()).await?;
        let (cost, params, uploads) =
            self.estimate(kind, params, seed, prepared.uploads, owner.clone(), (0, true)).await?;
        if cost.min_seconds > DRAFT_MAX_WORK_S {
            return Err(EngineError::field(
                &cost.work_field,
                format!(
                    "even as a draft this request is at least {:.0} s of work; a draft may be at most {DRAFT_MAX_WORK_S} s \
                     (submit it as a job)",
                    cost.min_seconds
                ),
            ));
        }
        let _reservation = self.reserve_draft(cost.memory_bytes)?;

        let cancel = Arc::new(AtomicBool::new(false));
        let _stop_when_dropped = StopOnDrop(cancel.clone());
        let store = self.inner.store.clone();
        let flag = cancel.clone();
        let started = Instant::now();
        let run = tokio::task::spawn_blocking(move || {
            let lookup = PendingUploads { uploads: &uploads, store: StoreTerrain { store, owner } };
            let ctx = RunContext {
                cancel: &flag,
                sink: &SilentProgress,
                terrain: &lookup,
                limits: &limits,
                mesh: MeshSettings { form: mesh.form, lods: Vec::new() },
                draft: true,
            };
            kind_impl.run(&params, seed, &ctx)
        });
        let output = match tokio::time::timeout(DRAFT_TIMEOUT, run).await {
            Err(_) => {
                cancel.store(true, Ordering::Relaxed);
                return Err(EngineError::DraftFailed {
                    message: format!("the draft ran longer than {} s", DRAFT_TIMEOUT.as_secs()),
                    timed_out: true,
                });
            }
            Ok(joined) => joined.map_err(|e| EngineError::Internal(e.to_string()))?,
        };
        let output = output.map_err(|e| {
            EngineError::from_sim(e, |other| EngineError::DraftFailed { message: other.to_string(), timed_out: false })
        })?;
        let seconds = started.elapsed().as_secs_f64();
        let glb = output
            .artifacts
            .into_iter()
            .find(|a| a.name == "mesh.glb")
            .map(|a| a.bytes)
            .ok_or_else(|| EngineError::Internal(format!("{kind} made no mesh.glb")))?;
        Ok(Draft { glb, result: output.result, seconds })
    }

    /// Hold `bytes` of the memory budget for a draft, beside the running jobs; `Busy` when they
    /// leave too little (a draft never waits: the next edit asks again).
    fn reserve_draft(&self, bytes: u64) -> Result<Reservation<'_>, EngineError> {
        let budget = self.inner.config.memory_budget;
        let mut q = self.inner.queue.lock();
        if q.memory_reserved.saturating_add(bytes) > budget && q.memory_reserved > 0 {
            return Err(EngineError::Busy(format!(
                "the jobs and drafts running hold {} MiB of the {} MiB memory budget; this draft needs {} MiB",
                q.memory_reserved >> 20,
                budget >> 20,
                bytes.div_ceil(1 << 20),
            )));
        }
        q.memory_reserved += bytes;
        Ok(Reservation { engine: self, bytes })
    }
}
