//! The engine with a real SQLite store and stand-in kinds whose behaviour the tests choose.

use std::sync::Arc;
use std::time::Duration;

use serde_json::{json, Value};

use super::test_kind::StandIn;
use super::{Engine, EngineConfig, JobStatus};
use crate::store::SqliteStore;

fn engine(dir: &tempfile::TempDir) -> Engine {
    engine_with(dir, EngineConfig { workers: 2, concurrent_jobs: 1, ..EngineConfig::default() })
}

fn engine_with(dir: &tempfile::TempDir, config: EngineConfig) -> Engine {
    let store = Arc::new(SqliteStore::open(dir.path().join("t.db").to_str().unwrap()).unwrap());
    let engine = Engine::new(store, vec![Box::new(StandIn)], config).expect("engine");
    engine.start();
    engine
}

async fn submit(engine: &Engine, body: Value) -> String {
    match engine.submit("stand-in", body, 0, None, &Default::default()).await.expect("submit") {
        super::Submitted::Created(j) | super::Submitted::Existing(j) => j.id,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panic_inside_a_job_fails_that_job_only() {
    let dir = tempfile::tempdir().unwrap();
    let engine = engine(&dir);
    let bad = submit(&engine, json!({ "panic": true })).await;
    let good = submit(&engine, json!({ "n": 7 })).await;
    let bad = engine.wait(&bad, Duration::from_secs(30)).await.unwrap();
    assert_eq!(bad.status, JobStatus::Failed);
    let detail = bad.error.unwrap()["detail"].as_str().unwrap().to_string();
    assert!(!detail.contains("a bug inside"), "the panic message stays in the log: {detail}");
    let good = engine.wait(&good, Duration::from_secs(30)).await.unwrap();
    assert_eq!(good.status, JobStatus::Succeeded);
    assert_eq!(engine.artifact(&good.id, "n.txt").await.unwrap().unwrap().1, b"7");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancelling_a_queued_job_ends_it_at_once_and_the_queue_moves_on() {
    let dir = tempfile::tempdir().unwrap();
    let engine = engine(&dir);
    let long = submit(&engine, json!({ "steps": 300 })).await;
    let queued = submit(&engine, json!({ "n": 1 })).await;
    let after = submit(&engine, json!({ "n": 2 })).await;
    let cancelled = engine.cancel(&queued, None).await.unwrap();
    assert_eq!(cancelled.status, JobStatus::Cancelled);
    engine.cancel(&long, None).await.unwrap();
    assert_eq!(engine.wait(&long, Duration::from_secs(30)).await.unwrap().status, JobStatus::Cancelled);
    assert_eq!(engine.wait(&after, Duration::from_secs(30)).await.unwrap().status, JobStatus::Succeeded);
    assert!(matches!(engine.cancel(&after, None).await, Err(super::EngineError::Conflict(_))));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn deleting_a_running_job_stops_it_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let engine = engine(&dir);
    let long = submit(&engine, json!({ "steps": 300 })).await;
    tokio::time::sleep(Duration::from_millis(100)).await;
    engine.delete(&long, None).await.unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert!(matches!(engine.get(&long, None).await, Err(super::EngineError::NotFound(_))));
    let next = submit(&engine, json!({ "n": 3 })).await;
    assert_eq!(engine.wait(&next, Duration::from_secs(30)).await.unwrap().status, JobStatus::Succeeded);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn deleting_a_queued_job_ends_its_stream_and_frees_its_place() {
    let dir = tempfile::tempdir().unwrap();
    let engine = engine(&dir);
    let long = submit(&engine, json!({ "steps": 300 })).await;
    let queued = submit(&engine, json!({ "n": 1 })).await;
    while engine.get(&long, None).await.unwrap().status != JobStatus::Running {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let super::EventFeed::Live { mut rx, .. } = engine.events(&queued, None, None).await.unwrap() else {
        panic!("a queued job has a live feed");
    };
    assert_eq!(engine.queue_depth(), 1);
    engine.delete(&queued, None).await.unwrap();
    assert_eq!(engine.queue_depth(), 0);
    let done = tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            let ev = rx.recv().await.unwrap();
            if ev.event == "done" {
                return ev;
            }
        }
    })
    .await
    .expect("the stream ends at once");
    assert_eq!(done.data["status"], "cancelled");
    engine.cancel(&long, None).await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_interrupted_too_often_is_failed_not_run_again() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.db");
    let store = Arc::new(SqliteStore::open(path.to_str().unwrap()).unwrap());
    let mut job = {
        let engine = Engine::new(store.clone(), vec![Box::new(StandIn)], EngineConfig::default()).unwrap();
        match engine.submit("stand-in", json!({ "n": 1 }), 0, None, &Default::default()).await.unwrap() {
            super::Submitted::Created(j) | super::Submitted::Existing(j) => j,
        }
    };
    use crate::store::JobStore;
    // Three starts that each ended with the process gone.
    for _ in 0..super::MAX_ATTEMPTS {
        job.status = JobStatus::Queued;
        store.update(&job).unwrap();
        job.status = JobStatus::Running;
        store.update(&job).unwrap();
    }
    let engine = Engine::new(store.clone(), vec![Box::new(StandIn)], EngineConfig::default()).unwrap();
    engine.recover().unwrap();
    let after = engine.get(&job.id, None).await.unwrap();
    assert_eq!(after.status, JobStatus::Failed);
    assert_eq!(after.error.unwrap()["title"], "Job interrupted repeatedly");
    assert_eq!(engine.queue_depth(), 0);
}
