//! What a grow-cave job costs before it runs. Memory: the recorded rings, the roof and floor
//! grids and their meshes, and the speleothem tubes with their glb and render copies (each
//! tube has its recorded rings and at most three more at its end, `segments` vertices a
//! ring). Work: rings grown, chamber samples generated, tube vertices written and rendered.

use super::chamber::surface_grid;
use super::params::{Conditions, GrowCaveParams, Pluviometric, Sites};
use crate::jobs::{Cost, CostBuilder, SimError};
use crate::terrain::TerrainLookup;

/// Work units (a ring grown, a sample generated, a vertex written) per second at best.
const UNITS_PER_SECOND: f64 = 1e9;
/// Bytes per ring recorded: the ring, its copies in the sequence and its pretty JSON.
const RING_BYTES: u64 = 600;
const SITE_BYTES: u64 = 450;
/// Bytes per speleothem vertex at the final build: the tube, its glb (twice) and the render's
/// copy, with the slack of growing buffers.
const TUBE_VERTEX_BYTES: u64 = 140;
/// Bytes per roof or floor sample: the grid, its mesh and their copies in glb and render.
const SURFACE_SAMPLE_BYTES: u64 = 100;
/// Bytes per glb node (a speleothem): its JSON and glTF structures.
const NODE_BYTES: u64 = 10_000;
/// The job's fixed part, with the 32-bit glb of a small cave (the default form since issue 31).
const BASE_BYTES: u64 = 7 << 20;
/// What levels of detail add at the peak, in percent of the rest of the estimate: the levels
/// of a cave's pieces are kept until written, smaller copies of what the rest holds (measured
/// 0–17 % of it on the examples since the chamber shell reduces; 26 % while it stayed whole,
/// when 27 put chamber-with-entrance's estimate at 3.01 × its peak). A share of the estimate
/// rather than bytes per triangle, because this estimate overcounts the crowded caves'
/// triangles and the levels' bytes follow the real ones.
const LOD_PERCENT_OF_REST: u64 = 18;
/// Caves of more sites than this are sized from their first passes grown for real (see
/// [`probe`]); fewer sites are sized from the parameters alone, within 3 × of their peak.
const PROBE_FROM_SITES: u64 = 256;
/// Passes the probe grows.
const PROBE_PASSES: u32 = 4;

pub fn estimate(params: &GrowCaveParams, seed: u64, _terrain: &dyn TerrainLookup) -> Result<Cost, SimError> {
    let sites = match &params.sites {
        Sites::Explicit(list) => list.len() as u64,
        Sites::Scatter { count, .. } => u64::from(*count),
    };
    let segments = u64::from(params.segments);
    // Speleothems per site: level 1 grows stalactites only, level 2 (or random) both.
    let tubes_of = |c: &Conditions| match c.pluviometric_index {
        Pluviometric::Level0 => 0,
        Pluviometric::Level1 => 1,
        Pluviometric::Level2 | Pluviometric::Random => 2,
    };
    let tubes: u64 = match &params.sites {
        Sites::Explicit(list) => {
            list.iter().map(|s| tubes_of(s.conditions.as_ref().unwrap_or(&params.conditions))).sum()
        }
        Sites::Scatter { count, .. } => u64::from(*count) * tubes_of(&params.conditions),
    };
    // Every ring grows at least half a height step (Table 2's multiples are at least 1), and
    // a site's speleothems together span at most the chamber's height (manual rings aside).
    let rings = u64::from(params.rings);
    let height_bound = if params.manual.is_some() || params.height_step_m <= 0.0 {
        u64::MAX
    } else {
        (params.chamber.height_m / (0.5 * params.height_step_m)).ceil() as u64
    };
    // Per speleothem: its rings, an anchor and a tip.
    let recorded = (tubes * rings).min(sites.saturating_mul(height_bound).saturating_add(tubes));
    // A straw's canal doubles its stalactite's rings (every site with a tube has a stalactite).
    let stalactites = match &params.sites {
        Sites::Explicit(list) => {
            list.iter().filter(|s| tubes_of(s.conditions.as_ref().unwrap_or(&params.conditions)) > 0).count() as u64
        }
        Sites::Scatter { count, .. } => u64::from(*count) * tubes_of(&params.conditions).min(1),
    };
    // Crowded sites merge at the start or stop within a few rings, which the parameters cannot
    // tell: the first passes, grown as the run grows them, bound what can follow.
    let (recorded, tubes, stalactites, pieces) = match (sites > PROBE_FROM_SITES).then(|| probe(params, seed)).flatten()
    {
        Some(p) => (recorded.min(p.recorded), tubes.min(p.tubes), stalactites.min(p.stalactites), p.sites),
        None => (recorded, tubes, stalactites, sites),
    };
    let canal = if params.canal_radius_m > 0.0 { stalactites } else { 0 };
    let tube_vertices = (recorded + 3 * tubes) * segments * (tubes + canal) / tubes.max(1);
    let (cols, rows, _) = surface_grid(&params.chamber);
    // The mesh of a surface keeps at most 1025 samples a side; the grids here have at most 513.
    // Roof, floor and walls (at most 64 levels round the edge).
    let surface = 2 * (cols * rows) as u64 + 64 * 2 * (cols + rows) as u64;
    let mut cost = CostBuilder::new();
    // Tubes and surfaces have about two triangles a vertex (or sample).
    cost.memory("", BASE_BYTES)
        .memory("rings", RING_BYTES * recorded + SITE_BYTES * sites)
        .memory("chamber.samples", SURFACE_SAMPLE_BYTES * surface)
        .memory("sites", TUBE_VERTEX_BYTES * tube_vertices + NODE_BYTES * pieces);
    let scatter = match &params.sites {
        // Placing each site against those near it: at least one try a site.
        Sites::Scatter { .. } => sites,
        Sites::Explicit(_) => 0,
    };
    // Keeping sites apart: every site against those near it at the start, then each ring's
    // capsules (two) against those sharing its bins, once when grown and once for the
    // coating's clearances — at the least, capsules spread evenly over the bins.
    let c = &params.chamber;
    let cell = super::neighbours::bin_size(params).max(c.width_m.max(c.depth_m) / 128.0).max(1e-6);
    let bins = ((c.width_m / cell).ceil().clamp(1.0, 128.0) * (c.depth_m / cell).ceil().clamp(1.0, 128.0)) as u64;
    let capsules = 2 * recorded;
    let per_bin = (capsules / bins.max(1)).max(1);
    let neighbours = sites + 2 * capsules * per_bin;
    // Surfaces are generated for each live snapshot and the final scene (about three times).
    let work = recorded * segments + scatter + neighbours + 3 * surface * 50 + 3 * tube_vertices * 20;
    let field = if tube_vertices * 60 > surface * 150 { "rings" } else { "chamber.samples" };
    // Tubes and surfaces have about two triangles a vertex (or sample).
    cost.work(field, work).lods(2 * (tube_vertices + surface), 0);
    let mut cost = cost.build("units", UNITS_PER_SECOND);
    cost.lod_bytes = cost.memory_bytes / 100 * LOD_PERCENT_OF_REST;
    Ok(cost)
}

/// A bound on a cave's growth from its first passes.
struct Probed {
    /// Rings recorded at most: those of the first passes, and one a pass for every speleothem
    /// still growing after them.
    recorded: u64,
    /// Speleothems that have rings or may still get them.
    tubes: u64,
    stalactites: u64,
    /// Sites that grow anything (a piece of the scene each).
    sites: u64,
}

/// Grow the first [`PROBE_PASSES`] passes as the run would (the same seed, the same sites, the
/// same merges and clearances): a merged site never grows, and a speleothem that stopped never
/// starts again, so what is still growing then bounds the rest. `None` when the probe fails
/// (the run would report it).
fn probe(params: &GrowCaveParams, seed: u64) -> Option<Probed> {
    let passes = PROBE_PASSES.min(params.rings);
    let sequence = super::grow_passes(params, seed, passes, &mut |_, _| Ok(())).ok()?;
    let left = u64::from(params.rings - passes);
    let mut probed = Probed { recorded: 0, tubes: 0, stalactites: 0, sites: 0 };
    for g in sequence.sites.iter().map(|s| &s.growth).filter(|g| g.merged_into.is_none()) {
        let vertical = g.column_at.is_none();
        let more = [vertical && !g.stalactite_done, vertical && !g.stalagmite_done];
        let has = [!g.stalactite.is_empty() || more[0], !g.stalagmite.is_empty() || more[1]];
        probed.recorded +=
            (g.stalactite.len() + g.stalagmite.len()) as u64 + left * more.iter().filter(|&&m| m).count() as u64;
        probed.tubes += has.iter().filter(|&&h| h).count() as u64;
        probed.stalactites += u64::from(has[0]);
        probed.sites += u64::from(has[0] || has[1]);
    }
    Some(probed)
}
