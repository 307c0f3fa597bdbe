//! A request to stop long work early, visible to every layer: the engine raises it when a job
//! is cancelled or runs past its time limit, and meshing, export and the kinds look at it
//! between chunks of work, so a stopped job ends within a moment wherever it is.

use std::sync::atomic::{AtomicBool, Ordering};

/// Where a piece of work looks to see whether it should stop. `Stop::NEVER` for work that
/// runs to the end (tests, benchmarks, the CLI's own steps).
#[derive(Clone, Copy, Debug)]
pub struct Stop<'a>(Option<&'a AtomicBool>);

/// The work stopped before it finished because a stop was requested.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("stopped on request")]
pub struct Stopped;

impl Default for Stop<'_> {
    fn default() -> Self {
        Stop::NEVER
    }
}

impl<'a> Stop<'a> {
    pub const NEVER: Stop<'static> = Stop(None);

    pub fn new(flag: &'a AtomicBool) -> Self {
        Stop(Some(flag))
    }

    /// Whether a stop can ever be requested (`false` for [`Stop::NEVER`]).
    pub fn can_stop(&self) -> bool {
        self.0.is_some()
    }

    pub fn requested(&self) -> bool {
        self.0.is_some_and(|f| f.load(Ordering::Relaxed))
    }

    /// `Err(Stopped)` once a stop was requested.
    pub fn check(&self) -> Result<(), Stopped> {
        if self.requested() {
            Err(Stopped)
        } else {
            Ok(())
        }
    }
}
