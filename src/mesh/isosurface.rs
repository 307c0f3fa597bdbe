//! Closed surfaces of volumes: marching tetrahedra over a dense scalar field.
//!
//! Each grid cube is split into the six Kuhn (Freudenthal) tetrahedra around its main diagonal
//! (0,0,0)–(1,1,1). Neighbouring cubes then cut their shared face along the same diagonal, so
//! the surface is watertight, and every surface edge lies in one tetrahedron face shared by
//! exactly two tetrahedra, so it is 2-manifold along edges even where voxels touch only along
//! an edge or at a corner (table marching cubes has ambiguous faces there; surface nets gives
//! edges of four faces). Every tetrahedron edge runs from a sample `p` to `p + d` with `d` one
//! of seven non-negative offsets (three axes, three face diagonals, the body diagonal), which
//! names each surface vertex uniquely, so welding needs no hashing.

use rayon::prelude::*;

use super::normals::recompute_normals;
use super::Mesh;
use crate::stop::{Stop, Stopped};

/// A dense scalar volume: `dims = [nx, ny, nz]` samples, sample (x, y, z) at
/// `origin_m + [x, y, z] * spacing_m`, stored at index `x + nx * (z + nz * y)` (x fastest,
/// then z, then y).
#[derive(Clone, Copy, Debug)]
pub struct ScalarField<'a> {
    pub dims: [usize; 3],
    pub origin_m: [f32; 3],
    pub spacing_m: f32,
    pub values: &'a [f32],
}

/// The surface `value == iso` around the region `value > iso` (inside). Samples beyond the grid
/// count as outside, so the mesh is always closed: every edge shared by exactly two triangles,
/// consistently wound CCW seen from outside (positive signed_volume), normals area-weighted
/// smooth, uvs = (x, z) over the grid's extent in [0,1], colors None. Empty mesh when nothing
/// is inside.
///
/// A sample equal to `iso` (or NaN) is outside. Crossings are linearly interpolated, between
/// values moved off the surface where a sample lies too near it (see `kept_off`), then kept
/// at least [`min_crossing`] of an edge away from both ends: a sample lying on the surface
/// (exactly `iso`, as on flat caps, walls and floors that fall on a sample plane) would
/// otherwise put the vertices of all its edges at one point, giving duplicated positions and
/// zero-area triangles, which engines' physics and lightmappers reject. Kept apart, vertices on
/// distinct edges never coincide and no triangle is degenerate (the points on a tetrahedron's
/// edges strictly between its corners never lie three on a line), and they stay apart once
/// written: the distance is at least four steps of the coarsest position grid a glb form uses
/// for a box the grid's size. The surface moves by at most that distance, and only where it
/// passes that close to a sample. Where the region reaches the grid's side the surface closes half a
/// sample beyond the last sample, as for a voxel centred on its sample. Identical output
/// whatever the thread count.
///
/// # Panics
/// When `values.len()` is not `nx * ny * nz`, or the surface needs more than `u32::MAX`
/// vertices.
///
/// Looks at `stop` before each layer of cubes and answers `Err(Stopped)` once it is raised.
pub fn extract_isosurface(field: &ScalarField, iso: f32, stop: Stop) -> Result<Mesh, Stopped> {
    let [nx, ny, nz] = field.dims;
    assert_eq!(field.values.len(), nx * ny * nz, "scalar field of {nx}x{ny}x{nz} samples");
    if nx == 0 || ny == 0 || nz == 0 {
        return Ok(Mesh::default());
    }
    let grid = PaddedGrid::new(field, iso);
    // Cube layer (and edge base plane) `py` in padded coordinates spans samples py..=py+1; the
    // base plane ny + 1 lies wholly in the padding and has no crossings.
    let layers: Vec<Layer> = (0..=ny)
        .into_par_iter()
        .map(|py| if stop.requested() { Layer::default() } else { grid.crossings(py) })
        .collect();
    stop.check()?;
    let mut first_vertex = Vec::with_capacity(layers.len());
    let mut total = 0usize;
    for layer in &layers {
        first_vertex.push(total);
        total += layer.positions.len();
    }
    if total == 0 {
        return Ok(Mesh::default());
    }
    assert!(total <= u32::MAX as usize, "isosurface of {total} vertices exceeds u32 indices");
    let first_vertex: Vec<u32> = first_vertex.into_iter().map(|v| v as u32).collect();
    let triangles: Vec<Vec<u32>> = (0..=ny)
        .into_par_iter()
        .map(|py| if stop.requested() { Vec::new() } else { grid.triangles(py, &layers, &first_vertex) })
        .collect();
    stop.check()?;

    let mut positions = Vec::with_capacity(total);
    for layer in &layers {
        positions.extend_from_slice(&layer.positions);
    }
    let indices = triangles.concat();
    let extent = |n: usize| if n > 1 { (n - 1) as f32 * field.spacing_m } else { 0.0 };
    let (ex, ez) = (extent(nx), extent(nz));
    let uv =
        |v: f32, origin: f32, extent: f32| if extent > 0.0 { ((v - origin) / extent).clamp(0.0, 1.0) } else { 0.5 };
    let uvs = positions.iter().map(|p| [uv(p[0], field.origin_m[0], ex), uv(p[2], field.origin_m[2], ez)]).collect();
    let mut mesh = Mesh { positions, normals: Vec::new(), uvs, colors: None, indices };
    recompute_normals(&mut mesh);
    Ok(mesh)
}

/// Bits per coordinate of the coarsest position grid a glb form writes (meshopt's 14, as
/// gltfpack's default; the quantised form has 16).
const COARSEST_POSITION_BITS: u32 = 14;

/// The closest a crossing comes to either end of its edge, as a fraction of the edge, for a
/// grid of `dims` samples: four steps of a [`COARSEST_POSITION_BITS`] grid over the longest
/// side (rounding moves a point by at most √3/2 of a step, so points four steps apart never
/// share a written position, and the short sides of the triangles around a sample on the
/// surface keep their shape), and never under 1/1024 of an edge. 1/64 of a voxel for a
/// 257-sample side, 1/16 for 1025.
pub fn min_crossing(dims: [usize; 3]) -> f32 {
    let longest = dims.into_iter().max().unwrap_or(0) as f32;
    (4.0 * longest / ((1u32 << COARSEST_POSITION_BITS) - 1) as f32).max(1.0 / 1024.0)
}

/// The six Kuhn tetrahedra of a cube as corner numbers (`dx | dy << 1 | dz << 2`), each
/// ordered so every edge runs from a corner to one with more bits, with the sign of its
/// orientation: one tetrahedron per order of the axes walked from (0,0,0) to (1,1,1), signed
/// by that permutation's parity.
const TETRAHEDRA: [([u8; 4], bool); 6] = [
    ([0, 1, 3, 7], true),  // x, y, z
    ([0, 1, 5, 7], false), // x, z, y
    ([0, 2, 3, 7], false), // y, x, z
    ([0, 2, 6, 7], true),  // y, z, x
    ([0, 4, 5, 7], true),  // z, x, y
    ([0, 4, 6, 7], false), // z, y, x
];

/// For a positively oriented tetrahedron, the face opposite each vertex wound to face away
/// from it.
const OPPOSITE_FACE: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// Where the field is inside, with one layer of outside samples around it so every cube from
/// -1 to n has eight samples to read.
struct PaddedGrid<'a> {
    field: &'a ScalarField<'a>,
    iso: f32,
    /// Padded side lengths `[nx + 2, ny + 2, nz + 2]`.
    size: [usize; 3],
    inside: Vec<bool>,
    /// [`min_crossing`] of the field's grid.
    min_crossing: f32,
}

/// The surface vertices on edges based in one padded plane y, and that plane's cubes that
/// straddle the surface.
#[derive(Default)]
struct Layer {
    /// `(px, pz, corner bits)` of the plane's mixed cubes, z-major.
    mixed: Vec<(u32, u32, u8)>,
    /// `keys[row_start[pz]..row_start[pz + 1]]` are the crossed edges based in row `pz`.
    row_start: Vec<u32>,
    /// `px * 7 + direction`, increasing within a row; direction is the edge's offset bits − 1.
    keys: Vec<u32>,
    positions: Vec<[f32; 3]>,
}

impl<'a> PaddedGrid<'a> {
    fn new(field: &'a ScalarField<'a>, iso: f32) -> Self {
        let [nx, ny, nz] = field.dims;
        let size = [nx + 2, ny + 2, nz + 2];
        let plane = size[0] * size[2];
        let mut inside = vec![false; plane * size[1]];
        inside.par_chunks_mut(plane).enumerate().skip(1).take(ny).for_each(|(py, out)| {
            for z in 0..nz {
                let src = &field.values[nx * (z + nz * (py - 1))..][..nx];
                let dst = &mut out[size[0] * (z + 1) + 1..][..nx];
                for (d, &v) in dst.iter_mut().zip(src) {
                    *d = v > iso;
                }
            }
        });
        Self { field, iso, size, inside, min_crossing: min_crossing(field.dims) }
    }

    fn index(&self, px: usize, py: usize, pz: usize) -> usize {
        px + self.size[0] * (pz + self.size[2] * py)
    }

    /// The field at a padded sample, `None` in the padding.
    fn value(&self, px: usize, py: usize, pz: usize) -> Option<f32> {
        let [nx, ny, nz] = self.field.dims;
        let real = |p: usize, n: usize| p >= 1 && p <= n;
        (real(px, nx) && real(py, ny) && real(pz, nz))
            .then(|| self.field.values[(px - 1) + nx * ((pz - 1) + nz * (py - 1))])
    }

    /// Corner bits of the padded row of cubes at (py, pz), built from per-column nibbles: the
    /// column at x holds the four samples (y, z), (y+1, z), (y, z+1), (y+1, z+1) in bits 0, 2,
    /// 4, 6, so a cube's code is its left column ORed with its right one shifted by one.
    fn row_columns(&self, py: usize, pz: usize, columns: &mut Vec<u8>) {
        let sx = self.size[0];
        let rows = [
            self.index(0, py, pz),
            self.index(0, py + 1, pz),
            self.index(0, py, pz + 1),
            self.index(0, py + 1, pz + 1),
        ];
        let rows = rows.map(|start| &self.inside[start..start + sx]);
        columns.clear();
        columns.extend(
            (0..sx).map(|x| {
                rows[0][x] as u8 | (rows[1][x] as u8) << 2 | (rows[2][x] as u8) << 4 | (rows[3][x] as u8) << 6
            }),
        );
    }

    /// The crossed edges based in padded plane `py` and the plane's mixed cubes. Every edge
    /// based at `p` lies in the cube whose lowest corner is `p`, so only mixed cubes are read.
    fn crossings(&self, py: usize) -> Layer {
        let [nx, _, nz] = self.field.dims;
        let mut layer =
            Layer { mixed: Vec::new(), row_start: Vec::with_capacity(nz + 3), keys: Vec::new(), positions: Vec::new() };
        let mut columns = Vec::with_capacity(self.size[0]);
        for pz in 0..=nz {
            layer.row_start.push(layer.keys.len() as u32);
            self.row_columns(py, pz, &mut columns);
            for px in 0..=nx {
                let code = columns[px] | columns[px + 1] << 1;
                if code == 0 || code == 0xff {
                    continue;
                }
                layer.mixed.push((px as u32, pz as u32, code));
                let base_inside = code & 1;
                for offset in 1..8u8 {
                    if (code >> offset) & 1 != base_inside {
                        layer.keys.push(px as u32 * 7 + offset as u32 - 1);
                        layer.positions.push(self.crossing_point([px, py, pz], offset));
                    }
                }
            }
        }
        // Rows nz + 1 (padding only) are empty; the extra entries keep lookups in range.
        let end = layer.keys.len() as u32;
        layer.row_start.extend([end, end]);
        layer
    }

    /// Sample `p`'s value `v`, moved off the surface if it lies too near it: to
    /// `min_crossing / (1 − min_crossing)` of the largest difference from `iso` among its 14
    /// lattice neighbours, on its own side. The surface near such a sample then shifts as a
    /// whole (a plane moves parallel to itself), so every crossing on its edges keeps
    /// `min_crossing` from it and the small triangles around it keep the surface's normal;
    /// clamping each crossing alone put them on a little cap around the sample, whose
    /// normals were off by 35°. A sample exactly on the surface (flat caps, walls and floors
    /// on a sample plane, whose neighbours along the plane are on it too) is left to the
    /// clamp, which keeps such a cap flat.
    fn kept_off(&self, p: [usize; 3], v: f32) -> f32 {
        let gap = v - self.iso;
        if gap == 0.0 || gap.is_nan() {
            return v;
        }
        let mut largest = 0.0f32;
        for offset in 1..8u8 {
            let d = [(offset & 1) as usize, ((offset >> 1) & 1) as usize, ((offset >> 2) & 1) as usize];
            let up = self.value(p[0] + d[0], p[1] + d[1], p[2] + d[2]);
            let down = (p[0] >= d[0] && p[1] >= d[1] && p[2] >= d[2])
                .then(|| self.value(p[0] - d[0], p[1] - d[1], p[2] - d[2]))
                .flatten();
            for w in up.into_iter().chain(down) {
                largest = largest.max((w - self.iso).abs());
            }
        }
        let least = self.min_crossing / (1.0 - self.min_crossing) * largest;
        if gap.abs() >= least {
            v
        } else {
            self.iso + least.copysign(gap)
        }
    }

    /// Where the field crosses `iso` on the edge from padded sample `base` to `base + offset`.
    fn crossing_point(&self, base: [usize; 3], offset: u8) -> [f32; 3] {
        let d = [(offset & 1) as usize, ((offset >> 1) & 1) as usize, ((offset >> 2) & 1) as usize];
        let far = [base[0] + d[0], base[1] + d[1], base[2] + d[2]];
        let a = self.value(base[0], base[1], base[2]).map(|v| self.kept_off(base, v));
        let b = self.value(far[0], far[1], far[2]).map(|v| self.kept_off(far, v));
        let t = match (a, b) {
            // Exactly one end is inside (> iso), so va != vb unless NaN or overflow intervene.
            (Some(va), Some(vb)) => {
                let t = (self.iso - va) / (vb - va);
                if t.is_finite() {
                    t.clamp(self.min_crossing, 1.0 - self.min_crossing)
                } else {
                    0.5
                }
            }
            // The padding has no value: close the surface halfway, like a voxel's face.
            _ => 0.5,
        };
        let s = self.field.spacing_m;
        let o = self.field.origin_m;
        std::array::from_fn(|k| o[k] + (base[k] as f32 - 1.0 + t * d[k] as f32) * s)
    }

    /// Triangles of cube layer `py` as global vertex indices.
    fn triangles(&self, py: usize, layers: &[Layer], first_vertex: &[u32]) -> Vec<u32> {
        let mut out = Vec::with_capacity(layers[py].mixed.len() * 6);
        for &(px, pz, code) in &layers[py].mixed {
            let (px, pz) = (px as usize, pz as usize);
            // Global index and position of the vertex on the cube edge between two corners,
            // `from` having a subset of `to`'s bits.
            let vertex = |from: u8, to: u8| -> (u32, [f32; 3]) {
                let bx = px + (from & 1) as usize;
                let by = py + ((from >> 1) & 1) as usize;
                let bz = pz + ((from >> 2) & 1) as usize;
                let layer = &layers[by];
                let row = layer.row_start[bz] as usize..layer.row_start[bz + 1] as usize;
                let key = bx as u32 * 7 + (to ^ from) as u32 - 1;
                let at = layer.keys[row.clone()].binary_search(&key).expect("every crossed edge has a vertex");
                (first_vertex[by] + (row.start + at) as u32, layer.positions[row.start + at])
            };
            for &(corners, positive) in &TETRAHEDRA {
                let inside: [bool; 4] = corners.map(|c| (code >> c) & 1 == 1);
                let n_inside = inside.iter().filter(|&&i| i).count();
                if n_inside == 0 || n_inside == 4 {
                    continue;
                }
                let edge = |i: usize, j: usize| {
                    let (lo, hi) = if i < j { (i, j) } else { (j, i) };
                    vertex(corners[lo], corners[hi])
                };
                let start = out.len();
                match n_inside {
                    1 | 3 => {
                        let lone = inside.iter().position(|&i| i == (n_inside == 1)).expect("one vertex differs");
                        let f = OPPOSITE_FACE[lone];
                        // The face opposite the lone vertex faces away from it: outwards when
                        // it is the inside one, inwards when it is the outside one.
                        let tri = if n_inside == 1 { [f[0], f[1], f[2]] } else { [f[0], f[2], f[1]] };
                        out.extend(tri.map(|k| edge(lone, k).0));
                    }
                    _ => {
                        let mut ins = (0..4).filter(|&k| inside[k]);
                        let (i, j) = (ins.next().unwrap(), ins.next().unwrap());
                        let mut outs = (0..4).filter(|&k| !inside[k]);
                        let (k, l) = (outs.next().unwrap(), outs.next().unwrap());
                        // The loop ik, il, jl, jk faces from {i, j} towards {k, l} for the
                        // vertex order (0, 1 | 2, 3); an odd permutation of it flips that.
                        let inversions = [(i, k), (i, l), (j, k), (j, l)].iter().filter(|(a, b)| a > b).count();
                        let mut quad = [edge(i, k), edge(i, l), edge(j, l), edge(j, k)];
                        if inversions % 2 == 1 {
                            quad.reverse();
                        }
                        let d2 = |a: [f32; 3], b: [f32; 3]| (0..3).map(|m| (a[m] - b[m]) * (a[m] - b[m])).sum::<f32>();
                        // Split along the shorter diagonal for better-shaped triangles.
                        let [q0, q1, q2, q3] = quad.map(|(v, _)| v);
                        if d2(quad[0].1, quad[2].1) <= d2(quad[1].1, quad[3].1) {
                            out.extend([q0, q1, q2, q0, q2, q3]);
                        } else {
                            out.extend([q1, q2, q3, q1, q3, q0]);
                        }
                    }
                }
                if !positive {
                    for t in out[start..].chunks_exact_mut(3) {
                        t.swap(1, 2);
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Whether every directed edge appears once and its reverse once: closed and consistently
    /// wound.
    pub(crate) fn consistently_wound(mesh: &Mesh) -> bool {
        let mut edges: Vec<(u32, u32)> = Vec::new();
        for t in mesh.indices.chunks_exact(3) {
            edges.extend([(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]);
        }
        edges.sort_unstable();
        let unique = edges.windows(2).all(|w| w[0] != w[1]);
        unique && edges.iter().all(|&(a, b)| edges.binary_search(&(b, a)).is_ok())
    }

    /// A sphere field (value = radius − distance, metres) on a cube grid of `n` samples a side.
    fn sphere_values(n: usize, spacing_m: f32, origin_m: [f32; 3], center_m: [f32; 3], radius_m: f32) -> Vec<f32> {
        let mut values = vec![0.0; n * n * n];
        for y in 0..n {
            for z in 0..n {
                for x in 0..n {
                    let p = [x as f32, y as f32, z as f32].map(|v| v * spacing_m);
                    let d: f32 = (0..3).map(|k| (p[k] + origin_m[k] - center_m[k]).powi(2)).sum::<f32>().sqrt();
                    values[x + n * (z + n * y)] = radius_m - d;
                }
            }
        }
        values
    }

    /// 1.0 inside the given voxels, 0.0 elsewhere, on an `n`-cube grid; meshed at iso 0.5.
    fn voxels(n: usize, filled: &[[usize; 3]]) -> Mesh {
        let mut values = vec![0.0; n * n * n];
        for &[x, y, z] in filled {
            values[x + n * (z + n * y)] = 1.0;
        }
        extract_isosurface(
            &ScalarField { dims: [n; 3], origin_m: [0.0; 3], spacing_m: 1.0, values: &values },
            0.5,
            Stop::NEVER,
        )
        .unwrap()
    }

    fn assert_closed_outwards(mesh: &Mesh) {
        mesh.check().unwrap();
        assert!(mesh.is_closed(), "open mesh of {} triangles", mesh.triangle_count());
        assert!(consistently_wound(mesh));
        assert!(mesh.signed_volume() > 0.0, "volume {}", mesh.signed_volume());
    }

    #[test]
    fn sphere_is_closed_with_its_volume_and_radius() {
        // Radius 5 m = 10 samples of 0.5 m, centred off the grid's lattice, origin off zero.
        let (n, spacing, origin, center, r) = (26, 0.5, [-3.0, 1.0, 2.0], [3.2, 7.1, 8.3], 5.0f32);
        let values = sphere_values(n, spacing, origin, center, r);
        let mesh = extract_isosurface(
            &ScalarField { dims: [n; 3], origin_m: origin, spacing_m: spacing, values: &values },
            0.0,
            Stop::NEVER,
        )
        .unwrap();
        assert_closed_outwards(&mesh);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * (r as f64).powi(3);
        let volume = mesh.signed_volume();
        assert!((volume / exact - 1.0).abs() < 0.02, "volume {volume} vs {exact}");
        for p in &mesh.positions {
            let d = (0..3).map(|k| (p[k] - center[k]).powi(2)).sum::<f32>().sqrt();
            assert!((d - r).abs() < 0.5 * spacing, "vertex {p:?} at {d} m from the centre");
        }
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            let radial: [f32; 3] = std::array::from_fn(|k| (p[k] - center[k]) / r);
            let dot: f32 = (0..3).map(|k| radial[k] * n[k]).sum();
            assert!(dot > 0.9, "normal {n:?} at {p:?}");
        }
        assert!(mesh.uvs.iter().flatten().all(|&c| (0.0..=1.0).contains(&c)));
        assert!(mesh.colors.is_none());
    }

    #[test]
    fn random_voxels_give_a_closed_outward_mesh() {
        let n = 20;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut filled = Vec::new();
        for y in 0..n {
            for z in 0..n {
                for x in 0..n {
                    // xorshift64*: seeded, about half the voxels filled.
                    state ^= state >> 12;
                    state ^= state << 25;
                    state ^= state >> 27;
                    if state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 63 == 1 {
                        filled.push([x, y, z]);
                    }
                }
            }
        }
        assert!((3000..5000).contains(&filled.len()));
        let mesh = voxels(n, &filled);
        assert_closed_outwards(&mesh);
        // Midpoint crossings chamfer the unit voxels around the samples but keep most of them.
        let ratio = mesh.signed_volume() / filled.len() as f64;
        assert!((0.5..1.0).contains(&ratio), "volume per voxel {ratio}");
    }

    #[test]
    fn voxels_touching_along_an_edge_or_at_a_corner_are_closed() {
        for pair in [[[1, 1, 1], [2, 2, 1]], [[1, 1, 1], [2, 1, 2]], [[1, 1, 1], [2, 2, 2]], [[2, 1, 1], [1, 2, 2]]] {
            let mesh = voxels(4, &pair);
            assert_closed_outwards(&mesh);
        }
    }

    #[test]
    fn single_voxel_spans_half_a_sample_each_way() {
        let mesh = voxels(3, &[[1, 1, 1]]);
        assert_closed_outwards(&mesh);
        let (lo, hi) = mesh.bounds().unwrap();
        assert_eq!((lo, hi), ([0.5; 3], [1.5; 3]));
    }

    #[test]
    fn region_reaching_the_grid_side_closes_half_a_sample_beyond() {
        let values = vec![1.0f32; 3 * 4 * 5];
        let field = ScalarField { dims: [3, 4, 5], origin_m: [10.0, 0.0, -2.0], spacing_m: 2.0, values: &values };
        let mesh = extract_isosurface(&field, 0.0, Stop::NEVER).unwrap();
        assert_closed_outwards(&mesh);
        assert_eq!(mesh.bounds().unwrap(), ([9.0, -1.0, -3.0], [15.0, 7.0, 7.0]));
        // The box 6 × 8 × 10 m less small chamfers along its edges.
        let volume = mesh.signed_volume();
        assert!(volume > 0.85 * 480.0 && volume < 480.0, "volume {volume}");
    }

    #[test]
    fn samples_on_the_surface_give_no_degenerate_triangles_or_shared_positions() {
        // Values in {-1, 0, 1}: a third of the samples lie exactly on the surface, as flat caps
        // and floors on a sample plane do.
        let n = 14;
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let values: Vec<f32> = (0..n * n * n)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state % 3) as f32 - 1.0
            })
            .collect();
        let mesh = extract_isosurface(
            &ScalarField { dims: [n; 3], origin_m: [0.0; 3], spacing_m: 1.0, values: &values },
            0.0,
            Stop::NEVER,
        )
        .unwrap();
        assert!(mesh.triangle_count() > 1000);
        assert_eq!(mesh.degeneracies(), (0, 0));
        assert!(consistently_wound(&mesh));
        // A slab whose faces fall on sample planes (exactly 0 there) keeps flat faces, moved by
        // the least crossing.
        let slab: Vec<f32> = (0..n * n * n).map(|i| 3.0 - ((i / (n * n)) as f32 - 6.0).abs()).collect();
        let mesh = extract_isosurface(
            &ScalarField { dims: [n; 3], origin_m: [0.0; 3], spacing_m: 1.0, values: &slab },
            0.0,
            Stop::NEVER,
        )
        .unwrap();
        assert_eq!(mesh.degeneracies(), (0, 0));
        let (lo, hi) = mesh.bounds().unwrap();
        let e = min_crossing([n; 3]);
        assert_eq!((lo[1], hi[1]), (3.0 + e, 9.0 - e));
        let faces = mesh.positions.iter().filter(|p| p[1] == lo[1] || p[1] == hi[1]).count();
        let near_faces = mesh.positions.iter().filter(|p| p[1] < 3.5 || p[1] > 8.5).count();
        assert_eq!(faces, near_faces, "every vertex near a face lies on its plane");
    }

    #[test]
    fn nothing_inside_gives_an_empty_mesh() {
        let values = vec![0.5f32; 27];
        let field = ScalarField { dims: [3, 3, 3], origin_m: [0.0; 3], spacing_m: 1.0, values: &values };
        // Samples equal to iso are outside.
        assert_eq!(extract_isosurface(&field, 0.5, Stop::NEVER).unwrap(), Mesh::default());
        let field = ScalarField { dims: [0, 3, 3], values: &[], ..field };
        assert_eq!(extract_isosurface(&field, 0.5, Stop::NEVER).unwrap(), Mesh::default());
    }

    #[test]
    fn same_mesh_on_one_thread_or_two() {
        let n = 40;
        let values: Vec<f32> = (0..n * n * n)
            .map(|i| {
                let (x, z, y) = ((i % n) as f32, ((i / n) % n) as f32, (i / (n * n)) as f32);
                (x * 0.3).sin() + (y * 0.25).cos() * (z * 0.2).sin() - 0.2
            })
            .collect();
        let field = ScalarField { dims: [n; 3], origin_m: [0.0; 3], spacing_m: 0.25, values: &values };
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let a = one.install(|| extract_isosurface(&field, 0.0, Stop::NEVER).unwrap());
        let b = two.install(|| extract_isosurface(&field, 0.0, Stop::NEVER).unwrap());
        assert_closed_outwards(&a);
        assert_eq!(a, b);
    }
}
