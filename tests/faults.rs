//! Faults across processes, on the SQLite file and on PostgreSQL (when
//! `LANDFORM_TEST_DATABASE_URL` names one): a worker SIGKILLed mid-job, a worker stalled
//! (SIGSTOP) past its lease and resumed, an API replica SIGKILLed while clients stream from it.
//! Nothing accepted is lost, and every job ends with the bytes an undisturbed run makes.
//!
//! The stall and resume of a worker started on its own runs on PostgreSQL only: on the SQLite
//! file a process stopped inside a write transaction keeps the database's only write lock, so
//! no other process can write until it is resumed (a limit of the embedded store, stated in the
//! README). There `serve` kills a supervised worker that stops, tested below.

mod common;

use std::time::{Duration, Instant};

use common::bodies::seconds_bulldoze;
use common::processes::{api_replica, children_of, kill_pid, signal_pid, with_schema, CpuHog, WorkerProcess};
use common::server::{artifact_hashes, Options, TestServer};
use common::sse::read_events;
use serde_json::Value;

/// Leases short enough that a takeover comes within a test's patience.
const LEASE_SECS: u64 = 2;

/// The artifacts an undisturbed single process makes for `body`.
async fn undisturbed(body: &Value) -> Vec<(String, String)> {
    let single = TestServer::start().await;
    artifact_hashes(&single.run("bulldoze", body).await)
}

async fn wait_running(api: &TestServer, id: &str) {
    let started = Instant::now();
    loop {
        let (_, job) = api.get_json(&format!("/v1/jobs/{id}")).await;
        if job["status"] == "running" {
            return;
        }
        assert_eq!(job["status"], "queued", "{job}");
        assert!(started.elapsed() < Duration::from_secs(60), "never started: {job}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

async fn a_killed_workers_job_finishes_on_another_worker(database: &str) {
    let doomed = WorkerProcess::start(database, LEASE_SECS);
    let api = api_replica(database).await;
    let body = seconds_bulldoze(9);
    let id = api.submit("bulldoze", &body).await["id"].as_str().unwrap().to_string();
    wait_running(&api, &id).await;
    doomed.signal("KILL");
    let _other = WorkerProcess::start(database, LEASE_SECS);
    let done = api.wait_done(&id).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(artifact_hashes(&done), undisturbed(&body).await);
}

async fn a_stalled_workers_late_writes_are_refused(database: &str) {
    let stalled = WorkerProcess::start(database, LEASE_SECS);
    let api = api_replica(database).await;
    let body = seconds_bulldoze(9);
    let id = api.submit("bulldoze", &body).await["id"].as_str().unwrap().to_string();
    wait_running(&api, &id).await;
    stalled.signal("STOP");
    let _other = WorkerProcess::start(database, LEASE_SECS);
    let done = api.wait_done(&id).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    // The stalled worker wakes up holding a claim that is no longer the job's: whatever it
    // still tries to write (progress, the outcome) is refused by the fence.
    stalled.signal("CONT");
    tokio::time::sleep(Duration::from_secs(LEASE_SECS + 2)).await;
    let (_, after) = api.get_json(&format!("/v1/jobs/{id}")).await;
    assert_eq!(after, done, "the job changed after the stalled worker resumed");
    assert_eq!(artifact_hashes(&after), undisturbed(&body).await);
}

async fn clients_of_a_killed_api_resume_on_another_and_miss_nothing(database: &str) {
    let _worker = WorkerProcess::start(database, LEASE_SECS);
    let (doomed, other) = (api_replica(database).await, api_replica(database).await);
    let id = doomed.submit("bulldoze", &seconds_bulldoze(9)).await["id"].as_str().unwrap().to_string();
    let url = |api: &TestServer| api.url(&format!("/v1/jobs/{id}/events"));
    let before = read_events(&doomed.client, &url(&doomed), None, 4).await;
    let seen = before.last().and_then(|e| e.id).expect("an event id");
    doomed.kill();
    let after = read_events(&other.client, &url(&other), Some(seen), 100_000).await;
    let done = after.last().expect("events after the reconnect");
    assert_eq!((done.event.as_str(), done.data["status"].as_str()), ("done", Some("succeeded")), "{after:?}");
    // The job's events carry consecutive ids: the stream went on exactly after the last one seen.
    let ids: Vec<u64> = after.iter().map(|e| e.id.expect("id")).collect();
    assert_eq!(ids, (seen + 1..seen + 1 + ids.len() as u64).collect::<Vec<_>>(), "{after:?}");
    assert!(after.len() > 2, "the job was still running when the client came back: {after:?}");
}

#[tokio::test]
async fn sqlite_a_killed_workers_job_finishes_on_another_worker() {
    let dir = tempfile::tempdir().unwrap();
    a_killed_workers_job_finishes_on_another_worker(dir.path().join("f.db").to_str().unwrap()).await;
}

#[tokio::test]
async fn sqlite_clients_of_a_killed_api_resume_on_another_and_miss_nothing() {
    let dir = tempfile::tempdir().unwrap();
    clients_of_a_killed_api_resume_on_another_and_miss_nothing(dir.path().join("f.db").to_str().unwrap()).await;
}

#[tokio::test]
async fn postgres_a_killed_workers_job_finishes_on_another_worker() {
    let Some(schema) = with_schema() else { return };
    a_killed_workers_job_finishes_on_another_worker(&schema.url).await;
}

#[tokio::test]
async fn postgres_a_stalled_workers_late_writes_are_refused() {
    let Some(schema) = with_schema() else { return };
    a_stalled_workers_late_writes_are_refused(&schema.url).await;
}

#[tokio::test]
async fn postgres_clients_of_a_killed_api_resume_on_another_and_miss_nothing() {
    let Some(schema) = with_schema() else { return };
    clients_of_a_killed_api_resume_on_another_and_miss_nothing(&schema.url).await;
}

/// The embedded default: `serve` and the worker process it supervises, with short leases.
async fn supervised(db: &std::path::Path) -> TestServer {
    let options = Options { extra: vec!["--lease-secs".into(), LEASE_SECS.to_string()], ..Options::default() };
    TestServer::start_on(db, &options).await
}

/// The worker the server supervises, once it has started.
async fn worker_child(server: &TestServer) -> u32 {
    let started = Instant::now();
    loop {
        if let Some(&pid) = children_of(server.pid()).first() {
            return pid;
        }
        assert!(started.elapsed() < Duration::from_secs(30), "no worker process");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

#[tokio::test]
async fn sqlite_a_killed_worker_child_is_restarted_and_its_job_finishes_while_the_api_answers() {
    let dir = tempfile::tempdir().unwrap();
    let server = supervised(&dir.path().join("s.db")).await;
    let body = seconds_bulldoze(9);
    let id = server.submit("bulldoze", &body).await["id"].as_str().unwrap().to_string();
    wait_running(&server, &id).await;
    let first = worker_child(&server).await;
    kill_pid(first);
    // The API never went away.
    let (status, _) = server.get_json("/healthz").await;
    assert_eq!(status, 200);
    let done = server.wait_done(&id).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_ne!(worker_child(&server).await, first, "a new worker process took over");
    assert_eq!(artifact_hashes(&done), undisturbed(&body).await);
}

#[tokio::test]
async fn sqlite_a_killed_process_group_restarted_finishes_the_job() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    let server = supervised(&db).await;
    let body = seconds_bulldoze(9);
    let id = server.submit("bulldoze", &body).await["id"].as_str().unwrap().to_string();
    wait_running(&server, &id).await;
    let worker = worker_child(&server).await;
    kill_pid(worker);
    server.kill();
    let again = supervised(&db).await;
    let done = again.wait_done(&id).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(artifact_hashes(&done), undisturbed(&body).await);
}

/// Fields of /proc/PID/stat from the third (state) on.
fn stat_fields(pid: u32) -> Vec<String> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    stat.rsplit_once(')').unwrap().1.split_whitespace().map(str::to_string).collect()
}

/// The supervised worker leaves the cores to the API: nice 10 (the default), and where the
/// kernel shares the cores between sessions first (autogroup), in a session of its own whose
/// group is at nice 10 too, while the API's session stays at 0.
#[tokio::test]
async fn sqlite_the_supervised_worker_yields_the_cores_in_a_session_of_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let server = supervised(&dir.path().join("s.db")).await;
    let worker = worker_child(&server).await;
    let started = Instant::now();
    while stat_fields(worker)[16] != "10" {
        assert!(started.elapsed() < Duration::from_secs(10), "the worker's niceness: {:?}", stat_fields(worker));
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let autogroup = std::fs::read_to_string("/proc/sys/kernel/sched_autogroup_enabled").unwrap_or_default();
    if autogroup.trim() != "1" {
        eprintln!("autogroup scheduling is off here: the session part is not observable");
        return;
    }
    // Niceness is set after the move to a new session, so both have happened by now.
    assert_eq!(stat_fields(worker)[3], worker.to_string(), "the worker leads a session of its own");
    // A process of the first session (started from init without a session of its own, as a CI
    // runner's may be) is in the kernel's default group, at nice 0, and its file is empty.
    let group = |pid: u32| {
        let shown = std::fs::read_to_string(format!("/proc/{pid}/autogroup")).unwrap();
        if shown.trim().is_empty() {
            "the default group, nice 0".to_string()
        } else {
            shown.trim().to_string()
        }
    };
    let (ours, api) = (group(worker), group(server.pid()));
    assert!(ours.starts_with("/autogroup-") && ours.ends_with("nice 10"), "the worker's group: {ours:?}");
    assert!(api.ends_with("nice 0"), "the API's group: {api:?}");
    assert_ne!(ours.split_whitespace().next(), api.split_whitespace().next());
}

#[tokio::test]
async fn sqlite_a_stopped_worker_child_is_killed_and_replaced_while_the_api_takes_jobs() {
    let dir = tempfile::tempdir().unwrap();
    let server = supervised(&dir.path().join("s.db")).await;
    let body = seconds_bulldoze(9);
    let id = server.submit("bulldoze", &body).await["id"].as_str().unwrap().to_string();
    wait_running(&server, &id).await;
    let stopped = worker_child(&server).await;
    // Stopped wherever it happens to be, perhaps inside a write transaction holding the lock.
    signal_pid(stopped, "STOP");
    // Submissions wait for the lock rather than fail, until the supervisor has killed the
    // silent worker; the API answers throughout.
    let (status, _) = server.get_json("/healthz").await;
    assert_eq!(status, 200);
    let second = server.submit("bulldoze", &seconds_bulldoze(1)).await["id"].as_str().unwrap().to_string();
    let done = server.wait_done(&id).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(server.wait_done(&second).await["status"], "succeeded");
    assert!(!std::path::Path::new(&format!("/proc/{stopped}")).exists(), "the stopped worker was killed and reaped");
    assert_ne!(worker_child(&server).await, stopped, "a new worker process took over");
    assert_eq!(artifact_hashes(&done), undisturbed(&body).await);
}

/// Under a CPU hog (8 spinning programs a core, each in a session of its own) the supervised
/// worker at nice 10 gets a sliver of the cores and its beats may come late, but it is
/// computing: the watchdog waits for it, and it keeps its job and finishes it once the load is
/// gone, with the bytes an undisturbed run makes.
#[tokio::test]
async fn sqlite_a_busy_worker_under_a_cpu_hog_keeps_its_job() {
    let dir = tempfile::tempdir().unwrap();
    let server = supervised(&dir.path().join("s.db")).await;
    let body = seconds_bulldoze(5);
    let id = server.submit("bulldoze", &body).await["id"].as_str().unwrap().to_string();
    wait_running(&server, &id).await;
    let worker = worker_child(&server).await;
    {
        let _hog = CpuHog::start(8);
        // Four of the watchdog's windows (3 s at this lease).
        tokio::time::sleep(Duration::from_secs(12)).await;
        let (_, job) = server.get_json(&format!("/v1/jobs/{id}")).await;
        assert_eq!(job["status"], "running", "the job under the hog: {job}");
    }
    let done = server.wait_done(&id).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(worker_child(&server).await, worker, "the busy worker was killed and replaced");
    assert_eq!(artifact_hashes(&done), undisturbed(&body).await);
}
