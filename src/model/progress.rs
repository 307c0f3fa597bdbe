//! How far a job has got.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// Where a job is: `fraction` in [0, 1], `step` of `steps` within `stage`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Progress {
    pub fraction: f64,
    pub step: u64,
    pub steps: u64,
    pub stage: String,
    pub message: String,
}
