//! The job model: what a job is, where it is, what it costs and what it made. It sits below
//! both the engine (`jobs`) and the stores (`store`), so each stands on it without importing
//! the other.

mod cost;
mod job;
mod progress;

pub use cost::{bytes, Cost, CostBuilder};
pub use job::{json_len, ArtifactMeta, ByteCount, Job, JobStatus, ReplaySpec, SUMMARY_REQUEST_BYTES};
pub use progress::Progress;
