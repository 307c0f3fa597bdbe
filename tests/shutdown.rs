//! SIGTERM: the server takes no more jobs, lets running ones finish until the deadline, then
//! returns the rest to the queue; the next start runs them, and nothing accepted is lost.

mod common;

use std::time::{Duration, Instant};

use common::bodies::{slow_bulldoze, small_bulldoze};
use common::server::{Options, TestServer};

async fn wait_running(server: &TestServer, id: &str) {
    let start = Instant::now();
    loop {
        let (_, job) = server.get_json(&format!("/v1/jobs/{id}")).await;
        if job["status"] == "running" {
            return;
        }
        assert!(start.elapsed() < Duration::from_secs(60), "{job}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

#[tokio::test]
async fn a_running_job_finishes_before_the_process_exits() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("landform.db");
    let options = Options { extra: vec!["--shutdown-deadline-secs".into(), "60".into()], ..Options::default() };
    let server = TestServer::start_on(&db, &options).await;
    // About a second of work, and a job behind it that has not started.
    let mut body = small_bulldoze();
    body["terrain"]["fractal"]["size"] = serde_json::json!(513);
    let running = server.submit("bulldoze", &body).await["id"].as_str().unwrap().to_string();
    wait_running(&server, &running).await;
    let exited = tokio::task::spawn_blocking(move || server.terminate(Duration::from_secs(60))).await.unwrap();
    assert!(exited, "the process did not exit after its job");
    let again = TestServer::start_on(&db, &Options::default()).await;
    let (_, job) = again.get_json(&format!("/v1/jobs/{running}")).await;
    assert_eq!(job["status"], "succeeded", "{job}");
}

#[tokio::test]
async fn at_the_deadline_running_jobs_go_back_to_the_queue_and_run_after_the_restart() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("landform.db");
    let options = Options {
        extra: vec!["--shutdown-deadline-secs".into(), "1".into(), "--concurrent-jobs".into(), "1".into()],
        ..Options::default()
    };
    let server = TestServer::start_on(&db, &options).await;
    let slow = server.submit("bulldoze", &slow_bulldoze()).await["id"].as_str().unwrap().to_string();
    let waiting = server.submit("bulldoze", &small_bulldoze()).await["id"].as_str().unwrap().to_string();
    wait_running(&server, &slow).await;
    let started = Instant::now();
    let exited = tokio::task::spawn_blocking(move || server.terminate(Duration::from_secs(30))).await.unwrap();
    assert!(exited, "the process did not exit");
    assert!(started.elapsed() < Duration::from_secs(15), "took {:?}", started.elapsed());

    // Before anything runs again, both are stored as queued: nothing was failed or lost.
    let store = landform::store::SqliteStore::open(db.to_str().unwrap()).unwrap();
    use landform::store::JobStore;
    for id in [&slow, &waiting] {
        let job = store.get(id).unwrap().expect("still there");
        assert_eq!(job.status, landform::jobs::JobStatus::Queued, "{id}");
        assert!(job.started_at.is_none());
    }
    drop(store);
    let again = TestServer::start_on(&db, &Options::default()).await;
    let done = again.wait_done(&waiting).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    again.client.post(again.url(&format!("/v1/jobs/{slow}/cancel"))).send().await.unwrap();
}
