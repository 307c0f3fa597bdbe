//! Drip sites that would grow into each other. At the start a site whose initial ring would
//! overlap an earlier site's **merges** into it (its water joins that site's flow; it grows
//! nothing of its own). Afterwards a ring that would reach another site's speleothem, or cross
//! the chamber's walls, is not grown and that speleothem **stops** growing vertically, as at
//! the roof or floor (a column forming in that pass stays two pieces and both stop).
//!
//! Each speleothem's body is a chain of capsules — anchor to first ring, ring to ring, with the
//! larger ring's radius plus its displacement — and, past every ring, a capsule for the rounded
//! top or the drip tip the mesh may add there. The coating and the column's waist later widen a
//! ring by less than half its clearance to any other site's capsules ([`Bodies::gap`]), so two
//! sites' surfaces never meet. A ring whose step would run into the floor (a stalagmite) or
//! the roof (a stalactite) away from its own foot stops it the same way: the wind can carry a
//! speleothem over a hump.

use super::chamber::{rim, ChamberShape};
use super::growth::{Ring, SiteGrowth};
use super::sequence::RecordedSite;

/// How far past a ring the mesh may reach (rounded top or drip tip), in ring radii.
pub const TIP_REACH: f32 = 1.2;
/// Share of a ring's clearance its coating and waist may take (the other site takes as much).
pub const CLEARANCE_SHARE: f32 = 0.45;
/// The least gap a new ring must keep from other sites' bodies and the walls, metres.
pub const MARGIN_M: f32 = 0.002;
/// Most bins along a side of the index.
const MAX_BINS: usize = 128;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Capsule {
    pub a: [f32; 3],
    pub b: [f32; 3],
    pub r: f32,
}

impl Capsule {
    /// The gap between the two surfaces (negative when they overlap).
    pub fn gap(&self, o: &Capsule) -> f32 {
        segment_distance(self.a, self.b, o.a, o.b) as f32 - self.r - o.r
    }

    /// (min x, max x, min z, max z) of the capsule.
    fn bounds_xz(&self) -> [f32; 4] {
        [
            self.a[0].min(self.b[0]) - self.r,
            self.a[0].max(self.b[0]) + self.r,
            self.a[2].min(self.b[2]) - self.r,
            self.a[2].max(self.b[2]) + self.r,
        ]
    }

    /// The gap to the walls of the box [0, width] × [0, depth] (negative when it crosses one).
    pub fn wall_gap(&self, width: f32, depth: f32) -> f32 {
        let [x0, x1, z0, z1] = self.bounds_xz();
        x0.min(width - x1).min(z0).min(depth - z1)
    }
}

/// The distance between segments pq and rs (closest points, Ericson §5.1.9), in f64.
fn segment_distance(p: [f32; 3], q: [f32; 3], r: [f32; 3], s: [f32; 3]) -> f64 {
    let v =
        |a: [f32; 3], b: [f32; 3]| [b[0] as f64 - a[0] as f64, b[1] as f64 - a[1] as f64, b[2] as f64 - a[2] as f64];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (d1, d2, w) = (v(p, q), v(r, s), v(r, p));
    let (a, e, f) = (dot(d1, d1), dot(d2, d2), dot(d2, w));
    let (mut sc, mut tc);
    if a <= 1e-18 && e <= 1e-18 {
        return dot(w, w).sqrt();
    }
    if a <= 1e-18 {
        sc = 0.0;
        tc = (f / e).clamp(0.0, 1.0);
    } else {
        let c = dot(d1, w);
        if e <= 1e-18 {
            tc = 0.0;
            sc = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = dot(d1, d2);
            let denom = a * e - b * b;
            sc = if denom > 1e-18 { ((b * f - c * e) / denom).clamp(0.0, 1.0) } else { 0.0 };
            tc = (b * sc + f) / e;
            if tc < 0.0 {
                tc = 0.0;
                sc = (-c / a).clamp(0.0, 1.0);
            } else if tc > 1.0 {
                tc = 1.0;
                sc = ((b - c) / a).clamp(0.0, 1.0);
            }
        }
    }
    let d: [f64; 3] = std::array::from_fn(|k| w[k] + d1[k] * sc - d2[k] * tc);
    dot(d, d).sqrt()
}

/// Every ring's centre, in world space, from the base (roof or floor) along the speleothem.
pub fn centres(site: &SiteGrowth, rings: &[Ring], down: bool) -> Vec<[f32; 3]> {
    let sign = if down { -1.0 } else { 1.0 };
    let (mut x, mut y, mut z) = (site.x_m, if down { site.roof_y_m } else { site.floor_y_m }, site.z_m);
    rings
        .iter()
        .map(|r| {
            x += r.shift()[0];
            z += r.shift()[1];
            y += sign * r.height();
            [x, y, z]
        })
        .collect()
}

/// The capsules ring `k` of a speleothem adds to its body: from the ring before (or the anchor
/// inside the rock) to this ring, and past this ring by [`TIP_REACH`] radii. `centres` are
/// [`centres`]'s.
pub fn ring_capsules(site: &SiteGrowth, rings: &[Ring], centres: &[[f32; 3]], k: usize, down: bool) -> [Capsule; 2] {
    let sign = if down { -1.0 } else { 1.0 };
    let base_y = if down { site.roof_y_m } else { site.floor_y_m };
    let (ring, here) = (rings[k], centres[k]);
    let reach = |r: &Ring| r.radius() + r.displacement();
    let (before, r_before) = if k == 0 {
        ([here[0], base_y - sign * ring.radius().max(0.02), here[2]], reach(&ring))
    } else {
        (centres[k - 1], reach(&rings[k - 1]))
    };
    let tip = [here[0], here[1] + sign * TIP_REACH * ring.radius(), here[2]];
    [Capsule { a: before, b: here, r: r_before.max(reach(&ring)) }, Capsule { a: here, b: tip, r: reach(&ring) }]
}

/// Every capsule of a site's speleothems, each with (stalagmite?, ring index).
pub fn site_capsules(site: &SiteGrowth) -> Vec<(bool, usize, Capsule)> {
    let mut out = Vec::new();
    for (up, rings) in [(false, &site.stalactite), (true, &site.stalagmite)] {
        let centres = centres(site, rings, !up);
        for k in 0..rings.len() {
            for c in ring_capsules(site, rings, &centres, k, !up) {
                out.push((up, k, c));
            }
        }
    }
    out
}

/// A uniform grid over the chamber (x, y, z) of every capsule grown so far, by site. Bins are
/// cubes; capsules beyond the chamber go in the bins at its edge.
pub struct Bodies {
    cell: f32,
    /// Bins along x, y, z.
    n: [usize; 3],
    bins: Vec<Vec<u32>>,
    items: Vec<(u32, Capsule)>,
}

impl Bodies {
    /// An empty index over width × height × depth with bins of about `cell` metres (at most
    /// [`MAX_BINS`] a side and [`MAX_BINS`]² · 16 in all).
    pub fn new(width: f32, depth: f32, height: f32, cell: f32) -> Self {
        let extent = [width, height, depth];
        let mut cell = extent.iter().fold(cell.max(1e-6), |c, &e| c.max(e / MAX_BINS as f32));
        let count = |cell: f32| extent.map(|e| ((e / cell).ceil() as usize).clamp(1, MAX_BINS));
        while count(cell).iter().product::<usize>() > MAX_BINS * MAX_BINS * 16 {
            cell *= 1.25;
        }
        let n = count(cell);
        Self { cell, n, bins: vec![Vec::new(); n[0] * n[1] * n[2]], items: Vec::new() }
    }

    fn empty_like(&self) -> Self {
        Self { cell: self.cell, n: self.n, bins: vec![Vec::new(); self.bins.len()], items: Vec::new() }
    }

    /// The bin box (low and high bin along x, y, z) of `c`.
    fn span(&self, c: &Capsule) -> ([i64; 3], [i64; 3]) {
        let index = |v: f32, k: usize| ((v / self.cell).floor().max(0.0) as i64).min(self.n[k] as i64 - 1);
        let lo = [0, 1, 2].map(|k| index(c.a[k].min(c.b[k]) - c.r, k));
        let hi = [0, 1, 2].map(|k| index(c.a[k].max(c.b[k]) + c.r, k));
        (lo, hi)
    }

    fn bin(&self, [x, y, z]: [i64; 3]) -> usize {
        (x as usize) + self.n[0] * ((z as usize) + self.n[2] * y as usize)
    }

    pub fn insert(&mut self, site: u32, c: Capsule) {
        let id = self.items.len() as u32;
        self.items.push((site, c));
        let (lo, hi) = self.span(&c);
        for y in lo[1]..=hi[1] {
            for z in lo[2]..=hi[2] {
                for x in lo[0]..=hi[0] {
                    let b = self.bin([x, y, z]);
                    self.bins[b].push(id);
                }
            }
        }
    }

    /// The smallest gap from `c` to a capsule of another site within `reach` metres of it
    /// (infinity when none is that near; a nearer one may be reported beyond it). Bins are
    /// searched in shells outwards from `c`'s own, and the search ends once a shell lies
    /// farther than the best gap so far: a capsule in shell k is at least (k − 1) bins away.
    pub fn gap(&self, site: u32, c: &Capsule, reach: f32) -> f32 {
        let (lo, hi) = self.span(c);
        let n = self.n.map(|v| v as i64);
        let mut best = f32::INFINITY;
        for k in 0i64.. {
            if k >= 1 && (k - 1) as f32 * self.cell > best.min(reach.max(0.0)) {
                break;
            }
            // The shells so far covered the whole grid.
            if k >= 1 && (0..3).all(|d| lo[d] - (k - 1) <= 0 && hi[d] + (k - 1) >= n[d] - 1) {
                break;
            }
            let (a, b) = (lo.map(|v| v - k), hi.map(|v| v + k));
            for y in a[1].max(0)..=b[1].min(n[1] - 1) {
                for z in a[2].max(0)..=b[2].min(n[2] - 1) {
                    // Inside the shell before: only the two x ends.
                    let inner = k > 0 && y > a[1] && y < b[1] && z > a[2] && z < b[2];
                    let xs: Vec<i64> = if inner { vec![a[0], b[0]] } else { (a[0]..=b[0]).collect() };
                    for x in xs {
                        if x < 0 || x >= n[0] {
                            continue;
                        }
                        for &id in &self.bins[self.bin([x, y, z])] {
                            let (other, o) = &self.items[id as usize];
                            if *other != site {
                                best = best.min(c.gap(o));
                            }
                        }
                    }
                }
            }
        }
        best
    }

    /// An index of every capsule of every site that grows.
    pub fn of_sites<'a>(
        sites: impl Iterator<Item = &'a SiteGrowth>,
        [width, depth, height]: [f32; 3],
        cell: f32,
    ) -> Self {
        let mut bodies = Bodies::new(width, depth, height, cell);
        for (i, s) in sites.enumerate() {
            for (_, _, c) in site_capsules(s) {
                bodies.insert(i as u32, c);
            }
        }
        bodies
    }
}

/// Bin size for a cave: a few of its largest rings across, or a ring's farthest wind drift.
pub fn bin_size(params: &super::params::GrowCaveParams) -> f32 {
    let radius = params.stalactite_radius_m.max(params.stalagmite_radius_m) + params.kf_m;
    let drift = params.wind.as_ref().map_or(0.0, |w| w.scale * 4.5 * params.height_step_m);
    (4.0 * radius).max(drift)
}

/// Which sites merge into an earlier one at the start: a site whose initial stalactite ring
/// (with its displacement) would come within [`MARGIN_M`] of an earlier, unmerged site's (the
/// earliest such).
pub fn merges(sites: &[(f32, f32)], radius: f32) -> Vec<Option<u32>> {
    let reach = 2.0 * radius + MARGIN_M;
    let mut unmerged = PointGrid::new(reach);
    let mut out: Vec<Option<u32>> = vec![None; sites.len()];
    for (i, &(x, z)) in sites.iter().enumerate() {
        out[i] =
            unmerged.near(x, z).filter(|&j| (sites[j as usize].0 - x).hypot(sites[j as usize].1 - z) < reach).min();
        if out[i].is_none() {
            unmerged.insert(i as u32, x, z);
        }
    }
    out
}

/// Points (by number) in square cells at least `reach` wide: every point nearer than `reach`
/// to a place is in the place's cell or the eight around it, so a search for close points
/// reads only those instead of every point.
pub struct PointGrid {
    cell: f32,
    cells: std::collections::HashMap<(i64, i64), Vec<u32>>,
}

impl PointGrid {
    pub fn new(reach: f32) -> Self {
        // A reach of 0 (or less) finds nothing nearer than it: any cell size does.
        Self { cell: if reach > 0.0 { reach } else { 1.0 }, cells: Default::default() }
    }

    fn key(&self, x: f32, z: f32) -> (i64, i64) {
        ((x / self.cell).floor() as i64, (z / self.cell).floor() as i64)
    }

    pub fn insert(&mut self, i: u32, x: f32, z: f32) {
        let key = self.key(x, z);
        self.cells.entry(key).or_default().push(i);
    }

    /// The points in the cell of (x, z) and the eight around it: a superset of those nearer
    /// than the reach.
    pub fn near(&self, x: f32, z: f32) -> impl Iterator<Item = u32> + '_ {
        let (cx, cz) = self.key(x, z);
        (-1..=1)
            .flat_map(move |dz| (-1..=1).map(move |dx| (cx.saturating_add(dx), cz.saturating_add(dz))))
            .filter_map(|k| self.cells.get(&k))
            .flatten()
            .copied()
    }
}

/// What a site may still lose this pass: its newest ring of one speleothem.
fn newest(site: &SiteGrowth, up: bool, pass: u32) -> Option<[Capsule; 2]> {
    let rings = if up { &site.stalagmite } else { &site.stalactite };
    rings.last().filter(|r| r.pass() == pass)?;
    let centres = centres(site, rings, !up);
    Some(ring_capsules(site, rings, &centres, rings.len() - 1, !up))
}

/// Whether the newest ring's step (from the ring before) stands in open air: its axis, and the
/// rim of its disc, every quarter radius along it above the floor for a stalagmite (below the
/// roof for a stalactite), except where its foot is buried in a sloping floor (roof) — up to
/// the highest floor (lowest roof) under a disc of its radius round its first ring. The other surface is
/// for [`super::growth::Grower::check_limits`], which stops the tip on it.
pub fn in_open_air(shape: &ChamberShape, site: &SiteGrowth, up: bool) -> bool {
    let rings = if up { &site.stalagmite } else { &site.stalactite };
    let Some(k) = rings.len().checked_sub(1).filter(|&k| k > 0) else { return true };
    let reach = |r: &Ring| r.radius() + r.displacement();
    let r = reach(&rings[k - 1]).max(reach(&rings[k]));
    let surface = |x: f32, z: f32| if up { shape.floor_y(x, z) } else { shape.roof_y(x, z) };
    let around = |x: f32, z: f32| rim([x, 0.0, z], r, 8);
    let sign = if up { 1.0 } else { -1.0 };
    let c = centres(site, rings, !up);
    // Heights measured along the speleothem's growth: up for a stalagmite, down for the other.
    let [x0, _, z0] = c[0];
    let foot = around(x0, z0).map(|(x, z)| sign * surface(x, z)).fold(f32::NEG_INFINITY, f32::max);
    let (a, b) = (c[k - 1], c[k]);
    let length = (0..3).map(|i| (b[i] - a[i]).powi(2)).sum::<f32>().sqrt();
    let n = ((length / (0.25 * r.max(0.01))).ceil() as usize).clamp(2, 256);
    (0..=n).all(|i| {
        let t = i as f32 / n as f32;
        let p: [f32; 3] = std::array::from_fn(|j| a[j] + (b[j] - a[j]) * t);
        let y = sign * p[1];
        y <= foot + MARGIN_M
            || y > sign * surface(p[0], p[2]) + MARGIN_M && around(p[0], p[2]).all(|(x, z)| y > sign * surface(x, z))
    })
}

/// Check this pass's new rings against the other sites' bodies, the walls, and the floor or
/// roof ([`in_open_air`]) — stalactites first, then stalagmites, placed under the drip point
/// as it now stands. A ring that would come within [`MARGIN_M`] of another site's body (grown
/// before or this pass) or of a wall, or into the floor or roof, is removed and its
/// speleothem stops; a site that became a column this pass loses the pass's
/// rings of both and both stop. Accepted rings enter `bodies`. Returns how many speleothems
/// stopped. Every decision depends only on the state before the check, so the order of sites
/// does not matter.
pub fn settle(sites: &mut [RecordedSite], bodies: &mut Bodies, shape: &ChamberShape, pass: u32) -> usize {
    use rayon::prelude::*;
    let (width, depth) = (shape.chamber.width_m, shape.chamber.depth_m);
    let mut stopped = 0;
    for up in [false, true] {
        if up {
            sites.par_iter_mut().for_each(|s| s.growth.place_under_drip(pass));
        }
        let pending: Vec<(usize, [Capsule; 2])> =
            sites.iter().enumerate().filter_map(|(i, s)| newest(&s.growth, up, pass).map(|c| (i, c))).collect();
        let mut this_pass = bodies.empty_like();
        for (i, caps) in &pending {
            for c in caps {
                this_pass.insert(*i as u32, *c);
            }
        }
        let rejected: Vec<bool> = pending
            .par_iter()
            .map(|(i, caps)| {
                !in_open_air(shape, &sites[*i].growth, up)
                    || caps.iter().any(|c| {
                        let site = *i as u32;
                        c.wall_gap(width, depth) < MARGIN_M
                            || bodies.gap(site, c, MARGIN_M) < MARGIN_M
                            || this_pass.gap(site, c, MARGIN_M) < MARGIN_M
                    })
            })
            .collect();
        for ((i, caps), no) in pending.into_iter().zip(rejected) {
            let site = &mut sites[i].growth;
            if !no {
                for c in caps {
                    bodies.insert(i as u32, c);
                }
                continue;
            }
            stopped += 1;
            if site.column_at == Some(pass) {
                site.column_at = None;
                site.stalactite.retain(|r| r.pass() != pass);
                site.stalagmite.retain(|r| r.pass() != pass);
                site.stalactite_done = true;
                site.stalagmite_done = true;
            } else if up {
                site.stalagmite.pop();
                site.stalagmite_done = true;
            } else {
                site.stalactite.pop();
                site.stalactite_done = true;
            }
        }
    }
    stopped
}
