//! The chamber: a floor at y ≥ 0 and a roof hanging from `height_m`, each flat or relieved by
//! seeded noise, and the drip sites on the roof.

use noise::{Fbm, MultiFractal, NoiseFn, Perlin};
use rand::Rng;

use super::growth::site_rng;
use super::neighbours::PointGrid;
use super::params::{Chamber, GrowCaveParams, Mineral, Site, Sites, Surface};

/// Roof and floor heights as functions of (x, z) in metres.
pub struct ChamberShape {
    pub chamber: Chamber,
    roof: Fbm<Perlin>,
    floor: Fbm<Perlin>,
    walls: Fbm<Perlin>,
}

impl ChamberShape {
    pub fn new(chamber: &Chamber, seed: u64) -> Self {
        let fbm = |salt: u64| Fbm::<Perlin>::new((seed ^ salt) as u32 ^ (seed >> 32) as u32).set_octaves(3);
        Self { chamber: chamber.clone(), roof: fbm(0x524F_4F46), floor: fbm(0x464C_4F52), walls: fbm(0x5741_4C4C) }
    }

    fn relief(noise: &Fbm<Perlin>, s: &Surface, x: f32, z: f32) -> f32 {
        if s.relief_m == 0.0 {
            return 0.0;
        }
        let f = s.frequency_per_m as f64;
        let n = noise.get([x as f64 * f, z as f64 * f]).clamp(-1.0, 1.0) as f32;
        s.relief_m * (n + 1.0) / 2.0
    }

    pub fn roof_y(&self, x: f32, z: f32) -> f32 {
        self.chamber.height_m - Self::relief(&self.roof, &self.chamber.roof, x, z)
    }

    pub fn floor_y(&self, x: f32, z: f32) -> f32 {
        Self::relief(&self.floor, &self.chamber.floor, x, z)
    }

    /// How far the wall at (x, y, z) stands out beyond the chamber's box, metres (noise read
    /// in 3D, so it runs on round the corners without a seam).
    pub fn wall_push(&self, x: f32, y: f32, z: f32) -> f32 {
        let s = &self.chamber.walls;
        if s.relief_m == 0.0 {
            return 0.0;
        }
        let f = s.frequency_per_m as f64;
        let n = self.walls.get([x as f64 * f, y as f64 * f, z as f64 * f]).clamp(-1.0, 1.0) as f32;
        s.relief_m * (n + 1.0) / 2.0
    }
}

/// The centre of a disc of radius `r` at `c` and `points` round its rim, (x, z): where growth
/// and the profiles look for the floor and roof under a ring.
pub fn rim(c: [f32; 3], r: f32, points: u32) -> impl Iterator<Item = (f32, f32)> {
    let step = std::f32::consts::TAU / points as f32;
    std::iter::once((c[0], c[2])).chain((0..points).map(move |i| {
        let (sin, cos) = (i as f32 * step).sin_cos();
        (c[0] + r * cos, c[2] + r * sin)
    }))
}

/// Roof and floor grids: `samples` along the chamber's longer side, square cells, the other
/// side matched to the nearest cell — so no aspect ratio makes a grid larger than `samples²`.
/// Returns (cols, rows, cell size in metres).
pub fn surface_grid(c: &Chamber) -> (usize, usize, f32) {
    let n = c.samples.max(2) as usize;
    let other = |long: f32, short: f32| {
        let cell = long / (n - 1) as f32;
        let m = (short / cell).round();
        (if m.is_finite() { (m as usize).min(n - 1) } else { 0 } + 1).max(2)
    };
    if c.width_m >= c.depth_m {
        (n, other(c.width_m, c.depth_m), c.width_m / (n - 1) as f32)
    } else {
        (other(c.depth_m, c.width_m), n, c.depth_m / (n - 1) as f32)
    }
}

/// The drip sites: those listed, or `count` scattered over the roof from the seed, kept a
/// stalactite's radius from the walls and (best effort) `min_spacing_m` apart.
pub fn drip_sites(params: &GrowCaveParams, seed: u64) -> Vec<Site> {
    match &params.sites {
        Sites::Explicit(sites) => sites.clone(),
        Sites::Scatter { count, min_spacing_m } => {
            let c = &params.chamber;
            let margin = params.stalactite_radius_m.max(params.stalagmite_radius_m).min(c.width_m.min(c.depth_m) / 4.0);
            // A stream of its own, after every site's.
            let mut rng = site_rng(seed, usize::MAX - 1);
            let mut out: Vec<Site> = Vec::with_capacity(*count as usize);
            // A candidate's gap matters only while it is under the spacing (at or over it, the
            // candidate is taken at once), so only the sites within the spacing are measured;
            // the gap is then the same as against every site (placing thousands of sites
            // stays linear, and the estimate can place them too).
            // Cells no smaller than 1/4096 of the chamber's side: a spacing of 1e-30 m would
            // otherwise give cell numbers past any integer.
            let mut placed = PointGrid::new(min_spacing_m.max(c.width_m.max(c.depth_m) / 4096.0));
            for i in 0..*count {
                let mut best = None;
                for _ in 0..30 {
                    let x = rng.random_range(margin..=c.width_m - margin);
                    let z = rng.random_range(margin..=c.depth_m - margin);
                    let gap = placed
                        .near(x, z)
                        .map(|j| (out[j as usize].x_m - x).hypot(out[j as usize].z_m - z))
                        .fold(f32::INFINITY, f32::min);
                    if best.is_none_or(|(_, _, g)| gap > g) {
                        best = Some((x, z, gap));
                    }
                    if gap >= *min_spacing_m {
                        break;
                    }
                }
                let (x_m, z_m, _) = best.expect("thirty candidates");
                placed.insert(i, x_m, z_m);
                out.push(Site { x_m, z_m, conditions: None, mineral: None });
            }
            out
        }
    }
}

/// A site's mineral: its own, the request's, or one of Table 1 drawn from its stream when
/// `random`.
pub fn site_mineral(params: &GrowCaveParams, site: &Site, seed: u64, index: usize) -> Mineral {
    match site.mineral.unwrap_or(params.mineral) {
        Mineral::Random => Mineral::ALL[site_rng(seed ^ 0x4D49_4E45, index).random_range(0..Mineral::ALL.len())],
        m => m,
    }
}
