//! A job's events as the store keeps them, so that a client on any API replica can follow a
//! job running on any worker: ids come from the store (one sequence for the whole database),
//! not from a process's clock, so `Last-Event-ID` means the same on every replica. A worker
//! appends under its claim (a worker whose lease ran out appends nothing), the latest live
//! snapshot sits beside the events. A minute after a job has ended its events and snapshot are
//! pruned by the workers' cleaner (a stream that was following it has read them by then; one
//! opened after the end gets `done` at once), so the table holds about the running jobs only.

use super::{JobQueue, StoreError};

/// One event as stored.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StoredEvent {
    pub id: u64,
    /// `progress`, `status` or `done`.
    pub event: String,
    /// JSON text.
    pub data: String,
}

/// What a store's notification path says. Ids only: whoever hears it reads the tables.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Notice {
    /// A job was queued (submitted, or given back by a worker).
    Queued(String),
    /// A job has new events, or has ended.
    Changed(String),
    /// The listener lost its connection and has it again: anything may have changed meanwhile.
    Reconnected,
}

/// Events and live snapshots, across processes.
pub trait EventLog: JobQueue {
    /// Notices of changes made by any process, where the store has a way to send them
    /// (PostgreSQL's LISTEN/NOTIFY); `None` where waiting means polling (SQLite).
    fn notices(&self) -> Option<tokio::sync::broadcast::Receiver<Notice>> {
        None
    }

    /// Append an event under a claim; its id, or `None` when the claim is no longer the job's.
    fn append_event(&self, job_id: &str, attempt: u32, event: &str, data: &str) -> Result<Option<u64>, StoreError>;

    /// The job's events with ids above `after`, oldest first, at most `limit`.
    fn events_after(&self, job_id: &str, after: u64, limit: u32) -> Result<Vec<StoredEvent>, StoreError>;

    /// The job's latest event of kind `event`, if it has one.
    fn last_event(&self, job_id: &str, event: &str) -> Result<Option<StoredEvent>, StoreError>;

    /// Keep `png` as the job's latest live snapshot, announced by event `event_id`; false
    /// when the claim is no longer the job's.
    fn put_snapshot(&self, job_id: &str, attempt: u32, event_id: u64, png: &[u8]) -> Result<bool, StoreError>;

    /// The job's latest live snapshot and the event that announced it.
    fn snapshot(&self, job_id: &str) -> Result<Option<(u64, Vec<u8>)>, StoreError>;

    /// Delete the events and snapshots of jobs that ended before `ended_before`; how many rows.
    fn prune_ended(&self, ended_before: chrono::DateTime<chrono::Utc>) -> Result<u64, StoreError>;
}

/// An id column read back as u64.
pub(super) fn event_id(n: i64) -> Result<u64, StoreError> {
    u64::try_from(n).map_err(|_| StoreError::Corrupt(format!("event id {n}")))
}
