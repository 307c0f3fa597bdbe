//! Admission by memory: jobs run side by side while their estimates fit the budget, the rest
//! wait in order; a job over the budget is refused with 413 naming its field, and work over the
//! time limit with 422.

mod common;

use std::time::{Duration, Instant};

use common::bodies::seconds_bulldoze;
use common::server::{Options, TestServer};
use serde_json::{json, Value};

/// A larger job: one mound on a 513² grid (its exports need about three small jobs' memory).
fn large() -> Value {
    json!({"terrain": {"fractal": {"size": 513, "relief": 50.0}}, "operations": [
        {"primitive": {"shape": {"mound": {"center": {"x": 300, "z": 300}, "radius_m": 100, "height_m": 5}}, "operator": "add"}}
    ]})
}

async fn estimate(server: &TestServer, body: &Value) -> u64 {
    let job = server.submit("bulldoze", body).await;
    let id = job["id"].as_str().unwrap();
    server.client.post(server.url(&format!("/v1/jobs/{id}/cancel"))).json(&json!({})).send().await.unwrap();
    job["cost"]["memory_bytes"].as_u64().expect("the job shows its estimate")
}

async fn statuses(server: &TestServer, ids: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    for id in ids {
        let (_, job) = server.get_json(&format!("/v1/jobs/{id}")).await;
        out.push(job["status"].as_str().unwrap_or_default().to_string());
    }
    out
}

#[tokio::test]
async fn four_small_jobs_run_at_once_while_a_large_one_waits() {
    let probe = TestServer::start().await;
    let small = estimate(&probe, &seconds_bulldoze(1)).await;
    let big = estimate(&probe, &large()).await;
    drop(probe);
    assert!(big > 2 * small && big < 4 * small, "small {small}, large {big}: pick other sizes");
    let budget = 4 * small + small / 2;
    let server = TestServer::start_with(Options {
        extra: vec!["--memory-budget".into(), budget.to_string()],
        ..Options::default()
    })
    .await;

    let mut smalls = Vec::new();
    for seed in 0..4 {
        smalls.push(server.submit("bulldoze", &seconds_bulldoze(seed)).await["id"].as_str().unwrap().to_string());
    }
    let large_id = server.submit("bulldoze", &large()).await["id"].as_str().unwrap().to_string();
    let started = Instant::now();
    let mut seen_four = false;
    while started.elapsed() < Duration::from_secs(60) {
        let now = statuses(&server, &smalls).await;
        let large_now = statuses(&server, std::slice::from_ref(&large_id)).await.remove(0);
        if now.iter().all(|s| s == "running") {
            assert_eq!(large_now, "queued", "the large job must wait while four small ones hold the budget");
            seen_four = true;
            break;
        }
        if now.iter().any(|s| s == "succeeded") {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert!(seen_four, "four small jobs were never running at once");
    // The metrics show what the running jobs reserve.
    let metrics = server.client.get(server.url("/metrics")).send().await.unwrap().text().await.unwrap();
    let reserved: f64 = metrics
        .lines()
        .find_map(|l| l.strip_prefix("landform_memory_reserved_bytes "))
        .and_then(|v| v.trim().parse().ok())
        .expect("reserved memory in /metrics");
    assert!(reserved <= budget as f64, "{reserved} reserved over a budget of {budget}");
    assert!(metrics.contains("landform_queue_wait_seconds_count"));
    // Everything ends, the large job too.
    for id in smalls.iter().chain([&large_id]) {
        let done = server.wait_done(id).await;
        assert_eq!(done["status"], "succeeded", "{done}");
    }
}

#[tokio::test]
async fn over_the_budget_is_413_and_over_the_time_limit_is_422_each_naming_its_field() {
    let server = TestServer::start_with(Options {
        job_timeout_secs: 5,
        extra: vec!["--memory-budget".into(), (200u64 << 20).to_string()],
        ..Options::default()
    })
    .await;
    let mut huge = large();
    huge["terrain"]["fractal"]["size"] = json!(1025);
    let (status, problem) = server.post("/v1/jobs/bulldoze", &huge).await;
    assert_eq!(status, 413, "{problem}");
    assert_eq!(problem["errors"][0]["field"], "terrain");
    assert_eq!(problem["memory_budget_bytes"], 200u64 << 20);
    assert!(problem["memory_estimate_bytes"].as_u64().unwrap() > 200 << 20, "{problem}");

    // 60 000 mounds each over the whole 513² grid: far more than 5 s of work anywhere.
    let ops: Vec<Value> = (0..60_000)
        .map(|_| json!({"primitive": {"shape": {"mound": {"center": {"x": 64, "z": 64}, "radius_m": 1000, "height_m": 0.1}}, "operator": "add"}}))
        .collect();
    // Without levels of detail, whose memory would be over this small budget first.
    let body = json!({"terrain": {"fractal": {"size": 513}}, "operations": ops, "lods": []});
    let (status, problem) = server.post("/v1/jobs/bulldoze", &body).await;
    assert_eq!(status, 422, "{problem}");
    assert_eq!(problem["errors"][0]["field"], "operations");
    assert_eq!(problem["time_limit_seconds"], 5);
}
