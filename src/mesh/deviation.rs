//! How far apart two surfaces are: the largest distance from a point of either mesh to the
//! other (two-sided, a sampled Hausdorff distance). Points are taken on every triangle at most
//! `spacing` apart (its corners, its edges and a barycentric grid inside), and each is measured
//! to the nearest triangle of the other mesh exactly (closest point on a triangle, in f64),
//! found through a bounding-volume hierarchy of the other mesh's triangles ([`SurfaceIndex`]). The largest distance wins, so the figure is the same whatever the thread count. A
//! mesh measured against many others (a full mesh against its levels of detail) is indexed
//! once.

use rayon::prelude::*;

use super::Mesh;
use crate::stop::{Stop, Stopped};

/// Most sample points on one triangle side (a triangle gets at most about half its square).
const MAX_SPLITS: usize = 256;

/// The sampled two-sided distance between `a` and `b` in metres, points at most `spacing_m`
/// apart (or `MAX_SPLITS` per triangle side). 0 for two empty meshes, infinite when only one
/// is empty. `stop` is looked at between chunks of samples (a large mesh takes seconds).
pub fn max_deviation(a: &Mesh, b: &Mesh, spacing_m: f32, stop: Stop) -> Result<f32, Stopped> {
    max_deviation_from(a, &SurfaceIndex::new(a, stop)?, b, spacing_m, stop)
}

/// [`max_deviation`] with `a` already indexed (`a_index` is `SurfaceIndex::new(a, _)`), for a
/// mesh measured against several others.
pub fn max_deviation_from(
    a: &Mesh,
    a_index: &SurfaceIndex,
    b: &Mesh,
    spacing_m: f32,
    stop: Stop,
) -> Result<f32, Stopped> {
    Ok(deviation_and_misses(a, a_index, b, None, spacing_m, f32::INFINITY, false, stop)?.0)
}

/// [`max_deviation_from`], and the samples (of either mesh) farther than `bound_m` from the
/// other, in no particular order: where a level of detail misses its bound. Collecting them
/// costs an exact distance for each, so a level within its bound costs no more than measuring.
/// `b_corners_on_a`: every vertex of `b` lies on `a` (a level of detail's vertices are the full
/// mesh's), so a sample of `b` is no farther from `a` than from its triangle's nearest corner,
/// and one that near cannot raise the figure or miss: it is not measured. The figure and the
/// misses are the same either way. `b_index` is `b`'s index when the caller has it (else it is
/// built here, beside `b`'s side).
#[allow(clippy::too_many_arguments)]
pub fn deviation_and_misses(
    a: &Mesh,
    a_index: &SurfaceIndex,
    b: &Mesh,
    b_index: Option<&SurfaceIndex>,
    spacing_m: f32,
    bound_m: f32,
    b_corners_on_a: bool,
    stop: Stop,
) -> Result<(f32, Vec<[f32; 3]>), Stopped> {
    match (a.indices.is_empty(), b.indices.is_empty()) {
        (true, true) => return Ok((0.0, Vec::new())),
        (true, false) | (false, true) => return Ok((f32::INFINITY, Vec::new())),
        _ => {}
    }
    let misses = std::sync::Mutex::new(Vec::new());
    let bound = f64::from(bound_m);
    // One running largest distance for both sides: a sample of either within it cannot raise
    // the two-sided figure, so each side skips more than with its own (the full mesh's side
    // usually finds the larger distance, and the level's side then checks against it).
    let found = std::sync::atomic::AtomicU64::new(0f64.to_bits());
    rayon::join(
        || match b_index {
            Some(b_index) => one_sided(a, b_index, spacing_m, bound, &found, &misses, false, stop),
            None => {
                if let Ok(b_index) = SurfaceIndex::new(b, stop) {
                    one_sided(a, &b_index, spacing_m, bound, &found, &misses, false, stop);
                }
            }
        },
        || one_sided(b, a_index, spacing_m, bound, &found, &misses, b_corners_on_a, stop),
    );
    stop.check()?;
    let misses = misses.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner);
    Ok((f64::from_bits(found.into_inner()) as f32, misses))
}

/// How much finer than a level's spacing [`chained_deviation`] samples the source.
const THROUGH_FINER: f32 = 4.0;

/// Whether [`chained_deviation`] at `spacing_m` samples the source more sparsely than the full
/// mesh's own vertices lie (its triangles' typical side `full_side_m`), i.e. costs fewer
/// queries than the full mesh's side of a direct measure (both query the level's index). Where
/// it does not — a bound under four of the full mesh's triangle sides, as on grow-cave's
/// pieces — the level is measured directly.
pub fn chain_pays(spacing_m: f32, full_side_m: f32) -> bool {
    spacing_m / THROUGH_FINER > full_side_m
}

/// The farthest a point of a triangle lies from its nearest sample, as a share of the
/// spacing: rows and the points along them are at most the spacing apart, so at most half of
/// it across and half along (√2 ÷ 2); a triangle no longer than the spacing has its corners,
/// within 1 ÷ √3 of it. (A triangle over [`MAX_SPLITS`] spacings a side is sampled more
/// sparsely, as the direct measure samples it.)
const SAMPLE_GAP: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// An upper figure for the two-sided distance between a full mesh (`full_index` indexes it)
/// and `level` (`level_index` indexes it), a mesh made from `source` by collapses (its vertices are the full mesh's)
/// whose own figure is `source_deviation`. The level's side is measured against the full mesh
/// as in [`deviation_and_misses`]; the full mesh's side, a query for each of its samples (the
/// bulk of a measure: millions on a carved island), is bounded through the source instead:
/// every point of the full mesh lies within `source_deviation` of the source, and every
/// point of the source within `h` of the level (the source measured against the level, a
/// mesh of a fraction of the full one's triangles), so within `source_deviation + h` of the
/// level (the triangle inequality). h is sampled [`THROUGH_FINER`] times finer than
/// `spacing_m` and raised by the farthest a point of the source can lie from its nearest sample
/// ([`SAMPLE_GAP`] of that spacing), so the figure is at least the direct measure's (whose full
/// mesh's side samples the full mesh's own vertices); where it passes a bound the caller
/// measures directly.
pub fn chained_deviation(
    full_index: &SurfaceIndex,
    source: &Mesh,
    source_deviation: f32,
    level: &Mesh,
    level_index: &SurfaceIndex,
    spacing_m: f32,
    stop: Stop,
) -> Result<f32, Stopped> {
    use std::sync::atomic::AtomicU64;
    if source.indices.is_empty() || level.indices.is_empty() || full_index.is_empty() {
        return Ok(if source.indices.is_empty() && level.indices.is_empty() {
            source_deviation
        } else {
            f32::INFINITY
        });
    }
    let no_misses = std::sync::Mutex::new(Vec::new());
    let (level_side, through) = (AtomicU64::new(0f64.to_bits()), AtomicU64::new(0f64.to_bits()));
    let fine = spacing_m / THROUGH_FINER;
    rayon::join(
        || one_sided(level, full_index, spacing_m, f64::INFINITY, &level_side, &no_misses, true, stop),
        || one_sided(source, level_index, fine, f64::INFINITY, &through, &no_misses, false, stop),
    );
    stop.check()?;
    let level_side = f64::from_bits(level_side.into_inner());
    let gap = SAMPLE_GAP * f64::from(fine.max(1e-6));
    let full_side = f64::from(source_deviation) + f64::from_bits(through.into_inner()) + gap;
    // Rounded up to the next f32, so the figure never falls below what it bounds.
    let figure = level_side.max(full_side);
    let rounded = figure as f32;
    Ok(if f64::from(rounded) < figure { f32::from_bits(rounded.to_bits() + 1) } else { rounded })
}

/// Raises `found` (an f64's bits; non-negative f64s order as their bits do) to the largest
/// distance from a sample of `from` to the surface `to` indexes, if larger. A sample within
/// the largest distance found so far (by any thread, from either side) cannot raise it, so it
/// is only checked against that distance (or `bound`, if less), stopping at the first triangle
/// close enough; the others are measured exactly, and those farther than `bound` added to
/// `misses`. The maximum, and the set of misses, are the same whichever samples were only
/// checked: the sample farthest away is always measured (nothing found so far exceeds it).
/// With `corners_on`, `from`'s vertices lie on `to`: a sample no farther from its triangle's
/// nearest corner than that distance is not even checked.
/// A stopped search returns early with what it found (the caller looks at `stop` again).
#[allow(clippy::too_many_arguments)]
fn one_sided(
    from: &Mesh,
    to: &SurfaceIndex,
    spacing_m: f32,
    bound: f64,
    found: &std::sync::atomic::AtomicU64,
    misses: &std::sync::Mutex<Vec<[f32; 3]>>,
    corners_on: bool,
    stop: Stop,
) {
    use std::sync::atomic::Ordering;
    if to.is_empty() {
        return;
    }
    for_each_sample(from, spacing_m, stop, corners_on, &|s, corner, hints| {
        let so_far = f64::from_bits(found.load(Ordering::Relaxed));
        if corner <= so_far.min(bound) {
            return;
        }
        if !to.any_within(s, so_far.min(bound), hints) {
            let d = to.distance(s);
            found.fetch_max(d.to_bits(), Ordering::Relaxed);
            if d > bound {
                misses.lock().unwrap_or_else(std::sync::PoisonError::into_inner).push(s.map(|v| v as f32));
            }
        }
    });
}

/// Every sample of `from` at most `spacing_m` apart, each given to `visit` with, when
/// `corners_on`, its distance to the nearest corner of its triangle (else infinity), and hints
/// (see [`SurfaceIndex::any_within`]) shared by neighbouring samples; in parallel, returning
/// early once `stop` is raised. With `corners_on` the vertices themselves (at distance 0) are
/// left out.
fn for_each_sample(
    from: &Mesh,
    spacing_m: f32,
    stop: Stop,
    corners_on: bool,
    visit: &(dyn Fn([f64; 3], f64, &mut Hints) + Sync),
) {
    let corner = |s: [f64; 3], corners: &[[f64; 3]; 3]| {
        if corners_on {
            corners.iter().map(|&c| dist(s, c)).fold(f64::INFINITY, f64::min)
        } else {
            f64::INFINITY
        }
    };
    let spacing = f64::from(spacing_m.max(1e-6));
    // The centres of triangles more than twice the spacing long first: on a coarse mesh they
    // are the points farthest from the fine one, so the largest distance is found early and
    // most later samples are only checked. (A smaller triangle's points all lie within the
    // spacing of its corners and edge samples; its centre, an extra query on every triangle of
    // a fine mesh, found nothing the rest did not.) A triangle no side of which is longer than
    // the spacing has its corners for samples.
    let longest = |t: &[u32]| {
        let [p, q, r] = [0, 1, 2].map(|k| point(from, t[k]));
        (dist(p, q).max(dist(q, r)).max(dist(r, p)), [p, q, r])
    };
    from.indices.par_chunks(3 * 256).for_each(|chunk| {
        if stop.requested() {
            return;
        }
        let mut hints = Hints::default();
        for t in chunk.chunks_exact(3) {
            let (side, [p, q, r]) = longest(t);
            if side > 2.0 * spacing {
                let centre = std::array::from_fn(|k| (p[k] + q[k] + r[k]) / 3.0);
                visit(centre, corner(centre, &[p, q, r]), &mut hints);
            }
        }
    });
    // Every vertex a triangle uses once (one no triangle uses is not on the surface), then the
    // points along and inside each triangle (not its corners).
    let mut used = vec![false; from.positions.len()];
    for &i in &from.indices {
        used[i as usize] = true;
    }
    from.positions.par_chunks(1024).zip(used.par_chunks(1024)).for_each(|(chunk, used)| {
        if stop.requested() || corners_on {
            return;
        }
        let mut hints = Hints::default();
        for (v, _) in chunk.iter().zip(used).filter(|(_, &u)| u) {
            visit(v.map(f64::from), f64::INFINITY, &mut hints);
        }
    });
    from.indices.par_chunks(3 * 64).for_each(|chunk| {
        // Neighbouring samples are near the same triangles of `to`: the last one found close
        // enough is tried first.
        let mut hints = Hints::default();
        for t in chunk.chunks_exact(3) {
            if stop.requested() {
                return;
            }
            let (side, corners) = longest(t);
            if side > spacing {
                inside_samples(corners, spacing, &mut |s| visit(s, corner(s, &corners), &mut hints));
            }
        }
    });
}

/// The points of triangle `corners` other than its corners, at most `spacing` apart along rows
/// parallel to its longest side, the rows at most `spacing` apart (each row at most
/// `MAX_SPLITS` points, at most `MAX_SPLITS` rows): about area ÷ spacing² points, so a long thin
/// triangle costs no more than its area.
fn inside_samples(corners: [[f64; 3]; 3], spacing: f64, visit: &mut impl FnMut([f64; 3])) {
    let k = (0..3)
        .max_by(|&i, &j| dist(corners[i], corners[(i + 1) % 3]).total_cmp(&dist(corners[j], corners[(j + 1) % 3])))
        .unwrap_or(0);
    let (a, b, c) = (corners[k], corners[(k + 1) % 3], corners[(k + 2) % 3]);
    let base = dist(a, b);
    let height = if base > 0.0 { norm(cross(sub(b, a), sub(c, a))) / base } else { 0.0 };
    let rows = ((height / spacing).ceil() as usize).clamp(1, MAX_SPLITS);
    let lerp = |p: [f64; 3], q: [f64; 3], t: f64| -> [f64; 3] { std::array::from_fn(|k| p[k] + t * (q[k] - p[k])) };
    // Row `rows` is the apex, a corner.
    for j in 0..rows {
        let t = j as f64 / rows as f64;
        let (from, to) = (lerp(a, c, t), lerp(b, c, t));
        let n = ((base * (1.0 - t) / spacing).ceil() as usize).clamp(1, MAX_SPLITS);
        for i in 0..=n {
            if j == 0 && (i == 0 || i == n) {
                continue;
            }
            visit(lerp(from, to, i as f64 / n as f64));
        }
    }
}

/// The side of a square of the mesh's mean triangle area, metres (0 without triangles).
pub fn mean_triangle_side(mesh: &Mesh) -> f64 {
    let area: f64 = mesh
        .indices
        .chunks_exact(3)
        .map(|t| {
            let [p, q, r] = [0, 1, 2].map(|k| point(mesh, t[k]));
            0.5 * norm(cross(sub(q, p), sub(r, p)))
        })
        .sum();
    (2.0 * area / mesh.triangle_count().max(1) as f64).sqrt()
}

fn point(mesh: &Mesh, i: u32) -> [f64; 3] {
    mesh.positions[i as usize].map(f64::from)
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// The triangle (its place in a [`SurfaceIndex`]) found near the last sample. (Keeping four
/// was slower: each costs a distance, and a miss is rarely saved by an older one.)
#[derive(Clone, Copy, Default)]
struct Hints {
    last: u32,
}

/// Triangles a leaf of [`SurfaceIndex`] holds at most.
const LEAF_TRIANGLES: usize = 4;

/// A node of [`SurfaceIndex`]'s tree: its box and, for a leaf, its range of triangles
/// (`count` > 0, from `first`), else its children (`first` and `first + 1`).
#[derive(Clone, Copy)]
struct Node {
    lo: [f32; 3],
    hi: [f32; 3],
    first: u32,
    count: u32,
}

impl Node {
    /// The squared distance from `p` to the box (0 inside), a lower bound of the distance to
    /// anything in it; a hair under it, so the f32 box never hides what the f64 test would find.
    fn gap_2(&self, p: [f64; 3]) -> f64 {
        let g: f64 =
            (0..3).map(|k| (f64::from(self.lo[k]) - p[k]).max(p[k] - f64::from(self.hi[k])).max(0.0).powi(2)).sum();
        g * (1.0 - 1e-6)
    }
}

/// A mesh's triangles in a bounding-volume hierarchy (a binary tree of boxes split at the
/// median along their longest side, up to [`LEAF_TRIANGLES`] a leaf): the distance from a point
/// to the nearest triangle, and whether any lies within a radius, visiting the nearer child
/// first and skipping every box farther than what is sought. Boxes are f32 (the mesh's own
/// precision); every distance that decides a figure is exact in f64.
/// (The `rstar` crate's R*-tree did the same queries 3–5 times slower on levels of detail: its
/// within-radius walk visits every box the radius reaches, and its nearest search keeps a heap.)
pub struct SurfaceIndex {
    nodes: Vec<Node>,
    /// The triangles' corners in the tree's order.
    corners: Vec<[[f32; 3]; 3]>,
}

impl SurfaceIndex {
    /// The index of `mesh`'s triangles. A million triangles take seconds on a loaded machine,
    /// so `stop` is looked at while the tree is built.
    pub fn new(mesh: &Mesh, stop: Stop) -> Result<Self, Stopped> {
        let mut numbers: Vec<u32> = (0..mesh.triangle_count() as u32).collect();
        let centres: Vec<[f32; 3]> = numbers
            .iter()
            .map(|&n| {
                let [a, b, c] = corners(mesh, n);
                std::array::from_fn(|k| (a[k] + b[k] + c[k]) / 3.0)
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * numbers.len() / LEAF_TRIANGLES + 1);
        if !numbers.is_empty() {
            nodes.push(Node { lo: [0.0; 3], hi: [0.0; 3], first: 0, count: 0 });
            build(mesh, &centres, &mut numbers, 0, 0, &mut nodes, stop);
        }
        stop.check()?;
        let corners = numbers.iter().map(|&n| corners(mesh, n)).collect();
        Ok(Self { nodes, corners })
    }

    fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Whether some triangle lies within `radius` of `p`. `hints` holds the triangle found near
    /// the sample before (neighbouring samples are usually near the same one), tried first; the
    /// triangle found replaces it.
    fn any_within(&self, p: [f64; 3], radius: f64, hints: &mut Hints) -> bool {
        let r2 = radius * radius;
        if (hints.last as usize) < self.corners.len() && distance_2(p, self.corners[hints.last as usize]) <= r2 {
            return true;
        }
        let mut found = None;
        self.walk(p, r2, |t, d2| {
            if d2 <= r2 {
                found = Some(t);
                return -1.0;
            }
            r2
        });
        match found {
            Some(t) => {
                hints.last = t as u32;
                true
            }
            None => false,
        }
    }

    /// The distance from `p` to the nearest triangle (infinite for an empty mesh).
    fn distance(&self, p: [f64; 3]) -> f64 {
        let mut best = f64::INFINITY;
        self.walk(p, best, |_, d2| {
            best = best.min(d2);
            best
        });
        best.sqrt()
    }

    /// Visit the triangles whose boxes lie within √`reach_2` of `p`, nearer children first:
    /// `seen(slot, squared distance)` returns the squared reach from then on (negative ends the
    /// walk).
    fn walk(&self, p: [f64; 3], mut reach_2: f64, mut seen: impl FnMut(usize, f64) -> f64) {
        if self.nodes.is_empty() {
            return;
        }
        // The tree splits at medians, so it is at most 32 levels deep (u32 triangles) and the
        // stack holds at most two nodes a level: on the stack, not the heap (a walk is made
        // for millions of samples).
        let mut stack = [0u32; 2 * 33];
        let mut depth = 1;
        while depth > 0 {
            depth -= 1;
            let n = stack[depth];
            let node = self.nodes[n as usize];
            if node.gap_2(p) > reach_2 {
                continue;
            }
            if node.count > 0 {
                for t in node.first as usize..(node.first + node.count) as usize {
                    let d2 = distance_2(p, self.corners[t]);
                    reach_2 = seen(t, d2);
                    if reach_2 < 0.0 {
                        return;
                    }
                }
                continue;
            }
            let (a, b) = (node.first, node.first + 1);
            let (ga, gb) = (self.nodes[a as usize].gap_2(p), self.nodes[b as usize].gap_2(p));
            // The nearer child is popped first.
            let pair = if ga <= gb { [b, a] } else { [a, b] };
            stack[depth..depth + 2].copy_from_slice(&pair);
            depth += 2;
        }
    }
}

/// Nodes with at least this many triangles look at the stop before they are split.
const STOP_CHECK_TRIANGLES: usize = 4096;

/// Fill node `at` for the triangles `numbers[from..]` (`numbers` is that slice), splitting at
/// the median centre along the longest side of their centres' box; children are pushed as a
/// pair, so a node's children sit side by side. A stop leaves the rest unbuilt (the caller
/// then discards the tree).
fn build(
    mesh: &Mesh,
    centres: &[[f32; 3]],
    numbers: &mut [u32],
    from: usize,
    at: usize,
    nodes: &mut Vec<Node>,
    stop: Stop,
) {
    if numbers.len() >= STOP_CHECK_TRIANGLES && stop.requested() {
        return;
    }
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    let mut clo = [f32::INFINITY; 3];
    let mut chi = [f32::NEG_INFINITY; 3];
    for &n in numbers.iter() {
        for corner in corners(mesh, n) {
            for k in 0..3 {
                lo[k] = lo[k].min(corner[k]);
                hi[k] = hi[k].max(corner[k]);
            }
        }
        let c = centres[n as usize];
        for k in 0..3 {
            clo[k] = clo[k].min(c[k]);
            chi[k] = chi[k].max(c[k]);
        }
    }
    if numbers.len() <= LEAF_TRIANGLES {
        nodes[at] = Node { lo, hi, first: from as u32, count: numbers.len() as u32 };
        return;
    }
    let axis = (0..3).max_by(|&i, &j| (chi[i] - clo[i]).total_cmp(&(chi[j] - clo[j]))).unwrap_or(0);
    let middle = numbers.len() / 2;
    numbers.select_nth_unstable_by(middle, |&x, &y| {
        centres[x as usize][axis].total_cmp(&centres[y as usize][axis]).then(x.cmp(&y))
    });
    let first = nodes.len();
    nodes[at] = Node { lo, hi, first: first as u32, count: 0 };
    nodes.extend([Node { lo, hi, first: 0, count: 0 }; 2]);
    let (left, right) = numbers.split_at_mut(middle);
    build(mesh, centres, left, from, first, nodes, stop);
    build(mesh, centres, right, from + middle, first + 1, nodes, stop);
}

/// The squared distance from `p` to the triangle with corners `corners`, in f64.
fn distance_2(p: [f64; 3], corners: [[f32; 3]; 3]) -> f64 {
    let d = sub(closest_on_triangle(p, corners.map(|c| c.map(f64::from))), p);
    dot(d, d)
}

/// Triangle `n` of `mesh`'s corners.
fn corners(mesh: &Mesh, n: u32) -> [[f32; 3]; 3] {
    let t = &mesh.indices[3 * n as usize..][..3];
    [0, 1, 2].map(|k| mesh.positions[t[k] as usize])
}

// Vector arithmetic in f64, shared with `crowded.rs`.
pub(super) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(super) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(super) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

pub(super) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// The point of triangle `[a, b, c]` closest to `p` (Ericson, Real-Time Collision Detection,
/// 5.1.5: by the Voronoi region of the triangle `p` falls in).
fn closest_on_triangle(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> [f64; 3] {
    let along = |o: [f64; 3], d: [f64; 3], t: f64| [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return along(a, ab, d1 / (d1 - d3));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return along(a, ac, d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return along(b, sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() < 1e-300 {
        // A degenerate triangle: its nearest corner.
        return [a, b, c].into_iter().min_by(|x, y| dist(p, *x).total_cmp(&dist(p, *y))).expect("three corners");
    }
    let (v, w) = (vb / denom, vc / denom);
    [a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::heightfield_mesh;
    use crate::terrain::Heightfield;

    fn plane(n: usize, height: impl Fn(f32, f32) -> f32) -> Mesh {
        heightfield_mesh(&Heightfield::from_fn(n, n, 1.0, height), 4097, None).mesh
    }

    #[test]
    fn closest_points_by_hand() {
        let tri = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 2.0]];
        assert_eq!(closest_on_triangle([0.5, 3.0, 0.5], tri), [0.5, 0.0, 0.5]);
        assert_eq!(closest_on_triangle([-1.0, 0.0, -1.0], tri), [0.0, 0.0, 0.0]);
        assert_eq!(closest_on_triangle([1.0, 1.0, -5.0], tri), [1.0, 0.0, 0.0]);
        assert_eq!(closest_on_triangle([2.0, 0.0, 2.0], tri), [1.0, 0.0, 1.0]);
    }

    /// A stop raised while a large mesh is indexed ends the build (a carved island's index took
    /// 4 s under load, past a job's time limit); a small mesh is indexed whatever the stop.
    #[test]
    fn indexing_a_large_mesh_stops_when_asked() {
        let raised = std::sync::atomic::AtomicBool::new(true);
        let large = plane(129, |x, z| (x * 0.1).sin() + z * 0.01);
        assert!(large.triangle_count() >= STOP_CHECK_TRIANGLES);
        assert!(SurfaceIndex::new(&large, Stop::new(&raised)).is_err());
        assert!(max_deviation(&large, &large, 0.5, Stop::new(&raised)).is_err());
        let index = SurfaceIndex::new(&large, Stop::NEVER).unwrap();
        assert_eq!(index.corners.len(), large.triangle_count());
        assert!((index.distance([10.0, 5.0, 10.0]) - (5.0 - (1.0f64).sin() - 0.1)).abs() < 0.05);
    }

    #[test]
    fn a_lifted_copy_deviates_by_the_lift_and_a_bump_by_its_height() {
        let flat = plane(33, |_, _| 0.0);
        let lifted = plane(33, |_, _| 0.75);
        assert!((max_deviation(&flat, &lifted, 0.5, Stop::NEVER).unwrap() - 0.75).abs() < 1e-6);
        // A cone 2 m high at (16, 16): the flat plane's farthest point from the cone's surface
        // is the tip's foot, but the cone's tip is 2 m from the plane: two-sided, 2 m.
        let cone = plane(33, |x, z| (2.0 - ((x - 16.0).powi(2) + (z - 16.0).powi(2)).sqrt()).max(0.0));
        assert!((max_deviation(&flat, &cone, 0.5, Stop::NEVER).unwrap() - 2.0).abs() < 1e-6);
        assert!(max_deviation(&cone, &cone, 0.5, Stop::NEVER).unwrap() < 1e-6);
    }

    #[test]
    fn one_sided_parts_differ_where_one_mesh_covers_less() {
        // A 10 m square against its left half: every point of the half lies on the square, but
        // the square's right edge is 5 m from the half.
        let whole = plane(11, |_, _| 0.0);
        let half = heightfield_mesh(&Heightfield::from_fn(6, 11, 1.0, |_, _| 0.0), 4097, None).mesh;
        let one_way = |from: &Mesh, to: &Mesh| {
            let index = SurfaceIndex::new(to, Stop::NEVER).unwrap();
            let found = std::sync::atomic::AtomicU64::new(0);
            one_sided(from, &index, 0.5, f64::INFINITY, &found, &Default::default(), false, Stop::NEVER);
            f64::from_bits(found.into_inner())
        };
        assert!(one_way(&half, &whole) < 1e-9);
        assert!((one_way(&whole, &half) - 5.0).abs() < 1e-9);
        assert!((max_deviation(&whole, &half, 0.5, Stop::NEVER).unwrap() - 5.0).abs() < 1e-6);
    }

    #[test]
    fn a_vertex_no_triangle_uses_is_not_on_the_surface() {
        // The same plane twice, one copy with a vertex 7 m up that no triangle uses (a hole's
        // leftover): the surfaces coincide.
        let flat = plane(11, |_, _| 0.0);
        let mut stray = flat.clone();
        stray.positions.push([5.0, 7.0, 5.0]);
        stray.normals.push([0.0, 1.0, 0.0]);
        stray.uvs.push([0.0, 0.0]);
        assert!(max_deviation(&stray, &flat, 0.5, Stop::NEVER).unwrap() < 1e-6);
        assert!(max_deviation(&flat, &stray, 0.5, Stop::NEVER).unwrap() < 1e-6);
    }

    /// A coarse grid over every fourth vertex of a fine one (its corners the fine mesh's own
    /// vertices): the figure and the misses are the same whether its samples near a corner are
    /// skipped or measured.
    #[test]
    fn samples_near_a_corner_on_the_other_surface_change_nothing() {
        let height = |x: f32, z: f32| (x * 0.4).sin() * 2.0 + (z * 0.3).cos() * 1.5 + (x * 1.3 + z).sin() * 0.3;
        let fine = plane(33, height);
        let coarse = heightfield_mesh(&Heightfield::from_fn(9, 9, 4.0, height), 4097, None).mesh;
        assert!(coarse.positions.iter().all(|p| fine.positions.contains(p)));
        let index = SurfaceIndex::new(&fine, Stop::NEVER).unwrap();
        for (spacing, bound) in [(0.5f32, 0.3f32), (1.0, 1.0), (0.25, 10.0)] {
            let measured =
                deviation_and_misses(&fine, &index, &coarse, None, spacing, bound, false, Stop::NEVER).unwrap();
            let skipped =
                deviation_and_misses(&fine, &index, &coarse, None, spacing, bound, true, Stop::NEVER).unwrap();
            assert_eq!(measured.0, skipped.0, "spacing {spacing}, bound {bound}");
            let sorted = |mut m: Vec<[f32; 3]>| {
                m.sort_by(|a, b| a.partial_cmp(b).unwrap());
                m
            };
            assert_eq!(sorted(measured.1.clone()), sorted(skipped.1), "spacing {spacing}, bound {bound}");
            if bound < 1.0 {
                assert!(!measured.1.is_empty(), "a bound the coarse grid misses");
            }
        }
    }
}
