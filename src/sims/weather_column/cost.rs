//! What a weather-column job costs before it runs. Memory: two bytes of state and two of air
//! count per voxel, the transients of set-up and of the meshing field, the active set, and the
//! mesh with its smoothing, glb and render copies — the mesh sized from the column's surface
//! (its footprint and perimeter times its height). Work: voxel and bubble-cell visits.

use super::grid::Grid;
use super::params::{Profile, Update, WeatherColumnParams};
use super::shape;
use super::weathering::STALE_EVENTS_PER_LIVE;
use crate::jobs::{Cost, CostBuilder, SimError};
use crate::terrain::TerrainLookup;

/// Visits per second at best (with a margin for machines several times faster).
const VISITS_PER_SECOND: f64 = 2e9;
/// Mesh vertices per exposed voxel face: marching tetrahedra put about 4 on a flat face, more
/// where weathering roughens it.
const VERTICES_PER_FACE: f64 = 4.5;
/// Bytes per mesh vertex at the final build: the mesh, its glb (twice) and the render's copy.
const BYTES_PER_VERTEX: u64 = 220;
/// Bytes per active voxel (synchronized: the set and its next version; event-based: its map).
const ACTIVE_BYTES: u64 = 52;
const EVENT_ACTIVE_BYTES: u64 = 94;
const EVENT_BYTES: u64 = 32;
const BASE_BYTES: u64 = 4 << 20;
/// Bytes levels of detail add at the peak per triangle (measured 0–31 on the examples since
/// the deviation's hierarchy replaced its search grid, 19–86 before).
const LOD_BYTES_PER_TRIANGLE: u64 = 60;
/// Footprints of more cells than this are sized on a coarser grid and scaled: the estimate
/// runs at submission, so its own cost (cells × polygon points) stays small.
const FOOTPRINT_SAMPLE_CELLS: u64 = 256 * 256;

pub fn estimate(params: &WeatherColumnParams, terrain: &dyn TerrainLookup) -> Result<Cost, SimError> {
    let (nx, ny, nz) = (params.grid.x as u64, params.grid.y as u64, params.grid.z as u64);
    let n = params.grid.voxels();
    let np = (nx + 2) * (ny + 2) * (nz + 2);
    let height = params.column_voxels() as u64;
    let (area, perimeter) = footprint_size(params, terrain)?;
    // Exposed faces: top and bottom of the footprint, and its sides up the column.
    let faces = 2.0 * area + perimeter * height as f64;
    let vertices = (VERTICES_PER_FACE * faces) as u64;
    let reach = params.layers.iter().map(|l| l.bubble.radii().iter().fold(1f32, |a, &b| a.max(b))).fold(1f32, f32::max);
    let bubble_cells = (4.0 / 3.0 * std::f64::consts::PI * (reach as f64).powi(3)).ceil() as u64;
    let rock = (area as u64).saturating_mul(height);
    // Active voxels: a shell as thick as the bubble's reach under the surface.
    let active = ((faces * reach as f64) as u64).min(rock);
    let removed = ((1.0 - params.stop_at_fraction as f64) * rock as f64) as u64;

    let active_bytes = match params.update {
        Update::Synchronized => ACTIVE_BYTES * active,
        // The heap is compacted once its stale events outnumber the live ones four to one.
        Update::EventBased => {
            EVENT_ACTIVE_BYTES * active + EVENT_BYTES * (STALE_EVENTS_PER_LIVE as u64 + 1) * active + EVENT_BYTES * 1024
        }
    };
    let mut cost = CostBuilder::new();
    // A closed surface has about two triangles a vertex.
    cost.lods(2 * vertices, LOD_BYTES_PER_TRIANGLE);
    cost.memory("", BASE_BYTES)
        .memory("grid", 4 * n + (5 * np).max(7 * n))
        .memory("update", active_bytes)
        .memory("column", BYTES_PER_VERTEX * vertices);
    // Gravity: each cell's voxel identity (4 bytes), the per-identity record and the grounded
    // marks (2 each), and the record's copy for the sequence.
    if params.gravity {
        cost.memory("gravity", 10 * n);
    }

    let update_visits = match params.update {
        Update::Synchronized => 1,
        Update::EventBased => 16,
    };
    let smoothing = params.mesh.smoothing_iterations as u64;
    let work = n * (6 + 4 * reach as u64)
        + active * bubble_cells
        + removed * bubble_cells * update_visits
        + 8 * np
        + vertices * (60 + 14 * smoothing)
        // Gravity: the searches to the ground from beside each removal (a column's height at
        // most, lowest first), and the air counted afresh after a fall (a few falls).
        + if params.gravity { removed * 6 * height + 4 * n * (6 + 4 * reach as u64) } else { 0 };
    let field = if removed * bubble_cells > n * 8 { "stop_at_fraction" } else { "grid" };
    Ok(cost.work(field, work).build("voxel visits", VISITS_PER_SECOND))
}

/// The column's footprint in voxel cells (area) and its perimeter in voxel edges.
fn footprint_size(params: &WeatherColumnParams, terrain: &dyn TerrainLookup) -> Result<(f64, f64), SimError> {
    let joint_map = match &params.column.profile {
        Profile::JointMap(image) => Some(image.bytes(terrain)?),
        _ => None,
    };
    let (nx, nz) = (params.grid.x as u64, params.grid.z as u64);
    // Sample a large footprint on a coarser grid of the same extent.
    let f = ((nx * nz) as f64 / FOOTPRINT_SAMPLE_CELLS as f64).sqrt().max(1.0);
    let mut coarse = params.clone();
    coarse.grid.x = ((nx as f64 / f).ceil() as u32).max(1);
    coarse.grid.z = ((nz as f64 / f).ceil() as u32).max(1);
    coarse.voxel_size_m = params.voxel_size_m * (nx as f32 / coarse.grid.x as f32);
    let grid = Grid::new(&coarse);
    let cells = match shape::footprint(&coarse, &grid, joint_map.as_deref()) {
        Ok(cells) => cells,
        // A footprint smaller than a coarse cell: the run finds it on the full grid.
        Err(_) if f > 1.0 => return Ok((f * f, 4.0 * f)),
        Err(e) => return Err(e),
    };
    let (cx, cz) = (grid.nx, grid.nz);
    let rock = |x: i64, z: i64| {
        x >= 0 && z >= 0 && (x as usize) < cx && (z as usize) < cz && cells[x as usize + cx * z as usize]
    };
    let mut area = 0u64;
    let mut edges = 0u64;
    for z in 0..cz as i64 {
        for x in 0..cx as i64 {
            if rock(x, z) {
                area += 1;
                edges +=
                    [(1, 0), (-1, 0), (0, 1), (0, -1)].iter().filter(|(dx, dz)| !rock(x + dx, z + dz)).count() as u64;
            }
        }
    }
    let scale = nx as f64 / cx as f64;
    Ok((area as f64 * scale * scale, edges as f64 * scale))
}
