//! What the simulated clients do. Each goose user is one client:
//!
//! - **steady** (`small_job`): submit a small job (the kinds in turn), follow it — even users
//!   over SSE, odd users by polling (every 100 ms by default) — on another API replica where there are
//!   several, then download one of its artifacts (in turn) and check its sha256; again.
//! - **burst** (`burst`): submit 8 small jobs back to back without waiting; `503` (queue full)
//!   is expected and counted apart.
//! - **large** (`large_job`): as steady, with a large body, followed over SSE.
//!
//! Requests are named for the report: `submit`, `events`, `poll`, `download`, `burst submit`.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

use goose::goose::{GooseMethod, GooseRequest};
use goose::prelude::*;
use serde_json::Value;
use sha2::{Digest, Sha256};

/// What a step of a transaction gives, or the error that ends the transaction.
type Step<T> = Result<T, Box<goose::goose::TransactionError>>;

/// A job the service accepted (202), for the end checks.
#[derive(Clone, Debug)]
pub struct Accepted {
    pub id: String,
    pub kind: String,
    pub phase: String,
}

pub struct Shared {
    pub apis: Vec<String>,
    pub small: Vec<(String, Value)>,
    pub large: Vec<(String, Value)>,
    pub phase: Mutex<String>,
    /// How often polling clients ask for a job's status.
    pub poll_every: Duration,
    pub accepted: Mutex<Vec<Accepted>>,
    pub burst_503: AtomicU64,
    /// What went wrong that is not an HTTP status: a job that failed, a wrong sha256, an event
    /// stream that ended without `done`.
    pub problems: Mutex<Vec<String>>,
}

static SHARED: OnceLock<Shared> = OnceLock::new();

pub fn init(shared: Shared) {
    assert!(SHARED.set(shared).is_ok(), "initialised once");
}

pub fn shared() -> &'static Shared {
    SHARED.get().expect("initialised before any attack")
}

fn problem(what: String) {
    let mut p = shared().problems.lock().unwrap();
    if p.len() < 1000 {
        p.push(what);
    }
}

/// A user's place in the rotation of kinds.
#[derive(Clone)]
struct Turn(usize);

fn next_turn(user: &mut GooseUser) -> usize {
    if user.get_session_data::<Turn>().is_none() {
        user.set_session_data(Turn(user.weighted_users_index));
    }
    let t = user.get_session_data_mut::<Turn>().expect("set above");
    t.0 += 1;
    t.0 - 1
}

fn is_terminal(status: &str) -> bool {
    matches!(status, "succeeded" | "failed" | "cancelled")
}

/// POST a job; its id when accepted. `burst`: a 503 is expected (counted, not a failure).
async fn submit(user: &mut GooseUser, api: &str, kind: &str, body: &Value, burst: bool) -> Step<Option<String>> {
    let url = format!("{api}/v1/jobs/{kind}");
    let builder = user.client.post(&url).json(body);
    let name = if burst { "burst submit" } else { "submit" };
    let request = GooseRequest::builder()
        .method(GooseMethod::Post)
        .path(url.as_str())
        .name(name)
        .expect_status_code(202)
        .set_request_builder(builder)
        .build();
    let mut goose = user.request(request).await?;
    let response = match goose.response {
        Ok(r) => r,
        Err(_) => return Ok(None),
    };
    let status = response.status().as_u16();
    if status == 503 && burst {
        shared().burst_503.fetch_add(1, Ordering::Relaxed);
        user.set_success(&mut goose.request)?;
        return Ok(None);
    }
    if status != 202 {
        return Ok(None);
    }
    let job: Value = match response.json().await {
        Ok(j) => j,
        Err(e) => {
            problem(format!("{kind}: the 202's body is not a job: {e}"));
            return Ok(None);
        }
    };
    let id = job["id"].as_str().unwrap_or_default().to_string();
    let s = shared();
    let phase = s.phase.lock().unwrap().clone();
    s.accepted.lock().unwrap().push(Accepted { id: id.clone(), kind: kind.to_string(), phase });
    Ok(Some(id))
}

/// Follow a job's event stream until `done`; the job it carries.
async fn follow_events(user: &mut GooseUser, api: &str, id: &str) -> Step<Option<Value>> {
    let url = format!("{api}/v1/jobs/{id}/events");
    let builder = user.client.get(&url).header("accept", "text/event-stream").timeout(Duration::from_secs(600));
    let request = GooseRequest::builder()
        .method(GooseMethod::Get)
        .path(url.as_str())
        .name("events")
        .set_request_builder(builder)
        .build();
    let goose = user.request(request).await?;
    let Ok(mut response) = goose.response else { return Ok(None) };
    if !response.status().is_success() {
        return Ok(None);
    }
    let mut buffer = String::new();
    loop {
        match response.chunk().await {
            Ok(Some(piece)) => buffer.push_str(&String::from_utf8_lossy(&piece)),
            Ok(None) => break,
            Err(e) => {
                problem(format!("job {id}: event stream broke: {e}"));
                return Ok(None);
            }
        }
        while let Some(end) = buffer.find("\n\n") {
            let event: String = buffer.drain(..end + 2).collect();
            if event.lines().any(|l| l == "event: done") {
                let data: String = event
                    .lines()
                    .filter_map(|l| l.strip_prefix("data:"))
                    .map(str::trim_start)
                    .collect::<Vec<_>>()
                    .join("\n");
                return Ok(serde_json::from_str(&data).ok());
            }
        }
    }
    problem(format!("job {id}: the event stream ended without `done`"));
    Ok(None)
}

/// Poll a job every 100 ms until it has ended; the job.
async fn poll(user: &mut GooseUser, api: &str, id: &str) -> Step<Option<Value>> {
    let url = format!("{api}/v1/jobs/{id}");
    loop {
        let request = GooseRequest::builder().method(GooseMethod::Get).path(url.as_str()).name("poll").build();
        let goose = user.request(request).await?;
        let Ok(response) = goose.response else { return Ok(None) };
        if !response.status().is_success() {
            return Ok(None);
        }
        let job: Value = response.json().await.unwrap_or_default();
        if is_terminal(job["status"].as_str().unwrap_or_default()) {
            return Ok(Some(job));
        }
        tokio::time::sleep(shared().poll_every).await;
    }
}

/// Download artifact number `pick` (in turn) of a finished job and check its sha256.
async fn download(user: &mut GooseUser, api: &str, job: &Value, pick: usize) -> TransactionResult {
    let id = job["id"].as_str().unwrap_or_default();
    if job["status"] != "succeeded" {
        problem(format!("job {id} ({}) ended {}: {}", job["kind"], job["status"], job["error"]));
        return Ok(());
    }
    let Some(artifacts) = job["artifacts"].as_array().filter(|a| !a.is_empty()) else {
        problem(format!("job {id} succeeded with no artifacts"));
        return Ok(());
    };
    let meta = &artifacts[pick % artifacts.len()];
    let name = meta["name"].as_str().unwrap_or_default();
    let url = format!("{api}/v1/jobs/{id}/artifacts/{name}");
    let request = GooseRequest::builder().method(GooseMethod::Get).path(url.as_str()).name("download").build();
    let goose = user.request(request).await?;
    let Ok(response) = goose.response else { return Ok(()) };
    if response.status().is_success() {
        match response.bytes().await {
            Ok(bytes) if format!("{:x}", Sha256::digest(&bytes)) == meta["sha256"].as_str().unwrap_or_default() => {}
            Ok(_) => problem(format!("job {id}: {name} does not match its sha256")),
            Err(e) => problem(format!("job {id}: {name}: download broke: {e}")),
        }
    }
    Ok(())
}

/// Submit one job from `bodies` (in turn), follow it and download one of its artifacts.
async fn one_job(user: &mut GooseUser, large: bool) -> TransactionResult {
    let s = shared();
    let turn = next_turn(user);
    let bodies = if large { &s.large } else { &s.small };
    let (kind, body) = &bodies[turn % bodies.len()];
    let me = user.weighted_users_index;
    let (submit_api, follow_api) = (&s.apis[me % s.apis.len()], &s.apis[(me + 1) % s.apis.len()]);
    let Some(id) = submit(user, submit_api, kind, body, false).await? else { return Ok(()) };
    let job = if large || me % 2 == 0 {
        follow_events(user, follow_api, &id).await?
    } else {
        poll(user, follow_api, &id).await?
    };
    if let Some(job) = job {
        download(user, submit_api, &job, turn / bodies.len() + me).await?;
    }
    Ok(())
}

pub async fn small_job(user: &mut GooseUser) -> TransactionResult {
    one_job(user, false).await
}

pub async fn large_job(user: &mut GooseUser) -> TransactionResult {
    one_job(user, true).await
}

/// Eight small jobs back to back, following none.
pub async fn burst(user: &mut GooseUser) -> TransactionResult {
    let s = shared();
    let me = user.weighted_users_index;
    for k in 0..8 {
        let (kind, body) = &s.small[(me + k) % s.small.len()];
        submit(user, &s.apis[me % s.apis.len()], kind, body, true).await?;
    }
    Ok(())
}
