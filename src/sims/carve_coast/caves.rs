//! Sea caves and through passages, counted on the sampled field: the air that has rock above it
//! in its column ("covered"), in 6-connected pieces, each opening onto the open air by one or
//! more mouths. A piece at sea level with one mouth that reaches at least [`MIN_CAVE_DEPTH_M`]
//! in from it is a sea cave; a piece with two or more mouths is a passage (under an arch, or a
//! tunnel). Arches themselves are counted by the mesh's genus.

use std::collections::{HashMap, HashSet, VecDeque};

use super::field::Grid;
use crate::terrain::Heightfield;

/// A cave reaches at least this far in from its mouth (and at least two voxels): shallower
/// covered air is a notch under an overhang.
pub const MIN_CAVE_DEPTH_M: f32 = 2.0;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Caves {
    pub sea_caves: usize,
    pub passages: usize,
}

pub fn count(values: &[f32], grid: &Grid, top: &Heightfield, sea_level: f32) -> Caves {
    let plane = grid.plane();
    let v = grid.voxel_m;
    let air = |i: usize| values[i] <= 0.0;
    let xyz = |i: usize| (i % grid.nx, i / plane, (i % plane) / grid.nx);
    // Inside the box's walls and above its bottom cap, under the column's topmost rock.
    let covered = |i: usize| {
        let (x, j, z) = xyz(i);
        x > 0
            && z > 0
            && x + 1 < grid.nx
            && z + 1 < grid.nz
            && j > 0
            && air(i)
            && grid.y_m(j) < top.heights_m[i % plane] - 0.5 * v
    };
    let neighbours = |i: usize| grid.neighbours(i);
    let mut seen = vec![0u64; grid.len().div_ceil(64)];
    let mut caves = Caves::default();
    for start in 0..grid.len() {
        if seen[start / 64] & (1 << (start % 64)) != 0 || !covered(start) {
            continue;
        }
        // One piece of covered air.
        let mut piece = Vec::new();
        let mut queue = VecDeque::from([start]);
        seen[start / 64] |= 1 << (start % 64);
        while let Some(i) = queue.pop_front() {
            piece.push(i);
            for n in neighbours(i).into_iter().flatten() {
                if seen[n / 64] & (1 << (n % 64)) == 0 && covered(n) {
                    seen[n / 64] |= 1 << (n % 64);
                    queue.push_back(n);
                }
            }
        }
        // Its mouths: samples next to open (uncovered) air, grouped 26-connected.
        let mouth: Vec<usize> = piece
            .iter()
            .copied()
            .filter(|&i| neighbours(i).into_iter().flatten().any(|n| air(n) && !covered(n)))
            .collect();
        if mouth.is_empty() {
            continue; // sealed air: the sampler fills such pockets, none should be left
        }
        let mouths = groups(&mouth, grid);
        if mouths >= 2 {
            caves.passages += 1;
            continue;
        }
        let at_sea = piece.iter().any(|&i| (grid.y_m(i / plane) - sea_level).abs() <= v);
        // How far the piece reaches in from its mouth, in voxel steps.
        let members: HashSet<usize> = piece.iter().copied().collect();
        let mut depth: HashMap<usize, u32> = mouth.iter().map(|&i| (i, 0)).collect();
        let mut queue: VecDeque<usize> = mouth.iter().copied().collect();
        let mut deepest = 0;
        while let Some(i) = queue.pop_front() {
            let d = depth[&i];
            deepest = deepest.max(d);
            for n in neighbours(i).into_iter().flatten() {
                if members.contains(&n) && !depth.contains_key(&n) {
                    depth.insert(n, d + 1);
                    queue.push_back(n);
                }
            }
        }
        if at_sea && deepest >= 2 && deepest as f32 * v >= MIN_CAVE_DEPTH_M {
            caves.sea_caves += 1;
        }
    }
    caves
}

/// Groups of samples, 26-connected.
fn groups(samples: &[usize], grid: &Grid) -> usize {
    let plane = grid.plane();
    let set: HashSet<usize> = samples.iter().copied().collect();
    let mut done: HashSet<usize> = HashSet::new();
    let mut count = 0;
    for &s in samples {
        if !done.insert(s) {
            continue;
        }
        count += 1;
        let mut stack = vec![s];
        while let Some(i) = stack.pop() {
            let (x, j, z) = ((i % grid.nx) as i64, (i / plane) as i64, ((i % plane) / grid.nx) as i64);
            for dj in -1..=1 {
                for dz in -1..=1 {
                    for dx in -1..=1 {
                        let (nx, nj, nz) = (x + dx, j + dj, z + dz);
                        if nx < 0
                            || nj < 0
                            || nz < 0
                            || nx >= grid.nx as i64
                            || nj >= grid.ny as i64
                            || nz >= grid.nz as i64
                        {
                            continue;
                        }
                        let n = nj as usize * plane + nz as usize * grid.nx + nx as usize;
                        if set.contains(&n) && done.insert(n) {
                            stack.push(n);
                        }
                    }
                }
            }
        }
    }
    count
}
