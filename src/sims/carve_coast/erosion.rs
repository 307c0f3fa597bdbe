//! Coastal erosion by spheres (the seed's `GetCoastalErosionSeeds`, `GrowFromSeed`,
//! `CoastalErosion`): seeds on steep surface near sea level, spheres grown from each inward,
//! slightly downward and mainly horizontally; each pass seeds on the surface the previous
//! passes left.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::implicit::{Implicit, Sphere};
use super::params::{CarveCoastParams, Erosion};
use crate::stop::{Stop, Stopped};

/// A seed: a surface point and its outward normal.
#[derive(Clone, Copy, Debug)]
pub struct SeedPoint {
    pub point: [f32; 3],
    pub normal: [f32; 3],
}

/// Whether a qualifying point is accepted: a hash of (seed, pass, column, crossing), so the
/// scan can run in parallel and still draw the same.
fn accepted(seed: u64, pass: u32, column: usize, k: usize, probability: f32) -> bool {
    let mut z = seed ^ (pass as u64) << 56 ^ (column as u64) << 8 ^ k as u64;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    ((z >> 40) as f32 / (1u64 << 24) as f32) < probability
}

/// Every steep surface crossing within the elevation range, on each heightfield column,
/// scanning down at `step_m` (seed: `GetCoastalErosionSeeds`), on the surface the passes so far
/// left and the warp shaped: a column is scanned wherever that surface can cross the range —
/// its original height near the range, or a carved sphere within reach (caves dug under ground
/// higher than the range are seeded again).
pub fn seeds(
    implicit: &Implicit,
    params: &CarveCoastParams,
    seed: u64,
    pass: u32,
    step_m: f32,
    stop: Stop,
) -> Result<Vec<SeedPoint>, Stopped> {
    let e = &params.erosion;
    let hf = implicit.hf;
    let (lo, hi) = (params.sea_level() + e.seed_elevation_range[0], params.sea_level() + e.seed_elevation_range[1]);
    let reach = e.radius_range[1] * 2.0 + implicit.warp_reach();
    let min_slope_cos = e.seed_min_slope.to_radians().cos();
    let per_row: Vec<Vec<SeedPoint>> = (0..hf.rows)
        .into_par_iter()
        .map(|row| {
            let mut out = Vec::new();
            if stop.requested() {
                return out;
            }
            for col in 0..hf.cols {
                let h = hf.get(col, row);
                let p = hf.position(col, row);
                let (x, z) = (p.x, p.z);
                if (h < lo - reach || h > hi + reach) && !carved_near(implicit, x, z) {
                    continue;
                }
                let mut y = hi;
                let mut above = implicit.distance([x, y, z]);
                let mut k = 0;
                while y > lo {
                    let y2 = (y - step_m).max(lo);
                    if y2 >= y {
                        // A step below the float spacing at this height makes no progress.
                        break;
                    }
                    let below = implicit.distance([x, y2, z]);
                    if above > 0.0 && below <= 0.0 {
                        let t = above / (above - below);
                        let point = [x, y + (y2 - y) * t, z];
                        let normal = implicit.normal(point, step_m * 0.5);
                        // Slope of the surface from horizontal: the normal's angle from up.
                        if normal[1] <= min_slope_cos
                            && accepted(seed, pass, row * hf.cols + col, k, e.seed_acceptance_probability)
                        {
                            out.push(SeedPoint { point, normal });
                        }
                        k += 1;
                    }
                    y = y2;
                    above = below;
                }
            }
            out
        })
        .collect();
    stop.check()?;
    Ok(per_row.concat())
}

/// Whether a carving can reach the world column at (x, z): its horizontal bounds within the
/// warp's reach of it.
fn carved_near(implicit: &Implicit, x: f32, z: f32) -> bool {
    let reach = implicit.warp_reach();
    let mut any = false;
    implicit.index.visit(x, z, reach, |i| {
        let (a, b) = implicit.spheres[i as usize].bounds();
        any |= x >= a[0] - reach && x <= b[0] + reach && z >= a[2] - reach && z <= b[2] + reach;
    });
    any
}

fn uniform(rng: &mut ChaCha8Rng, r: [f32; 2]) -> f32 {
    if r[1] > r[0] {
        rng.random_range(r[0]..=r[1])
    } else {
        r[0]
    }
}

fn count(rng: &mut ChaCha8Rng, r: [u32; 2]) -> u32 {
    rng.random_range(r[0]..=r[1])
}

/// Spheres grown from one seed inward (seed: `GrowFromSeed`): one at the seed, then at each
/// growth step a random number of random spheres around a point that moves along the inverted
/// normal, flattened and tipped slightly down. Centres stay within the elevation range.
pub fn grow_from_seed(s: &SeedPoint, e: &Erosion, y_range: (f32, f32), pass: u32, rng: &mut ChaCha8Rng) -> Vec<Sphere> {
    let clamp_y = |y: f32| y.clamp(y_range.0, y_range.1);
    let mut out = vec![Sphere([s.point[0], clamp_y(s.point[1]), s.point[2], uniform(rng, e.radius_range)], pass)];
    let (dx, dz) = (-s.normal[0], -s.normal[2]);
    let len = (dx * dx + 0.01 + dz * dz).sqrt();
    let dir = [dx / len, -0.1 / len, dz / len];
    let step = (e.radius_range[0] + e.radius_range[1]) / 2.0;
    let scatter = e.radius_range[1] / 2.0;
    let mut p = s.point;
    for _ in 0..count(rng, e.growth_step_range) {
        for _ in 0..count(rng, e.growth_sphere_range) {
            let offset: [f32; 3] = [0, 1, 2].map(|_| rng.random_range(-1.0..=1.0f32) * scatter);
            let r = uniform(rng, e.radius_range);
            out.push(Sphere([p[0] + offset[0], clamp_y(p[1] + offset[1]), p[2] + offset[2], r], pass));
        }
        p = [p[0] + dir[0] * step, p[1] + dir[1] * step, p[2] + dir[2] * step];
    }
    out
}

/// Seeds grown at a time: enough to keep every thread busy, few enough that a pass stops
/// growing soon after it reaches its room.
const SEEDS_PER_CHUNK: usize = 256;

/// The spheres of one pass, from the surface the spheres so far left (seed: `CoastalErosion`),
/// at most `room` of them: seeds are grown in order, a chunk at a time, until the room is
/// filled, so no pass builds more spheres than a job may keep.
pub fn erosion_pass(
    implicit: &Implicit,
    params: &CarveCoastParams,
    seed: u64,
    pass: u32,
    step_m: f32,
    room: usize,
    stop: Stop,
) -> Result<Vec<Sphere>, Stopped> {
    let e = &params.erosion;
    let found = seeds(implicit, params, seed, pass, step_m, stop)?;
    let y_range = (params.sea_level() + e.seed_elevation_range[0], params.sea_level() + e.seed_elevation_range[1]);
    let mut out: Vec<Sphere> = Vec::new();
    for (c, chunk) in found.chunks(SEEDS_PER_CHUNK).enumerate() {
        if out.len() >= room {
            break;
        }
        stop.check()?;
        let grown: Vec<Vec<Sphere>> = chunk
            .par_iter()
            .enumerate()
            .map(|(j, s)| {
                let i = c * SEEDS_PER_CHUNK + j;
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream(((pass as u64) << 40) | i as u64);
                // Grown in the world, placed in the warped domain the field is read in.
                let mut grown = grow_from_seed(s, e, y_range, pass, &mut rng);
                for sphere in &mut grown {
                    let [x, y, z] = implicit.warp(sphere.centre());
                    sphere.0[..3].copy_from_slice(&[x, y, z]);
                }
                grown
            })
            .collect();
        out.extend(grown.into_iter().flatten());
    }
    out.truncate(room);
    Ok(out)
}
