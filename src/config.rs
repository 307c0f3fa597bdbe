//! Configuration: command-line flags with environment fallbacks.

use std::sync::Arc;
use std::time::Duration;

use clap::builder::TypedValueParser;
use clap::Args;

use crate::http::auth::{DEFAULT_KEY_ACTIVE_JOBS, DEFAULT_KEY_SUBMISSIONS_PER_MINUTE};
use crate::http::server::ConnectionLimits;
use crate::http::{ApiKeys, HttpConfig, KeyLimits, DEFAULT_MAX_BODY_BYTES};
use crate::jobs::{
    default_memory_budget, EngineConfig, WorkerConfig, DEFAULT_CONCURRENT_JOBS, DEFAULT_JOB_TIMEOUT_S,
    DEFAULT_QUEUE_CAPACITY,
};
use crate::store::{EventLog, ObjectArtifacts, PostgresStore, SqliteStore};
use crate::validate::{Limits, DEFAULT_MAX_GRID_CELLS, DEFAULT_MAX_OPERATIONS, DEFAULT_MAX_VOXELS};

/// Settings shared by `serve` and `run`.
#[derive(Args, Clone, Debug)]
pub struct ServiceArgs {
    /// Job store: a SQLite file path (default `landform.db`). Falls back to DATABASE_URL.
    #[arg(long, env = "LANDFORM_DATABASE")]
    pub database: Option<String>,
    /// Where artifacts' bytes are kept: in the job store (the default), an S3-compatible bucket
    /// (`s3://bucket[/prefix]`; credentials, region and endpoint from the usual `AWS_*`
    /// variables, e.g. `AWS_ENDPOINT` and `AWS_ALLOW_HTTP=true` for a local server) or a
    /// directory (`file:///path`). Every process of a deployment needs the same one.
    #[arg(long, env = "LANDFORM_ARTIFACT_STORE")]
    pub artifact_store: Option<String>,
    /// Threads of the simulation pool (default: all cores).
    #[arg(long, env = "LANDFORM_WORKERS")]
    pub workers: Option<usize>,
    /// Jobs that may wait in the queue before submissions get 503.
    #[arg(long, env = "LANDFORM_QUEUE_CAPACITY", default_value_t = DEFAULT_QUEUE_CAPACITY, value_parser = clap::value_parser!(u64).range(1..).map(|n| n as usize))]
    pub queue_capacity: usize,
    /// Most jobs run at the same time (they share the pool; the memory budget decides first).
    #[arg(long, env = "LANDFORM_CONCURRENT_JOBS", default_value_t = DEFAULT_CONCURRENT_JOBS, value_parser = clap::value_parser!(u64).range(1..).map(|n| n as usize))]
    pub concurrent_jobs: usize,
    /// Bytes the running jobs' estimated peak memory may add up to (default: half the machine's
    /// memory). A job whose estimate alone is larger is refused with 413.
    #[arg(long, env = "LANDFORM_MEMORY_BUDGET", value_parser = clap::value_parser!(u64).range(1..))]
    pub memory_budget: Option<u64>,
    /// A job running longer than this many seconds is stopped and fails.
    #[arg(long, env = "LANDFORM_JOB_TIMEOUT_SECS", default_value_t = DEFAULT_JOB_TIMEOUT_S, value_parser = clap::value_parser!(u64).range(1..))]
    pub job_timeout_secs: u64,
    /// On SIGTERM, seconds running jobs may take to finish before they go back to the queue.
    #[arg(long, env = "LANDFORM_SHUTDOWN_DEADLINE_SECS", default_value_t = 30)]
    pub shutdown_deadline_secs: u64,
    /// Most samples (cols × rows) a heightfield may have; larger requests get 413.
    #[arg(long, env = "LANDFORM_MAX_GRID_CELLS", default_value_t = DEFAULT_MAX_GRID_CELLS)]
    pub max_grid_cells: u64,
    /// Most voxels a volumetric job may use; larger requests get 413.
    #[arg(long, env = "LANDFORM_MAX_VOXELS", default_value_t = DEFAULT_MAX_VOXELS)]
    pub max_voxels: u64,
    /// Most operations one request may carry.
    #[arg(long, env = "LANDFORM_MAX_OPERATIONS", default_value_t = DEFAULT_MAX_OPERATIONS)]
    pub max_operations: u64,
}

impl ServiceArgs {
    pub fn database_location(&self) -> String {
        self.database
            .clone()
            .or_else(|| std::env::var("DATABASE_URL").ok().filter(|s| !s.is_empty()))
            .unwrap_or_else(|| "landform.db".to_string())
    }

    /// The job store; `for_worker`: a worker's (on PostgreSQL, commits that need not wait for
    /// the disk, see `PostgresStore::with_relaxed_commits`).
    pub fn open_store(&self, for_worker: bool) -> anyhow::Result<Arc<dyn EventLog>> {
        let location = self.database_location();
        let objects =
            self.artifact_store.as_deref().filter(|s| !s.is_empty()).map(ObjectArtifacts::open).transpose()?;
        if location.starts_with("postgres://") || location.starts_with("postgresql://") {
            let mut store = PostgresStore::open(&location)?.with_objects(objects);
            if for_worker {
                store = store.with_relaxed_commits()?;
            }
            return Ok(Arc::new(store));
        }
        let path = location.strip_prefix("sqlite://").unwrap_or(&location);
        Ok(Arc::new(SqliteStore::open(path)?.with_objects(objects)))
    }

    pub fn engine_config(&self) -> EngineConfig {
        EngineConfig {
            workers: self.workers.filter(|&n| n > 0).unwrap_or_else(|| EngineConfig::default().workers),
            queue_capacity: self.queue_capacity,
            concurrent_jobs: self.concurrent_jobs,
            memory_budget: self.memory_budget.unwrap_or_else(default_memory_budget),
            job_timeout: Duration::from_secs(self.job_timeout_secs),
            limits: Limits {
                max_grid_cells: self.max_grid_cells,
                max_operations: self.max_operations,
                max_voxels: self.max_voxels,
            },
            runs_jobs: true,
        }
    }

    /// The flags that give a `landform worker` child these settings.
    pub fn worker_command_args(&self, worker: &WorkerArgs) -> Vec<String> {
        let engine = self.engine_config();
        let mut args: Vec<String> = [
            ("--database", self.database_location()),
            ("--workers", engine.workers.to_string()),
            ("--queue-capacity", self.queue_capacity.to_string()),
            ("--concurrent-jobs", self.concurrent_jobs.to_string()),
            ("--memory-budget", engine.memory_budget.to_string()),
            ("--job-timeout-secs", self.job_timeout_secs.to_string()),
            ("--shutdown-deadline-secs", self.shutdown_deadline_secs.to_string()),
            ("--max-grid-cells", self.max_grid_cells.to_string()),
            ("--max-voxels", self.max_voxels.to_string()),
            ("--max-operations", self.max_operations.to_string()),
            ("--lease-secs", worker.lease_secs.to_string()),
            ("--nice", worker.nice.to_string()),
        ]
        .into_iter()
        .flat_map(|(flag, value)| [flag.to_string(), value])
        .collect();
        if let Some(location) = &self.artifact_store {
            args.extend(["--artifact-store".to_string(), location.clone()]);
        }
        if let Some(name) = &worker.worker_name {
            args.extend(["--worker-name".to_string(), name.clone()]);
        }
        args
    }

    /// A worker's settings: the same budget, concurrency, time limit and caps as an engine's.
    pub fn worker_config(&self, worker: &WorkerArgs) -> WorkerConfig {
        let engine = self.engine_config();
        WorkerConfig {
            name: worker.worker_name.clone().unwrap_or_else(|| format!("worker-{}", std::process::id())),
            memory_budget: engine.memory_budget,
            concurrent_jobs: engine.concurrent_jobs,
            lease: Duration::from_secs(worker.lease_secs),
            poll: crate::jobs::STORE_POLL,
            job_timeout: engine.job_timeout,
            limits: engine.limits,
        }
    }
}

/// Which parts of the service a process runs.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Role {
    /// The HTTP API, and the jobs in a worker process it supervises.
    #[default]
    All,
    /// The HTTP API only: jobs wait in the store for workers (`landform worker`) to claim.
    Api,
    /// A worker only (as `landform worker`).
    Worker,
}

/// Settings of a worker that claims jobs from the store.
#[derive(Args, Clone, Debug)]
pub struct WorkerArgs {
    /// Seconds a claimed job stays this worker's without a renewal (renewed every third of
    /// it): how soon another worker takes over the jobs of one that died. A worker `serve`
    /// supervises is killed and replaced when it has been silent this long (at least 3 s).
    #[arg(long, env = "LANDFORM_LEASE_SECS", default_value_t = DEFAULT_LEASE_SECS, value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub lease_secs: u64,
    /// The name kept with this worker's claims (default `worker-PID`).
    #[arg(long, env = "LANDFORM_WORKER_NAME")]
    pub worker_name: Option<String>,
    /// Lower this worker's CPU priority by N (0–19; `nice`): an API process on the same machine
    /// (`serve`'s own, or replicas beside workers) then answers promptly however busy the jobs
    /// keep the cores. A worker with a machine to itself loses nothing by it. Where the kernel
    /// groups processes by session (autogroup), the worker moves into a session of its own and
    /// lowers that session's group by N as well, or a niceness would count within its session only.
    #[arg(long, env = "LANDFORM_WORKER_NICE", default_value_t = DEFAULT_WORKER_NICE, value_parser = clap::value_parser!(i32).range(0..=19))]
    pub nice: i32,
    /// Give the jobs back and exit when standard input closes: `serve` holds it open for the
    /// worker it supervises, so the worker never outlives it. Also beats a heartbeat on
    /// standard output, by which `serve` kills a worker that stopped (`supervisor`).
    #[arg(long, hide = true)]
    pub exit_with_parent: bool,
}

/// Default niceness of a worker: 10, which leaves about 90 % of a contended core to a
/// process at 0, such as the API beside it.
pub const DEFAULT_WORKER_NICE: i32 = 10;

/// Default lease: a crashed worker's job is claimed again within about five seconds, and a
/// renewal every 1.7 s costs one short UPDATE.
pub const DEFAULT_LEASE_SECS: u64 = 5;

/// Settings of the HTTP server only.
#[derive(Args, Clone, Debug)]
pub struct HttpArgs {
    /// Address to listen on; port 0 picks a free one (the bound address is printed).
    #[arg(long, env = "LANDFORM_ADDR", default_value = "127.0.0.1:8080")]
    pub addr: String,
    /// Most client connections open at once (default: three quarters of the descriptors the
    /// process may open, after raising its soft limit to the hard one). At the limit, the
    /// connection waiting longest with no request in flight is closed to make room; when all
    /// are busy, a newcomer gets 503.
    #[arg(long, env = "LANDFORM_MAX_CONNECTIONS", value_parser = clap::value_parser!(u64).range(1..=1_000_000).map(|n| n as usize))]
    pub max_connections: Option<usize>,
    /// Seconds a client has to send a request's headers.
    #[arg(long, env = "LANDFORM_HEADER_TIMEOUT_SECS", default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub header_timeout_secs: u64,
    /// Seconds a request's body may take to arrive whole (408 beyond).
    #[arg(long, env = "LANDFORM_BODY_TIMEOUT_SECS", default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub body_timeout_secs: u64,
    /// Seconds a connection may stay open with no request in flight.
    #[arg(long, env = "LANDFORM_IDLE_TIMEOUT_SECS", default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub idle_timeout_secs: u64,
    /// Seconds a reply (or an event stream) may wait for the client to read any of it before
    /// its connection is closed.
    #[arg(long, env = "LANDFORM_WRITE_TIMEOUT_SECS", default_value_t = 30, value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub write_timeout_secs: u64,
    /// Largest request body in bytes; larger bodies get 413.
    #[arg(long, env = "LANDFORM_MAX_BODY_BYTES", default_value_t = DEFAULT_MAX_BODY_BYTES)]
    pub max_body_bytes: usize,
    /// Origins whose pages may call the API (CORS, and changing state), comma-separated; `*`
    /// allows any. Default: none but the server's own pages (the playground).
    #[arg(long, env = "LANDFORM_CORS_ORIGINS", value_delimiter = ',')]
    pub cors_origins: Vec<String>,
    /// API keys file: `NAME KEY [submissions_per_minute=N] [active_jobs=N] [memory_bytes=N]` a
    /// line. With keys, every /v1 call needs `Authorization: Bearer KEY`. LANDFORM_API_KEYS may
    /// instead hold the lines themselves (separated by newlines or `;`).
    #[arg(long, env = "LANDFORM_API_KEYS_FILE")]
    pub api_keys: Option<std::path::PathBuf>,
    /// With keys, `/docs` and `/openapi.json` need a key too (`/metrics` always does with keys).
    #[arg(long, env = "LANDFORM_PROTECT_OPERATIONS")]
    pub protect_operations: bool,
    /// With keys, `/metrics` answers without one (for a scraper on a private network).
    #[arg(long, env = "LANDFORM_PUBLIC_METRICS")]
    pub public_metrics: bool,
    /// Each key's submissions (jobs and replays) per minute, unless its line says otherwise.
    #[arg(long, env = "LANDFORM_KEY_SUBMISSIONS_PER_MINUTE", default_value_t = DEFAULT_KEY_SUBMISSIONS_PER_MINUTE, value_parser = clap::value_parser!(u32).range(1..))]
    pub key_submissions_per_minute: u32,
    /// Each key's jobs queued or running at once, unless its line says otherwise.
    #[arg(long, env = "LANDFORM_KEY_ACTIVE_JOBS", default_value_t = DEFAULT_KEY_ACTIVE_JOBS, value_parser = clap::value_parser!(u32).range(1..))]
    pub key_active_jobs: u32,
    /// Each key's estimated memory of queued and running jobs at once, bytes (default: the
    /// memory budget), unless its line says otherwise.
    #[arg(long, env = "LANDFORM_KEY_MEMORY_BYTES", value_parser = clap::value_parser!(u64).range(1..))]
    pub key_memory_bytes: Option<u64>,
}

impl HttpArgs {
    /// The HTTP settings; `memory_budget` is the default of each key's memory quota.
    pub fn http_config(&self, memory_budget: u64) -> anyhow::Result<HttpConfig> {
        let text = match (&self.api_keys, std::env::var("LANDFORM_API_KEYS").ok().filter(|s| !s.trim().is_empty())) {
            (Some(path), _) => Some(
                std::fs::read_to_string(path)
                    .map_err(|e| anyhow::anyhow!("cannot read the API keys file {}: {e}", path.display()))?,
            ),
            (None, Some(inline)) => Some(inline.replace(';', "\n")),
            (None, None) => None,
        };
        let defaults = KeyLimits {
            submissions_per_minute: self.key_submissions_per_minute,
            active_jobs: self.key_active_jobs,
            memory_bytes: self.key_memory_bytes.unwrap_or(memory_budget),
        };
        let keys = text.map(|t| ApiKeys::parse(&t, defaults, self.protect_operations)).transpose()?.map(|mut k| {
            k.public_metrics = self.public_metrics;
            Arc::new(k)
        });
        if let Some(k) = &keys {
            tracing::info!(keys = ?k, "API keys required on /v1");
        }
        Ok(HttpConfig {
            max_body_bytes: self.max_body_bytes,
            cors_origins: self.cors_origins.clone(),
            keys,
            body_timeout: Duration::from_secs(self.body_timeout_secs),
        })
    }

    /// The accept loop's limits (call after `raise_descriptor_limit`, which the default
    /// connection limit depends on).
    pub fn connection_limits(&self) -> ConnectionLimits {
        ConnectionLimits {
            max_connections: self.max_connections.unwrap_or_else(crate::http::server::default_max_connections),
            header_timeout: Duration::from_secs(self.header_timeout_secs),
            body_timeout: Duration::from_secs(self.body_timeout_secs),
            idle_timeout: Duration::from_secs(self.idle_timeout_secs),
            write_timeout: Duration::from_secs(self.write_timeout_secs),
        }
    }
}
