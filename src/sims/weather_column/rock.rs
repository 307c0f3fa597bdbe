//! The rock as the simulation holds it: two bytes of state per voxel (rock, never rock, or the
//! step that removed it — the recorded sequence itself), two bytes of air count per voxel, and
//! weathering state only for the active voxels near the surface (paper section 5, with the
//! leaner data structure its future work asks for).

use rayon::prelude::*;

use super::bubble::BubbleTable;
use super::gravity::Gravity;
use super::grid::{Grid, ROCK};
use super::resistance::ResistanceField;
use crate::stop::{Stop, Stopped};

#[derive(Clone)]
pub struct Rock {
    pub grid: Grid,
    /// `ROCK`, `NEVER_ROCK`, or the step that removed the voxel.
    pub state: Vec<u16>,
    /// Air cells in each rock voxel's bubble. A rock voxel is active — its weathering state
    /// kept, as it is close enough to the surface (paper section 5) — when this is above 0; it
    /// decays once it touches air ([`Grid::exposure`]). (Cells that are not rock
    /// accumulate counts too; they are never read.)
    pub air: Vec<u16>,
    pub layer_of_plane: Vec<u8>,
    /// One per layer.
    pub bubbles: Vec<BubbleTable>,
    pub resistance: ResistanceField,
    /// Rock voxels left.
    pub rock_voxels: u64,
    /// Rock voxels before weathering.
    pub initial_voxels: u64,
    /// Largest reach of any bubble along X, Y, Z.
    pub reach: [i32; 3],
    /// Smallest and largest `dy` of any bubble.
    pub dy_range: (i32, i32),
    /// Voxel identities and falls, when rock falls (`gravity`).
    pub gravity: Option<Gravity>,
}

/// The weathering state of the active voxels, sorted by voxel index.
#[derive(Clone, Default)]
pub struct Active {
    pub index: Vec<u32>,
    /// Decimation level: 1 when it becomes active, removed at 0.
    pub level: Vec<f32>,
    pub resistance: Vec<f32>,
}

impl Active {
    pub fn len(&self) -> usize {
        self.index.len()
    }

    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }
}

/// Planes handled by one parallel task when removals update their neighbours.
const PLANES_PER_TASK: usize = 2;

impl Rock {
    pub fn new(
        grid: Grid,
        state: Vec<u16>,
        layer_of_plane: Vec<u8>,
        bubbles: Vec<BubbleTable>,
        resistance: ResistanceField,
    ) -> Self {
        let rock_voxels = state.par_iter().filter(|&&s| s == ROCK).count() as u64;
        let mut reach = [0; 3];
        let mut dy_range = (0, 0);
        for b in &bubbles {
            for (r, br) in reach.iter_mut().zip(b.reach) {
                *r = (*r).max(br);
            }
            dy_range = (dy_range.0.min(b.dy_min), dy_range.1.max(b.dy_max));
        }
        let air = vec![0; state.len()];
        Self {
            grid,
            state,
            air,
            layer_of_plane,
            bubbles,
            resistance,
            rock_voxels,
            initial_voxels: rock_voxels,
            reach,
            dy_range,
            gravity: None,
        }
    }

    pub fn bubble_of_plane(&self, y: usize) -> &BubbleTable {
        &self.bubbles[self.layer_of_plane[y] as usize]
    }

    /// Count the air in the bubble of every rock voxel near the surface and return those with
    /// any as the active set. Only voxels within a bubble's reach of air are counted: a
    /// separable dilation finds them.
    /// Answers `Err(Stopped)` once `stop` is raised (looked at plane by plane).
    pub fn initialise(&mut self, stop: Stop) -> Result<Active, Stopped> {
        let near = self.near_air();
        stop.check()?;
        let g = &self.grid;
        let plane = g.plane();
        let state = &self.state;
        let per_plane: Vec<Vec<u32>> = self
            .air
            .par_chunks_mut(plane)
            .enumerate()
            .map(|(y, air_plane)| {
                let mut active = Vec::new();
                if stop.requested() {
                    return active;
                }
                let bubble = &self.bubbles[self.layer_of_plane[y] as usize];
                for (k, a) in air_plane.iter_mut().enumerate() {
                    let i = y * plane + k;
                    if state[i] != ROCK || near[i] == 0 {
                        continue;
                    }
                    let (x, z) = (k % g.nx, k / g.nx);
                    *a = count_air(g, state, bubble, x as i64, y as i64, z as i64);
                    if *a > 0 {
                        active.push(i as u32);
                    }
                }
                active
            })
            .collect();
        stop.check()?;
        let index: Vec<u32> = per_plane.concat();
        let level = vec![1.0; index.len()];
        let resistance = index.par_iter().map(|&i| self.resistance_of(i as usize)).collect();
        Ok(Active { index, level, resistance })
    }

    /// The resistance of the voxel in cell `i`: where it started, so a fallen piece keeps its
    /// layers'.
    pub fn resistance_of(&self, i: usize) -> f32 {
        let i = match &self.gravity {
            Some(g) if g.origin[i] != super::gravity::EMPTY => g.origin[i] as usize,
            _ => i,
        };
        let (x, y, z) = self.grid.coords(i);
        self.resistance.at_voxel(self.layer_of_plane[y], x, y, z)
    }

    /// 1 where a cell within the largest bubble's bounding box of a voxel is air (cells outside
    /// the grid included), by three passes of a sliding window.
    fn near_air(&self) -> Vec<u8> {
        let g = &self.grid;
        let (nx, ny, nz, plane) = (g.nx, g.ny, g.nz, g.plane());
        let [rx, ry, rz] = self.reach.map(|r| r as usize);
        // Along X: any air in the row window, or the window leaves the grid.
        let mut along_x = vec![0u8; g.len()];
        along_x.par_chunks_mut(nx).enumerate().for_each(|(row, out)| {
            let cells = &self.state[row * nx..(row + 1) * nx];
            let mut prefix = vec![0u32; nx + 1];
            for x in 0..nx {
                prefix[x + 1] = prefix[x] + (cells[x] != ROCK) as u32;
            }
            for (x, o) in out.iter_mut().enumerate() {
                let (lo, hi) = (x as i64 - rx as i64, x + rx);
                *o = (lo < 0 || hi >= nx || prefix[hi + 1] - prefix[lo as usize] > 0) as u8;
            }
        });
        // Along Z within each plane.
        let mut along_z = vec![0u8; g.len()];
        along_z.par_chunks_mut(plane).enumerate().for_each(|(y, out)| {
            let src = &along_x[y * plane..(y + 1) * plane];
            for z in 0..nz {
                let row = &mut out[z * nx..(z + 1) * nx];
                if z < rz || z + rz >= nz {
                    row.fill(1);
                    continue;
                }
                for w in z - rz..=z + rz {
                    for (o, s) in row.iter_mut().zip(&src[w * nx..(w + 1) * nx]) {
                        *o |= s;
                    }
                }
            }
        });
        drop(along_x);
        // Along Y, plane by plane; below the grid is air only when floating.
        let mut along_y = vec![0u8; g.len()];
        along_y.par_chunks_mut(plane).enumerate().for_each(|(y, out)| {
            if y + ry >= ny || (g.floating && y < ry) {
                out.fill(1);
                return;
            }
            for w in y.saturating_sub(ry)..=y + ry {
                for (o, s) in out.iter_mut().zip(&along_z[w * plane..(w + 1) * plane]) {
                    *o |= s;
                }
            }
        });
        along_y
    }

    /// Remove `removed` (sorted voxel indices) at `step`: mark them, then give every voxel whose
    /// bubble held one of them one more cell of air, by the lookup table. Returns the rock
    /// voxels that became active, sorted. Parallel over slabs of planes; the result does not
    /// depend on the thread count.
    pub fn remove(&mut self, removed: &[u32], step: u16) -> Vec<u32> {
        for &u in removed {
            self.state[u as usize] = step;
        }
        self.rock_voxels -= removed.len() as u64;
        let mut air = std::mem::take(&mut self.air);
        let activated: Vec<Vec<u32>> = {
            let this = &*self;
            let plane = this.grid.plane();
            let ny = this.grid.ny;
            let state = &this.state;
            let (dy_min, dy_max) = this.dy_range;
            air.par_chunks_mut(plane * PLANES_PER_TASK)
                .enumerate()
                .map(|(task, slab)| {
                    let y0 = task * PLANES_PER_TASK;
                    let y1 = (y0 + PLANES_PER_TASK).min(ny);
                    // v = u − o with o.y in [dy_min, dy_max], so u's plane is within this range.
                    let u_lo = (y0 as i64 + dy_min as i64).max(0) as usize;
                    let u_hi = ((y1 as i64 + dy_max as i64).max(0) as usize).min(ny);
                    let first = removed.partition_point(|&u| (u as usize) < u_lo * plane);
                    let last = removed.partition_point(|&u| (u as usize) < u_hi * plane);
                    let mut activated = Vec::new();
                    for &u in &removed[first..last] {
                        this.for_each_target_run(u as usize, y0..y1, |row_start, x_lo, x_hi| {
                            let local = row_start - y0 * plane;
                            for (k, a) in slab[local + x_lo..=local + x_hi].iter_mut().enumerate() {
                                if *a == 0 && state[row_start + x_lo + k] == ROCK {
                                    activated.push((row_start + x_lo + k) as u32);
                                }
                                *a += 1;
                            }
                        });
                    }
                    activated.sort_unstable();
                    activated
                })
                .collect()
        };
        self.air = air;
        activated.concat()
    }

    /// For a removed voxel `u`, call `f(row_start, x_lo, x_hi)` for each row segment of voxels
    /// in planes `ys` whose bubble contains `u` (`row_start` = index of x = 0 in that row;
    /// `x_lo..=x_hi` within the grid). Each voxel's own layer decides its bubble.
    pub fn for_each_target_run(&self, u: usize, ys: std::ops::Range<usize>, mut f: impl FnMut(usize, usize, usize)) {
        let g = &self.grid;
        let (xu, yu, zu) = g.coords(u);
        let (xu, yu, zu) = (xu as i64, yu as i64, zu as i64);
        let (dy_min, dy_max) = self.dy_range;
        let y_lo = (yu - dy_max as i64).max(ys.start as i64);
        let y_hi = (yu - dy_min as i64).min(ys.end as i64 - 1);
        for yv in y_lo..=y_hi {
            let bubble = self.bubble_of_plane(yv as usize);
            for run in bubble.row((yu - yv) as i32) {
                let zv = zu - run.dz as i64;
                if zv < 0 || zv >= g.nz as i64 {
                    continue;
                }
                let x_lo = (xu - run.x_hi as i64).max(0);
                let x_hi = (xu - run.x_lo as i64).min(g.nx as i64 - 1);
                if x_lo > x_hi {
                    continue;
                }
                let row_start = g.index(0, yv as usize, zv as usize);
                f(row_start, x_lo as usize, x_hi as usize);
            }
        }
    }
}

/// Air cells in the bubble centred on `(x, y, z)`, cells outside the grid included.
pub fn count_air(g: &Grid, state: &[u16], bubble: &BubbleTable, x: i64, y: i64, z: i64) -> u16 {
    let mut air = 0u32;
    for dy in bubble.dy_min..=bubble.dy_max {
        let yy = y + dy as i64;
        for run in bubble.row(dy) {
            let zz = z + run.dz as i64;
            let len = (run.x_hi - run.x_lo + 1) as u32;
            if yy < 0 {
                air += if g.floating { len } else { 0 };
                continue;
            }
            if yy >= g.ny as i64 || zz < 0 || zz >= g.nz as i64 {
                air += len;
                continue;
            }
            let (lo, hi) = (x + run.x_lo as i64, x + run.x_hi as i64);
            let (clo, chi) = (lo.max(0), hi.min(g.nx as i64 - 1));
            if clo > chi {
                air += len;
                continue;
            }
            air += (clo - lo + hi - chi) as u32;
            let start = g.index(0, yy as usize, zz as usize);
            air += state[start + clo as usize..=start + chi as usize].iter().filter(|&&s| s != ROCK).count() as u32;
        }
    }
    air as u16
}
