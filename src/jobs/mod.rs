//! The engine and the `JobKind` trait every kind implements; the job model they use is
//! `crate::model`, re-exported here for the kinds.

mod kind;

pub use crate::model::{bytes, ArtifactMeta, CostBuilder, Job, JobStatus, ReplaySpec};
pub use kind::{
    parse_params, path_string, Artifact, Cost, JobKind, JobOutput, Kind, Outcome, Prepared, Progress, ProgressSink,
    References, RequestError, RunContext, Sequence, SilentProgress, SimError, Simulation,
};

mod draft;
mod engine;
mod live;
mod metrics;
mod remote;
mod runner;
mod store_terrain;
mod worker;

pub use draft::{Draft, DRAFT_MAX_WORK_S, DRAFT_TIMEOUT};
pub use engine::{
    build_pool, default_memory_budget, Engine, EngineConfig, EngineError, EventFeed, Submitted, Submitter,
    DEFAULT_CONCURRENT_JOBS, DEFAULT_JOB_TIMEOUT_S, DEFAULT_QUEUE_CAPACITY, MAX_ATTEMPTS,
};
pub use kind::{draft_terrain, DRAFT_MAX_SIDE};
pub use live::{JobEvent, LiveJob, StopReason};
pub use remote::{until_changed, STORE_POLL};
pub use runner::{problem, PROBLEM_TYPE_BASE};
pub use store_terrain::{StoreTerrain, HEIGHTFIELD_ARTIFACT};
pub use worker::{Worker, WorkerConfig, MAX_LOST_LEASES};

#[cfg(test)]
mod engine_tests;
#[cfg(test)]
mod test_kind;
#[cfg(test)]
mod worker_tests;
