//! Levels of detail: a mesh simplified by meshoptimizer's edge collapser (`meshopt_simplify`,
//! quadric error, topology kept) within an error bound in metres, then measured against the
//! full mesh ([`max_deviation`], two-sided and sampled). meshoptimizer bounds its own error
//! measure, not the distance between the surfaces, so a level whose measured distance exceeds
//! the bound is simplified again with half the target, until it holds (at worst the full mesh
//! is the level). Vertices on the mesh's topological border (where it meets another mesh: a
//! tile's or a heightfield's edge, an open rim) and on the faces of its bounding box (the box
//! sides of a carved coast, a column's base on the ground) never move, so pieces that meet stay
//! joined at every level.

use std::collections::HashMap;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::Arc;
use std::time::Duration;

use super::deviation::{max_deviation, mean_triangle_side};
use super::types::zero_area;
use super::Mesh;
use crate::stop::{Stop, Stopped};

/// Rounds of mending slivers (a split can leave a new one where corners line up again).
const MEND_ROUNDS: usize = 4;

/// Meshes of at least this many triangles simplify on a thread a stop can leave behind: under
/// it, meshoptimizer takes well under a second.
const DETACHED_SIMPLIFY_TRIANGLES: usize = 200_000;

/// Halvings of meshoptimizer's target before a level falls back to the full mesh.
const RETRIES: usize = 6;

/// One level of detail of a mesh.
#[derive(Clone, Debug)]
pub struct Lod {
    /// Only the vertices the triangles use, in their original order; normals, texcoords and
    /// colours are the full mesh's at those vertices.
    pub mesh: Mesh,
    /// The target given to meshoptimizer last (metres), at most the bound.
    pub target_m: f32,
    /// The error meshoptimizer reports for it (metres, its quadric measure).
    pub simplifier_error_m: f32,
    /// The sampled two-sided distance to the full mesh (metres), never above the bound.
    pub deviation_m: f32,
    /// The spacing of the samples that measured it (metres).
    pub sample_spacing_m: f32,
}

/// `mesh` simplified so that no sampled point of either surface lies farther than `bound_m`
/// from the other. `stop` is looked at between tries and while measuring.
pub fn simplify_within(mesh: &Mesh, bound_m: f32, stop: Stop) -> Result<Lod, Stopped> {
    let spacing = sample_spacing(mesh, bound_m);
    let locked = Arc::new(locked_vertices(mesh));
    let mut target = bound_m;
    for _ in 0..=RETRIES {
        stop.check()?;
        let (indices, error) = simplify_stoppable(mesh, &locked, target, stop)?;
        let simple = compact(mesh, &mend_slivers(indices, &mesh.positions));
        stop.check()?;
        let deviation = max_deviation(mesh, &simple, spacing, stop)?;
        if deviation <= bound_m {
            return Ok(Lod {
                mesh: simple,
                target_m: target,
                simplifier_error_m: error,
                deviation_m: deviation,
                sample_spacing_m: spacing,
            });
        }
        target *= 0.5;
    }
    Ok(Lod { mesh: mesh.clone(), target_m: 0.0, simplifier_error_m: 0.0, deviation_m: 0.0, sample_spacing_m: spacing })
}

/// meshoptimizer's simplification of `indices` over `positions` to within `target` metres,
/// `locked` vertices kept, and the error it reports.
fn simplify(indices: &[u32], positions: &[[f32; 3]], locked: &[bool], target: f32) -> (Vec<u32>, f32) {
    let adapter = meshopt::VertexDataAdapter::new(meshopt::typed_to_bytes(positions), 12, 0)
        .expect("positions are 12-byte vertices");
    let mut error = 0.0f32;
    let indices = meshopt::simplify_with_locks(
        indices,
        &adapter,
        locked,
        0,
        target,
        meshopt::SimplifyOptions::ErrorAbsolute | meshopt::SimplifyOptions::LockBorder,
        Some(&mut error),
    );
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
    stop: Stop,
) -> Result<(Vec<u32>, f32), Stopped> {
    if !stop.can_stop() || mesh.triangle_count() < DETACHED_SIMPLIFY_TRIANGLES {
        return Ok(simplify(&mesh.indices, &mesh.positions, &locked[..], target));
    }
    let (indices, positions, kept) = (mesh.indices.clone(), mesh.positions.clone(), Arc::clone(locked));
    let (send, receive) = mpsc::channel();
    let spawned = std::thread::Builder::new().name("meshopt-simplify".into()).spawn(move || {
        // The receiver is gone when the level stopped: nobody wants the result.
        let _ = send.send(simplify(&indices, &positions, &kept, target));
    });
    if spawned.is_err() {
        return Ok(simplify(&mesh.indices, &mesh.positions, &locked[..], target));
    }
    loop {
        match receive.recv_timeout(Duration::from_millis(20)) {
            Ok(simplified) => return Ok(simplified),
            Err(RecvTimeoutError::Timeout) => stop.check()?,
            Err(RecvTimeoutError::Disconnected) => panic!("meshoptimizer's simplifier panicked"),
        }
    }
}

/// `indices` without zero-area triangles, the surface unchanged. meshoptimizer can leave a
/// sliver whose three corners lie on one line where the surface runs exactly straight (a
/// refined grid resampled bilinearly, a locked straight border). The sliver is dropped, and
/// the triangle across its longest edge — which has the sliver's middle corner on that edge,
/// a T-junction — is split there in two, so the mesh stays watertight and its count of
/// triangles does not grow.
fn mend_slivers(mut indices: Vec<u32>, positions: &[[f32; 3]]) -> Vec<u32> {
    let p = |i: u32| positions[i as usize];
    let is_sliver = |t: &[u32]| zero_area(p(t[0]), p(t[1]), p(t[2]));
    for round in 0..=MEND_ROUNDS {
        if !indices.chunks_exact(3).any(is_sliver) {
            break;
        }
        if round == MEND_ROUNDS {
            // What is left after the rounds is dropped unmended: zero area covers nothing.
            return indices.chunks_exact(3).filter(|t| !is_sliver(t)).flatten().copied().collect();
        }
        let triangles: Vec<[u32; 3]> = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let across: HashMap<(u32, u32), usize> = triangles
            .iter()
            .enumerate()
            .flat_map(|(n, t)| [((t[0], t[1]), n), ((t[1], t[2]), n), ((t[2], t[0]), n)])
            .collect();
        let mut dead = vec![false; triangles.len()];
        let mut split = Vec::new();
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
            // Without one the long edge is the mesh's border, and the sliver just goes; one split
            // already this round waits for the next, when its halves are the neighbours.
            match across.get(&(to, from)) {
                Some(&m) if dead[m] || m == n => continue,
                Some(&m) => {
                    dead[m] = true;
                    let o = triangles[m];
                    let far = o.into_iter().find(|&v| v != to && v != from).unwrap_or(o[0]);
                    split.extend([to, middle, far, middle, from, far]);
                }
                None => {}
            }
            dead[n] = true;
        }
        indices = triangles.iter().zip(&dead).filter(|(_, &d)| !d).flat_map(|(t, _)| *t).chain(split).collect();
    }
    indices
}

/// How far apart the deviation's samples lie: half the bound, but no closer than the full
/// mesh's typical triangle side (a square of its mean triangle area), which keeps the measure
/// to seconds on meshes of a million triangles. The distance to a surface changes by at most
/// the distance moved, so a point between samples may exceed the largest sampled distance by
/// up to about half the spacing; the reported figure is the sampled one. Every vertex of both
/// meshes, where the surfaces bend, is a sample.
pub fn sample_spacing(mesh: &Mesh, bound_m: f32) -> f32 {
    (0.5 * bound_m).max(mean_triangle_side(mesh) as f32)
}

/// Vertices on a vertical side of the mesh's bounding box (within a millionth of its longest
/// side), where a neighbouring piece would meet it: the box sides of a carved coast, a tile's
/// edge. The top and bottom are free to simplify.
fn locked_vertices(mesh: &Mesh) -> Vec<bool> {
    let Some((lo, hi)) = mesh.bounds() else { return Vec::new() };
    let tolerance = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max) * 1e-6;
    mesh.positions
        .iter()
        .map(|p| [0, 2].iter().any(|&k| p[k] - lo[k] <= tolerance || hi[k] - p[k] <= tolerance))
        .collect()
}

/// The triangles `indices` of `mesh` with only the vertices they use, kept in their order.
pub(super) fn compact(mesh: &Mesh, indices: &[u32]) -> Mesh {
    let mut new_index = vec![u32::MAX; mesh.vertex_count()];
    for &i in indices {
        new_index[i as usize] = 0;
    }
    let mut kept = Vec::new();
    for (old, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = kept.len() as u32;
            kept.push(old);
        }
    }
    let take = |values: &[_]| kept.iter().map(|&i| values[i]).collect();
    Mesh {
        positions: take(&mesh.positions),
        normals: take(&mesh.normals),
        uvs: kept.iter().map(|&i| mesh.uvs[i]).collect(),
        colors: mesh.colors.as_ref().map(|c| kept.iter().map(|&i| c[i]).collect()),
        indices: indices.iter().map(|&i| new_index[i as usize]).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::heightfield_mesh;
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
        let mended = mend_slivers(vec![a, b, c, a, c, d, b, a, e, c, b, e], &positions);
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

    #[test]
    fn compact_keeps_used_vertices_in_order() {
        let full = hills();
        let used = [5u32, 2, 9];
        let m = compact(&full, &used);
        assert_eq!(m.positions, vec![full.positions[2], full.positions[5], full.positions[9]]);
        assert_eq!(m.indices, [1, 0, 2]);
    }
}
