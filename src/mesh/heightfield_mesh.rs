//! A heightfield as a regular triangle mesh.
//!
//! Vertex `(i, j)` of the sampled grid sits at `(x = c * cell, y = h, z = r * cell)` metres
//! for grid column `c` and row `r`; each grid quad becomes two triangles wound
//! counter-clockwise seen from above, so their geometric normals point +Y.

use rayon::prelude::*;

use super::Mesh;
use crate::terrain::Heightfield;

/// Game engines and viewers handle about a million vertices comfortably; 1025 samples a side
/// keeps a 4097² grid at ≤ 1025² vertices with stride 4.
pub const DEFAULT_MAX_SIDE_SAMPLES: usize = 1025;

/// Per-vertex colour from `(height_m, slope_deg)` (slope from horizontal) to sRGB + alpha.
pub type VertexColorFn<'a> = &'a (dyn Fn(f32, f32) -> [u8; 4] + Sync);

/// A heightfield's mesh and the grid stride it was sampled with (1 = every sample).
#[derive(Clone, Debug, PartialEq)]
pub struct HeightfieldMesh {
    /// `vertices[0] × vertices[1]` vertices, row by row (see [`grid_triangles`]).
    pub mesh: Mesh,
    pub stride: usize,
    /// Vertices along X and along Z.
    pub vertices: [usize; 2],
}

/// The smallest stride that keeps both sides at or under `max_side_samples` vertices, counting
/// the always-kept last row and column.
pub fn mesh_stride(cols: usize, rows: usize, max_side_samples: usize) -> usize {
    let max = max_side_samples.max(2);
    let longest = cols.max(rows);
    if longest <= max {
        1
    } else {
        // ceil((n - 1) / s) + 1 samples per side must be <= max.
        (longest - 1).div_ceil(max - 1)
    }
}

/// Grid indices kept along a side of `n` samples: every `stride`-th, then the last.
fn sampled_indices(n: usize, stride: usize) -> Vec<usize> {
    let mut kept: Vec<usize> = (0..n).step_by(stride).collect();
    if n > 0 && kept.last() != Some(&(n - 1)) {
        kept.push(n - 1);
    }
    kept
}

/// Mesh a heightfield, sampling every `stride` cells when a side has more than
/// `max_side_samples` samples (see [`mesh_stride`]). Normals come from central differences
/// over the sampled neighbours, so shading matches the (possibly coarser) geometry. UVs are
/// `(c / (cols - 1), r / (rows - 1))`, which maps the heightmap and preview PNGs (row 0 at the
/// top) straight onto the mesh. Output is identical whatever the thread count.
pub fn heightfield_mesh(hf: &Heightfield, max_side_samples: usize, colors: Option<VertexColorFn>) -> HeightfieldMesh {
    let stride = mesh_stride(hf.cols, hf.rows, max_side_samples);
    let xs = sampled_indices(hf.cols, stride);
    let zs = sampled_indices(hf.rows, stride);
    let (nx, nz) = (xs.len(), zs.len());
    let n = nx * nz;
    if n == 0 {
        return HeightfieldMesh { mesh: Mesh::default(), stride, vertices: [nx, nz] };
    }

    let grid = SampledGrid { hf, xs: &xs, zs: &zs };
    let u_scale = 1.0 / (hf.cols.max(2) - 1) as f32;
    let v_scale = 1.0 / (hf.rows.max(2) - 1) as f32;

    let mut positions = vec![[0.0f32; 3]; n];
    let mut normals = vec![[0.0f32; 3]; n];
    let mut uvs = vec![[0.0f32; 2]; n];
    positions.par_chunks_mut(nx).zip(normals.par_chunks_mut(nx)).zip(uvs.par_chunks_mut(nx)).enumerate().for_each(
        |(j, ((pos_row, nrm_row), uv_row))| {
            let r = zs[j];
            let z = r as f32 * hf.cell_size_m;
            for (i, &c) in xs.iter().enumerate() {
                let (dx, dz) = grid.gradient(i, j);
                let len = (dx * dx + 1.0 + dz * dz).sqrt();
                pos_row[i] = [c as f32 * hf.cell_size_m, hf.get(c, r), z];
                nrm_row[i] = [-dx / len, 1.0 / len, -dz / len];
                uv_row[i] = [c as f32 * u_scale, r as f32 * v_scale];
            }
        },
    );

    let colors = colors.map(|color_of| {
        let mut out = vec![[0u8; 4]; n];
        out.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
            for (i, &c) in xs.iter().enumerate() {
                let (dx, dz) = grid.gradient(i, j);
                let slope_deg = (dx * dx + dz * dz).sqrt().atan().to_degrees();
                row[i] = color_of(hf.get(c, zs[j]), slope_deg);
            }
        });
        out
    });

    let indices = grid_triangles(nx, nz);

    HeightfieldMesh { mesh: Mesh { positions, normals, uvs, colors, indices }, stride, vertices: [nx, nz] }
}

/// The triangles of a grid of `nx × nz` vertices numbered row by row: two per quad, wound
/// counter-clockwise seen from +Y. Quad (i, j) is split along its diagonal from (i, j) to
/// (i + 1, j + 1) when i + j is even, else along the other: the finest level of a
/// right-triangulated irregular network ([`super::Rtin`]), whose every edge then lies on the
/// grid's own edges, so its levels of detail are measured against the grid exactly.
pub(super) fn grid_triangles(nx: usize, nz: usize) -> Vec<u32> {
    grid_triangles_at(nx, nz, [0, 0])
}

/// [`grid_triangles`] of the part of a larger grid whose first vertex is that grid's vertex
/// `origin` (column, row): its quads split as the larger grid's do.
pub(super) fn grid_triangles_at(nx: usize, nz: usize, origin: [usize; 2]) -> Vec<u32> {
    let mut indices = vec![0u32; nx.saturating_sub(1) * nz.saturating_sub(1) * 6];
    if nx > 1 {
        indices.par_chunks_mut((nx - 1) * 6).enumerate().for_each(|(j, row)| {
            for (i, quad) in row.chunks_exact_mut(6).enumerate() {
                quad.copy_from_slice(&quad_triangles(nx, i, j, origin));
            }
        });
    }
    indices
}

/// The two triangles of quad (i, j) (its first corner vertex (i, j)) of a grid `nx` vertices
/// wide whose first vertex is a larger grid's vertex `origin`: split along (i, j)–(i+1, j+1)
/// when the larger grid's i + j is even, else along the other diagonal.
pub(super) fn quad_triangles(nx: usize, i: usize, j: usize, origin: [usize; 2]) -> [u32; 6] {
    // a b     a = (i, j), b = (i + 1, j): +X to the right, +Z downwards, so
    // c d     a→c→b and b→c→d (or a→c→d and a→d→b) turn counter-clockwise seen
    //         from +Y.
    let a = (j * nx + i) as u32;
    let b = a + 1;
    let c = a + nx as u32;
    let d = c + 1;
    if (origin[0] + i + origin[1] + j) % 2 == 0 {
        [a, c, d, a, d, b]
    } else {
        [a, c, b, b, c, d]
    }
}

/// The heightfield seen through the kept rows and columns.
struct SampledGrid<'a> {
    hf: &'a Heightfield,
    xs: &'a [usize],
    zs: &'a [usize],
}

impl SampledGrid<'_> {
    /// (dh/dx, dh/dz) at sampled vertex (i, j) by central differences between its sampled
    /// neighbours (one-sided at the edges); zero along a side with one sample.
    fn gradient(&self, i: usize, j: usize) -> (f32, f32) {
        let (c, r) = (self.xs[i], self.zs[j]);
        let c0 = self.xs[i.saturating_sub(1)];
        let c1 = self.xs[(i + 1).min(self.xs.len() - 1)];
        let r0 = self.zs[j.saturating_sub(1)];
        let r1 = self.zs[(j + 1).min(self.zs.len() - 1)];
        let cell = self.hf.cell_size_m;
        let dx = if c1 > c0 { (self.hf.get(c1, r) - self.hf.get(c0, r)) / ((c1 - c0) as f32 * cell) } else { 0.0 };
        let dz = if r1 > r0 { (self.hf.get(c, r1) - self.hf.get(c, r0)) / ((r1 - r0) as f32 * cell) } else { 0.0 };
        (dx, dz)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn bumpy(cols: usize, rows: usize) -> Heightfield {
        Heightfield::from_fn(cols, rows, 2.0, |x, z| (x * 0.3).sin() * 5.0 + (z * 0.2).cos() * 3.0 + 0.1 * x)
    }

    #[test]
    fn triangles_face_up() {
        let m = heightfield_mesh(&bumpy(17, 11), DEFAULT_MAX_SIDE_SAMPLES, None).mesh;
        assert!(m.check().is_ok());
        assert_eq!(m.triangle_count(), 16 * 10 * 2);
        for t in m.indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| Vec3::from(m.positions[i as usize]));
            let n = (b - a).cross(c - a);
            assert!(n.y > 0.0, "triangle {t:?} has geometric normal {n}");
        }
    }

    #[test]
    fn vertices_sit_on_the_grid_in_metres() {
        let hf = bumpy(5, 4);
        let m = heightfield_mesh(&hf, DEFAULT_MAX_SIDE_SAMPLES, None).mesh;
        assert_eq!(m.vertex_count(), 20);
        let v = m.positions[2 * 5 + 3];
        assert_eq!(v, [3.0 * 2.0, hf.get(3, 2), 2.0 * 2.0]);
        assert_eq!(m.uvs[2 * 5 + 3], [3.0 / 4.0, 2.0 / 3.0]);
        assert_eq!(m.uvs[19], [1.0, 1.0]);
    }

    #[test]
    fn normals_are_unit_and_match_the_heightfield() {
        let hf = bumpy(9, 9);
        let m = heightfield_mesh(&hf, DEFAULT_MAX_SIDE_SAMPLES, None).mesh;
        for (k, n) in m.normals.iter().enumerate() {
            let n = Vec3::from(*n);
            assert!((n.length() - 1.0).abs() < 1e-6);
            let expected = hf.normal(k % 9, k / 9);
            assert!(n.abs_diff_eq(expected, 1e-5), "{n} vs {expected}");
        }
    }

    #[test]
    fn large_grid_is_strided_to_the_side_limit_keeping_the_last_sample() {
        assert_eq!(mesh_stride(4097, 4097, 1025), 4);
        assert_eq!(mesh_stride(1025, 10, 1025), 1);
        assert_eq!(mesh_stride(1026, 10, 1025), 2);
        assert_eq!(sampled_indices(10, 4), vec![0, 4, 8, 9]);
        assert_eq!(sampled_indices(9, 4), vec![0, 4, 8]);

        let hf = bumpy(40, 23);
        let out = heightfield_mesh(&hf, 10, None);
        // 39 cells / 9 → stride 5; columns 0,5,…,35,39 (9 samples), rows 0,5,…,20,22 (6).
        assert_eq!(out.stride, 5);
        assert_eq!(out.mesh.vertex_count(), 9 * 6);
        let (lo, hi) = out.mesh.bounds().unwrap();
        assert_eq!((lo[0], lo[2], hi[0], hi[2]), (0.0, 0.0, 39.0 * 2.0, 22.0 * 2.0));
        assert!(out.mesh.check().is_ok());
    }

    #[test]
    fn colors_come_from_height_and_slope() {
        let hf = Heightfield::from_fn(3, 3, 1.0, |x, _| x);
        let color = |h: f32, slope: f32| [h as u8, slope.round() as u8, 0, 255];
        let m = heightfield_mesh(&hf, DEFAULT_MAX_SIDE_SAMPLES, Some(&color)).mesh;
        let colors = m.colors.unwrap();
        assert_eq!(colors[4], [1, 45, 0, 255]);
        assert_eq!(colors[8], [2, 45, 0, 255]);
    }

    #[test]
    fn same_mesh_on_one_thread_or_many() {
        let hf = bumpy(130, 70);
        let many = heightfield_mesh(&hf, 50, None);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let one = pool.install(|| heightfield_mesh(&hf, 50, None));
        assert_eq!(many, one);
    }
}
