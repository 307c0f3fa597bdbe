//! Tiles cut from a heightfield's grid mesh (see [`super::heightfield_mesh`]): rectangles of
//! its vertex grid whose edges neighbouring tiles share, as engines' terrain tiles do. A tile
//! holds the grid's own vertices (positions, normals, texcoords and colours copied, never
//! recomputed) and the grid's own triangles, so the tiles of a grid together are the grid.

use std::ops::RangeInclusive;

use super::heightfield_mesh::grid_triangles;
use super::Mesh;

/// Where `count` tiles split `n` vertices along one side: `count + 1` increasing vertex
/// indices from 0 to `n − 1`, tile k spanning `edges[k]..=edges[k + 1]` (as even as whole
/// cells allow). A side of fewer cells than `count` gets one tile per cell.
pub fn tile_edges(n: usize, count: usize) -> Vec<usize> {
    let cells = n.saturating_sub(1);
    if cells == 0 {
        return vec![0, 0];
    }
    let count = count.clamp(1, cells);
    (0..=count).map(|k| (k * cells + count / 2) / count).collect()
}

/// The tile of a grid mesh of `columns` vertices per row that spans vertex columns `xs` and
/// vertex rows `zs` (inclusive), its vertices row by row.
pub fn grid_patch(mesh: &Mesh, columns: usize, xs: RangeInclusive<usize>, zs: RangeInclusive<usize>) -> Mesh {
    let kept: Vec<usize> = zs.clone().flat_map(|j| xs.clone().map(move |i| j * columns + i)).collect();
    let take = |values: &[[f32; 3]]| kept.iter().map(|&v| values[v]).collect();
    Mesh {
        positions: take(&mesh.positions),
        normals: take(&mesh.normals),
        uvs: kept.iter().map(|&v| mesh.uvs[v]).collect(),
        colors: mesh.colors.as_ref().map(|c| kept.iter().map(|&v| c[v]).collect()),
        indices: grid_triangles(xs.count(), zs.count()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{heightfield_mesh, DEFAULT_MAX_SIDE_SAMPLES};
    use crate::terrain::Heightfield;
    use std::collections::BTreeSet;

    #[test]
    fn edges_split_cells_evenly_and_share_the_boundaries() {
        assert_eq!(tile_edges(257, 4), [0, 64, 128, 192, 256]);
        assert_eq!(tile_edges(11, 3), [0, 3, 7, 10]); // 10 cells: 3, 4, 3
        assert_eq!(tile_edges(3, 16), [0, 1, 2]); // 2 cells: one tile each
        assert_eq!(tile_edges(9, 1), [0, 8]);
    }

    /// Every triangle of the grid as its three corner positions' bits.
    fn triangles(mesh: &Mesh) -> BTreeSet<[[u32; 3]; 3]> {
        mesh.indices
            .chunks_exact(3)
            .map(|t| std::array::from_fn(|k| mesh.positions[t[k] as usize].map(f32::to_bits)))
            .collect()
    }

    #[test]
    fn the_tiles_together_are_the_grid() {
        let hf = Heightfield::from_fn(23, 17, 1.5, |x, z| (x * 0.3).sin() * 4.0 + z * 0.2);
        let grid = heightfield_mesh(&hf, DEFAULT_MAX_SIDE_SAMPLES, None);
        let [nx, nz] = grid.vertices;
        let (xs, zs) = (tile_edges(nx, 3), tile_edges(nz, 2));
        let mut union = BTreeSet::new();
        let mut count = 0;
        for z in zs.windows(2) {
            for x in xs.windows(2) {
                let tile = grid_patch(&grid.mesh, nx, x[0]..=x[1], z[0]..=z[1]);
                assert!(tile.check().is_ok());
                assert_eq!(tile.vertex_count(), (x[1] - x[0] + 1) * (z[1] - z[0] + 1));
                // The tile's corner is the grid's vertex there, bit for bit.
                assert_eq!(tile.positions[0], grid.mesh.positions[z[0] * nx + x[0]]);
                assert_eq!(tile.normals[0], grid.mesh.normals[z[0] * nx + x[0]]);
                count += tile.triangle_count();
                union.extend(triangles(&tile));
            }
        }
        // 22 × 16 cells, two triangles each, no triangle in two tiles, none missing.
        assert_eq!(count, 22 * 16 * 2);
        assert_eq!(union, triangles(&grid.mesh));
    }
}
