//! Earlier jobs' heightfields, read from the store: how jobs compose (`terrain: {"job": id}`).

use std::sync::Arc;

use crate::export::read_heightfield_npy;
use crate::store::{JobStore, StoreError};
use crate::terrain::{Heightfield, TerrainLookup};

use super::{Job, JobStatus};

/// The artifact holding a heightfield job's exact heights.
pub const HEIGHTFIELD_ARTIFACT: &str = "heightfield.npy";

pub struct StoreTerrain(pub Arc<dyn JobStore>);

/// Store failures are logged; the job or the client hears only that the store failed.
fn store_failed(e: StoreError) -> String {
    tracing::error!(error = %e, "store failure while reading an earlier job's terrain");
    "the job store failed; the server's log has the details".to_string()
}

impl StoreTerrain {
    /// The job, when it can serve as terrain; otherwise why not.
    fn usable(&self, job_id: &str) -> Result<Result<Job, String>, String> {
        Ok(match self.0.get(job_id).map_err(store_failed)? {
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
            .0
            .artifact(job_id, HEIGHTFIELD_ARTIFACT)
            .map_err(store_failed)?
            .ok_or_else(|| format!("job {job_id} has no {HEIGHTFIELD_ARTIFACT}"))?;
        read_heightfield_npy(&bytes, cell_size as f32)
    }

    fn input(&self, sha256: &str) -> Result<Vec<u8>, String> {
        self.0.input(sha256).map_err(store_failed)?.ok_or_else(|| format!("no upload with sha256 {sha256}"))
    }
}
