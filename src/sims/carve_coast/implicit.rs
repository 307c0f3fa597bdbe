//! The terrain in implicit form (seed: `SDFHeightfield`, CSG subtraction, `Warp`): a signed
//! distance bound, positive in air and negative in rock, inside the terrain's box.

use noise::{NoiseFn, Perlin};
use serde::{Deserialize, Serialize};

use super::params::Warp;
use crate::terrain::Heightfield;

/// A carved sphere: `[x, y, z, radius, pass]`, metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sphere(pub [f32; 4], pub u32);

impl Sphere {
    pub fn centre(&self) -> [f32; 3] {
        [self.0[0], self.0[1], self.0[2]]
    }
    pub fn radius(&self) -> f32 {
        self.0[3]
    }
    pub fn pass(&self) -> u32 {
        self.1
    }
    pub fn distance(&self, p: [f32; 3]) -> f32 {
        let c = self.centre();
        ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt() - self.radius()
    }
}

/// Spheres binned on a horizontal grid, so a point tests only the spheres that can reach it.
pub struct SphereIndex {
    cell_m: f32,
    cols: usize,
    rows: usize,
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl SphereIndex {
    pub fn new(spheres: &[Sphere], width_m: f32, depth_m: f32) -> Self {
        let max_r = spheres.iter().map(Sphere::radius).fold(1.0f32, f32::max);
        let cell_m = (2.0 * max_r).max(width_m.max(depth_m) / 1024.0);
        let cols = (width_m / cell_m).ceil() as usize + 1;
        let rows = (depth_m / cell_m).ceil() as usize + 1;
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        for (i, s) in spheres.iter().enumerate() {
            let [x, _, z] = s.centre();
            let r = s.radius();
            let c0 = ((x - r) / cell_m).floor().max(0.0) as usize;
            let c1 = (((x + r) / cell_m).floor().max(0.0) as usize).min(cols - 1);
            let r0 = ((z - r) / cell_m).floor().max(0.0) as usize;
            let r1 = (((z + r) / cell_m).floor().max(0.0) as usize).min(rows - 1);
            for row in r0..=r1 {
                for col in c0..=c1 {
                    pairs.push(((row * cols + col) as u32, i as u32));
                }
            }
        }
        pairs.sort_unstable();
        let mut offsets = vec![0u32; cols * rows + 1];
        for &(cell, _) in &pairs {
            offsets[cell as usize + 1] += 1;
        }
        for k in 1..offsets.len() {
            offsets[k] += offsets[k - 1];
        }
        Self { cell_m, cols, rows, offsets, items: pairs.into_iter().map(|(_, i)| i).collect() }
    }

    /// Indices of the spheres whose horizontal bounds touch the bin of (x, z).
    pub fn near(&self, x: f32, z: f32) -> &[u32] {
        let col = ((x / self.cell_m).floor().max(0.0) as usize).min(self.cols - 1);
        let row = ((z / self.cell_m).floor().max(0.0) as usize).min(self.rows - 1);
        let cell = row * self.cols + col;
        &self.items[self.offsets[cell] as usize..self.offsets[cell + 1] as usize]
    }
}

/// The implicit terrain: heightfield distance, minus the spheres, warped, within the
/// footprint (the sampler adds the bottom).
pub struct Implicit<'a> {
    pub hf: &'a Heightfield,
    pub spheres: &'a [Sphere],
    pub index: SphereIndex,
    warp: Option<(f32, f32, Perlin)>,
}

impl<'a> Implicit<'a> {
    pub fn new(hf: &'a Heightfield, spheres: &'a [Sphere], warp: Option<&Warp>, seed: u64) -> Self {
        let index = SphereIndex::new(spheres, hf.width_m(), hf.depth_m());
        let warp = warp
            .filter(|w| w.amplitude_m > 0.0)
            .map(|w| (w.amplitude_m, w.frequency_per_m, Perlin::new(seed as u32 ^ 0x5741_5250)));
        Self { hf, spheres, index, warp }
    }

    /// Central-difference gradient of the heightfield at (x, z), metres per metre.
    pub fn gradient(&self, x: f32, z: f32) -> (f32, f32) {
        let c = self.hf.cell_size_m;
        let gx = (self.hf.sample(x + c, z) - self.hf.sample(x - c, z)) / (2.0 * c);
        let gz = (self.hf.sample(x, z + c) - self.hf.sample(x, z - c)) / (2.0 * c);
        (gx, gz)
    }

    /// The warped point (seed: `Warp`): pushed along the horizontal gradient by a 1D noise of
    /// height.
    pub fn warp(&self, p: [f32; 3]) -> [f32; 3] {
        match &self.warp {
            None => p,
            Some((amplitude, frequency, noise)) => {
                let w = noise.get([0.0, p[1] as f64 * *frequency as f64 + 0.5, 0.0]) as f32 * amplitude;
                let (gx, gz) = self.gradient(p[0], p[2]);
                [p[0] + gx * w, p[1], p[2] + gz * w]
            }
        }
    }

    /// The heightfield's approximate signed distance: height difference scaled by the slope, so
    /// it stays a distance bound on steep ground.
    pub fn terrain_distance(&self, p: [f32; 3]) -> f32 {
        let q = self.warp(p);
        let (gx, gz) = self.gradient(q[0], q[2]);
        (q[1] - self.hf.sample(q[0], q[2])) / (1.0 + gx * gx + gz * gz).sqrt()
    }

    /// Distance to the nearest carved sphere's surface (negative inside one), from `near`.
    pub fn sphere_distance(&self, p: [f32; 3], near: &[u32]) -> f32 {
        near.iter().map(|&i| self.spheres[i as usize].distance(p)).fold(f32::INFINITY, f32::min)
    }

    /// The full implicit function at `p`, with the spheres that can reach it.
    pub fn distance_with(&self, p: [f32; 3], near: &[u32]) -> f32 {
        let carved = self.terrain_distance(p).max(-self.sphere_distance(p, near));
        let walls = (-p[0]).max(p[0] - self.hf.width_m()).max(-p[2]).max(p[2] - self.hf.depth_m());
        carved.max(walls)
    }

    pub fn distance(&self, p: [f32; 3]) -> f32 {
        self.distance_with(p, self.index.near(p[0], p[2]))
    }

    /// Unit gradient of the implicit function (the outward normal) by central differences.
    pub fn normal(&self, p: [f32; 3], h: f32) -> [f32; 3] {
        let d = |dx: f32, dy: f32, dz: f32| self.distance([p[0] + dx, p[1] + dy, p[2] + dz]);
        let g = [d(h, 0.0, 0.0) - d(-h, 0.0, 0.0), d(0.0, h, 0.0) - d(0.0, -h, 0.0), d(0.0, 0.0, h) - d(0.0, 0.0, -h)];
        let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        if len > 0.0 {
            g.map(|c| c / len)
        } else {
            [0.0, 1.0, 0.0]
        }
    }
}
