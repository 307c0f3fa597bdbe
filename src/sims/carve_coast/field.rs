//! The sampled implicit terrain for meshing: exact only in a narrow band around the surface
//! (from the heightfield and the spheres' bounds), the plain height difference elsewhere;
//! floating fragments removed; per-column figures.

use std::collections::VecDeque;

use rayon::prelude::*;

use super::implicit::{max_gradient, Implicit};
use crate::terrain::Heightfield;

/// The sampling grid: sample (x, y, z) at `(x·v, bottom + y·v, z·v)`, index x + nx·(z + nz·y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    pub voxel_m: f32,
    pub bottom_y: f32,
}

impl Grid {
    pub fn len(&self) -> usize {
        self.nx * self.ny * self.nz
    }
    pub fn plane(&self) -> usize {
        self.nx * self.nz
    }
    pub fn y_m(&self, j: usize) -> f32 {
        self.bottom_y + j as f32 * self.voxel_m
    }

    /// The six face neighbours of sample `i` inside the grid.
    pub fn neighbours(&self, i: usize) -> [Option<usize>; 6] {
        let plane = self.plane();
        let (x, j, z) = (i % self.nx, i / plane, (i % plane) / self.nx);
        [
            (x > 0).then(|| i - 1),
            (x + 1 < self.nx).then(|| i + 1),
            (z > 0).then(|| i - self.nx),
            (z + 1 < self.nz).then(|| i + self.nx),
            (j > 0).then(|| i - plane),
            (j + 1 < self.ny).then(|| i + plane),
        ]
    }
}

/// The box around the terrain: its footprint, from below its lowest point to above its highest
/// plus what warping and carving can add.
pub fn grid_for(hf: &Heightfield, voxel_m: f32, headroom_m: f32) -> Grid {
    let (lo, hi) = hf.min_max();
    let bottom_y = lo - 3.0 * voxel_m;
    let nx = (hf.width_m() / voxel_m).floor() as usize + 1;
    let nz = (hf.depth_m() / voxel_m).floor() as usize + 1;
    let ny = ((hi + headroom_m + 3.0 * voxel_m - bottom_y) / voxel_m).ceil() as usize + 1;
    Grid { nx, ny, nz, voxel_m, bottom_y }
}

/// Per column, the samples `lo..hi` that need the full implicit function.
pub struct Bands {
    pub lo: Vec<u32>,
    pub hi: Vec<u32>,
}

/// The band of each column: the heightfield's range over the column's neighbourhood, padded by
/// two voxels and by how far the warp can move the surface, joined with the vertical extent of
/// every sphere over the column. `dense` makes every band the whole column (for comparison).
pub fn bands(implicit: &Implicit, grid: &Grid, warp_amplitude_m: f32, dense: bool) -> Bands {
    let hf = implicit.hf;
    let v = grid.voxel_m;
    let g_max = max_gradient(hf);
    let warp_pad = warp_amplitude_m * g_max * g_max.max(1.0);
    let pad = 2.0 * v + warp_pad;
    let reach = v + warp_amplitude_m * g_max;
    let columns: Vec<(u32, u32)> = (0..grid.nz)
        .into_par_iter()
        .flat_map_iter(|z| {
            (0..grid.nx).map(move |x| {
                if dense {
                    return (0, grid.ny as u32);
                }
                let (px, pz) = (x as f32 * v, z as f32 * v);
                let mut lo = f32::INFINITY;
                let mut hi = f32::NEG_INFINITY;
                for (dx, dz) in [(0.0, 0.0), (-reach, 0.0), (reach, 0.0), (0.0, -reach), (0.0, reach)] {
                    let h = hf.sample(px + dx, pz + dz);
                    lo = lo.min(h);
                    hi = hi.max(h);
                }
                lo -= pad;
                hi += pad;
                // Spheres live in the warped domain: a world column sees those within the warp's
                // reach of it.
                implicit.index.visit(px, pz, reach, |i| {
                    let (a, b) = implicit.spheres[i as usize].bounds();
                    if px >= a[0] - reach && px <= b[0] + reach && pz >= a[2] - reach && pz <= b[2] + reach {
                        lo = lo.min(a[1] - 2.0 * v);
                        hi = hi.max(b[1] + 2.0 * v);
                    }
                });
                let to_j = |y: f32| ((y - grid.bottom_y) / v).clamp(0.0, grid.ny as f32);
                (to_j(lo).floor() as u32, (to_j(hi).ceil() as u32 + 1).min(grid.ny as u32))
            })
        })
        .collect();
    let (lo, hi) = columns.into_iter().unzip();
    Bands { lo, hi }
}

/// Sample the field (positive in rock) over `planes` of the grid, into `out` (those planes).
pub fn sample_planes(implicit: &Implicit, grid: &Grid, bands: &Bands, planes: std::ops::Range<usize>, out: &mut [f32]) {
    let plane = grid.plane();
    out.par_chunks_mut(plane).zip(planes).for_each(|(values, j)| {
        let y = grid.y_m(j);
        for (k, value) in values.iter_mut().enumerate() {
            let (x, z) = ((k % grid.nx) as f32 * grid.voxel_m, (k / grid.nx) as f32 * grid.voxel_m);
            let p = [x, y, z];
            *value = if (bands.lo[k] as usize..bands.hi[k] as usize).contains(&j) {
                -implicit.distance(p).max(grid.bottom_y - y)
            } else {
                // Far from any crossing only the sign matters: rock below the band, air above
                // it. The box's walls and bottom are exactly 0 (outside), as the implicit form
                // gives there inside the band, so the caps lie flat on the box.
                let wall = x <= 0.0 || z <= 0.0 || x >= implicit.hf.width_m() || z >= implicit.hf.depth_m();
                if j == 0 || wall {
                    0.0
                } else if j >= bands.hi[k] as usize {
                    -grid.voxel_m
                } else {
                    grid.voxel_m
                }
            };
        }
    });
}

/// Turn rock not connected to the ground into air and air not connected to the open air into
/// rock; returns (rock pieces removed, air pockets filled). Everything below a column's band is
/// rock joined to the ground and everything above it open air, so searches from there through
/// the bands find every grounded rock and every open air sample (6-connected).
pub fn remove_fragments(values: &mut [f32], grid: &Grid, bands: &Bands) -> (usize, usize) {
    let rock = |v: f32| v > 0.0;
    let pieces = flood_unreached(values, grid, bands, true);
    let air = -0.5 * grid.voxel_m;
    for &i in pieces.iter().flatten() {
        values[i] = air;
    }
    let pockets = flood_unreached(values, grid, bands, false);
    let solid = 0.5 * grid.voxel_m;
    for &i in pockets.iter().flatten() {
        values[i] = solid;
    }
    debug_assert!(pockets.iter().flatten().all(|&i| rock(values[i])));
    (pieces.len(), pockets.len())
}

/// The band samples of one kind (rock when `want_rock`, else air) that no search from outside
/// the bands reaches, as connected pieces.
fn flood_unreached(values: &[f32], grid: &Grid, bands: &Bands, want_rock: bool) -> Vec<Vec<usize>> {
    let plane = grid.plane();
    let is = |i: usize| (values[i] > 0.0) == want_rock;
    let in_band = |i: usize| {
        let (k, j) = (i % plane, i / plane);
        (bands.lo[k] as usize..bands.hi[k] as usize).contains(&j)
    };
    let neighbours = |i: usize| grid.neighbours(i);
    let mut seen = vec![0u64; grid.len().div_ceil(64)];
    let mut mark = |i: usize| -> bool {
        let (w, b) = (i / 64, 1u64 << (i % 64));
        let fresh = seen[w] & b == 0;
        seen[w] |= b;
        fresh
    };
    let mut queue = VecDeque::new();
    // Starts: band samples of the kind touching a sample of the kind outside the bands (rock
    // below, air above and around the box), and the ground or the grid's boundary.
    for k in 0..plane {
        for j in bands.lo[k] as usize..bands.hi[k] as usize {
            let i = j * plane + k;
            if !is(i) {
                continue;
            }
            let ns = neighbours(i);
            // Rock on the bottom layer (sample 1; sample 0 is the box's outside) is ground.
            let boundary = if want_rock { j == 1 } else { ns.iter().any(Option::is_none) };
            if (boundary || ns.iter().flatten().any(|&n| !in_band(n) && is(n))) && mark(i) {
                queue.push_back(i);
            }
        }
    }
    let flood = |queue: &mut VecDeque<usize>, mark: &mut dyn FnMut(usize) -> bool, piece: &mut Vec<usize>| {
        while let Some(i) = queue.pop_front() {
            piece.push(i);
            for n in neighbours(i).into_iter().flatten() {
                if in_band(n) && is(n) && mark(n) {
                    queue.push_back(n);
                }
            }
        }
    };
    flood(&mut queue, &mut mark, &mut Vec::new());
    let mut pieces = Vec::new();
    for k in 0..plane {
        for j in bands.lo[k] as usize..bands.hi[k] as usize {
            let i = j * plane + k;
            if is(i) && mark(i) {
                let mut piece = Vec::new();
                queue.push_back(i);
                flood(&mut queue, &mut mark, &mut piece);
                pieces.push(piece);
            }
        }
    }
    pieces
}

/// Per column: surface crossings along y, and the topmost surface height.
pub fn columns(values: &[f32], grid: &Grid) -> (Vec<u32>, Heightfield) {
    let plane = grid.plane();
    let per: Vec<(u32, f32)> = (0..plane)
        .into_par_iter()
        .map(|k| {
            let mut crossings = 0;
            let mut top = grid.bottom_y;
            let mut found = false;
            // From the top down to the first sample above the bottom cap (sample 0 is outside).
            for j in (2..grid.ny).rev() {
                let (above, below) = (values[j * plane + k], values[(j - 1) * plane + k]);
                if (above > 0.0) != (below > 0.0) {
                    crossings += 1;
                    if !found && below > 0.0 {
                        let t = -above / (below - above);
                        top = grid.y_m(j) - t * grid.voxel_m;
                        found = true;
                    }
                }
            }
            (crossings, top)
        })
        .collect();
    let crossings = per.iter().map(|c| c.0).collect();
    let mut hf = Heightfield::flat(grid.nx, grid.nz, grid.voxel_m, 0.0);
    for (k, (_, top)) in per.iter().enumerate() {
        hf.heights_m[k] = *top;
    }
    (crossings, hf)
}

/// Set the box's outer ring of `top` (from [`columns`]) to the carved terrain's topmost
/// surface there. The sampled field is air on the box's walls (the solid's sides stand half a
/// voxel's clamp inside them), so those columns find no crossing and would report the box's
/// bottom: a heightmap whose border is a moat tens of metres deep, and a wrong `z_min`. Each
/// wall column is searched from the top down on the implicit function without its walls, and
/// the crossing interpolated as [`columns`] does inside.
pub fn surface_at_walls(implicit: &Implicit, grid: &Grid, top: &mut Heightfield) {
    let (nx, nz) = (grid.nx, grid.nz);
    let mut ring: Vec<usize> = (0..nx).flat_map(|x| [x, (nz - 1) * nx + x]).collect();
    ring.extend((1..nz.saturating_sub(1)).flat_map(|z| [z * nx, z * nx + nx - 1]));
    ring.sort_unstable();
    ring.dedup();
    let (w, d) = (implicit.hf.width_m(), implicit.hf.depth_m());
    let tops: Vec<f32> = ring
        .par_iter()
        .map(|&k| {
            // Sample positions on the walls lie on them exactly, even where the footprint is not
            // a whole number of voxels.
            let (x, z) = (((k % nx) as f32 * grid.voxel_m).min(w), ((k / nx) as f32 * grid.voxel_m).min(d));
            let rock = |j: usize| -implicit.carved([x, grid.y_m(j), z]);
            let mut above = rock(grid.ny - 1);
            for j in (1..grid.ny - 1).rev() {
                let below = rock(j);
                if above <= 0.0 && below > 0.0 {
                    let t = -above / (below - above);
                    return grid.y_m(j + 1) - t * grid.voxel_m;
                }
                above = below;
            }
            grid.bottom_y
        })
        .collect();
    for (k, h) in ring.into_iter().zip(tops) {
        top.heights_m[k] = h;
    }
}
