//! A run context for the kinds' unit tests: progress goes nowhere, and every `{"job": …}` terrain resolves
//! to the one heightfield the test supplies.

use crate::export::MeshSettings;
use std::sync::atomic::AtomicBool;

use crate::jobs::{ProgressSink, RunContext, SilentProgress};
use crate::model::Progress;
use crate::terrain::{Heightfield, TerrainLookup, TerrainSource};
use crate::validate::Limits;

struct OneTerrain(Heightfield);

impl TerrainLookup for OneTerrain {
    fn job_heightfield(&self, _job_id: &str) -> Result<Heightfield, String> {
        Ok(self.0.clone())
    }
    fn input(&self, sha256: &str) -> Result<Vec<u8>, String> {
        Err(format!("no upload with sha256 {sha256} in a test"))
    }
}

/// What a [`RunContext`] borrows.
pub struct TestContext {
    pub cancel: AtomicBool,
    pub limits: Limits,
    terrain: OneTerrain,
}

impl TestContext {
    /// A context in which [`job_terrain`] is `terrain`.
    pub fn new(terrain: Heightfield) -> Self {
        Self { cancel: AtomicBool::new(false), limits: Limits::default(), terrain: OneTerrain(terrain) }
    }

    pub fn ctx(&self) -> RunContext<'_> {
        self.ctx_reporting_to(&SilentProgress)
    }

    /// The context with progress and snapshots going to `sink`.
    pub fn ctx_reporting_to<'a>(&'a self, sink: &'a dyn ProgressSink) -> RunContext<'a> {
        RunContext {
            cancel: &self.cancel,
            sink,
            terrain: &self.terrain,
            limits: &self.limits,
            mesh: MeshSettings::default(),
            draft: false,
        }
    }
}

/// A sink that wants a live snapshot at every step and keeps them, so a kind's snapshots can be
/// tested however quickly it runs (the service's sink takes the first after a quarter second).
#[derive(Default)]
pub struct EverySnapshot(pub std::sync::Mutex<Vec<Vec<u8>>>);

impl ProgressSink for EverySnapshot {
    fn progress(&self, _progress: Progress) {}
    fn snapshot_due(&self) -> bool {
        true
    }
    fn snapshot(&self, png: Vec<u8>, _progress: Progress) {
        self.0.lock().expect("not poisoned").push(png);
    }
}

/// A terrain source naming an earlier job, which a [`TestContext`] resolves.
pub fn job_terrain() -> TerrainSource {
    TerrainSource::Job("0190a0f4-4a9e-7c3e-8000-000000000001".to_string())
}
