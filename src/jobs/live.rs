//! In-memory state of a job the engine holds (queued or running): its cancel flag, its event
//! log for SSE resumption, its latest progress and live snapshot.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use bytes::Bytes;
use parking_lot::Mutex;
use serde_json::{json, Value};
use tokio::sync::{broadcast, watch};

use super::{JobStatus, Progress, ProgressSink};

/// Events kept for `Last-Event-ID` resumption; older ones are dropped first.
const EVENT_LOG_CAPACITY: usize = 4096;
const PROGRESS_EVENT_INTERVAL: Duration = Duration::from_millis(50);
const SNAPSHOT_INTERVAL: Duration = Duration::from_secs(1);
/// A job's first live snapshot comes this long after its first step, not at once: a job done
/// sooner has its preview at once, and a snapshot cost such a job up to a fifth of its time
/// (grow-cave's columns: 19 → 23 ms, `cargo bench --bench job_path`).
const FIRST_SNAPSHOT_AFTER: Duration = Duration::from_millis(250);

/// One server-sent event of a job's stream.
#[derive(Clone, Debug, PartialEq)]
pub struct JobEvent {
    pub id: u64,
    /// `progress`, `status` or `done`.
    pub event: &'static str,
    pub data: Value,
}

/// Why a job's cancel flag was raised.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    Cancelled,
    TimedOut,
    Deleted,
    /// The process is shutting down: the job goes back to the queue for the next start.
    ShuttingDown,
    /// The job's lease ran out and another worker holds it now: stop and write nothing.
    LeaseLost,
}

/// Event ids grow across process restarts too (a re-run job's events follow the ones a client
/// saw before the restart), so they start from the clock in microseconds.
fn first_event_id() -> u64 {
    let micros = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_micros());
    u64::try_from(micros).unwrap_or(u64::MAX / 2).max(1)
}

/// Rate limits of a job's progress events and live snapshots.
#[derive(Default)]
pub(super) struct Throttle {
    last_progress: Option<Instant>,
    last_snapshot: Option<Instant>,
    /// When the job first offered a snapshot (its first step).
    first_offered: Option<Instant>,
}

impl Throttle {
    /// Whether a progress event is due now (the last of a stage always is); if so, it is
    /// counted as sent.
    pub fn progress_due(&mut self, progress: &Progress) -> bool {
        let last = progress.steps > 0 && progress.step >= progress.steps;
        let due = self.last_progress.is_none_or(|at| at.elapsed() >= PROGRESS_EVENT_INTERVAL);
        if due || last {
            self.last_progress = Some(Instant::now());
        }
        due || last
    }

    /// The first snapshot comes [`FIRST_SNAPSHOT_AFTER`] into the job's steps, the next ones
    /// [`SNAPSHOT_INTERVAL`] apart.
    pub fn snapshot_due(&mut self) -> bool {
        match self.last_snapshot {
            Some(at) => at.elapsed() >= SNAPSHOT_INTERVAL,
            None => self.first_offered.get_or_insert_with(Instant::now).elapsed() >= FIRST_SNAPSHOT_AFTER,
        }
    }

    /// A snapshot (and the progress event announcing it) was just sent.
    pub fn snapshot_sent(&mut self) {
        self.last_snapshot = Some(Instant::now());
        self.last_progress = self.last_snapshot;
    }
}

/// A job's cancel flag, which the simulation looks at, and why it was raised.
#[derive(Default)]
pub struct StopFlag {
    pub cancel: AtomicBool,
    reason: Mutex<Option<StopReason>>,
}

impl StopFlag {
    /// Raise the flag; the first reason given sticks.
    pub fn stop(&self, reason: StopReason) {
        let mut r = self.reason.lock();
        if r.is_none() {
            *r = Some(reason);
        }
        self.cancel.store(true, Ordering::Relaxed);
    }

    pub fn reason(&self) -> Option<StopReason> {
        *self.reason.lock()
    }
}

/// A progress event's data: the progress, and the live snapshot's href when it announces one.
pub(super) fn progress_data(progress: &Progress, snapshot: Option<String>) -> Value {
    let mut data = serde_json::to_value(progress).unwrap_or(Value::Null);
    if let (Some(href), Some(obj)) = (snapshot, data.as_object_mut()) {
        obj.insert("snapshot".into(), Value::String(href));
    }
    data
}

pub struct LiveJob {
    pub id: String,
    /// The API key name that owns the job (none without keys).
    pub owner: Option<String>,
    /// The memory its estimate reserves while it is queued or running.
    pub memory: u64,
    pub flag: StopFlag,
    log: Mutex<VecDeque<JobEvent>>,
    next_event_id: AtomicU64,
    tx: broadcast::Sender<JobEvent>,
    progress: Mutex<Progress>,
    throttle: Mutex<Throttle>,
    snapshot: Mutex<Option<(u64, Bytes)>>,
    snapshots_taken: AtomicU64,
    done_tx: watch::Sender<bool>,
}

impl LiveJob {
    pub fn new(id: String) -> Self {
        Self::for_job(id, None, 0)
    }

    pub fn for_job(id: String, owner: Option<String>, memory: u64) -> Self {
        let (tx, _) = broadcast::channel(1024);
        let (done_tx, _) = watch::channel(false);
        Self {
            id,
            owner,
            memory,
            flag: StopFlag::default(),
            log: Mutex::new(VecDeque::new()),
            next_event_id: AtomicU64::new(first_event_id()),
            tx,
            progress: Mutex::new(Progress::default()),
            throttle: Mutex::new(Throttle::default()),
            snapshot: Mutex::new(None),
            snapshots_taken: AtomicU64::new(0),
            done_tx,
        }
    }

    /// Raise the cancel flag; the first reason given sticks.
    pub fn stop(&self, reason: StopReason) {
        self.flag.stop(reason);
    }

    pub fn stop_reason(&self) -> Option<StopReason> {
        self.flag.reason()
    }

    pub fn progress(&self) -> Progress {
        self.progress.lock().clone()
    }

    pub fn snapshot(&self) -> Option<(u64, Bytes)> {
        self.snapshot.lock().clone()
    }

    /// Append an event to the log and send it to subscribers.
    pub fn emit(&self, event: &'static str, data: Value) {
        let mut log = self.log.lock();
        let ev = JobEvent { id: self.next_event_id.fetch_add(1, Ordering::Relaxed), event, data };
        if log.len() == EVENT_LOG_CAPACITY {
            log.pop_front();
        }
        log.push_back(ev.clone());
        // Sent under the log lock so a subscriber never sees a gap or a duplicate.
        let _ = self.tx.send(ev);
    }

    pub fn emit_status(&self, status: JobStatus) {
        self.emit("status", json!({ "status": status }));
    }

    /// The final event; wakes everyone waiting for the job to end.
    pub fn emit_done(&self, job: Value) {
        self.emit("done", job);
        self.done_tx.send_replace(true);
    }

    /// Events after `last_event_id` and a receiver for everything later, without a gap.
    pub fn subscribe(&self, last_event_id: Option<u64>) -> (Vec<JobEvent>, broadcast::Receiver<JobEvent>) {
        let log = self.log.lock();
        let after = last_event_id.unwrap_or(0);
        let backlog = log.iter().filter(|e| e.id > after || e.event == "done").cloned().collect();
        (backlog, self.tx.subscribe())
    }

    /// Events after `last_event_id` still in the log (used after a lagging receiver).
    pub fn events_after(&self, last_event_id: u64) -> Vec<JobEvent> {
        self.log.lock().iter().filter(|e| e.id > last_event_id || e.event == "done").cloned().collect()
    }

    pub fn done_receiver(&self) -> watch::Receiver<bool> {
        self.done_tx.subscribe()
    }

    pub fn is_done(&self) -> bool {
        *self.done_tx.borrow()
    }

    fn progress_event(&self, progress: &Progress, snapshot: Option<String>) {
        self.emit("progress", progress_data(progress, snapshot));
    }
}

impl ProgressSink for LiveJob {
    fn progress(&self, progress: Progress) {
        *self.progress.lock() = progress.clone();
        if self.throttle.lock().progress_due(&progress) {
            self.progress_event(&progress, None);
        }
    }

    fn snapshot_due(&self) -> bool {
        self.throttle.lock().snapshot_due()
    }

    fn snapshot(&self, png: Vec<u8>, progress: Progress) {
        let n = self.snapshots_taken.fetch_add(1, Ordering::Relaxed) + 1;
        *self.snapshot.lock() = Some((n, Bytes::from(png)));
        *self.progress.lock() = progress.clone();
        self.throttle.lock().snapshot_sent();
        self.progress_event(&progress, Some(format!("/v1/jobs/{}/live.png?n={n}", self.id)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subscribe_resumes_after_the_last_event_id() {
        let live = LiveJob::new("j".into());
        live.emit_status(JobStatus::Queued);
        live.emit_status(JobStatus::Running);
        let first = live.subscribe(None).0[0].id;
        let (backlog, mut rx) = live.subscribe(Some(first));
        assert_eq!(backlog.iter().map(|e| e.id).collect::<Vec<_>>(), vec![first + 1]);
        live.emit_done(json!({}));
        assert_eq!(rx.try_recv().unwrap().event, "done");
        assert!(live.is_done());
    }

    #[test]
    fn the_first_stop_reason_sticks() {
        let live = LiveJob::new("j".into());
        live.stop(StopReason::TimedOut);
        live.stop(StopReason::Cancelled);
        assert_eq!(live.stop_reason(), Some(StopReason::TimedOut));
        assert!(live.flag.cancel.load(Ordering::Relaxed));
    }
}
