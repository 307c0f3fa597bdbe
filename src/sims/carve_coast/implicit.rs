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

/// An authored capsule: `[ax, ay, az, bx, by, bz, radius]` (a segment swept by a sphere) and
/// its pass, metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Capsule(pub [f32; 7], pub u32);

impl Capsule {
    pub fn ends(&self) -> ([f32; 3], [f32; 3]) {
        let c = self.0;
        ([c[0], c[1], c[2]], [c[3], c[4], c[5]])
    }
    pub fn distance(&self, p: [f32; 3]) -> f32 {
        let (a, b) = self.ends();
        let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
        let len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
        let t = if len2 > 0.0 { ((ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / len2).clamp(0.0, 1.0) } else { 0.0 };
        let d = [ap[0] - ab[0] * t, ap[1] - ab[1] * t, ap[2] - ab[2] * t];
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - self.0[6]
    }
}

/// One carving of the sequence: a sphere (eroded or authored) or an authored capsule. Stored as
/// `[[x, y, z, r], pass]` or `[[ax, ay, az, bx, by, bz, r], pass]`, so sequences written before
/// capsules existed read the same.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Carving {
    Sphere(Sphere),
    Capsule(Capsule),
}

impl Carving {
    pub fn pass(&self) -> u32 {
        match self {
            Carving::Sphere(s) => s.pass(),
            Carving::Capsule(c) => c.1,
        }
    }
    pub fn radius(&self) -> f32 {
        match self {
            Carving::Sphere(s) => s.radius(),
            Carving::Capsule(c) => c.0[6],
        }
    }
    /// The sphere's centre, or the capsule's middle.
    pub fn centre(&self) -> [f32; 3] {
        match self {
            Carving::Sphere(s) => s.centre(),
            Carving::Capsule(c) => {
                let (a, b) = c.ends();
                [0, 1, 2].map(|k| (a[k] + b[k]) / 2.0)
            }
        }
    }
    pub fn distance(&self, p: [f32; 3]) -> f32 {
        match self {
            Carving::Sphere(s) => s.distance(p),
            Carving::Capsule(c) => c.distance(p),
        }
    }
    /// The box it carves within: (least, greatest) corner.
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let r = self.radius();
        let (a, b) = match self {
            Carving::Sphere(s) => (s.centre(), s.centre()),
            Carving::Capsule(c) => c.ends(),
        };
        ([0, 1, 2].map(|k| a[k].min(b[k]) - r), [0, 1, 2].map(|k| a[k].max(b[k]) + r))
    }
}

/// Carvings binned on a horizontal grid by their horizontal bounds, so a point tests only the
/// spheres that can reach it. A query names how far it must see ([`SphereIndex::visit`]): every
/// bin that box overlaps is visited, so no sphere within that reach is missed at a bin's edge.
pub struct CarvingIndex {
    cell_m: f32,
    cols: usize,
    rows: usize,
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl CarvingIndex {
    pub fn new(spheres: &[Carving], width_m: f32, depth_m: f32) -> Self {
        // Bins twice the largest sphere's radius (capsules span several bins).
        let max_r = spheres.iter().map(Carving::radius).fold(1.0f32, f32::max);
        let cell_m = (2.0 * max_r).max(width_m.max(depth_m) / 1024.0);
        let cols = (width_m / cell_m).ceil() as usize + 1;
        let rows = (depth_m / cell_m).ceil() as usize + 1;
        let mut index = Self { cell_m, cols, rows, offsets: vec![0; cols * rows + 1], items: Vec::new() };
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        for (i, s) in spheres.iter().enumerate() {
            match s {
                Carving::Sphere(sphere) => {
                    let [x, _, z] = sphere.centre();
                    index.insert_box(x, z, sphere.radius(), i, &mut pairs);
                }
                // A capsule goes into the bins along its segment, not its whole bounding box:
                // a long diagonal one would otherwise fill every bin of the grid. The segment is
                // clipped first to the footprint with a wide margin (its ends may lie far outside;
                // the margin keeps what warped points near the edges can reach).
                Carving::Capsule(c) => {
                    let r = c.0[6];
                    let (a, b) = c.ends();
                    let m = r + 0.5 * width_m.max(depth_m);
                    let Some((t0, t1)) = clip([a[0], a[2]], [b[0], b[2]], -m, width_m + m, -m, depth_m + m) else {
                        continue;
                    };
                    let (dx, dz) = (b[0] - a[0], b[2] - a[2]);
                    let length = (t1 - t0) * (dx * dx + dz * dz).sqrt();
                    let steps = (length / (0.5 * cell_m)).ceil() as usize;
                    for k in 0..=steps {
                        let t = t0 + (t1 - t0) * k as f32 / steps.max(1) as f32;
                        index.insert_box(a[0] + dx * t, a[2] + dz * t, r + 0.5 * cell_m, i, &mut pairs);
                    }
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        for &(cell, _) in &pairs {
            index.offsets[cell as usize + 1] += 1;
        }
        for k in 1..index.offsets.len() {
            index.offsets[k] += index.offsets[k - 1];
        }
        index.items = pairs.into_iter().map(|(_, i)| i).collect();
        index
    }

    fn insert_box(&self, x: f32, z: f32, reach: f32, item: usize, pairs: &mut Vec<(u32, u32)>) {
        let (c0, c1, r0, r1) = self.bins(x, z, reach);
        for row in r0..=r1 {
            for col in c0..=c1 {
                pairs.push(((row * self.cols + col) as u32, item as u32));
            }
        }
    }

    /// The bins (first and last column, first and last row) a square of half-side `reach`
    /// around (x, z) overlaps.
    fn bins(&self, x: f32, z: f32, reach: f32) -> (usize, usize, usize, usize) {
        let bin = |v: f32, n: usize| ((v / self.cell_m).floor().max(0.0) as usize).min(n - 1);
        (bin(x - reach, self.cols), bin(x + reach, self.cols), bin(z - reach, self.rows), bin(z + reach, self.rows))
    }

    /// Calls `f` with every carving whose horizontal bounds come within `reach` of (x, z) (and
    /// perhaps others; a sphere in several visited bins is seen once per bin).
    pub fn visit(&self, x: f32, z: f32, reach: f32, mut f: impl FnMut(u32)) {
        let (c0, c1, r0, r1) = self.bins(x, z, reach);
        for row in r0..=r1 {
            for col in c0..=c1 {
                let cell = row * self.cols + col;
                for &i in &self.items[self.offsets[cell] as usize..self.offsets[cell + 1] as usize] {
                    f(i);
                }
            }
        }
    }
}

/// The implicit terrain (seed: `Warp` applied to the point before the whole function): the
/// heightfield's distance carved by the spheres, both read at the warped point, within the
/// footprint (the sampler adds the bottom). Spheres live in the warped domain: a sphere grown
/// from a point p of the warped surface is centred at `warp(p)`.
pub struct Implicit<'a> {
    pub hf: &'a Heightfield,
    pub spheres: &'a [Carving],
    pub index: CarvingIndex,
    warp: Option<(f32, f32, Perlin)>,
    /// The field is exact where it is within this of zero (and right in sign everywhere).
    exact_m: f32,
    /// The furthest the warp moves a point horizontally, metres.
    warp_reach_m: f32,
}

impl<'a> Implicit<'a> {
    /// `exact_m`: within this distance of the surface the field equals the full function over
    /// every sphere (a sampler passes a couple of voxels).
    pub fn new(hf: &'a Heightfield, spheres: &'a [Carving], warp: Option<&Warp>, seed: u64, exact_m: f32) -> Self {
        let index = CarvingIndex::new(spheres, hf.width_m(), hf.depth_m());
        let warp = warp
            .filter(|w| w.amplitude_m > 0.0)
            .map(|w| (w.amplitude_m, w.frequency_per_m, Perlin::new(seed as u32 ^ 0x5741_5250)));
        let warp_reach_m = match &warp {
            None => 0.0,
            Some((amplitude, _, _)) => amplitude * max_gradient(hf),
        };
        Self { hf, spheres, index, warp, exact_m, warp_reach_m }
    }

    /// The furthest the warp moves a point horizontally, metres (0 without warp).
    pub fn warp_reach(&self) -> f32 {
        self.warp_reach_m
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

    /// The heightfield's approximate signed distance at a point of the warped domain: height
    /// difference scaled by the slope, so it stays a distance bound on steep ground.
    pub(super) fn terrain_distance_at(&self, q: [f32; 3]) -> f32 {
        let (gx, gz) = self.gradient(q[0], q[2]);
        (q[1] - self.hf.sample(q[0], q[2])) / (1.0 + gx * gx + gz * gz).sqrt()
    }

    /// Distance to the nearest carved sphere's surface at a point of the warped domain
    /// (negative inside one); exact within `exact_m`; beyond it never smaller than the true
    /// distance (spheres further than that may be left out), so the field's sign stays right.
    pub(super) fn sphere_distance_at(&self, q: [f32; 3]) -> f32 {
        let mut d = f32::INFINITY;
        self.index.visit(q[0], q[2], self.exact_m, |i| d = d.min(self.spheres[i as usize].distance(q)));
        d
    }

    /// Distance from world point `p` to the carved spheres' surfaces, read at its warped point.
    pub fn sphere_distance(&self, p: [f32; 3]) -> f32 {
        self.sphere_distance_at(self.warp(p))
    }

    /// The carved terrain at world point `p` without the box's walls: positive in air. On a
    /// wall it gives the surface the solid's side meets.
    pub fn carved(&self, p: [f32; 3]) -> f32 {
        let q = self.warp(p);
        self.terrain_distance_at(q).max(-self.sphere_distance_at(q))
    }

    /// The full implicit function at world point `p`: positive in air.
    pub fn distance(&self, p: [f32; 3]) -> f32 {
        let carved = self.carved(p);
        let walls = (-p[0]).max(p[0] - self.hf.width_m()).max(-p[2]).max(p[2] - self.hf.depth_m());
        carved.max(walls)
    }

    /// The same over every sphere, without the index: the reference the index is tested by.
    #[cfg(test)]
    pub fn distance_brute(&self, p: [f32; 3]) -> f32 {
        let q = self.warp(p);
        let s = self.spheres.iter().map(|s| s.distance(q)).fold(f32::INFINITY, f32::min);
        let carved = self.terrain_distance_at(q).max(-s);
        let walls = (-p[0]).max(p[0] - self.hf.width_m()).max(-p[2]).max(p[2] - self.hf.depth_m());
        carved.max(walls)
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

/// The part `[t0, t1]` of the segment a→b (horizontal, t in [0, 1]) inside the box
/// `[x0, x1] × [z0, z1]` (Liang–Barsky), or `None` when it misses.
fn clip(a: [f32; 2], b: [f32; 2], x0: f32, x1: f32, z0: f32, z1: f32) -> Option<(f32, f32)> {
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    let d = [b[0] - a[0], b[1] - a[1]];
    for (p, q) in [(-d[0], a[0] - x0), (d[0], x1 - a[0]), (-d[1], a[1] - z0), (d[1], z1 - a[1])] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// The steepest slope of the heightfield (central differences), metres per metre.
pub fn max_gradient(hf: &Heightfield) -> f32 {
    use rayon::prelude::*;
    (0..hf.rows)
        .into_par_iter()
        .map(|r| {
            (0..hf.cols)
                .map(|c| {
                    let (gx, gz) = hf.gradient(c, r);
                    (gx * gx + gz * gz).sqrt()
                })
                .fold(0.0f32, f32::max)
        })
        .reduce(|| 0.0, f32::max)
}
