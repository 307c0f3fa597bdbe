//! The recorded sequence (paper §4.5): the starting terrain plus every deformation applied.
//! It is the terrain, compressed: replay applies the operations with no search.

use serde::{Deserialize, Serialize};

use crate::jobs::Sequence;
use crate::terrain::TerrainSource;

/// `sequence.json` of a deform-terrain job.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeformSequence {
    /// The starting terrain, as requested.
    pub terrain: TerrainSource,
    /// In the order applied.
    pub operations: Vec<Deformation>,
}

/// One truncated-Gaussian deformation: the vertex (col, row) moves to `amplitude` and the
/// cells within `radius_cells` follow by the kernel. `x`, `z` and `radius_m` are the same in
/// metres, for reading; replay uses the grid fields.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Deformation {
    pub x: f64,
    pub z: f64,
    pub col: u32,
    pub row: u32,
    /// Metres: the height the vertex moves to. An f32, so the JSON round trip is exact.
    pub amplitude: f32,
    pub radius_cells: u32,
    pub radius_m: f64,
}

impl Sequence for DeformSequence {
    fn steps(&self) -> u64 {
        self.operations.len() as u64
    }
}
