//! Plain mesh data shared by every job kind and the glb writer.
//!
//! Conventions: positions in metres, Y up (right-handed, +X right, +Z towards the viewer);
//! triangles are wound counter-clockwise when seen from the side their normal points to, so a
//! closed mesh's front faces look outwards and a terrain's look up.

/// An indexed triangle mesh.
///
/// `positions`, `normals`, `uvs` and (when present) `colors` are per vertex and have the same
/// length; `indices` holds three vertex indices per triangle, counter-clockwise from the front.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Metres, Y up.
    pub positions: Vec<[f32; 3]>,
    /// Unit vectors.
    pub normals: Vec<[f32; 3]>,
    /// Texture coordinates in [0, 1], (0, 0) at the first vertex's corner.
    pub uvs: Vec<[f32; 2]>,
    /// sRGB colour and alpha per vertex, if the mesh carries them.
    pub colors: Option<Vec<[u8; 4]>>,
    pub indices: Vec<u32>,
}

impl Mesh {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The mesh less the vertices no triangle uses, the others kept in their order.
    pub fn without_unused_vertices(&self) -> Mesh {
        compact(self, &self.indices)
    }

    /// Axis-aligned bounds `(min, max)` of the positions; `None` for a mesh without vertices.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let first = *self.positions.first()?;
        let (mut lo, mut hi) = (first, first);
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        Some((lo, hi))
    }

    /// Whether the per-vertex arrays agree in length, the index count is a multiple of three,
    /// every index names a vertex and every position is finite. Writers assert this; meshers
    /// test it.
    pub fn check(&self) -> Result<(), String> {
        let n = self.positions.len();
        if self.normals.len() != n {
            return Err(format!("{} normals for {n} positions", self.normals.len()));
        }
        if self.uvs.len() != n {
            return Err(format!("{} uvs for {n} positions", self.uvs.len()));
        }
        if let Some(colors) = &self.colors {
            if colors.len() != n {
                return Err(format!("{} colors for {n} positions", colors.len()));
            }
        }
        if self.indices.len() % 3 != 0 {
            return Err(format!("{} indices is not a whole number of triangles", self.indices.len()));
        }
        if let Some(&bad) = self.indices.iter().find(|&&i| i as usize >= n) {
            return Err(format!("index {bad} out of range for {n} vertices"));
        }
        if let Some(i) = self.positions.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(format!("position {i} is not finite: {:?}", self.positions[i]));
        }
        Ok(())
    }

    /// Whether every undirected edge is shared by exactly two triangles: the mesh bounds a
    /// volume without holes or fins (it may still be wound inconsistently; see
    /// [`Mesh::signed_volume`]).
    pub fn is_closed(&self) -> bool {
        !self.indices.is_empty() && sorted_edges(&self.indices).chunk_by(|a, b| a == b).all(|run| run.len() == 2)
    }

    /// `(zero-area triangles, vertices at the position of another)`: triangles whose corners'
    /// cross product is exactly zero (computed in f64 from the f32 positions, so exact), and
    /// vertices beyond the first at each position. Physics engines and lightmappers reject
    /// meshes with either; every mesh Landform writes has (0, 0).
    pub fn degeneracies(&self) -> (usize, usize) {
        let zero_area = self
            .indices
            .chunks_exact(3)
            .filter(|t| {
                zero_area(self.positions[t[0] as usize], self.positions[t[1] as usize], self.positions[t[2] as usize])
            })
            .count();
        let mut keys: Vec<[u32; 3]> = self.positions.iter().map(|q| q.map(|c| (c + 0.0).to_bits())).collect();
        rayon::slice::ParallelSliceMut::par_sort_unstable(&mut keys[..]);
        let duplicates = keys.windows(2).filter(|w| w[0] == w[1]).count();
        (zero_area, duplicates)
    }

    /// Signed volume in cubic metres enclosed by the triangles (divergence theorem, summed in
    /// f64). Positive when a closed mesh's triangles face outwards; meaningless when open.
    pub fn signed_volume(&self) -> f64 {
        let p = |i: u32| {
            let v = self.positions[i as usize];
            [v[0] as f64, v[1] as f64, v[2] as f64]
        };
        self.indices
            .chunks_exact(3)
            .map(|t| {
                let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
                // a · (b × c) is six times the tetrahedron (origin, a, b, c).
                a[0] * (b[1] * c[2] - b[2] * c[1])
                    + a[1] * (b[2] * c[0] - b[0] * c[2])
                    + a[2] * (b[0] * c[1] - b[1] * c[0])
            })
            .sum::<f64>()
            / 6.0
    }
}

/// How a node's surface looks in a glb: a non-metallic PBR material, fully rough for ground and
/// stone.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MaterialKind {
    /// Coloured by the mesh's per-vertex colours (base colour white); light grey without them.
    #[default]
    VertexColors,
    /// One colour, as sRGB bytes (e.g. sandstone `[194, 140, 96]`), times any vertex colours.
    Matte { srgb: [u8; 3] },
    /// A sea or lake surface: blue and smoother than ground.
    Water,
}

/// One named object in a [`Scene`].
#[derive(Clone, Debug, PartialEq)]
pub struct SceneNode {
    /// Shown by viewers and engines; need not be unique, but should be.
    pub name: String,
    pub mesh: Mesh,
    pub material: MaterialKind,
    /// The piece's own base in world coordinates, where a glb puts the node's origin (its
    /// `translation`), so an engine or Blender moves, rotates and scales the piece about it:
    /// a speleothem's root on the roof or floor. `None`: the middle of the bottom of the
    /// mesh's box (see [`SceneNode::pivot`]).
    pub pivot: Option<[f32; 3]>,
    /// `Some([columns, rows])` when the mesh is a heightfield's grid of that many vertices,
    /// as [`heightfield_mesh`](super::heightfield_mesh) lays it out: its levels of detail are
    /// then triangulated from the grid and measured exactly ([`grid_levels`](super::grid_levels)).
    pub grid: Option<[usize; 2]>,
}

impl SceneNode {
    pub fn new(name: impl Into<String>, mesh: Mesh, material: MaterialKind) -> Self {
        Self { name: name.into(), mesh, material, pivot: None, grid: None }
    }

    /// This node as a heightfield's grid of `vertices` (along X, along Z).
    pub fn with_grid(self, vertices: [usize; 2]) -> Self {
        Self { grid: Some(vertices), ..self }
    }

    /// This node with its pivot at `pivot` (world coordinates).
    pub fn with_pivot(self, pivot: [f32; 3]) -> Self {
        Self { pivot: Some(pivot), ..self }
    }

    /// Where the node's origin goes: the pivot given, else the centre of the bottom face of
    /// the mesh's box (a rock's or a terrain's foot), else the world origin for an empty mesh.
    pub fn pivot(&self) -> [f32; 3] {
        self.pivot.or_else(|| self.mesh.bounds().map(|(lo, hi)| bottom_centre(lo, hi))).unwrap_or([0.0; 3])
    }
}

/// The centre of the bottom (lowest y) face of the box `(lo, hi)`, computed so that it lies
/// exactly between the corners' x and z.
pub fn bottom_centre(lo: [f32; 3], hi: [f32; 3]) -> [f32; 3] {
    let mid = |a: f32, b: f32| ((f64::from(a) + f64::from(b)) / 2.0) as f32;
    [mid(lo[0], hi[0]), lo[1], mid(lo[2], hi[2])]
}

/// What a glb holds: named nodes in world coordinates (no transforms), written in this order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    pub nodes: Vec<SceneNode>,
}

impl Scene {
    /// A scene of one node with the default material.
    pub fn single(name: impl Into<String>, mesh: Mesh) -> Self {
        Self { nodes: vec![SceneNode::new(name, mesh, MaterialKind::default())] }
    }
}

/// Whether a triangle's corners have an exactly zero cross product (computed in f64 from the
/// f32 positions, so exact): collinear or coincident corners.
pub fn zero_area(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> bool {
    let (a, b, c) = (a.map(f64::from), b.map(f64::from), c.map(f64::from));
    let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
    u[1] * v[2] - u[2] * v[1] == 0.0 && u[2] * v[0] - u[0] * v[2] == 0.0 && u[0] * v[1] - u[1] * v[0] == 0.0
}

/// A triangle's least height: twice its area over its longest side (0 when flat).
pub fn least_height(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> f64 {
    let (a, b, c) = (a.map(f64::from), b.map(f64::from), c.map(f64::from));
    let d = |p: [f64; 3], q: [f64; 3]| [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
    let len = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let (u, v) = (d(a, b), d(a, c));
    let cross = len([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]);
    let longest = len(u).max(len(v)).max(len(d(b, c)));
    if longest > 0.0 {
        cross / longest
    } else {
        0.0
    }
}

/// Every triangle's three edges as [`edge_key`]s, sorted: an edge appears once for each
/// triangle on it. Sorting packed keys instead of counting in a HashMap keeps this
/// allocation-light and independent of hashing order.
pub fn sorted_edges(indices: &[u32]) -> Vec<u64> {
    let mut edges: Vec<u64> = Vec::with_capacity(indices.len());
    for t in indices.chunks_exact(3) {
        edges.extend([(t[0], t[1]), (t[1], t[2]), (t[2], t[0])].map(|(a, b)| edge_key(a, b)));
    }
    rayon::slice::ParallelSliceMut::par_sort_unstable(&mut edges[..]);
    edges
}

/// The edge between vertices `a` and `b`, either way round, as one number.
pub fn edge_key(a: u32, b: u32) -> u64 {
    (u64::from(a.min(b)) << 32) | u64::from(a.max(b))
}

/// The triangles `indices` of `mesh` with only the vertices they use, kept in their order.
pub(super) fn compact(mesh: &Mesh, indices: &[u32]) -> Mesh {
    compact_keeping(mesh, indices).0
}

/// [`compact`], and the number in `mesh` of each vertex kept.
pub(super) fn compact_keeping(mesh: &Mesh, indices: &[u32]) -> (Mesh, Vec<u32>) {
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
    let mesh = Mesh {
        positions: take(&mesh.positions),
        normals: take(&mesh.normals),
        uvs: kept.iter().map(|&i| mesh.uvs[i]).collect(),
        colors: mesh.colors.as_ref().map(|c| kept.iter().map(|&i| c[i]).collect()),
        indices: indices.iter().map(|&i| new_index[i as usize]).collect(),
    };
    (mesh, kept.into_iter().map(|i| i as u32).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube, triangles facing outwards.
    fn cube() -> Mesh {
        let positions: Vec<[f32; 3]> =
            (0..8).map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32]).collect();
        #[rustfmt::skip]
        let indices = vec![
            0, 1, 5, 0, 5, 4, // y = 0, facing -Y
            2, 6, 7, 2, 7, 3, // y = 1, facing +Y
            0, 4, 6, 0, 6, 2, // x = 0, facing -X
            1, 3, 7, 1, 7, 5, // x = 1, facing +X
            0, 2, 3, 0, 3, 1, // z = 0, facing -Z
            4, 5, 7, 4, 7, 6, // z = 1, facing +Z
        ];
        let n = positions.len();
        Mesh { positions, normals: vec![[0.0, 1.0, 0.0]; n], uvs: vec![[0.0; 2]; n], colors: None, indices }
    }

    #[test]
    fn outward_cube_is_closed_with_volume_one() {
        let m = cube();
        assert!(m.check().is_ok());
        assert!(m.is_closed());
        assert!((m.signed_volume() - 1.0).abs() < 1e-12);
        assert_eq!(m.triangle_count(), 12);
        assert_eq!(m.bounds(), Some(([0.0; 3], [1.0; 3])));
    }

    #[test]
    fn cube_missing_a_face_is_open() {
        let mut m = cube();
        m.indices.truncate(30);
        assert!(!m.is_closed());
    }

    #[test]
    fn inverted_cube_has_negative_volume() {
        let mut m = cube();
        for t in m.indices.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
        assert!(m.is_closed());
        assert!((m.signed_volume() + 1.0).abs() < 1e-12);
    }

    #[test]
    fn check_rejects_out_of_range_index() {
        let mut m = cube();
        m.indices[0] = 8;
        assert!(m.check().unwrap_err().contains("out of range"));
    }
}
