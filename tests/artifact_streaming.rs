//! Large artifacts are streamed from the store a chunk at a time: downloading a 150 MB artifact
//! barely moves the server's resident memory, and the bytes arrive whole with the length and
//! sha256 the job advertises.

mod common;

use common::processes::{reset_peak_rss, status_bytes};
use common::server::{Options, TestServer};
use serde_json::json;
use sha2::{Digest, Sha256};

/// Downloads `path` chunk by chunk (the test holds no whole copy either); its length, the
/// Content-Length it was announced with, and its sha256.
async fn download(server: &TestServer, path: &str, range: Option<&str>) -> (u64, u64, String) {
    let mut req = server.client.get(server.url(path));
    if let Some(r) = range {
        req = req.header("range", r);
    }
    let mut res = req.send().await.unwrap();
    assert!(res.status().is_success(), "{path}: {}", res.status());
    let announced = res.content_length().expect("Content-Length on a streamed artifact");
    let (mut hash, mut got) = (Sha256::new(), 0u64);
    while let Some(piece) = res.chunk().await.unwrap() {
        got += piece.len() as u64;
        hash.update(&piece);
    }
    (got, announced, format!("{:x}", hash.finalize()))
}

#[tokio::test]
async fn a_150_mb_artifact_downloads_with_the_server_growing_by_under_20_mb() {
    // 6200² f32 heights: heightfield.npy is 153.8 MB (the mesh is capped at 1025² samples).
    let side = 6200u64;
    let server =
        TestServer::start_with(Options { max_grid_cells: side * side, workers: 2, ..Options::default() }).await;
    let body =
        json!({"terrain": {"fractal": {"size": side, "relief": 40.0, "octaves": 1, "seed": 5}}, "operations": []});
    let job = server.run("bulldoze", &body).await;
    let id = job["id"].as_str().unwrap();
    let meta = job["artifacts"].as_array().unwrap().iter().find(|a| a["name"] == "heightfield.npy").unwrap().clone();
    let bytes = meta["bytes"].as_u64().unwrap();
    assert!(bytes >= 150_000_000, "{bytes} bytes");

    // Peak resident memory from here on (writing 5 to clear_refs resets VmHWM to VmRSS).
    let pid = server.pid();
    let before = reset_peak_rss(pid);
    let (got, announced, sha256) = download(&server, &format!("/v1/jobs/{id}/artifacts/heightfield.npy"), None).await;
    let peak = status_bytes(pid, "VmHWM");
    assert_eq!((got, announced), (bytes, bytes));
    assert_eq!(sha256, meta["sha256"].as_str().unwrap());
    let growth = peak.saturating_sub(before);
    eprintln!("download of {bytes} bytes: RSS {before} before, peak {peak} (+{growth})");
    assert!(growth < 20 << 20, "the server grew by {growth} bytes while sending {bytes}");

    // A range across several chunks streams just that part, with the same bytes as the whole
    // artifact has there (checked against a second download of exactly those bytes' hash).
    let (first, last) = (1_000_000u64, 3_500_000u64);
    let path = format!("/v1/jobs/{id}/artifacts/heightfield.npy");
    let (got, announced, part_hash) = download(&server, &path, Some(&format!("bytes={first}-{last}"))).await;
    assert_eq!((got, announced), (last - first + 1, last - first + 1));
    let whole = server.artifact(id, "heightfield.npy").await;
    assert_eq!(format!("{:x}", Sha256::digest(&whole[first as usize..=last as usize])), part_hash);
}
