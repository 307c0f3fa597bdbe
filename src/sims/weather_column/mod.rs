//! `weather-column`: sandstone goblins by spheroidal weathering (seed 000, Beardall et al.).
//!
//! A column of rock — a joint map's profile, or a box, cylinder or polygon — stands on the
//! ground (or floats) in a voxel grid, split into bedding layers of differing resistance. Each
//! step, every voxel near the surface loses decimation in proportion to the air-to-rock ratio
//! of the bubble around it and in inverse proportion to its resistance; fully decimated voxels
//! are removed, and the lookup table of their bubble gives their neighbours more air. The
//! removal step of every voxel is the recorded sequence; replay reads the rock off it.

mod bubble;
mod cost;
mod gravity;
mod grid;
mod outputs;
pub mod params;
mod resistance;
mod rock;
mod sequence;
mod shape;
mod weathering;

#[cfg(test)]
mod gravity_tests;
#[cfg(test)]
mod tests;

use crate::jobs::{Outcome, RunContext, SimError, Simulation};
use crate::terrain::ImageUpload;

use bubble::BubbleTable;
use grid::{layer_of_plane, Grid};
pub use params::WeatherColumnParams;
use params::{Profile, Update};
use resistance::ResistanceField;
use rock::Rock;
pub use sequence::WeatherSequence;
use weathering::{weather_event_based, weather_synchronized, History, OnStep, Schedule};

pub struct WeatherColumn;

impl Simulation for WeatherColumn {
    const KIND: &'static str = "weather-column";
    const SUMMARY: &'static str =
        "Weather a rock column into sandstone goblins by spheroidal weathering on a voxel grid (glTF mesh, lit preview)";
    /// Version 2: the mesh's vertices keep apart on every written grid (the least crossing
    /// follows the grid's size).
    const GENERATOR_VERSION: u32 = 2;
    type Params = WeatherColumnParams;
    type Sequence = WeatherSequence;

    const DRAFT_RULE: &'static str = "the grid has half the voxels along each axis, each twice as large, with bubbles half as many voxels across and half the steps: the same rock in metres, an eighth of the voxels";

    fn draft(params: &mut Self::Params) {
        params::draft(params);
    }

    fn image_uploads(params: &mut Self::Params) -> Vec<(String, &mut ImageUpload)> {
        match &mut params.column.profile {
            Profile::JointMap(image) => vec![("column.profile.joint_map".to_string(), image)],
            _ => Vec::new(),
        }
    }

    fn estimate(
        params: &WeatherColumnParams,
        _seed: u64,
        terrain: &dyn crate::terrain::TerrainLookup,
    ) -> Result<crate::jobs::Cost, SimError> {
        cost::estimate(params, terrain)
    }

    fn run(params: &Self::Params, seed: u64, ctx: &RunContext) -> Result<Outcome<Self::Sequence>, SimError> {
        let joint_map = match &params.column.profile {
            Profile::JointMap(image) => Some(image.bytes(ctx.terrain)?),
            _ => None,
        };
        let mut on_step = |step: u32, rock: &Rock, active: usize| {
            ctx.check_cancelled()?;
            let left = rock.rock_voxels as f64 * (rock.grid.voxel_size_m as f64).powi(3);
            let percent = 100.0 * rock.rock_voxels as f64 / rock.initial_voxels.max(1) as f64;
            let message = format!("{left:.3} m³ of rock left ({percent:.1} %), {active} active voxels");
            ctx.report_with_snapshot("weathering", step as u64, params.steps as u64, message, || {
                outputs::snapshot_png(&rock.grid, &rock.state, ctx.stop())
            });
            Ok(())
        };
        ctx.report("weathering", 0, params.steps as u64, "building the column");
        let (rock, history) = simulate(params, seed, joint_map.as_deref(), ctx.stop(), &mut on_step)?;
        ctx.check_cancelled()?;
        ctx.report("meshing", history.steps() as u64, params.steps as u64, "extracting the surface");
        let sequence = WeatherSequence::record(&rock, seed, &history);
        let (result, artifacts) = outputs::build(
            params,
            &rock.grid,
            &rock.resistance,
            &rock.state,
            rock.gravity.as_ref().map(|g| g.origin.as_slice()),
            rock.initial_voxels,
            &history,
            ctx.stop(),
            &ctx.mesh,
        )?;
        Ok(Outcome { result, sequence, artifacts })
    }

    fn replay(
        params: &Self::Params,
        sequence: &Self::Sequence,
        until_step: Option<u64>,
        ctx: &RunContext,
    ) -> Result<Outcome<Self::Sequence>, SimError> {
        let grid = Grid::new(params);
        let sequence = sequence.until(&grid, until_step)?;
        let (state, origin, initial) = sequence.cells(&grid)?;
        let history = sequence.history();
        ctx.check_cancelled()?;
        ctx.report("meshing", history.steps() as u64, sequence.steps as u64, "extracting the surface");
        let resistance = ResistanceField::new(params, sequence.seed);
        let (result, artifacts) = outputs::build(
            params,
            &grid,
            &resistance,
            &state,
            origin.as_deref(),
            initial,
            &history,
            ctx.stop(),
            &ctx.mesh,
        )?;
        Ok(Outcome { result, sequence, artifacts })
    }
}

/// The synchronized update one step at a time, for benchmarks: the column as a request
/// describes it, weathered by [`Stepper::step`].
#[derive(Clone)]
pub struct Stepper {
    rock: Rock,
    active: rock::Active,
    step: u16,
    rate: f32,
}

impl Stepper {
    /// The column of a request with a built-in profile (not a joint map), counted and ready.
    pub fn new(params: &WeatherColumnParams, seed: u64) -> Result<Self, SimError> {
        let mut rock = build_rock(params, seed, None)?;
        let active = rock.initialise(crate::stop::Stop::NEVER)?;
        Ok(Self { rock, active, step: 0, rate: params.rate })
    }

    /// Weather one step; returns the voxels it removed.
    pub fn step(&mut self) -> usize {
        self.step += 1;
        weathering::synchronized_step(&mut self.rock, &mut self.active, self.rate, self.step)
    }

    pub fn active_voxels(&self) -> usize {
        self.active.len()
    }

    pub fn rock_voxels(&self) -> u64 {
        self.rock.rock_voxels
    }
}

fn build_rock(params: &WeatherColumnParams, seed: u64, joint_map: Option<&[u8]>) -> Result<Rock, SimError> {
    let grid = Grid::new(params);
    let footprint = shape::footprint(params, &grid, joint_map)?;
    let state = shape::initial_state(&footprint, &grid, params.column_voxels() as usize);
    let layers = layer_of_plane(params, &grid);
    let bubbles = params.layers.iter().map(|l| BubbleTable::new(&l.bubble, params.ratio_exponent)).collect();
    let mut rock = Rock::new(grid, state, layers, bubbles, ResistanceField::new(params, seed));
    if params.gravity {
        rock.gravity = Some(gravity::Gravity::new(&rock.state));
    }
    Ok(rock)
}

/// Build the column and weather it; `on_step` hears of every step and may stop the run.
fn simulate(
    params: &WeatherColumnParams,
    seed: u64,
    joint_map: Option<&[u8]>,
    stop: crate::stop::Stop,
    on_step: &mut OnStep,
) -> Result<(Rock, History), SimError> {
    let mut rock = build_rock(params, seed, joint_map)?;
    stop.check()?;
    // Gravity runs the synchronized update only (validation refuses the other).
    let schedule = Schedule {
        stop,
        rate: params.rate,
        steps: params.steps,
        stop_at_voxels: (params.stop_at_fraction as f64 * rock.initial_voxels as f64).floor() as u64,
    };
    let history = match params.update {
        Update::Synchronized => weather_synchronized(&mut rock, schedule, on_step)?,
        Update::EventBased => weather_event_based(&mut rock, schedule, on_step)?,
    };
    Ok((rock, history))
}
