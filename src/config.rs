//! Configuration: command-line flags with environment fallbacks.

use std::sync::Arc;
use std::time::Duration;

use clap::builder::TypedValueParser;
use clap::Args;

use crate::http::{HttpConfig, DEFAULT_MAX_BODY_BYTES};
use crate::jobs::{EngineConfig, DEFAULT_JOB_TIMEOUT_S, DEFAULT_QUEUE_CAPACITY};
use crate::store::{JobStore, SqliteStore};
use crate::validate::{Limits, DEFAULT_MAX_GRID_CELLS, DEFAULT_MAX_OPERATIONS, DEFAULT_MAX_VOXELS};

/// Settings shared by `serve` and `run`.
#[derive(Args, Clone, Debug)]
pub struct ServiceArgs {
    /// Job store: a SQLite file path (default `landform.db`). Falls back to DATABASE_URL.
    #[arg(long, env = "LANDFORM_DATABASE")]
    pub database: Option<String>,
    /// Threads of the simulation pool (default: all cores).
    #[arg(long, env = "LANDFORM_WORKERS")]
    pub workers: Option<usize>,
    /// Jobs that may wait in the queue before submissions get 503.
    #[arg(long, env = "LANDFORM_QUEUE_CAPACITY", default_value_t = DEFAULT_QUEUE_CAPACITY, value_parser = clap::value_parser!(u64).range(1..).map(|n| n as usize))]
    pub queue_capacity: usize,
    /// Jobs run at the same time; each uses the whole pool.
    #[arg(long, env = "LANDFORM_CONCURRENT_JOBS", default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..).map(|n| n as usize))]
    pub concurrent_jobs: usize,
    /// A job running longer than this many seconds is stopped and fails.
    #[arg(long, env = "LANDFORM_JOB_TIMEOUT_SECS", default_value_t = DEFAULT_JOB_TIMEOUT_S, value_parser = clap::value_parser!(u64).range(1..))]
    pub job_timeout_secs: u64,
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

    pub fn open_store(&self) -> anyhow::Result<Arc<dyn JobStore>> {
        let location = self.database_location();
        if location.starts_with("postgres://") || location.starts_with("postgresql://") {
            anyhow::bail!("this build has only the embedded SQLite store; give --database a file path");
        }
        let path = location.strip_prefix("sqlite://").unwrap_or(&location);
        Ok(Arc::new(SqliteStore::open(path)?))
    }

    pub fn engine_config(&self) -> EngineConfig {
        EngineConfig {
            workers: self.workers.filter(|&n| n > 0).unwrap_or_else(|| EngineConfig::default().workers),
            queue_capacity: self.queue_capacity,
            concurrent_jobs: self.concurrent_jobs,
            job_timeout: Duration::from_secs(self.job_timeout_secs),
            limits: Limits {
                max_grid_cells: self.max_grid_cells,
                max_operations: self.max_operations,
                max_voxels: self.max_voxels,
            },
        }
    }
}

/// Settings of the HTTP server only.
#[derive(Args, Clone, Debug)]
pub struct HttpArgs {
    /// Address to listen on; port 0 picks a free one (the bound address is printed).
    #[arg(long, env = "LANDFORM_ADDR", default_value = "127.0.0.1:8080")]
    pub addr: String,
    /// Largest request body in bytes; larger bodies get 413.
    #[arg(long, env = "LANDFORM_MAX_BODY_BYTES", default_value_t = DEFAULT_MAX_BODY_BYTES)]
    pub max_body_bytes: usize,
    /// Origins allowed by CORS, comma-separated; `*` allows any.
    #[arg(long, env = "LANDFORM_CORS_ORIGINS", value_delimiter = ',', default_value = "*")]
    pub cors_origins: Vec<String>,
}

impl HttpArgs {
    pub fn http_config(&self) -> HttpConfig {
        HttpConfig { max_body_bytes: self.max_body_bytes, cors_origins: self.cors_origins.clone() }
    }
}
