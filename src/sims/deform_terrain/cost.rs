//! What a deform-terrain job costs before it runs. Memory: the grid's per-cell arrays (the
//! original and working heights, the fitness sums, each constraint's weights and targets), the
//! candidate table, the kernels, the recorded operations and the exports. Work: cell
//! evaluations — building the constraints, filling the candidate table, and per iteration a
//! scan of the table plus each applied deformation's window once per constraint.

use super::params::{Constraint, DeformTerrainParams, MaskShape};
use crate::export::{heightfield_artifacts_peak_bytes, heightfield_lod_triangles, HEIGHTFIELD_LOD_BYTES_PER_TRIANGLE};
use crate::jobs::{Cost, CostBuilder, SimError};
use crate::terrain::TerrainLookup;

/// Cell evaluations per second at best (with a margin for machines several times faster).
const EVALUATIONS_PER_SECOND: f64 = 2e9;
/// Bytes per cell every job holds: original and working heights (f64), the fitness sums and
/// the search's weighted residual, one iteration's changes of it (the batch's windows are
/// disjoint, so at most one value a cell), the interest and candidate marks, and transients
/// while fields are built.
const GRID_BYTES_PER_CELL: u64 = 76;
/// Bytes per cell the limits add when on, all of it between the search (whose table is freed
/// by then) and the exports (which start once it is freed again), so the peak holds the
/// largest of the three: each sample's band (two f64), the footprint and asked marks, the
/// earthwork cones while they are built (four f64), and the projection's envelopes (four
/// f64).
const LIMIT_BYTES_PER_CELL: u64 = 82;
/// Bytes per cell a constraint's field keeps (weights, targets, interest), and the largest
/// transient while one is built.
const FIELD_BYTES_PER_CELL: u64 = 25;
const BUILD_BYTES_PER_CELL: u64 = 40;
/// Bytes per candidate-table entry during the search: the entry (56), its key and its
/// confidence (8 each), whether its sum missed changes (1), its place in the per-row index
/// (8), the lists of improving, waiting and recomputed entries (8 each) and a recomputation's
/// result (32).
const TABLE_ENTRY_BYTES: u64 = 137;
/// Bytes per recorded operation: the operation, its history record and its lines of
/// `sequence.json` and `fitness.json` (each while growing), plus per constraint.
const OPERATION_BYTES: u64 = 700;
const OPERATION_BYTES_PER_CONSTRAINT: u64 = 60;
const BASE_BYTES: u64 = 2 << 20;
/// Entries per lattice vertex and radius, counting the quadtree's refinement around
/// constrained regions.
const ENTRIES_PER_LATTICE_RADIUS: u64 = 3;
const MAX_TABLE_ENTRIES: u64 = super::MAX_TABLE_ENTRIES as u64;

pub fn estimate(params: &DeformTerrainParams, terrain: &dyn TerrainLookup) -> Result<Cost, SimError> {
    let extent =
        params.terrain.extent(terrain).map_err(|message| SimError::Invalid { field: "terrain".into(), message })?;
    let (cols, rows) = (extent.cols, extent.rows);
    let cells = extent.cells();
    let k = params.constraints.len() as u64;

    let mut field_cells = 0u64;
    let mut build_work = 0u64;
    for c in &params.constraints {
        let (kept, work) = match c {
            Constraint::Preserve(_) | Constraint::Points(_) => (FIELD_BYTES_PER_CELL, 5),
            Constraint::Terraces(t) => {
                (FIELD_BYTES_PER_CELL + 2, 5 + t.regions.iter().map(|r| r.polygon_m.len()).sum::<usize>() as u64)
            }
            Constraint::MatchHeightmap(_) => (FIELD_BYTES_PER_CELL + 8, 10),
            Constraint::Road(r) => (FIELD_BYTES_PER_CELL + 16, 5 + 4 * r.path.len() as u64),
            Constraint::EdgeMatch(_) => (FIELD_BYTES_PER_CELL + 16, 10),
            Constraint::Tileable(_) => (9, 2),
            Constraint::ShapeMask(m) => match &m.mask {
                MaskShape::Image(_) => (6, 10),
                MaskShape::PolygonsM(p) => (2, 5 + p.iter().map(Vec::len).sum::<usize>() as u64),
            },
        };
        field_cells += kept;
        build_work = build_work.saturating_add(work.saturating_mul(cells));
    }

    let shorter = cols.min(rows).max(1);
    let coarse = params.coarse_spacing(shorter as usize) as u64;
    let radii = params.radii_cells(shorter as usize);
    let lattice = (cols.div_ceil(coarse) + 1) * (rows.div_ceil(coarse) + 1);
    // The coarse lattice alone, every vertex with every radius, is a floor on the table: over
    // the cap, the run would stop at once, so the request is refused now.
    if lattice.saturating_mul(radii.len() as u64) > MAX_TABLE_ENTRIES {
        return Err(SimError::Invalid {
            field: "coarse_spacing_cells".into(),
            message: format!(
                "a lattice of {lattice} vertices with {} radii is more than the cap of {MAX_TABLE_ENTRIES} candidate \
                 deformations; raise coarse_spacing_cells or use fewer radii",
                radii.len()
            ),
        });
    }
    let entries = (lattice * radii.len() as u64 * ENTRIES_PER_LATTICE_RADIUS).min(MAX_TABLE_ENTRIES);
    let kernel_bytes: u64 = radii.iter().map(|&r| 8 * (2 * r as u64 + 1).pow(2)).sum();
    let operations = u64::from(params.max_iterations) * u64::from(params.batch);
    let per_operation = OPERATION_BYTES + OPERATION_BYTES_PER_CONSTRAINT * k;

    let limited = params.limited();
    let grid = GRID_BYTES_PER_CELL * cells;
    let fields = field_cells * cells + BUILD_BYTES_PER_CELL * cells;
    let limit_bytes = if limited { LIMIT_BYTES_PER_CELL * cells } else { 0 };
    let search_bytes = TABLE_ENTRY_BYTES * entries + 24 * lattice + kernel_bytes;
    let exports = heightfield_artifacts_peak_bytes(cols, rows, params.tiles.is_some()).max(limit_bytes);
    let mut cost = CostBuilder::new();
    cost.lods(heightfield_lod_triangles(cols, rows, params.tiles.is_some()), HEIGHTFIELD_LOD_BYTES_PER_TRIANGLE);
    cost.memory("", BASE_BYTES)
        .memory("terrain", grid)
        .memory("constraints", fields)
        .memory("coarse_spacing_cells", search_bytes)
        .memory("max_iterations", per_operation * operations)
        .memory("terrain", exports);

    // Each iteration scans the table and applies up to `batch` deformations, each touching its
    // kernel window once per constraint (and its tileable partner).
    let r_max = radii.last().copied().unwrap_or(1) as u64;
    // A mask's one-sided penalty is not quadratic: a window is visited once per sampled
    // displacement, and once more, rather than through one running sum. (The limits are the
    // projection's, after the search: `limit_work`.)
    let masked = params.constraints.iter().any(|c| matches!(c, Constraint::ShapeMask(_)));
    let visits = if masked { u64::from(params.amplitudes) + 1 } else { 1 };
    let window = (2 * r_max + 1).pow(2) * visits;
    let first_fill = entries * window.min(625 * visits);
    let per_iteration = entries + u64::from(params.batch) * (2 * k + 2) * window;
    let search_work = u64::from(params.max_iterations).saturating_mul(per_iteration);
    let limit_work = if limited { 60 * cells } else { 0 };
    let work = build_work
        .saturating_add(first_fill)
        .saturating_add(search_work)
        .saturating_add(40 * cells)
        .saturating_add(limit_work);
    Ok(cost.work("max_iterations", work).build("cell evaluations", EVALUATIONS_PER_SECOND))
}
