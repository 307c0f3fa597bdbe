//! The service split across processes: API replicas (`serve --role api`) and workers
//! (`landform worker`) on one database — the embedded SQLite file, and PostgreSQL when
//! `LANDFORM_TEST_DATABASE_URL` names one. A job submitted to one replica is followed on
//! another, downloaded from a third, and makes the same bytes as in a single process.

mod common;

use common::bodies::{slow_bulldoze, small_bulldoze};
use common::processes::{api_replica, with_schema, WorkerProcess};
use common::server::{artifact_hashes, TestServer};
use common::sse::read_events;
use serde_json::json;

/// Three API replicas and two workers on `database`: jobs cross between them.
async fn jobs_cross_replicas_and_workers(database: &str) {
    let _workers = [WorkerProcess::start(database, 3), WorkerProcess::start(database, 3)];
    let (one, two, three) = (api_replica(database).await, api_replica(database).await, api_replica(database).await);

    // Submitted to one replica, followed to the end on the other, from its first event.
    let job = one.submit("bulldoze", &small_bulldoze()).await;
    let id = job["id"].as_str().unwrap().to_string();
    let events = read_events(&two.client, &two.url(&format!("/v1/jobs/{id}/events")), None, 10_000).await;
    let done = events.last().expect("events");
    assert_eq!((done.event.as_str(), done.data["status"].as_str()), ("done", Some("succeeded")), "{events:?}");
    let ids: Vec<u64> = events.iter().filter_map(|e| e.id).collect();
    assert!(ids.windows(2).all(|w| w[0] < w[1]), "event ids grow: {ids:?}");

    // Every replica lists and serves it the same, with the bytes one process makes; it is
    // downloaded from the third.
    let (_, from_one) = one.get_json(&format!("/v1/jobs/{id}")).await;
    let (_, from_two) = two.get_json(&format!("/v1/jobs/{id}")).await;
    let (_, from_three) = three.get_json(&format!("/v1/jobs/{id}")).await;
    assert_eq!(from_one, from_two);
    assert_eq!(from_one, from_three);
    let single = TestServer::start().await;
    let alone = single.run("bulldoze", &small_bulldoze()).await;
    assert_eq!(artifact_hashes(&from_two), artifact_hashes(&alone));
    for (name, _) in artifact_hashes(&alone) {
        let here = three.artifact(&id, &name).await;
        assert_eq!(here, single.artifact(alone["id"].as_str().unwrap(), &name).await, "{name}");
    }
    let (_, page_one) = one.get_json("/v1/jobs?limit=10").await;
    let (_, page_two) = two.get_json("/v1/jobs?limit=10").await;
    let (_, page_three) = three.get_json("/v1/jobs?limit=10").await;
    assert_eq!(page_one["items"], page_two["items"]);
    assert_eq!(page_one["items"], page_three["items"]);

    // A long job: progress from its worker reaches a stream on either replica, a client
    // resuming with Last-Event-ID on the other replica misses nothing after it, and a cancel
    // sent to either stops it.
    let slow = one.submit("bulldoze", &slow_bulldoze()).await;
    let slow_id = slow["id"].as_str().unwrap().to_string();
    let first = read_events(&two.client, &two.url(&format!("/v1/jobs/{slow_id}/events")), None, 3).await;
    assert!(first.iter().any(|e| e.event == "progress"), "{first:?}");
    let seen = first.last().and_then(|e| e.id).unwrap();
    let (status, cancelled) = two.post(&format!("/v1/jobs/{slow_id}/cancel"), &json!({})).await;
    assert_eq!(status, 200, "{cancelled}");
    let rest = read_events(&one.client, &one.url(&format!("/v1/jobs/{slow_id}/events")), Some(seen), 10_000).await;
    assert!(rest.iter().filter_map(|e| e.id).all(|i| i > seen), "{rest:?}");
    let end = rest.last().unwrap();
    assert_eq!((end.event.as_str(), end.data["status"].as_str()), ("done", Some("cancelled")));

    // Prefer: wait holds the answer on a replica that runs no job itself.
    let (status, waited) = two.submit_waiting("bulldoze", &small_bulldoze(), 60).await;
    assert_eq!(status, 200);
    assert_eq!(waited["status"], "succeeded", "{waited}");
    assert_eq!(artifact_hashes(&waited), artifact_hashes(&alone));
}

#[tokio::test]
async fn three_api_replicas_and_two_workers_share_one_sqlite_file() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("shared.db");
    jobs_cross_replicas_and_workers(db.to_str().unwrap()).await;
}

#[tokio::test]
async fn three_api_replicas_and_two_workers_share_one_postgres_database() {
    let Some(schema) = with_schema() else { return };
    jobs_cross_replicas_and_workers(&schema.url).await;
}
