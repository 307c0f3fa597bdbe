//! Earlier jobs' heightfields, read from the store: how jobs compose (`terrain: {"job": id}`).

use std::sync::Arc;

use crate::export::read_heightfield_npy;
use crate::store::{JobStore, StoreError};
use crate::terrain::{Heightfield, TerrainExtent, TerrainLookup};

use super::{Job, JobStatus};

/// The artifact holding a heightfield job's exact heights.
pub const HEIGHTFIELD_ARTIFACT: &str = "heightfield.npy";

/// Reads for a job of `owner`: another key's jobs are not there for it.
pub struct StoreTerrain {
    pub store: Arc<dyn JobStore>,
    pub owner: Option<String>,
}

/// Store failures are logged; the job or the client hears only that the store failed.
fn store_failed(e: StoreError) -> String {
    tracing::error!(error = %e, "store failure while reading an earlier job's terrain");
    "the job store failed; the server's log has the details".to_string()
}

impl StoreTerrain {
    /// The job, when it can serve as terrain; otherwise why not.
    fn usable(&self, job_id: &str) -> Result<Result<Job, String>, String> {
        Ok(match self.store.get(job_id).map_err(store_failed)? {
            Some(j) if j.owner != self.owner => Err(format!("no job with id {job_id}")),
            None => Err(format!("no job with id {job_id}")),
            Some(j) if j.status != JobStatus::Succeeded => {
                Err(format!("job {job_id} has not succeeded (it is {})", j.status.as_str()))
            }
            Some(j) if !j.artifacts.iter().any(|a| a.name == HEIGHTFIELD_ARTIFACT) => {
                Err(format!("job {job_id} ({}) produced no heightfield", j.kind))
            }
            Some(j) => Ok(j),
        })
    }

    /// Why the job can't serve as terrain, or None when it can.
    pub fn unusable_reason(&self, job_id: &str) -> Result<Option<String>, String> {
        Ok(self.usable(job_id)?.err())
    }
}

impl TerrainLookup for StoreTerrain {
    fn job_heightfield(&self, job_id: &str) -> Result<Heightfield, String> {
        let job = self.usable(job_id)??;
        let cell_size = job
            .result
            .as_ref()
            .and_then(|r| r.pointer("/grid/cell_size_m"))
            .and_then(|v| v.as_f64())
            .ok_or_else(|| format!("job {job_id} has no grid cell size in its result"))?;
        let (_, bytes) = self
            .store
            .artifact(job_id, HEIGHTFIELD_ARTIFACT)
            .map_err(store_failed)?
            .ok_or_else(|| format!("job {job_id} has no {HEIGHTFIELD_ARTIFACT}"))?;
        read_heightfield_npy(&bytes, cell_size as f32)
    }

    fn job_artifact(&self, job_id: &str, name: &str) -> Result<Vec<u8>, String> {
        self.usable(job_id)??;
        let (_, bytes) = self
            .store
            .artifact(job_id, name)
            .map_err(store_failed)?
            .ok_or_else(|| format!("job {job_id} has no {name}"))?;
        Ok(bytes)
    }

    fn input(&self, sha256: &str) -> Result<Vec<u8>, String> {
        self.store.input(sha256).map_err(store_failed)?.ok_or_else(|| format!("no upload with sha256 {sha256}"))
    }

    fn job_extent(&self, job_id: &str) -> Result<TerrainExtent, String> {
        let job = self.usable(job_id)??;
        let result = job.result.unwrap_or_default();
        let number = |pointer: &str| {
            result
                .pointer(pointer)
                .and_then(|v| v.as_f64())
                .ok_or_else(|| format!("job {job_id} has no {pointer} in its result"))
        };
        Ok(TerrainExtent {
            cols: number("/grid/cols")? as u64,
            rows: number("/grid/rows")? as u64,
            cell_size_m: number("/grid/cell_size_m")?,
            z_span_m: (number("/z_max")? - number("/z_min")?).abs(),
        })
    }
}
