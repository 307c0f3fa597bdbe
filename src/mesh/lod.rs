//! Levels of detail: a mesh simplified by meshoptimizer's edge collapser (`meshopt_simplify`,
//! quadric error, topology kept) within an error bound in metres, then measured against the
//! full mesh ([`max_deviation_from`], two-sided and sampled, the full mesh indexed once for all
//! its levels). Each level is made from the one before (a cascade: the coarse levels simplify
//! a mesh already reduced), with meshoptimizer's target the bound's remaining budget divided by
//! [`SIMPLIFIER_MARGIN`]; a level made from a level is first bounded through it
//! ([`chained_deviation`]: the full mesh's side by the triangle inequality), and measured
//! against the full mesh only where that bound passes the level's. meshoptimizer bounds its own error measure (an area-weighted mean of
//! plane distances), not the distance between the surfaces, so a level measured over its bound
//! is made once more, holding the vertices near where it came within [`NEAR_MISS`] of the bound
//! and with a target scaled by how far it missed; one that gives an edge a third triangle is
//! made again holding the vertices around it (up to [`CROWDED_RETRIES`] times). If that fails,
//! the level is the previous one unchanged and says why ([`Lod::unreduced`]), never a silent
//! full mesh.
//! Vertices on the mesh's topological border (where it meets another mesh: a tile's or a
//! heightfield's edge, an open rim) never move, nor do those on the rim of a vertical side of
//! the bounding box (where a carved coast's top meets its box side) or on two sides (the box's
//! vertical edges), so pieces that meet stay joined at every level; the flat inside of a box
//! side simplifies like any plane.

use std::borrow::Cow;
use std::collections::{HashMap, HashSet};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::Arc;
use std::time::Duration;

use super::crowded::{crowded_edges, relieve_crowded_edges, without_paired_triangles};
use super::deviation::{chain_pays, chained_deviation, deviation_and_misses, mean_triangle_side, SurfaceIndex};
use super::types::{compact_keeping, least_height as height, zero_area};
use super::Mesh;
use crate::stop::{Stop, Stopped};

/// Rounds of mending slivers (a split can leave a new one where corners line up again).
const MEND_ROUNDS: usize = 4;

/// Meshes of at least this many triangles simplify on a thread a stop can leave behind: under
/// it, meshoptimizer takes well under a second.
const DETACHED_SIMPLIFY_TRIANGLES: usize = 200_000;

/// meshoptimizer's target is a level's error budget divided by this: its own error is an
/// area-weighted mean, and the measured distance ran 3–6 times above it on the examples (cut
/// rims, thin spires). At 2, most first tries missed and the second held so many vertices that
/// coarse levels stalled (goblin-valley's level 1 kept its full mesh); at 4 every example's
/// coarsest level is at most 5.2 % of its full mesh but the chamber's (`scripts/lod-timing`).
pub const SIMPLIFIER_MARGIN: f32 = 4.0;

/// The share of the bound beyond which a try's samples are held on the next try (every try
/// until one is made again for its distance).
const NEAR_MISS: f32 = 0.75;

/// Tries made again, past the one for distance, when a level keeps within its bound but gives
/// edges a third triangle. meshoptimizer crowds 0–3 edges a try on the carved coasts, each
/// time somewhere else (a pinch where two sheets come close), and a flip of a convex quad
/// relieves few of them ([`relieve_crowded_edges`]: most such quads are concave); holding
/// what every try before crowded, a later one seldom does. With one retry carve-coast's
/// coarse levels stayed at 12 % of the full mesh (cliff-strata's at 100 %); with two,
/// cliff-strata's level 3 still kept level 2 (7.6 %); with four it was 3.3 % while the flip
/// could pair triangles of two sheets across a third. Flips that would pierce a sheet are
/// refused now, and with four retries cliff-strata's and sea-cave-and-blowhole's level 3 kept
/// their level 2 (7.7 % and 5.0 %); with eight they are 4.0 % and 1.8 %, in about the same
/// time (`scripts/lod-timing`). Such retries mostly fall on coarse levels, made from small
/// meshes.
const CROWDED_RETRIES: u32 = 8;

/// The first level (made from the full mesh) weighs each collapse's change of the vertex
/// normals as well as its quadric error, at this many times the target (metres) in
/// meshoptimizer's frame, where the mesh's extent is 1: a unit of normal change costs
/// NORMAL_WEIGHT × target × the piece's extent in metres, so the weight grows with the piece's
/// size. meshoptimizer's error is a mean, so a first try missed its bound at sharp features (a
/// cut's rim, an arch, a thin spire: carve-coast's island by 2.2×, joint-map's goblins by 3×)
/// and the level was made again from the full mesh, the costliest part of its levels; with the
/// normals weighed both keep within on the first try (island-defaults 4.4× → 3.2× the job
/// without levels, joint-map 3.8× → 2.7×). At 1, joint-map's first try still missed by 2× and
/// the island's crowded an edge. A weight independent of size (K × target metres a unit) did
/// not serve both: K = 1 024 gave the island 3.5× and joint-map 4.6×, K = 256 4.2× and 2.8×,
/// K = 32 4.4× and 3.2× (`scripts/lod-timing`, debug). Coarser levels are made without: weighed
/// at 4 × their larger targets, the wobble of every normal on a rough surface held them near
/// the level before (the island's level 3 kept 10 % of the full mesh).
const NORMAL_WEIGHT: f32 = 4.0;

/// One level of detail of a mesh.
#[derive(Clone, Debug)]
pub struct Lod {
    /// Only the vertices the triangles use, in their original order; normals, texcoords and
    /// colours are the full mesh's at those vertices.
    pub mesh: Mesh,
    /// The target given to meshoptimizer last (metres), at most the bound.
    pub target_m: f32,
    /// The error meshoptimizer reports for it (metres, its quadric measure, relative to the
    /// level it was made from; for the first level, with the normals' term, see
    /// [`NORMAL_WEIGHT`]).
    pub simplifier_error_m: f32,
    /// The sampled two-sided distance to the full mesh (metres), never above the bound: measured
    /// for the first level; for a level made from another, an upper figure through that level
    /// when it shows the bound kept ([`chained_deviation`]), else measured.
    pub deviation_m: f32,
    /// The spacing of the samples that measured it (metres).
    pub sample_spacing_m: f32,
    /// Tries of meshoptimizer this level took (0 when there was nothing to simplify).
    pub tries: u32,
    /// Why this level is the previous one unchanged, when its tries missed the bound or crowded an edge.
    pub unreduced: Option<String>,
}

/// `mesh` simplified so that no sampled point of either surface lies farther than `bound_m`
/// from the other. `stop` is looked at between tries and while measuring.
pub fn simplify_within(mesh: &Mesh, bound_m: f32, stop: Stop) -> Result<Lod, Stopped> {
    Ok(simplify_levels(mesh, &[bound_m], stop)?.remove(0))
}

/// What a level may do with the mesh's topological border (its open edges).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Border {
    /// Every border vertex and every rim of a vertical side of the box stays: pieces that
    /// meet there stay joined at every level.
    Held,
    /// Held, and shared vertex for vertex with a neighbour (a tile without a skirt): a low
    /// sliver with an edge on it stays even where no split can mend it, since dropping it
    /// would drop a vertex the neighbour keeps (a lone mesh's edge loses it, so that no
    /// quantised form decodes the sliver flat).
    Shared,
    /// Border vertices may collapse along the border onto their neighbours (meshoptimizer
    /// moves a border vertex only along a border edge, so a straight side stays on its line in
    /// plan); only the corners of the box's sides stay. For a tile whose skirt hides where
    /// its border and its neighbour's part.
    Free,
}

/// One level of `mesh` for each of `bounds_m` (increasing), each made from the one before and
/// measured against `mesh`, its border held. `stop` is looked at between tries and while
/// measuring.
pub fn simplify_levels(mesh: &Mesh, bounds_m: &[f32], stop: Stop) -> Result<Vec<Lod>, Stopped> {
    simplify_levels_with(mesh, bounds_m, Border::Held, 0.0, stop)
}

/// [`simplify_levels`], with the border held or free, and every triangle less than `sliver_m`
/// high (from its longest side to the corner across) mended as a sliver: a glb that stores
/// positions on a grid of steps makes such a triangle flat (see [`sliver_height`]).
pub fn simplify_levels_with(
    mesh: &Mesh,
    bounds_m: &[f32],
    border: Border,
    sliver_m: f32,
    stop: Stop,
) -> Result<Vec<Lod>, Stopped> {
    // The full mesh's index, built beside meshoptimizer's first simplification.
    let index = std::sync::OnceLock::new();
    let mut levels: Vec<Lod> = Vec::with_capacity(bounds_m.len());
    // The level the next is made from, its locked vertices and its distance to `mesh`.
    let mut source = Cow::Borrowed(mesh);
    let mut locked = Arc::new(locked_vertices(mesh, border));
    let mut source_deviation = 0.0f32;
    // meshoptimizer does not check the link condition: a collapse can give an edge a third
    // triangle. A try may have no more such edges than its source (none, from a manifold mesh).
    let mut source_crowded = crowded_edges(&mesh.indices).len();
    // The full mesh's typical side, for every level's spacing (see [`sample_spacing`]).
    let full_side = mean_triangle_side(mesh) as f32;
    for &bound in bounds_m {
        let spacing = bound.max(full_side);
        let budget = (bound - source_deviation).max(0.0);
        let mut target = budget / SIMPLIFIER_MARGIN;
        let mut made = None;
        let mut missed = None;
        let mut tries = 0;
        // A try over the bound is made again once; one within it that gives an edge a third
        // triangle up to CROWDED_RETRIES times, each holding what the tries before it held.
        let (mut retried_for_distance, mut retried_for_crowding) = (false, 0);
        let mut try_locked = Arc::clone(&locked);
        // The first level, made from the full mesh, weighs the normals too (see NORMAL_WEIGHT).
        let first_level = levels.is_empty();
        while budget > 0.0 && tries < 2 + CROWDED_RETRIES {
            stop.check()?;
            tries += 1;
            let (simplified, _) = rayon::join(
                || simplify_stoppable(&source, &try_locked, target, first_level, border, stop),
                || index.get_or_init(|| SurfaceIndex::new(mesh, stop)),
            );
            let (indices, error) = simplified?;
            let index = index.get().expect("built").as_ref().map_err(|_| Stopped)?;
            let indices = mend_slivers(indices, &source.positions, sliver_m, border == Border::Shared, stop)?;
            let indices = without_paired_triangles(indices);
            let indices = relieve_crowded_edges(indices, &source.positions, sliver_m);
            if indices.len() >= source.indices.len() {
                // Held so much that nothing goes: a reason from the tries before still holds,
                // with this one counted.
                missed = missed.map(|why| format!("{why}; try {tries} removed no triangle"));
                break;
            }
            let crowded = crowded_edges(&indices);
            let (simple, kept) = compact_keeping(&source, &indices);
            stop.check()?;
            // Until a try is made again for its distance, each notes where it came near the
            // bound, for the next to hold.
            let near = if retried_for_distance { f32::INFINITY } else { NEAR_MISS * bound };
            // A level made from a level is first bounded through it where that is cheaper (the
            // full mesh's side, most of a measure, is then not queried); one that bound cannot
            // show within is measured, with the same index of the level.
            let simple_index = SurfaceIndex::new(&simple, stop)?;
            let chained = match &source {
                Cow::Owned(level) if chain_pays(spacing, full_side) => {
                    Some(chained_deviation(index, level, source_deviation, &simple, &simple_index, spacing, stop)?)
                }
                _ => None,
            };
            let (deviation, mut misses) = match chained {
                Some(figure) if figure <= bound => (figure, Vec::new()),
                // A level's vertices are the full mesh's: its samples near a corner need no query.
                _ => deviation_and_misses(mesh, index, &simple, Some(&simple_index), spacing, near, true, stop)?,
            };
            let within = deviation <= bound;
            if within && crowded.len() <= source_crowded {
                made = Some((simple, kept, error, deviation, crowded.len()));
                break;
            }
            missed = Some(if within {
                format!("simplified {tries} times, {} edges had three triangles or more", crowded.len())
            } else {
                format!(
                    "simplified {tries} times, it lay {deviation:.4} m from the full mesh, over the bound of {bound:.4} m"
                )
            });
            if within {
                if retried_for_crowding == CROWDED_RETRIES {
                    break;
                }
                retried_for_crowding += 1;
                // Within the bound: only the crowded edges need holding.
                misses.clear();
            } else {
                if retried_for_distance {
                    break;
                }
                retried_for_distance = true;
            }
            // The next try holds the source's vertices around each crowded edge, where the
            // collapses that crowded it came from, besides all that the tries before it held.
            let p = |v: u32| source.positions[v as usize];
            misses.extend(crowded.iter().flat_map(|&(a, b)| [p(a), p(b)]));
            // meshoptimizer's error is a mean over a vertex's faces, so a level misses at a few
            // sharp features (a cut's rim, a thin spire) while the rest holds. The next try
            // keeps the vertices near every sample that came within NEAR_MISS of the bound or
            // beyond (a miss moves to the next-worst place), and aims a fifth further inside the
            // budget in proportion to the miss.
            let radius = 2.0 * spacing.max(mean_triangle_side(&source) as f32);
            try_locked = Arc::new(lock_near(&source.positions, &try_locked, &misses, radius));
            if !within {
                target *= 0.8 * budget / (deviation - source_deviation).max(budget);
            }
        }
        let lod = match made {
            Some((simple, kept, error, deviation, crowded)) => {
                source_crowded = crowded;
                let level_locked: Vec<bool> = kept.iter().map(|&i| locked[i as usize]).collect();
                locked = Arc::new(level_locked);
                source = Cow::Owned(simple.clone());
                source_deviation = deviation;
                Lod {
                    mesh: simple,
                    target_m: target,
                    simplifier_error_m: error,
                    deviation_m: deviation,
                    sample_spacing_m: spacing,
                    tries,
                    unreduced: None,
                }
            }
            None => Lod {
                mesh: source.clone().into_owned(),
                target_m: target,
                simplifier_error_m: 0.0,
                deviation_m: source_deviation,
                sample_spacing_m: spacing,
                tries,
                unreduced: missed,
            },
        };
        levels.push(lod);
    }
    Ok(levels)
}

/// `locked`, and every vertex of `positions` within `radius` of one of `points`.
fn lock_near(positions: &[[f32; 3]], locked: &[bool], points: &[[f32; 3]], radius: f32) -> Vec<bool> {
    let tree = rstar::RTree::bulk_load(points.to_vec());
    let r2 = radius * radius;
    positions.iter().zip(locked).map(|(p, &l)| l || tree.locate_within_distance(*p, r2).next().is_some()).collect()
}

/// meshoptimizer's simplification of `indices` over `positions` to within `target` metres,
/// `locked` vertices kept, and the error it reports.
/// With `normals`, each collapse also costs the change of the vertex normals it makes, weighed
/// by [`NORMAL_WEIGHT`] × `target` a unit of change in meshoptimizer's frame (× the mesh's
/// extent in metres; its attribute-aware simplifier), and the error it reports includes that
/// term.
fn simplify(
    indices: &[u32],
    positions: &[[f32; 3]],
    normals: Option<&[[f32; 3]]>,
    locked: &[bool],
    target: f32,
    border: Border,
) -> (Vec<u32>, f32) {
    let adapter = meshopt::VertexDataAdapter::new(meshopt::typed_to_bytes(positions), 12, 0)
        .expect("positions are 12-byte vertices");
    let mut error = 0.0f32;
    let options = match border {
        Border::Held | Border::Shared => meshopt::SimplifyOptions::ErrorAbsolute | meshopt::SimplifyOptions::LockBorder,
        Border::Free => meshopt::SimplifyOptions::ErrorAbsolute,
    };
    let indices = match normals {
        Some(normals) => {
            // meshoptimizer weighs attributes in its own frame, where the mesh's extent is 1:
            // a unit of normal change costs `weight` × the extent in metres (see NORMAL_WEIGHT).
            let weight = NORMAL_WEIGHT * target;
            // SAFETY: `[f32; 3]` is three f32s without padding, so the slice's memory is
            // `3 × len` f32s.
            let flat: &[f32] = unsafe { std::slice::from_raw_parts(normals.as_ptr().cast(), normals.len() * 3) };
            meshopt::simplify_with_attributes_and_locks(
                indices,
                &adapter,
                flat,
                &[weight; 3],
                12,
                locked,
                0,
                target,
                options,
                Some(&mut error),
            )
        }
        None => meshopt::simplify_with_locks(indices, &adapter, locked, 0, target, options, Some(&mut error)),
    };
    (indices, error)
}

/// [`simplify`], left behind when `stop` is raised. meshoptimizer cannot be interrupted, and
/// on a million triangles it takes seconds (10.8 s for a 257² carved island's level on this
/// 2-core machine under load, when a cancel must end a job within 2 s). On a mesh that large
/// it runs on a thread of its own with copies of the indices and positions, and a stop
/// returns at once: the thread finishes and frees its copies. Smaller meshes, and work that
/// is never stopped, simplify in place.
fn simplify_stoppable(
    mesh: &Mesh,
    locked: &Arc<Vec<bool>>,
    target: f32,
    with_normals: bool,
    border: Border,
    stop: Stop,
) -> Result<(Vec<u32>, f32), Stopped> {
    let weighed = with_normals && mesh.normals.len() == mesh.positions.len();
    let own_normals = weighed.then_some(&mesh.normals[..]);
    if !stop.can_stop() || mesh.triangle_count() < DETACHED_SIMPLIFY_TRIANGLES {
        return Ok(simplify(&mesh.indices, &mesh.positions, own_normals, &locked[..], target, border));
    }
    let (indices, positions, kept) = (mesh.indices.clone(), mesh.positions.clone(), Arc::clone(locked));
    let normals = weighed.then(|| mesh.normals.clone());
    let (send, receive) = mpsc::channel();
    let spawned = std::thread::Builder::new().name("meshopt-simplify".into()).spawn(move || {
        // The receiver is gone when the level stopped: nobody wants the result.
        let _ = send.send(simplify(&indices, &positions, normals.as_deref(), &kept, target, border));
    });
    if spawned.is_err() {
        return Ok(simplify(&mesh.indices, &mesh.positions, own_normals, &locked[..], target, border));
    }
    loop {
        match receive.recv_timeout(Duration::from_millis(20)) {
            Ok(simplified) => return Ok(simplified),
            Err(RecvTimeoutError::Timeout) => stop.check()?,
            Err(RecvTimeoutError::Disconnected) => panic!("meshoptimizer's simplifier panicked"),
        }
    }
}

/// `indices` without zero-area triangles, nor ones lower than `sliver_m` (0: only exactly flat
/// ones), the surface unchanged to within that height. meshoptimizer can leave a sliver whose
/// three corners lie on (or, for a glb's grid, near) one line where the surface runs straight (a
/// refined grid resampled bilinearly, a locked straight border, a chamber's flat wall). The
/// sliver is dropped, and the triangle across its longest edge — which has the sliver's middle
/// corner on (or within `sliver_m` of) that edge, a T-junction — is split there in two, so the
/// mesh stays watertight and its count of triangles does not grow. A split that would give an
/// edge a third triangle waits for the next round; what no round can mend is dropped at the
/// end (a gap no wider than `sliver_m`, nothing once quantised), except a low sliver whose long
/// edge is on the border, or (`shared_border`, a tile's) any low sliver with an edge on it:
/// dropping it would move the border, or drop a border vertex, a neighbour shares.
fn mend_slivers(
    mut indices: Vec<u32>,
    positions: &[[f32; 3]],
    sliver_m: f32,
    shared_border: bool,
    stop: Stop,
) -> Result<Vec<u32>, Stopped> {
    let p = |i: u32| positions[i as usize];
    let flat = |t: &[u32]| zero_area(p(t[0]), p(t[1]), p(t[2]));
    let is_sliver = |t: &[u32]| flat(t) || sliver_m > 0.0 && height(p(t[0]), p(t[1]), p(t[2])) < f64::from(sliver_m);
    for round in 0..=MEND_ROUNDS {
        stop.check()?;
        if !indices.chunks_exact(3).any(is_sliver) {
            break;
        }
        let last = round == MEND_ROUNDS;
        let triangles: Vec<[u32; 3]> = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let across: HashMap<(u32, u32), usize> = triangles
            .iter()
            .enumerate()
            .flat_map(|(n, t)| [((t[0], t[1]), n), ((t[1], t[2]), n), ((t[2], t[0]), n)])
            .collect();
        let mut dead = vec![false; triangles.len()];
        let mut on_border = vec![false; triangles.len()];
        let mut split = Vec::new();
        let mut added = HashSet::new();
        for (n, t) in triangles.iter().enumerate() {
            if dead[n] || !is_sliver(t) {
                continue;
            }
            // The longest edge (from, to) and the corner between its ends.
            let length = |a: u32, b: u32| {
                let (a, b) = (p(a), p(b));
                (0..3).map(|k| (f64::from(a[k]) - f64::from(b[k])).powi(2)).sum::<f64>()
            };
            let k = (0..3)
                .max_by(|&i, &j| length(t[i], t[(i + 1) % 3]).total_cmp(&length(t[j], t[(j + 1) % 3])))
                .unwrap_or(0);
            let (from, to, middle) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            // The neighbour runs the edge the other way: (to, from, far) → (to, middle, far) and
            // (middle, from, far), the same winding.
            // Without one the long edge is the mesh's border: a flat sliver just goes, a low one
            // stays; one split already this round waits for the next, when its halves are the
            // neighbours.
            match across.get(&(to, from)) {
                Some(_) if last => continue,
                Some(&m) if dead[m] || m == n => continue,
                Some(&m) => {
                    let o = triangles[m];
                    let far = o.into_iter().find(|&v| v != to && v != from).unwrap_or(o[0]);
                    // The split adds the edge middle–far: where the mesh has it already, it
                    // would join three triangles or more. The sliver waits for the next round
                    // (a neighbour's split may change it), or is dropped after the last.
                    let edge = (middle.min(far), middle.max(far));
                    if across.contains_key(&(middle, far)) || across.contains_key(&(far, middle)) || !added.insert(edge)
                    {
                        continue;
                    }
                    dead[m] = true;
                    split.extend([to, middle, far, middle, from, far]);
                }
                None if !flat(t) => {
                    on_border[n] = true;
                    continue;
                }
                None => {}
            }
            dead[n] = true;
        }
        if last || !dead.contains(&true) {
            // Nothing more can be mended: the slivers left go, but those a border keeps (on a
            // shared border, a low one with an edge on it: dropping it would drop a border
            // vertex the neighbour keeps).
            let border_edge = |t: &[u32; 3]| (0..3).any(|k| !across.contains_key(&(t[(k + 1) % 3], t[k])));
            return Ok(triangles
                .iter()
                .enumerate()
                .filter(|&(n, t)| {
                    !dead[n] && (on_border[n] || !is_sliver(t) || shared_border && !flat(t) && border_edge(t))
                })
                .flat_map(|(_, t)| *t)
                .chain(split)
                .collect());
        }
        indices = triangles.iter().zip(&dead).filter(|(_, &d)| !d).flat_map(|(t, _)| *t).chain(split).collect();
    }
    Ok(indices)
}

/// The height under which a triangle is mended as a sliver for a glb whose positions lie on a
/// grid of `bits` bits over `longest_m` (the quantised forms'; the meshopt form's 14 bits are
/// the coarsest): rounding moves each corner by at most √3 ÷ 2 of a step, so a triangle less
/// than twice that high may come out flat.
pub fn sliver_height(longest_m: f64, bits: u32) -> f32 {
    (3f64.sqrt() * longest_m / f64::from((1u32 << bits) - 1)) as f32
}

/// How far apart the deviation's samples lie: the bound, but no closer than the full mesh's
/// typical triangle side (a square of its mean triangle area), which keeps the measure under a
/// second on meshes of a million triangles. The distance to a surface changes by at most the
/// distance moved, so a point between samples may exceed the largest sampled distance by up to
/// about half the spacing; the reported figure is the sampled one. Every vertex of both meshes,
/// where the surfaces bend, is a sample.
pub fn sample_spacing(mesh: &Mesh, bound_m: f32) -> f32 {
    bound_m.max(mean_triangle_side(mesh) as f32)
}

/// Vertices on the rim of a vertical side of the mesh's bounding box (within a millionth of its
/// longest side): on a side and in a triangle that is not wholly on one face of the box (the
/// sides and the bottom), or on two sides (the box's vertical edges). There a neighbouring
/// piece meets the mesh (a carved coast's top meets its box side, a tile meets the next), so
/// they never move. The inside of a side, and its foot on the bottom, are planes and straight
/// lines free to simplify, as are the top and bottom. With a [`Border::Free`] only the box's
/// vertical edges stay (a tile's corners).
fn locked_vertices(mesh: &Mesh, border: Border) -> Vec<bool> {
    let Some((lo, hi)) = mesh.bounds() else { return Vec::new() };
    let tolerance = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max) * 1e-6;
    // Bit s set: the vertex lies on face s (x low, x high, z low, z high, bottom).
    const SIDES: u8 = 0b1111;
    let faces: Vec<u8> = mesh
        .positions
        .iter()
        .map(|p| {
            [(0, false), (0, true), (2, false), (2, true), (1, false)].iter().enumerate().fold(
                0u8,
                |bits, (s, &(k, high))| {
                    let on = if high { hi[k] - p[k] <= tolerance } else { p[k] - lo[k] <= tolerance };
                    bits | (u8::from(on) << s)
                },
            )
        })
        .collect();
    let mut locked: Vec<bool> = faces.iter().map(|f| (f & SIDES).count_ones() >= 2).collect();
    if border == Border::Free {
        return locked;
    }
    for t in mesh.indices.chunks_exact(3) {
        if faces[t[0] as usize] & faces[t[1] as usize] & faces[t[2] as usize] == 0 {
            for &v in t {
                if faces[v as usize] & SIDES != 0 {
                    locked[v as usize] = true;
                }
            }
        }
    }
    locked
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::heightfield_mesh;
    use crate::mesh::types::compact;
    use crate::terrain::Heightfield;

    fn hills() -> Mesh {
        let hf = Heightfield::from_fn(65, 65, 1.0, |x, z| (x * 0.13).sin() * 6.0 + (z * 0.1).cos() * 4.0);
        heightfield_mesh(&hf, 4097, None).mesh
    }

    #[test]
    fn levels_keep_within_their_bound_and_get_coarser() {
        let full = hills();
        let mut last = full.triangle_count();
        for bound in [0.1, 0.4, 1.6] {
            let lod = simplify_within(&full, bound, Stop::NEVER).unwrap();
            assert!(lod.deviation_m <= bound, "{} > {bound}", lod.deviation_m);
            let triangles = lod.mesh.triangle_count();
            assert!(triangles < last, "{triangles} triangles at {bound} m, {last} before");
            assert!(lod.mesh.check().is_ok());
            last = triangles;
        }
        assert!(last * 10 < full.triangle_count(), "{last} of {}", full.triangle_count());
    }

    #[test]
    fn the_border_stays_where_it_was() {
        let full = hills();
        let lod = simplify_within(&full, 0.8, Stop::NEVER).unwrap();
        let on_border = |p: &[f32; 3]| p[0] == 0.0 || p[2] == 0.0 || p[0] == 64.0 || p[2] == 64.0;
        let border = |m: &Mesh| {
            let mut v: Vec<[u32; 3]> =
                m.positions.iter().filter(|p| on_border(p)).map(|p| p.map(f32::to_bits)).collect();
            v.sort_unstable();
            v
        };
        assert_eq!(border(&lod.mesh), border(&full), "every border vertex kept, bit for bit");
    }

    #[test]
    fn a_sliver_is_dropped_and_the_triangle_across_it_split_at_its_middle_corner() {
        // A, B, C on one line (a sliver A B C), D on one side, E on the other; the sliver's
        // long edge C A is D's triangle's edge A C, with B on it: a T-junction once the sliver
        // is gone.
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]];
        let (a, b, c, d, e) = (0, 1, 2, 3, 4);
        let mended =
            mend_slivers(vec![a, b, c, a, c, d, b, a, e, c, b, e], &positions, 0.0, false, Stop::NEVER).unwrap();
        let triangles: Vec<&[u32]> = mended.chunks_exact(3).collect();
        assert_eq!(triangles.len(), 4, "{mended:?}");
        assert!(triangles.iter().all(|t| !zero_area(
            positions[t[0] as usize],
            positions[t[1] as usize],
            positions[t[2] as usize]
        )));
        // The area (all in the y = 0 plane, wound one way) is the two halves' 1 + 1, and the
        // only edges used once are the outline D C, A D, A E, E C: no T-junction at B.
        let area: f64 = triangles
            .iter()
            .map(|t| {
                let q = |i: u32| positions[i as usize].map(f64::from);
                let (p0, p1, p2) = (q(t[0]), q(t[1]), q(t[2]));
                0.5 * ((p1[2] - p0[2]) * (p2[0] - p0[0]) - (p1[0] - p0[0]) * (p2[2] - p0[2]))
            })
            .sum();
        assert!((area.abs() - 2.0).abs() < 1e-12, "{area}");
        let mut edges: Vec<(u32, u32)> = triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(x, y)| (x.min(y), x.max(y)))
            .collect();
        edges.sort_unstable();
        let once: Vec<(u32, u32)> =
            edges.chunk_by(|x, y| x == y).filter(|run| run.len() == 1).map(|run| run[0]).collect();
        assert_eq!(once, vec![(a, d), (a, e), (c, d), (c, e)]);
    }

    /// A closed block: the top a heightfield `height` over [0, n]², four walls of `rows` rows
    /// down to y = 0 and a flat bottom, every face wound outwards, welded by position.
    fn block(n: usize, rows: usize, height: impl Fn(f32, f32) -> f32) -> Mesh {
        let mut mesh =
            Mesh { positions: Vec::new(), normals: Vec::new(), uvs: Vec::new(), colors: None, indices: Vec::new() };
        let mut welded: HashMap<[u32; 3], u32> = HashMap::new();
        let mut vertex = |p: [f32; 3], mesh: &mut Mesh| {
            *welded.entry(p.map(f32::to_bits)).or_insert_with(|| {
                mesh.positions.push(p);
                mesh.normals.push([0.0, 1.0, 0.0]);
                mesh.uvs.push([0.0, 0.0]);
                (mesh.positions.len() - 1) as u32
            })
        };
        let wall = |h: f32, row: usize| if row == rows { h } else { h * row as f32 / rows as f32 };
        let (nf, r) = (n as f32, rows);
        // Each face as P(u, v) over a grid, ∂u × ∂v pointing out of the block.
        type Face<'a> = (usize, usize, Box<dyn Fn(usize, usize) -> [f32; 3] + 'a>);
        let faces: [Face; 6] = [
            (n, n, Box::new(|u, v| [v as f32, height(v as f32, u as f32), u as f32])),
            (n, n, Box::new(|u, v| [u as f32, 0.0, v as f32])),
            (n, r, Box::new(|u, v| [0.0, wall(height(0.0, u as f32), v), u as f32])),
            (r, n, Box::new(|u, v| [nf, wall(height(nf, v as f32), u), v as f32])),
            (r, n, Box::new(|u, v| [v as f32, wall(height(v as f32, 0.0), u), 0.0])),
            (n, r, Box::new(|u, v| [u as f32, wall(height(u as f32, nf), v), nf])),
        ];
        for (us, vs, at) in &faces {
            for u in 0..*us {
                for v in 0..*vs {
                    let [a, b, c, d] = [(u, v), (u + 1, v), (u + 1, v + 1), (u, v + 1)].map(|(u, v)| at(u, v));
                    let [a, b, c, d] = [a, b, c, d].map(|p| vertex(p, &mut mesh));
                    mesh.indices.extend([a, b, c, a, c, d]);
                }
            }
        }
        mesh
    }

    #[test]
    fn a_block_keeps_its_top_rim_and_its_flat_walls_simplify() {
        let n = 32;
        let height = |x: f32, z: f32| 6.0 + (x * 0.3).sin() * 1.5 + (z * 0.2).cos() * 1.0;
        let full = block(n, 8, height);
        assert!(full.is_closed());
        assert!(full.signed_volume() > 0.0, "wound outwards");
        let nf = n as f32;
        let on_side = |p: &[f32; 3]| p[0] == 0.0 || p[2] == 0.0 || p[0] == nf || p[2] == nf;
        let rim = |m: &Mesh| {
            let mut v: Vec<[u32; 3]> = m
                .positions
                .iter()
                .filter(|p| on_side(p) && p[1] == height(p[0], p[2]))
                .map(|p| p.map(f32::to_bits))
                .collect();
            v.sort_unstable();
            v
        };
        let walls = |m: &Mesh| {
            m.indices
                .chunks_exact(3)
                .filter(|t| {
                    let [a, b, c] = [0, 1, 2].map(|k| m.positions[t[k] as usize]);
                    (0..3).step_by(2).any(|k| [0.0, nf].iter().any(|&s| a[k] == s && b[k] == s && c[k] == s))
                })
                .count()
        };
        assert_eq!(rim(&full).len(), 4 * n);
        let bound = 0.032 * nf;
        let lod = simplify_within(&full, bound, Stop::NEVER).unwrap();
        assert!(lod.deviation_m <= bound, "{}", lod.deviation_m);
        assert!(lod.unreduced.is_none());
        assert_eq!(rim(&lod.mesh), rim(&full), "every top rim vertex kept, bit for bit");
        assert!(lod.mesh.is_closed(), "still closed");
        // A side needs at least a fan from its 33 rim vertices to its two bottom corners: 32
        // triangles and one, 132 of the 2048 the walls had. (Measured: 209.)
        let (before, after) = (walls(&full), walls(&lod.mesh));
        assert_eq!(before, 4 * 2 * n * 8);
        assert!(after <= 2 * 4 * (n + 1), "walls {after} of {before} triangles");
        assert!(after >= 4 * (n + 1), "walls {after} triangles cannot span the rim");
    }

    #[test]
    fn levels_are_made_on_the_first_try_and_measured_against_the_full_mesh() {
        for full in [hills(), block(32, 8, |x, z| 6.0 + (x * 0.3).sin() * 1.5 + (z * 0.2).cos())] {
            let bounds = [0.064, 0.256, 1.024];
            let levels = simplify_levels(&full, &bounds, Stop::NEVER).unwrap();
            let mut last = full.triangle_count();
            for (lod, bound) in levels.iter().zip(bounds) {
                assert_eq!(lod.tries, 1, "{bound} m");
                let measured = crate::mesh::max_deviation(&full, &lod.mesh, 0.5 * bound, Stop::NEVER).unwrap();
                assert!(measured <= bound, "{measured} over {bound}");
                assert!((measured - lod.deviation_m).abs() <= 0.5 * bound, "{measured} vs {}", lod.deviation_m);
                assert!(lod.mesh.triangle_count() < last);
                last = lod.mesh.triangle_count();
            }
        }
    }

    /// The figure through the level before against the two-sided measure made directly (the
    /// second method), at the levels' own spacing: never below it, and no more than the larger
    /// of it and the triangle inequality's sum of the two parts measured apart (with the
    /// samples' gap).
    #[test]
    fn a_level_bounded_through_the_one_before_is_no_nearer_than_measured() {
        use crate::mesh::max_deviation;
        for full in [hills(), block(32, 8, |x, z| 6.0 + (x * 0.3).sin() * 1.5 + (z * 0.2).cos())] {
            let index = SurfaceIndex::new(&full, Stop::NEVER).unwrap();
            let levels = simplify_levels(&full, &[0.064, 0.256, 1.024], Stop::NEVER).unwrap();
            for pair in levels.windows(2) {
                let (source, level) = (&pair[0], &pair[1]);
                // The spacing the levels use (see `simplify_levels_with`).
                let spacing = level.sample_spacing_m;
                let level_index = SurfaceIndex::new(&level.mesh, Stop::NEVER).unwrap();
                let chained = chained_deviation(
                    &index,
                    &source.mesh,
                    source.deviation_m,
                    &level.mesh,
                    &level_index,
                    spacing,
                    Stop::NEVER,
                )
                .unwrap();
                let measured = max_deviation(&full, &level.mesh, spacing, Stop::NEVER).unwrap();
                assert!(chained >= measured, "{chained} through the level before, {measured} measured");
                let fine = spacing / 4.0;
                let between = max_deviation(&source.mesh, &level.mesh, fine, Stop::NEVER).unwrap();
                let gap = std::f32::consts::FRAC_1_SQRT_2 * fine;
                assert!(
                    chained <= measured.max(source.deviation_m + between + gap) + 1e-6,
                    "{chained} over {measured} and {} + {between} + {gap}",
                    source.deviation_m
                );
            }
        }
    }

    /// On a fine mesh with bounds of many triangle sides, where coarse levels are bounded
    /// through the level before: every level's figure is within its bound and never below the
    /// two-sided measure made directly at its spacing.
    #[test]
    fn levels_bounded_through_the_one_before_keep_their_bounds_by_the_direct_measure() {
        use crate::mesh::max_deviation;
        let hf = Heightfield::from_fn(129, 129, 0.25, |x, z| (x * 0.5).sin() * 1.5 + (z * 0.4).cos() * 1.0);
        let full = heightfield_mesh(&hf, 4097, None).mesh;
        let full_side = crate::mesh::deviation::mean_triangle_side(&full) as f32;
        let bounds = [0.1, 1.6, 6.4];
        let levels = simplify_levels(&full, &bounds, Stop::NEVER).unwrap();
        assert!(chain_pays(bounds[1].max(full_side), full_side), "level 2 is bounded through level 1");
        for (lod, bound) in levels.iter().zip(bounds) {
            let measured = max_deviation(&full, &lod.mesh, lod.sample_spacing_m, Stop::NEVER).unwrap();
            assert!(lod.deviation_m <= bound, "{} over {bound}", lod.deviation_m);
            assert!(lod.deviation_m >= measured, "{} below the direct {measured} at {bound}", lod.deviation_m);
        }
        assert!(levels[2].mesh.triangle_count() * 20 < full.triangle_count());
    }

    #[test]
    fn mending_never_gives_an_edge_a_third_triangle() {
        // The sliver A B C (B on A C) has D's triangle across its long edge; splitting that
        // at B would add the edge B D, which the mesh already has (two triangles above, in
        // y = 1: a fold meshoptimizer can leave). The sliver waits, and is dropped at last.
        let positions =
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.5, 1.0, 0.5], [1.5, 1.0, 0.5]];
        let (a, b, c, d, e, f) = (0, 1, 2, 3, 4, 5);
        let mended =
            mend_slivers(vec![a, b, c, a, c, d, b, d, e, d, b, f], &positions, 0.0, false, Stop::NEVER).unwrap();
        assert!(crowded_edges(&mended).is_empty(), "{mended:?}");
        assert!(mended.chunks_exact(3).all(|t| !zero_area(
            positions[t[0] as usize],
            positions[t[1] as usize],
            positions[t[2] as usize]
        )));
    }

    /// A low sliver with edges on the border whose split is blocked (the edge B D exists): a
    /// shared border (a tile's) keeps it, with its vertex B the neighbour tile has too; a lone
    /// mesh's border lets it go.
    #[test]
    fn an_unmendable_sliver_stays_on_a_shared_border_only() {
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.001], [2.0, 0.0, 0.0], [1.0, 0.0, 1.0], [3.0, 0.0, 1.0]];
        let (a, b, c, d, e) = (0, 1, 2, 3, 4);
        let mesh = vec![a, b, c, a, c, d, b, e, d];
        let limit = sliver_height(2.0, 8);
        assert_eq!(mend_slivers(mesh.clone(), &positions, limit, true, Stop::NEVER).unwrap(), mesh);
        assert_eq!(mend_slivers(mesh, &positions, limit, false, Stop::NEVER).unwrap(), vec![a, c, d, b, e, d]);
    }

    #[test]
    fn a_triangle_lower_than_the_grid_can_hold_is_mended_too() {
        // As the sliver test's, B 1 mm off the line A C: flat once a glb rounds it to a 1 cm
        // grid, so mended at that height and kept without.
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.001], [2.0, 0.0, 0.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]];
        let (a, b, c, d, e) = (0, 1, 2, 3, 4);
        let mesh = vec![a, b, c, a, c, d, b, a, e, c, b, e];
        assert_eq!(mend_slivers(mesh.clone(), &positions, 0.0, false, Stop::NEVER).unwrap(), mesh);
        let mended = mend_slivers(mesh, &positions, sliver_height(2.0, 8), false, Stop::NEVER).unwrap();
        assert_eq!(mended.len(), 12, "{mended:?}");
        assert!(mended.chunks_exact(3).all(|t| !(t.contains(&a) && t.contains(&c))), "the edge A C is split at B");
        let p = |i: u32| positions[i as usize];
        assert!(mended.chunks_exact(3).all(|t| height(p(t[0]), p(t[1]), p(t[2])) > 0.5), "{mended:?}");
        // 2 m over 8 bits: steps of 7.8 mm, so triangles under 13.6 mm high are slivers.
        assert!((sliver_height(2.0, 8) - 0.013_585).abs() < 1e-5);
    }

    #[test]
    fn compact_keeps_used_vertices_in_order() {
        let full = hills();
        let used = [5u32, 2, 9];
        let m = compact(&full, &used);
        assert_eq!(m.positions, vec![full.positions[2], full.positions[5], full.positions[9]]);
        assert_eq!(m.indices, [1, 0, 2]);
    }
}
