//! What an erode job costs before it runs: memory from the grid (the erosion's arrays, then
//! the maps, the measures and the exports), work from cells × iterations.

use super::params::{BaseLevel, ErodeParams};
use super::METRICS_MAX_CELLS;
use crate::export::{heightfield_artifacts_peak_bytes, heightfield_lod_triangles, HEIGHTFIELD_LOD_BYTES_PER_TRIANGLE};
use crate::jobs::{Cost, CostBuilder, SimError};
use crate::terrain::TerrainLookup;

/// Cell updates a second at best: an iteration of the fluvial step counts 1 per cell, the
/// hillslope step 1 or 2. A 2-core machine measures about 1.5e7 (`cargo bench --bench erode`); the
/// margin is for machines several times faster, so only work that could not finish within the
/// time limit anywhere is refused.
const CELL_UPDATES_PER_SECOND: f64 = 1e8;
/// Request, result, sequence and small buffers of any job.
const BASE_BYTES: u64 = 256 << 10;
/// Bytes per cell while eroding: the input (f32), heights, the hillslope's two buffers (f64
/// each), and with the fluvial step Ψ, its solve buffer, area, sediment and losses (f64 each),
/// receivers, donors and the order (6), outlets and the deltas' visit stamps (5).
const THERMAL_BYTES_PER_CELL: u64 = 4 + 8 + 8 + 8 + 1;
const FLUVIAL_BYTES_PER_CELL: u64 = 5 * 8 + 6 + 5;
/// The flood's heap and closed set at its worst, before the erosion's arrays.
const FLOOD_BYTES_PER_CELL: u64 = 4 + 8 + 1 + 1 + 16;
/// Finishing: input and output (f32), the maps (three f32, two u8) and the route they read
/// (heights, area, sediment, zeros in f64 and 6 more), then the landform measures (D8: 57).
const FINISH_BYTES_PER_CELL: u64 = 8 + 14 + 4 * 8 + 6;
const METRICS_BYTES_PER_CELL: u64 = 57;
/// Decoding a painted map: the PNG's pixels as decoded (up to 8 bytes, RGBA16), as 16-bit grey or
/// 8-bit RGBA (4), and as f32 (4).
const MAP_BYTES_PER_PIXEL: u64 = 16;
/// A closed basin's bed (`base_level: none`) at its widest, a cell each: the set of cells seen
/// (a hash set, grown by doubling), the heap of its front and the cells taken.
const BASIN_BYTES_PER_CELL: u64 = 48 + 16 + 16;
/// Sequence bytes per iteration (a checksum and its JSON).
const ITERATION_BYTES: u64 = 64;

pub fn estimate(params: &ErodeParams, terrain: &dyn TerrainLookup) -> Result<Cost, SimError> {
    let extent =
        params.terrain.extent(terrain).map_err(|message| SimError::Invalid { field: "terrain".into(), message })?;
    let span = |n: u64| (n.max(1) - 1) as f64 * extent.cell_size_m;
    super::keep::check_jobs(&params.keep, terrain, span(extent.cols), span(extent.rows))?;
    let (cols, rows) = (extent.cols, extent.rows);
    let mut decoding = 0u64;
    let cells = cols.saturating_mul(rows);
    let fluvial = params.hydraulic.on().is_some();
    // Painted maps: checked against the terrain now; each is decoded (at most
    // MAP_BYTES_PER_PIXEL a pixel) and kept as an f32 a cell.
    let mut painted = 0u64;
    if let Some(h) = params.hydraulic.on() {
        for (field, map) in [("erodibility_map", &h.erodibility_map), ("uplift_map", &h.uplift_map)] {
            if let Some(map) = map {
                let pixels = map.check(&format!("hydraulic.{field}"), terrain, cols, rows, extent.cell_size_m)?;
                painted = painted.saturating_add(cells.saturating_mul(4));
                decoding = decoding.max(pixels.saturating_mul(MAP_BYTES_PER_PIXEL));
            }
        }
    }
    // The hillslope step: two implicit line solves and a few failure sweeps, about two cell
    // updates (or one with creep off).
    let hill = params.thermal.on().map_or(0, |t| if t.diffusivity_m2_per_yr > 0.0 { 8 } else { 4 });
    let iterations = u64::from(params.iterations);

    let eroding = cells.saturating_mul(THERMAL_BYTES_PER_CELL + if fluvial { FLUVIAL_BYTES_PER_CELL } else { 0 });
    let flood = if fluvial { cells.saturating_mul(FLOOD_BYTES_PER_CELL) } else { 0 };
    let metrics = if cells <= METRICS_MAX_CELLS { cells.saturating_mul(METRICS_BYTES_PER_CELL) } else { 0 };
    let finish = cells.saturating_mul(FINISH_BYTES_PER_CELL).max(metrics)
        + heightfield_artifacts_peak_bytes(cols, rows, params.tiles.is_some()).max(cells.saturating_mul(8));
    let mut cost = CostBuilder::new();
    cost.lods(heightfield_lod_triangles(cols, rows, params.tiles.is_some()), HEIGHTFIELD_LOD_BYTES_PER_TRIANGLE);
    cost.memory("", BASE_BYTES).memory("iterations", iterations * ITERATION_BYTES);
    let basin =
        if params.base_level == BaseLevel::None && fluvial { cells.saturating_mul(BASIN_BYTES_PER_CELL) } else { 0 };
    cost.memory("terrain", (eroding + painted + decoding + basin).max(flood).max(finish));
    // Per iteration: the fluvial step (1 per cell) and the hillslope step; loading,
    // measures and exports visit every cell a few dozen times.
    let per_iteration = cells.saturating_mul(4 * u64::from(fluvial) + hill) / 4;
    let work = per_iteration.saturating_mul(iterations).saturating_add(cells.saturating_mul(40));
    Ok(cost.work("iterations", work).build("cell updates", CELL_UPDATES_PER_SECOND))
}
