//! The recorded sequence: the terrain it started from and the carvings in order (authored
//! before, eroded spheres, authored after). The warp is in the request; replay until k carves
//! the first k spheres.

use serde::{Deserialize, Serialize};

use super::implicit::Carving;
use crate::jobs::Sequence;
use crate::terrain::TerrainSource;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoastSequence {
    /// The starting terrain, as requested (replay reads it from the request, which holds the
    /// same).
    pub terrain: TerrainSource,
    /// Seeds the warp's noise.
    pub seed: u64,
    /// In carving order: spheres `[[x, y, z, radius], pass]` and authored capsules
    /// `[[ax, ay, az, bx, by, bz, radius], pass]`, metres, in the warped domain the field is
    /// read in. Authored carvings made before the erosion are pass 0, after it `passes + 1`.
    pub spheres: Vec<Carving>,
}

impl Sequence for CoastSequence {
    fn steps(&self) -> u64 {
        self.spheres.len() as u64
    }
}

impl CoastSequence {
    pub fn until(&self, until: Option<u64>) -> CoastSequence {
        let k = until.map_or(self.spheres.len(), |k| (k as usize).min(self.spheres.len()));
        CoastSequence { terrain: self.terrain.clone(), seed: self.seed, spheres: self.spheres[..k].to_vec() }
    }
}
