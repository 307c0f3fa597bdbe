//! The recorded sequence: for every voxel, the step that removed it — a compact volume,
//! deflated — plus the per-step counts, and with gravity the falls (the voxels indexed by the
//! cell each started in). Replay until step k keeps the voxels removed after k and the falls
//! up to k.

use std::io::{Read, Write};

use base64::Engine as _;
use serde::{Deserialize, Serialize};

use super::gravity::{replay_cells, Fall};
use super::grid::{Grid, NEVER_ROCK, ROCK};
use super::rock::Rock;
use super::weathering::History;
use crate::jobs::{Sequence, SimError};

/// The encoding of `removal_steps`: each voxel's 16-bit state (0 = rock at the end, 65535 =
/// never rock, otherwise the removing step), in the grid's index order (x fastest, then z, then
/// y), stored as all low bytes then all high bytes, raw-deflated, base64.
pub const FORMAT: &str = "u16-planes-deflate-base64";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WeatherSequence {
    pub format: String,
    /// Voxels along X, Y, Z.
    pub grid: [u32; 3],
    /// Seeds the in-layer resistance noise (vertex colours depend on it).
    pub seed: u64,
    pub steps: u32,
    pub active_per_step: Vec<u32>,
    pub removed_per_step: Vec<u32>,
    pub removal_steps: String,
    /// With gravity: the pieces that fell, in the order they fell (`removal_steps` is then
    /// indexed by the cell each voxel started in).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub falls: Vec<Fall>,
}

impl Sequence for WeatherSequence {
    fn steps(&self) -> u64 {
        self.steps as u64
    }
}

impl WeatherSequence {
    /// The sequence of a run: the rock's state (by identity, with gravity) and falls.
    pub fn record(rock: &Rock, seed: u64, history: &History) -> Self {
        match &rock.gravity {
            Some(g) => Self { falls: g.falls.clone(), ..Self::of_state(&rock.grid, seed, history, &g.record) },
            None => Self::of_state(&rock.grid, seed, history, &rock.state),
        }
    }

    fn of_state(grid: &Grid, seed: u64, history: &History, state: &[u16]) -> Self {
        Self {
            format: FORMAT.into(),
            grid: [grid.nx as u32, grid.ny as u32, grid.nz as u32],
            seed,
            steps: history.steps(),
            active_per_step: history.active_per_step.clone(),
            removed_per_step: history.removed_per_step.clone(),
            removal_steps: encode(state),
            falls: Vec::new(),
        }
    }

    /// The sequence a run of `until` steps would have recorded (all when `None` or beyond).
    pub fn until(&self, grid: &Grid, until: Option<u64>) -> Result<Self, SimError> {
        let (record, history) = self.state_until(grid, until)?;
        let k = history.steps();
        let falls = self.falls.iter().filter(|f| f.step <= k).copied().collect();
        Ok(Self { falls, ..Self::of_state(grid, self.seed, &history, &record) })
    }

    /// The cells the sequence ends with, each cell's voxel identity when anything fell, and
    /// how many voxels were rock at the start.
    #[allow(clippy::type_complexity)]
    pub fn cells(&self, grid: &Grid) -> Result<(Vec<u16>, Option<Vec<u32>>, u64), SimError> {
        let (record, _) = self.state_until(grid, None)?;
        let initial = record.iter().filter(|&&s| s != NEVER_ROCK).count() as u64;
        if self.falls.is_empty() {
            return Ok((record, None, initial));
        }
        let steps = u16::try_from(self.steps).map_err(|_| SimError::Failed("too many steps".into()))?;
        let (cells, origin) = replay_cells(grid, &record, &self.falls, steps);
        Ok((cells, Some(origin), initial))
    }

    pub fn history(&self) -> History {
        History { active_per_step: self.active_per_step.clone(), removed_per_step: self.removed_per_step.clone() }
    }

    /// The recorded volume after `until` steps (all of them when `None`) and the history so
    /// far: the cells, without gravity; by identity, with it.
    pub fn state_until(&self, grid: &Grid, until: Option<u64>) -> Result<(Vec<u16>, History), SimError> {
        if self.format != FORMAT {
            return Err(SimError::Failed(format!("unknown sequence format {:?}", self.format)));
        }
        if self.grid != [grid.nx as u32, grid.ny as u32, grid.nz as u32] {
            return Err(SimError::Failed("the sequence's grid differs from the request's".into()));
        }
        let mut state = decode(&self.removal_steps, grid.len())?;
        let mut history = self.history();
        if let Some(k) = until.filter(|&k| k < self.steps as u64) {
            let k = k as u16;
            for s in state.iter_mut() {
                if *s != NEVER_ROCK && *s > k {
                    *s = ROCK;
                }
            }
            history.active_per_step.truncate(k as usize);
            history.removed_per_step.truncate(k as usize);
        }
        Ok((state, history))
    }
}

fn encode(state: &[u16]) -> String {
    let mut planes = Vec::with_capacity(state.len() * 2);
    planes.extend(state.iter().map(|s| *s as u8));
    planes.extend(state.iter().map(|s| (*s >> 8) as u8));
    let mut encoder = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::new(6));
    encoder.write_all(&planes).expect("deflate to memory");
    let deflated = encoder.finish().expect("deflate to memory");
    base64::engine::general_purpose::STANDARD.encode(deflated)
}

fn decode(text: &str, voxels: usize) -> Result<Vec<u16>, SimError> {
    let bad = |why: String| SimError::Failed(format!("stored removal steps unreadable: {why}"));
    let deflated = base64::engine::general_purpose::STANDARD.decode(text).map_err(|e| bad(e.to_string()))?;
    let mut planes = Vec::with_capacity(voxels * 2);
    flate2::read::DeflateDecoder::new(&deflated[..])
        .take(voxels as u64 * 2 + 1)
        .read_to_end(&mut planes)
        .map_err(|e| bad(e.to_string()))?;
    if planes.len() != voxels * 2 {
        return Err(bad(format!("{} bytes for {voxels} voxels", planes.len())));
    }
    let (lo, hi) = planes.split_at(voxels);
    Ok(lo.iter().zip(hi).map(|(&l, &h)| l as u16 | (h as u16) << 8).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn removal_steps_round_trip_and_truncate() {
        let grid = Grid { nx: 3, ny: 2, nz: 2, voxel_size_m: 1.0, floating: false };
        let state: Vec<u16> = vec![0, 1, 2, 3, NEVER_ROCK, 0, 5, 5, 0, 0, 1, 2];
        let history = History { active_per_step: vec![9, 8, 7, 6, 5], removed_per_step: vec![2, 2, 1, 0, 2] };
        let seq = WeatherSequence::of_state(&grid, 7, &history, &state);
        assert_eq!(seq.state_until(&grid, None).unwrap().0, state);
        let (two, h) = seq.state_until(&grid, Some(2)).unwrap();
        assert_eq!(two, vec![0, 1, 2, 0, NEVER_ROCK, 0, 0, 0, 0, 0, 1, 2]);
        assert_eq!(h.removed_per_step, vec![2, 2]);
        let other = Grid { nx: 4, ..grid };
        assert!(seq.state_until(&other, None).is_err());
    }
}
