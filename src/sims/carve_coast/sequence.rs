//! The recorded sequence: the carved spheres in order (centre, radius, pass). The terrain
//! source and warp are in the request; replay until k carves the first k spheres.

use serde::{Deserialize, Serialize};

use super::implicit::Sphere;
use crate::jobs::Sequence;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoastSequence {
    /// Seeds the warp's noise.
    pub seed: u64,
    /// `[[x, y, z, radius], pass]`, metres, in carving order.
    pub spheres: Vec<Sphere>,
}

impl Sequence for CoastSequence {
    fn steps(&self) -> u64 {
        self.spheres.len() as u64
    }
}

impl CoastSequence {
    pub fn until(&self, until: Option<u64>) -> CoastSequence {
        let k = until.map_or(self.spheres.len(), |k| (k as usize).min(self.spheres.len()));
        CoastSequence { seed: self.seed, spheres: self.spheres[..k].to_vec() }
    }
}
