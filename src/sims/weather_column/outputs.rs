//! What a weathered rock becomes: a closed, smoothed, resistance-coloured mesh (`mesh.glb`), a
//! lit picture of it (`preview.png`), and the job's summary figures. Everything here depends
//! only on the rock's occupancy, the request and the seed, so a replay rebuilds it exactly.

use rayon::prelude::*;
use serde_json::{json, Value};

use super::grid::Grid;
use super::params::WeatherColumnParams;
use super::resistance::ResistanceField;
use super::weathering::History;
use crate::export::{mesh_glbs, render_png, Artifact, MeshSettings, View};
use crate::mesh::{extract_isosurface, smooth, MaterialKind, Mesh, ScalarField, Scene, SceneNode, Smoothing};
use crate::stop::{Stop, Stopped};

/// The isosurface between rock and air.
const ISO: f32 = 0.5;
/// Field values clamp to these on either side of `ISO`: every rock voxel's centre stays inside
/// the surface and every air voxel's outside, however the smoothing of the field below pulls.
const ROCK_MIN: f32 = 0.65;
const AIR_MAX: f32 = 0.35;

const PREVIEW: View = View { width_px: 1024, height_px: 768, azimuth_deg: 35.0, elevation_deg: 20.0 };
const SNAPSHOT: View = View { width_px: 256, height_px: 192, azimuth_deg: 35.0, elevation_deg: 20.0 };

/// Resistance colours from least to most resistant: pale siltstone, ochre, the red the paper's
/// viewer gave the most resistant rock.
const RAMP: [[f32; 3]; 3] = [[226.0, 208.0, 160.0], [204.0, 130.0, 64.0], [168.0, 42.0, 30.0]];

/// The surface of the voxels for which `rock(i)` holds, in metres (voxel `(x, y, z)` centred at
/// `((x, y, z) + 0.5) × voxel size`), wound outwards, closed. The field meshed is each voxel's
/// 3×3×3 rock fraction, clamped so that every voxel keeps its side of the surface: flat faces
/// sit on the voxel boundaries, edges and corners are cut, and no rock is lost or added. On
/// the ground the base is flat at y = 0 and stays there when smoothed.
pub fn rock_mesh(
    grid: &Grid,
    rock: &(dyn Fn(usize) -> bool + Sync),
    smoothing_iterations: u32,
    stop: Stop,
) -> Result<Mesh, Stopped> {
    let (px, py, pz) = (grid.nx + 2, grid.ny + 2, grid.nz + 2);
    let pplane = px * pz;
    let ground = !grid.floating as u8;
    // Rock count over each padded sample's 3×3 neighbourhood within its plane.
    let mut plane_sums = vec![0u8; pplane * py];
    plane_sums.par_chunks_mut(pplane).enumerate().for_each(|(py_i, out)| {
        let occ = |x: usize, z: usize| -> u8 {
            if py_i == 0 {
                return ground;
            }
            if x == 0 || z == 0 || x > grid.nx || z > grid.nz || py_i > grid.ny {
                return 0;
            }
            rock(grid.index(x - 1, py_i - 1, z - 1)) as u8
        };
        let mut row_sums = vec![0u8; pplane];
        for z in 0..pz {
            for x in 0..px {
                let left = if x > 0 { occ(x - 1, z) } else { 0 };
                let right = if x + 1 < px { occ(x + 1, z) } else { 0 };
                row_sums[x + px * z] = left + occ(x, z) + right;
            }
        }
        for z in 0..pz {
            for x in 0..px {
                let below = if z > 0 { row_sums[x + px * (z - 1)] } else { 0 };
                let above = if z + 1 < pz { row_sums[x + px * (z + 1)] } else { 0 };
                out[x + px * z] = below + row_sums[x + px * z] + above;
            }
        }
    });
    let mut values = vec![0f32; pplane * py];
    values.par_chunks_mut(pplane).enumerate().for_each(|(y, out)| {
        if y == 0 || y > grid.ny {
            return;
        }
        for z in 1..=grid.nz {
            for x in 1..=grid.nx {
                let p = x + px * z;
                let sum = plane_sums[(y - 1) * pplane + p] as u32
                    + plane_sums[y * pplane + p] as u32
                    + plane_sums[(y + 1) * pplane + p] as u32;
                let fraction = sum as f32 / 27.0;
                out[p] =
                    if rock(grid.index(x - 1, y - 1, z - 1)) { fraction.max(ROCK_MIN) } else { fraction.min(AIR_MAX) };
            }
        }
    });
    drop(plane_sums);
    stop.check()?;
    let s = grid.voxel_size_m;
    let field = ScalarField { dims: [px, py, pz], origin_m: [-0.5 * s; 3], spacing_m: s, values: &values };
    let mut mesh = extract_isosurface(&field, ISO, stop)?;
    drop(values);
    if !grid.floating {
        // Crossings towards the padding below the grid are the base: put them on the ground.
        for p in &mut mesh.positions {
            if p[1] < 0.4 * s {
                p[1] = 0.0;
            }
        }
    }
    if smoothing_iterations > 0 && !mesh.indices.is_empty() {
        let floor_y = (!grid.floating).then_some(0.0);
        smooth(&mut mesh, &Smoothing { iterations: smoothing_iterations, floor_y, ..Smoothing::default() }, stop)?;
    } else if !grid.floating {
        crate::mesh::recompute_normals(&mut mesh);
    }
    Ok(mesh)
}

/// Per-vertex sRGB colours by the resistance of the rock at each vertex.
/// `origin` (with gravity): each cell's voxel identity, so a fallen piece keeps its layers'
/// colours — each vertex reads the resistance where the rock next to it started.
pub fn colour_by_resistance(
    mesh: &mut Mesh,
    params: &WeatherColumnParams,
    grid: &Grid,
    resistance: &ResistanceField,
    origin: Option<&[u32]>,
) {
    let (lo, hi) = resistance.range();
    let span = hi - lo;
    let colours = mesh
        .positions
        .par_iter()
        .map(|p| {
            let p = &origin.map_or(*p, |o| started_at(grid, o, *p));
            let layer = layer_at_height(params, p[1]);
            let t = if span > 1e-6 { ((resistance.at_m(layer, *p) - lo) / span).clamp(0.0, 1.0) } else { 0.5 };
            let (a, b, f) = if t < 0.5 { (RAMP[0], RAMP[1], t * 2.0) } else { (RAMP[1], RAMP[2], t * 2.0 - 1.0) };
            let c = |k: usize| (a[k] + (b[k] - a[k]) * f).round() as u8;
            [c(0), c(1), c(2), 255]
        })
        .collect();
    mesh.colors = Some(colours);
}

/// Where the rock at `p` started: `p` lifted by as many cells as the voxel in the nearest rock
/// cell (its own or, in a fixed order, one of the 26 around it) has fallen.
fn started_at(grid: &Grid, origin: &[u32], p: [f32; 3]) -> [f32; 3] {
    let v = grid.voxel_size_m;
    let cell = |k: usize, n: usize| ((p[k] / v).floor().max(0.0) as i64).min(n as i64 - 1);
    let (cx, cy, cz) = (cell(0, grid.nx), cell(1, grid.ny), cell(2, grid.nz));
    for (dx, dy, dz) in std::iter::once((0, 0, 0))
        .chain((-1..=1).flat_map(|a| (-1..=1).flat_map(move |b| (-1..=1).map(move |c| (a, b, c)))))
    {
        let (x, y, z) = (cx + dx, cy + dy, cz + dz);
        if x < 0 || y < 0 || z < 0 || x >= grid.nx as i64 || y >= grid.ny as i64 || z >= grid.nz as i64 {
            continue;
        }
        let i = grid.index(x as usize, y as usize, z as usize);
        if origin[i] != super::gravity::EMPTY {
            let fell = grid.coords(origin[i] as usize).1 as f32 - y as f32;
            return [p[0], p[1] + fell * v, p[2]];
        }
    }
    p
}

fn layer_at_height(params: &WeatherColumnParams, y_m: f32) -> u8 {
    let last = params.layers.len() - 1;
    params.layers.iter().position(|l| y_m < l.top_m).unwrap_or(last) as u8
}

/// One node, `rock`; when nothing is left it has no triangles (and the glb no mesh).
fn scene(mesh: Mesh) -> Scene {
    Scene { nodes: vec![SceneNode::new("rock", mesh, MaterialKind::VertexColors)] }
}

/// Most voxels a live snapshot meshes. A 256-pixel picture shows no more, and meshing the
/// whole grid made snapshots dear: a 10 M-voxel column weathered to nothing ran 41 % longer
/// with its five snapshots (`cargo bench --bench job_path`).
const SNAPSHOT_MAX_VOXELS: usize = 1 << 19;

/// A small picture of the rock as it is now, for live progress (no smoothing, no colour). A
/// grid of more than [`SNAPSHOT_MAX_VOXELS`] is seen through blocks of f³ voxels, each rock
/// where any of its voxels is, so thin spires stay in the picture.
pub fn snapshot_png(grid: &Grid, state: &[u16], stop: Stop) -> Result<Vec<u8>, Stopped> {
    let rock = |i: usize| state[i] == super::grid::ROCK;
    let f = snapshot_block(grid);
    if f == 1 {
        return render_png(&scene(rock_mesh(grid, &rock, 0, stop)?), &SNAPSHOT, stop);
    }
    let coarse = Grid {
        nx: grid.nx.div_ceil(f),
        ny: grid.ny.div_ceil(f),
        nz: grid.nz.div_ceil(f),
        voxel_size_m: grid.voxel_size_m * f as f32,
        floating: grid.floating,
    };
    let mut blocks = vec![false; coarse.len()];
    blocks.par_chunks_mut(coarse.plane()).enumerate().for_each(|(cy, plane)| {
        for y in cy * f..((cy + 1) * f).min(grid.ny) {
            for z in 0..grid.nz {
                for x in 0..grid.nx {
                    if rock(grid.index(x, y, z)) {
                        plane[x / f + coarse.nx * (z / f)] = true;
                    }
                }
            }
        }
    });
    stop.check()?;
    render_png(&scene(rock_mesh(&coarse, &|i| blocks[i], 0, stop)?), &SNAPSHOT, stop)
}

/// The side of the blocks a snapshot sees the grid through: the smallest that keeps it to
/// [`SNAPSHOT_MAX_VOXELS`].
pub(super) fn snapshot_block(grid: &Grid) -> usize {
    (1..).find(|&f| grid.nx.div_ceil(f) * grid.ny.div_ceil(f) * grid.nz.div_ceil(f) <= SNAPSHOT_MAX_VOXELS).unwrap_or(1)
}

/// `mesh.glb` and `preview.png` of the rock in `state` (after however many steps it holds),
/// and the job's result figures; `origin` is each cell's voxel identity when anything fell,
/// `initial` how many voxels were rock at the start.
#[allow(clippy::too_many_arguments)]
pub fn build(
    params: &WeatherColumnParams,
    grid: &Grid,
    resistance: &ResistanceField,
    state: &[u16],
    origin: Option<&[u32]>,
    initial: u64,
    history: &History,
    stop: Stop,
    mesh_settings: &MeshSettings,
) -> Result<(Value, Vec<Artifact>), Stopped> {
    let rock = |i: usize| state[i] == super::grid::ROCK;
    let mut mesh = rock_mesh(grid, &rock, params.mesh.smoothing_iterations, stop)?;
    colour_by_resistance(&mut mesh, params, grid, resistance, origin);
    let closed = mesh.is_closed();
    let mesh_volume = mesh.signed_volume();
    let (vertices, triangles) = (mesh.vertex_count(), mesh.triangle_count());
    let scene = scene(mesh);
    stop.check()?;
    let (glbs, preview) = rayon::join(|| mesh_glbs(&scene, mesh_settings, stop), || render_png(&scene, &PREVIEW, stop));
    let (glbs, glb_figures) = glbs?;
    let preview = preview?;

    let remaining = state.par_iter().filter(|&&s| s == super::grid::ROCK).count() as u64;
    // The shortest decimal of the f32 edge (0.1, not 0.10000000149), cubed.
    let edge_m: f64 = grid.voxel_size_m.to_string().parse().unwrap_or(grid.voxel_size_m as f64);
    let voxel_m3 = edge_m.powi(3);
    let result = json!({
        "steps_run": history.steps(),
        "voxels": { "initial": initial, "removed": initial - remaining, "remaining": remaining },
        "volume_m3": { "initial": initial as f64 * voxel_m3, "final": remaining as f64 * voxel_m3 },
        "remaining_fraction": if initial == 0 { 0.0 } else { remaining as f64 / initial as f64 },
        "active_voxels": {
            "min": history.active_per_step.iter().min().copied().unwrap_or(0),
            "max": history.active_per_step.iter().max().copied().unwrap_or(0),
        },
        "mesh": { "vertices": vertices, "triangles": triangles, "closed": closed, "volume_m3": mesh_volume },
        "glb": glb_figures,
    });
    let mut glbs = glbs.into_iter();
    let mut artifacts =
        vec![glbs.next().expect("mesh.glb comes first"), Artifact::new("preview.png", "image/png", preview)];
    artifacts.extend(glbs);
    Ok((result, artifacts))
}
