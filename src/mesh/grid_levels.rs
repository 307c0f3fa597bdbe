//! Levels of detail of a heightfield's grid: at each bound the grid triangulated as a right-
//! triangulated irregular network ([`Rtin`]) and measured exactly in the vertical
//! ([`vertical_deviation`]), a few milliseconds for a 257² grid where meshoptimizer's tries and
//! the sampled measure take a tenth of a second or more. Every level tiles the grid's whole
//! rectangle without T-junctions, so its border runs where the full mesh's does (vertices along
//! it may go, the line stays), no triangle is flat (each is half a square in plan) and no edge
//! has a third triangle.

use super::heightfield_mesh::quad_triangles;
use super::lod::Lod;
use super::rtin::vertical_deviation;
use super::types::compact;
use super::{Mesh, Rtin};
use crate::stop::{Stop, Stopped};

/// One level of `mesh`, a heightfield's grid of `cols × rows` vertices, for each of `bounds_m`;
/// `None` when the mesh is not such a grid with evenly spaced columns and rows (a stride that
/// leaves a narrower last column), for the simplifier to make instead.
pub fn grid_levels(
    mesh: &Mesh,
    [cols, rows]: [usize; 2],
    bounds_m: &[f32],
    stop: Stop,
) -> Option<Result<Vec<Lod>, Stopped>> {
    if !is_even_grid(mesh, cols, rows) {
        return None;
    }
    let heights: Vec<f32> = mesh.positions.iter().map(|p| p[1]).collect();
    let rtin = Rtin::new(&heights, cols, rows)?;
    let mut levels: Vec<Lod> = Vec::with_capacity(bounds_m.len());
    let mut previous: Option<(Vec<u32>, f32)> = None;
    for &bound in bounds_m {
        if let Err(stopped) = stop.check() {
            return Some(Err(stopped));
        }
        let triangles = rtin.triangles(bound);
        let deviation = vertical_deviation(&heights, cols, rows, &triangles);
        let (triangles, deviation, unreduced) = if deviation <= bound {
            (triangles, deviation, None)
        } else {
            // Not expected: every triangle kept is within the bound, and the finest are the
            // grid's own. Kept as a guard so no level is ever over its bound.
            let reason = format!("the grid triangulated lay {deviation:.4} m from it, over the {bound:.4} m bound");
            let (kept, kept_deviation) = previous.clone().unwrap_or_else(|| (mesh.indices.clone(), 0.0));
            (kept, kept_deviation, Some(reason))
        };
        levels.push(Lod {
            mesh: compact(mesh, &triangles),
            target_m: bound,
            simplifier_error_m: 0.0,
            deviation_m: deviation,
            sample_spacing_m: 0.0,
            tries: 0,
            unreduced,
        });
        previous = Some((triangles, deviation));
    }
    Some(Ok(levels))
}

/// Whether `mesh` is a grid of `cols × rows` vertices row by row, its columns and rows evenly
/// spaced (to a thousandth of a cell), its cells split as [`grid_triangles`](super::heightfield_mesh::grid_triangles) splits them (the
/// measure assumes that split).
fn is_even_grid(mesh: &Mesh, cols: usize, rows: usize) -> bool {
    if cols < 2 || rows < 2 || mesh.vertex_count() != cols * rows || mesh.indices.len() != (cols - 1) * (rows - 1) * 6 {
        return false;
    }
    // Quad by quad, as `grid_triangles` would make them, without making them.
    let split_as_the_grid = mesh
        .indices
        .chunks_exact(6)
        .enumerate()
        .all(|(n, quad)| quad == quad_triangles(cols, n % (cols - 1), n / (cols - 1), [0, 0]));
    if !split_as_the_grid {
        return false;
    }
    let p = &mesh.positions;
    let (x0, z0) = (f64::from(p[0][0]), f64::from(p[0][2]));
    let (dx, dz) = (f64::from(p[1][0]) - x0, f64::from(p[cols][2]) - z0);
    dx > 0.0
        && dz > 0.0
        && (0..cols).all(|i| (f64::from(p[i][0]) - x0 - i as f64 * dx).abs() <= 1e-3 * dx)
        && (0..rows).all(|j| (f64::from(p[j * cols][2]) - z0 - j as f64 * dz).abs() <= 1e-3 * dz)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::heightfield_mesh;
    use crate::terrain::Heightfield;

    fn hills(cols: usize, rows: usize) -> Heightfield {
        Heightfield::from_fn(cols, rows, 2.0, |x, z| {
            (x * 0.11).sin() * 9.0 + (z * 0.07).cos() * 6.0 + (x * 0.5 + z * 0.3).sin() * 0.4
        })
    }

    #[test]
    fn levels_keep_their_bounds_and_the_grids_attributes() {
        let hf = hills(97, 60);
        let grid = heightfield_mesh(&hf, 4097, None);
        let bounds = [0.5f32, 2.0, 8.0];
        let levels = grid_levels(&grid.mesh, grid.vertices, &bounds, Stop::NEVER).unwrap().unwrap();
        let mut last = grid.mesh.triangle_count();
        for (lod, &bound) in levels.iter().zip(&bounds) {
            assert!(lod.unreduced.is_none());
            assert!(lod.deviation_m <= bound);
            assert!(lod.mesh.triangle_count() < last, "{} then {}", last, lod.mesh.triangle_count());
            last = lod.mesh.triangle_count();
            // Every vertex is one of the grid's, with its normal and texcoords.
            for (k, p) in lod.mesh.positions.iter().enumerate() {
                let at = grid.mesh.positions.iter().position(|q| q == p).expect("a grid vertex");
                assert_eq!(lod.mesh.normals[k], grid.mesh.normals[at]);
                assert_eq!(lod.mesh.uvs[k], grid.mesh.uvs[at]);
            }
            // A second method: the sampled two-sided distance keeps within the exact figure.
            let sampled = crate::mesh::max_deviation(&grid.mesh, &lod.mesh, 0.5, Stop::NEVER).unwrap();
            assert!(sampled <= lod.deviation_m + 1e-3, "sampled {sampled} over exact {}", lod.deviation_m);
        }
        assert!(levels[2].mesh.triangle_count() * 20 < grid.mesh.triangle_count());
    }

    #[test]
    fn a_grid_with_a_narrower_last_column_is_left_to_the_simplifier() {
        let hf = hills(10, 9);
        // A stride of 2 over 10 columns keeps 0, 2, …, 8 and 9: the last cell is half as wide.
        let grid = heightfield_mesh(&hf, 6, None);
        assert_eq!(grid.stride, 2);
        assert!(grid_levels(&grid.mesh, grid.vertices, &[1.0], Stop::NEVER).is_none());
        let even = heightfield_mesh(&hills(9, 9), 5, None);
        assert!(grid_levels(&even.mesh, even.vertices, &[1.0], Stop::NEVER).is_some());
        assert!(grid_levels(&even.mesh, [3, 27], &[1.0], Stop::NEVER).is_none());
        // Cells split some other way: the exact measure would not be the mesh's.
        let mut turned = even.mesh.clone();
        let n = even.vertices[0] as u32;
        turned.indices[..6].copy_from_slice(&[0, n, 1, 1, n, n + 1]);
        assert_ne!(turned.indices, even.mesh.indices);
        assert!(grid_levels(&turned, even.vertices, &[1.0], Stop::NEVER).is_none());
    }
}
