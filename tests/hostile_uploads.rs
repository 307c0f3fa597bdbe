//! Uploaded heightmaps (issue 28, item 5): an upload belongs to the key that sent it (another
//! key gets the same answer for it as for a hash nobody uploaded), is stored only with a job
//! that was admitted, and goes with the last job that reads it. The uploads kept are counted
//! in the server's own SQLite file.

mod common;

use std::path::Path;

use base64::Engine as _;
use common::server::{Options, TestServer};
use serde_json::{json, Value};
use sha2::{Digest, Sha256};

const ALICE: &str = "alice-key-0123456789abcdef";
const BOB: &str = "bob-key-0123456789abcdef01";

/// A 16-bit grayscale PNG of `side`², different for each `salt`.
fn png(side: u32, salt: u32) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut e = png::Encoder::new(&mut out, side, side);
        e.set_color(png::ColorType::Grayscale);
        e.set_depth(png::BitDepth::Sixteen);
        let data: Vec<u8> = (0..side * side)
            .flat_map(|i| ((i.wrapping_mul(2_654_435_761u32.wrapping_add(salt)) >> 16) as u16).to_be_bytes())
            .collect();
        e.write_header().unwrap().write_image_data(&data).unwrap();
    }
    out
}

fn with_upload(bytes: &[u8]) -> Value {
    json!({"terrain": {"heightmap": {"png_base64": base64::engine::general_purpose::STANDARD.encode(bytes),
        "cell_size": 1.0, "z_min": 0.0, "z_max": 20.0}}, "operations": []})
}

fn naming(sha256: &str) -> Value {
    json!({"terrain": {"heightmap": {"png_sha256": sha256, "cell_size": 1.0, "z_min": 0.0, "z_max": 20.0}},
        "operations": []})
}

fn uploads_kept(db: &Path) -> i64 {
    let conn = rusqlite::Connection::open(db).unwrap();
    conn.query_row("SELECT COUNT(*) FROM inputs", [], |r| r.get(0)).unwrap()
}

async fn post(server: &TestServer, key: Option<&str>, path: &str, body: &Value) -> (u16, Value) {
    let mut req = server.client.post(server.url(path)).json(body);
    if let Some(k) = key {
        req = req.bearer_auth(k);
    }
    let res = req.send().await.unwrap();
    let status = res.status().as_u16();
    (status, res.json().await.unwrap_or(Value::Null))
}

#[tokio::test]
async fn another_keys_upload_answers_as_one_that_does_not_exist() {
    let dir = tempfile::tempdir().unwrap();
    let keys = dir.path().join("keys");
    std::fs::write(&keys, format!("alice {ALICE}\nbob {BOB}\n")).unwrap();
    let server = TestServer::start_with(Options {
        extra: vec!["--api-keys".into(), keys.to_str().unwrap().into()],
        ..Options::default()
    })
    .await;
    let bytes = png(65, 1);
    let sha = hex::encode(Sha256::digest(&bytes));
    let (status, job) = post(&server, Some(ALICE), "/v1/jobs/bulldoze", &with_upload(&bytes)).await;
    assert_eq!(status, 202, "{job}");
    // Alice may name her upload again.
    let (status, again) = post(&server, Some(ALICE), "/v1/jobs/bulldoze", &naming(&sha)).await;
    assert_eq!(status, 202, "{again}");
    // Bob naming it, and Bob naming a hash nobody uploaded, get the same answer but for the hash.
    let (status, theirs) = post(&server, Some(BOB), "/v1/jobs/bulldoze", &naming(&sha)).await;
    let nobodys = "ab".repeat(32);
    let (status_none, none) = post(&server, Some(BOB), "/v1/jobs/bulldoze", &naming(&nobodys)).await;
    assert_eq!((status, status_none), (422, 422), "{theirs} / {none}");
    assert_eq!(theirs.to_string().replace(&sha, "SHA"), none.to_string().replace(&nobodys, "SHA"));
    // Nor can Bob reach Alice's heights through a job of his own.
    assert_eq!(uploads_kept(&server.db), 1);
}

#[tokio::test]
async fn uploads_are_kept_only_with_admitted_jobs_and_go_with_the_last() {
    // No worker (`--role api`) and one place in the queue: the first job waits, the rest get 503.
    let server = TestServer::start_with(Options {
        queue_capacity: 1,
        extra: vec!["--role".into(), "api".into()],
        ..Options::default()
    })
    .await;
    let first = png(65, 100);
    let (status, kept) = post(&server, None, "/v1/jobs/bulldoze", &with_upload(&first)).await;
    assert_eq!(status, 202, "{kept}");
    for salt in 0..20 {
        let (status, refused) = post(&server, None, "/v1/jobs/bulldoze", &with_upload(&png(65, salt))).await;
        assert_eq!(status, 503, "{refused}");
    }
    // Refused at validation too (a bad field beside the upload).
    let mut bad = with_upload(&png(65, 50));
    bad["operations"] =
        json!([{"primitive": {"shape": {"mound": {"center": {"x": 1, "z": 1}, "radius_m": -1, "height_m": 1}}}}]);
    assert_eq!(post(&server, None, "/v1/jobs/bulldoze", &bad).await.0, 422);
    assert_eq!(uploads_kept(&server.db), 1, "only the admitted job's upload is kept");

    // A second job naming the same upload keeps it alive when the first goes.
    let sha = hex::encode(Sha256::digest(&first));
    let id = kept["id"].as_str().unwrap().to_string();
    let cancel = server.client.post(server.url(&format!("/v1/jobs/{id}/cancel"))).send().await.unwrap();
    assert_eq!(cancel.status(), 200);
    let (status, second) = post(&server, None, "/v1/jobs/bulldoze", &naming(&sha)).await;
    assert_eq!(status, 202, "{second}");
    let delete = |id: String| server.client.delete(server.url(&format!("/v1/jobs/{id}"))).send();
    assert_eq!(delete(id).await.unwrap().status(), 204);
    assert_eq!(uploads_kept(&server.db), 1, "the second job still reads it");
    assert_eq!(delete(second["id"].as_str().unwrap().to_string()).await.unwrap().status(), 204);
    assert_eq!(uploads_kept(&server.db), 0, "deleted with its last job");
}
