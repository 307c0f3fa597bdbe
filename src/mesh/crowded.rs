//! Edges of three triangles or more. meshoptimizer's collapses can make them (it does not check
//! the link condition): a collapse whose ends share a third neighbour folds a flap shut, or
//! joins two sheets along one edge. Game engines' physics and lightmappers reject such edges,
//! so a level of detail takes them away again, without moving a vertex.

use std::collections::{HashMap, HashSet};

use super::deviation::{cross, dot, norm, sub};
use super::intersections::corners_meet;
use super::types::{edge_key, least_height, sorted_edges, zero_area};

/// `indices` less every pair of triangles on the same three vertices (a flap of no volume a
/// collapse folded shut: its edges are each shared by both, so one of them with a neighbour
/// on each side has four triangles). Dropping both leaves every other edge as it was; of an odd
/// number, one stays.
pub(super) fn without_paired_triangles(indices: Vec<u32>) -> Vec<u32> {
    let key = |t: &[u32]| {
        let mut k = [t[0], t[1], t[2]];
        k.sort_unstable();
        k
    };
    let mut order: Vec<usize> = (0..indices.len() / 3).collect();
    order.sort_unstable_by_key(|&n| (key(&indices[3 * n..3 * n + 3]), n));
    let mut dropped = vec![false; order.len()];
    for run in order.chunk_by(|&a, &b| key(&indices[3 * a..3 * a + 3]) == key(&indices[3 * b..3 * b + 3])) {
        for &n in &run[..run.len() / 2 * 2] {
            dropped[n] = true;
        }
    }
    if !dropped.contains(&true) {
        return indices;
    }
    indices.chunks_exact(3).zip(&dropped).filter(|(_, &d)| !d).flat_map(|(t, _)| t.iter().copied()).collect()
}

/// The edges of `indices` that three triangles or more share, each once, as (lower, higher)
/// vertex.
pub(super) fn crowded_edges(indices: &[u32]) -> Vec<(u32, u32)> {
    sorted_edges(indices)
        .chunk_by(|a, b| a == b)
        .filter(|run| run.len() > 2)
        .map(|run| ((run[0] >> 32) as u32, run[0] as u32))
        .collect()
}

/// `indices` with each edge of three triangles or more relieved where a flip can do it. Two
/// triangles on the edge a–b that run it opposite ways, (a, b, c) and (b, a, d), make a quad
/// a–d–b–c folded on its diagonal; turned onto its other diagonal, (c, a, d) and (d, b, c), it
/// leaves the edge, while each of its four sides keeps its count and c–d, which must be no edge
/// yet, gets just these two. A pair whose new triangles would meet another triangle on a–b
/// (exactly, but for a sliver of it along a–b) stays: the new diagonal sweeps the wedge between
/// the two, and would pierce a sheet lying in it. Of the quads an edge offers, the flattest is
/// turned whose new triangles face the way both old ones did and are no lower than `sliver_m`
/// (nor flat). A vertex never moves; the surface moves by at most the quad's bend, and the
/// level is measured after. What no flip can relieve is left as it is.
pub(super) fn relieve_crowded_edges(mut indices: Vec<u32>, positions: &[[f32; 3]], sliver_m: f32) -> Vec<u32> {
    let crowded = crowded_edges(&indices);
    if crowded.is_empty() {
        return indices;
    }
    let edges = sorted_edges(&indices);
    let wanted: HashSet<u64> = crowded.iter().map(|&(a, b)| edge_key(a, b)).collect();
    let mut on: HashMap<u64, Vec<usize>> = HashMap::new();
    for (n, t) in indices.chunks_exact(3).enumerate() {
        for k in 0..3 {
            let key = edge_key(t[k], t[(k + 1) % 3]);
            if wanted.contains(&key) {
                on.entry(key).or_default().push(n);
            }
        }
    }
    let p = |v: u32| positions[v as usize].map(f64::from);
    let normal = |t: [u32; 3]| {
        let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
        normalized(cross(sub(b, a), sub(c, a)))
    };
    let sound = |t: [u32; 3]| {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        !zero_area(a, b, c) && least_height(a, b, c) >= f64::from(sliver_m)
    };
    let mut added: HashSet<u64> = HashSet::new();
    for &(a, b) in &crowded {
        // Each triangle on the edge turned to start at its first end there: (a, b, c) runs it
        // forward, (b, a, d) back.
        let starting = |indices: &[u32], n: usize, first: u32, second: u32| {
            let t = &indices[3 * n..3 * n + 3];
            (0..3).find(|&k| t[k] == first && t[(k + 1) % 3] == second).map(|k| t[(k + 2) % 3])
        };
        let mut on_edge: Vec<usize> = on.get(&edge_key(a, b)).cloned().unwrap_or_default();
        while on_edge.len() > 2 {
            let mut best: Option<(f64, usize, usize, u32, u32)> = None;
            for &f in &on_edge {
                let Some(c) = starting(&indices, f, a, b) else { continue };
                for &g in &on_edge {
                    let Some(d) = starting(&indices, g, b, a) else { continue };
                    let diagonal = edge_key(c, d);
                    if c == d || edges.binary_search(&diagonal).is_ok() || added.contains(&diagonal) {
                        continue;
                    }
                    let (old_f, old_g) = (normal([a, b, c]), normal([b, a, d]));
                    let new = [[c, a, d], [d, b, c]];
                    let facing = new.iter().all(|&t| {
                        let m = normal(t);
                        dot(m, old_f) > 0.0 && dot(m, old_g) > 0.0
                    });
                    if !facing || !new.iter().all(|&t| sound(t)) {
                        continue;
                    }
                    // The new diagonal sweeps the wedge between the two: a sheet in it (another
                    // triangle on a–b) would be pierced. Each is taken without a sliver along
                    // a–b, which the diagonal of a flat quad crosses wherever it lies.
                    let pierced = on_edge.iter().filter(|&&n| n != f && n != g).any(|&n| {
                        let Some(x) = indices[3 * n..3 * n + 3].iter().copied().find(|&v| v != a && v != b) else {
                            return true;
                        };
                        let toward = |v: u32| {
                            let (v, x) = (p(v), p(x));
                            std::array::from_fn(|k| v[k] + 1e-3 * (x[k] - v[k]))
                        };
                        let other = [toward(a), toward(b), p(x)];
                        new.iter().any(|t| corners_meet(t.map(p), other))
                    });
                    if pierced {
                        continue;
                    }
                    let bend = 1.0 - dot(old_f, old_g);
                    if best.is_none_or(|(least, ..)| bend < least) {
                        best = Some((bend, f, g, c, d));
                    }
                }
            }
            let Some((_, f, g, c, d)) = best else { break };
            // The turned triangles leave their old edges' lists and join their new ones', so a
            // crowded edge taken later sees them as they are now.
            for (n, new) in [(f, [c, a, d]), (g, [d, b, c])] {
                let old = [indices[3 * n], indices[3 * n + 1], indices[3 * n + 2]];
                for k in 0..3 {
                    if let Some(list) = on.get_mut(&edge_key(old[k], old[(k + 1) % 3])) {
                        list.retain(|&m| m != n);
                    }
                }
                for k in 0..3 {
                    let key = edge_key(new[k], new[(k + 1) % 3]);
                    if wanted.contains(&key) {
                        on.entry(key).or_default().push(n);
                    }
                }
                indices[3 * n..3 * n + 3].copy_from_slice(&new);
            }
            added.insert(edge_key(c, d));
            on_edge.retain(|&n| n != f && n != g);
        }
    }
    indices
}

fn normalized(v: [f64; 3]) -> [f64; 3] {
    let len = norm(v).max(f64::MIN_POSITIVE);
    v.map(|x| x / len)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Edges by hand: a fan of three triangles on one edge, and a closed tetrahedron.
    #[test]
    fn paired_triangles_go_and_their_edges_are_shared_by_two_again() {
        // A flap A B C folded shut on the edge A B, which two more triangles share.
        let mesh = vec![0, 1, 2, 1, 0, 2, 0, 1, 3, 1, 0, 4];
        assert_eq!(crowded_edges(&mesh), vec![(0, 1)]);
        let kept = without_paired_triangles(mesh);
        assert_eq!(kept, vec![0, 1, 3, 1, 0, 4]);
        assert!(crowded_edges(&kept).is_empty());
        // Three on the same vertices: one stays.
        assert_eq!(without_paired_triangles(vec![0, 1, 2, 2, 1, 0, 1, 2, 0]), vec![1, 2, 0]);
    }

    #[test]
    fn crowded_edges_are_those_of_three_triangles_or_more() {
        assert_eq!(crowded_edges(&[0, 1, 2, 1, 0, 3, 0, 1, 4]), vec![(0, 1)]);
        assert_eq!(crowded_edges(&[0, 1, 2, 0, 3, 1, 1, 3, 2, 0, 2, 3]), vec![]);
        assert_eq!(crowded_edges(&[2, 1, 0, 0, 1, 3, 1, 0, 4, 4, 0, 1]), vec![(0, 1)]);
    }

    /// Two sheets on one diagonal a–b: a flat square in y = 0 and a bent one above it.
    fn two_sheets() -> (Vec<[f32; 3]>, Vec<u32>) {
        let positions = vec![
            [0.0, 0.0, 0.0],  // a
            [1.0, 0.0, 1.0],  // b
            [1.0, 0.0, 0.0],  // c: flat sheet
            [0.0, 0.0, 1.0],  // d: flat sheet
            [0.8, 0.5, 0.2],  // e: bent sheet
            [0.2, 0.5, 0.8],  // f: bent sheet
            [0.5, -1.0, 0.5], // elsewhere
        ];
        // Each sheet's two triangles run a–b opposite ways: the flat one's (a, b, c) and
        // (b, a, d), the bent one's (a, b, e) and (b, a, f).
        (positions, vec![0, 1, 2, 1, 0, 3, 0, 1, 4, 1, 0, 5])
    }

    fn edge_counts(indices: &[u32]) -> HashMap<u64, usize> {
        let mut counts = HashMap::new();
        for t in indices.chunks_exact(3) {
            for k in 0..3 {
                *counts.entry(edge_key(t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        counts
    }

    #[test]
    fn the_flattest_quad_on_a_crowded_edge_turns_onto_its_other_diagonal() {
        let (positions, indices) = two_sheets();
        let before = edge_counts(&indices);
        let relieved = relieve_crowded_edges(indices, &positions, 0.0);
        assert!(crowded_edges(&relieved).is_empty());
        let after = edge_counts(&relieved);
        // a–b keeps the bent sheet's two; c–d is new with two; every other edge as it was.
        assert_eq!(after[&edge_key(0, 1)], 2);
        assert_eq!(after[&edge_key(2, 3)], 2);
        for (edge, count) in &before {
            if *edge != edge_key(0, 1) {
                assert_eq!(after[edge], *count, "edge {edge:x}");
            }
        }
        // The flat sheet turned (its diagonal c–d), the bent one kept: no vertex left y = 0.
        assert_eq!(&relieved[6..], &[0, 1, 4, 1, 0, 5]);
        assert!(relieved[..6].iter().all(|&v| positions[v as usize][1] == 0.0));
    }

    #[test]
    fn a_quad_whose_other_diagonal_is_an_edge_already_stays() {
        let (positions, mut indices) = two_sheets();
        // c–d is an edge elsewhere: the flat quad cannot turn. Around a–b the third corners lie
        // c, e, f, d (a half turn from c to d through e and f, above y = 0): of the pairs that
        // run the edge opposite ways only e and f are neighbours there, so the bent sheet
        // turns onto e–f. The pair c, f would cross the bent sheet's (a, b, e) (c–f passes
        // through it at (0.636, 0.227, 0.364)), and e, d the triangle (b, a, f).
        indices.extend([2, 3, 6]);
        let before = edge_counts(&indices);
        let relieved = relieve_crowded_edges(indices, &positions, 0.0);
        assert!(crowded_edges(&relieved).is_empty());
        let after = edge_counts(&relieved);
        assert_eq!(after[&edge_key(2, 3)], 1, "c–d keeps just the triangle elsewhere");
        assert_eq!(after[&edge_key(0, 1)], 2);
        assert_eq!(after[&edge_key(4, 5)], 2, "the bent sheet's other diagonal e–f");
        assert!(!after.contains_key(&edge_key(2, 5)) && !after.contains_key(&edge_key(4, 3)));
        for (edge, count) in &before {
            if *edge != edge_key(0, 1) {
                assert_eq!(after[edge], *count, "edge {edge:x}");
            }
        }
        assert_eq!(after.len(), before.len() + 1, "one new edge, the turned quad's diagonal");
        // The flat sheet stays as it was.
        assert_eq!(&relieved[..6], &[0, 1, 2, 1, 0, 3]);
        // Three triangles running the edge one way offer no quad: left as they are.
        let same_way = vec![0, 1, 2, 0, 1, 4, 0, 1, 3];
        assert_eq!(relieve_crowded_edges(same_way.clone(), &positions, 0.0), same_way);
    }

    /// A sheet between the two triangles of a quad keeps them from turning, even where theirs
    /// is the flattest quad on the edge: the diagonal would pierce it.
    #[test]
    fn a_quad_with_another_sheet_in_its_wedge_stays() {
        let positions = vec![
            [0.0, 0.0, 0.0],    // a
            [0.0, 0.0, 1.0],    // b: the edge runs along +z
            [1.0, 0.0, 0.5],    // c: at 0° around it
            [0.0, 1.0, 0.5],    // d: 90°
            [0.7, 0.7, 0.5],    // e: 45°, between c and d
            [-0.94, 0.34, 0.5], // f: 160°
        ];
        // Forward (a, b, c), (a, b, e), (a, b, f); back (b, a, d). The quad on c and d is the
        // flattest (bend 1, against 1.34 for f and d, 1.71 for e and d), but e lies in its
        // wedge: f and d, neighbours, turn instead.
        let indices = vec![0, 1, 2, 1, 0, 3, 0, 1, 4, 0, 1, 5];
        let turned = relieve_crowded_edges(indices, &positions, 0.0);
        assert_eq!(turned, vec![0, 1, 2, 3, 1, 5, 0, 1, 4, 5, 0, 3]);
        assert!(crowded_edges(&turned).is_empty());
        // Without e, c and d are neighbours and turn.
        let without_e = vec![0, 1, 2, 1, 0, 3, 0, 1, 5];
        let turned = relieve_crowded_edges(without_e, &positions, 0.0);
        assert_eq!(turned, vec![2, 0, 3, 3, 1, 2, 0, 1, 5]);
    }
}
