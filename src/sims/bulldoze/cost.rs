//! What a bulldoze job costs before it runs: memory from the grid (source, working copy, the
//! grid before the edit, the exports) and the recorded steps; work from the samples each
//! operation's bounding box covers, as the rasteriser visits them.

use super::apply::{cells_within, Bounds};
use super::params::{resampled_dimensions, BulldozeParams, Operation, Window};
use super::primitives::shape_bounds;
use crate::export::{heightfield_artifacts_peak_bytes, heightfield_lod_triangles, HEIGHTFIELD_LOD_BYTES_PER_TRIANGLE};
use crate::jobs::{Cost, CostBuilder, SimError};
use crate::terrain::TerrainLookup;

/// Samples combined per second at best (a 2-core machine measures about a tenth of this; the
/// margin is for machines several times faster), so only work that could not finish within
/// the time limit anywhere is refused.
const SAMPLES_PER_SECOND: f64 = 1e9;
/// Bytes a recorded step holds: the step, its copy in the outcome, and its pretty JSON twice
/// (serialised, then growing), plus per profile point.
const STEP_BYTES: u64 = 2_000;
const STEP_PROFILE_POINT_BYTES: u64 = 200;
/// Request, result and small buffers of any job.
const BASE_BYTES: u64 = 256 << 10;

pub fn estimate(params: &BulldozeParams, terrain: &dyn TerrainLookup) -> Result<Cost, SimError> {
    let extent =
        params.terrain.extent(terrain).map_err(|message| SimError::Invalid { field: "terrain".into(), message })?;
    let source = extent.cells();
    let (cols, rows) = match params.resolution {
        Some(res) => resampled_dimensions(extent.cols, extent.rows, extent.cell_size_m as f32, res),
        None => (extent.cols, extent.rows),
    };
    // A refine resamples to a finer grid: the finest bounds the grid's memory and every
    // operation's samples.
    let finest = params
        .operations
        .iter()
        .filter_map(|op| match op {
            Operation::Refine(r) if r.resolution.is_finite() && r.resolution > 0.0 => Some(r.resolution),
            _ => None,
        })
        .fold(None, |a: Option<f32>, r| Some(a.map_or(r, |a| a.min(r))));
    let (cols, rows) = match finest {
        Some(res) => {
            let (c, r) = resampled_dimensions(extent.cols, extent.rows, extent.cell_size_m as f32, res);
            (c.max(cols), r.max(rows))
        }
        None => (cols, rows),
    };
    let cells = cols.saturating_mul(rows);
    let cell_m = params.resolution.map_or(extent.cell_size_m, f64::from).min(finest.map_or(f64::INFINITY, f64::from));
    let grid_field = if params.resolution.is_some() { "resolution" } else { "terrain" };

    let mut steps_bytes = 0u64;
    let mut work = 0u64;
    let clip = |b: Bounds| covered_samples(b, params.window.as_ref(), cell_m, cols, rows);
    for op in &params.operations {
        match op {
            Operation::Primitive(p) => {
                steps_bytes += STEP_BYTES;
                work = work.saturating_add(clip(shape_bounds(&p.shape)));
            }
            Operation::Local(l) => steps_bytes += STEP_BYTES + 100 * l.vertices.len() as u64,
            // The resampling visits every sample of the finer grid.
            Operation::Refine(_) => {
                steps_bytes += STEP_BYTES;
                work = work.saturating_add(cells);
            }
            // Every sample once, as the grid's own work counts it.
            Operation::Global(_) => {
                steps_bytes += STEP_BYTES;
                work = work.saturating_add(cells);
            }
            Operation::Pass(pass) => {
                let b = &pass.blade;
                // The blade's farthest reach from the path: its half width turned by its angle.
                let reach = (b.width_m as f64 / 2.0) / (b.angle_deg as f64).to_radians().cos().max(0.1)
                    + (b.offset_m as f64).abs();
                let moves = pass.vertices().saturating_sub(1);
                // Keyframes record a second profile per move (a blend holds both's points).
                let points = b.profile.len() + pass.keyframes.iter().map(|k| k.profile.len()).max().unwrap_or(0);
                steps_bytes = steps_bytes
                    .saturating_add(moves.saturating_mul(STEP_BYTES + 2 * STEP_PROFILE_POINT_BYTES * points as u64));
                if pass.base == super::params::PathBase::Ground {
                    // The pass-start grid the base reads.
                    steps_bytes += 4 * cells;
                }
                if let Some(c) = &pass.contour {
                    // Unknown until traced: each move sweeps at most spacing + 2 reach square
                    // (clipped to the grid), and tracing visits every sample once.
                    let side = c.spacing_m as f64 + 2.0 * reach;
                    let per_move = ((side / cell_m).ceil() as u64 + 1).pow(2).min(cells);
                    work = work.saturating_add(cells).saturating_add(moves.saturating_mul(2 * per_move));
                }
                for pair in pass.path.windows(2) {
                    let segment =
                        Bounds::around([(pair[0].x as f64, pair[0].z as f64), (pair[1].x as f64, pair[1].z as f64)]);
                    let reached = Bounds {
                        min_x: segment.min_x - reach,
                        min_z: segment.min_z - reach,
                        max_x: segment.max_x + reach,
                        max_z: segment.max_z + reach,
                    };
                    // A move after a bend also sweeps its pivot: about twice the cost per sample.
                    work = work.saturating_add(2 * clip(reached));
                }
            }
        }
    }
    let load = 8 * source;
    let resample = 4 * source + 4 * cells;
    // The edited grid and the grid before the edit, the exports, the steps.
    let finish = 8 * cells + heightfield_artifacts_peak_bytes(cols, rows, params.tiles.is_some());
    let mut cost = CostBuilder::new();
    cost.lods(heightfield_lod_triangles(cols, rows, params.tiles.is_some()), HEIGHTFIELD_LOD_BYTES_PER_TRIANGLE);
    cost.memory("", BASE_BYTES).memory("operations", steps_bytes);
    if load.max(resample) > finish {
        cost.memory("terrain", load.max(resample));
    } else {
        cost.memory(grid_field, finish);
    }
    // Loading, resampling, checks and exports visit every sample a few dozen times.
    let grid_work = 40 * cells + 10 * source;
    let (field, total) =
        if work > grid_work { ("operations", work + grid_work) } else { (grid_field, work + grid_work) };
    Ok(cost.work(field, total).build("samples", SAMPLES_PER_SECOND))
}

/// Samples of a `cols × rows` grid `cell_m` apart inside `b` (and the window), as the
/// rasteriser visits them.
fn covered_samples(b: Bounds, window: Option<&Window>, cell_m: f64, cols: u64, rows: u64) -> u64 {
    cells_within(cols as usize, rows as usize, cell_m, b, window)
        .map_or(0, |((c0, c1), (r0, r1))| ((c1 - c0 + 1) * (r1 - r0 + 1)) as u64)
}
