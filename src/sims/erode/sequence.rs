//! The recorded sequence: the input (by source and hash), every setting the erosion used, and
//! a checksum of the heights after each iteration. The erosion has no search and draws no
//! random numbers, so replaying is re-running, checked iteration by iteration.

use serde::{Deserialize, Serialize};

use super::keep::Keep;
use super::params::{BaseLevel, ErodeParams, Hydraulic, Switch, Thermal};
use crate::jobs::Sequence;
use crate::terrain::TerrainSource;

/// `sequence.json` of an erode job.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ErodeSequence {
    /// The starting terrain, as requested.
    pub terrain: TerrainSource,
    /// sha256 of the starting heights (little-endian f32s): a replay refuses another terrain.
    pub input_sha256: String,
    pub sea_level: f32,
    pub time_step_years: f64,
    pub hydraulic: Switch<Hydraulic>,
    pub thermal: Switch<Thermal>,
    /// Where water left the map.
    #[serde(default, skip_serializing_if = "BaseLevel::is_all")]
    pub base_level: BaseLevel,
    /// The areas kept at their starting heights.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub keep: Vec<Keep>,
    /// After each iteration, the first 16 hex digits of the sha256 of the heights as
    /// little-endian f32s.
    pub checksums: Vec<String>,
}

impl Sequence for ErodeSequence {
    fn steps(&self) -> u64 {
        self.checksums.len() as u64
    }
}

impl ErodeSequence {
    /// The request this sequence replays, for `iterations` iterations.
    pub fn params(&self, iterations: u32, tiles: Option<crate::export::TileGrid>) -> ErodeParams {
        ErodeParams {
            terrain: self.terrain.clone(),
            sea_level: self.sea_level,
            iterations,
            time_step_years: self.time_step_years,
            hydraulic: self.hydraulic.clone(),
            thermal: self.thermal.clone(),
            base_level: self.base_level,
            keep: self.keep.clone(),
            tiles,
        }
    }
}
