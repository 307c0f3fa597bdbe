//! Exact checks of a closed surface (for tests, and for a level of detail's flips): 2-manifold
//! and consistently oriented, and free of self-intersections — every pair of triangles tested with Shewchuk's exact orientation
//! predicates (`robust`), so a touch is found however small and nothing is found that is not
//! there. Triangles sharing a vertex or an edge are tested for what they share beyond it.

use robust::{orient2d, orient3d, Coord, Coord3D};

use super::Mesh;

type P = [f64; 3];

fn o3(a: P, b: P, c: P, d: P) -> f64 {
    let k = |p: P| Coord3D { x: p[0], y: p[1], z: p[2] };
    orient3d(k(a), k(b), k(c), k(d))
}

/// The two coordinates kept when a plane is projected along its largest normal component.
#[derive(Clone, Copy)]
struct Plane(usize, usize);

impl Plane {
    fn of(a: P, b: P, c: P) -> Plane {
        let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
        let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        // Projection keeps orientation signs consistent within one test; which way round does
        // not matter to the tests below.
        match (0..3).max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs())).unwrap_or(2) {
            0 => Plane(1, 2),
            1 => Plane(2, 0),
            _ => Plane(0, 1),
        }
    }
    fn o2(&self, a: P, b: P, c: P) -> f64 {
        let k = |p: P| Coord { x: p[self.0], y: p[self.1] };
        orient2d(k(a), k(b), k(c))
    }
    fn on_segment(&self, p: P, a: P, b: P) -> bool {
        let within = |k: usize| p[k] >= a[k].min(b[k]) && p[k] <= a[k].max(b[k]);
        self.o2(a, b, p) == 0.0 && within(self.0) && within(self.1)
    }
    /// Closed segments ab and cd meet.
    fn segments_meet(&self, a: P, b: P, c: P, d: P) -> bool {
        let (d1, d2) = (self.o2(a, b, c), self.o2(a, b, d));
        let (d3, d4) = (self.o2(c, d, a), self.o2(c, d, b));
        if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
            return true;
        }
        self.on_segment(c, a, b) || self.on_segment(d, a, b) || self.on_segment(a, c, d) || self.on_segment(b, c, d)
    }
    /// p lies in the closed triangle abc.
    fn in_triangle(&self, p: P, a: P, b: P, c: P) -> bool {
        let (x, y, z) = (self.o2(a, b, p), self.o2(b, c, p), self.o2(c, a, p));
        (x >= 0.0 && y >= 0.0 && z >= 0.0) || (x <= 0.0 && y <= 0.0 && z <= 0.0)
    }
    /// Two coplanar closed triangles meet.
    fn triangles_meet(&self, t: [P; 3], u: [P; 3]) -> bool {
        for i in 0..3 {
            for j in 0..3 {
                if self.segments_meet(t[i], t[(i + 1) % 3], u[j], u[(j + 1) % 3]) {
                    return true;
                }
            }
        }
        self.in_triangle(t[0], u[0], u[1], u[2]) || self.in_triangle(u[0], t[0], t[1], t[2])
    }
}

/// The closed segment s0 s1 meets the closed triangle abc.
fn segment_meets_triangle(s0: P, s1: P, [a, b, c]: [P; 3]) -> bool {
    let (o0, o1) = (o3(a, b, c, s0), o3(a, b, c, s1));
    if o0 * o1 > 0.0 {
        return false;
    }
    if o0 == 0.0 && o1 == 0.0 {
        let plane = Plane::of(a, b, c);
        return plane.segments_meet(s0, s1, a, b)
            || plane.segments_meet(s0, s1, b, c)
            || plane.segments_meet(s0, s1, c, a)
            || plane.in_triangle(s0, a, b, c);
    }
    let (e1, e2, e3) = (o3(s0, s1, a, b), o3(s0, s1, b, c), o3(s0, s1, c, a));
    (e1 >= 0.0 && e2 >= 0.0 && e3 >= 0.0) || (e1 <= 0.0 && e2 <= 0.0 && e3 <= 0.0)
}

/// Two triangles with no vertex in common meet.
fn disjoint_triangles_meet(t: [P; 3], u: [P; 3]) -> bool {
    let du = u.map(|p| o3(t[0], t[1], t[2], p));
    if du.iter().all(|&d| d > 0.0) || du.iter().all(|&d| d < 0.0) {
        return false;
    }
    let dt = t.map(|p| o3(u[0], u[1], u[2], p));
    if dt.iter().all(|&d| d > 0.0) || dt.iter().all(|&d| d < 0.0) {
        return false;
    }
    if du.iter().all(|&d| d == 0.0) {
        return Plane::of(t[0], t[1], t[2]).triangles_meet(t, u);
    }
    (0..3).any(|i| segment_meets_triangle(t[i], t[(i + 1) % 3], u))
        || (0..3).any(|i| segment_meets_triangle(u[i], u[(i + 1) % 3], t))
}

/// Triangles (v, a, b) and (v, c, d) sharing only v meet somewhere else.
fn fan_neighbours_meet(v: P, a: P, b: P, c: P, d: P) -> bool {
    if segment_meets_triangle(a, b, [v, c, d]) || segment_meets_triangle(c, d, [v, a, b]) {
        return true;
    }
    // Coplanar, an edge from v may run into the other's wedge.
    if o3(v, a, b, c) != 0.0 || o3(v, a, b, d) != 0.0 {
        return false;
    }
    let plane = Plane::of(v, a, b);
    let inside = |p: P, x: P, y: P| {
        let (s, t, w) = (plane.o2(v, x, p), plane.o2(v, p, y), plane.o2(v, x, y));
        (s * w > 0.0 && t * w > 0.0) || (s == 0.0 && dot_from(v, p, x) > 0.0) || (t == 0.0 && dot_from(v, p, y) > 0.0)
    };
    inside(a, c, d) || inside(b, c, d) || inside(c, a, b) || inside(d, a, b)
}

fn dot_from(v: P, p: P, q: P) -> f64 {
    (0..3).map(|k| (p[k] - v[k]) * (q[k] - v[k])).sum()
}

/// Triangles sharing the edge (e0, e1) with opposite vertices p and q fold onto each other.
fn edge_neighbours_meet(e0: P, e1: P, p: P, q: P) -> bool {
    if o3(e0, e1, p, q) != 0.0 {
        return false;
    }
    let plane = Plane::of(e0, e1, p);
    plane.o2(e0, e1, p) * plane.o2(e0, e1, q) > 0.0
}

/// Pairs of triangles of `a` and `b` whose bounding boxes overlap (b = None: within `a`).
fn candidate_pairs(a: &Mesh, b: Option<&Mesh>) -> Vec<(usize, usize)> {
    let boxes = |m: &Mesh| -> Vec<[f32; 6]> {
        m.indices
            .chunks_exact(3)
            .map(|t| {
                let p = [t[0], t[1], t[2]].map(|i| m.positions[i as usize]);
                let lo = |k: usize| p[0][k].min(p[1][k]).min(p[2][k]);
                let hi = |k: usize| p[0][k].max(p[1][k]).max(p[2][k]);
                [lo(0), lo(1), lo(2), hi(0), hi(1), hi(2)]
            })
            .collect()
    };
    let (ba, bb) = (boxes(a), b.map(boxes));
    // Sweep along x: both lists sorted by their boxes' lower x.
    let mut events: Vec<(f32, usize, bool)> = ba.iter().enumerate().map(|(i, x)| (x[0], i, false)).collect();
    if let Some(bb) = &bb {
        events.extend(bb.iter().enumerate().map(|(i, x)| (x[0], i, true)));
    }
    events.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.2.cmp(&y.2)).then(x.1.cmp(&y.1)));
    let boxes_of = |second: bool| if second { bb.as_ref().expect("second mesh") } else { &ba };
    let mut out = Vec::new();
    let mut open: Vec<(usize, bool)> = Vec::new();
    for &(x, i, second) in &events {
        open.retain(|&(j, s)| boxes_of(s)[j][3] >= x);
        let me = boxes_of(second)[i];
        for &(j, s) in &open {
            let other = boxes_of(s)[j];
            let overlap = (1..3).all(|k| me[k] <= other[k + 3] && other[k] <= me[k + 3]);
            if !overlap {
                continue;
            }
            match (b.is_some(), second, s) {
                (false, _, _) => out.push((i.min(j), i.max(j))),
                (true, true, false) => out.push((j, i)),
                (true, false, true) => out.push((i, j)),
                _ => {}
            }
        }
        open.push((i, second));
    }
    out
}

fn corners(m: &Mesh, t: usize) -> ([u32; 3], [P; 3]) {
    let idx = [m.indices[3 * t], m.indices[3 * t + 1], m.indices[3 * t + 2]];
    (idx, idx.map(|i| m.positions[i as usize].map(f64::from)))
}

/// How many pairs of `mesh`'s triangles meet beyond the vertices and edges they share.
pub fn self_intersections(mesh: &Mesh) -> usize {
    use rayon::prelude::*;
    candidate_pairs(mesh, None)
        .par_iter()
        .filter(|&&(i, j)| {
            let ((ti, pi), (tj, pj)) = (corners(mesh, i), corners(mesh, j));
            meet_beyond_shared((ti, pi), (tj, pj))
        })
        .count()
}

/// Whether the triangles with corners `t` and `u` meet anywhere (taken as sharing no vertex).
pub fn corners_meet(t: [[f64; 3]; 3], u: [[f64; 3]; 3]) -> bool {
    disjoint_triangles_meet(t, u)
}

fn meet_beyond_shared((ti, pi): ([u32; 3], [P; 3]), (tj, pj): ([u32; 3], [P; 3])) -> bool {
    let shared: Vec<(usize, usize)> =
        (0..3).flat_map(|a| (0..3).map(move |b| (a, b))).filter(|&(a, b)| ti[a] == tj[b]).collect();
    match shared.len() {
        0 => disjoint_triangles_meet(pi, pj),
        1 => {
            let (a, b) = shared[0];
            fan_neighbours_meet(pi[a], pi[(a + 1) % 3], pi[(a + 2) % 3], pj[(b + 1) % 3], pj[(b + 2) % 3])
        }
        2 => {
            let other = |sh: &[usize]| (0..3).find(|k| !sh.contains(k)).expect("a third corner");
            let (oi, oj) = (other(&[shared[0].0, shared[1].0]), other(&[shared[0].1, shared[1].1]));
            edge_neighbours_meet(pi[shared[0].0], pi[shared[1].0], pi[oi], pj[oj])
        }
        _ => true, // the same triangle twice
    }
}

/// Whether any triangle of `a` meets any of `b` (no vertices shared between them).
pub fn meshes_meet(a: &Mesh, b: &Mesh) -> bool {
    use rayon::prelude::*;
    candidate_pairs(a, Some(b)).par_iter().any(|&(i, j)| disjoint_triangles_meet(corners(a, i).1, corners(b, j).1))
}

/// Every edge shared by exactly two triangles running it in opposite directions, and the
/// triangles round every vertex one fan: a closed, oriented 2-manifold.
pub fn is_oriented_manifold(mesh: &Mesh) -> bool {
    use std::collections::HashMap;
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    let mut around: HashMap<u32, Vec<(u32, u32)>> = HashMap::new();
    for t in mesh.indices.chunks_exact(3) {
        for k in 0..3 {
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            *directed.entry((a, b)).or_default() += 1;
            around.entry(a).or_default().push((b, c));
        }
    }
    if directed.iter().any(|(&(a, b), &n)| n != 1 || directed.get(&(b, a)) != Some(&1)) {
        return false;
    }
    around.values().all(|fan| {
        // Follow b -> c round the vertex: one cycle through every triangle.
        let next: HashMap<u32, u32> = fan.iter().copied().collect();
        if next.len() != fan.len() {
            return false;
        }
        let (start, mut at, mut steps) = (fan[0].0, fan[0].1, 1);
        while at != start {
            match next.get(&at) {
                Some(&n) => at = n,
                None => return false,
            }
            steps += 1;
            if steps > fan.len() {
                return false;
            }
        }
        steps == fan.len()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh(positions: Vec<[f32; 3]>, indices: Vec<u32>) -> Mesh {
        Mesh {
            normals: vec![[0.0, 1.0, 0.0]; positions.len()],
            uvs: vec![[0.0; 2]; positions.len()],
            positions,
            indices,
            ..Mesh::default()
        }
    }

    /// A unit tetrahedron, faces out.
    fn tetra(offset: [f32; 3]) -> Mesh {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            .map(|q: [f32; 3]| [q[0] + offset[0], q[1] + offset[1], q[2] + offset[2]]);
        mesh(p.to_vec(), vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3])
    }

    #[test]
    fn a_tetrahedron_is_a_clean_manifold() {
        let t = tetra([0.0; 3]);
        assert!(is_oriented_manifold(&t));
        assert_eq!(self_intersections(&t), 0);
    }

    #[test]
    fn two_crossing_tetrahedra_in_one_mesh_are_found() {
        let (a, b) = (tetra([0.0; 3]), tetra([0.25, 0.25, 0.25]));
        assert!(meshes_meet(&a, &b));
        let mut both = a.clone();
        both.positions.extend(&b.positions);
        both.indices.extend(b.indices.iter().map(|i| i + 4));
        assert!(self_intersections(&both) > 0);
        // Apart by a hair: nothing.
        assert!(!meshes_meet(&a, &tetra([1.0001, 0.0, 0.0])));
        // Touching at a corner counts.
        assert!(meshes_meet(&a, &tetra([1.0, 0.0, 0.0])));
    }

    #[test]
    fn a_folded_edge_and_a_fan_overlap_are_found() {
        // Two coplanar triangles on the same side of their shared edge.
        let folded =
            mesh(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.5, 0.0, 0.5]], vec![0, 1, 2, 1, 0, 3]);
        assert_eq!(self_intersections(&folded), 1);
        // Sharing one vertex, one poking through the other.
        let poke = mesh(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.5, 0.5, 0.2], [0.5, -0.5, 0.2]],
            vec![0, 1, 2, 0, 3, 4],
        );
        assert_eq!(self_intersections(&poke), 1);
        assert!(!is_oriented_manifold(&poke));
    }
}
