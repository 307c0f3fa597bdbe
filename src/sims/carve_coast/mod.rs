//! `carve-coast`: coastal erosion with overhangs, sea caves and arches (seed 003). The
//! heightfield becomes an implicit surface; passes of spheres grown inward from steep points
//! near sea level are subtracted from it; an optional warp adds strata; the result is meshed
//! in a narrow band around the surface into a closed solid.

mod caves;
mod cost;
mod erosion;
mod field;
mod implicit;
mod outputs;
pub mod params;
mod sequence;

#[cfg(test)]
mod tests;

use crate::jobs::{Outcome, RunContext, SimError, Simulation};
use crate::terrain::{Heightfield, TerrainSource};

use crate::stop::Stop;
use implicit::{Capsule, Carving, Implicit, Sphere};
pub use params::CarveCoastParams;
use params::{estimate_voxels, AuthoredCarving, When, MAX_SPHERES};
pub use sequence::CoastSequence;

pub struct CarveCoast;

/// The field is exact within this many voxels of the surface: the mesher interpolates between
/// neighbouring samples and the normals take central differences half a voxel either side.
const EXACT_VOXELS: f32 = 2.0;

impl Simulation for CarveCoast {
    const KIND: &'static str = "carve-coast";
    const SUMMARY: &'static str =
        "Carve a coastline with overhangs, sea caves and arches out of a terrain's implicit form, meshed as a closed solid";
    /// Version 2: the heightmap's border is the surface there (it was the box's bottom) and the
    /// mesh's vertices keep apart on every written grid.
    const GENERATOR_VERSION: u32 = 2;
    type Params = CarveCoastParams;
    type Sequence = CoastSequence;

    const DRAFT_RULE: &'static str =
        "`voxel_size_m` is doubled (absent, it is twice the draft terrain's cell), and at most 2 erosion passes run";

    fn draft(params: &mut Self::Params) {
        params.voxel_size_m = params.voxel_size_m.map(|v| v * 2.0);
        params.passes = params.passes.min(2);
    }

    fn terrain_sources(params: &mut Self::Params) -> Vec<(String, &mut TerrainSource)> {
        vec![("terrain".to_string(), &mut params.terrain)]
    }

    fn estimate(
        params: &CarveCoastParams,
        _seed: u64,
        terrain: &dyn crate::terrain::TerrainLookup,
    ) -> Result<crate::jobs::Cost, SimError> {
        cost::estimate(params, terrain)
    }

    fn run(params: &Self::Params, seed: u64, ctx: &RunContext) -> Result<Outcome<Self::Sequence>, SimError> {
        let hf = ctx.resolve_terrain(&params.terrain)?;
        let params = &*params.with_sea_level(&hf);
        let voxel_m = checked_voxel(params, &hf, ctx)?;
        let total = params.passes as u64 + 1;
        let spheres = carve(params, &hf, seed, voxel_m, ctx.stop(), &mut |pass, spheres| {
            ctx.check_cancelled()?;
            let implicit = Implicit::new(&hf, spheres, params.warp.as_ref(), seed, 8.0 * voxel_m);
            let message = format!("pass {pass}: {} spheres carved", spheres.len());
            ctx.report_with_snapshot("carving", pass as u64, total, message, || {
                outputs::snapshot_png(&implicit, params, voxel_m, ctx.stop())
            });
            Ok(())
        })?;
        let sequence = CoastSequence { terrain: params.terrain.clone(), seed, spheres };
        finish(params, &hf, sequence, voxel_m, ctx)
    }

    fn replay(
        params: &Self::Params,
        sequence: &Self::Sequence,
        until_step: Option<u64>,
        ctx: &RunContext,
    ) -> Result<Outcome<Self::Sequence>, SimError> {
        let hf = ctx.resolve_terrain(&params.terrain)?;
        let params = &*params.with_sea_level(&hf);
        let voxel_m = checked_voxel(params, &hf, ctx)?;
        finish(params, &hf, sequence.until(until_step), voxel_m, ctx)
    }
}

/// The voxel size, after checking the sea level and the voxel cap against the resolved terrain.
/// A draft's default voxel is twice the (draft) terrain's cell: the meshing is most of the work.
fn checked_voxel(params: &CarveCoastParams, hf: &Heightfield, ctx: &RunContext) -> Result<f32, SimError> {
    let limits = ctx.limits;
    let (lo, hi) = hf.min_max();
    if !(lo..=hi).contains(&params.sea_level()) {
        return Err(SimError::Invalid {
            field: "sea_level".into(),
            message: format!("must lie within the terrain's heights ({lo} to {hi} m), got {}", params.sea_level()),
        });
    }
    let draft_scale = if ctx.draft { 2.0 } else { 1.0 };
    let voxel_m = params.voxel_size_m.unwrap_or(hf.cell_size_m * draft_scale);
    let voxels = estimate_voxels(
        hf.cols as u64,
        hf.rows as u64,
        hf.cell_size_m,
        hi - lo,
        voxel_m,
        params.max_radius(),
        params.warp_amplitude(),
    );
    if voxels > limits.max_voxels {
        return Err(SimError::Invalid {
            field: "voxel_size_m".into(),
            message: format!("meshing would take about {voxels} voxels, more than the cap of {}", limits.max_voxels),
        });
    }
    Ok(voxel_m)
}

/// Hears of each finished pass with the spheres so far; may stop the run.
pub type OnPass<'a> = dyn FnMut(u32, &[Carving]) -> Result<(), SimError> + 'a;

/// The authored carvings made `when`, in the warped domain (their points mapped as a seed's
/// are), as pass `pass`.
fn authored(params: &CarveCoastParams, warped: &Implicit, when: When, pass: u32) -> Vec<Carving> {
    params
        .carve
        .iter()
        .filter(|c| c.when() == when)
        .map(|c| match c {
            AuthoredCarving::Sphere { centre, radius_m, .. } => {
                let [x, y, z] = warped.warp(*centre);
                Carving::Sphere(Sphere([x, y, z, *radius_m], pass))
            }
            AuthoredCarving::Capsule { from, to, radius_m, .. } => {
                let (a, b) = (warped.warp(*from), warped.warp(*to));
                Carving::Capsule(Capsule([a[0], a[1], a[2], b[0], b[1], b[2], *radius_m], pass))
            }
        })
        .collect()
}

/// The authored carvings made before the passes, all passes of erosion, then the authored
/// carvings made after them; `on_pass(pass, carvings so far)` after each pass.
pub fn carve(
    params: &CarveCoastParams,
    hf: &Heightfield,
    seed: u64,
    voxel_m: f32,
    stop: Stop,
    on_pass: &mut OnPass,
) -> Result<Vec<Carving>, SimError> {
    let warp_only = Implicit::new(hf, &[], params.warp.as_ref(), seed, 0.0);
    let mut spheres = authored(params, &warp_only, When::Before, 0);
    for pass in 1..=params.passes {
        let new = {
            // Seeds are found on the surface carved so far, warped as the result will be.
            let step = voxel_m.min(hf.cell_size_m);
            let implicit = Implicit::new(hf, &spheres, params.warp.as_ref(), seed, 2.0 * step);
            let room = MAX_SPHERES.saturating_sub(spheres.len());
            erosion::erosion_pass(&implicit, params, seed, pass, step, room, stop)?
        };
        spheres.extend(new.into_iter().map(Carving::Sphere));
        on_pass(pass, &spheres)?;
    }
    spheres.extend(authored(params, &warp_only, When::After, params.passes + 1));
    Ok(spheres)
}

fn finish(
    params: &CarveCoastParams,
    hf: &Heightfield,
    sequence: CoastSequence,
    voxel_m: f32,
    ctx: &RunContext,
) -> Result<Outcome<CoastSequence>, SimError> {
    let implicit = Implicit::new(hf, &sequence.spheres, params.warp.as_ref(), sequence.seed, EXACT_VOXELS * voxel_m);
    let total = params.passes as u64 + 1;
    let mut on_chunk = |done, of| {
        ctx.check_cancelled()?;
        ctx.report("meshing", params.passes as u64, total, format!("sampled chunk {done} of {of}"));
        Ok(())
    };
    let on_stage = |stage: &str| ctx.report("meshing", params.passes as u64, total, stage);
    let (result, artifacts) =
        outputs::build(&implicit, params, &sequence.spheres, voxel_m, &mut on_chunk, &on_stage, ctx.stop(), &ctx.mesh)?;
    Ok(Outcome { result, sequence, artifacts })
}

/// For benchmarks: carve a fractal-terrain request, then time sampling and meshing its field in
/// the narrow band or densely over the whole box. Returns (seconds, triangles).
pub fn meshing_seconds(params: &CarveCoastParams, seed: u64, dense: bool) -> Result<(f64, usize), SimError> {
    let TerrainSource::Fractal(f) = &params.terrain else {
        return Err(SimError::Failed("meshing_seconds takes fractal terrain".into()));
    };
    let hf = crate::terrain::generate_fractal(f);
    let voxel_m = params.voxel_size_m.unwrap_or(hf.cell_size_m);
    let spheres = carve(params, &hf, seed, voxel_m, Stop::NEVER, &mut |_, _| Ok(()))?;
    let implicit = Implicit::new(&hf, &spheres, params.warp.as_ref(), seed, EXACT_VOXELS * voxel_m);
    let started = std::time::Instant::now();
    let sampled = outputs::sample(&implicit, params, voxel_m, dense, &mut |_, _| Ok(()))?;
    let mesh = outputs::surface(&sampled, Stop::NEVER)?;
    Ok((started.elapsed().as_secs_f64(), mesh.triangle_count()))
}
