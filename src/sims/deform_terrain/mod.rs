//! `deform-terrain`: a fractal heightfield deformed by stochastic local search over truncated
//! Gaussian operations until it satisfies constraints — the seed paper's algorithm (§3), with
//! the fitness change of a deformation evaluated over its kernel's window only, candidates
//! evaluated in parallel, and the deformation sequence recorded as the terrain (§4.5).

mod bounds;
mod candidates;
mod constraints;
mod cost;
mod kernel;
pub mod packed;
mod params;
mod prediction;
mod projection;
mod search;
mod sequence;

#[cfg(test)]
mod limit_tests;
#[cfg(test)]
mod tests;

use serde_json::{json, Map, Value};

pub use kernel::Kernel;
pub use params::{
    Constraint, DeformTerrainParams, Edge, EdgeMatch, HeightPoint, MaskShape, MatchHeightmap, PlanPoint, Points,
    Preserve, Road, RoadHeight, RoadProfile, ShapeMask, TileAxes, Tileable, MAX_ITERATIONS,
};
pub use sequence::{DeformSequence, Deformation};

use crate::export::{Artifact, HeightfieldExport};
use crate::jobs::{Outcome, RunContext, SimError, Simulation};
use crate::terrain::{Heightfield, TerrainSource};
use constraints::{Field, Fitness, Grid};
use search::{Record, Searched, Settings, Stop, Tracker, Watch};

/// The `deform-terrain` job kind.
pub struct DeformTerrain;

const STAGE: &str = "search";

/// Most (vertex, radius) entries the search table may hold (about 40 bytes each).
const MAX_TABLE_ENTRIES: usize = 4_000_000;

/// How many of the smallest radii an anchor vertex (a road, seam or point cell) is tried with.
const ANCHOR_RADII: usize = 4;
/// How many an anchor inside an area (off its edges) is tried with. Terraces at 257² with
/// every region sample taking 4: 97 800 entries; edges 4 and inside 2: 59 400, 40 % less
/// search, fitness within 0.3 % (`benches/deform_against.sh`).
const INSIDE_ANCHOR_RADII: usize = 2;

impl Simulation for DeformTerrain {
    const KIND: &'static str = "deform-terrain";
    const SUMMARY: &'static str =
        "Deform a terrain by stochastic local search over Gaussian operations until it satisfies constraints";
    /// 2: the limits' projection after the search (a sequence recorded with the limits on
    /// replays to other heights than version 1's).
    /// 3: the search stops when it stalls (`stall_iterations`, `stall_gain`).
    /// 4: earthworks at their cut and fill slopes, the slope limit from a percentile of the
    /// input's steps, targets held by priority.
    const GENERATOR_VERSION: u32 = 4;
    type Params = DeformTerrainParams;
    type Sequence = DeformSequence;

    const DRAFT_RULE: &'static str =
        "at most 150 iterations of the search on the draft terrain (radii in cells span twice or more the metres), and no tiles are cut";

    fn draft(params: &mut Self::Params) {
        params.max_iterations = params.max_iterations.min(150);
        params.tiles = None;
    }

    fn terrain_sources(params: &mut DeformTerrainParams) -> Vec<(String, &mut TerrainSource)> {
        let mut out = vec![("terrain".to_string(), &mut params.terrain)];
        for (i, c) in params.constraints.iter_mut().enumerate() {
            match c {
                Constraint::MatchHeightmap(m) => {
                    out.push((format!("constraints[{i}].match_heightmap.target"), &mut m.target))
                }
                Constraint::ShapeMask(ShapeMask { mask: MaskShape::Image(src), .. }) => {
                    out.push((format!("constraints[{i}].shape_mask.mask.image"), src))
                }
                Constraint::EdgeMatch(e) => out.push((format!("constraints[{i}].edge_match.terrain"), &mut e.terrain)),
                _ => {}
            }
        }
        out
    }

    fn estimate(
        params: &DeformTerrainParams,
        _seed: u64,
        terrain: &dyn crate::terrain::TerrainLookup,
    ) -> Result<crate::jobs::Cost, SimError> {
        cost::estimate(params, terrain)
    }

    fn run(params: &DeformTerrainParams, seed: u64, ctx: &RunContext) -> Result<Outcome<DeformSequence>, SimError> {
        let problem = Problem::new(params, ctx)?;
        let mut h = problem.original.clone();
        let grid = problem.grid();
        let fields = problem.fields(&grid)?;
        let settings = problem.settings(params, &fields)?;
        let mut fitness = Fitness::new(&fields, grid.cols, grid.rows);
        // The footprints, only when the keep pull needs them. The limits are the projection's
        // after the search ([`bounds`]), so the search stays on its fast path.
        if params.keep_weight > 0.0 {
            let bounds = bounds::Bounds::new(&fields, &grid, params.max_free_change);
            // Not pulled: the targets, and a tile's wrap band (pulled, the tileable example's
            // p99 bend came out up to 3.4 × the input's: kernels small enough to slip between
            // the pull and the wrap's fit).
            let mut targets = vec![false; grid.cells()];
            if let Some(band) = tile_band(params) {
                let near = |v: usize, n: usize| v < band || v + band >= n;
                for (i, t) in targets.iter_mut().enumerate() {
                    let (c, r) = (i % grid.cols, i / grid.cols);
                    *t = (settings.tile_x && near(c, grid.cols)) || (settings.tile_z && near(r, grid.rows));
                }
            }
            for tier in &constraints::held(&fields)[constraints::Priority::Point as usize..] {
                for b in tier {
                    targets[b.sample] = true;
                }
            }
            if let Some(keep) = constraints::keep(&bounds.footprint, &targets, &grid, params.keep_weight, KEEP_INSIDE) {
                fitness = fitness.with(&keep);
            }
        }
        let interest = constraints::interest(&fields, grid.cells());
        let vertices = vertices(params, &settings, &fields, &interest, &grid);
        let entries: usize = vertices.iter().map(|v| v.2.count_ones() as usize).sum();
        if entries > MAX_TABLE_ENTRIES {
            return Err(SimError::Invalid {
                field: "coarse_spacing_cells".into(),
                message: format!(
                    "{entries} candidate deformations is more than the cap of {MAX_TABLE_ENTRIES}; \
                     raise coarse_spacing_cells or min_spacing_cells, or use fewer radii or narrower roads"
                ),
            });
        }
        let mut tracker = Tracker::new(&fields, &h, grid.cols, grid.rows);
        let watch = JobWatch { ctx, cols: grid.cols, rows: grid.rows, cell_m: grid.cell_m };
        let started = std::time::Instant::now();
        // The search runs on a thread of the pool: its parallel recomputations, a thousand or
        // more of them, are then taken up by the pool's threads at once instead of each waking
        // them from outside and waiting to be woken back (on the S-road that hand-over was a
        // fifth of the search).
        let (searched, ()) =
            rayon::join(|| search::search(&mut h, &fitness, &mut tracker, &vertices, &settings, seed, &watch), || ());
        let searched = searched?;
        // Wall time goes to the log only: artifacts stay the same bytes run after run.
        tracing::debug!(search_ms = started.elapsed().as_millis() as u64, entries, "deform-terrain search done");
        let history = std::mem::take(&mut tracker.history);
        let sequence = DeformSequence { terrain: params.terrain.clone(), operations: searched.operations.clone() };
        let run = RunFigures { searched: Some(&searched), candidates: vertices.len(), prediction: params.prediction };
        // The exports too, for the same reason as the search.
        let export = HeightfieldExport::new(&ctx.mesh, params.tiles, ctx.stop());
        rayon::join(|| finish(&problem, &fields, &h, &history, &interest, &settings, sequence, run, export), || ()).0
    }

    fn replay(
        params: &DeformTerrainParams,
        sequence: &DeformSequence,
        until_step: Option<u64>,
        ctx: &RunContext,
    ) -> Result<Outcome<DeformSequence>, SimError> {
        let k = until_step.map_or(sequence.operations.len(), |k| (k as usize).min(sequence.operations.len()));
        let params = DeformTerrainParams { terrain: sequence.terrain.clone(), ..params.clone() };
        let problem = Problem::new(&params, ctx)?;
        let grid = problem.grid();
        let fields = problem.fields(&grid)?;
        let settings = problem.settings(&params, &fields)?;
        let interest = constraints::interest(&fields, grid.cells());
        let mut h = problem.original.clone();
        let mut tracker = Tracker::new(&fields, &h, grid.cols, grid.rows);
        let ops = &sequence.operations[..k];
        // A search uses a handful of radii many times over: build each kernel once.
        let mut kernels: Vec<Kernel> = Vec::new();
        for (n, op) in ops.iter().enumerate() {
            ctx.check_cancelled()?;
            check_operation(op, n, grid.cols, grid.rows)?;
            let radius = op.radius_cells as usize;
            let kernel = match kernels.iter().position(|k| k.radius == radius) {
                Some(i) => &kernels[i],
                None => {
                    kernels.push(Kernel::new(radius));
                    kernels.last().expect("just pushed")
                }
            };
            tracker.apply(&mut h, op, kernel);
            ctx.report("replay", n as u64 + 1, k as u64, format!("operation {} of {k}", n + 1));
        }
        let history = std::mem::take(&mut tracker.history);
        let sequence = DeformSequence { terrain: sequence.terrain.clone(), operations: ops.to_vec() };
        let run = RunFigures { searched: None, candidates: 0, prediction: params.prediction };
        finish(
            &problem,
            &fields,
            &h,
            &history,
            &interest,
            &settings,
            sequence,
            run,
            HeightfieldExport::new(&ctx.mesh, params.tiles, ctx.stop()),
        )
    }
}

/// Refuse a recorded operation outside the grid.
fn check_operation(op: &Deformation, n: usize, cols: usize, rows: usize) -> Result<(), SimError> {
    let radius_ok = (1..=params::MAX_RADIUS_CELLS).contains(&op.radius_cells);
    if op.col as usize >= cols || op.row as usize >= rows || !radius_ok || !op.amplitude.is_finite() {
        return Err(SimError::Failed(format!("recorded operation {n} does not fit the terrain")));
    }
    Ok(())
}

/// The resolved terrain and the constraints' inputs.
struct Problem<'p> {
    params: &'p DeformTerrainParams,
    cols: usize,
    rows: usize,
    cell_m: f64,
    original: Vec<f64>,
    relief: f64,
    resolved: Vec<Option<Heightfield>>,
}

impl<'p> Problem<'p> {
    fn new(params: &'p DeformTerrainParams, ctx: &RunContext) -> Result<Self, SimError> {
        let terrain = ctx.resolve_terrain(&params.terrain)?;
        let original: Vec<f64> = terrain.heights_m.iter().map(|&v| v as f64).collect();
        let (lo, hi) = terrain.min_max();
        let relief = if hi > lo { hi as f64 - lo as f64 } else { 1.0 };
        let mut resolved = Vec::with_capacity(params.constraints.len());
        for c in &params.constraints {
            ctx.check_cancelled()?;
            resolved.push(match c {
                Constraint::MatchHeightmap(m) => Some(ctx.resolve_terrain(&m.target)?),
                Constraint::ShapeMask(ShapeMask { mask: MaskShape::Image(src), .. }) => Some(ctx.resolve_terrain(src)?),
                Constraint::EdgeMatch(e) => Some(ctx.resolve_terrain(&e.terrain)?),
                _ => None,
            });
        }
        let p = Self {
            params,
            cols: terrain.cols,
            rows: terrain.rows,
            cell_m: terrain.cell_size_m as f64,
            original,
            relief,
            resolved,
        };
        p.check_against_grid()?;
        Ok(p)
    }

    fn grid(&self) -> Grid<'_> {
        let p = self.params;
        let slope_limit = bounds::slope_limit(
            &self.original,
            self.cols,
            self.rows,
            self.cell_m,
            p.max_slope_ratio,
            p.slope_percentile,
        );
        Grid {
            cols: self.cols,
            rows: self.rows,
            cell_m: self.cell_m,
            original: &self.original,
            relief: self.relief,
            slope_limit,
            cut: p.earthworks.cut_slope.gradient(),
            fill: p.earthworks.fill_slope.gradient(),
        }
    }

    fn fields(&self, grid: &Grid) -> Result<Vec<Field>, SimError> {
        constraints::build(&self.params.constraints, &self.resolved, grid)
            .map_err(|e| SimError::Invalid { field: e.field, message: e.message })
    }

    /// What validation could not check before the terrain was known (an earlier job's grid).
    fn check_against_grid(&self) -> Result<(), SimError> {
        let p = self.params;
        let shorter = self.cols.min(self.rows);
        let invalid = |field: String, message: String| Err(SimError::Invalid { field, message });
        if shorter < 3 {
            return invalid("terrain".into(), format!("needs at least 3 samples a side (got {shorter})"));
        }
        for (leaf, r) in [("min_radius_cells", Some(p.min_radius_cells)), ("max_radius_cells", p.max_radius_cells)] {
            if let Some(r) = r.filter(|&r| r as usize >= shorter) {
                return invalid(leaf.into(), format!("{r} cells is larger than the grid ({shorter} samples a side)"));
            }
        }
        let (w, d) = ((self.cols - 1) as f64 * self.cell_m, (self.rows - 1) as f64 * self.cell_m);
        let off = |x: f64, z: f64| !(0.0..=w).contains(&x) || !(0.0..=d).contains(&z);
        for (i, c) in p.constraints.iter().enumerate() {
            match c {
                Constraint::Road(r) => {
                    if let Some(k) = r.path.iter().position(|q| off(q.x, q.z)) {
                        return invalid(
                            format!("constraints[{i}].road.path[{k}]"),
                            format!("is off the grid (0..{w} m × 0..{d} m)"),
                        );
                    }
                }
                Constraint::Points(pts) => {
                    if let Some(k) = pts.points.iter().position(|q| off(q.x, q.z)) {
                        return invalid(
                            format!("constraints[{i}].points.points[{k}]"),
                            format!("is off the grid (0..{w} m × 0..{d} m)"),
                        );
                    }
                }
                Constraint::EdgeMatch(EdgeMatch { band_cells, .. })
                | Constraint::Tileable(Tileable { band_cells, .. })
                    if *band_cells as usize > shorter / 2 =>
                {
                    return invalid(
                        format!("constraints[{i}].{}.band_cells", c.name()),
                        format!("must be at most half the grid ({} cells)", shorter / 2),
                    );
                }
                _ => {}
            }
        }
        Ok(())
    }

    fn settings(&self, p: &DeformTerrainParams, fields: &[Field]) -> Result<Settings, SimError> {
        let shorter = self.cols.min(self.rows);
        let radii = p.radii_cells(shorter);
        let unit = search::unit_displacements(p.amplitudes as usize);
        let d_max: Vec<f64> = radii.iter().map(|&r| p.max_displacement_ratio * r as f64 * self.cell_m).collect();
        let deltas = d_max.iter().map(|&d| unit.iter().map(|u| u * d).collect()).collect();
        let (tile_x, tile_z) = fields
            .iter()
            .find_map(|f| match f.detail {
                constraints::Detail::Tileable { x, z } => Some((x, z)),
                _ => None,
            })
            .unwrap_or((false, false));
        Ok(Settings {
            max_iterations: p.max_iterations,
            epsilon: p.epsilon,
            stall_iterations: p.stall_iterations,
            stall_gain: p.stall_gain,
            p: p.p,
            top_fraction: p.top_fraction,
            prediction: p.prediction,
            prediction_constant: p.prediction_constant,
            batch: p.batch.max(1) as usize,
            kernels: radii.iter().map(|&r| Kernel::new(r)).collect(),
            deltas,
            d_max,
            cell_m: self.cell_m,
            tile_x,
            tile_z,
        })
    }
}

/// Progress and cancellation from a job's context.
struct JobWatch<'a, 'c> {
    ctx: &'a RunContext<'c>,
    cols: usize,
    rows: usize,
    cell_m: f64,
}

impl Watch for JobWatch<'_, '_> {
    type Stop = SimError;

    fn check(&self) -> Result<(), SimError> {
        self.ctx.check_cancelled()
    }

    fn progress(&self, iteration: u64, total: u64, fitness: f64, h: &[f64]) {
        self.ctx.report_with_snapshot(STAGE, iteration, total, format!("fitness {fitness:.3e}"), || {
            Ok(crate::export::snapshot_png(&to_heightfield(h, self.cols, self.rows, self.cell_m)))
        });
    }
}

fn to_heightfield(h: &[f64], cols: usize, rows: usize, cell_m: f64) -> Heightfield {
    Heightfield { cols, rows, cell_size_m: cell_m as f32, heights_m: h.iter().map(|&v| v as f32).collect() }
}

/// The keep pull inside a footprint, as a share of the pull outside ([`constraints::keep`]):
/// at 0.1 the examples ran 0.24–0.92 s with no spike and the earthworks within their slopes;
/// at 0 (none) the search stacked kernels 300 m high on `limit_tests`' 22 m of relief.
const KEEP_INSIDE: f64 = 0.1;

/// What only a run knows.
struct RunFigures<'a> {
    searched: Option<&'a Searched>,
    candidates: usize,
    prediction: bool,
}

/// `fitness.json`: the fitness after every iteration, in total and per constraint.
#[derive(serde::Serialize)]
struct FitnessLog<'a> {
    constraints: Vec<&'static str>,
    weights: Vec<f64>,
    iterations: &'a [Record],
}

/// The candidate vertices (Figure 2) with the radii each takes, a bit each, sorted by (row,
/// col). Anchors fit narrow features cell by cell, so they take the small radii only (the
/// inside of an area the smallest few); the lattice's vertices take every radius their place
/// allows (the wide ones a coarser lattice, away from narrow features and coasts). The maps
/// built on the way are dropped before the search.
fn vertices(
    params: &DeformTerrainParams,
    settings: &Settings,
    fields: &[Field],
    interest: &[bool],
    grid: &Grid,
) -> Vec<(usize, usize, u32)> {
    let coarse = params.coarse_spacing(grid.cols.min(grid.rows));
    let lattice =
        candidates::candidate_vertices(interest, grid.cols, grid.rows, coarse, params.min_spacing_cells as usize);
    let small = (1u32 << settings.kernels.len().min(ANCHOR_RADII)) - 1;
    let inside = (1u32 << settings.kernels.len().min(INSIDE_ANCHOR_RADII)) - 1;
    let narrow = candidates::distance_to(&constraints::placed_closely(fields, grid.cells()), grid.cols, grid.rows);
    let radii: Vec<usize> = settings.kernels.iter().map(|k| k.radius).collect();
    let steps: Vec<usize> = radii.iter().map(|&r| candidates::radius_step(r, coarse)).collect();
    let place = |c: usize, r: usize| {
        candidates::radii_at((c, r), (grid.cols, grid.rows), coarse, &radii, &steps, narrow[r * grid.cols + c])
    };
    let mut vertices: Vec<(usize, usize, u32)> = lattice.iter().map(|&(c, r)| (c, r, place(c, r))).collect();
    vertices.extend(
        constraints::anchors(fields, grid.cols)
            .into_iter()
            .map(|(c, r, within)| (c, r, if within { inside } else { small })),
    );
    vertices.sort_by_key(|&(c, r, _)| (r, c));
    vertices.dedup_by(|later, kept| {
        let same = (later.0, later.1) == (kept.0, kept.1);
        if same {
            kept.2 |= later.2;
        }
        same
    });
    vertices
}

#[allow(clippy::too_many_arguments)]
fn finish(
    problem: &Problem,
    fields: &[Field],
    h: &[f64],
    history: &[Record],
    interest: &[bool],
    settings: &Settings,
    sequence: DeformSequence,
    run: RunFigures,
    output: HeightfieldExport,
) -> Result<Outcome<DeformSequence>, SimError> {
    let grid = problem.grid();
    if let Some(i) = h.iter().position(|v| !v.is_finite()) {
        return Err(SimError::Failed(format!("non-finite height at sample {i}")));
    }
    // sequence.bin replays the search's heights; with the limits on, the slope limit and the
    // pins are then held exactly, and the seam filter follows (a 3-tap mean keeps every step
    // within the limit), in run and replay alike.
    let searched = h;
    let (held, conflicts) = match problem.params.limited() {
        true => {
            let band = tile_band(problem.params);
            let (held, conflicts) = hold_limits(fields, &grid, settings, problem.params.max_free_change, band, h);
            (Some(held), conflicts)
        }
        false => (None, Vec::new()),
    };
    let h = held.as_deref().unwrap_or(h);
    let filtered = filter_seams(problem, h);
    let h = filtered.as_deref().unwrap_or(h);
    let hf = to_heightfield(h, grid.cols, grid.rows, grid.cell_m);
    let log = FitnessLog {
        constraints: fields.iter().map(|f| f.name).collect(),
        weights: fields.iter().map(|f| f.weight).collect(),
        iterations: history,
    };
    let roads = constraints::road_material(fields, grid.cells());
    let sea_level_m = constraints::water_level(fields).unwrap_or(0.0) as f32;
    let options = HeightfieldExport { material: roads.as_deref(), sea_level_m, ..output };
    // Packing (which replays the sequence to check it), the logs and the pictures and meshes
    // are independent: each on a thread of its own.
    let ((packed, logs), exported) = rayon::join(
        || {
            rayon::join(
                || pack(problem, &sequence, searched),
                || -> Result<(Vec<u8>, usize), SimError> {
                    let fitness_json = serde_json::to_vec(&log).map_err(|e| SimError::Failed(e.to_string()))?;
                    // The length of the `sequence.json` the adapter writes, counted, not kept.
                    let mut counted = crate::model::ByteCount(0);
                    serde_json::to_writer_pretty(&mut counted, &sequence)
                        .map_err(|e| SimError::Failed(e.to_string()))?;
                    let sequence_bytes = counted.0;
                    Ok((fitness_json, sequence_bytes))
                },
            )
        },
        || crate::export::heightfield_artifacts(&hf, &options),
    );
    let (fitness_json, sequence_bytes) = logs?;
    let exported = exported?;
    let heightmap_png_bytes =
        exported.artifacts.iter().find(|a| a.name == "heightmap.png").map_or(0, |a| a.bytes.len());
    let mut result = match exported.summary {
        Value::Object(map) => map,
        other => [("export".to_string(), other)].into_iter().collect::<Map<_, _>>(),
    };
    let (mut limits, asked) = limits_figures(fields, &grid, problem.params.max_free_change, h);
    if let Some(held) = &held {
        // How much the projection had to do after the search.
        let moved = held.iter().zip(searched).filter(|(a, b)| a != b).count();
        let most = held.iter().zip(searched).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        limits["held"] = json!({"samples_moved": moved, "max_change_m": most});
    }
    // Far from every cell a constraint refines around or asks to move (a road's earthworks).
    let asked: Vec<bool> = asked.iter().zip(interest).map(|(&a, &i)| a || i).collect();
    let total: f64 = fields.iter().map(|f| f.weight * f.value(h, grid.cols, grid.rows)).sum();
    let max_radius = settings.kernels.iter().map(|k| k.radius).max().unwrap_or(1);
    let figures: Vec<Value> = fields.iter().map(|f| f.figures(h, &grid)).collect();
    result.insert("fitness".into(), json!(total));
    result.insert("fitness_initial".into(), json!(history.first().map_or(total, |r| r.total)));
    result.insert("constraints".into(), Value::Array(figures));
    result.insert("operations".into(), json!(sequence.operations.len()));
    let iterations = run.searched.map_or(history.len().saturating_sub(1) as u64, |s| s.iterations);
    result.insert("iterations".into(), json!(iterations));
    result.insert("prediction".into(), json!(run.prediction));
    if let Some(s) = run.searched {
        result.insert("evaluations".into(), json!(s.evaluations));
        result.insert("candidate_vertices".into(), json!(run.candidates));
        result.insert(
            "stopped".into(),
            json!(match s.stop {
                Stop::Epsilon => "epsilon",
                Stop::MaxIterations => "max_iterations",
                Stop::NoImprovement => "no_improvement",
                Stop::Stalled => "stalled",
            }),
        );
    }
    result.insert(
        "far_cells".into(),
        far_cells(h, &problem.original, &asked, grid.cols, grid.rows, 2 * max_radius, grid.relief),
    );
    result.insert("limits".into(), limits);
    result.insert("conflicts".into(), conflicts_json(&conflicts, fields, &grid));
    result.insert("sequence_bytes".into(), json!(sequence_bytes));
    result.insert(
        "sequence_bin".into(),
        json!({
            "bytes": packed.bytes.len(),
            "operations": packed.operations,
            "quantum_m": packed.quantum_m,
            "tolerance_m": packed.tolerance_m,
            "max_error_m": packed.max_error_m,
        }),
    );
    result.insert("heightmap_png_bytes".into(), json!(heightmap_png_bytes));
    let mut artifacts = exported.artifacts;
    artifacts.push(Artifact::new("fitness.json", "application/json", fitness_json));
    artifacts.push(Artifact::new("sequence.bin", "application/octet-stream", packed.bytes));
    if let Some(roads) = constraints::roads_json(fields, h, &grid) {
        let bytes = serde_json::to_vec(&roads).map_err(|e| SimError::Failed(e.to_string()))?;
        artifacts.push(Artifact::new("road.json", "application/json", bytes));
    }
    Ok(Outcome { result: Value::Object(result), sequence, artifacts })
}

/// How the result keeps to the limits ([`bounds`]): the limits, the footprint's size, and
/// outside it the share of samples within a tenth of the relief of their input height and the
/// largest change; the steepest step against the input's.
fn limits_figures(fields: &[Field], grid: &Grid, max_free_change: f64, h: &[f64]) -> (Value, Vec<bool>) {
    let b = bounds::Bounds::new(fields, grid, max_free_change);
    let (mut outside, mut within, mut worst) = (0u64, 0u64, 0.0f64);
    for (i, (&v, &o)) in h.iter().zip(grid.original).enumerate() {
        if !b.footprint[i] {
            outside += 1;
            within += u64::from((v - o).abs() <= 0.1 * grid.relief);
            worst = worst.max((v - o).abs());
        }
    }
    let figures = json!({
        "max_step_m": b.step_max,
        "footprint_samples": b.footprint.iter().filter(|&&f| f).count(),
        "outside_footprint": {
            "samples": outside,
            "share_within_tenth_of_relief": if outside == 0 { 1.0 } else { within as f64 / outside as f64 },
            "max_change_of_relief": worst / grid.relief,
        },
        "steepest_step_m": bounds::steepest_step(h, grid.cols, grid.rows),
        "input_steepest_step_m": bounds::steepest_step(grid.original, grid.cols, grid.rows),
    });
    (figures, b.asked)
}

/// `h` within the slope limit everywhere and the free samples within their band, each held
/// sample within its bounds by priority ([`projection`]), a tiled terrain's opposite edges
/// then set to their mean; and the held targets it could not meet.
fn hold_limits(
    fields: &[Field],
    grid: &Grid,
    settings: &Settings,
    max_free_change: f64,
    tile_band: Option<usize>,
    h: &[f64],
) -> (Vec<f64>, Vec<projection::Conflict>) {
    let (cols, rows) = (grid.cols, grid.rows);
    // Held a few f32 steps of the highest height inside the limit, so the f32 heights the
    // artifacts carry keep to it too.
    let highest = h.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let margin = 4.0 * f64::from(f32::EPSILON) * highest;
    let step_max = (grid.slope_limit * grid.cell_m - margin).max(0.0);
    let mut limits = bounds::EdgeLimits::new(grid.original, cols, rows, step_max);
    (limits.wrap_x, limits.wrap_z) = (settings.tile_x, settings.tile_z);
    let bounds = bounds::Bounds::new(fields, grid, max_free_change);
    let held = constraints::held(fields);
    let face = |slope: f64| (slope * grid.cell_m - margin).max(0.0);
    let terrace = &held[constraints::Priority::Terrace as usize];
    let mut regions = vec![false; grid.cells()];
    for b in terrace {
        regions[b.sample] = true;
    }
    let mut tiers: Vec<projection::Tier> = Vec::new();
    for (p, held) in constraints::Priority::ALL.iter().zip(&held) {
        let (cut, fill) = if p.earthwork() { (face(grid.cut), face(grid.fill)) } else { (step_max, step_max) };
        tiers.push(projection::Tier { held, cut, fill, pin: p.pinned(), skip: None });
        if *p == constraints::Priority::Terrace && !held.is_empty() {
            // The apron around the regions, at the earthworks' slopes.
            let (cut, fill) = (face(grid.cut), face(grid.fill));
            tiers.push(projection::Tier { held, cut, fill, pin: false, skip: Some(&regions) });
        }
    }
    // A mask's sea floor no lower than the input's (or the sea's bound, where the input stands
    // above it): the pits the search's kernels dug pushing the sea under are filled back, and
    // the projection lowers only what stands too high.
    let mut undug = h.to_vec();
    for b in &held[constraints::Priority::Mask as usize] {
        if b.lo == f64::NEG_INFINITY {
            let i = b.sample;
            undug[i] = undug[i].max(grid.original[i].min(b.hi));
        }
    }
    let mut out = projection::hold(&undug, cols, rows, &limits, Some(bounds.band()), &tiers);
    let conflicts = projection::conflicts(&out, cols, &tiers, CONFLICT_TOLERANCE_M.max(1e-6 * grid.relief));
    let mut pair = |a: usize, b: usize| {
        let m = 0.5 * (out[a] + out[b]);
        out[a] = m;
        out[b] = m;
    };
    if settings.tile_x {
        for r in 0..rows {
            pair(r * cols, r * cols + cols - 1);
        }
    }
    if settings.tile_z {
        for c in 0..cols {
            pair(c, (rows - 1) * cols + c);
        }
    }
    if let Some(band) = tile_band {
        let reach = band.clamp(2, cols.min(rows) / 4);
        if settings.tile_x {
            for r in 0..rows {
                smooth_wrap(&mut out, r * cols, 1, cols, reach);
            }
        }
        if settings.tile_z {
            for c in 0..cols {
                smooth_wrap(&mut out, c, cols, rows, reach);
            }
        }
    }
    (out, conflicts)
}

/// A `tileable` constraint's wrap band, in samples.
fn tile_band(params: &DeformTerrainParams) -> Option<usize> {
    params.constraints.iter().find_map(|c| match c {
        Constraint::Tileable(t) => Some(t.band_cells as usize),
        _ => None,
    })
}

/// Make a line of `n` samples (from `start`, `stride` apart), whose ends are one sample on a
/// tile, C¹ across its wrap: the slope mismatch k between its first and last steps is shared
/// out, each end's step moved by k/2 towards the other's and the change faded out over `reach`
/// samples by d(j) = j (1 − (j − 1)/(reach − 1))² (d(1) = 1, d(reach) = 0, flat there), so
/// its bends are about 2k/reach. The slope limit's clipping near the wrap bent it by up to
/// 1.1 × the terrain's own 99th-percentile bend; this may steepen a step there by k/2.
fn smooth_wrap(h: &mut [f64], start: usize, stride: usize, n: usize, reach: usize) {
    let at = |j: usize| start + j * stride;
    let k = (h[at(1)] - h[at(0)]) - (h[at(n - 1)] - h[at(n - 2)]);
    let fade = |j: usize| {
        let t = 1.0 - (j as f64 - 1.0) / (reach as f64 - 1.0);
        j as f64 * t * t
    };
    for j in 1..reach {
        // The first step falls by k/2, the last rises by k/2.
        h[at(j)] -= 0.5 * k * fade(j);
        h[at(n - 1 - j)] -= 0.5 * k * fade(j);
    }
}

/// A held target missed by less than this is met (a centimetre).
const CONFLICT_TOLERANCE_M: f64 = 0.01;

/// `conflicts`: each constraint a held target of which the result misses, where it misses
/// worst, by how much, and the constraint that won there.
fn conflicts_json(conflicts: &[projection::Conflict], fields: &[Field], grid: &Grid) -> Value {
    let at =
        |i: usize| json!({"x_m": (i % grid.cols) as f64 * grid.cell_m, "z_m": (i / grid.cols) as f64 * grid.cell_m});
    let bound = |v: f64| if v.is_finite() { json!(v) } else { Value::Null };
    Value::Array(
        conflicts
            .iter()
            .map(|c| {
                json!({
                    "constraint": c.source,
                    "kind": fields[c.source as usize].name,
                    "at": at(c.sample),
                    "wanted_min_m": bound(c.target_lo),
                    "wanted_max_m": bound(c.target_hi),
                    "missed_by_m": c.missed_m,
                    "held_by": {"constraint": c.by, "kind": fields[c.by as usize].name, "at": at(c.by_sample)},
                })
            })
            .collect(),
    )
}

/// The heights with the 3 × 1 seam filter of every `edge_match` that asks for it, if any does.
fn filter_seams(problem: &Problem, h: &[f64]) -> Option<Vec<f64>> {
    let edges: Vec<Edge> = problem
        .params
        .constraints
        .iter()
        .filter_map(|c| match c {
            Constraint::EdgeMatch(e) if e.seam_filter => Some(e.edges.clone()),
            _ => None,
        })
        .flatten()
        .collect();
    (!edges.is_empty()).then(|| constraints::seam_filter(h, problem.cols, problem.rows, &edges))
}

/// `sequence.bin` of the sequence that ended at `h`, within the requested tolerance (absent:
/// half a step of the 16-bit heightmap over `h`'s range).
fn pack(problem: &Problem, sequence: &DeformSequence, h: &[f64]) -> packed::Packed {
    let (lo, hi) = h.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let step = if hi > lo { (hi - lo) / 65535.0 } else { 0.0 };
    let tolerance = problem.params.sequence_tolerance_m.unwrap_or(step / 2.0);
    let start = packed::Start { original: &problem.original, cols: problem.cols, rows: problem.rows };
    packed::encode(sequence, &start, h, tolerance)
}

/// Cells at least `distance` cells (Chebyshev) from every marked cell: how many, and
/// their largest change from the original as a share of the relief.
fn far_cells(
    h: &[f64],
    original: &[f64],
    interest: &[bool],
    cols: usize,
    rows: usize,
    distance: usize,
    relief: f64,
) -> Value {
    let near = dilate(interest, cols, rows, distance.saturating_sub(1));
    let mut count = 0u64;
    let mut worst = 0.0f64;
    for i in 0..h.len() {
        if !near[i] {
            count += 1;
            worst = worst.max((h[i] - original[i]).abs());
        }
    }
    json!({ "distance_cells": distance, "cells": count, "max_change_of_relief": worst / relief })
}

/// Mark every cell within `d` (Chebyshev) of a marked one: a separable max filter.
fn dilate(marked: &[bool], cols: usize, rows: usize, d: usize) -> Vec<bool> {
    let pass = |src: &[bool], along_rows: bool| {
        let mut out = vec![false; src.len()];
        let (n, m) = if along_rows { (rows, cols) } else { (cols, rows) };
        for a in 0..n {
            let idx = |b: usize| if along_rows { a * cols + b } else { b * cols + a };
            // Distance to the last marked cell seen, forward then backward.
            let mut last: Option<usize> = None;
            for b in 0..m {
                if src[idx(b)] {
                    last = Some(b);
                }
                if last.is_some_and(|l| b - l <= d) {
                    out[idx(b)] = true;
                }
            }
            last = None;
            for b in (0..m).rev() {
                if src[idx(b)] {
                    last = Some(b);
                }
                if last.is_some_and(|l| l - b <= d) {
                    out[idx(b)] = true;
                }
            }
        }
        out
    };
    let once = pass(marked, true);
    pass(&once, false)
}

/// Apply a sequence's first operations to a heightfield without a job (benches, tests).
pub fn apply_sequence(hf: &Heightfield, operations: &[Deformation]) -> Heightfield {
    let mut h: Vec<f64> = hf.heights_m.iter().map(|&v| v as f64).collect();
    for op in operations {
        kernel::apply(
            &mut h,
            hf.cols,
            hf.rows,
            op.col as usize,
            op.row as usize,
            op.amplitude as f64,
            &Kernel::new(op.radius_cells as usize),
        );
    }
    to_heightfield(&h, hf.cols, hf.rows, hf.cell_size_m as f64)
}
