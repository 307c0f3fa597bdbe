//! The job model, the engine, and the `JobKind` trait every kind implements.

mod kind;
mod model;

pub use kind::{
    parse_params, path_string, Artifact, JobKind, JobOutput, Kind, Outcome, Prepared, Progress, ProgressSink,
    References, RequestError, RunContext, Sequence, SilentProgress, SimError, Simulation,
};
pub use model::{ArtifactMeta, Job, JobStatus, ReplaySpec};

mod engine;
mod live;
mod metrics;
mod runner;
mod store_terrain;

pub use engine::{
    Engine, EngineConfig, EngineError, EventFeed, Submitted, DEFAULT_JOB_TIMEOUT_S, DEFAULT_QUEUE_CAPACITY,
    MAX_ATTEMPTS,
};
pub use live::{JobEvent, LiveJob, StopReason};
pub use runner::{problem, PROBLEM_TYPE_BASE};
pub use store_terrain::{StoreTerrain, HEIGHTFIELD_ARTIFACT};

#[cfg(test)]
mod engine_tests;
