//! The job queue the stores keep, for workers in any process on any machine: a worker claims
//! the oldest job it can run, holds it under a lease it renews, and writes under its claim's
//! attempt number. The database decides who owns a job — its clock sets the leases, and the
//! attempt number (raised by every claim) fences every later write — so a worker whose lease
//! ran out while it stalled can never overwrite the work of the one that took the job over.

use std::time::Duration;

use super::{JobStore, StoreError};
use crate::export::Artifact;
use crate::model::Job;

/// A job a worker holds.
#[derive(Debug)]
pub struct Claim {
    /// The job as claimed: `running`, attempts counted.
    pub job: Job,
    /// This claim's fence: every write under the claim carries it.
    pub attempt: u32,
    /// How often a holder's lease ran out before the job ended (it crashed or stalled): a job
    /// that keeps killing its workers is failed, not claimed for ever.
    pub lost_leases: u32,
}

/// What a lease's renewal found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Renewal {
    /// The claim is still the job's; `cancel_requested` once a client asked to stop it.
    Held { cancel_requested: bool },
    /// The claim is no longer the job's (taken over, ended or deleted): stop, write nothing.
    Lost,
}

/// Claims, leases, cancel requests and fenced writes.
pub trait JobQueue: JobStore {
    /// Claim the oldest job that is queued or whose holder's lease has run out, if its
    /// estimated memory is at most `max_memory` (the worker's free budget): jobs are taken in
    /// submission order, and a large one is not passed over for smaller ones behind it. The
    /// lease lasts `lease` by the database's clock. Jobs running without a lease (an engine
    /// that runs them in its own process) are never claimed.
    fn claim(&self, worker: &str, lease: Duration, max_memory: u64) -> Result<Option<Claim>, StoreError>;

    /// Extend a claim's lease to `lease` from now, and read whether a cancel was requested.
    fn renew(&self, id: &str, attempt: u32, lease: Duration) -> Result<Renewal, StoreError>;

    /// Ask whoever runs (or will run) the job to stop: its worker sees it within
    /// `worker::CANCEL_POLL` (or at its next renewal). False when there is no such job or it
    /// has ended.
    fn request_cancel(&self, id: &str) -> Result<bool, StoreError>;

    /// Whether a cancel was requested for the job (false when there is none): what a worker
    /// looks at between renewals, so a cancel stops a job within a moment.
    fn cancel_requested(&self, id: &str) -> Result<bool, StoreError>;

    /// Give a claimed job back to the queue at once (a worker shutting down); false when the
    /// claim is no longer the job's.
    fn release(&self, id: &str, attempt: u32) -> Result<bool, StoreError>;

    /// Jobs queued or running for `owner` (None: jobs made without a key), and the memory
    /// their estimates reserve: what a key's quotas count, whichever process runs them.
    fn active(&self, owner: Option<&str>) -> Result<(u32, u64), StoreError>;

    /// The memory the estimates of all running jobs reserve.
    fn reserved(&self) -> Result<u64, StoreError>;

    /// Jobs that ended after `after` (oldest end first, at most `limit`): what a process's
    /// metrics have not yet counted of the jobs its workers ran.
    fn ended_after(&self, after: chrono::DateTime<chrono::Utc>, limit: u32) -> Result<Vec<Job>, StoreError>;

    /// `JobStore::update` under a claim; false (nothing written) when the claim is no longer
    /// the job's.
    fn update_claimed(&self, job: &Job, attempt: u32) -> Result<bool, StoreError>;

    /// `JobStore::finish` under a claim; false (nothing written) when the claim is no longer
    /// the job's.
    fn finish_claimed(&self, job: &Job, attempt: u32, artifacts: &[Artifact]) -> Result<bool, StoreError>;
}

/// A lease in whole milliseconds, at least one.
pub(super) fn lease_ms(lease: Duration) -> i64 {
    i64::try_from(lease.as_millis()).unwrap_or(i64::MAX).max(1)
}

/// A count column read back as u32.
pub(super) fn count(what: &str, id: &str, n: i64) -> Result<u32, StoreError> {
    u32::try_from(n).map_err(|_| StoreError::Corrupt(format!("job {id}: {what} {n}")))
}
