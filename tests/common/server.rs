//! Starts the real `landform` binary on 127.0.0.1:0 with a fresh SQLite file, and talks to it
//! over HTTP: jobs are posted, followed and downloaded through the Rust client
//! (`landform-client`, `lf`), and raw calls (status codes, headers, hostile bodies) go through
//! reqwest (`client`).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// Flags for one server process.
#[derive(Clone, Debug)]
pub struct Options {
    pub workers: usize,
    pub queue_capacity: usize,
    pub job_timeout_secs: u64,
    pub max_body_bytes: usize,
    pub max_grid_cells: u64,
    /// More flags, as given (e.g. `--memory-budget`, `--api-keys`).
    pub extra: Vec<String>,
    /// A database URL (PostgreSQL) to use instead of the SQLite file.
    pub database_url: Option<String>,
    /// Environment variables for the process (e.g. an object store's `AWS_*`).
    pub envs: Vec<(String, String)>,
    /// The process's limit of open descriptors (soft and hard), when set.
    pub max_descriptors: Option<u64>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            workers: 2,
            queue_capacity: 16,
            job_timeout_secs: 120,
            max_body_bytes: 8 * 1024 * 1024,
            max_grid_cells: 1025 * 1025,
            extra: Vec::new(),
            database_url: None,
            envs: Vec::new(),
            max_descriptors: None,
        }
    }
}

pub struct TestServer {
    pub base: String,
    pub client: reqwest::Client,
    /// The Rust client on the same connection pool.
    pub lf: landform_client::Client,
    pub db: PathBuf,
    child: Child,
    _dir: Option<tempfile::TempDir>,
}

impl TestServer {
    pub async fn start() -> Self {
        Self::start_with(Options::default()).await
    }

    pub async fn start_with(options: Options) -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        let db = dir.path().join("landform.db");
        let mut s = Self::start_on(&db, &options).await;
        s._dir = Some(dir);
        s
    }

    /// A server on an existing database file (to test restarts); the caller keeps the folder.
    pub async fn start_on(db: &Path, options: &Options) -> Self {
        let mut command = Command::new(env!("CARGO_BIN_EXE_landform"));
        if let Some(n) = options.max_descriptors {
            use std::os::unix::process::CommandExt;
            // SAFETY: setrlimit is async-signal-safe and touches only the child's limits.
            unsafe {
                command.pre_exec(move || {
                    let limit = libc::rlimit { rlim_cur: n, rlim_max: n };
                    if libc::setrlimit(libc::RLIMIT_NOFILE, &limit) == 0 {
                        Ok(())
                    } else {
                        Err(std::io::Error::last_os_error())
                    }
                });
            }
        }
        let mut child = command
            .args(["serve", "--addr", "127.0.0.1:0", "--database"])
            .arg(options.database_url.as_deref().map_or(db.as_os_str(), std::ffi::OsStr::new))
            .args(["--workers", &options.workers.to_string()])
            .args(["--queue-capacity", &options.queue_capacity.to_string()])
            .args(["--job-timeout-secs", &options.job_timeout_secs.to_string()])
            .args(["--max-body-bytes", &options.max_body_bytes.to_string()])
            .args(["--max-grid-cells", &options.max_grid_cells.to_string()])
            .args(&options.extra)
            .envs(options.envs.iter().map(|(k, v)| (k, v)))
            .env("RUST_LOG", "warn")
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start the landform binary");
        let stdout = child.stdout.take().expect("stdout");
        let base = tokio::task::spawn_blocking(move || {
            let mut lines = BufReader::new(stdout).lines();
            let line = lines.next().expect("server printed nothing").expect("read stdout");
            // Keep draining so the child never blocks on a full pipe.
            std::thread::spawn(move || for _ in lines {});
            line.trim().strip_prefix("listening on ").expect("listening line").to_string()
        })
        .await
        .expect("read address");
        let client = reqwest::Client::builder().timeout(Duration::from_secs(120)).build().expect("client");
        let lf = landform_client::Client::with_http(client.clone(), base.clone());
        Self { base, client, lf, db: db.to_path_buf(), child, _dir: None }
    }

    /// The server process's id (to read its memory from /proc).
    #[allow(dead_code)]
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{}", self.base, path)
    }

    /// SIGTERM, as an orchestrator stops a service; waits (at most `within`) for the process
    /// to exit and says whether it did.
    pub fn terminate(mut self, within: Duration) -> bool {
        let _ = Command::new("kill").args(["-TERM", &self.child.id().to_string()]).status();
        let start = Instant::now();
        while start.elapsed() < within {
            if let Ok(Some(_)) = self.child.try_wait() {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }

    /// Stop the process at once (like a crash), leaving the database as it is.
    pub fn kill(mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// POST a body; returns (status, json).
    pub async fn post(&self, path: &str, body: &Value) -> (u16, Value) {
        let res = self.client.post(self.url(path)).json(body).send().await.expect("POST");
        let status = res.status().as_u16();
        (status, res.json().await.unwrap_or(Value::Null))
    }

    pub async fn get_json(&self, path: &str) -> (u16, Value) {
        let res = self.client.get(self.url(path)).send().await.expect("GET");
        let status = res.status().as_u16();
        (status, res.json().await.unwrap_or(Value::Null))
    }

    /// Submit a job through the client and return its document.
    pub async fn submit(&self, kind: &str, body: &Value) -> Value {
        let job = self.lf.submit_json(kind, body, &Default::default()).await;
        let job = job.unwrap_or_else(|e| panic!("submit {kind}: {e}"));
        serde_json::to_value(job.document()).expect("a job document")
    }

    /// Poll until the job has ended (at most 5 minutes).
    pub async fn wait_done(&self, id: &str) -> Value {
        let start = Instant::now();
        let mut job = self.lf.job(id).await.unwrap_or_else(|e| panic!("job {id}: {e}"));
        loop {
            if job.document().status.is_terminal() {
                return serde_json::to_value(job.document()).expect("a job document");
            }
            assert!(start.elapsed() < Duration::from_secs(300), "job {id} did not end: {:?}", job.document());
            tokio::time::sleep(Duration::from_millis(50)).await;
            job.refresh().await.unwrap_or_else(|e| panic!("job {id}: {e}"));
        }
    }

    /// Submit and wait for success.
    pub async fn run(&self, kind: &str, body: &Value) -> Value {
        let job = self.submit(kind, body).await;
        let done = self.wait_done(job["id"].as_str().unwrap()).await;
        assert_eq!(done["status"], "succeeded", "{done}");
        done
    }

    /// Submit with `Prefer: wait=SECONDS`; returns (status, json).
    pub async fn submit_waiting(&self, kind: &str, body: &Value, seconds: u64) -> (u16, Value) {
        let res = self
            .client
            .post(self.url(&format!("/v1/jobs/{kind}")))
            .header("prefer", format!("wait={seconds}"))
            .json(body)
            .send()
            .await
            .expect("POST");
        let status = res.status().as_u16();
        (status, res.json().await.expect("json"))
    }

    pub async fn artifact(&self, id: &str, name: &str) -> Vec<u8> {
        let job = self.lf.job(id).await.unwrap_or_else(|e| panic!("job {id}: {e}"));
        job.artifact_bytes(name).await.unwrap_or_else(|e| panic!("artifact {name}: {e}"))
    }
}

impl Drop for TestServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// sha256 per artifact name of a finished job.
pub fn artifact_hashes(job: &Value) -> Vec<(String, String)> {
    let mut v: Vec<_> = job["artifacts"]
        .as_array()
        .expect("artifacts")
        .iter()
        .map(|a| (a["name"].as_str().unwrap().to_string(), a["sha256"].as_str().unwrap().to_string()))
        .collect();
    v.sort();
    v
}

/// A body from api/<kind>/<name>.json.
pub fn example(kind: &str, name: &str) -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("api").join(kind).join(format!("{name}.json"));
    serde_json::from_slice(&std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).expect("json")
}
