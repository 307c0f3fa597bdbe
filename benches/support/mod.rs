//! What the benches share: a run context with no store behind it.

use landform::export::MeshSettings;
use std::sync::atomic::AtomicBool;

use landform::jobs::{RunContext, SilentProgress};
use landform::terrain::{Heightfield, TerrainLookup};
use landform::validate::Limits;

pub struct NoStore;

impl TerrainLookup for NoStore {
    fn job_heightfield(&self, job_id: &str) -> Result<Heightfield, String> {
        Err(format!("no job {job_id} in a bench"))
    }
    fn input(&self, sha256: &str) -> Result<Vec<u8>, String> {
        Err(format!("no upload {sha256} in a bench"))
    }
}

/// Run `f` with a context that never cancels, reports nowhere and has no earlier jobs.
#[allow(dead_code)] // not every bench uses both
pub fn with_context<T>(f: impl FnOnce(&RunContext) -> T) -> T {
    with_limits(&Limits::default(), f)
}

/// The same with caps of the bench's choosing.
#[allow(dead_code)]
pub fn with_limits<T>(limits: &Limits, f: impl FnOnce(&RunContext) -> T) -> T {
    let cancel = AtomicBool::new(false);
    f(&RunContext {
        cancel: &cancel,
        sink: &SilentProgress,
        terrain: &NoStore,
        limits,
        mesh: MeshSettings::default(),
        draft: false,
    })
}
