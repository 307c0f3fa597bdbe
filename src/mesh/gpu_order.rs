//! A mesh's triangles and vertices in the order a GPU draws them fastest: triangles through
//! meshoptimizer's vertex cache optimiser (`meshopt::optimize_vertex_cache`: fewer vertex
//! shader runs per triangle), then vertices in the order the triangles first use them (what
//! `meshopt_optimizeVertexFetchRemap` computes: fewer memory fetches). Done here rather than
//! through the crate's remap, which truncates its table when a vertex is unused; unused
//! vertices keep their place after the used ones, so the vertex count never changes. The same
//! triangles, each with its winding, and the same vertices: only the order differs. Used by the
//! glb writer for every mesh; the bytes depend only on the mesh.

use super::Mesh;

/// The new order: `indices` index the reordered vertices, `source[k]` is the original index
/// of new vertex `k`.
pub struct GpuOrder {
    pub indices: Vec<u32>,
    pub source: Vec<u32>,
}

impl GpuOrder {
    pub fn of(mesh: &Mesh) -> Self {
        Self::from_triangle_order(mesh, meshopt::optimize_vertex_cache(&mesh.indices, mesh.vertex_count()))
    }

    /// The order for meshes that are compressed next: triangles through meshoptimizer's
    /// strip-like cache optimiser (`meshopt_optimizeVertexCacheStrip`), which draws a little
    /// slower but whose consecutive triangles and vertices differ less, so meshoptimizer's
    /// index and vertex codecs compress them further (as `gltfpack -cc` orders them).
    pub fn for_compression(mesh: &Mesh) -> Self {
        let mut strip = vec![0u32; mesh.indices.len()];
        // SAFETY: `strip` holds as many indices as the input; indices are below the vertex
        // count (checked by Mesh::check before any writer runs).
        unsafe {
            meshopt::ffi::meshopt_optimizeVertexCacheStrip(
                strip.as_mut_ptr(),
                mesh.indices.as_ptr(),
                mesh.indices.len(),
                mesh.vertex_count(),
            );
        }
        Self::from_triangle_order(mesh, strip)
    }

    /// Vertices renumbered in the order the triangles `cached` first use them.
    fn from_triangle_order(mesh: &Mesh, cached: Vec<u32>) -> Self {
        let n = mesh.vertex_count();
        let mut new_index = vec![u32::MAX; n];
        let mut source = Vec::with_capacity(n);
        let indices = cached
            .iter()
            .map(|&old| {
                let slot = &mut new_index[old as usize];
                if *slot == u32::MAX {
                    *slot = source.len() as u32;
                    source.push(old);
                }
                *slot
            })
            .collect();
        source.extend((0..n as u32).filter(|&old| new_index[old as usize] == u32::MAX));
        Self { indices, source }
    }

    /// `values` (one per vertex) in the new order.
    pub fn at<T: Copy>(&self, values: &[T], k: usize) -> T {
        values[self.source[k] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::heightfield_mesh;
    use crate::terrain::Heightfield;

    /// Vertex shader runs per triangle through a FIFO post-transform cache of `size` entries,
    /// simulated here independently of meshoptimizer.
    fn acmr(indices: &[u32], size: usize) -> f64 {
        let mut fifo = std::collections::VecDeque::new();
        let mut misses = 0;
        for &i in indices {
            if !fifo.contains(&i) {
                misses += 1;
                fifo.push_back(i);
                if fifo.len() > size {
                    fifo.pop_front();
                }
            }
        }
        misses as f64 / (indices.len() / 3) as f64
    }

    /// Each triangle as its three positions, rotated to start at the smallest (winding kept).
    fn triangles(positions: &[[f32; 3]], indices: &[u32]) -> Vec<[[u32; 3]; 3]> {
        let mut t: Vec<[[u32; 3]; 3]> = indices
            .chunks_exact(3)
            .map(|t| {
                let p = [0, 1, 2].map(|k| positions[t[k] as usize].map(f32::to_bits));
                let first = (0..3).min_by_key(|&k| p[k]).unwrap();
                [p[first], p[(first + 1) % 3], p[(first + 2) % 3]]
            })
            .collect();
        t.sort_unstable();
        t
    }

    #[test]
    fn a_grid_draws_with_fewer_cache_misses_and_keeps_its_triangles_and_vertices() {
        let hf = Heightfield::from_fn(65, 65, 1.0, |x, z| (x * 0.1).sin() * 3.0 + z * 0.05);
        let mesh = heightfield_mesh(&hf, 4097, None).mesh;
        let order = GpuOrder::of(&mesh);
        let positions: Vec<[f32; 3]> = (0..mesh.vertex_count()).map(|k| order.at(&mesh.positions, k)).collect();
        assert_eq!(triangles(&positions, &order.indices), triangles(&mesh.positions, &mesh.indices));
        let mut sorted = order.source.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..mesh.vertex_count() as u32).collect::<Vec<_>>(), "every vertex once");
        // Row by row, a 16-entry cache has lost the row above by the time it is needed again:
        // about one miss per triangle. Reordered, well under it.
        let (before, after) = (acmr(&mesh.indices, 16), acmr(&order.indices, 16));
        eprintln!("ACMR (16-entry FIFO): {before:.3} → {after:.3}");
        assert!(before > 0.95, "{before}");
        assert!(after < 0.75, "{before} → {after}");
        // Vertices come in the order the triangles first use them.
        let mut seen = 0u32;
        for &i in &order.indices {
            assert!(i <= seen, "vertex {i} used before vertex {seen}");
            seen = seen.max(i + 1);
        }
    }

    #[test]
    fn unused_vertices_keep_their_place_after_the_used_ones() {
        let mesh = Mesh {
            positions: vec![[0.0; 3], [9.0; 3], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            normals: vec![[0.0, 1.0, 0.0]; 4],
            uvs: vec![[0.0; 2]; 4],
            colors: None,
            indices: vec![0, 3, 2],
        };
        let order = GpuOrder::of(&mesh);
        assert_eq!(order.source.len(), 4);
        assert_eq!(order.source[3], 1, "{:?}", order.source);
    }
}
