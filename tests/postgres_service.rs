//! The service on PostgreSQL (`--database postgres://…`), each test in a schema of its own on
//! the database `LANDFORM_TEST_DATABASE_URL` names; without that variable these tests have
//! nothing to talk to and return at once (`.ci/run` sets it).

mod common;

use common::bodies::small_bulldoze;
use common::server::{artifact_hashes, Options, TestServer};
use serde_json::json;

/// A fresh schema, dropped afterwards, and the URL that uses it.
struct Schema {
    admin: Option<postgres::Client>,
    name: String,
    url: String,
}

impl Schema {
    /// The synchronous client runs a runtime of its own: it works on a thread of its own.
    fn new() -> Option<Self> {
        let base = std::env::var("LANDFORM_TEST_DATABASE_URL").ok().filter(|u| !u.is_empty())?;
        std::thread::spawn(move || {
            let name = format!("s_{}", uuid::Uuid::now_v7().simple());
            let mut admin = postgres::Client::connect(&base, postgres::NoTls).expect("connect");
            admin.batch_execute(&format!("CREATE SCHEMA {name}")).expect("schema");
            let sep = if base.contains('?') { '&' } else { '?' };
            let url = format!("{base}{sep}options=-csearch_path%3D{name}");
            Self { admin: Some(admin), name, url }
        })
        .join()
        .ok()
    }
}

impl Drop for Schema {
    fn drop(&mut self) {
        let (admin, sql) = (self.admin.take(), format!("DROP SCHEMA {} CASCADE", self.name));
        let _ = std::thread::spawn(move || admin.map(|mut a| a.batch_execute(&sql))).join();
    }
}

async fn server_on(url: &str) -> TestServer {
    let options = Options { database_url: Some(url.to_string()), ..Options::default() };
    TestServer::start_on(std::path::Path::new("unused"), &options).await
}

#[tokio::test]
async fn a_job_runs_replays_and_survives_a_restart_on_postgres() {
    let Some(schema) = Schema::new() else { return };
    let server = server_on(&schema.url).await;
    let done = server.run("bulldoze", &small_bulldoze()).await;
    let id = done["id"].as_str().unwrap().to_string();
    let glb = server.artifact(&id, "mesh.glb").await;
    assert_eq!(&glb[..4], b"glTF");

    // The same request on the embedded store makes the same bytes.
    let sqlite = TestServer::start().await;
    let there = sqlite.run("bulldoze", &small_bulldoze()).await;
    assert_eq!(artifact_hashes(&done), artifact_hashes(&there));

    let (status, replay) = server.post(&format!("/v1/jobs/{id}/replay"), &json!({})).await;
    assert_eq!(status, 202, "{replay}");
    let replayed = server.wait_done(replay["id"].as_str().unwrap()).await;
    assert_eq!(artifact_hashes(&replayed), artifact_hashes(&done));

    // A job left queued when the process dies runs after the restart.
    let slow = server.submit("bulldoze", &common::bodies::slow_bulldoze()).await;
    let queued = server.submit("bulldoze", &small_bulldoze()).await;
    server.kill();
    let again = server_on(&schema.url).await;
    let (_, page) = again.get_json("/v1/jobs?limit=100").await;
    // The job, its replay, and the two left behind.
    assert_eq!(page["items"].as_array().unwrap().len(), 4);
    let finished = again.wait_done(queued["id"].as_str().unwrap()).await;
    assert_eq!(finished["status"], "succeeded", "{finished}");
    again.client.post(again.url(&format!("/v1/jobs/{}/cancel", slow["id"].as_str().unwrap()))).send().await.unwrap();
}
