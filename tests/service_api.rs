//! The HTTP contract around jobs: waiting, idempotency, listing, caching, cancelling, the queue
//! bound, operations endpoints, and the committed OpenAPI document.

mod common;

use common::bodies::{slow_bulldoze, small_bulldoze};
use common::server::{Options, TestServer};
use common::sse::read_events;
use serde_json::json;

#[tokio::test]
async fn prefer_wait_holds_the_answer_until_the_job_ends() {
    let server = TestServer::start().await;
    let res = server
        .client
        .post(server.url("/v1/jobs/bulldoze"))
        .header("prefer", "wait=60")
        .json(&small_bulldoze())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    assert_eq!(res.headers()["preference-applied"], "wait=60");
    let location = res.headers()["location"].to_str().unwrap().to_string();
    let job: serde_json::Value = res.json().await.unwrap();
    assert_eq!(job["status"], "succeeded");
    assert_eq!(location, format!("/v1/jobs/{}", job["id"].as_str().unwrap()));

    // A job that can't end in a second comes back 202 after the wait.
    let (status, job) = server.submit_waiting("bulldoze", &slow_bulldoze(), 1).await;
    assert_eq!(status, 202);
    assert!(matches!(job["status"].as_str(), Some("queued" | "running")), "{job}");
}

#[tokio::test]
async fn an_idempotency_key_returns_the_same_job_and_refuses_another_body() {
    let server = TestServer::start().await;
    let send = |body: serde_json::Value| {
        server.client.post(server.url("/v1/jobs/bulldoze")).header("idempotency-key", "k-1").json(&body).send()
    };
    let first = send(slow_bulldoze()).await.unwrap();
    assert_eq!(first.status(), 202);
    let first: serde_json::Value = first.json().await.unwrap();
    // A retry while the job still runs: the same job, still 202.
    let second = send(slow_bulldoze()).await.unwrap();
    assert_eq!(second.status(), 202);
    assert_eq!(second.headers()["idempotent-replayed"], "true");
    let second: serde_json::Value = second.json().await.unwrap();
    assert_eq!(first["id"], second["id"]);

    let mut other = slow_bulldoze();
    other["label"] = json!("something else");
    let third = send(other).await.unwrap();
    assert_eq!(third.status(), 409);
    assert_eq!(third.headers()["content-type"], "application/problem+json");

    // Once it has ended, a retry answers 200 with the finished job.
    let id = first["id"].as_str().unwrap();
    server.post(&format!("/v1/jobs/{id}/cancel"), &json!({})).await;
    server.wait_done(id).await;
    let fourth = send(slow_bulldoze()).await.unwrap();
    assert_eq!(fourth.status(), 200);
    let (_, page) = server.get_json("/v1/jobs").await;
    assert_eq!(page["items"].as_array().unwrap().len(), 1, "one job for one key");
}

#[tokio::test]
async fn the_list_pages_newest_first_with_a_cursor_and_filters() {
    let server = TestServer::start().await;
    let mut ids = Vec::new();
    for i in 0..3 {
        let mut body = small_bulldoze();
        body["label"] = json!(format!("job {i}"));
        ids.push(server.run("bulldoze", &body).await["id"].as_str().unwrap().to_string());
    }
    let (status, page) = server.get_json("/v1/jobs?limit=2").await;
    assert_eq!(status, 200);
    let got: Vec<&str> = page["items"].as_array().unwrap().iter().map(|j| j["id"].as_str().unwrap()).collect();
    assert_eq!(got, vec![ids[2].as_str(), ids[1].as_str()]);
    let cursor = page["next_cursor"].as_str().expect("a next cursor");
    let (_, page2) = server.get_json(&format!("/v1/jobs?limit=2&cursor={cursor}")).await;
    let got2: Vec<&str> = page2["items"].as_array().unwrap().iter().map(|j| j["id"].as_str().unwrap()).collect();
    assert_eq!(got2, vec![ids[0].as_str()]);
    assert!(page2["next_cursor"].is_null());

    let (_, filtered) = server.get_json("/v1/jobs?kind=bulldoze&status=failed").await;
    assert_eq!(filtered["items"].as_array().unwrap().len(), 0);
    let (status, bad) = server.get_json("/v1/jobs?status=done").await;
    assert_eq!(status, 422);
    assert_eq!(bad["errors"][0]["field"], "status");
}

#[tokio::test]
async fn artifacts_are_immutable_with_their_sha256_as_etag() {
    let server = TestServer::start().await;
    let job = server.run("bulldoze", &small_bulldoze()).await;
    let id = job["id"].as_str().unwrap();
    let meta = job["artifacts"].as_array().unwrap().iter().find(|a| a["name"] == "preview.png").unwrap();
    let res = server.client.get(server.url(meta["href"].as_str().unwrap())).send().await.unwrap();
    assert_eq!(res.status(), 200);
    assert_eq!(res.headers()["content-type"], "image/png");
    assert_eq!(res.headers()["cache-control"], "public, max-age=31536000, immutable");
    let etag = res.headers()["etag"].to_str().unwrap().to_string();
    assert_eq!(etag, format!("\"{}\"", meta["sha256"].as_str().unwrap()));
    let bytes = res.bytes().await.unwrap();
    assert_eq!(bytes.len() as u64, meta["bytes"].as_u64().unwrap());
    use sha2::Digest;
    assert_eq!(hex::encode(sha2::Sha256::digest(&bytes)), meta["sha256"].as_str().unwrap());

    let res = server.client.get(server.url(meta["href"].as_str().unwrap())).header("if-none-match", &etag).send().await;
    assert_eq!(res.unwrap().status(), 304);
    let glb = server.client.get(server.url(&format!("/v1/jobs/{id}/artifacts/mesh.glb"))).send().await.unwrap();
    assert_eq!(glb.headers()["content-type"], "model/gltf-binary");
    let missing = server.client.get(server.url(&format!("/v1/jobs/{id}/artifacts/nope.bin"))).send().await.unwrap();
    assert_eq!(missing.status(), 404);
    assert_eq!(missing.headers()["content-type"], "application/problem+json");
}

#[tokio::test]
async fn cancel_stops_a_running_job_and_a_finished_one_answers_409() {
    let server = TestServer::start().await;
    let job = server.submit("bulldoze", &slow_bulldoze()).await;
    let id = job["id"].as_str().unwrap();
    let (status, after) = server.post(&format!("/v1/jobs/{id}/cancel"), &json!({})).await;
    assert_eq!(status, 200, "{after}");
    let done = server.wait_done(id).await;
    assert_eq!(done["status"], "cancelled", "{done}");
    assert!(done["artifacts"].as_array().unwrap().is_empty());
    let (status, problem) = server.post(&format!("/v1/jobs/{id}/cancel"), &json!({})).await;
    assert_eq!(status, 409, "{problem}");
}

#[tokio::test]
async fn a_full_queue_answers_503_with_retry_after() {
    let server = TestServer::start_with(Options {
        queue_capacity: 1,
        workers: 1,
        extra: vec!["--concurrent-jobs".into(), "1".into()],
        ..Options::default()
    })
    .await;
    let mut statuses = Vec::new();
    let mut retry_after = None;
    for _ in 0..4 {
        let res = server.client.post(server.url("/v1/jobs/bulldoze")).json(&slow_bulldoze()).send().await.unwrap();
        if res.status() == 503 {
            retry_after = res.headers().get("retry-after").map(|v| v.to_str().unwrap().to_string());
            let p: serde_json::Value = res.json().await.unwrap();
            assert_eq!(p["status"], 503);
            statuses.push(503);
        } else {
            statuses.push(res.status().as_u16());
        }
    }
    assert!(statuses.contains(&503), "{statuses:?}");
    assert!(retry_after.is_some_and(|s| s.parse::<u64>().is_ok()));
    // Nothing already accepted was lost: cancel them all and see them end.
    let (_, page) = server.get_json("/v1/jobs").await;
    let accepted = page["items"].as_array().unwrap().clone();
    assert_eq!(accepted.len(), statuses.iter().filter(|&&s| s == 202).count());
    for j in accepted {
        let id = j["id"].as_str().unwrap();
        server.post(&format!("/v1/jobs/{id}/cancel"), &json!({})).await;
        assert_eq!(server.wait_done(id).await["status"], "cancelled");
    }
}

#[tokio::test]
async fn events_resume_after_last_event_id_and_live_png_shows_the_run() {
    let server = TestServer::start().await;
    let job = server.submit("bulldoze", &slow_bulldoze()).await;
    let id = job["id"].as_str().unwrap();
    let url = server.url(&format!("/v1/jobs/{id}/events"));
    let first = read_events(&server.client, &url, None, 3).await;
    assert_eq!(first.len(), 3);
    let last = first.last().unwrap().id.unwrap();
    // The first snapshot comes a quarter second into the steps.
    let started = std::time::Instant::now();
    let png = loop {
        let png = server.client.get(server.url(&format!("/v1/jobs/{id}/live.png"))).send().await.unwrap();
        if png.status() == 200 || started.elapsed() > std::time::Duration::from_secs(60) {
            break png;
        }
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    };
    assert_eq!(png.status(), 200, "a live snapshot is there once the job has run a while");
    assert_eq!(png.headers()["content-type"], "image/png");
    let rest = read_events(&server.client, &url, Some(last), 100_000).await;
    assert!(rest.iter().all(|e| e.id.unwrap() > last), "only what was missed");
    assert_eq!(rest.last().unwrap().event, "done");
    assert!(
        first.iter().chain(&rest).any(|e| e.data.get("snapshot").and_then(|s| s.as_str()).is_some()),
        "a progress event announces the snapshot"
    );
}

#[tokio::test]
async fn delete_removes_the_job_and_its_artifacts() {
    let server = TestServer::start().await;
    let job = server.run("bulldoze", &small_bulldoze()).await;
    let id = job["id"].as_str().unwrap();
    let res = server.client.delete(server.url(&format!("/v1/jobs/{id}"))).send().await.unwrap();
    assert_eq!(res.status(), 204);
    let (status, _) = server.get_json(&format!("/v1/jobs/{id}")).await;
    assert_eq!(status, 404);
    let res = server.client.get(server.url(&format!("/v1/jobs/{id}/artifacts/mesh.glb"))).send().await.unwrap();
    assert_eq!(res.status(), 404);
    let res = server.client.delete(server.url(&format!("/v1/jobs/{id}"))).send().await.unwrap();
    assert_eq!(res.status(), 404);
}

#[tokio::test]
async fn operations_endpoints_answer() {
    let server = TestServer::start().await;
    server.run("bulldoze", &small_bulldoze()).await;
    assert_eq!(server.get_json("/healthz").await.0, 200);
    assert_eq!(server.get_json("/readyz").await.0, 200);
    let metrics = server.client.get(server.url("/metrics")).send().await.unwrap().text().await.unwrap();
    assert!(metrics.contains(r#"landform_jobs{kind="bulldoze",status="succeeded"} 1"#), "{metrics}");
    assert!(metrics.contains("landform_queue_depth 0"));
    assert!(metrics.contains("landform_job_duration_seconds_bucket"));
    let (status, spec) = server.get_json("/openapi.json").await;
    assert_eq!(status, 200);
    assert!(spec["paths"]["/v1/jobs/bulldoze"]["post"].is_object());
    let docs = server.client.get(server.url("/docs/")).send().await.unwrap();
    assert_eq!(docs.status(), 200);
    assert!(docs.text().await.unwrap().contains("swagger"));
    // CORS is closed by default: another origin's page gets no permission to read.
    let cors = server.client.get(server.url("/healthz")).header("origin", "http://example.test").send().await.unwrap();
    assert!(cors.headers().get("access-control-allow-origin").is_none(), "{:?}", cors.headers());
}

#[tokio::test]
async fn cors_opens_for_the_origins_a_flag_lists() {
    let server = TestServer::start_with(Options {
        extra: vec!["--cors-origins".into(), "http://tool.example".into()],
        ..Options::default()
    })
    .await;
    let get = |origin: &'static str| server.client.get(server.url("/v1/jobs")).header("origin", origin).send();
    let allowed = get("http://tool.example").await.unwrap();
    assert_eq!(allowed.headers()["access-control-allow-origin"], "http://tool.example");
    let other = get("http://other.example").await.unwrap();
    assert!(other.headers().get("access-control-allow-origin").is_none());
    // The listed origin may submit; another may not, whatever it sends.
    let post = |origin: &'static str| {
        server.client.post(server.url("/v1/jobs/bulldoze")).header("origin", origin).json(&small_bulldoze()).send()
    };
    assert_eq!(post("http://tool.example").await.unwrap().status(), 202);
    assert_eq!(post("http://other.example").await.unwrap().status(), 403);
}

#[test]
fn the_committed_openapi_yaml_is_what_the_binary_prints() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_landform")).arg("openapi").output().unwrap();
    assert!(out.status.success());
    let committed = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/openapi.yaml")).unwrap();
    assert!(
        String::from_utf8(out.stdout).unwrap() == committed,
        "openapi.yaml is stale: run `cargo run -- openapi > openapi.yaml`"
    );
}

#[tokio::test]
async fn a_job_over_the_time_limit_fails() {
    // The estimate admits it (its least time is under the limit) but the run takes longer.
    let server = TestServer::start_with(Options { job_timeout_secs: 2, ..Options::default() }).await;
    // Without levels of detail, whose least time alone would be over this short limit.
    let mut body = slow_bulldoze();
    body["lods"] = serde_json::json!([]);
    let job = server.submit("bulldoze", &body).await;
    let done = server.wait_done(job["id"].as_str().unwrap()).await;
    assert_eq!(done["status"], "failed");
    assert!(done["error"]["detail"].as_str().unwrap().contains("longer than"), "{done}");
}

#[tokio::test]
async fn errors_outside_the_job_routes_are_problems_too() {
    let server = TestServer::start().await;
    let res = server.client.put(server.url("/v1/jobs")).send().await.unwrap();
    assert_eq!(res.status(), 405);
    assert_eq!(res.headers()["content-type"], "application/problem+json");
    let res = server.client.get(server.url("/nowhere")).send().await.unwrap();
    assert_eq!(res.status(), 404);
    assert_eq!(res.headers()["content-type"], "application/problem+json");
    // Not a number, or no number at all (`limit=`: the schema says integer).
    for bad in ["lots", ""] {
        let (status, p) = server.get_json(&format!("/v1/jobs?limit={bad}")).await;
        assert_eq!(status, 422, "limit={bad}");
        assert_eq!(p["errors"][0]["field"], "limit");
    }
    // The largest event id the schema allows (19 digits) reaches the job lookup; 20 digits
    // (u64::MAX among them) are not an event id, as the schema's pattern says.
    let events = |last: String| {
        server
            .client
            .get(server.url("/v1/jobs/01920000-0000-7000-8000-000000000000/events"))
            .header("last-event-id", last)
            .send()
    };
    assert_eq!(events("9".repeat(19)).await.unwrap().status(), 404);
    let res = events(u64::MAX.to_string()).await.unwrap();
    assert_eq!(res.status(), 400);
    assert_eq!(res.headers()["content-type"], "application/problem+json");
}

#[tokio::test]
async fn artifacts_serve_byte_ranges() {
    let server = TestServer::start().await;
    let job = server.run("bulldoze", &common::bodies::small_bulldoze()).await;
    let id = job["id"].as_str().unwrap();
    let whole = server.artifact(id, "mesh.glb").await;
    let get = |range: &'static str| {
        server.client.get(server.url(&format!("/v1/jobs/{id}/artifacts/mesh.glb"))).header("range", range).send()
    };
    let res = get("bytes=0-3").await.unwrap();
    assert_eq!(res.status(), 206);
    assert_eq!(res.headers()["content-range"], format!("bytes 0-3/{}", whole.len()));
    assert_eq!(res.headers()["accept-ranges"], "bytes");
    assert_eq!(&res.bytes().await.unwrap()[..], b"glTF");
    let res = get("bytes=-10").await.unwrap();
    assert_eq!(res.status(), 206);
    assert_eq!(res.bytes().await.unwrap(), whole[whole.len() - 10..]);
    let res = get("bytes=100-").await.unwrap();
    assert_eq!(res.bytes().await.unwrap(), whole[100..]);
    let past = format!("bytes={}-", whole.len());
    let res = server
        .client
        .get(server.url(&format!("/v1/jobs/{id}/artifacts/mesh.glb")))
        .header("range", past)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 416);
    assert_eq!(res.headers()["content-range"], format!("bytes */{}", whole.len()));
    // Several ranges, or another unit: the whole artifact.
    let res = get("bytes=0-1,5-6").await.unwrap();
    assert_eq!(res.status(), 200);
    assert_eq!(res.bytes().await.unwrap().len(), whole.len());
}
