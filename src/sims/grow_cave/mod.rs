//! `grow-cave`: stalactites, stalagmites and columns grown ring by ring in a cave chamber
//! (seed 001, Tortelli & Walter). The paper grows them on the GPU's geometry shader, one pass
//! of the pipeline per ring; here each pass grows every speleothem's next ring on the CPU in
//! parallel, each drip site drawing from its own random stream.

mod chamber;
mod chamber_mesh;
mod cost;
mod growth;
mod neighbours;
mod outputs;
pub mod params;
mod profile;
mod sequence;
mod speleothem_mesh;

#[cfg(test)]
mod shape_tests;
#[cfg(test)]
mod tests;

use rayon::prelude::*;

use crate::jobs::{Outcome, RunContext, SimError, Simulation};

use chamber::{drip_sites, site_mineral, ChamberShape};
use growth::{site_rng, Grower, SiteGrowth};
pub use outputs::scene;
pub use params::GrowCaveParams;
pub use sequence::CaveSequence;
use sequence::RecordedSite;

pub struct GrowCave;

impl Simulation for GrowCave {
    const KIND: &'static str = "grow-cave";
    const SUMMARY: &'static str =
        "Grow stalactites, stalagmites and columns ring by ring in a cave chamber from geological parameters (glTF scene)";
    const GENERATOR_VERSION: u32 = 2;
    type Params = GrowCaveParams;
    type Sequence = CaveSequence;

    const DRAFT_RULE: &'static str =
        "the roof and floor have half the samples a side (at least 9) and each ring half the vertices (at least 6)";

    fn draft(params: &mut Self::Params) {
        let samples = params.chamber.samples;
        params.chamber.samples = samples.div_ceil(2).max(9).min(samples);
        params.segments = params.segments.div_ceil(2).max(6).min(params.segments);
    }

    fn estimate(
        params: &GrowCaveParams,
        seed: u64,
        terrain: &dyn crate::terrain::TerrainLookup,
    ) -> Result<crate::jobs::Cost, SimError> {
        cost::estimate(params, seed, terrain)
    }

    fn run(params: &Self::Params, seed: u64, ctx: &RunContext) -> Result<Outcome<Self::Sequence>, SimError> {
        let sequence = grow(params, seed, &mut |pass, sequence| {
            ctx.check_cancelled()?;
            let growing = sequence.sites.iter().filter(|s| s.growth.growing()).count();
            let message = format!("pass {pass}: {growing} of {} drip sites still growing", sequence.sites.len());
            ctx.report_with_snapshot("growing", pass as u64, params.rings as u64, message, || {
                outputs::snapshot_png(params, sequence, ctx.stop())
            });
            Ok(())
        })?;
        ctx.report("meshing", sequence.passes as u64, params.rings as u64, "building the scene");
        let (result, artifacts) = outputs::build(params, &sequence, ctx.stop(), &ctx.mesh)?;
        Ok(Outcome { result, sequence, artifacts })
    }

    fn replay(
        params: &Self::Params,
        sequence: &Self::Sequence,
        until_step: Option<u64>,
        ctx: &RunContext,
    ) -> Result<Outcome<Self::Sequence>, SimError> {
        ctx.check_cancelled()?;
        let sequence = sequence.until(until_step);
        let (result, artifacts) = outputs::build(params, &sequence, ctx.stop(), &ctx.mesh)?;
        Ok(Outcome { result, sequence, artifacts })
    }
}

/// Grow every drip site pass by pass; `on_pass` hears of each pass and may stop the run.
pub fn grow(
    params: &GrowCaveParams,
    seed: u64,
    on_pass: &mut dyn FnMut(u32, &CaveSequence) -> Result<(), SimError>,
) -> Result<CaveSequence, SimError> {
    grow_passes(params, seed, params.rings, on_pass)
}

/// The first `passes` passes of [`grow`] (the run's own, bit for bit).
fn grow_passes(
    params: &GrowCaveParams,
    seed: u64,
    passes: u32,
    on_pass: &mut dyn FnMut(u32, &CaveSequence) -> Result<(), SimError>,
) -> Result<CaveSequence, SimError> {
    let shape = ChamberShape::new(&params.chamber, seed);
    let sites = drip_sites(params, seed);
    let growers: Vec<Grower> = sites
        .iter()
        .map(|s| Grower { params, conditions: s.conditions.unwrap_or(params.conditions), shape: &shape })
        .collect();
    let mut sequence = CaveSequence {
        seed,
        passes: 0,
        sites: sites
            .iter()
            .enumerate()
            .map(|(i, s)| RecordedSite {
                mineral: site_mineral(params, s, seed, i),
                growth: SiteGrowth::new(s.x_m, s.z_m, shape.roof_y(s.x_m, s.z_m), shape.floor_y(s.x_m, s.z_m)),
            })
            .collect(),
    };
    let reach = params.stalactite_radius_m + params.kf_m;
    let at: Vec<(f32, f32)> = sites.iter().map(|s| (s.x_m, s.z_m)).collect();
    for (site, merged) in sequence.sites.iter_mut().zip(neighbours::merges(&at, reach)) {
        site.growth.merged_into = merged;
    }
    let (width, depth) = (params.chamber.width_m, params.chamber.depth_m);
    let height = params.chamber.height_m;
    let mut bodies = neighbours::Bodies::new(width, depth, height, neighbours::bin_size(params));
    let mut rngs: Vec<_> = (0..sites.len()).map(|i| site_rng(seed, i)).collect();
    for pass in 1..=passes.min(params.rings) {
        sequence
            .sites
            .par_iter_mut()
            .zip(rngs.par_iter_mut())
            .zip(growers.par_iter())
            .for_each(|((site, rng), grower)| grower.pass(&mut site.growth, rng, pass));
        sequence.sites.par_iter_mut().zip(growers.par_iter()).for_each(|(site, grower)| {
            let g = &mut site.growth;
            let grew = |rings: &[growth::Ring]| rings.last().is_some_and(|r| r.pass() == pass);
            if grew(&g.stalactite) || grew(&g.stalagmite) {
                grower.check_limits(g, pass);
            }
        });
        neighbours::settle(&mut sequence.sites, &mut bodies, &shape, pass);
        sequence.passes = pass;
        on_pass(pass, &sequence)?;
        // Once nothing grows vertically, only the coating goes on; without it, nothing does.
        let still = |s: &RecordedSite| s.growth.merged_into.is_none() && s.growth.growing();
        if params.coating_share == 0.0 && !sequence.sites.iter().any(still) {
            break;
        }
    }
    Ok(sequence)
}
