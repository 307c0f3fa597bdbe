//! Smooth vertex normals from the triangles.

use super::Mesh;

/// Replace `mesh.normals` with area-weighted vertex normals: each vertex gets the sum of the
/// un-normalised cross products (twice the area times the unit normal) of the triangles using
/// it, normalised. Vertices used by no triangle, or whose triangles cancel or have no area, get
/// `(0, 1, 0)`. Triangles are summed in index order, so the result never depends on threads.
pub fn recompute_normals(mesh: &mut Mesh) {
    let mut sums = vec![[0.0f32; 3]; mesh.positions.len()];
    for t in mesh.indices.chunks_exact(3) {
        let (a, b, c) = (mesh.positions[t[0] as usize], mesh.positions[t[1] as usize], mesh.positions[t[2] as usize]);
        let n = cross(sub(b, a), sub(c, a));
        for &i in t {
            let s = &mut sums[i as usize];
            for k in 0..3 {
                s[k] += n[k];
            }
        }
    }
    mesh.normals = sums.into_iter().map(unit_or_up).collect();
}

/// `v` scaled to unit length, or +Y when it has no usable direction.
pub(crate) fn unit_or_up(v: [f32; 3]) -> [f32; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len > f32::MIN_POSITIVE && len.is_finite() {
        [v[0] / len, v[1] / len, v[2] / len]
    } else {
        [0.0, 1.0, 0.0]
    }
}

pub(crate) fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh(positions: Vec<[f32; 3]>, indices: Vec<u32>) -> Mesh {
        let n = positions.len();
        Mesh { positions, normals: vec![[9.0; 3]; n], uvs: vec![[0.0; 2]; n], colors: None, indices }
    }

    #[test]
    fn flat_ccw_quad_facing_up_has_up_normals() {
        // Seen from +Y, (0,0,1) → (1,0,1) → (1,0,0) runs counter-clockwise.
        let mut m =
            mesh(vec![[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, 0.0]], vec![0, 1, 2, 0, 2, 3]);
        recompute_normals(&mut m);
        for n in &m.normals {
            assert!((n[1] - 1.0).abs() < 1e-6 && n[0].abs() < 1e-6 && n[2].abs() < 1e-6, "{n:?}");
        }
    }

    #[test]
    fn larger_triangle_weighs_more_at_a_shared_vertex() {
        // Vertex 0 is shared by a big triangle facing +Y and a small one facing +X.
        let mut m = mesh(
            vec![[0.0, 0.0, 0.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]],
            vec![0, 1, 2, 0, 4, 3],
        );
        recompute_normals(&mut m);
        let n = m.normals[0];
        assert!(n[1] > 0.9 && n[0] > 0.0, "{n:?}");
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-6);
        // 16 : 1 area ratio (both doubled) → the angle from +Y is atan(1/16).
        assert!((n[0] / n[1] - 1.0 / 16.0).abs() < 1e-6, "{n:?}");
    }

    #[test]
    fn isolated_and_degenerate_vertices_point_up() {
        let mut m = mesh(vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [5.0, 5.0, 5.0]], vec![0, 1, 2]);
        recompute_normals(&mut m);
        assert_eq!(m.normals, vec![[0.0, 1.0, 0.0]; 4]);
    }
}
