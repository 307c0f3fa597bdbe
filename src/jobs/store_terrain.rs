//! Earlier jobs' heightfields, read from the store: how jobs compose (`terrain: {"job": id}`).

use std::sync::Arc;

use crate::export::read_heightfield_npy;
use crate::store::JobStore;
use crate::terrain::{Heightfield, TerrainLookup};

use super::JobStatus;

/// The artifact holding a heightfield job's exact heights.
pub const HEIGHTFIELD_ARTIFACT: &str = "heightfield.npy";

pub struct StoreTerrain(pub Arc<dyn JobStore>);

impl StoreTerrain {
    /// Why the job can't serve as terrain, or None when it can.
    pub fn unusable_reason(&self, job_id: &str) -> Result<Option<String>, String> {
        let job = self.0.get(job_id).map_err(|e| e.to_string())?;
        Ok(match job {
            None => Some(format!("no job with id {job_id}")),
            Some(j) if j.status != JobStatus::Succeeded => {
                Some(format!("job {job_id} has not succeeded (it is {})", j.status.as_str()))
            }
            Some(j) if !j.artifacts.iter().any(|a| a.name == HEIGHTFIELD_ARTIFACT) => {
                Some(format!("job {job_id} ({}) produced no heightfield", j.kind))
            }
            Some(_) => None,
        })
    }
}

impl TerrainLookup for StoreTerrain {
    fn job_heightfield(&self, job_id: &str) -> Result<Heightfield, String> {
        if let Some(reason) = self.unusable_reason(job_id)? {
            return Err(reason);
        }
        let job = self.0.get(job_id).map_err(|e| e.to_string())?.ok_or("job vanished")?;
        let cell_size = job
            .result
            .as_ref()
            .and_then(|r| r.pointer("/grid/cell_size_m"))
            .and_then(|v| v.as_f64())
            .ok_or_else(|| format!("job {job_id} has no grid cell size in its result"))?;
        let (_, bytes) = self
            .0
            .artifact(job_id, HEIGHTFIELD_ARTIFACT)
            .map_err(|e| e.to_string())?
            .ok_or_else(|| format!("job {job_id} has no {HEIGHTFIELD_ARTIFACT}"))?;
        read_heightfield_npy(&bytes, cell_size as f32)
    }

    fn has_heightfield(&self, job_id: &str) -> Result<bool, String> {
        Ok(self.unusable_reason(job_id)?.is_none())
    }
}
