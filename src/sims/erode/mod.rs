//! `erode`: hydraulic and thermal erosion of a heightfield, so fractal terrain reads as land
//! shaped by water — valleys that branch and drain, ridges between them, fans where rivers
//! slow, scree below cliffs.
//!
//! The fluvial step is the stream-power law E = k·A^m·S^n solved implicitly in O(n) per
//! iteration (Braun & Willett 2013) on multiple-flow-direction drainage weighted by contour
//! length (Quinn et al. 1991), with the deposition term of Yuan et al. 2019; sediment that
//! reaches the sea settles as a delta (`marine.rs`); the surface is kept free of pits by
//! Priority-Flood+ε (Barnes et al. 2014) once and a raise along the drainage after every
//! iteration. The hillslope step (`thermal` in the request) is creep that grows towards the
//! talus slope (Roering et al. 1999), solved implicitly, and failure of anything steeper,
//! measured on the gradient. Every rate is per year and per metre, so the landform does not
//! depend on the time step or the cell size beyond the methods' error. Cordonnier et al. 2016
//! and Schott et al. 2023 show the same stream-power model shaping terrain for authoring. Every
//! pass is a fixed-order sequential sweep or a row-parallel gather, so the bytes do not depend
//! on the thread count.

mod cost;
mod erosion;
mod flood;
mod flow;
mod grid;
mod hillslope;
mod keep;
mod maps;
mod marine;
pub mod metrics;
mod painted;
mod params;
mod sequence;
mod stream_power;

#[cfg(test)]
mod tests;

use rayon::prelude::*;
use serde_json::{json, Map, Value};

pub use erosion::{input_sha256, Erosion};
pub use keep::{Keep, KeepPoint, KeepPolygon, KeepWorked};
pub use painted::{Channel, PaintedMap, SplatChannel};
pub use params::{BaseLevel, ErodeParams, Hydraulic, Switch, Thermal, MAX_ITERATIONS};
pub use sequence::ErodeSequence;

use crate::export::{short_decimal, HeightfieldExport};
use crate::jobs::{Cost, Outcome, RunContext, SimError, Simulation};
use crate::terrain::{Heightfield, TerrainLookup, TerrainSource};
use maps::Maps;

/// The `erode` job kind.
pub struct Erode;

const STAGE: &str = "eroding";
/// Most iterations a draft runs: the request's years, in longer steps.
const DRAFT_ITERATIONS: u32 = 50;
/// Grids up to this many cells get the landform measures in their result (their D8 routing
/// sorts every cell; larger grids would spend more time on it than on a short erosion).
pub const METRICS_MAX_CELLS: u64 = 1025 * 1025;

impl Simulation for Erode {
    const KIND: &'static str = "erode";
    const SUMMARY: &'static str =
        "Erode a heightfield: stream-power rivers with deposition on a pit-free surface, and talus-angle scree";
    // 3: hillslope creep and failure in physical units, contour-length flow weights, outlets
    // found every iteration, deltas (2: deposition capped by the donors' heights plus their own
    // deposits; 1: every non-outlet neighbour's height).
    const GENERATOR_VERSION: u32 = 3;
    type Params = ErodeParams;
    type Sequence = ErodeSequence;

    const DRAFT_RULE: &'static str = "no tiles are cut; the same years run in at most 50 iterations (each longer: \
        the landform does not depend on the time step beyond a few per cent), on the draft terrain";

    fn draft(params: &mut Self::Params) {
        params.tiles = None;
        // Every rate is per year, so fewer, longer steps make the same landform (the time step
        // test: 50 × 1 000 against 200 × 250 years, 5 % RMS of the mean erosion).
        let years = f64::from(params.iterations) * params.time_step_years;
        if params.iterations > DRAFT_ITERATIONS && years / f64::from(DRAFT_ITERATIONS) <= params::MAX_TIME_STEP_YEARS {
            params.iterations = DRAFT_ITERATIONS;
            params.time_step_years = years / f64::from(DRAFT_ITERATIONS);
        }
    }

    fn terrain_sources(params: &mut ErodeParams) -> Vec<(String, &mut TerrainSource)> {
        vec![("terrain".to_string(), &mut params.terrain)]
    }

    fn image_uploads(params: &mut ErodeParams) -> Vec<(String, &mut crate::terrain::ImageUpload)> {
        let Switch::On(h) = &mut params.hydraulic else { return Vec::new() };
        let mut out = Vec::new();
        if let Some(png) = h.erodibility_map.as_mut().and_then(|m| m.png.as_mut()) {
            out.push(("hydraulic.erodibility_map.png".to_string(), png));
        }
        if let Some(png) = h.uplift_map.as_mut().and_then(|m| m.png.as_mut()) {
            out.push(("hydraulic.uplift_map.png".to_string(), png));
        }
        out
    }

    fn estimate(params: &ErodeParams, _seed: u64, terrain: &dyn TerrainLookup) -> Result<Cost, SimError> {
        cost::estimate(params, terrain)
    }

    fn run(params: &ErodeParams, _seed: u64, ctx: &RunContext) -> Result<Outcome<ErodeSequence>, SimError> {
        let input = ctx.resolve_terrain(&params.terrain)?;
        let input_sha256 = input_sha256(&input);
        let (erosion, checksums) = erode(&input, params, None, ctx)?;
        let sequence = ErodeSequence {
            terrain: params.terrain.clone(),
            input_sha256,
            sea_level: params.sea_level,
            time_step_years: params.time_step_years,
            hydraulic: params.hydraulic.clone(),
            thermal: params.thermal.clone(),
            base_level: params.base_level,
            keep: params.keep.clone(),
            checksums,
        };
        finish(&input, erosion, params, sequence, ctx)
    }

    fn replay(
        params: &ErodeParams,
        sequence: &ErodeSequence,
        until_step: Option<u64>,
        ctx: &RunContext,
    ) -> Result<Outcome<ErodeSequence>, SimError> {
        let input = ctx.resolve_terrain(&sequence.terrain)?;
        let hash = input_sha256(&input);
        if hash != sequence.input_sha256 {
            return Err(SimError::Failed(format!(
                "the terrain's heights are not those the sequence was recorded on (sha256 {hash}, recorded {})",
                sequence.input_sha256
            )));
        }
        let k = until_step.map_or(sequence.checksums.len(), |k| (k as usize).min(sequence.checksums.len()));
        let replayed = sequence.params(k as u32, params.tiles);
        let (erosion, checksums) = erode(&input, &replayed, Some(&sequence.checksums[..k]), ctx)?;
        let sequence = ErodeSequence { checksums, ..sequence.clone() };
        finish(&input, erosion, &replayed, sequence, ctx)
    }
}

/// Run `params.iterations` iterations on `input`, reporting progress with live snapshots;
/// with `expected`, each checksum must match it (a replay).
fn erode(
    input: &Heightfield,
    params: &ErodeParams,
    expected: Option<&[String]>,
    ctx: &RunContext,
) -> Result<(Erosion, Vec<String>), SimError> {
    let held = keep::weights(&params.keep, input, ctx.terrain)?;
    let mut erosion = Erosion::new(input, params);
    if let Some(h) = params.hydraulic.on() {
        let grid = erosion.grid;
        let sample = |map: &Option<PaintedMap>, field: &str| {
            map.as_ref().map(|m| m.sample(&format!("hydraulic.{field}"), &grid, ctx.terrain)).transpose()
        };
        erosion.paint(sample(&h.erodibility_map, "erodibility_map")?, sample(&h.uplift_map, "uplift_map")?);
    }
    erosion.check_base_level()?;
    if let Some(weights) = held {
        erosion.hold(input, &weights);
    }
    let total = u64::from(params.iterations);
    let mut checksums = Vec::with_capacity(params.iterations as usize);
    for it in 0..params.iterations as usize {
        ctx.check_cancelled()?;
        erosion.step();
        let sum = erosion.checksum();
        if let Some(recorded) = expected.and_then(|e| e.get(it)) {
            if *recorded != sum {
                return Err(SimError::Failed(format!(
                    "replay diverged at iteration {}: heights checksum {sum}, recorded {recorded}",
                    it + 1
                )));
            }
        }
        checksums.push(sum);
        let message = format!("iteration {} of {total}", it + 1);
        ctx.report_with_snapshot(STAGE, it as u64 + 1, total, message, || {
            Ok(crate::export::snapshot_png(&erosion.heightfield()))
        });
    }
    erosion.flush();
    Ok((erosion, checksums))
}

/// The outcome: the standard heightfield exports with the splat map from wear and
/// deposition, the erosion's maps, and its figures.
fn finish(
    input: &Heightfield,
    erosion: Erosion,
    params: &ErodeParams,
    sequence: ErodeSequence,
    ctx: &RunContext,
) -> Result<Outcome<ErodeSequence>, SimError> {
    let totals = erosion.totals;
    let steep_share = erosion.steep_share();
    let uplift_m = erosion.uplift_total_m(params.hydraulic.on().map_or(0.0, |h| h.uplift_m_per_yr));
    let output = erosion.heightfield();
    drop(erosion);
    check_heights(&output)?;
    let exponent = params.hydraulic.on().map_or(1.0, |h| h.flow_exponent);
    let maps = Maps::new(input, &output, params.sea_level, exponent, &uplift_m);
    let mut figures = figures(input, &output, params, &maps, totals);
    if let Some(share) = steep_share {
        figures.insert("steeper_than_talus_share".into(), json!(round6(share)));
    }
    let map_files = maps.artifacts(output.cols, output.rows);
    let (material, rock) = maps.splat();
    drop(maps);
    let options = HeightfieldExport {
        material: Some(&material),
        rock: Some(&rock),
        sea_level_m: params.sea_level,
        ..HeightfieldExport::new(&ctx.mesh, params.tiles, ctx.stop())
    };
    let exported = crate::export::heightfield_artifacts(&output, &options)?;
    let mut result = match exported.summary {
        Value::Object(map) => map,
        other => [("export".to_string(), other)].into_iter().collect(),
    };
    result.append(&mut figures);
    let mut artifacts = exported.artifacts;
    // The erosion's maps after the standard images, before the levels of detail and tiles.
    let at = artifacts.iter().position(|a| a.name == "splatmap.png").map_or(artifacts.len(), |i| i + 1);
    artifacts.splice(at..at, map_files);
    Ok(Outcome { result: Value::Object(result), sequence, artifacts })
}

/// Refuse heights the exports cannot represent (the bounds on every parameter keep them
/// finite; this is a last guard).
fn check_heights(hf: &Heightfield) -> Result<(), SimError> {
    match hf.heights_m.iter().position(|h| !h.is_finite()) {
        None => Ok(()),
        Some(i) => Err(SimError::Invalid {
            field: "hydraulic".into(),
            message: format!(
                "the erosion drove the height of sample {i} out of range; use a smaller uplift, k or time step"
            ),
        }),
    }
}

/// The erosion's figures: volumes moved, and the landform measures of input and output.
fn figures(
    input: &Heightfield,
    output: &Heightfield,
    params: &ErodeParams,
    maps: &Maps,
    totals: erosion::Totals,
) -> Map<String, Value> {
    let cell_area = f64::from(output.cell_size_m) * f64::from(output.cell_size_m);
    let sum = |v: &[f32]| v.iter().map(|&x| f64::from(x)).sum::<f64>() * cell_area;
    let mut out = Map::new();
    out.insert("iterations".into(), json!(totals.iterations));
    out.insert("years".into(), json!(round3(f64::from(totals.iterations) * params.time_step_years)));
    out.insert("eroded_m3".into(), json!(round3(sum(&maps.wear))));
    out.insert("deposited_m3".into(), json!(round3(sum(&maps.deposition))));
    out.insert("lake_fill_m3".into(), json!(round3(totals.lake_fill_m3)));
    out.insert("drain_raise_m3".into(), json!(round3(totals.drain_raise_m3)));
    out.insert("mass_balance".into(), mass_balance(input, output, params.sea_level, totals));
    if (output.cols * output.rows) as u64 <= METRICS_MAX_CELLS {
        out.insert("landform".into(), landform(input, output, params));
    }
    out
}

/// Where the material went, m³, from the heights themselves and the erosion's own counts:
/// `eroded + lake_fill + drain_raise + uplift + unsettled + held = deposited_on_land +
/// deposited_in_sea + exported` (to the rounding of the f32 heights).
fn mass_balance(input: &Heightfield, output: &Heightfield, sea_level: f32, totals: erosion::Totals) -> Value {
    let cell_area = f64::from(output.cell_size_m) * f64::from(output.cell_size_m);
    let cols = output.cols;
    // Per row, then the rows in order: the same sums with any thread count.
    let rows: Vec<[f64; 3]> = (0..output.rows)
        .into_par_iter()
        .map(|r| {
            let mut sums = [0.0; 3];
            for i in r * cols..(r + 1) * cols {
                let (a, b) = (output.heights_m[i], input.heights_m[i]);
                let d = f64::from(a) - f64::from(b);
                if d < 0.0 {
                    sums[0] -= d;
                } else if a > sea_level {
                    sums[1] += d;
                } else {
                    sums[2] += d;
                }
            }
            sums
        })
        .collect();
    let sum = |k: usize| round3(rows.iter().map(|s| s[k]).sum::<f64>() * cell_area);
    json!({
        "eroded_m3": sum(0),
        "deposited_on_land_m3": sum(1),
        "deposited_in_sea_m3": sum(2),
        "exported_m3": round3(totals.exported_m3),
        "settled_in_sea_by_rivers_m3": round3(totals.settled_in_sea_m3),
        "lake_fill_m3": round3(totals.lake_fill_m3),
        "drain_raise_m3": round3(totals.drain_raise_m3),
        "uplift_m3": round3(totals.uplift_m3),
        "unsettled_m3": round3(totals.unsettled_m3),
        "held_m3": round3(totals.held_m3),
    })
}

/// `{"input": {…}, "output": {…}}` of the measures in [`metrics`].
fn landform(input: &Heightfield, output: &Heightfield, params: &ErodeParams) -> Value {
    let sea = params.sea_level;
    let land: Vec<bool> = input.heights_m.iter().map(|&h| h > sea).collect();
    let talus = params.thermal.on().map(|t| t.talus_angle_deg);
    let measure = |hf: &Heightfield| {
        let d8 = metrics::D8::new(hf, sea);
        let pair = |f: Option<(f64, f64)>| f.map(|(x, r2)| json!({"value": round3(x), "r2": round3(r2)}));
        let mut m = json!({
            "drained_share": round6(metrics::drained_share(hf, sea)),
            "concavity": pair(d8.concavity()),
            "hack_exponent": pair(d8.hack()),
            "hypsometric_integral": metrics::hypsometric_integral(hf, &land, sea).map(round3),
            "max_m": short_decimal(hf.min_max().1),
        });
        if let Some(t) = talus {
            m["within_talus_2deg_share"] = json!(round6(metrics::within_angle_share(hf, t + 2.0)));
        }
        m
    };
    json!({"input": measure(input), "output": measure(output)})
}

fn round3(x: f64) -> f64 {
    (x * 1e3).round() / 1e3
}

fn round6(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}
