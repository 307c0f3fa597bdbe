//! What a carve-coast job costs before it runs. Memory: the field sampled over the whole
//! meshing box (four bytes a sample, plus the inside mask and flood bits), the spheres and
//! their record, and the closed mesh with its glb and render copies — sized from the box's
//! top surface, its bottom and its walls. Work: implicit-function evaluations.

use super::params::{estimate_voxels, CarveCoastParams, MAX_SPHERES};
use crate::jobs::{Cost, CostBuilder, SimError};
use crate::terrain::TerrainLookup;

/// Evaluations per second at best (with a margin for machines several times faster).
const EVALUATIONS_PER_SECOND: f64 = 4e9;
/// Bytes per box sample: the field, the meshing mask and flood bits.
const SAMPLE_BYTES: u64 = 6;
/// Bytes per box sample of the field's values, freed once the surface is meshed and its caves
/// counted, before the levels of detail are made.
const FIELD_VALUE_BYTES: u64 = 4;
/// Bytes per mesh triangle at the final build: the mesh, its glb (twice) and the render's copy.
const TRIANGLE_BYTES: u64 = 140;
/// Triangles per surface cube crossed: marching tetrahedra make 8 on flat ground, up to 12.
const TRIANGLES_PER_CUBE: f64 = 10.0;
/// Bytes per sphere: the sphere, its bin entries and its line of `sequence.json`.
const SPHERE_BYTES: u64 = 360;
const BASE_BYTES: u64 = 4 << 20;
/// Bytes per column of the top surface for its maps, all written at once: `heightmap.r16`, the
/// normal map's RGB and the splat map's RGBA with their PNGs, and the splat material.
const MAP_BYTES_PER_COLUMN: u64 = 24;
/// Bytes levels of detail add at the peak per triangle: measured 23–109 with the search grid the
/// deviation used before; with its hierarchy, and the first level made once (its normals
/// weighed) instead of twice, 0 on small-island-one-pass, whose levels fit under the carve's
/// own peak in the field's freed values, and 6–18 on the islands of 1.4–3.6 M triangles
/// (`LANDFORM_LEVELS_UP_TO=4000000 cargo test --test cost_estimates carve_coast`; the test
/// measures only the small one by default). The hierarchy and meshoptimizer's arrays take
/// about 70 B a triangle while both are alive, mostly in the field's place; at 78 the small
/// island's estimate was 3.1 × its peak.
const LOD_BYTES_PER_TRIANGLE: u64 = 40;

pub fn estimate(params: &CarveCoastParams, terrain: &dyn TerrainLookup) -> Result<Cost, SimError> {
    let extent =
        params.terrain.extent(terrain).map_err(|message| SimError::Invalid { field: "terrain".into(), message })?;
    let cell = extent.cell_size_m;
    let voxel = params.voxel_size_m.map_or(cell, f64::from);
    let span = extent.z_span_m;
    let e = &params.erosion;
    let voxels = estimate_voxels(
        extent.cols,
        extent.rows,
        cell as f32,
        span as f32,
        voxel as f32,
        params.max_radius(),
        params.warp_amplitude(),
    );
    let side = |n: u64| ((n.saturating_sub(1)) as f64 * cell / voxel).floor() + 1.0;
    let (nx, nz) = (side(extent.cols), side(extent.rows));
    let columns = nx * nz;
    let width_m = (nx.max(nz) - 1.0).max(1.0) * voxel;
    // The top surface (steeper ground crosses more cubes), the flat bottom, and the walls up
    // to the rock's mean height.
    let steepness = (span / width_m).min(span / cell.max(1e-6));
    let cubes = columns * (2.0 + steepness) + 2.0 * (nx + nz) * (span / voxel / 2.0 + 4.0);
    let triangles = (TRIANGLES_PER_CUBE * cubes) as u64;

    // Seeds: columns whose surface crosses the seed band, times the acceptance chance; each
    // grows a sphere and then up to steps × spheres more.
    let band =
        ((e.seed_elevation_range[1] - e.seed_elevation_range[0]) as f64 + 2.0 * e.radius_range[1] as f64).max(0.0);
    let crossing = if span > 0.0 { (band / span).min(1.0) } else { 1.0 };
    let seeds = columns * crossing * e.seed_acceptance_probability as f64 * params.passes as f64;
    let mean = |r: [u32; 2]| (r[0] + r[1]) as f64 / 2.0;
    let per_seed = 1.0 + mean(e.growth_step_range) * mean(e.growth_sphere_range);
    let spheres = (seeds * per_seed).min(MAX_SPHERES as f64) as u64;

    let mut cost = CostBuilder::new();
    cost.lods(triangles, LOD_BYTES_PER_TRIANGLE).lods_reuse(FIELD_VALUE_BYTES.saturating_mul(voxels));
    cost.memory("", BASE_BYTES)
        .memory("terrain", 4 * extent.cells())
        .memory("voxel_size_m", SAMPLE_BYTES.saturating_mul(voxels))
        .memory("erosion", SPHERE_BYTES * spheres)
        .memory("voxel_size_m", MAP_BYTES_PER_COLUMN * columns as u64)
        .memory("terrain", TRIANGLE_BYTES.saturating_mul(triangles));

    // Seed scans step through the band on every column within reach of it, each pass;
    // sampling evaluates the box (the narrow band fully, the rest cheaply). Each evaluation
    // visits the spheres of its bin: bins are twice the largest radius across, and the spheres
    // line a coast that crosses about four bins per bin along the side (each sphere in up to
    // four), so only the columns in those bins pay for them.
    let step = voxel.min(cell).max(1e-9);
    let steps_per_column = (band / step).ceil();
    let bin_m = (2.0 * e.radius_range[1] as f64).max(width_m / 1024.0);
    let coast_bins = (4.0 * width_m / bin_m).max(1.0);
    let per_bin = 1.0 + (4.0 * spheres as f64 / coast_bins).min(spheres as f64);
    let coast_columns = (coast_bins * (bin_m / voxel).powi(2)).min(columns);
    let scan = params.passes as f64 * steps_per_column * (columns * crossing + coast_columns * per_bin);
    let band_samples = voxels as f64 / 4.0;
    let carved_samples = coast_columns * (band / voxel + 8.0) * per_bin;
    let work = (scan + band_samples + carved_samples + triangles as f64 * 20.0).min(u64::MAX as f64 / 2.0) as u64;
    let field = if scan > voxels as f64 { "erosion.seed_elevation_range" } else { "voxel_size_m" };
    Ok(cost.work(field, work).build("evaluations", EVALUATIONS_PER_SECOND))
}
