//! Tiles cut from a heightfield's grid mesh (see [`super::heightfield_mesh`]): rectangles of
//! its vertex grid whose edges neighbouring tiles share, as engines' terrain tiles do. A tile
//! holds the grid's own vertices (positions, normals, texcoords and colours copied, never
//! recomputed) and the grid's own triangles, so the tiles of a grid together are the grid.

use std::ops::RangeInclusive;

use super::heightfield_mesh::grid_triangles_at;
use super::types::{edge_key, sorted_edges};
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
        indices: grid_triangles_at(xs.clone().count(), zs.clone().count(), [*xs.start(), *zs.start()]),
    }
}

/// The vertices of `mesh` on one vertical side of the box `(lo, hi)` (`axis` 0: x = lo or hi
/// as `high`; 2: z), as (position along the side, height), in order along it.
fn side_profile(mesh: &Mesh, (lo, hi): ([f32; 3], [f32; 3]), axis: usize, high: bool) -> Vec<(f32, f32)> {
    let at = if high { hi[axis] } else { lo[axis] };
    let along = 2 - axis;
    let mut profile: Vec<(f32, f32)> =
        mesh.positions.iter().filter(|p| p[axis] == at).map(|p| (p[along], p[1])).collect();
    profile.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    profile.dedup_by(|a, b| a.0 == b.0);
    profile
}

/// The height of a side's `profile` at `u` along it, linear between its vertices (the edges
/// a border runs along); the nearest end's beyond them.
fn profile_height(profile: &[(f32, f32)], u: f32) -> f32 {
    let after = profile.partition_point(|p| p.0 < u);
    match (after.checked_sub(1).map(|k| profile[k]), profile.get(after)) {
        (Some((u0, h0)), Some(&(u1, h1))) if u1 > u0 => h0 + (h1 - h0) * (u - u0) / (u1 - u0),
        (_, Some(&(_, h))) | (Some((_, h)), None) => h,
        (None, None) => f32::NAN,
    }
}

/// How far, vertically, the border of `level` (a simplification of the tile `full` whose border
/// was free to move along its sides) lies from `full`'s border, at its worst over every border
/// vertex of `full`: the crack that can open between neighbouring tiles is at most the sum of
/// both tiles' figures, which is what a skirt must hide. Sides are found exactly: the tiles'
/// border vertices are the grid's own and keep their coordinates.
pub fn border_drift(full: &Mesh, level: &Mesh) -> f32 {
    let Some(frame) = full.bounds() else { return 0.0 };
    let mut worst = 0.0f32;
    for (axis, high) in [(0, false), (0, true), (2, false), (2, true)] {
        let want = side_profile(full, frame, axis, high);
        let got = side_profile(level, frame, axis, high);
        for &(u, h) in &want {
            worst = worst.max((profile_height(&got, u) - h).abs());
        }
    }
    worst
}

/// `mesh` (a simplified tile) without fins on its sides: triangles whose three corners lie on
/// one side of the box `frame` (the full tile's). With its border free, an inside vertex may
/// collapse onto the border and leave such a triangle standing upright on the tile's side,
/// where the skirt is the wall; seen from above it covers nothing, so dropping it leaves the
/// ground as it was. The vertices left unused go.
pub fn without_fins(mesh: &Mesh, (lo, hi): ([f32; 3], [f32; 3])) -> Mesh {
    let p = |i: u32| mesh.positions[i as usize];
    let fin = |t: &[u32]| {
        [(0, lo[0]), (0, hi[0]), (2, lo[2]), (2, hi[2])].iter().any(|&(k, at)| t.iter().all(|&v| p(v)[k] == at))
    };
    if !mesh.indices.chunks_exact(3).any(fin) {
        return mesh.clone();
    }
    let kept: Vec<u32> = mesh.indices.chunks_exact(3).filter(|t| !fin(t)).flatten().copied().collect();
    super::types::compact(mesh, &kept)
}

/// `mesh` (a tile) with a skirt: from every border edge a wall hangs `depth_m` straight down,
/// facing out of the tile, its lower vertices copies of the border's (same normal, texcoords
/// and colour) lowered by `depth_m`. The surface's vertices and triangles come first,
/// unchanged.
pub fn with_skirt(mesh: &Mesh, depth_m: f32) -> Mesh {
    let edges = sorted_edges(&mesh.indices);
    let once = |a: u32, b: u32| {
        let key = edge_key(a, b);
        let first = edges.partition_point(|e| *e < key);
        edges.get(first) == Some(&key) && edges.get(first + 1) != Some(&key)
    };
    let mut out = mesh.clone();
    let mut lowered: Vec<Option<u32>> = vec![None; mesh.vertex_count()];
    let mut lower = |v: u32, out: &mut Mesh| -> u32 {
        *lowered[v as usize].get_or_insert_with(|| {
            let v = v as usize;
            let [x, y, z] = mesh.positions[v];
            out.positions.push([x, y - depth_m, z]);
            out.normals.push(mesh.normals[v]);
            out.uvs.push(mesh.uvs[v]);
            if let (Some(colors), Some(from)) = (out.colors.as_mut(), mesh.colors.as_ref()) {
                colors.push(from[v]);
            }
            (out.positions.len() - 1) as u32
        })
    };
    for t in mesh.indices.chunks_exact(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if once(a, b) {
                // The surface runs a → b with the tile on its left seen from above: the wall
                // (a, a', b), (b, a', b') faces right, out of the tile.
                let (a_low, b_low) = (lower(a, &mut out), lower(b, &mut out));
                out.indices.extend([a, a_low, b, b, a_low, b_low]);
            }
        }
    }
    out
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

    #[test]
    fn a_skirt_hangs_a_closed_wall_facing_out_from_every_border_edge() {
        // A 4 × 3 grid of 1 m cells on a slope: 14 border edges, so 14 quads, 14 new vertices.
        let hf = Heightfield::from_fn(5, 4, 1.0, |x, z| 10.0 + 0.5 * x + 0.25 * z);
        let grid = heightfield_mesh(&hf, DEFAULT_MAX_SIDE_SAMPLES, None).mesh;
        let skirted = with_skirt(&grid, 2.0);
        assert!(skirted.check().is_ok());
        assert_eq!(skirted.vertex_count(), 20 + 14);
        assert_eq!(skirted.triangle_count(), 24 + 28);
        assert_eq!(skirted.indices[..grid.indices.len()], grid.indices[..], "the surface first, unchanged");
        let p = |i: u32| skirted.positions[i as usize];
        for t in skirted.indices[grid.indices.len()..].chunks_exact(3) {
            let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
            let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
            let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            // Vertical, facing away from the tile's middle (2, 1.5), 2 m deep.
            assert_eq!(n[1], 0.0, "{t:?} is not vertical");
            let centre = [(a[0] + b[0] + c[0]) / 3.0 - 2.0, (a[2] + b[2] + c[2]) / 3.0 - 1.5];
            assert!(n[0] * centre[0] + n[2] * centre[1] > 0.0, "{t:?} faces in");
            let ys = [a[1], b[1], c[1]];
            assert!(ys.iter().any(|y| ys.iter().any(|z| (y - z - 2.0).abs() < 1e-5)), "{ys:?}");
        }
        // Surface and skirt together: every edge but the skirt's foot joins two triangles.
        let mut edges = std::collections::BTreeMap::new();
        for t in skirted.indices.chunks_exact(3) {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        let open: Vec<_> = edges.iter().filter(|(_, &n)| n != 2).map(|(e, _)| *e).collect();
        assert_eq!(open.len(), 14);
        assert!(open.iter().all(|&(a, b)| a >= 20 && b >= 20), "only the foot is open: {open:?}");
    }

    #[test]
    fn a_fin_standing_on_a_side_goes_and_the_ground_stays() {
        let hf = Heightfield::from_fn(4, 3, 1.0, |x, z| x * 0.5 + z);
        let grid = heightfield_mesh(&hf, DEFAULT_MAX_SIDE_SAMPLES, None).mesh;
        let frame = grid.bounds().unwrap();
        assert_eq!(without_fins(&grid, frame), grid);
        // Vertices 0, 1, 2 lie on the side z = 0: a triangle of them is a fin.
        let mut finned = grid.clone();
        finned.indices.extend([0, 2, 1]);
        assert_eq!(without_fins(&finned, frame), grid);
    }

    #[test]
    fn border_drift_is_the_vertical_gap_at_the_full_borders_vertices() {
        let hf = Heightfield::from_fn(5, 5, 1.0, |x, z| if x == 2.0 && z == 0.0 { 3.0 } else { 1.0 });
        let full = heightfield_mesh(&hf, DEFAULT_MAX_SIDE_SAMPLES, None).mesh;
        assert_eq!(border_drift(&full, &full), 0.0);
        // Without the raised vertex on the z = 0 side, its border runs straight at 1 m there:
        // 2 m below the full border.
        let mut level = full.clone();
        level.positions[2] = [2.0, 5.0, 0.5];
        assert_eq!(border_drift(&full, &level), 2.0);
    }
}
