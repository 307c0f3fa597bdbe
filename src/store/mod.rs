//! Where jobs live: the `JobStore` trait, its embedded SQLite form and its PostgreSQL form.

mod artifacts;
#[cfg(test)]
pub(crate) mod contract;
mod events;
mod listener;
mod notifier;
mod objects;
mod pg_conn;
mod postgres;
mod queue;
mod row;
mod sqlite;

pub use artifacts::{ArtifactStore, CHUNK_BYTES};
pub use events::{EventLog, Notice, StoredEvent};
pub use objects::ObjectArtifacts;
pub use postgres::PostgresStore;
pub use queue::{Claim, JobQueue, Renewal};
pub use sqlite::SqliteStore;

use crate::export::Artifact;
use crate::model::{Job, JobStatus};

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("store: {0}")]
    Backend(String),
    #[error("store: stored data unreadable: {0}")]
    Corrupt(String),
}

/// Which jobs `list` returns: newest first, ids strictly below `before_id` when set; a
/// `limit` of 0 means no limit.
#[derive(Clone, Debug, Default)]
pub struct ListFilter {
    pub kind: Option<String>,
    pub status: Option<JobStatus>,
    pub before_id: Option<String>,
    pub limit: u32,
    /// Only the jobs of this API key (by name), when set.
    pub owner: Option<String>,
}

/// Outcome of an insert carrying an idempotency key.
#[derive(Debug)]
pub enum IdempotentInsert {
    Inserted,
    /// The key was used before: the job it created, and whether the body hash matched.
    Existing {
        job: Box<Job>,
        same_body: bool,
    },
}

/// Persistent job storage, artifacts included. Methods are blocking; async callers use
/// `spawn_blocking`.
pub trait JobStore: ArtifactStore {
    /// Store a new job. With `idempotency = Some((key, body_sha256))`, the key is recorded with
    /// it in the same transaction, unless the key already exists (then nothing is written).
    fn insert(&self, job: &Job, idempotency: Option<(&str, &str)>) -> Result<IdempotentInsert, StoreError>;
    fn get(&self, id: &str) -> Result<Option<Job>, StoreError>;
    fn list(&self, filter: &ListFilter) -> Result<Vec<Job>, StoreError>;
    /// Save a job's status, timestamps, progress, result and error (not its artifacts).
    fn update(&self, job: &Job) -> Result<(), StoreError>;
    /// Save a finished job and its artifacts (in chunks) in one transaction; `job.artifacts`
    /// is set from them.
    fn finish(&self, job: &Job, artifacts: &[Artifact]) -> Result<(), StoreError>;
    /// Remove a job, its artifacts and its idempotency key; false if there was none.
    fn delete(&self, id: &str) -> Result<bool, StoreError>;
    /// Jobs queued or running (oldest first): to run again after a restart.
    fn unfinished(&self) -> Result<Vec<Job>, StoreError>;
    /// Keep an uploaded file under its sha256 (hex); storing the same file again does nothing.
    fn put_input(&self, sha256: &str, data: &[u8]) -> Result<(), StoreError>;
    fn input(&self, sha256: &str) -> Result<Option<Vec<u8>>, StoreError>;
    fn has_input(&self, sha256: &str) -> Result<bool, StoreError>;
    /// How many times the job has entered `running` (0 if it never ran); None if there is none.
    fn attempts(&self, id: &str) -> Result<Option<u32>, StoreError>;
    /// Number of jobs waiting in the queue (what admission compares with its capacity, on
    /// every submission: an index lookup, not a count of every job ever stored).
    fn queued(&self) -> Result<u64, StoreError>;
    /// Number of jobs per (kind, status).
    fn counts(&self) -> Result<Vec<(String, JobStatus, u64)>, StoreError>;
}
