//! The chamber as one surface seen from inside: the floor and the roof as grids, joined round
//! their edges by four walls, every side relieved by its own noise (the walls push outwards
//! only, so the free space is never smaller than the box the drip sites stand in). Without an
//! opening it is closed — every edge shared by two triangles, all facing in — so a player
//! inside sees rock in every direction. An opening removes a rectangle of wall from the floor
//! up and carries its rim straight out through the rock as a tunnel, open at its far end.

use super::chamber::ChamberShape;
use super::params::{Opening, Side};
use crate::mesh::{recompute_normals, Mesh};

/// Most rows of wall between floor and roof.
const MAX_WALL_LEVELS: usize = 64;

/// The grid: (cols, rows) samples spanning exactly width × depth.
fn grid(shape: &ChamberShape) -> (usize, usize, f32, f32) {
    let (cols, rows, _) = super::chamber::surface_grid(&shape.chamber);
    let c = &shape.chamber;
    (cols, rows, c.width_m / (cols - 1) as f32, c.depth_m / (rows - 1) as f32)
}

/// The grid points round the edge, in order: along z = 0 (north) towards +x, up the east side,
/// back along the south side, down the west side. Each with its outward direction.
fn perimeter(cols: usize, rows: usize) -> Vec<((usize, usize), [f32; 2])> {
    let mut out = Vec::with_capacity(2 * (cols + rows));
    for i in 0..cols - 1 {
        out.push((i, 0));
    }
    for j in 0..rows - 1 {
        out.push((cols - 1, j));
    }
    for i in (1..cols).rev() {
        out.push((i, rows - 1));
    }
    for j in (1..rows).rev() {
        out.push((0, j));
    }
    out.into_iter()
        .map(|(i, j)| {
            let x = if i == 0 {
                -1.0
            } else if i == cols - 1 {
                1.0
            } else {
                0.0
            };
            let z = if j == 0 {
                -1.0
            } else if j == rows - 1 {
                1.0
            } else {
                0.0
            };
            let len = f32::hypot(x, z);
            ((i, j), [x / len, z / len])
        })
        .collect()
}

/// Which side a perimeter point lies on for an opening, and its index along that side.
fn along(side: Side, (i, j): (usize, usize), cols: usize, rows: usize) -> Option<usize> {
    match side {
        Side::North if j == 0 => Some(i),
        Side::South if j == rows - 1 => Some(i),
        Side::West if i == 0 => Some(j),
        Side::East if i == cols - 1 => Some(j),
        _ => None,
    }
}

fn outward(side: Side) -> [f32; 2] {
    match side {
        Side::West => [-1.0, 0.0],
        Side::East => [1.0, 0.0],
        Side::North => [0.0, -1.0],
        Side::South => [0.0, 1.0],
    }
}

/// The chamber's surface.
pub fn chamber_mesh(shape: &ChamberShape) -> Mesh {
    let c = &shape.chamber;
    let (cols, rows, dx, dz) = grid(shape);
    let ring = perimeter(cols, rows);
    let free = c.height_m - c.roof.relief_m - c.floor.relief_m;
    let levels = ((c.height_m / dx.min(dz)).round() as usize).clamp(2, MAX_WALL_LEVELS);
    let mut on_edge = vec![None; cols * rows];
    for (p, &((i, j), _)) in ring.iter().enumerate() {
        on_edge[j * cols + i] = Some(p);
    }
    let mut positions: Vec<[f32; 3]> = Vec::with_capacity(2 * cols * rows + ring.len() * levels);
    let pushed = |x: f32, y: f32, z: f32, p: Option<usize>| match p {
        Some(p) => {
            let (_, [ox, oz]) = ring[p];
            let push = shape.wall_push(x, y, z);
            [x + ox * push, y, z + oz * push]
        }
        None => [x, y, z],
    };
    // Floor then roof, row by row.
    for surface in 0..2 {
        for j in 0..rows {
            for i in 0..cols {
                let (x, z) = (i as f32 * dx, j as f32 * dz);
                let y = if surface == 0 { shape.floor_y(x, z) } else { shape.roof_y(x, z) };
                positions.push(pushed(x, y, z, on_edge[j * cols + i]));
            }
        }
    }
    let roof_at = cols * rows;
    // Wall levels 1..levels-1 round the perimeter.
    let wall_at = positions.len();
    for l in 1..levels {
        for (p, &((i, j), _)) in ring.iter().enumerate() {
            let (x, z) = (i as f32 * dx, j as f32 * dz);
            let t = l as f32 / levels as f32;
            let y = shape.floor_y(x, z) + t * (shape.roof_y(x, z) - shape.floor_y(x, z));
            positions.push(pushed(x, y, z, Some(p)));
        }
    }
    let n = ring.len();
    let column = |p: usize, l: usize| -> u32 {
        let (i, j) = ring[p % n].0;
        (match l {
            0 => j * cols + i,
            l if l == levels => roof_at + j * cols + i,
            l => wall_at + (l - 1) * n + p % n,
        }) as u32
    };
    let mut indices = Vec::with_capacity(12 * cols * rows + 6 * n * levels);
    for j in 0..rows - 1 {
        for i in 0..cols - 1 {
            let (a, b, cc, d) = (j * cols + i, j * cols + i + 1, (j + 1) * cols + i, (j + 1) * cols + i + 1);
            // Floor faces up, roof down: both into the chamber.
            indices.extend([a, cc, b, b, cc, d].map(|v| v as u32));
            indices.extend([a, b, cc, b, d, cc].map(|v| (roof_at + v) as u32));
        }
    }
    let hole = c.opening.as_ref().and_then(|o| hole(o, &ring, cols, rows, dx, dz, levels, free));
    let in_hole = |p: usize, l: usize| hole.is_some_and(|(p0, p1, top)| p >= p0 && p < p1 && l < top);
    for p in 0..n {
        for l in 0..levels {
            if in_hole(p, l) {
                continue;
            }
            let (a, b, cc, d) = (column(p, l), column(p + 1, l), column(p, l + 1), column(p + 1, l + 1));
            indices.extend([a, b, cc, b, d, cc]);
        }
    }
    if let (Some((p0, p1, top)), Some(o)) = (hole, c.opening.as_ref()) {
        // The hole's rim in the order the removed wall ran round it: along the floor, up the
        // far side, back along the top, down the near side.
        let mut rim: Vec<u32> = (p0..p1).map(|p| column(p, 0)).collect();
        rim.extend((0..top).map(|l| column(p1, l)));
        rim.extend((p0 + 1..=p1).rev().map(|p| column(p, top)));
        rim.extend((1..=top).rev().map(|l| column(p0, l)));
        let [ox, oz] = outward(o.wall);
        let far_at = positions.len() as u32;
        for &v in &rim {
            let q = positions[v as usize];
            positions.push([q[0] + ox * o.length_m, q[1], q[2] + oz * o.length_m]);
        }
        let m = rim.len();
        for k in 0..m {
            let (u, v) = (rim[k], rim[(k + 1) % m]);
            let (uf, vf) = (far_at + k as u32, far_at + ((k + 1) % m) as u32);
            indices.extend([u, v, uf, v, vf, uf]);
        }
    }
    // The wall's vertices inside the opening belong to no triangle: dropped, so that nothing
    // measuring the surface by its vertices (a level's deviation) finds a point in mid-air.
    let mut mesh = Mesh {
        normals: vec![[0.0, 1.0, 0.0]; positions.len()],
        uvs: positions.iter().map(|p| [p[0] / c.width_m.max(1e-6), p[2] / c.depth_m.max(1e-6)]).collect(),
        positions,
        indices,
        ..Mesh::default()
    }
    .without_unused_vertices();
    recompute_normals(&mut mesh);
    mesh
}

/// The opening as (first perimeter column, last perimeter column, wall levels it spans): the
/// columns nearest its ends on its side, at least one cell apart and one from each corner; the levels up to its height
/// over the free height, at least one and below the roof.
#[allow(clippy::too_many_arguments)]
fn hole(
    o: &Opening,
    ring: &[((usize, usize), [f32; 2])],
    cols: usize,
    rows: usize,
    dx: f32,
    dz: f32,
    levels: usize,
    free: f32,
) -> Option<(usize, usize, usize)> {
    let cell = match o.wall {
        Side::West | Side::East => dz,
        Side::North | Side::South => dx,
    };
    let sides = if matches!(o.wall, Side::West | Side::East) { rows } else { cols };
    if sides < 4 {
        return None; // refused by validation
    }
    // A cell clear of each corner, so the hole's columns run on in the loop's order.
    let lo = (((o.centre_m - o.width_m / 2.0) / cell).round().max(1.0) as usize).min(sides - 3);
    let hi = (((o.centre_m + o.width_m / 2.0) / cell).round() as usize).clamp(lo + 1, sides - 2);
    let find = |k: usize| {
        ring.iter().position(|&(ij, _)| along(o.wall, ij, cols, rows) == Some(k)).expect("a point of the side")
    };
    let (a, b) = (find(lo).min(find(hi)), find(lo).max(find(hi)));
    let top = ((o.height_m / free.max(1e-6) * levels as f32).ceil() as usize).clamp(1, levels - 1);
    Some((a, b, top))
}
