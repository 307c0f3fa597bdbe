//! The engine with a real SQLite store and stand-in kinds whose behaviour the tests choose.

use std::sync::Arc;
use std::time::Duration;

use serde_json::{json, Value};

use super::{
    Artifact, Engine, EngineConfig, JobKind, JobOutput, JobStatus, Prepared, RequestError, RunContext, SimError,
};
use crate::store::SqliteStore;
use crate::validate::Limits;

/// Panics when `params.panic` is true; otherwise writes one artifact named after `params.n`.
struct StandIn;

impl JobKind for StandIn {
    fn name(&self) -> &'static str {
        "stand-in"
    }
    fn summary(&self) -> &'static str {
        "test kind"
    }
    fn prepare(&self, params: Value, _: &Limits) -> Result<Prepared, RequestError> {
        Ok(Prepared { params, job_refs: Vec::new() })
    }
    fn run(&self, params: &Value, _seed: u64, ctx: &RunContext) -> Result<JobOutput, SimError> {
        if params["panic"].as_bool() == Some(true) {
            panic!("a bug inside a simulation");
        }
        for step in 0..params["steps"].as_u64().unwrap_or(1) {
            ctx.check_cancelled()?;
            ctx.report("work", step, 10, "");
            std::thread::sleep(Duration::from_millis(10));
        }
        let bytes = params["n"].to_string().into_bytes();
        Ok(JobOutput {
            result: json!({ "n": params["n"] }),
            artifacts: vec![Artifact::new("n.txt", "text/plain", bytes)],
        })
    }
    fn sequence_steps(&self, _: &[u8]) -> Result<u64, SimError> {
        Ok(0)
    }
    fn replay(&self, p: &Value, _: &[u8], _: Option<u64>, ctx: &RunContext) -> Result<JobOutput, SimError> {
        self.run(p, 0, ctx)
    }
    fn request_schema(&self) -> super::kind::RequestSchema {
        ("StandIn".into(), utoipa::openapi::RefOr::T(utoipa::openapi::Schema::default()), Vec::new())
    }
}

fn engine(dir: &tempfile::TempDir) -> Engine {
    let store = Arc::new(SqliteStore::open(dir.path().join("t.db").to_str().unwrap()).unwrap());
    let engine = Engine::new(store, vec![Box::new(StandIn)], EngineConfig { workers: 2, ..EngineConfig::default() })
        .expect("engine");
    engine.start();
    engine
}

async fn submit(engine: &Engine, body: Value) -> String {
    match engine.submit("stand-in", body, None).await.expect("submit") {
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
    let cancelled = engine.cancel(&queued).await.unwrap();
    assert_eq!(cancelled.status, JobStatus::Cancelled);
    engine.cancel(&long).await.unwrap();
    assert_eq!(engine.wait(&long, Duration::from_secs(30)).await.unwrap().status, JobStatus::Cancelled);
    assert_eq!(engine.wait(&after, Duration::from_secs(30)).await.unwrap().status, JobStatus::Succeeded);
    assert!(matches!(engine.cancel(&after).await, Err(super::EngineError::Conflict(_))));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn deleting_a_running_job_stops_it_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let engine = engine(&dir);
    let long = submit(&engine, json!({ "steps": 300 })).await;
    tokio::time::sleep(Duration::from_millis(100)).await;
    engine.delete(&long).await.unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert!(matches!(engine.get(&long).await, Err(super::EngineError::NotFound(_))));
    let next = submit(&engine, json!({ "n": 3 })).await;
    assert_eq!(engine.wait(&next, Duration::from_secs(30)).await.unwrap().status, JobStatus::Succeeded);
}
