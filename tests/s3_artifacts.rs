//! Artifacts in an S3-compatible object store (`--artifact-store s3://…`), against a local
//! server (moto, started by `scripts/test`, on 127.0.0.1) named by `LANDFORM_TEST_S3_ENDPOINT`;
//! without the variable these tests pass without running, as the PostgreSQL ones do.
//!
//! The bucket is read directly with S3's own API (ListObjectsV2, a signed GET), not through
//! Landform, so what is checked is what an operator would find there.

mod common;

use common::server::{artifact_hashes, Options, TestServer};
use sha2::{Digest, Sha256};

fn endpoint() -> Option<String> {
    std::env::var("LANDFORM_TEST_S3_ENDPOINT").ok().filter(|s| !s.is_empty())
}

/// A fresh bucket on the local server; moto takes unsigned requests.
async fn bucket(endpoint: &str) -> String {
    let name = format!("landform-{}-{:x}", std::process::id(), rand_suffix());
    let res = reqwest::Client::new().put(format!("{endpoint}/{name}")).send().await.expect("create a bucket");
    assert!(res.status().is_success(), "create bucket: {}", res.status());
    name
}

fn rand_suffix() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos() as u64
}

/// (key, size) of every object under `prefix`, straight from the S3 API.
async fn list(endpoint: &str, bucket: &str, prefix: &str) -> Vec<(String, u64)> {
    let xml = reqwest::get(format!("{endpoint}/{bucket}?list-type=2&prefix={prefix}"))
        .await
        .expect("ListObjectsV2")
        .text()
        .await
        .unwrap();
    let mut out: Vec<(String, u64)> = xml
        .split("<Contents>")
        .skip(1)
        .map(|c| {
            let field =
                |tag: &str| c.split(&format!("<{tag}>")).nth(1).unwrap().split(&format!("</{tag}>")).next().unwrap();
            (field("Key").to_string(), field("Size").parse().unwrap())
        })
        .collect();
    out.sort();
    out
}

/// An object's bytes by a signed S3 GET (moto keeps objects private).
async fn read_object(endpoint: &str, bucket: &str, key: &str) -> Vec<u8> {
    use object_store::ObjectStore;
    let s3 = object_store::aws::AmazonS3Builder::new()
        .with_endpoint(endpoint)
        .with_allow_http(true)
        .with_bucket_name(bucket)
        .with_region("us-east-1")
        .with_access_key_id("test")
        .with_secret_access_key("test")
        .build()
        .unwrap();
    let got = s3.get(&object_store::path::Path::from(key)).await.unwrap_or_else(|e| panic!("GET {key}: {e}"));
    got.bytes().await.unwrap().to_vec()
}

fn s3_server(endpoint: &str, bucket: &str, database_url: Option<String>, role: &[&str]) -> Options {
    let envs = [
        ("AWS_ENDPOINT", endpoint),
        ("AWS_ALLOW_HTTP", "true"),
        ("AWS_ACCESS_KEY_ID", "test"),
        ("AWS_SECRET_ACCESS_KEY", "test"),
        ("AWS_DEFAULT_REGION", "us-east-1"),
    ];
    let mut extra = vec!["--artifact-store".to_string(), format!("s3://{bucket}/landform")];
    extra.extend(role.iter().map(|s| s.to_string()));
    Options {
        database_url,
        extra,
        envs: envs.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect(),
        ..Options::default()
    }
}

/// Submit, download every artifact (whole and a range) and compare with the bucket; then
/// delete the job and find the bucket empty.
async fn round_trip(server: &TestServer, endpoint: &str, bucket: &str) {
    let job = server.run("bulldoze", &common::bodies::small_bulldoze()).await;
    assert_eq!(job["status"], "succeeded", "{job}");
    let id = job["id"].as_str().unwrap();
    let metas = job["artifacts"].as_array().unwrap();
    let objects = list(endpoint, bucket, &format!("landform/{id}/")).await;
    assert_eq!(objects.len(), metas.len(), "one object per artifact: {objects:?}");

    for (name, sha256) in artifact_hashes(&job) {
        let bytes = server.artifact(id, &name).await;
        assert_eq!(format!("{:x}", Sha256::digest(&bytes)), sha256, "{name} through the API");
        // The object holding it, read with S3's API, is the same bytes.
        let (key, size) = objects.iter().find(|(k, _)| k.ends_with(&format!("/{name}"))).expect("its object");
        assert_eq!(*size, bytes.len() as u64, "{key}");
        let direct = read_object(endpoint, bucket, key).await;
        assert_eq!(format!("{:x}", Sha256::digest(&direct)), sha256, "{key} read from the bucket");
        if bytes.len() > 10 {
            let res = server
                .client
                .get(server.url(&format!("/v1/jobs/{id}/artifacts/{name}")))
                .header("range", "bytes=3-9")
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 206, "{name}");
            assert_eq!(res.content_length(), Some(7));
            assert_eq!(res.bytes().await.unwrap().as_ref(), &bytes[3..10], "{name} bytes 3-9");
        }
    }

    let res = server.client.delete(server.url(&format!("/v1/jobs/{id}"))).send().await.unwrap();
    assert!(res.status().is_success(), "delete: {}", res.status());
    assert_eq!(list(endpoint, bucket, "landform/").await, vec![], "the job's objects go with it");
}

#[tokio::test]
async fn artifacts_go_to_the_bucket_and_come_back_on_the_embedded_store() {
    let Some(endpoint) = endpoint() else { return };
    let bucket = bucket(&endpoint).await;
    // serve: the API and its supervised worker process both use the bucket.
    let side = 1700u64;
    let options = Options { max_grid_cells: side * side, ..s3_server(&endpoint, &bucket, None, &[]) };
    let server = TestServer::start_with(options).await;
    round_trip(&server, &endpoint, &bucket).await;

    // An artifact over the 8 MiB part size goes up as a multipart upload and streams back whole.
    let body = serde_json::json!({"terrain": {"fractal": {"size": side, "relief": 40.0, "octaves": 2, "seed": 9}}, "operations": []});
    let job = server.run("bulldoze", &body).await;
    let id = job["id"].as_str().unwrap();
    let npy = job["artifacts"].as_array().unwrap().iter().find(|a| a["name"] == "heightfield.npy").unwrap();
    assert!(npy["bytes"].as_u64().unwrap() > 8 << 20, "{npy}");
    let bytes = server.artifact(id, "heightfield.npy").await;
    assert_eq!(format!("{:x}", Sha256::digest(&bytes)), npy["sha256"].as_str().unwrap());
    let objects = list(&endpoint, &bucket, &format!("landform/{id}/")).await;
    let (key, size) = objects.iter().find(|(k, _)| k.ends_with("/heightfield.npy")).unwrap();
    assert_eq!(*size, bytes.len() as u64);
    assert_eq!(read_object(&endpoint, &bucket, key).await, bytes);
}

#[tokio::test]
async fn artifacts_go_to_the_bucket_and_come_back_on_postgres_with_separate_roles() {
    let Some(endpoint) = endpoint() else { return };
    let Some(schema) = common::processes::with_schema() else { return };
    let bucket = bucket(&endpoint).await;
    let options = s3_server(&endpoint, &bucket, Some(schema.url.clone()), &["--role", "api"]);
    let api = TestServer::start_on(std::path::Path::new("unused"), &options).await;
    let worker = s3_server(&endpoint, &bucket, None, &[]);
    let _worker = common::processes::WorkerProcess::start_with(&schema.url, 5, &worker.extra, &worker.envs);
    round_trip(&api, &endpoint, &bucket).await;
}
