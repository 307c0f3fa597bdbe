//! A speleothem's surface: a closed tube through its rings (paper Figures 5–6: each pass joins
//! the new ring to the one before), capped inside the roof or floor it hangs from and closed
//! at its tip, coloured base to tip by fv_c = mc · (arID / rc) (section 4.2).

use std::f32::consts::TAU;

use super::growth::{Ring, SiteGrowth, CLOSED_RADIUS_M};
use crate::mesh::{recompute_normals, Mesh};

/// One ring as placed: centre, radius, displacement, colour factor.
struct Placed {
    centre: [f32; 3],
    radius: f32,
    displacement: f32,
    /// The colour factor: arID / rc, lifted so the base is not black (see [`BASE_SHADE`]).
    shade: f32,
}

/// fv_c = mc · (arID / rc) darkens a speleothem's first rings to black, which no cave shows
/// (the paper's own pictures are light at the base): the linear variation runs from this share
/// of mc at the base to all of it at the tip.
pub const BASE_SHADE: f32 = 0.4;

fn shade(ring_fraction: f32) -> f32 {
    BASE_SHADE + (1.0 - BASE_SHADE) * ring_fraction
}

/// Rings of a stalactite (down from the roof, `down = true`) or stalagmite (up from the floor),
/// in world space, starting with an anchor one radius inside the rock so the base is sealed
/// however the rock surface slopes.
fn place(site: &SiteGrowth, rings: &[Ring], down: bool) -> Vec<Placed> {
    let sign = if down { -1.0 } else { 1.0 };
    let base_y = if down { site.roof_y_m } else { site.floor_y_m };
    let rc = rings.len() as f32;
    let mut out = Vec::with_capacity(rings.len() + 1);
    let first = rings[0];
    // A stalagmite's first ring stands under the drip point (its recorded shift from the site).
    let [fx, fz] = first.shift();
    out.push(Placed {
        centre: [site.x_m + fx, base_y - sign * first.radius().max(0.02), site.z_m + fz],
        radius: first.radius(),
        displacement: 0.0,
        shade: shade(1.0 / rc),
    });
    let (mut x, mut y, mut z) = (site.x_m, base_y, site.z_m);
    for (k, ring) in rings.iter().enumerate() {
        let [dx, dz] = ring.shift();
        x += dx;
        z += dz;
        y += sign * ring.height();
        out.push(Placed {
            centre: [x, y, z],
            radius: ring.radius(),
            displacement: ring.displacement(),
            shade: shade((k + 1) as f32 / rc),
        });
    }
    out
}

/// Per-vertex horizontal displacement factor in [0, 1]: a hash of (site, ring, vertex), so a
/// replay needs no random stream.
fn roughness(site: u64, ring: usize, vertex: usize) -> f32 {
    let mut z = site.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (ring as u64) << 20 ^ vertex as u64;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}

/// Builds one closed tube: rings of `segments` vertices, a cap at each end.
struct Tube {
    mesh: Mesh,
    segments: usize,
    colour: [f32; 3],
    site: u64,
}

impl Tube {
    fn new(segments: usize, colour: [f32; 3], site: u64) -> Self {
        let mesh = Mesh { colors: Some(Vec::new()), ..Mesh::default() };
        Self { mesh, segments, colour, site }
    }

    fn vertex(&mut self, p: [f32; 3], shade: f32, uv: [f32; 2]) -> u32 {
        let c = self.colour.map(|c| (c * shade * 255.0).round().clamp(0.0, 255.0) as u8);
        self.mesh.positions.push(p);
        self.mesh.normals.push([0.0, 1.0, 0.0]);
        self.mesh.uvs.push(uv);
        self.mesh.colors.as_mut().expect("colours").push([c[0], c[1], c[2], 255]);
        (self.mesh.positions.len() - 1) as u32
    }

    /// Add a ring's vertices (or one vertex when it has closed to a point); returns the first.
    fn ring(&mut self, r: &Placed, index: usize, v: f32) -> (u32, bool) {
        if r.radius < CLOSED_RADIUS_M {
            return (self.vertex(r.centre, r.shade, [0.5, v]), true);
        }
        let first = self.mesh.positions.len() as u32;
        for j in 0..self.segments {
            let a = TAU * j as f32 / self.segments as f32;
            let rr = r.radius + r.displacement * roughness(self.site, index, j);
            let p = [r.centre[0] + rr * a.cos(), r.centre[1], r.centre[2] + rr * a.sin()];
            self.vertex(p, r.shade, [j as f32 / self.segments as f32, v]);
        }
        (first, false)
    }

    /// Join ring `a` to ring `b` (either may be a point) with triangles facing out of the
    /// tube; `down` when `b` lies below `a`.
    fn join(&mut self, a: (u32, bool), b: (u32, bool), down: bool) {
        let n = self.segments as u32;
        let tri = |m: &mut Mesh, i: u32, j: u32, k: u32| {
            if down {
                m.indices.extend([i, j, k]);
            } else {
                m.indices.extend([i, k, j]);
            }
        };
        for s in 0..n {
            let t = (s + 1) % n;
            match (a.1, b.1) {
                (false, false) => {
                    tri(&mut self.mesh, a.0 + s, a.0 + t, b.0 + s);
                    tri(&mut self.mesh, a.0 + t, b.0 + t, b.0 + s);
                }
                (false, true) => tri(&mut self.mesh, a.0 + s, a.0 + t, b.0),
                (true, false) => tri(&mut self.mesh, a.0, b.0 + t, b.0 + s),
                (true, true) => {}
            }
        }
    }

    /// Close ring `r` with a fan to `apex`.
    fn cap(&mut self, r: (u32, bool), apex: [f32; 3], shade: f32, v: f32, down: bool) {
        if r.1 {
            return;
        }
        let c = (self.vertex(apex, shade, [0.5, v]), true);
        self.join(r, c, down);
    }
}

/// Run the tube through the placed rings, in order (top to bottom when `down`), capping the
/// first and last.
fn tube_through(tube: &mut Tube, placed: &[Placed], down: bool) {
    let sign = if down { -1.0 } else { 1.0 };
    let count = placed.len() as f32;
    let mut previous: Option<(u32, bool)> = None;
    for (k, r) in placed.iter().enumerate() {
        let v = k as f32 / count;
        let current = tube.ring(r, k, v);
        match previous {
            None => {
                let apex = [r.centre[0], r.centre[1] - sign * r.radius * 0.5, r.centre[2]];
                tube.cap(current, apex, r.shade, v, !down);
            }
            Some(p) => tube.join(p, current, down),
        }
        previous = Some(current);
        if current.1 {
            return; // closed to a point: the tip
        }
    }
    let last = placed.last().expect("rings");
    let apex = [last.centre[0], last.centre[1] + sign * last.radius * 0.5, last.centre[2]];
    tube.cap(previous.expect("a ring"), apex, last.shade, 1.0, down);
}

fn finish(mut tube: Tube) -> Mesh {
    recompute_normals(&mut tube.mesh);
    tube.mesh
}

/// A stalactite or stalagmite on its own.
pub fn speleothem_mesh(
    site: &SiteGrowth,
    index: u64,
    rings: &[Ring],
    down: bool,
    segments: usize,
    colour: [f32; 3],
) -> Mesh {
    let placed = place(site, rings, down);
    let mut tube = Tube::new(segments, colour, index * 2 + !down as u64);
    tube_through(&mut tube, &placed, down);
    finish(tube)
}

/// A column: the stalactite's rings down to where they met, then the stalagmite's back down
/// to the floor, one closed tube.
pub fn column_mesh(site: &SiteGrowth, index: u64, segments: usize, colour: [f32; 3]) -> Mesh {
    let mut placed = place(site, &site.stalactite, true);
    let mut below = place(site, &site.stalagmite, false);
    below.reverse();
    // The two meeting rings coincide in height; keep the stalactite's.
    below.remove(0);
    placed.extend(below);
    let mut tube = Tube::new(segments, colour, index * 2);
    tube_through(&mut tube, &placed, true);
    finish(tube)
}
