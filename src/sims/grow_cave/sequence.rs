//! The recorded sequence: per drip site, its place, its mineral and the rings of every pass.
//! Replay until pass k keeps the rings the first k passes grew.

use serde::{Deserialize, Serialize};

use super::growth::SiteGrowth;
use super::params::Mineral;
use crate::jobs::Sequence;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RecordedSite {
    pub mineral: Mineral,
    #[serde(flatten)]
    pub growth: SiteGrowth,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaveSequence {
    /// Seeds the roof and floor relief (the rings' roughness is a hash of the site).
    pub seed: u64,
    pub passes: u32,
    pub sites: Vec<RecordedSite>,
}

impl Sequence for CaveSequence {
    fn steps(&self) -> u64 {
        self.passes as u64
    }
}

impl CaveSequence {
    /// The cave after `until` passes (all when `None` or beyond the end).
    pub fn until(&self, until: Option<u64>) -> CaveSequence {
        let Some(k) = until.filter(|&k| k < self.passes as u64) else { return self.clone() };
        let k = k as u32;
        CaveSequence {
            seed: self.seed,
            passes: k,
            sites: self.sites.iter().map(|s| RecordedSite { mineral: s.mineral, growth: s.growth.until(k) }).collect(),
        }
    }
}
