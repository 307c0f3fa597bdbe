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
    /// Leave out replays (jobs with `replay_of`), which a timeline makes one per position.
    pub no_replays: bool,
}

/// The uploads a new job reads: those it sent inline, `(sha256, bytes)`, and those it names by
/// sha256 (sent with an earlier job of the same key).
#[derive(Clone, Copy, Debug, Default)]
pub struct JobInputs<'a> {
    pub sent: &'a [(String, Vec<u8>)],
    pub named: &'a [String],
}

impl JobInputs<'_> {
    /// Every sha256 the job reads, once each.
    pub fn all(&self) -> Vec<&str> {
        let mut all: Vec<&str> =
            self.sent.iter().map(|(s, _)| s.as_str()).chain(self.named.iter().map(String::as_str)).collect();
        all.sort_unstable();
        all.dedup();
        all
    }
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
    fn insert(&self, job: &Job, idempotency: Option<(&str, &str)>) -> Result<IdempotentInsert, StoreError> {
        self.insert_with_inputs(job, idempotency, JobInputs::default())
    }
    /// [`JobStore::insert`], with the uploads the job sent kept (once, by content) and every
    /// upload it reads recorded as the job's, in the same transaction: an upload is stored only
    /// with a job that was admitted, and goes with the last job that reads it.
    fn insert_with_inputs(
        &self,
        job: &Job,
        idempotency: Option<(&str, &str)>,
        inputs: JobInputs,
    ) -> Result<IdempotentInsert, StoreError>;
    fn get(&self, id: &str) -> Result<Option<Job>, StoreError>;
    /// The job as a summary (`Job::summarised`), without reading a request over
    /// `SUMMARY_REQUEST_BYTES`.
    fn get_summary(&self, id: &str) -> Result<Option<Job>, StoreError>;
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
    /// An upload's bytes by its sha256 (hex), for the jobs that read it.
    fn input(&self, sha256: &str) -> Result<Option<Vec<u8>>, StoreError>;
    /// Whether `sha256` names an upload that a job of `owner` (an API key's name; none without
    /// keys) sent or reads: an upload belongs to the key that sent it, and to any other key it
    /// does not exist.
    fn has_input(&self, sha256: &str, owner: Option<&str>) -> Result<bool, StoreError>;
    /// The job's status and owner alone (what a stream or a wait polls for, without reading
    /// and parsing its request); None if there is no such job.
    fn status(&self, id: &str) -> Result<Option<(JobStatus, Option<String>)>, StoreError>;
    /// How many times the job has entered `running` (0 if it never ran); None if there is none.
    fn attempts(&self, id: &str) -> Result<Option<u32>, StoreError>;
    /// Number of jobs waiting in the queue (what admission compares with its capacity, on
    /// every submission: an index lookup, not a count of every job ever stored).
    fn queued(&self) -> Result<u64, StoreError>;
    /// Number of jobs per (kind, status).
    fn counts(&self) -> Result<Vec<(String, JobStatus, u64)>, StoreError>;
}
