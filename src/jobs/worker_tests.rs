//! Workers on the store's queue, each with a store of its own on one SQLite file (as separate
//! processes would be), running the stand-in kind.

use std::sync::Arc;
use std::time::{Duration, Instant};

use serde_json::json;

use super::test_kind::StandIn;
use super::worker::{Worker, WorkerConfig, MAX_LOST_LEASES};
use super::{Cost, Job, JobStatus};
use crate::store::{contract, ArtifactStore, EventLog, JobQueue, JobStore, SqliteStore};
use crate::validate::Limits;

struct Setup {
    dir: tempfile::TempDir,
}

impl Setup {
    fn new() -> Self {
        Setup { dir: tempfile::tempdir().unwrap() }
    }

    /// A store of its own on the shared file.
    fn store(&self) -> Arc<SqliteStore> {
        Arc::new(SqliteStore::open(self.dir.path().join("q.db").to_str().unwrap()).unwrap())
    }

    fn worker(&self, name: &str, tune: impl FnOnce(&mut WorkerConfig)) -> Worker {
        let mut config = WorkerConfig {
            name: name.into(),
            memory_budget: 1 << 30,
            concurrent_jobs: 4,
            lease: Duration::from_millis(600),
            poll: Duration::from_millis(20),
            job_timeout: Duration::from_secs(60),
            limits: Limits::default(),
        };
        tune(&mut config);
        let store: Arc<dyn EventLog> = self.store();
        Worker::new(store, vec![Box::new(StandIn)], config)
    }
}

/// A queued stand-in job: `steps` × 10 ms of work, `memory` bytes estimated.
fn submit(store: &dyn JobStore, n: u64, steps: u64, memory: u64) -> Job {
    let mut job = contract::job(n, "stand-in", JobStatus::Queued);
    job.request = json!({ "n": n, "steps": steps, "seed": 0 });
    job.cost = Some(Cost {
        memory_bytes: memory,
        memory_field: "memory".into(),
        work: steps,
        work_unit: "steps".into(),
        work_field: "steps".into(),
        min_seconds: 0.0,
        lod_triangles: 0,
        lod_bytes: 0,
    });
    store.insert(&job, None).unwrap();
    job
}

async fn wait_for(what: &str, mut done: impl FnMut() -> bool) {
    let started = Instant::now();
    while !done() {
        assert!(started.elapsed() < Duration::from_secs(30), "waited 30 s for {what}");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

fn status(store: &dyn JobStore, job: &Job) -> JobStatus {
    store.get(&job.id).unwrap().unwrap().status
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_workers_run_every_job_once_and_record_its_artifacts() {
    let setup = Setup::new();
    let store = setup.store();
    let jobs: Vec<Job> = (1..=8).map(|n| submit(store.as_ref(), n, 3, 1 << 20)).collect();
    let workers = [setup.worker("a", |_| {}), setup.worker("b", |_| {})];
    for w in &workers {
        tokio::spawn({
            let w = w.clone();
            async move { w.run().await }
        });
    }
    wait_for("every job to succeed", || jobs.iter().all(|j| status(store.as_ref(), j) == JobStatus::Succeeded)).await;
    for j in &jobs {
        let n = j.request["n"].to_string().into_bytes();
        assert_eq!(store.artifact(&j.id, "n.txt").unwrap().unwrap().1, n);
        // One claim each: nobody ran a job twice.
        assert_eq!(store.attempts(&j.id).unwrap(), Some(1));
    }
    for w in &workers {
        w.shutdown(Duration::from_secs(1)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jobs_run_side_by_side_only_while_their_estimates_fit_the_budget() {
    let setup = Setup::new();
    let store = setup.store();
    let jobs: Vec<Job> = (1..=5).map(|n| submit(store.as_ref(), n, 30, 400)).collect();
    let worker = setup.worker("a", |c| c.memory_budget = 1000);
    tokio::spawn({
        let w = worker.clone();
        async move { w.run().await }
    });
    let mut most = 0;
    wait_for("every job to end", || {
        let running = jobs.iter().filter(|j| status(store.as_ref(), j) == JobStatus::Running).count();
        most = most.max(running);
        jobs.iter().all(|j| status(store.as_ref(), j) == JobStatus::Succeeded)
    })
    .await;
    assert_eq!(most, 2, "two jobs of 400 bytes fit a budget of 1000, three do not");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn progress_reaches_the_store_while_a_job_runs() {
    let setup = Setup::new();
    let store = setup.store();
    let job = submit(store.as_ref(), 1, 60, 1);
    let worker = setup.worker("a", |_| {});
    tokio::spawn({
        let w = worker.clone();
        async move { w.run().await }
    });
    wait_for("progress events", || {
        let events = store.events_after(&job.id, 0, 100).unwrap();
        events.first().is_some_and(|e| e.event == "status" && e.data.contains("running"))
            && events.iter().any(|e| e.event == "progress" && e.data.contains("\"stage\":\"work\""))
    })
    .await;
    wait_for("the job to end", || status(store.as_ref(), &job) == JobStatus::Succeeded).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_whose_claim_was_taken_over_stops_and_writes_nothing() {
    let setup = Setup::new();
    let store = setup.store();
    let job = submit(store.as_ref(), 1, 300, 1);
    let worker = setup.worker("stalled", |_| {});
    tokio::spawn({
        let w = worker.clone();
        async move { w.run().await }
    });
    wait_for("the job to start", || status(store.as_ref(), &job) == JobStatus::Running).await;
    // The worker stalls past its lease (the clock moves on): another worker takes the job.
    let conn = rusqlite::Connection::open(setup.dir.path().join("q.db")).unwrap();
    conn.execute("UPDATE jobs SET lease_until = 0 WHERE id = ?1", [&job.id]).unwrap();
    let other = store.claim("other", Duration::from_secs(60), u64::MAX).unwrap().expect("the job is claimable");
    assert_eq!((other.attempt, other.lost_leases), (2, 1));
    let after_takeover = store.events_after(&job.id, 0, 1000).unwrap().len();

    // The first worker learns at its next renewal and stops, recording nothing.
    tokio::time::sleep(Duration::from_millis(600)).await;
    let now = store.get(&job.id).unwrap().unwrap();
    assert_eq!((now.status, now.result.clone(), now.artifacts.len()), (JobStatus::Running, None, 0));
    assert_eq!(store.events_after(&job.id, 0, 1000).unwrap().len(), after_takeover, "no event from the old claim");
    let mut done = other.job.clone();
    done.status = JobStatus::Succeeded;
    done.result = Some(json!({ "by": "other" }));
    assert!(store.finish_claimed(&done, other.attempt, &[]).unwrap());
    worker.shutdown(Duration::from_secs(1)).await;
    assert_eq!(store.get(&job.id).unwrap().unwrap().result, Some(json!({ "by": "other" })));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_that_took_its_worker_down_three_times_fails_instead_of_running_again() {
    let setup = Setup::new();
    let store = setup.store();
    let job = submit(store.as_ref(), 1, 1, 1);
    // Three workers die holding it: each claim's lease runs out.
    for _ in 0..MAX_LOST_LEASES {
        store.claim("doomed", Duration::from_millis(1), u64::MAX).unwrap().unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    let worker = setup.worker("a", |_| {});
    tokio::spawn({
        let w = worker.clone();
        async move { w.run().await }
    });
    wait_for("the job to fail", || status(store.as_ref(), &job) == JobStatus::Failed).await;
    let failed = store.get(&job.id).unwrap().unwrap();
    assert_eq!(failed.error.unwrap()["type"], "https://landform.dev/problems/worker-lost");
    assert!(failed.artifacts.is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancel_request_stops_a_running_job_and_a_time_limit_fails_one() {
    let setup = Setup::new();
    let store = setup.store();
    let cancelled = submit(store.as_ref(), 1, 3000, 1);
    let timed_out = submit(store.as_ref(), 2, 3000, 1);
    let worker = setup.worker("a", |c| c.job_timeout = Duration::from_millis(800));
    tokio::spawn({
        let w = worker.clone();
        async move { w.run().await }
    });
    wait_for("the first job to start", || status(store.as_ref(), &cancelled) == JobStatus::Running).await;
    let asked = Instant::now();
    assert!(store.request_cancel(&cancelled.id).unwrap());
    wait_for("the cancel", || status(store.as_ref(), &cancelled) == JobStatus::Cancelled).await;
    // Its 3000 steps would take 30 s: it stopped at a renewal instead.
    assert!(asked.elapsed() < Duration::from_secs(15), "the cancel was not seen");
    wait_for("the time limit", || status(store.as_ref(), &timed_out) == JobStatus::Failed).await;
    let failed = store.get(&timed_out.id).unwrap().unwrap();
    assert_eq!(failed.error.unwrap()["type"], "https://landform.dev/problems/timeout");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn at_shutdown_a_running_job_goes_back_to_the_queue_for_another_worker() {
    let setup = Setup::new();
    let store = setup.store();
    let job = submit(store.as_ref(), 1, 200, 1);
    let first = setup.worker("first", |_| {});
    tokio::spawn({
        let w = first.clone();
        async move { w.run().await }
    });
    wait_for("the job to start", || status(store.as_ref(), &job) == JobStatus::Running).await;
    first.shutdown(Duration::ZERO).await;
    assert_eq!(status(store.as_ref(), &job), JobStatus::Queued, "released, not left to its lease");
    let second = setup.worker("second", |_| {});
    tokio::spawn({
        let w = second.clone();
        async move { w.run().await }
    });
    wait_for("the second worker to finish it", || status(store.as_ref(), &job) == JobStatus::Succeeded).await;
    // Released, not lost: the job did not take its worker down.
    assert_eq!(store.attempts(&job.id).unwrap(), Some(2));
}
