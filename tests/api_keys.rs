//! API keys against the real binary: every /v1 call needs a known key, a job is visible to the
//! key that made it only (404 to any other on every endpoint), and per-key quotas answer 429
//! with Retry-After.

mod common;

use std::time::Duration;

use common::bodies::{slow_bulldoze, small_bulldoze};
use common::server::{Options, TestServer};
use reqwest::Method;
use serde_json::{json, Value};

const ALICE: &str = "alice-key-0123456789abcdef";
const BOB: &str = "bob-key-0123456789abcdef01";
const CAROL: &str = "carol-key-0123456789abcdef";
const DAVE: &str = "dave-key-0123456789abcdef0";

/// A server with four keys: carol may submit twice a minute, dave hold one job at a time.
async fn server_with_keys(extra: &[&str]) -> (TestServer, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let keys = dir.path().join("keys");
    std::fs::write(
        &keys,
        format!(
            "# name key [limits]\nalice {ALICE}\nbob {BOB}\ncarol {CAROL} submissions_per_minute=2\ndave {DAVE} active_jobs=1\n"
        ),
    )
    .unwrap();
    let mut args = vec!["--api-keys".to_string(), keys.to_str().unwrap().to_string()];
    args.extend(extra.iter().map(|s| s.to_string()));
    (TestServer::start_with(Options { extra: args, ..Options::default() }).await, dir)
}

async fn call(
    server: &TestServer,
    method: Method,
    path: &str,
    key: Option<&str>,
    body: Option<&Value>,
) -> (u16, Value, reqwest::header::HeaderMap) {
    let mut req = server.client.request(method, server.url(path));
    if let Some(k) = key {
        req = req.bearer_auth(k);
    }
    if let Some(b) = body {
        req = req.json(b);
    }
    let res = req.send().await.expect("request");
    let status = res.status().as_u16();
    let headers = res.headers().clone();
    let bytes = res.bytes().await.unwrap_or_default();
    (status, serde_json::from_slice(&bytes).unwrap_or(Value::Null), headers)
}

async fn finished_job(server: &TestServer, key: &str) -> String {
    let res = server
        .client
        .post(server.url("/v1/jobs/bulldoze"))
        .bearer_auth(key)
        .header("prefer", "wait=60")
        .json(&small_bulldoze())
        .send()
        .await
        .unwrap();
    let job: Value = res.json().await.unwrap();
    assert_eq!(job["status"], "succeeded", "{job}");
    job["id"].as_str().unwrap().to_string()
}

#[tokio::test]
async fn without_a_known_key_every_v1_call_and_the_metrics_are_401_and_health_and_docs_stay_open() {
    let (server, _dir) = server_with_keys(&[]).await;
    for key in [None, Some("not-a-key-0123456789abcdef")] {
        for (method, path) in [
            (Method::GET, "/v1/jobs"),
            (Method::POST, "/v1/jobs/bulldoze"),
            (Method::GET, "/v1/jobs/01920000-0000-7000-8000-000000000000"),
        ] {
            let (status, problem, headers) = call(&server, method, path, key, Some(&small_bulldoze())).await;
            assert_eq!(status, 401, "{path}: {problem}");
            assert_eq!(headers["www-authenticate"], "Bearer realm=\"landform\"");
            assert_eq!(headers["content-type"], "application/problem+json");
        }
    }
    for path in ["/healthz", "/readyz", "/openapi.json"] {
        let (status, _, _) = call(&server, Method::GET, path, None, None).await;
        assert_eq!(status, 200, "{path}");
    }
    // The metrics count every key's jobs: with keys they need one.
    assert_eq!(call(&server, Method::GET, "/metrics", None, None).await.0, 401);
    assert_eq!(call(&server, Method::GET, "/metrics", Some(ALICE), None).await.0, 200);
}

#[tokio::test]
async fn the_metrics_can_be_opened_for_a_scraper() {
    let (server, _dir) = server_with_keys(&["--public-metrics"]).await;
    assert_eq!(call(&server, Method::GET, "/metrics", None, None).await.0, 200);
    assert_eq!(call(&server, Method::GET, "/v1/jobs", None, None).await.0, 401);
}

#[tokio::test]
async fn operations_can_be_put_behind_a_key() {
    let (server, _dir) = server_with_keys(&["--protect-operations"]).await;
    for path in ["/metrics", "/openapi.json"] {
        assert_eq!(call(&server, Method::GET, path, None, None).await.0, 401, "{path}");
        assert_eq!(call(&server, Method::GET, path, Some(ALICE), None).await.0, 200, "{path}");
    }
    assert_eq!(call(&server, Method::GET, "/healthz", None, None).await.0, 200);
}

#[tokio::test]
async fn another_keys_job_is_not_there_on_any_endpoint() {
    let (server, _dir) = server_with_keys(&[]).await;
    let id = finished_job(&server, ALICE).await;
    let replay = json!({});
    // (method, path, body, status for the owner). Delete goes last.
    let table: Vec<(Method, String, Option<&Value>, u16)> = vec![
        (Method::GET, format!("/v1/jobs/{id}"), None, 200),
        (Method::GET, format!("/v1/jobs/{id}/events"), None, 200),
        (Method::GET, format!("/v1/jobs/{id}/live.png"), None, 200),
        (Method::GET, format!("/v1/jobs/{id}/artifacts/mesh.glb"), None, 200),
        (Method::GET, format!("/v1/jobs/{id}/artifacts/heightmap.png"), None, 200),
        (Method::GET, format!("/v1/jobs/{id}/sequence"), None, 200),
        (Method::POST, format!("/v1/jobs/{id}/replay"), Some(&replay), 202),
        (Method::POST, format!("/v1/jobs/{id}/cancel"), Some(&replay), 409),
        (Method::DELETE, format!("/v1/jobs/{id}"), None, 204),
    ];
    for (method, path, body, owner_status) in &table {
        let (status, problem, headers) = call(&server, method.clone(), path, Some(BOB), *body).await;
        assert_eq!(status, 404, "bob {method} {path}: {problem}");
        assert_eq!(headers["content-type"], "application/problem+json", "{path}");
        // The same answer as for a job that never existed.
        let never = path.replace(&id, "01920000-0000-7000-8000-000000000000");
        let (never_status, never_problem, _) = call(&server, method.clone(), &never, Some(BOB), *body).await;
        assert_eq!(never_status, 404, "{never}");
        assert_eq!(problem["title"], never_problem["title"]);
        let (status, body, _) = call(&server, method.clone(), path, Some(ALICE), *body).await;
        assert_eq!(status, *owner_status, "alice {method} {path}: {body}");
    }
}

#[tokio::test]
async fn lists_sources_and_idempotency_keys_are_per_key() {
    let (server, _dir) = server_with_keys(&[]).await;
    let id = finished_job(&server, ALICE).await;
    let (_, alices, _) = call(&server, Method::GET, "/v1/jobs", Some(ALICE), None).await;
    let (_, bobs, _) = call(&server, Method::GET, "/v1/jobs", Some(BOB), None).await;
    let ids = |page: &Value| -> Vec<String> {
        page["items"].as_array().unwrap().iter().map(|j| j["id"].as_str().unwrap().to_string()).collect()
    };
    assert_eq!(ids(&alices), vec![id.clone()]);
    assert!(ids(&bobs).is_empty(), "{bobs}");

    // Bob cannot start from Alice's terrain: to him it does not exist.
    let on_alices = json!({"terrain": {"job": id}, "operations": []});
    let (status, problem, _) = call(&server, Method::POST, "/v1/jobs/bulldoze", Some(BOB), Some(&on_alices)).await;
    assert_eq!(status, 422, "{problem}");
    assert_eq!(problem["errors"][0]["field"], "terrain.job");
    assert!(problem["errors"][0]["message"].as_str().unwrap().contains("no job with id"), "{problem}");
    let (status, _, _) = call(&server, Method::POST, "/v1/jobs/bulldoze", Some(ALICE), Some(&on_alices)).await;
    assert_eq!(status, 202);

    // One Idempotency-Key used by both: each gets a job of their own.
    let submit = |key: &'static str| {
        server
            .client
            .post(server.url("/v1/jobs/bulldoze"))
            .bearer_auth(key)
            .header("idempotency-key", "same-key")
            .json(&small_bulldoze())
            .send()
    };
    let a: Value = submit(ALICE).await.unwrap().json().await.unwrap();
    let b: Value = submit(BOB).await.unwrap().json().await.unwrap();
    assert_ne!(a["id"], b["id"]);
    let again: Value = submit(BOB).await.unwrap().json().await.unwrap();
    assert_eq!(again["id"], b["id"]);
}

#[tokio::test]
async fn quotas_answer_429_with_retry_after() {
    let (server, _dir) = server_with_keys(&[]).await;
    // Carol: two submissions a minute (replays count too).
    let mut statuses = Vec::new();
    let mut retry = None;
    for _ in 0..3 {
        let (status, _, headers) =
            call(&server, Method::POST, "/v1/jobs/bulldoze", Some(CAROL), Some(&small_bulldoze())).await;
        statuses.push(status);
        if status == 429 {
            retry = headers.get("retry-after").and_then(|v| v.to_str().ok()).and_then(|v| v.parse::<u64>().ok());
        }
    }
    assert_eq!(statuses, [202, 202, 429]);
    assert!(retry.is_some_and(|s| (1..=60).contains(&s)), "{retry:?}");
    // Alice is not slowed by Carol.
    assert_eq!(call(&server, Method::POST, "/v1/jobs/bulldoze", Some(ALICE), Some(&small_bulldoze())).await.0, 202);

    // Dave: one job queued or running at once.
    let (status, job, _) = call(&server, Method::POST, "/v1/jobs/bulldoze", Some(DAVE), Some(&slow_bulldoze())).await;
    assert_eq!(status, 202, "{job}");
    let (status, problem, headers) =
        call(&server, Method::POST, "/v1/jobs/bulldoze", Some(DAVE), Some(&small_bulldoze())).await;
    assert_eq!(status, 429, "{problem}");
    assert!(headers.contains_key("retry-after"));
    assert_eq!(problem["status"], 429);
    let id = job["id"].as_str().unwrap();
    call(&server, Method::POST, &format!("/v1/jobs/{id}/cancel"), Some(DAVE), Some(&json!({}))).await;
    // Once it has ended, Dave may submit again.
    let started = std::time::Instant::now();
    loop {
        let (status, _, _) =
            call(&server, Method::POST, "/v1/jobs/bulldoze", Some(DAVE), Some(&small_bulldoze())).await;
        if status == 202 {
            break;
        }
        assert!(started.elapsed() < Duration::from_secs(30), "dave still refused");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}
