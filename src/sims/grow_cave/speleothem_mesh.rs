//! A speleothem's surface: a closed tube through the sections of its profile (paper Figures
//! 5–6: each pass joins the new ring to the one before), capped inside the roof or floor it
//! hangs from and closed at its tip — to a point, or round into the central canal of a hollow
//! straw — coloured base to tip by fv_c = mc · (arID / rc) (section 4.2).

use std::f32::consts::TAU;

use super::growth::CLOSED_RADIUS_M;
use crate::mesh::{recompute_normals, Mesh};

/// One cross-section of a speleothem's surface: a horizontal ring (or a point when its
/// radius is below [`CLOSED_RADIUS_M`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Section {
    pub centre: [f32; 3],
    pub radius: f32,
    /// How far the roughness may push a vertex out (vd of section 4.1).
    pub displacement: f32,
    /// The colour factor: arID / rc, lifted so the base is not black (see [`BASE_SHADE`]).
    pub shade: f32,
}

/// How a tube ends past its last section.
#[derive(Clone, Debug, PartialEq)]
pub enum End {
    /// A fan to this point.
    Apex([f32; 3]),
    /// Open into a central canal: an annulus at the last section, then the canal's wall up
    /// through the sections from `from` (radii `radii`, tip last) to a point at `apex`.
    Canal { from: usize, radii: Vec<f32>, apex: [f32; 3] },
}

/// A speleothem's surface as a tube through its sections, in order (top to bottom when
/// `down`), closed at the start by a fan to `start` and at the end by `end`.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    pub sections: Vec<Section>,
    pub down: bool,
    pub start: [f32; 3],
    pub end: End,
}

/// fv_c = mc · (arID / rc) darkens a speleothem's first rings to black, which no cave shows
/// (the paper's own pictures are light at the base): the linear variation runs from this share
/// of mc at the base to all of it at the tip.
pub const BASE_SHADE: f32 = 0.4;

pub fn shade(ring_fraction: f32) -> f32 {
    BASE_SHADE + (1.0 - BASE_SHADE) * ring_fraction
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

    /// Add a section's vertices (or one vertex when it has closed to a point); returns the
    /// first. `index` keys the roughness.
    fn ring(&mut self, r: &Section, index: usize, v: f32) -> (u32, bool) {
        if r.radius < CLOSED_RADIUS_M {
            return (self.vertex(r.centre, r.shade, [0.5, v]), true);
        }
        let first = self.mesh.positions.len() as u32;
        for j in 0..self.segments {
            let a = TAU * j as f32 / self.segments as f32;
            let rough = if r.displacement > 0.0 { r.displacement * roughness(self.site, index, j) } else { 0.0 };
            let rr = r.radius + rough;
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

/// Run the tube through the profile's sections and close both ends.
fn tube_through(tube: &mut Tube, p: &Profile) {
    let (placed, down) = (&p.sections, p.down);
    let count = placed.len() as f32;
    let mut previous: Option<(u32, bool)> = None;
    for (k, r) in placed.iter().enumerate() {
        let v = k as f32 / count;
        let current = tube.ring(r, k, v);
        match previous {
            None => tube.cap(current, p.start, r.shade, v, !down),
            Some(p) => tube.join(p, current, down),
        }
        previous = Some(current);
        if current.1 {
            return; // closed to a point: the tip
        }
    }
    let last = placed.last().expect("sections");
    let outer = previous.expect("a ring");
    match &p.end {
        End::Apex(apex) => tube.cap(outer, *apex, last.shade, 1.0, down),
        End::Canal { from, radii, apex } => {
            // The canal's wall faces its axis: joined the other way round from the outside.
            let mut inner = None;
            for (k, (s, &c)) in placed[*from..].iter().zip(radii).enumerate().rev() {
                let section = Section { radius: c, displacement: 0.0, ..*s };
                let ring = tube.ring(&section, from + k, 1.0);
                match inner {
                    None => tube.join(outer, ring, down),
                    Some(below) => tube.join(below, ring, down),
                }
                inner = Some(ring);
            }
            tube.cap(inner.expect("a hollow section"), *apex, last.shade, 1.0, down);
        }
    }
}

/// The tube's mesh with its normals, less any vertex no triangle uses (it would be no point
/// of the surface, yet a level's measure or an engine's bounds would count it).
fn finish(mut tube: Tube) -> Mesh {
    recompute_normals(&mut tube.mesh);
    tube.mesh.without_unused_vertices()
}

/// The closed surface of a profile: `key` seeds its roughness.
pub fn profile_mesh(p: &Profile, key: u64, segments: usize, colour: [f32; 3]) -> Mesh {
    let mut tube = Tube::new(segments, colour, key);
    tube_through(&mut tube, p);
    finish(tube)
}
