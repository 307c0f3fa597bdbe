//! What every `JobStore` must do, as test bodies any backend runs: `store_contract_tests!`
//! makes one `#[test]` of each for a backend's fixture.

use chrono::{TimeZone, Utc};
use serde_json::json;

use std::time::Duration;

use super::{EventLog, IdempotentInsert, JobQueue, JobStore, ListFilter, Renewal, StoreError, StoredEvent};
use crate::export::Artifact;
use crate::model::Cost;
use crate::model::{Job, JobStatus, Progress};

/// A store for one test, and whatever must live as long as it (a folder, a schema).
pub struct Fixture {
    pub store: Box<dyn EventLog>,
    pub _guard: Box<dyn std::any::Any>,
}

/// UUIDv7 ids whose order is `n`'s order, as the engine's would be.
pub fn id(n: u64) -> String {
    uuid::Builder::from_unix_timestamp_millis(1_750_000_000_000 + n * 1000, &[n as u8; 10]).into_uuid().to_string()
}

pub fn job(n: u64, kind: &str, status: JobStatus) -> Job {
    Job {
        id: id(n),
        kind: kind.to_string(),
        status,
        label: None,
        created_at: Utc.timestamp_opt(1_750_000_000 + n as i64, 0).unwrap(),
        started_at: None,
        finished_at: None,
        progress: Progress::default(),
        request: json!({ "seed": n }),
        request_omitted: false,
        result: None,
        artifacts: Vec::new(),
        error: None,
        replay_of: None,
        replay_until_step: None,
        cost: None,
        owner: None,
    }
}

pub fn ids(jobs: &[Job]) -> Vec<String> {
    jobs.iter().map(|j| j.id.clone()).collect()
}

pub fn artifacts() -> Vec<Artifact> {
    vec![
        Artifact::new("mesh.glb", "model/gltf-binary", vec![7; 1000]),
        Artifact::new("heightmap.png", "image/png", b"abc".to_vec()),
        Artifact::new("a-last.json", "application/json", Vec::new()),
    ]
}

pub const SHA256_ABC: &str = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";

pub const SHA256_EMPTY: &str = "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855";

pub fn ids_of_artifacts(j: &Job) -> Vec<&str> {
    j.artifacts.iter().map(|a| a.name.as_str()).collect()
}

pub fn insert_then_get_round_trips_every_field(store: &dyn JobStore) {
    let mut j = job(1, "deform-terrain", JobStatus::Failed);
    j.label = Some("ridge «north»".into());
    j.created_at = Utc.timestamp_opt(1_750_000_001, 123_456_789).unwrap();
    j.started_at = Some(Utc.timestamp_opt(1_750_000_002, 5).unwrap());
    j.finished_at = Some(Utc.timestamp_opt(1_750_000_003, 999_999_999).unwrap());
    j.progress = Progress { fraction: 0.25, step: 3, steps: 12, stage: "search".into(), message: "iteration 3".into() };
    j.request = json!({ "seed": 18446744073709551615u64, "terrain": { "fractal": { "size": 65 } } });
    j.result = Some(json!({ "z_min": -1.5, "z_max": 99.25 }));
    j.error = Some(json!({ "type": "about:blank", "status": 500 }));
    j.replay_of = Some(id(0));
    j.replay_until_step = Some(7);

    assert!(matches!(store.insert(&j, None).unwrap(), IdempotentInsert::Inserted));
    assert_eq!(store.get(&j.id).unwrap(), Some(j.clone()));
    assert_eq!(store.get(&id(99)).unwrap(), None);
    assert_eq!(store.attempts(&j.id).unwrap(), Some(0));
}

pub fn list_pages_newest_first_with_filters(store: &dyn JobStore) {
    let statuses = [JobStatus::Queued, JobStatus::Succeeded, JobStatus::Failed];
    let mut all = Vec::new();
    for n in 0..10u64 {
        let kind = if n % 2 == 0 { "bulldoze" } else { "grow-cave" };
        let j = job(n, kind, statuses[n as usize % 3]);
        store.insert(&j, None).unwrap();
        all.push(j);
    }
    let newest: Vec<String> = all.iter().rev().map(|j| j.id.clone()).collect();

    let page = |filter: ListFilter| ids(&store.list(&filter).unwrap());
    let first = page(ListFilter { limit: 4, ..Default::default() });
    assert_eq!(first, newest[..4]);
    let second = page(ListFilter { limit: 4, before_id: first.last().cloned(), ..Default::default() });
    assert_eq!(second, newest[4..8]);
    let third = page(ListFilter { limit: 4, before_id: second.last().cloned(), ..Default::default() });
    assert_eq!(third, newest[8..]);
    assert_eq!(page(ListFilter::default()), newest, "limit 0 is no limit");

    let expect = |pred: &dyn Fn(&Job) -> bool| -> Vec<String> {
        all.iter().rev().filter(|j| pred(j)).map(|j| j.id.clone()).collect()
    };
    let caves = page(ListFilter { kind: Some("grow-cave".into()), limit: 100, ..Default::default() });
    assert_eq!(caves, expect(&|j| j.kind == "grow-cave"));
    let failed = page(ListFilter { status: Some(JobStatus::Failed), limit: 100, ..Default::default() });
    assert_eq!(failed, expect(&|j| j.status == JobStatus::Failed));
    let both = page(ListFilter {
        kind: Some("bulldoze".into()),
        status: Some(JobStatus::Queued),
        before_id: Some(id(6)),
        limit: 100,
        owner: None,
        no_replays: false,
    });
    assert_eq!(both, vec![id(0)]);
    assert!(page(ListFilter { kind: Some("nope".into()), limit: 5, ..Default::default() }).is_empty());

    // Replays left out by the store, so a page of `limit` holds that many originals.
    for n in 10..16u64 {
        let mut r = job(n, "bulldoze", JobStatus::Succeeded);
        r.replay_of = Some(id(n % 3));
        store.insert(&r, None).unwrap();
    }
    let without = page(ListFilter { limit: 4, no_replays: true, ..Default::default() });
    assert_eq!(without, newest[..4], "the newest four that are not replays");
    assert_eq!(page(ListFilter { no_replays: true, ..Default::default() }), newest);
    assert_eq!(page(ListFilter { limit: 100, ..Default::default() }).len(), 16, "replays are listed by default");
}

pub fn idempotency_key_returns_the_first_job_and_compares_the_body(store: &dyn JobStore) {
    let first = job(1, "bulldoze", JobStatus::Queued);
    let retry = job(2, "bulldoze", JobStatus::Queued);
    let key = Some(("key-1", "aa11"));

    assert!(matches!(store.insert(&first, key).unwrap(), IdempotentInsert::Inserted));
    match store.insert(&retry, key).unwrap() {
        IdempotentInsert::Existing { job, same_body } => {
            assert_eq!(*job, first);
            assert!(same_body);
        }
        other => panic!("expected Existing, got {other:?}"),
    }
    match store.insert(&retry, Some(("key-1", "bb22"))).unwrap() {
        IdempotentInsert::Existing { job, same_body } => {
            assert_eq!(job.id, first.id);
            assert!(!same_body);
        }
        other => panic!("expected Existing, got {other:?}"),
    }
    assert_eq!(store.get(&retry.id).unwrap(), None, "a repeated key writes nothing");

    // Another key is another job; deleting a job frees its key.
    assert!(matches!(store.insert(&retry, Some(("key-2", "aa11"))).unwrap(), IdempotentInsert::Inserted));
    assert!(store.delete(&first.id).unwrap());
    let third = job(3, "bulldoze", JobStatus::Queued);
    assert!(matches!(store.insert(&third, key).unwrap(), IdempotentInsert::Inserted));
}

pub fn finish_stores_artifacts_with_sha256_in_production_order(store: &dyn JobStore) {
    let mut j = job(1, "carve-coast", JobStatus::Running);
    store.insert(&j, None).unwrap();
    j.status = JobStatus::Succeeded;
    j.finished_at = Some(Utc.timestamp_opt(1_750_000_100, 0).unwrap());
    j.result = Some(json!({ "caves": 3 }));
    store.finish(&j, &artifacts()).unwrap();

    let got = store.get(&j.id).unwrap().unwrap();
    assert_eq!(got.status, JobStatus::Succeeded);
    assert_eq!(got.result, j.result);
    let names: Vec<&str> = got.artifacts.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["mesh.glb", "heightmap.png", "a-last.json"]);
    let png = &got.artifacts[1];
    assert_eq!((png.media_type.as_str(), png.bytes, png.sha256.as_str()), ("image/png", 3, SHA256_ABC));
    assert_eq!(got.artifacts[2].sha256, SHA256_EMPTY);
    assert_eq!(got.artifacts[0].bytes, 1000);
    assert!(got.artifacts.iter().all(|a| a.href.is_empty()));

    assert_eq!(store.artifact(&j.id, "heightmap.png").unwrap(), Some(("image/png".into(), b"abc".to_vec())));
    assert_eq!(store.artifact(&j.id, "a-last.json").unwrap(), Some(("application/json".into(), Vec::new())));
    assert_eq!(store.artifact(&j.id, "nope.bin").unwrap(), None);

    // Finishing again replaces the artifacts.
    store.finish(&j, &[Artifact::new("sequence.json", "application/json", b"[]".to_vec())]).unwrap();
    let got = store.get(&j.id).unwrap().unwrap();
    assert_eq!(ids_of_artifacts(&got), ["sequence.json"]);
    assert_eq!(store.artifact(&j.id, "mesh.glb").unwrap(), None);
}

/// An artifact of two and a half chunks: every byte tells its position, so a piece read from
/// the wrong place or in the wrong order shows.
pub fn artifacts_read_in_pieces_across_chunk_boundaries(store: &dyn JobStore) {
    let chunk = super::CHUNK_BYTES;
    let data: Vec<u8> = (0..chunk * 5 / 2).map(|i| (i % 251) as u8).collect();
    let mut j = job(1, "bulldoze", JobStatus::Succeeded);
    store.insert(&j, None).unwrap();
    j.finished_at = Some(Utc.timestamp_opt(1_750_000_100, 0).unwrap());
    store.finish(&j, &[Artifact::new("heightfield.npy", "application/octet-stream", data.clone())]).unwrap();

    let read = |offset: usize, len: usize| store.read_artifact(&j.id, "heightfield.npy", offset as u64, len).unwrap();
    for (offset, len) in
        [(0, 10), (chunk - 3, 6), (chunk, chunk), (chunk - 1, chunk + 2), (5, data.len()), (0, usize::MAX)]
    {
        let end = offset.saturating_add(len).min(data.len());
        assert_eq!(read(offset, len).as_deref(), Some(&data[offset..end]), "offset {offset} len {len}");
    }
    assert_eq!(read(data.len(), 1), Some(Vec::new()));
    assert_eq!(read(data.len() + 100, 1), Some(Vec::new()));
    assert_eq!(read(3, 0), Some(Vec::new()));
    assert_eq!(store.read_artifact(&j.id, "nope.bin", 0, 1).unwrap(), None);
    assert_eq!(store.artifact(&j.id, "heightfield.npy").unwrap().map(|a| a.1), Some(data));

    // The chunks go with the job.
    assert!(store.delete(&j.id).unwrap());
    assert_eq!(store.read_artifact(&j.id, "heightfield.npy", 0, 1).unwrap(), None);
}

pub fn finish_refuses_duplicate_names_and_leaves_the_job_untouched(store: &dyn JobStore) {
    let j = job(1, "bulldoze", JobStatus::Running);
    store.insert(&j, None).unwrap();
    let mut done = j.clone();
    done.status = JobStatus::Succeeded;
    let twice = [Artifact::new("a", "x/y", vec![1]), Artifact::new("a", "x/y", vec![2])];
    assert!(matches!(store.finish(&done, &twice), Err(StoreError::Backend(_))));
    assert_eq!(store.get(&j.id).unwrap(), Some(j));
}

pub fn unfinished_is_oldest_first_and_counts_group_by_kind_and_status(store: &dyn JobStore) {
    let plan = [
        ("bulldoze", JobStatus::Running),
        ("grow-cave", JobStatus::Succeeded),
        ("bulldoze", JobStatus::Queued),
        ("bulldoze", JobStatus::Queued),
        ("grow-cave", JobStatus::Cancelled),
        ("grow-cave", JobStatus::Queued),
    ];
    for (n, (kind, status)) in plan.iter().enumerate() {
        store.insert(&job(n as u64, kind, *status), None).unwrap();
    }
    assert_eq!(ids(&store.unfinished().unwrap()), vec![id(0), id(2), id(3), id(5)]);
    assert_eq!(
        store.counts().unwrap(),
        vec![
            ("bulldoze".to_string(), JobStatus::Queued, 2),
            ("bulldoze".to_string(), JobStatus::Running, 1),
            ("grow-cave".to_string(), JobStatus::Cancelled, 1),
            ("grow-cave".to_string(), JobStatus::Queued, 1),
            ("grow-cave".to_string(), JobStatus::Succeeded, 1),
        ]
    );
    assert_eq!(store.queued().unwrap(), 3);
}

pub fn attempts_count_each_entry_into_running(store: &dyn JobStore) {
    let mut j = job(1, "bulldoze", JobStatus::Queued);
    store.insert(&j, None).unwrap();
    for status in [JobStatus::Running, JobStatus::Running, JobStatus::Queued, JobStatus::Running] {
        j.status = status;
        store.update(&j).unwrap();
    }
    assert_eq!(store.attempts(&j.id).unwrap(), Some(2));
    assert_eq!(store.attempts("missing").unwrap(), None);
}

/// A queued job whose estimate is `memory` bytes.
fn queued(store: &dyn JobQueue, n: u64, memory: u64) -> Job {
    let mut j = job(n, "bulldoze", JobStatus::Queued);
    j.cost = Some(Cost {
        memory_bytes: memory,
        memory_field: "terrain".into(),
        work: 1,
        work_unit: "cells".into(),
        work_field: "terrain".into(),
        min_seconds: 0.0,
        lod_triangles: 0,
        lod_bytes: 0,
    });
    store.insert(&j, None).unwrap();
    j
}

const LONG: Duration = Duration::from_secs(600);
const HELD: Renewal = Renewal::Held { cancel_requested: false };
const NO_LIMIT: u64 = u64::MAX;

pub fn claims_take_jobs_oldest_first_and_each_once(store: &dyn JobQueue) {
    for n in [3, 1, 2] {
        queued(store, n, 10);
    }
    let mut claimed = Vec::new();
    while let Some(c) = store.claim("w1", LONG, NO_LIMIT).unwrap() {
        assert_eq!((c.job.status, c.attempt, c.lost_leases), (JobStatus::Running, 1, 0));
        assert_eq!(store.get(&c.job.id).unwrap().unwrap().status, JobStatus::Running);
        claimed.push(c.job.id);
    }
    assert_eq!(claimed, [id(1), id(2), id(3)]);
    // A job running in an engine's own process (no lease) is never claimed.
    let mut own = job(4, "bulldoze", JobStatus::Queued);
    store.insert(&own, None).unwrap();
    own.status = JobStatus::Running;
    store.update(&own).unwrap();
    assert!(store.claim("w1", LONG, NO_LIMIT).unwrap().is_none());
}

pub fn active_jobs_and_their_memory_count_per_owner(store: &dyn JobQueue) {
    let mut mine = queued(store, 1, 100);
    let mut theirs = job(2, "bulldoze", JobStatus::Queued);
    theirs.owner = Some("bob".into());
    theirs.cost = mine.cost.clone();
    store.insert(&theirs, None).unwrap();
    queued(store, 3, 20);
    assert_eq!(store.active(None).unwrap(), (2, 120));
    assert_eq!(store.active(Some("bob")).unwrap(), (1, 100));
    assert_eq!(store.active(Some("carol")).unwrap(), (0, 0));
    let c = store.claim("w", LONG, NO_LIMIT).unwrap().unwrap();
    assert_eq!(store.reserved().unwrap(), 100, "the running job's estimate");
    mine.status = JobStatus::Succeeded;
    mine.finished_at = Some(Utc.timestamp_opt(1_750_000_100, 0).unwrap());
    assert!(store.update_claimed(&mine, c.attempt).unwrap());
    assert_eq!(store.active(None).unwrap(), (1, 20));
    assert_eq!(store.reserved().unwrap(), 0);
    let before = Utc.timestamp_opt(1_750_000_099, 0).unwrap();
    assert_eq!(ids(&store.ended_after(before, 10).unwrap()), [mine.id.clone()]);
    assert_eq!(store.ended_after(Utc.timestamp_opt(1_750_000_100, 0).unwrap(), 10).unwrap(), []);
}

pub fn a_job_over_the_free_budget_waits_and_is_not_passed_over(store: &dyn JobQueue) {
    queued(store, 1, 100);
    queued(store, 2, 10);
    assert!(store.claim("w1", LONG, 50).unwrap().is_none(), "the large job first, or nothing");
    assert_eq!(store.claim("w1", LONG, 100).unwrap().unwrap().job.id, id(1));
    assert_eq!(store.claim("w1", LONG, 10).unwrap().unwrap().job.id, id(2));
}

pub fn an_expired_lease_is_taken_over_and_the_old_claims_writes_are_refused(store: &dyn JobQueue) {
    queued(store, 1, 10);
    let stale = store.claim("w1", Duration::from_millis(1), NO_LIMIT).unwrap().unwrap();
    std::thread::sleep(Duration::from_millis(30));
    let fresh = store.claim("w2", LONG, NO_LIMIT).unwrap().expect("the lease ran out: the job is claimable");
    assert_eq!((fresh.job.id.as_str(), fresh.attempt, fresh.lost_leases), (id(1).as_str(), 2, 1));
    assert!(store.claim("w3", LONG, NO_LIMIT).unwrap().is_none(), "a live lease is not taken");

    // The stalled worker wakes up: every write under its claim is refused.
    assert_eq!(store.renew(&stale.job.id, stale.attempt, LONG).unwrap(), Renewal::Lost);
    let mut late = stale.job.clone();
    late.progress.message = "late".into();
    assert!(!store.update_claimed(&late, stale.attempt).unwrap());
    late.status = JobStatus::Succeeded;
    late.result = Some(json!({"by": "w1"}));
    let late_artifacts = [Artifact::new("mesh.glb", "model/gltf-binary", b"stale".to_vec())];
    assert!(!store.finish_claimed(&late, stale.attempt, &late_artifacts).unwrap());
    assert!(!store.release(&stale.job.id, stale.attempt).unwrap());
    let now = store.get(&fresh.job.id).unwrap().unwrap();
    assert_eq!((now.status, now.result, now.artifacts.len()), (JobStatus::Running, None, 0));

    // The new holder's writes go through.
    assert_eq!(store.renew(&fresh.job.id, fresh.attempt, LONG).unwrap(), HELD);
    let mut done = fresh.job.clone();
    done.status = JobStatus::Succeeded;
    done.result = Some(json!({"by": "w2"}));
    assert!(store.finish_claimed(&done, fresh.attempt, &artifacts()).unwrap());
    let now = store.get(&done.id).unwrap().unwrap();
    assert_eq!((now.status, now.result, now.artifacts.len()), (JobStatus::Succeeded, Some(json!({"by": "w2"})), 3));
    // An ended job is claimed by no one.
    assert!(store.claim("w3", Duration::from_millis(1), NO_LIMIT).unwrap().is_none());
}

pub fn a_renewed_lease_holds_and_a_released_job_is_claimed_again_at_once(store: &dyn JobQueue) {
    queued(store, 1, 10);
    let c = store.claim("w1", Duration::from_millis(300), NO_LIMIT).unwrap().unwrap();
    for _ in 0..4 {
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(store.renew(&c.job.id, c.attempt, Duration::from_millis(300)).unwrap(), HELD);
        assert!(store.claim("w2", LONG, NO_LIMIT).unwrap().is_none(), "renewed: still held");
    }
    assert!(store.release(&c.job.id, c.attempt).unwrap());
    assert_eq!(store.get(&c.job.id).unwrap().unwrap().status, JobStatus::Queued);
    let again = store.claim("w2", LONG, NO_LIMIT).unwrap().unwrap();
    // A release is not a lost lease: the job did not take its worker down.
    assert_eq!((again.attempt, again.lost_leases), (2, 0));
}

pub fn workers_claiming_at_once_take_each_job_exactly_once(store: &dyn JobQueue) {
    for n in 1..=24 {
        queued(store, n, 10);
    }
    let taken: Vec<String> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..4)
            .map(|w| {
                s.spawn(move || {
                    let mut mine = Vec::new();
                    while let Some(c) = store.claim(&format!("w{w}"), LONG, NO_LIMIT).unwrap() {
                        mine.push(c.job.id);
                    }
                    mine
                })
            })
            .collect();
        workers.into_iter().flat_map(|h| h.join().unwrap()).collect()
    });
    let mut sorted = taken.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!((taken.len(), sorted), (24, (1..=24).map(id).collect::<Vec<_>>()));
}

pub fn events_get_growing_store_ids_and_resume_after_any_of_them(store: &dyn EventLog) {
    queued(store, 1, 10);
    queued(store, 2, 10);
    let a = store.claim("w1", LONG, NO_LIMIT).unwrap().unwrap();
    let b = store.claim("w2", LONG, NO_LIMIT).unwrap().unwrap();
    let mut ids = Vec::new();
    for k in 0..3 {
        ids.push(store.append_event(&a.job.id, a.attempt, "progress", &format!("{{\"step\":{k}}}")).unwrap().unwrap());
        store.append_event(&b.job.id, b.attempt, "progress", "{}").unwrap().unwrap();
    }
    assert!(ids.windows(2).all(|w| w[0] < w[1]), "{ids:?}");
    let all = store.events_after(&a.job.id, 0, 100).unwrap();
    assert_eq!(
        all,
        (0..3)
            .map(|k| StoredEvent { id: ids[k], event: "progress".into(), data: format!("{{\"step\":{k}}}") })
            .collect::<Vec<_>>()
    );
    assert_eq!(store.events_after(&a.job.id, ids[0], 100).unwrap(), all[1..]);
    assert_eq!(store.events_after(&a.job.id, ids[0], 1).unwrap(), all[1..2]);
    assert_eq!(store.events_after(&a.job.id, ids[2], 100).unwrap(), []);
    assert_eq!(store.last_event(&a.job.id, "progress").unwrap().as_ref(), all.last());
    assert_eq!(store.last_event(&a.job.id, "status").unwrap(), None);

    // The latest snapshot wins; a job's events and snapshot outlive its end (a stream still
    // reads them) until the cleaner prunes jobs that ended before its cut-off.
    assert!(store.put_snapshot(&a.job.id, a.attempt, ids[0], b"png-0").unwrap());
    assert!(store.put_snapshot(&a.job.id, a.attempt, ids[2], b"png-2").unwrap());
    assert_eq!(store.snapshot(&a.job.id).unwrap(), Some((ids[2], b"png-2".to_vec())));
    let ended = Utc.timestamp_opt(1_750_000_500, 0).unwrap();
    let mut done = a.job.clone();
    done.status = JobStatus::Succeeded;
    done.finished_at = Some(ended);
    assert!(store.finish_claimed(&done, a.attempt, &artifacts()).unwrap());
    assert_eq!(store.events_after(&a.job.id, 0, 100).unwrap(), all);
    let mut failed = b.job.clone();
    failed.status = JobStatus::Failed;
    failed.finished_at = Some(ended + chrono::Duration::seconds(60));
    assert!(store.update_claimed(&failed, b.attempt).unwrap());
    assert_eq!(store.prune_ended(ended).unwrap(), 0, "nothing ended before the cut-off");
    assert_eq!(store.prune_ended(ended + chrono::Duration::seconds(1)).unwrap(), 4, "a's three events and snapshot");
    assert_eq!(store.events_after(&a.job.id, 0, 100).unwrap(), []);
    assert_eq!(store.snapshot(&a.job.id).unwrap(), None);
    assert_eq!(store.events_after(&b.job.id, 0, 100).unwrap().len(), 3, "b ended later");
}

pub fn a_claim_that_lost_its_lease_appends_no_event_and_no_snapshot(store: &dyn EventLog) {
    queued(store, 1, 10);
    let stale = store.claim("w1", Duration::from_millis(1), NO_LIMIT).unwrap().unwrap();
    std::thread::sleep(Duration::from_millis(30));
    let fresh = store.claim("w2", LONG, NO_LIMIT).unwrap().unwrap();
    assert_eq!(store.append_event(&stale.job.id, stale.attempt, "progress", "{}").unwrap(), None);
    assert!(!store.put_snapshot(&stale.job.id, stale.attempt, 1, b"stale").unwrap());
    let id = store.append_event(&fresh.job.id, fresh.attempt, "status", "{}").unwrap().unwrap();
    assert!(store.put_snapshot(&fresh.job.id, fresh.attempt, id, b"fresh").unwrap());
    assert_eq!(store.events_after(&fresh.job.id, 0, 10).unwrap().len(), 1);
    assert_eq!(store.snapshot(&fresh.job.id).unwrap(), Some((id, b"fresh".to_vec())));
}

pub fn a_cancel_request_reaches_the_holder_at_its_next_renewal(store: &dyn EventLog) {
    let j = queued(store, 1, 10);
    assert!(store.request_cancel(&j.id).unwrap(), "a queued job can be asked to stop");
    let c = store.claim("w1", LONG, NO_LIMIT).unwrap().unwrap();
    assert_eq!(store.renew(&c.job.id, c.attempt, LONG).unwrap(), Renewal::Held { cancel_requested: true });
    let other = queued(store, 2, 10);
    let c2 = store.claim("w1", LONG, NO_LIMIT).unwrap().unwrap();
    assert_eq!(c2.job.id, other.id);
    assert_eq!(store.renew(&c2.job.id, c2.attempt, LONG).unwrap(), HELD);
    let mut ended = c2.job.clone();
    ended.status = JobStatus::Cancelled;
    assert!(store.update_claimed(&ended, c2.attempt).unwrap());
    assert!(!store.request_cancel(&other.id).unwrap(), "an ended job has nothing to stop");
    assert!(!store.request_cancel("no-such-job").unwrap());
}

/// One `#[test]` per contract body, on the store `$fixture()` gives (`None`: the backend is
/// not configured here, and the test passes without running).
#[macro_export]
macro_rules! store_contract_tests {
    ($fixture:path) => {
        $crate::store_contract_tests!(@each $fixture;
            insert_then_get_round_trips_every_field,
            list_pages_newest_first_with_filters,
            idempotency_key_returns_the_first_job_and_compares_the_body,
            finish_stores_artifacts_with_sha256_in_production_order,
            artifacts_read_in_pieces_across_chunk_boundaries,
            finish_refuses_duplicate_names_and_leaves_the_job_untouched,
            unfinished_is_oldest_first_and_counts_group_by_kind_and_status,
            attempts_count_each_entry_into_running,
            claims_take_jobs_oldest_first_and_each_once,
            a_job_over_the_free_budget_waits_and_is_not_passed_over,
            active_jobs_and_their_memory_count_per_owner,
            an_expired_lease_is_taken_over_and_the_old_claims_writes_are_refused,
            a_renewed_lease_holds_and_a_released_job_is_claimed_again_at_once,
            workers_claiming_at_once_take_each_job_exactly_once,
            events_get_growing_store_ids_and_resume_after_any_of_them,
            a_claim_that_lost_its_lease_appends_no_event_and_no_snapshot,
            a_cancel_request_reaches_the_holder_at_its_next_renewal
        );
    };
    (@each $fixture:path; $($name:ident),*) => {
        $(
            #[test]
            fn $name() {
                if let Some(f) = $fixture() {
                    $crate::store::contract::$name(f.store.as_ref());
                }
            }
        )*
    };
}

/// Every file under `dir` (relative path → bytes): the objects a store keeps in a directory.
fn objects_in(dir: &std::path::Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    fn walk(root: &std::path::Path, at: &std::path::Path, out: &mut std::collections::BTreeMap<String, Vec<u8>>) {
        let Ok(entries) = std::fs::read_dir(at) else { return };
        for e in entries.map(Result::unwrap) {
            let path = e.path();
            if path.is_dir() {
                walk(root, &path, out);
            } else {
                let rel = path.strip_prefix(root).unwrap().to_string_lossy().into_owned();
                out.insert(rel, std::fs::read(&path).unwrap());
            }
        }
    }
    let mut out = std::collections::BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// A store keeping artifacts in the object store at `dir` (a directory): the bytes are there,
/// one object per artifact under the job's id, and no object outlives the row that points at
/// it — not after a finish replaced them, a fenced-off worker's refused finish, or a delete.
pub fn objects_hold_the_bytes_and_none_outlives_its_row(store: &dyn JobQueue, dir: &std::path::Path) {
    queued(store, 1, 10);
    let stale = store.claim("w1", Duration::from_millis(1), NO_LIMIT).unwrap().unwrap();
    std::thread::sleep(Duration::from_millis(30));
    let fresh = store.claim("w2", LONG, NO_LIMIT).unwrap().unwrap();

    // The stalled worker's finish is refused and leaves no object behind.
    let mut late = stale.job.clone();
    late.status = JobStatus::Succeeded;
    assert!(!store
        .finish_claimed(&late, stale.attempt, &[Artifact::new("mesh.glb", "model/gltf-binary", b"stale".to_vec())])
        .unwrap());
    assert!(objects_in(dir).is_empty(), "a refused finish left {:?}", objects_in(dir).keys());

    let mut done = fresh.job.clone();
    done.status = JobStatus::Succeeded;
    assert!(store.finish_claimed(&done, fresh.attempt, &artifacts()).unwrap());
    let objects = objects_in(dir);
    let mut held: Vec<(String, Vec<u8>)> = objects
        .iter()
        .map(|(k, v)| {
            let mut parts = k.split('/');
            assert_eq!(parts.next(), Some(done.id.as_str()), "object {k} is not under its job's id");
            (parts.nth(1).unwrap().to_string(), v.clone())
        })
        .collect();
    held.sort();
    let mut expected: Vec<(String, Vec<u8>)> = artifacts().into_iter().map(|a| (a.name.to_string(), a.bytes)).collect();
    expected.sort();
    assert_eq!(held, expected);
    assert_eq!(store.artifact(&done.id, "heightmap.png").unwrap(), Some(("image/png".into(), b"abc".to_vec())));
    assert_eq!(store.read_artifact(&done.id, "mesh.glb", 998, 10).unwrap(), Some(vec![7, 7]));

    // Finishing again replaces the objects; deleting the job removes them.
    store.finish(&done, &[Artifact::new("sequence.json", "application/json", b"[1]".to_vec())]).unwrap();
    let objects = objects_in(dir);
    assert_eq!(objects.len(), 1, "{:?}", objects.keys());
    assert!(objects.keys().all(|k| k.ends_with("/sequence.json")));
    assert_eq!(store.artifact(&done.id, "sequence.json").unwrap().map(|a| a.1), Some(b"[1]".to_vec()));
    assert!(store.delete(&done.id).unwrap());
    assert!(objects_in(dir).is_empty());
}
