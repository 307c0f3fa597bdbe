//! The Rust client (`clients/rust`, `landform-client`) against the real binary: typed requests
//! (the server's own parameter types), a job followed to its end, its events resumed after an
//! id, artifacts streamed, replay, cancel, problem+json as a typed error, API keys, idempotency
//! keys, presets, and every route it calls present in the server's OpenAPI document.

mod common;

use common::bodies::{seconds_bulldoze, small_bulldoze};
use common::server::{Options, TestServer};
use landform_client::{BulldozeParams, Client, Error, JobStatus, Request, Submit, ROUTES};
use serde_json::{json, Value};
use sha2::{Digest, Sha256};

fn typed(body: Value) -> BulldozeParams {
    serde_json::from_value(body).expect("the test body is a bulldoze request")
}

#[tokio::test]
async fn a_typed_job_is_followed_to_its_end_and_its_artifacts_streamed() {
    let server = TestServer::start().await;
    let client = Client::new(&server.base).unwrap();
    let job = client.submit(&Request::new(typed(small_bulldoze())).seed(9).label("client test")).await.unwrap();
    assert_eq!(job.document().kind, "bulldoze");
    let done = job.wait().await.unwrap();
    assert_eq!(done.status, JobStatus::Succeeded);
    assert_eq!(done.request["seed"], 9, "the common fields are sent beside the parameters");
    assert_eq!(done.label.as_deref(), Some("client test"));

    // Every artifact's bytes, streamed, match the sha256 the job lists (read independently of
    // the client's types: the hash is computed here).
    for meta in &done.artifacts {
        let bytes = job.artifact_bytes(&meta.name).await.unwrap();
        assert_eq!(bytes.len() as u64, meta.bytes, "{}", meta.name);
        assert_eq!(hex(&Sha256::digest(&bytes)), meta.sha256, "{}", meta.name);
    }
    let glb = job.artifact_bytes("mesh.glb").await.unwrap();
    assert_eq!(&glb[..4], b"glTF");
    let dir = tempfile::tempdir().unwrap();
    let written = job.download("mesh.glb", dir.path().join("m.glb")).await.unwrap();
    assert_eq!(std::fs::read(dir.path().join("m.glb")).unwrap(), glb);
    assert_eq!(written, glb.len() as u64);

    // A missing artifact is a typed 404.
    let err = job.artifact_bytes("nope.glb").await.unwrap_err();
    assert_eq!(err.problem().map(|p| p.status), Some(404), "{err}");
}

#[tokio::test]
async fn events_run_to_done_and_resume_after_an_id_without_repeating() {
    let server = TestServer::start().await;
    let client = Client::new(&server.base).unwrap();
    let job = client.submit_json("bulldoze", &seconds_bulldoze(1), &Submit::default()).await.unwrap();
    let mut all = Vec::new();
    let mut events = job.events(None);
    while let Some(e) = events.next().await {
        all.push(e.unwrap());
    }
    assert_eq!(all.last().unwrap().event, "done");
    assert!(all.iter().any(|e| e.event == "progress"), "{all:?}");
    let done = all.last().unwrap().json().unwrap();
    assert_eq!(done["status"], "succeeded");
    // Resumed after the first event: only later ids, ending with `done`.
    let first: u64 = all[0].id.as_deref().unwrap().parse().unwrap();
    let mut resumed = Vec::new();
    let mut events = job.events(Some(first.to_string()));
    while let Some(e) = events.next().await {
        resumed.push(e.unwrap());
    }
    assert_eq!(resumed.last().unwrap().event, "done");
    assert!(resumed.iter().filter_map(|e| e.id.as_deref()).all(|id| id.parse::<u64>().unwrap() > first), "{resumed:?}");
}

#[tokio::test]
async fn replay_cancel_and_problems_are_typed() {
    let server = TestServer::start().await;
    let client = Client::new(&server.base).unwrap();
    let job = client.submit(&Request::new(typed(small_bulldoze()))).await.unwrap();
    let done = job.wait().await.unwrap();
    let whole = job.replay(None).await.unwrap().wait().await.unwrap();
    let hashes = |d: &landform_client::JobDocument| {
        let mut v: Vec<_> = d.artifacts.iter().map(|a| (a.name.clone(), a.sha256.clone())).collect();
        v.sort();
        v
    };
    assert_eq!(hashes(&whole), hashes(&done), "a whole replay makes the same bytes");
    let part = job.replay(Some(1)).await.unwrap().wait().await.unwrap();
    assert_eq!(part.replay_of.as_deref(), Some(job.id()));
    let err = job.replay(Some(1_000_000)).await.unwrap_err();
    let problem = err.problem().expect("a problem");
    assert_eq!((problem.status, problem.fields()), (422, vec!["until_step"]), "{err}");

    // A bad field: a 422 naming it.
    let err = client
        .submit_json("bulldoze", &json!({"terrain": {"fractal": {"size": 1}}, "operations": []}), &Submit::default())
        .await
        .unwrap_err();
    let problem = err.problem().expect("a problem");
    assert_eq!(problem.status, 422);
    assert!(problem.fields().contains(&"terrain.fractal.size"), "{problem:?}");

    // Cancel a running job: wait() answers Ended with the cancelled document.
    let mut slow = client.submit_json("bulldoze", &seconds_bulldoze(2), &Submit::default()).await.unwrap();
    let after = slow.cancel().await.unwrap();
    assert!(
        matches!(after.status, JobStatus::Cancelled | JobStatus::Running | JobStatus::Queued),
        "{:?}",
        after.status
    );
    match slow.wait().await {
        Err(Error::Ended(doc)) => assert_eq!(doc.status, JobStatus::Cancelled),
        other => panic!("a cancelled job's wait: {other:?}"),
    }
    let err = slow.cancel().await.unwrap_err();
    assert_eq!(err.problem().map(|p| p.status), Some(409), "{err}");
    slow.delete().await.unwrap();
}

#[tokio::test]
async fn keys_idempotency_and_presets() {
    let dir = tempfile::tempdir().unwrap();
    let keys = dir.path().join("keys");
    std::fs::write(&keys, "ann k-ann-0123456789abcdef\n").unwrap();
    let options = Options { extra: vec!["--api-keys".into(), keys.to_str().unwrap().into()], ..Options::default() };
    let server = TestServer::start_with(options).await;

    let anonymous = Client::new(&server.base).unwrap();
    let err = anonymous.presets(None).await.unwrap_err();
    assert_eq!(err.problem().map(|p| p.status), Some(401), "{err}");

    let client = Client::new(&server.base).unwrap().with_api_key("k-ann-0123456789abcdef");
    let presets = client.presets(Some("bulldoze")).await.unwrap();
    assert!(presets.len() >= 5 && presets.iter().all(|p| p.kind == "bulldoze"), "{presets:?}");
    let mut ziggurat = client.preset::<BulldozeParams>("ziggurat").await.unwrap();
    ziggurat.terrain = typed(small_bulldoze()).terrain;

    let how = Submit { idempotency_key: Some("zig-1".into()), wait_s: Some(60) };
    let request = Request::new(ziggurat).seed(3);
    let first = client.submit_with(&request, &how).await.unwrap();
    let again = client.submit_with(&request, &how).await.unwrap();
    assert_eq!(first.id(), again.id(), "the same key and body give the same job");
    assert_eq!(again.document().status, JobStatus::Succeeded, "Prefer: wait held the answer to the end");
    let err = client.submit_with(&request.clone().seed(4), &how).await.unwrap_err();
    assert_eq!(err.problem().map(|p| p.status), Some(409), "{err}");
}

#[tokio::test]
async fn every_route_the_client_calls_is_in_the_servers_document() {
    let server = TestServer::start().await;
    let doc: Value = server.client.get(server.url("/openapi.json")).send().await.unwrap().json().await.unwrap();
    for (method, path) in ROUTES {
        // The document names the submit route per kind and the artifact's name `{name}`.
        let paths: Vec<String> = if path.contains("{kind}") {
            ["bulldoze", "carve-coast", "deform-terrain", "erode", "grow-cave", "weather-column"]
                .iter()
                .map(|k| path.replace("{kind}", k))
                .collect()
        } else {
            vec![path.to_string()]
        };
        for p in paths {
            assert!(doc["paths"][&p][method].is_object(), "{method} {p} is not in the server's document");
        }
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
