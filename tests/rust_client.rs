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

/// A proxy to `target` that cuts its first `cuts` event streams after `after` bytes from the
/// server, as a dropped network does (other calls pass whole); with the count of event streams
/// it carried.
async fn cutting_proxy(
    target: String,
    cuts: usize,
    after: usize,
) -> (String, std::sync::Arc<std::sync::atomic::AtomicUsize>) {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let target = target.trim_start_matches("http://").to_string();
    let cut = Arc::new(AtomicUsize::new(0));
    let count = cut.clone();
    tokio::spawn(async move {
        loop {
            let Ok((mut client, _)) = listener.accept().await else { return };
            let mut server = tokio::net::TcpStream::connect(&target).await.unwrap();
            let cut = cut.clone();
            tokio::spawn(async move {
                let (mut cr, mut cw) = client.split();
                let (mut sr, mut sw) = server.split();
                let mut first = [0u8; 4096];
                let Ok(k) = cr.read(&mut first).await else { return };
                let events = first[..k].windows(7).any(|w| w == b"/events");
                let limit = if events && cut.fetch_add(1, Ordering::SeqCst) < cuts { after } else { usize::MAX };
                if sw.write_all(&first[..k]).await.is_err() {
                    return;
                }
                let up = tokio::io::copy(&mut cr, &mut sw);
                let down = async {
                    let mut sent = 0;
                    let mut buf = [0u8; 512];
                    while sent < limit {
                        let k = match sr.read(&mut buf).await {
                            Ok(0) | Err(_) => break,
                            Ok(k) => k.min(limit - sent),
                        };
                        if cw.write_all(&buf[..k]).await.is_err() {
                            break;
                        }
                        sent += k;
                    }
                };
                tokio::select! { _ = up => {}, _ = down => {} }
            });
        }
    });
    (format!("http://{addr}"), count)
}

#[tokio::test]
async fn a_dropped_event_stream_resumes_where_it_was_cut_without_a_repeat() {
    let server = TestServer::start().await;
    let job = server.lf.submit_json("bulldoze", &seconds_bulldoze(3), &Submit::default()).await.unwrap();
    // Read as it runs, directly and through a proxy that cuts the first three streams mid-way.
    let (proxy, cuts) = cutting_proxy(server.base.clone(), 3, 700).await;
    // A connection a call (no pooling: the proxy looks at each connection's first request).
    let http = reqwest::Client::builder().pool_max_idle_per_host(0).build().unwrap();
    let proxied = Client::with_http(http, proxy).job(job.id()).await.unwrap();
    let read = |events: landform_client::Events| async move {
        let mut events = events;
        let mut got = Vec::new();
        while let Some(e) = events.next().await {
            got.push(e.unwrap());
        }
        got
    };
    let (direct, cut) = tokio::join!(read(job.events(None)), read(proxied.events(None)));
    assert!(cuts.load(std::sync::atomic::Ordering::SeqCst) > 3, "the proxy cut three streams");
    let ids =
        |v: &[landform_client::Event]| -> Vec<u64> { v.iter().filter_map(|e| e.id.as_deref()?.parse().ok()).collect() };
    let (direct_ids, cut_ids) = (ids(&direct), ids(&cut));
    assert_eq!(cut.last().unwrap().event, "done", "{cut:?}");
    assert!(cut_ids.windows(2).all(|w| w[0] < w[1]), "no event twice: {cut_ids:?}");
    assert!(cut.iter().filter(|e| e.event == "progress").count() > 1, "{cut:?}");
    let progress = |v: &[landform_client::Event]| -> Vec<u64> {
        v.iter().filter(|e| e.event == "progress").filter_map(|e| e.id.as_deref()?.parse().ok()).collect()
    };
    // Every progress event read through the cuts is one the direct reader saw.
    assert!(progress(&cut).iter().all(|id| direct_ids.contains(id)), "{cut_ids:?} against {direct_ids:?}");
    assert_eq!(cut.last().unwrap().json().unwrap()["status"], "succeeded");
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
    // The usual "seconds" job on a 1025² grid, sixteen times its work: on a busy machine the
    // 257² one (under a second here) once ended before the cancel reached the server.
    let mut body = seconds_bulldoze(2);
    body["terrain"]["fractal"]["size"] = json!(1025);
    let mut slow = client.submit_json("bulldoze", &body, &Submit::default()).await.unwrap();
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
