//! `bulldoze`: a heightfield edited by blades swept along paths and by landform primitives,
//! each combined with the surface by an operator — Ervin & Westort, "Procedural Terrain: A
//! Virtual Bulldozer".
//!
//! Operations apply in order. A primitive is one step; a pass is one step per move (path
//! segment), its relative path heights resolved against the terrain as the pass starts and
//! recorded, so a replay repeats the steps without looking anything up.

mod apply;
mod blade;
mod combine;
mod contour;
mod cost;
mod params;
mod path;
mod primitives;
mod refine;
mod scopes;
mod sequence;

#[cfg(test)]
mod tests;

use crate::export::HeightfieldExport;
use std::convert::Infallible;

use rayon::prelude::*;
use serde_json::{json, Value};

pub use blade::Blade;
pub use combine::Operator;
pub use contour::{ContourPath, Side};
pub use params::{BulldozeParams, Operation, PassOp, PathVertex, PlanPoint, PrimitiveOp, Window};
pub use path::{MoveStep, PathPoint};
pub use primitives::{Berm, BoxShape, Cone, HalfCylinder, Mound, Ramp, Shape, Torus};
pub use refine::Refine;
pub use scopes::{Clamp, Exaggerate, GlobalOp, LocalOp, LocalVertex};
pub use sequence::{BulldozeSequence, Step};

use crate::jobs::{Cost, Outcome, RunContext, SimError, Simulation};
use crate::terrain::{Heightfield, TerrainLookup, TerrainSource};
use params::{check_resampled, resampled_dimensions};
use sequence::Group;

/// The `bulldoze` job kind.
pub struct Bulldoze;

const STAGE: &str = "bulldoze";

impl Simulation for Bulldoze {
    const KIND: &'static str = "bulldoze";
    const SUMMARY: &'static str =
        "Edit a heightfield with blades swept along paths and landform primitives combined by operators";
    const GENERATOR_VERSION: u32 = 1;
    type Params = BulldozeParams;
    type Sequence = BulldozeSequence;

    const DRAFT_RULE: &'static str =
        "the output grid is the draft terrain's (`resolution` is not used) and no tiles are cut";

    fn draft(params: &mut Self::Params) {
        params.resolution = None;
        params.tiles = None;
    }

    fn terrain_sources(params: &mut BulldozeParams) -> Vec<(String, &mut TerrainSource)> {
        vec![("terrain".to_string(), &mut params.terrain)]
    }

    fn estimate(params: &BulldozeParams, _seed: u64, terrain: &dyn TerrainLookup) -> Result<Cost, SimError> {
        cost::estimate(params, terrain)
    }

    fn run(params: &BulldozeParams, _seed: u64, ctx: &RunContext) -> Result<Outcome<BulldozeSequence>, SimError> {
        let edit = run_edit(params, ctx)?;
        edit.finish(HeightfieldExport::new(&ctx.mesh, params.tiles, ctx.stop()))
    }

    fn replay(
        params: &BulldozeParams,
        sequence: &BulldozeSequence,
        until_step: Option<u64>,
        ctx: &RunContext,
    ) -> Result<Outcome<BulldozeSequence>, SimError> {
        replay_edit(sequence, until_step, ctx)?.finish(HeightfieldExport::new(&ctx.mesh, params.tiles, ctx.stop()))
    }
}

/// A finished edit: the grid before and after, what was applied, and its record.
struct Edit {
    /// The grid before the edit, at its starting resolution.
    initial: Heightfield,
    hf: Heightfield,
    tally: Tally,
    sequence: BulldozeSequence,
}

fn run_edit(params: &BulldozeParams, ctx: &RunContext) -> Result<Edit, SimError> {
    let terrain = ctx.resolve_terrain(&params.terrain)?;
    let mut hf = at_resolution(terrain, params.resolution, ctx)?;
    let initial = hf.clone();
    let start_resolution_m = hf.cell_size_m;
    let mut dozer = Bulldozer::new(&mut hf, params.window, params.step_count(), ctx);
    let steps = dozer.operations(&params.operations)?;
    let tally = dozer.tally;
    check_heights(&hf)?;
    let sequence = BulldozeSequence {
        terrain: params.terrain.clone(),
        resolution_m: start_resolution_m,
        window: params.window,
        steps,
    };
    Ok(Edit { initial, hf, tally, sequence })
}

/// Rebuild from a sequence: its terrain at its resolution, then its first `until_step` steps
/// (all of them when `None`), with no terrain lookups for path heights.
fn replay_edit(sequence: &BulldozeSequence, until_step: Option<u64>, ctx: &RunContext) -> Result<Edit, SimError> {
    let k = until_step.map_or(sequence.steps.len(), |k| (k as usize).min(sequence.steps.len()));
    let steps = &sequence.steps[..k];
    let terrain = ctx.resolve_terrain(&sequence.terrain)?;
    let mut hf = at_resolution(terrain, Some(sequence.resolution_m), ctx)?;
    let initial = hf.clone();
    let mut dozer = Bulldozer::new(&mut hf, sequence.window, k as u64, ctx);
    for group in sequence::groups(steps) {
        match group {
            Group::Primitive(p) => dozer.primitive(p)?,
            Group::Pass(moves) => dozer.pass(&moves)?,
            Group::Local(l) => dozer.local(l)?,
            Group::Global(g) => dozer.global(g)?,
            Group::Refine(r) => _ = dozer.refine(r, "refine".into())?,
        }
    }
    let tally = dozer.tally;
    check_heights(&hf)?;
    let sequence = BulldozeSequence { steps: steps.to_vec(), ..sequence.clone() };
    Ok(Edit { initial, hf, tally, sequence })
}

/// Apply `operations` to `hf` in place, as a job does but without progress reports or
/// cancellation, and return the steps it would record.
pub fn apply_operations(hf: &mut Heightfield, operations: &[Operation], window: Option<&Window>) -> Vec<Step> {
    let total = operations.len() as u64;
    let Ok(steps) = Bulldozer::new(hf, window.copied(), total, &Unwatched).operations(operations);
    steps
}

/// Refuse a grid that the exports cannot represent. Validation caps every length and height,
/// so this is a last guard: a height that overflowed is the request's doing, not a fault.
fn check_heights(hf: &Heightfield) -> Result<(), SimError> {
    let Some(i) = hf.heights_m.par_iter().position_first(|h| !h.is_finite()) else {
        return Ok(());
    };
    let (x, z) = ((i % hf.cols) as f32 * hf.cell_size_m, (i / hf.cols) as f32 * hf.cell_size_m);
    Err(SimError::Invalid {
        field: "operations".to_string(),
        message: format!(
            "the operations drive the height at x = {x} m, z = {z} m out of range ({}); use smaller heights or \
             fewer operations",
            hf.heights_m[i]
        ),
    })
}

/// The terrain resampled to `resolution_m` (the paper's sketch mode), unless it is already
/// at that cell size.
fn at_resolution(hf: Heightfield, resolution_m: Option<f32>, ctx: &RunContext) -> Result<Heightfield, SimError> {
    let Some(res) = resolution_m.filter(|&r| r != hf.cell_size_m) else {
        return Ok(hf);
    };
    let (cols, rows) = resampled_dimensions(hf.cols as u64, hf.rows as u64, hf.cell_size_m, res);
    if let Some((message, _)) = check_resampled(cols, rows, ctx.limits) {
        return Err(SimError::Invalid { field: "resolution".to_string(), message });
    }
    Ok(hf.resampled(res))
}

/// What has been applied so far.
#[derive(Clone, Copy, Debug, Default)]
struct Tally {
    steps: u64,
    primitives: u64,
    passes: u64,
    moves: u64,
    /// Local and global operations.
    scoped: u64,
}

/// Who follows an edit between its steps: a job's run context, or nobody.
trait Watcher {
    /// Why the edit stopped early.
    type Stop;
    fn check_cancelled(&self) -> Result<(), Self::Stop>;
    /// Progress after `step` of `total` steps, with a live snapshot of `hf` if one is given
    /// and due; `message` is built only when someone listens.
    fn progress(&self, step: u64, total: u64, message: impl FnOnce() -> String, hf: Option<&Heightfield>);
    /// An operation that the terrain makes impossible (a contour it does not cross): a job
    /// stops with a problem naming `field`; without a job the operation is skipped.
    fn invalid(&self, field: String, message: String) -> Result<(), Self::Stop>;
    /// The limits the edit keeps to.
    fn limits(&self) -> crate::validate::Limits {
        crate::validate::Limits::default()
    }
}

impl Watcher for RunContext<'_> {
    type Stop = SimError;

    fn check_cancelled(&self) -> Result<(), SimError> {
        RunContext::check_cancelled(self)
    }

    fn invalid(&self, field: String, message: String) -> Result<(), SimError> {
        Err(SimError::Invalid { field, message })
    }

    fn limits(&self) -> crate::validate::Limits {
        self.limits.clone()
    }

    fn progress(&self, step: u64, total: u64, message: impl FnOnce() -> String, hf: Option<&Heightfield>) {
        match hf {
            // Snapshots are rate-limited by the sink, so offering one per step is cheap.
            Some(hf) => {
                self.report_with_snapshot(STAGE, step, total, message(), || Ok(crate::export::snapshot_png(hf)))
            }
            None => self.report(STAGE, step, total, message()),
        }
    }
}

/// Nobody: nothing is reported, and nothing can stop the edit.
struct Unwatched;

impl Watcher for Unwatched {
    type Stop = Infallible;

    fn check_cancelled(&self) -> Result<(), Infallible> {
        Ok(())
    }

    fn progress(&self, _step: u64, _total: u64, _message: impl FnOnce() -> String, _hf: Option<&Heightfield>) {}

    fn invalid(&self, _field: String, _message: String) -> Result<(), Infallible> {
        Ok(())
    }
}

/// The grid being edited, reporting to its watcher between steps.
struct Bulldozer<'a, W: Watcher> {
    hf: &'a mut Heightfield,
    window: Option<Window>,
    /// The grid cap a refine must keep to.
    limits: crate::validate::Limits,
    total: u64,
    tally: Tally,
    watcher: &'a W,
}

impl<'a, W: Watcher> Bulldozer<'a, W> {
    fn new(hf: &'a mut Heightfield, window: Option<Window>, total: u64, watcher: &'a W) -> Self {
        let limits = watcher.limits();
        Self { hf, window, limits, total, tally: Tally::default(), watcher }
    }

    /// Apply operations in order, resolving each pass's path against the surface as the
    /// pass starts; returns the steps to record.
    fn operations(&mut self, operations: &[Operation]) -> Result<Vec<Step>, W::Stop> {
        let mut steps = Vec::new();
        for (i, op) in operations.iter().enumerate() {
            match op {
                Operation::Primitive(p) => {
                    self.primitive(p)?;
                    steps.push(Step::Primitive(p.clone()));
                }
                Operation::Pass(p) => {
                    let traced;
                    let p = match &p.contour {
                        Some(c) => match contour::contour_vertices(self.hf, c) {
                            Ok(path) => {
                                traced = PassOp { path, contour: None, ..p.clone() };
                                &traced
                            }
                            Err(message) => {
                                let field = format!("operations[{i}].pass.contour");
                                self.watcher.invalid(field, message)?;
                                continue;
                            }
                        },
                        None => p,
                    };
                    let moves = path::resolve_pass(self.hf, self.tally.passes as u32, p);
                    self.pass(&moves)?;
                    steps.extend(moves.into_iter().map(Step::Move));
                }
                Operation::Local(l) => {
                    self.local(l)?;
                    steps.push(Step::Local(l.clone()));
                }
                Operation::Global(g) => {
                    self.global(g)?;
                    steps.push(Step::Global(g.clone()));
                }
                Operation::Refine(r) => {
                    if self.refine(r, format!("operations[{i}].refine.resolution"))? {
                        steps.push(Step::Refine(*r));
                    }
                }
            }
        }
        Ok(steps)
    }

    fn primitive(&mut self, p: &PrimitiveOp) -> Result<(), W::Stop> {
        self.watcher.check_cancelled()?;
        primitives::apply_shape(self.hf, &p.shape, p.operator, self.window.as_ref());
        self.tally.steps += 1;
        self.tally.primitives += 1;
        let message = || format!("{} ({})", primitives::shape_name(&p.shape), p.operator.name());
        self.watcher.progress(self.tally.steps, self.total, message, Some(self.hf));
        Ok(())
    }

    fn local(&mut self, l: &LocalOp) -> Result<(), W::Stop> {
        self.watcher.check_cancelled()?;
        scopes::apply_local(self.hf, l, self.window.as_ref());
        self.single_step(|| format!("local: {} vertices", l.vertices.len()))
    }

    fn global(&mut self, g: &GlobalOp) -> Result<(), W::Stop> {
        self.watcher.check_cancelled()?;
        scopes::apply_global(self.hf, g, self.window.as_ref());
        self.single_step(|| "global".to_string())
    }

    /// Resample to a finer resolution and narrow the window; whether it was applied (a grid
    /// too fine for the cap, or a coarser resolution, is `invalid` under `field`).
    fn refine(&mut self, r: &Refine, field: String) -> Result<bool, W::Stop> {
        self.watcher.check_cancelled()?;
        let hf = &*self.hf;
        let (cols, rows) = params::resampled_dimensions(hf.cols as u64, hf.rows as u64, hf.cell_size_m, r.resolution);
        let problem = if r.resolution > hf.cell_size_m {
            Some(format!("must not be coarser than the grid's {} m", hf.cell_size_m))
        } else {
            check_resampled(cols, rows, &self.limits).map(|(message, _)| message)
        };
        if let Some(message) = problem {
            self.watcher.invalid(field, message)?;
            return Ok(false);
        }
        if r.resolution != hf.cell_size_m {
            *self.hf = hf.resampled(r.resolution);
        }
        self.window = Some(refine::intersect(self.window, r.window));
        self.single_step(|| format!("refine to {} m", r.resolution))?;
        Ok(true)
    }

    /// Count a one-step operation of a scope without a primitive's footprint and report it.
    fn single_step(&mut self, message: impl FnOnce() -> String) -> Result<(), W::Stop> {
        self.tally.steps += 1;
        self.tally.scoped += 1;
        self.watcher.progress(self.tally.steps, self.total, message, Some(self.hf));
        Ok(())
    }

    fn pass(&mut self, moves: &[MoveStep]) -> Result<(), W::Stop> {
        let Some(first) = moves.first() else {
            return Ok(());
        };
        let pass = first.pass;
        self.watcher.check_cancelled()?;
        let (watcher, total, tally) = (self.watcher, self.total, &mut self.tally);
        path::apply_pass(self.hf, moves, self.window.as_ref(), |k| {
            tally.steps += 1;
            watcher.progress(tally.steps, total, || format!("pass {pass}: move {} of {}", k + 1, moves.len()), None);
            watcher.check_cancelled()
        })?;
        self.tally.passes += 1;
        self.tally.moves += moves.len() as u64;
        self.watcher.progress(self.tally.steps, total, || format!("pass {pass} done"), Some(self.hf));
        Ok(())
    }
}

impl Edit {
    /// The bulldozer's own figures: counts of what was applied, and how the grid changed.
    /// The start's heights on the final grid: a refined grid is compared with the start
    /// resampled to it.
    fn initial_on_grid(&self) -> std::borrow::Cow<'_, [f32]> {
        if self.initial.cols == self.hf.cols && self.initial.rows == self.hf.rows {
            std::borrow::Cow::Borrowed(&self.initial.heights_m)
        } else {
            std::borrow::Cow::Owned(self.initial.resampled(self.hf.cell_size_m).heights_m)
        }
    }

    /// The figures, for tests (a job computes them in `finish`, sharing the resampled start).
    #[cfg(test)]
    fn figures(&self) -> serde_json::Map<String, Value> {
        self.figures_from(&self.initial_on_grid())
    }

    /// [`Self::figures`] against the start's heights already on the final grid.
    fn figures_from(&self, initial: &[f32]) -> serde_json::Map<String, Value> {
        let cell_area = self.hf.cell_size_m as f64 * self.hf.cell_size_m as f64;
        let (changed, cut, fill) = change_totals(initial, &self.hf);
        let t = self.tally;
        [
            ("operations", json!(t.primitives + t.passes + t.scoped)),
            ("steps", json!(t.steps)),
            ("passes", json!(t.passes)),
            ("primitives", json!(t.primitives)),
            ("moves", json!(t.moves)),
            ("changed_samples", json!(changed)),
            ("cut_volume_m3", json!(cut * cell_area)),
            ("fill_volume_m3", json!(fill * cell_area)),
        ]
        .into_iter()
        .map(|(name, value)| (name.to_string(), value))
        .collect()
    }

    /// The job's outcome: the export summary merged with the bulldozer's figures.
    fn finish(self, output: HeightfieldExport) -> Result<Outcome<BulldozeSequence>, SimError> {
        // The start on the final grid once: a refined grid is resampled for it.
        let initial = self.initial_on_grid();
        let figures = self.figures_from(&initial);
        let material = shaped_cells(&initial, &self.hf.heights_m);
        drop(initial);
        let output = HeightfieldExport { material: Some(&material), ..output };
        let exported = crate::export::heightfield_artifacts(&self.hf, &output)?;
        let mut result = match exported.summary {
            Value::Object(map) => map,
            other => [("export".to_string(), other)].into_iter().collect(),
        };
        result.extend(figures);
        Ok(Outcome { result: Value::Object(result), sequence: self.sequence, artifacts: exported.artifacts })
    }
}

/// A sample the bulldozer moved by more than this (metres) is its work in `splatmap.png`'s A.
pub const SHAPED_M: f32 = 0.01;

/// `splatmap.png`'s material: 255 where the bulldozer cut or filled more than [`SHAPED_M`]
/// (roads, pads, channels), 0 elsewhere.
fn shaped_cells(initial: &[f32], after: &[f32]) -> Vec<u8> {
    initial.par_iter().zip(after).map(|(&b, &a)| if (a - b).abs() > SHAPED_M { 255 } else { 0 }).collect()
}

/// Samples whose height changed, and the summed height lost (cut) and gained (fill) in
/// metres; rows are summed in parallel and the row totals in order, so the figures do not
/// depend on the thread count.
fn change_totals(initial: &[f32], hf: &Heightfield) -> (u64, f64, f64) {
    let rows: Vec<(u64, f64, f64)> = initial
        .par_chunks(hf.cols)
        .zip(hf.heights_m.par_chunks(hf.cols))
        .map(|(before, after)| {
            before.iter().zip(after).fold((0u64, 0.0f64, 0.0f64), |(n, cut, fill), (&b, &a)| {
                let dz = a as f64 - b as f64;
                (n + (a != b) as u64, cut + (-dz).max(0.0), fill + dz.max(0.0))
            })
        })
        .collect();
    rows.into_iter().fold((0, 0.0, 0.0), |(n, c, f), (rn, rc, rf)| (n + rn, c + rc, f + rf))
}
