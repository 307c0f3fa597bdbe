//! Gravity (the paper's future work; its Figure 2d is a toppled cap): after each step's
//! removals, rock no longer connected to the ground falls straight down as a rigid piece until
//! it rests on rock or the ground, then keeps weathering where it lies, its layers' resistance
//! going with it.
//!
//! Each voxel keeps its identity — the cell it started in — so the recorded sequence stays "the
//! step that removed each voxel" (indexed by that identity) plus the list of falls, each named
//! by its step, its drop and one voxel of the piece; a replay re-finds the piece as that
//! voxel's connected rock, so nothing else needs storing.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use serde::{Deserialize, Serialize};

use super::grid::{Grid, NEVER_ROCK, ROCK};

/// No voxel here.
pub const EMPTY: u32 = u32::MAX;

/// One piece coming to rest: at the end of `step`, the connected rock holding the voxel that
/// started in cell `voxel` dropped `dy` cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Fall {
    pub step: u32,
    pub voxel: u32,
    pub dy: u32,
}

/// What gravity keeps beside the rock's cells.
#[derive(Clone, Debug)]
pub struct Gravity {
    /// Per cell: the identity (starting cell) of the voxel in it, or [`EMPTY`].
    pub origin: Vec<u32>,
    /// Per identity: `ROCK` while it lasts, the step that removed it, or `NEVER_ROCK`.
    pub record: Vec<u16>,
    pub falls: Vec<Fall>,
    /// Per cell: the step in which it was last found connected to the ground.
    grounded: Vec<u16>,
}

impl Gravity {
    pub fn new(state: &[u16]) -> Self {
        let origin = state.iter().enumerate().map(|(i, &s)| if s == ROCK { i as u32 } else { EMPTY }).collect();
        Self { origin, record: state.to_vec(), falls: Vec::new(), grounded: vec![0; state.len()] }
    }

    /// Note the removal of the voxels in `cells` at `step`.
    pub fn removed(&mut self, cells: &[u32], step: u16) {
        for &c in cells {
            let id = std::mem::replace(&mut self.origin[c as usize], EMPTY);
            if id != EMPTY {
                self.record[id as usize] = step;
            }
        }
    }
}

/// The six neighbours of cell `i` that lie in the grid.
fn neighbours(g: &Grid, i: usize) -> impl Iterator<Item = usize> + '_ {
    let (x, y, z) = g.coords(i);
    let (x, y, z) = (x as i64, y as i64, z as i64);
    [(-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)].into_iter().filter_map(move |(dx, dy, dz)| {
        let (a, b, c) = (x + dx, y + dy, z + dz);
        let inside = a >= 0 && b >= 0 && c >= 0 && a < g.nx as i64 && b < g.ny as i64 && c < g.nz as i64;
        inside.then(|| g.index(a as usize, b as usize, c as usize))
    })
}

/// The rock connected to `start`, searched lowest first: `Ok` once it reaches the ground (all
/// it visited is grounded), `Err(piece)` with the whole component, sorted, when it never does.
fn reach_ground(g: &Grid, state: &[u16], grounded: &[u16], step: u16, start: usize) -> Result<Vec<usize>, Vec<usize>> {
    let mut seen = vec![start];
    let mut mark = std::collections::HashSet::from([start]);
    let mut queue = BinaryHeap::from([Reverse((g.coords(start).1, start))]);
    while let Some(Reverse((y, i))) = queue.pop() {
        if y == 0 || grounded[i] == step {
            return Ok(seen);
        }
        for n in neighbours(g, i) {
            if state[n] == ROCK && mark.insert(n) {
                seen.push(n);
                queue.push(Reverse((g.coords(n).1, n)));
            }
        }
    }
    seen.sort_unstable();
    Err(seen)
}

/// How far `piece` (sorted cells) can drop before a cell of it would enter rock outside it or
/// go below the ground.
fn drop_of(g: &Grid, state: &[u16], piece: &[usize]) -> u32 {
    let inside = |i: usize| piece.binary_search(&i).is_ok();
    let plane = g.plane();
    piece
        .iter()
        .map(|&i| {
            let mut dy = 0u32;
            let mut below = i;
            while below >= plane {
                below -= plane;
                if state[below] == ROCK && !inside(below) {
                    break;
                }
                dy += 1;
            }
            dy
        })
        .min()
        .unwrap_or(0)
}

/// Move `piece` (sorted cells) down by `dy`, lowest cells first: each leaves its cell marked
/// as vacated at `step`.
pub fn move_piece(g: &Grid, state: &mut [u16], origin: &mut [u32], piece: &[usize], dy: u32, step: u16) {
    let shift = dy as usize * g.plane();
    for &i in piece {
        let id = std::mem::replace(&mut origin[i], EMPTY);
        state[i] = step;
        state[i - shift] = ROCK;
        origin[i - shift] = id;
    }
}

/// After `step`'s removals (`removed`, cells): find every piece no longer connected to the
/// ground among the rock next to them, lowest first, and let each fall. Returns the falls with
/// the cells each piece left. Floating columns have no ground: nothing falls.
pub fn settle(
    g: &Grid,
    state: &mut [u16],
    gravity: &mut Gravity,
    removed: &[u32],
    step: u16,
) -> Vec<(Fall, Vec<usize>)> {
    if g.floating {
        return Vec::new();
    }
    let mut candidates: Vec<usize> =
        removed.iter().flat_map(|&u| neighbours(g, u as usize)).filter(|&n| state[n] == ROCK).collect();
    candidates.sort_unstable();
    candidates.dedup();
    let mut pieces: Vec<Vec<usize>> = Vec::new();
    let mut in_piece = std::collections::HashSet::new();
    for c in candidates {
        if gravity.grounded[c] == step || in_piece.contains(&c) {
            continue;
        }
        match reach_ground(g, state, &gravity.grounded, step, c) {
            Ok(seen) => seen.into_iter().for_each(|i| gravity.grounded[i] = step),
            Err(piece) => {
                in_piece.extend(piece.iter().copied());
                pieces.push(piece);
            }
        }
    }
    // Lower pieces first, so one above lands on where the one below came to rest.
    pieces.sort_by_key(|p| (p.iter().map(|&i| g.coords(i).1).min(), p[0]));
    let mut falls = Vec::new();
    for found in pieces {
        // As a replay finds it: the rock connected to its first cell now (a piece that fell
        // before it may have come to touch it).
        let piece = component(g, state, found[0]);
        let dy = drop_of(g, state, &piece);
        if dy == 0 {
            continue;
        }
        let fall = Fall { step: step as u32, voxel: gravity.origin[piece[0]], dy };
        move_piece(g, state, &mut gravity.origin, &piece, dy, step);
        gravity.falls.push(fall);
        falls.push((fall, piece));
    }
    falls
}

/// The connected rock (6-neighbours, cells whose `state` is rock) holding cell `start`, sorted.
pub fn component(g: &Grid, state: &[u16], start: usize) -> Vec<usize> {
    let mut seen = vec![start];
    let mut mark = std::collections::HashSet::from([start]);
    let mut k = 0;
    while k < seen.len() {
        let i = seen[k];
        k += 1;
        for n in neighbours(g, i) {
            if state[n] == ROCK && mark.insert(n) {
                seen.push(n);
            }
        }
    }
    seen.sort_unstable();
    seen
}

/// The cells after `until` steps of a run with gravity, from the per-identity removal steps
/// `record` and the `falls`: removals and falls applied in the order the run made them, so
/// every cell holds what the run's did then (rock, the step that emptied it, or never rock);
/// and each cell's voxel identity.
pub fn replay_cells(g: &Grid, record: &[u16], falls: &[Fall], until: u16) -> (Vec<u16>, Vec<u32>) {
    let mut state: Vec<u16> = record.iter().map(|&s| if s == NEVER_ROCK { NEVER_ROCK } else { ROCK }).collect();
    let mut origin: Vec<u32> =
        record.iter().enumerate().map(|(i, &s)| if s == NEVER_ROCK { EMPTY } else { i as u32 }).collect();
    // Where each identity is now.
    let mut at: Vec<u32> = (0..record.len() as u32).collect();
    // Identities by the step that removed them.
    let mut by_step: Vec<Vec<u32>> = vec![Vec::new(); until as usize + 1];
    for (id, &s) in record.iter().enumerate() {
        if s != ROCK && s != NEVER_ROCK && s <= until {
            by_step[s as usize].push(id as u32);
        }
    }
    let mut falls = falls.iter().filter(|f| f.step <= until as u32).peekable();
    for step in 1..=until {
        for &id in &by_step[step as usize] {
            let cell = at[id as usize] as usize;
            state[cell] = step;
            origin[cell] = EMPTY;
        }
        while let Some(f) = falls.next_if(|f| f.step == step as u32) {
            let piece = component(g, &state, at[f.voxel as usize] as usize);
            let shift = f.dy * g.plane() as u32;
            for &c in &piece {
                at[origin[c] as usize] -= shift;
            }
            move_piece(g, &mut state, &mut origin, &piece, f.dy, step);
        }
    }
    (state, origin)
}

/// Whether every rock cell is connected to the ground (nothing floats).
#[cfg(test)]
pub fn all_grounded(g: &Grid, state: &[u16]) -> bool {
    let plane = g.plane();
    let mut seen = vec![false; state.len()];
    let mut stack: Vec<usize> = (0..plane).filter(|&i| state[i] == ROCK).collect();
    for &i in &stack {
        seen[i] = true;
    }
    while let Some(i) = stack.pop() {
        for n in neighbours(g, i) {
            if state[n] == ROCK && !seen[n] {
                seen[n] = true;
                stack.push(n);
            }
        }
    }
    state.iter().zip(&seen).all(|(&s, &k)| s != ROCK || k)
}
