//! The `deform-terrain` request: a terrain, the constraints it must satisfy, and the search's
//! settings (paper §3.3–3.5).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::export::TileGrid;
use crate::terrain::TerrainSource;
use crate::validate::{Limits, Validate, Validator};

/// Most search iterations a request may ask for (413 beyond).
pub const MAX_ITERATIONS: u32 = 20_000;
/// Most sampled amplitudes and radii.
pub const MAX_AMPLITUDES: u32 = 101;
pub const MAX_RADII: u32 = 32;
/// Most operations one job may record (max_iterations × batch): each is a line of
/// `sequence.json` and of `fitness.json`.
pub const MAX_OPERATIONS_PER_JOB: u64 = 1_000_000;
/// Most constraints one request may combine: each holds a few per-cell arrays.
pub const MAX_CONSTRAINTS: usize = 32;
/// Largest kernel radius in cells: a (2r+1)² weight table each, and a window that wide to sum.
pub const MAX_RADIUS_CELLS: u32 = 512;
/// Largest `max_displacement_ratio`: beyond it, displacements dwarf the kernel (§3.4).
pub const MAX_DISPLACEMENT_RATIO: f64 = 10.0;
/// Most road vertices, points and polygon vertices, each.
pub const MAX_VERTICES: usize = 10_000;
/// Most vertices of a road's path, or of a mask's polygons together: building a road or a
/// polygon mask visits the grid once per segment.
pub const MAX_OUTLINE_VERTICES: usize = 256;

fn one() -> f64 {
    1.0
}
fn default_max_iterations() -> u32 {
    500
}
fn default_epsilon() -> f64 {
    1e-6
}
fn default_stall_iterations() -> u32 {
    50
}
fn default_stall_gain() -> f64 {
    0.01
}
fn default_p() -> f64 {
    0.65
}
fn default_top_fraction() -> f64 {
    0.05
}
fn default_amplitudes() -> u32 {
    25
}
fn default_radii() -> u32 {
    7
}
fn default_min_radius() -> u32 {
    2
}
fn default_ratio() -> f64 {
    0.5
}
fn default_min_spacing() -> u32 {
    2
}
fn default_true() -> bool {
    true
}
fn default_prediction_constant() -> f64 {
    0.1
}
fn default_batch() -> u32 {
    16
}
fn default_band() -> u32 {
    16
}

/// Deform a terrain by stochastic local search over truncated-Gaussian deformations until it
/// satisfies the constraints (Tasse & Gain's "fractal terrain deformation" seed, §3).
///
/// Each constraint is a fitness F_c: a sum of per-vertex penalties divided by (constrained
/// vertices × relief²), relief = the starting terrain's max − min, so F_c is a mean-square
/// error in units of relief². The search minimises F = Σ weight_c · F_c. Every length and
/// coordinate is metres on the grid: x along columns, z along rows, sample (col, row) at
/// (col × cell size, row × cell size); only radii, spacings and bands count cells.
///
/// Besides the heightfield artifacts a job writes `fitness.json` (the fitness after every
/// iteration), `sequence.bin` (the terrain compressed as its deformation sequence, within
/// `sequence_tolerance_m`) and, with a road, `road.json` (every road constraint's centreline in
/// metres with the deformed terrain's height along it, its width and the gradient reached).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformTerrainParams)]
pub struct DeformTerrainParams {
    /// The starting terrain.
    pub terrain: TerrainSource,
    /// The constraints, combined by their weights (at least one, at most 32; at most one
    /// `shape_mask` and one `tileable`).
    // 32 = MAX_CONSTRAINTS
    #[schema(min_items = 1, max_items = 32)]
    pub constraints: Vec<Constraint>,
    /// Stop after this many iterations (each applies 1 to `batch` deformations). At most
    /// 20 000 and at most the server's operation cap (100 000 by default); `max_iterations` ×
    /// `batch` at most 1 000 000 (more is answered with 413).
    #[serde(default = "default_max_iterations")]
    // 20000 = MAX_ITERATIONS
    #[schema(default = 500, minimum = 1, maximum = 20000)]
    pub max_iterations: u32,
    /// Stop once F ≤ epsilon.
    #[serde(default = "default_epsilon")]
    #[schema(default = 1e-6, minimum = 0.0)]
    pub epsilon: f64,
    /// Stop when F has fallen by less than `stall_gain` of itself over the last
    /// `stall_iterations` iterations: the search has stalled, and the projection finishes the
    /// constraints (`stopped`: `stalled`): a search that ran to `max_iterations` spent most of
    /// its time gaining little. 0: never.
    #[serde(default = "default_stall_iterations")]
    // 20000 = MAX_ITERATIONS
    #[schema(default = 50, minimum = 0, maximum = 20000)]
    pub stall_iterations: u32,
    /// See `stall_iterations`: the share of F it must fall by to go on.
    #[serde(default = "default_stall_gain")]
    #[schema(default = 0.01, minimum = 0.0, maximum = 1.0)]
    pub stall_gain: f64,
    /// Probability of taking the best deformation; otherwise one of the top fraction (§3.3).
    #[serde(default = "default_p")]
    #[schema(default = 0.65, minimum = 0.0, maximum = 1.0)]
    pub p: f64,
    /// The share of the candidate table a non-greedy choice is drawn from.
    #[serde(default = "default_top_fraction")]
    #[schema(default = 0.05, minimum = 0.0, maximum = 1.0)]
    pub top_fraction: f64,
    /// Displacements sampled per (vertex, radius), spread over ±max_displacement_ratio·radius
    /// (zero excluded); the closed-form best displacement of the quadratic penalties is tried too.
    #[serde(default = "default_amplitudes")]
    // 101 = MAX_AMPLITUDES
    #[schema(default = 25, minimum = 1, maximum = 101)]
    pub amplitudes: u32,
    /// Radii sampled, geometric between `min_radius_cells` and `max_radius_cells`.
    #[serde(default = "default_radii")]
    // 32 = MAX_RADII
    #[schema(default = 7, minimum = 1, maximum = 32)]
    pub radii: u32,
    /// The smallest radius: 2 lets a deformation move a vertex with its neighbours at 0.31,
    /// fine enough to seat a road within half a percent of the relief; 1 would move single
    /// cells, the spikes of the paper's Figure 3. At most 512 (more is answered with 413), and
    /// smaller than the terrain's shorter side in samples.
    #[serde(default = "default_min_radius")]
    // 512 = MAX_RADIUS_CELLS
    #[schema(default = 2, minimum = 1, maximum = 512)]
    pub min_radius_cells: u32,
    /// Absent: an eighth of the terrain's shorter side. At least `min_radius_cells`, at most 512
    /// (more is answered with 413), and smaller than the terrain's shorter side in samples.
    #[serde(default)]
    // 512 = MAX_RADIUS_CELLS
    #[schema(minimum = 1, maximum = 512)]
    pub max_radius_cells: Option<u32>,
    /// Frequency limitation (§3.4): a displacement may be at most this times the radius (both
    /// in metres).
    #[serde(default = "default_ratio")]
    // 10 = MAX_DISPLACEMENT_RATIO
    #[schema(default = 0.5, exclusive_minimum = 0.0, maximum = 10.0)]
    pub max_displacement_ratio: f64,
    /// Spacing of the coarse uniform grid of candidate vertices (Figure 2). Absent: a
    /// sixteenth of the terrain's shorter side.
    #[serde(default)]
    #[schema(minimum = 1)]
    pub coarse_spacing_cells: Option<u32>,
    /// Smallest quadtree cell around constrained regions. Wide kernels are offered on a coarser
    /// lattice, a power of two near a quarter of their radius, except where a road, seam,
    /// point or mask coastline lies within their radius; cells of a road, seam or point (and of a terrace
    /// region, its inside with the two smallest radii only) are candidates themselves.
    #[serde(default = "default_min_spacing")]
    #[schema(default = 2, minimum = 1)]
    pub min_spacing_cells: u32,
    /// Prediction with per-deformation confidence (§3.5): skip recomputing unlikely candidates.
    #[serde(default = "default_true")]
    #[schema(default = true)]
    pub prediction: bool,
    /// The constant C that raises every confidence so each candidate is recomputed eventually.
    #[serde(default = "default_prediction_constant")]
    #[schema(default = 0.1, exclusive_minimum = 0.0, maximum = 1.0)]
    pub prediction_constant: f64,
    /// Deformations applied per iteration. After the chosen one (§3.3), further improving
    /// candidates are added best first while their kernel windows (with their tileable
    /// partners) stay clear of every window already taken this iteration, so each one's change
    /// in fitness is exact and the changes add. Each is recorded as its own operation. 1 is the
    /// paper's one deformation per iteration. `max_iterations` × `batch` at most 1 000 000
    /// (more is answered with 413).
    #[serde(default = "default_batch")]
    #[schema(default = 16, minimum = 1, maximum = 256)]
    pub batch: u32,
    /// Cut the terrain's mesh into tiles as well, at every level of detail (`tiles/…`).
    /// Absent: no tiles.
    #[serde(default)]
    pub tiles: Option<TileGrid>,
    /// `sequence.bin` (the compressed terrain) replays to within this many metres of the
    /// result at every sample: each vertex's operations of one radius are summed into one (in
    /// raster order, not the run's), the sums quantised and those of no step left out until
    /// it holds. 0: amplitudes exact and every operation kept in the run's order, so its
    /// replay is bit-identical to `sequence.json`'s. Absent: half a step of the 16-bit
    /// `heightmap.png` (the result's height range / 65 535 / 2), the PNG's own rounding. Never
    /// finer than four f32 steps of the highest height (what the f32 heights themselves hold;
    /// 1.4 mm at 3 000 m): the result's `sequence_bin.tolerance_m` gives the one held.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    // 1e6 = MAX_METRES
    #[schema(minimum = 0.0, maximum = 1000000.0)]
    pub sequence_tolerance_m: Option<f64>,
    /// The pull of every sample no constraint asks about back to its input height (the
    /// paper's "the original terrain be preserved as much as possible", §3.1): the mean
    /// square of their changes in units of relief², weighted against the constraints. It is
    /// not part of the fitness the search stops on (`epsilon`) or reports per constraint.
    /// Samples in a constraint's footprint (see `max_free_change`) other than its targets are
    /// pulled a tenth as hard, so kernels do not pile up there. 0: none, the constraints alone
    /// decide, within the limits below.
    #[serde(default = "one")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1000000.0)]
    pub keep_weight: f64,
    /// How far a sample outside every constraint's footprint may move, as a share of the
    /// input's relief: held after the search, with the slope limit (which has the last word;
    /// the result's `limits` says how many samples kept within a tenth). A constraint's
    /// footprint is what it needs to move (a road's cells, a mask's samples on the wrong side,
    /// a point, a region, a seam band), the earthwork around it (faces at the `earthworks`
    /// slopes from a target, at 0.8 × the slope limit from a mask or a seam, down or up to the
    /// input ground, as a road's cutting daylights), and room beyond for transitions half as
    /// steep. Past a seam band, also at most the band's own largest wanted change. The search
    /// itself only pulls samples back to their input (`keep_weight`, a tenth as hard inside
    /// a footprint), so it keeps to its fast path. 1 with `max_slope_ratio` 100: no limits
    /// (the paper's search alone, with nothing to stop free terrain drifting or steps growing
    /// many times steeper than the input's).
    #[serde(default = "default_max_free_change")]
    #[schema(default = 0.1, minimum = 0.0, maximum = 1.0)]
    pub max_free_change: f64,
    /// The steepest step between row or column neighbours the result may have, as a multiple
    /// of the input's steps' `slope_percentile` (on a flat input, 5 %); where the input's own
    /// step is steeper, that step (and no limit inside a `tileable` wrap band, whose fit keeps
    /// the tile C¹). After the search, every step is held within it exactly, every road cell,
    /// point, terrace sample and seam edge is set on its target and a mask's land and sea on
    /// their sides of the water, the samples beside them moved as little as that takes: a
    /// cutting or an embankment at the `earthworks` slopes from a road or a point, an apron
    /// at those slopes around a terrace's regions (at the limit between two of them), a shore
    /// at the limit from a mask. Where two targets cannot both be met (a point high above a
    /// road beside it), the one of higher priority holds — a seam over a road over a terrace
    /// over a point over a mask's side — and the result names the other in `conflicts`. 1:
    /// never steeper than the input's percentile; raise it for sharp terraces, cliffs or a
    /// seam band narrower than its mismatch needs. 100 with `max_free_change` 1: no limits.
    #[serde(default = "default_max_slope_ratio")]
    #[schema(default = 1.1, minimum = 1.0, maximum = 100.0)]
    pub max_slope_ratio: f64,
    /// Which of the input's steps the slope limit is a multiple of: this percentile of their
    /// steepness (100: the single steepest step). The input's own steps steeper than the limit
    /// stay as they are; no step is made steeper than the limit or than it was.
    #[serde(default = "default_slope_percentile")]
    #[schema(default = 99.0, minimum = 50.0, maximum = 100.0)]
    pub slope_percentile: f64,
    /// The faces cut into the ground or built up on it beside a road, a terrace or a point
    /// (with the limits on): their slopes.
    #[serde(default)]
    pub earthworks: Earthworks,
}

/// The faces the projection builds from the held targets (roads, points, terraces' regions)
/// to the ground: a cutting where the ground stood above its target, an embankment where it
/// lay below, each at its slope until it daylights, the ground beyond as the search left it.
/// Road practice (AASHTO, FHWA): cuts at 1V:1.5H to 2H, fills at 1V:2H to 3H; loose material
/// rests at 34–37°.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformEarthworks)]
pub struct Earthworks {
    /// The slope of a cutting's face. Default 1V:1.5H (33.7°).
    #[serde(default = "default_cut_slope")]
    #[schema(default = json!({"h_per_v": 1.5}))]
    pub cut_slope: Slope,
    /// The slope of an embankment's face (a terrace's or mesa's talus apron too). Default
    /// 1V:2H (26.6°).
    #[serde(default = "default_fill_slope")]
    #[schema(default = json!({"h_per_v": 2.0}))]
    pub fill_slope: Slope,
}

impl Default for Earthworks {
    fn default() -> Self {
        Self { cut_slope: default_cut_slope(), fill_slope: default_fill_slope() }
    }
}

/// A slope, as run over rise (`{"h_per_v": 1.5}` is 1V:1.5H) or in degrees from level
/// (`{"degrees": 30}`): exactly one of the two.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformSlope)]
pub struct Slope {
    /// Horizontal metres per vertical metre.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 0.05, maximum = 100.0)]
    pub h_per_v: Option<f64>,
    /// Degrees from level.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 0.5, maximum = 87.0)]
    pub degrees: Option<f64>,
}

impl Slope {
    pub fn h_per_v(h: f64) -> Self {
        Self { h_per_v: Some(h), degrees: None }
    }

    /// Metres of rise per metre of run (validated: exactly one form, within its range).
    pub fn gradient(self) -> f64 {
        match (self.h_per_v, self.degrees) {
            (Some(h), _) => 1.0 / h,
            (None, Some(d)) => d.to_radians().tan(),
            (None, None) => 1.0,
        }
    }

    fn validate(self, v: &mut Validator, field: &str) {
        v.field(field, |v| match (self.h_per_v, self.degrees) {
            (Some(h), None) => v.in_range("h_per_v", h, 0.05, 100.0),
            (None, Some(d)) => v.in_range("degrees", d, 0.5, 87.0),
            _ => v.error("", "give exactly one of h_per_v and degrees"),
        });
    }
}

fn default_cut_slope() -> Slope {
    Slope::h_per_v(1.5)
}

fn default_fill_slope() -> Slope {
    Slope::h_per_v(2.0)
}

fn default_slope_percentile() -> f64 {
    99.0
}

fn default_max_free_change() -> f64 {
    0.1
}

fn default_max_slope_ratio() -> f64 {
    1.1
}

impl DeformTerrainParams {
    /// Whether the request asks for the limits ([`super::bounds`]).
    pub fn limited(&self) -> bool {
        self.max_free_change < 1.0 || self.max_slope_ratio < 100.0
    }
}

/// One constraint: exactly one of the kinds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
#[schema(as = DeformConstraint)]
pub enum Constraint {
    MatchHeightmap(MatchHeightmap),
    ShapeMask(ShapeMask),
    Road(Road),
    EdgeMatch(EdgeMatch),
    Tileable(Tileable),
    Points(Points),
    Preserve(Preserve),
    Terraces(Terraces),
}

/// Penalise (h − t)² against a desired heightfield of the same size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformMatchHeightmap)]
pub struct MatchHeightmap {
    pub target: TerrainSource,
    #[serde(default = "one")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1000000.0)]
    pub weight: f64,
}

/// Where land must be above `water_level` (equation 3, with a margin).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformShapeMask)]
pub struct ShapeMask {
    pub mask: MaskShape,
    /// Metres. Absent: the starting terrain's median height.
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub water_level: Option<f64>,
    /// Land wants h ≥ water_level + margin, sea h ≤ water_level − margin; metres. Absent: 1% of
    /// the relief.
    #[serde(default)]
    // 1e6 = MAX_METRES
    #[schema(minimum = 0.0, maximum = 1e6)]
    pub margin: Option<f64>,
    #[serde(default = "one")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1000000.0)]
    pub weight: f64,
}

/// The land mask: an image of the terrain's size (brighter than its mid-range = land; e.g. an
/// 8- or 16-bit grayscale PNG as a `heightmap`, white = land), or polygons.
///
/// Polygons were once given in grid cells (`polygons`, [col, row] pairs); that form is refused
/// with a problem saying what replaced it, since the same numbers would mean other places.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields, try_from = "MaskForm")]
#[schema(as = DeformMaskShape)]
pub enum MaskShape {
    Image(TerrainSource),
    /// Polygons of points in metres on the grid (x along columns, z along rows, sample (col,
    /// row) at (col × cell size, row × cell size)); land is inside any of them (even-odd). At
    /// least one polygon, each of at least 3 vertices, at most 256 vertices in all (more is
    /// answered with 413); coordinates within ±1 000 000.
    PolygonsM(Vec<Vec<PlanPoint>>),
}

/// What a mask may be sent as, the retired form included.
#[derive(Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum MaskForm {
    Image(TerrainSource),
    PolygonsM(Vec<Vec<PlanPoint>>),
    Polygons(serde::de::IgnoredAny),
}

/// Said when a request uses the retired form.
pub const RETIRED_POLYGONS: &str = "`polygons` ([col, row] grid cells) was replaced by `polygons_m`: every \
     coordinate is now metres on the grid, each vertex {\"x\": col × cell size, \"z\": row × cell size}";

impl TryFrom<MaskForm> for MaskShape {
    type Error = &'static str;

    fn try_from(form: MaskForm) -> Result<Self, Self::Error> {
        match form {
            MaskForm::Image(src) => Ok(Self::Image(src)),
            MaskForm::PolygonsM(polys) => Ok(Self::PolygonsM(polys)),
            MaskForm::Polygons(_) => Err(RETIRED_POLYGONS),
        }
    }
}

/// A road: cells within width/2 of the polyline want the road's height; other cells their
/// original height (equation 4), over the whole terrain or only the road's corridor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformRoad)]
pub struct Road {
    /// At least 2 points and at most 256 (more is answered with 413), in metres, on the grid.
    // 256 = MAX_OUTLINE_VERTICES
    #[schema(min_items = 2, max_items = 256)]
    pub path: Vec<PlanPoint>,
    /// Metres; at most half the terrain's extent (its longer side).
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub width_m: f64,
    pub height: RoadHeight,
    /// Beyond the road's edge, the pull back to the original terrain grows linearly from 0 to
    /// full over this distance, leaving room for cuttings and embankments. Absent: four times
    /// the width. At most half the terrain's extent (its longer side).
    #[serde(default)]
    // 1e6 = MAX_METRES
    #[schema(minimum = 0.0, maximum = 1e6)]
    pub shoulder_m: Option<f64>,

    /// The weight of the preservation term (other cells pulled back to their original heights)
    /// relative to the road-cell term; both are mean squares in units of relief². 0 leaves the
    /// rest of the terrain to the other constraints.
    #[serde(default = "one")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1000000.0)]
    pub preserve_weight: f64,
    /// Where the preservation term applies. `everywhere` is equation 4 as written: every
    /// non-road cell is pulled to its original height. `corridor` keeps the pull only within the
    /// road's shoulder (width/2 + `shoulder_m` of the path), with the same per-cell weight, so the
    /// road does not fight terrain-wide constraints (a shape mask, a target heightmap, another
    /// road) elsewhere; add a `preserve` constraint for a terrain-wide pull. Absent: `everywhere`
    /// when the road is the request's only constraint, `corridor` when it is combined with
    /// others (the paper's star island with roads, Figure 4).
    #[serde(default)]
    pub preserve: Option<RoadPreserve>,
    #[serde(default = "one")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1000000.0)]
    pub weight: f64,
}

/// Where a road's preservation term applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = DeformRoadPreserve)]
pub enum RoadPreserve {
    Everywhere,
    Corridor,
}

/// A horizontal position in metres, on the grid: x from 0 to (cols − 1) × cell_size, z from 0 to
/// (rows − 1) × cell_size (when the terrain's size is not known before the run, e.g. an earlier
/// job's, from 0 to 1 000 000).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformPoint)]
pub struct PlanPoint {
    #[schema(minimum = 0.0)]
    pub x: f64,
    #[schema(minimum = 0.0)]
    pub z: f64,
}

/// A constant road height, or the original terrain along the path limited to a gradient.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
#[schema(as = DeformRoadHeight)]
pub enum RoadHeight {
    /// Metres, within ±1 000 000.
    Constant(f64),
    Profile(RoadProfile),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformRoadProfile)]
pub struct RoadProfile {
    /// Largest rise per run along the road, percent.
    #[schema(exclusive_minimum = 0.0, maximum = 1000.0)]
    pub max_gradient_percent: f64,
}

/// Continue another terrain of the same size across shared edges (equation 5).
///
/// Edge convention (the same for `tileable`): neighbouring tiles share their edge samples, as
/// engines' terrain tiles do — this terrain's west column is the neighbour's east column, and
/// so on; placed side by side, tiles of N samples step N − 1 samples apart. The seam matches
/// the neighbour in height and in slope (C¹).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformEdgeMatch)]
pub struct EdgeMatch {
    /// The neighbour, of the same size; it lies beyond each listed edge of this terrain.
    pub terrain: TerrainSource,
    /// At least one edge, each at most once.
    #[schema(min_items = 1, max_items = 4)]
    pub edges: Vec<Edge>,
    /// Cells from the edge over which W(y) = (1 − y/band)² fades; at most half the terrain's
    /// shorter side in samples.
    #[serde(default = "default_band")]
    #[schema(default = 16, minimum = 1)]
    pub band_cells: u32,
    #[serde(default = "one")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1000000.0)]
    pub weight: f64,
    /// The paper's Figure 7 finish: after the search, a 3 × 1 mean filter across the seam on
    /// the two samples next to each shared edge (each takes the mean of itself and its two
    /// neighbours across the seam, all as the search left them); the shared edge samples stay
    /// the neighbour's. `sequence.bin` replays the search; the filter follows it, in a replay
    /// as in the run.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub seam_filter: bool,
}

/// An edge of the grid: west = column 0, east = last column, north = row 0, south = last row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = DeformEdge)]
pub enum Edge {
    West,
    East,
    North,
    South,
}

/// Opposite edges match each other so the tile repeats.
///
/// Edge convention (the same for `edge_match`): the first and last columns (rows) are the same
/// samples of the repeating terrain, so the tile of N samples repeats every N − 1.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformTileable)]
pub struct Tileable {
    #[serde(default)]
    pub edges: TileAxes,
    /// Cells from each edge where candidate vertices are concentrated; at most half the
    /// terrain's shorter side in samples.
    #[serde(default = "default_band")]
    #[schema(default = 16, minimum = 1)]
    pub band_cells: u32,
    #[serde(default = "one")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1000000.0)]
    pub weight: f64,
}

/// Which pairs of edges: `x` = west/east, `z` = north/south.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = DeformTileAxes)]
pub enum TileAxes {
    #[default]
    Both,
    X,
    Z,
}

/// Terraces and plateaus (the paper's future work: "masks for more than one height
/// threshold"): regions, each a polygon with its own level. Every sample inside a region wants
/// the region's level, penalised by (h − level)² over the regions' samples; where regions
/// overlap the later one's level holds. Samples outside every region are left to the other
/// constraints (add `preserve` to hold them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformTerraces)]
pub struct Terraces {
    /// 1 to 64 regions; their polygons at most 256 vertices in all (more is answered with 413).
    // 64 = MAX_REGIONS
    #[schema(min_items = 1, max_items = 64)]
    pub regions: Vec<TerraceRegion>,
    #[serde(default = "one")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1000000.0)]
    pub weight: f64,
}

/// One level of a terrace mask.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformTerraceRegion)]
pub struct TerraceRegion {
    /// The region: a polygon of at least 3 points in metres on the grid (even-odd inside; a
    /// sample exactly on an edge counts on the polygon's low-x and low-z sides, not on its
    /// high ones).
    #[schema(min_items = 3)]
    pub polygon_m: Vec<PlanPoint>,
    /// Its height, metres, within ±1 000 000.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1000000.0, maximum = 1000000.0)]
    pub level_m: f64,
}

/// Most regions of a terrace mask.
pub const MAX_REGIONS: usize = 64;

/// The terrain passes through these points (nearest vertex).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformPoints)]
pub struct Points {
    /// At least one point and at most 10 000 (more is answered with 413).
    // 10000 = MAX_VERTICES
    #[schema(min_items = 1, max_items = 10000)]
    pub points: Vec<HeightPoint>,
    #[serde(default = "one")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1000000.0)]
    pub weight: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformHeightPoint)]
pub struct HeightPoint {
    /// Metres, on the grid (as a road's points).
    #[schema(minimum = 0.0)]
    pub x: f64,
    /// Metres, on the grid (as a road's points).
    #[schema(minimum = 0.0)]
    pub z: f64,
    /// Metres.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub height: f64,
}

/// Divergence from the original terrain everywhere.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = DeformPreserve)]
pub struct Preserve {
    #[serde(default = "one")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1000000.0)]
    pub weight: f64,
}

/// Largest magnitude of a coordinate or height, metres.
const MAX_METRES: f64 = 1e6;

impl Constraint {
    pub fn name(&self) -> &'static str {
        match self {
            Constraint::MatchHeightmap(_) => "match_heightmap",
            Constraint::ShapeMask(_) => "shape_mask",
            Constraint::Road(_) => "road",
            Constraint::EdgeMatch(_) => "edge_match",
            Constraint::Tileable(_) => "tileable",
            Constraint::Points(_) => "points",
            Constraint::Preserve(_) => "preserve",
            Constraint::Terraces(_) => "terraces",
        }
    }

    pub fn weight(&self) -> f64 {
        match self {
            Constraint::MatchHeightmap(c) => c.weight,
            Constraint::ShapeMask(c) => c.weight,
            Constraint::Road(c) => c.weight,
            Constraint::EdgeMatch(c) => c.weight,
            Constraint::Tileable(c) => c.weight,
            Constraint::Points(c) => c.weight,
            Constraint::Preserve(c) => c.weight,
            Constraint::Terraces(c) => c.weight,
        }
    }
}

/// Check that a source has the terrain's size when both are known before the run.
fn same_size(v: &mut Validator, leaf: &str, source: &TerrainSource, terrain: Option<(u64, u64)>, limits: &Limits) {
    v.field(leaf, |v| source.validate(v, limits));
    if let (Some(a), Some(b)) = (source.known_dimensions(), terrain) {
        if a != b {
            v.error(leaf, format!("is {}×{} samples; the terrain is {}×{}", a.0, a.1, b.0, b.1));
        }
    }
}

fn on_grid(v: &mut Validator, x: f64, z: f64, extent: Option<(f64, f64)>) {
    if !v.finite("x", x) || !v.finite("z", z) {
        return;
    }
    match extent {
        Some((w, d)) => {
            if !(0.0..=w).contains(&x) {
                v.error("x", format!("must be on the grid, between 0 and {w} m (got {x})"));
            }
            if !(0.0..=d).contains(&z) {
                v.error("z", format!("must be on the grid, between 0 and {d} m (got {z})"));
            }
        }
        None => {
            if x < 0.0 || x.abs() > MAX_METRES {
                v.error("x", format!("must be on the grid (got {x})"));
            }
            if z < 0.0 || z.abs() > MAX_METRES {
                v.error("z", format!("must be on the grid (got {z})"));
            }
        }
    }
}

impl DeformTerrainParams {
    /// The coarse lattice's spacing on a grid whose shorter side has `shorter` samples: as
    /// given, or a sixteenth of that side.
    pub fn coarse_spacing(&self, shorter: usize) -> usize {
        self.coarse_spacing_cells.map_or((shorter / 16).max(1), |c| c as usize).max(1)
    }

    /// The radii sampled on such a grid (`max_radius_cells` defaults to an eighth of the side).
    pub fn radii_cells(&self, shorter: usize) -> Vec<usize> {
        let min = self.min_radius_cells as usize;
        let max = self.max_radius_cells.map_or((shorter / 8).max(min), |r| r as usize);
        super::search::radii(min, max, self.radii as usize)
    }
}

impl Validate for DeformTerrainParams {
    fn validate(&self, v: &mut Validator, limits: &Limits) {
        v.field("terrain", |v| self.terrain.validate(v, limits));
        if let Some(tiles) = &self.tiles {
            v.field("tiles", |v| tiles.validate(v, limits));
        }
        if let Some(t) = self.sequence_tolerance_m {
            v.in_range("sequence_tolerance_m", t, 0.0, MAX_METRES);
        }
        let dims = self.terrain.known_dimensions();
        let extent = match (dims, self.terrain.known_cell_size()) {
            (Some((c, r)), Some(cell)) => Some(((c - 1) as f64 * cell as f64, (r - 1) as f64 * cell as f64)),
            _ => None,
        };
        if self.constraints.is_empty() {
            v.error("constraints", "needs at least one constraint");
        } else if self.constraints.len() > MAX_CONSTRAINTS {
            v.too_large(
                "constraints",
                format!("{} constraints is more than the cap of {MAX_CONSTRAINTS}", self.constraints.len()),
            );
        }
        for kind in ["shape_mask", "tileable"] {
            if self.constraints.iter().filter(|c| c.name() == kind).count() > 1 {
                v.error("constraints", format!("may hold at most one {kind}"));
            }
        }
        v.field("constraints", |v| {
            for (i, c) in self.constraints.iter().enumerate() {
                v.index(i, |v| v.field(c.name(), |v| validate_constraint(c, v, limits, dims, extent)));
            }
        });
        if self.max_iterations == 0 {
            v.error("max_iterations", "must be at least 1");
        } else if self.max_iterations > MAX_ITERATIONS {
            v.too_large("max_iterations", format!("must be at most {MAX_ITERATIONS} (got {})", self.max_iterations));
        }
        v.non_negative("epsilon", self.epsilon);
        if self.stall_iterations > MAX_ITERATIONS {
            v.too_large(
                "stall_iterations",
                format!("must be at most {MAX_ITERATIONS} (got {})", self.stall_iterations),
            );
        }
        v.in_range("stall_gain", self.stall_gain, 0.0, 1.0);
        v.in_range("p", self.p, 0.0, 1.0);
        v.in_range("top_fraction", self.top_fraction, 0.0, 1.0);
        if !(1..=MAX_AMPLITUDES).contains(&self.amplitudes) {
            v.error("amplitudes", format!("must be between 1 and {MAX_AMPLITUDES} (got {})", self.amplitudes));
        }
        if !(1..=MAX_RADII).contains(&self.radii) {
            v.error("radii", format!("must be between 1 and {MAX_RADII} (got {})", self.radii));
        }
        if self.min_radius_cells == 0 {
            v.error("min_radius_cells", "must be at least 1");
        }
        for (leaf, r) in
            [("min_radius_cells", Some(self.min_radius_cells)), ("max_radius_cells", self.max_radius_cells)]
        {
            if let Some(r) = r.filter(|&r| r > MAX_RADIUS_CELLS) {
                v.too_large(leaf, format!("{r} cells is more than the cap of {MAX_RADIUS_CELLS}"));
            }
        }
        let shorter = dims.map(|(c, r)| c.min(r));
        if let Some(max) = self.max_radius_cells {
            if max == 0 {
                v.error("max_radius_cells", "must be at least 1");
            } else if max < self.min_radius_cells {
                v.error("max_radius_cells", "must not be below min_radius_cells");
            }
        }
        if let Some(n) = shorter {
            for (leaf, r) in
                [("min_radius_cells", Some(self.min_radius_cells)), ("max_radius_cells", self.max_radius_cells)]
            {
                if let Some(r) = r.filter(|&r| r as u64 >= n) {
                    v.error(leaf, format!("{r} cells is larger than the grid ({n} samples a side)"));
                }
            }
        }
        v.positive("max_displacement_ratio", self.max_displacement_ratio);
        if self.max_displacement_ratio > MAX_DISPLACEMENT_RATIO {
            v.error("max_displacement_ratio", format!("must be at most {MAX_DISPLACEMENT_RATIO}"));
        }
        if self.coarse_spacing_cells == Some(0) {
            v.error("coarse_spacing_cells", "must be at least 1");
        }
        if self.min_spacing_cells == 0 {
            v.error("min_spacing_cells", "must be at least 1");
        }
        v.in_range("prediction_constant", self.prediction_constant, 0.0, 1.0);
        // The server's configured operation cap (LANDFORM_MAX_OPERATIONS) bounds it too.
        if self.max_iterations <= MAX_ITERATIONS && u64::from(self.max_iterations) > limits.max_operations {
            v.too_large(
                "max_iterations",
                format!(
                    "must be at most the configured cap of {} (got {})",
                    limits.max_operations, self.max_iterations
                ),
            );
        }
        let operations = u64::from(self.max_iterations) * u64::from(self.batch);
        if operations > MAX_OPERATIONS_PER_JOB {
            v.too_large(
                "batch",
                format!(
                    "max_iterations × batch = {operations} operations, more than the cap of {MAX_OPERATIONS_PER_JOB}"
                ),
            );
        }
        if !(1..=256).contains(&self.batch) {
            v.error("batch", format!("must be between 1 and 256 (got {})", self.batch));
        }
        if self.prediction_constant <= 0.0 {
            v.error("prediction_constant", "must be greater than 0");
        }
        if v.finite("keep_weight", self.keep_weight) && !(0.0..=1e6).contains(&self.keep_weight) {
            v.error("keep_weight", "must be between 0 and 1000000");
        }
        v.in_range("max_free_change", self.max_free_change, 0.0, 1.0);
        v.in_range("max_slope_ratio", self.max_slope_ratio, 1.0, 100.0);
        v.in_range("slope_percentile", self.slope_percentile, 50.0, 100.0);
        v.field("earthworks", |v| {
            self.earthworks.cut_slope.validate(v, "cut_slope");
            self.earthworks.fill_slope.validate(v, "fill_slope");
        });
    }
}

fn validate_constraint(
    c: &Constraint,
    v: &mut Validator,
    limits: &Limits,
    dims: Option<(u64, u64)>,
    extent: Option<(f64, f64)>,
) {
    let weight = c.weight();
    if v.finite("weight", weight) && !(0.0..=1e6).contains(&weight) {
        v.error("weight", format!("must be between 0 and 1000000 (got {weight})"));
    }
    match c {
        Constraint::MatchHeightmap(m) => same_size(v, "target", &m.target, dims, limits),
        Constraint::ShapeMask(m) => {
            match &m.mask {
                MaskShape::Image(src) => v.field("mask", |v| same_size(v, "image", src, dims, limits)),
                MaskShape::PolygonsM(polys) => v.field("mask", |v| {
                    if polys.is_empty() {
                        v.error("polygons_m", "needs at least one polygon");
                    }
                    if polys.iter().map(Vec::len).sum::<usize>() > MAX_OUTLINE_VERTICES {
                        v.too_large("polygons_m", format!("more than {MAX_OUTLINE_VERTICES} vertices in all"));
                    }
                    v.field("polygons_m", |v| {
                        for (i, poly) in polys.iter().enumerate() {
                            if poly.len() < 3 {
                                v.index(i, |v| v.error("", "a polygon needs at least 3 vertices"));
                            }
                            let bad = |x: f64| !x.is_finite() || x.abs() > MAX_METRES;
                            if poly.iter().any(|q| bad(q.x) || bad(q.z)) {
                                v.index(i, |v| v.error("", "coordinates must be finite metres within ±1000000"));
                            }
                        }
                    });
                }),
            }
            if let Some(w) = m.water_level {
                v.in_range("water_level", w, -MAX_METRES, MAX_METRES);
            }
            if let Some(margin) = m.margin {
                v.in_range("margin", margin, 0.0, MAX_METRES);
            }
        }
        Constraint::Road(r) => {
            if r.path.len() < 2 {
                v.error("path", format!("needs at least 2 points (got {})", r.path.len()));
            } else if r.path.len() > MAX_OUTLINE_VERTICES {
                v.too_large("path", format!("more than {MAX_OUTLINE_VERTICES} points"));
            }
            v.field("path", |v| {
                for (i, p) in r.path.iter().enumerate() {
                    v.index(i, |v| on_grid(v, p.x, p.z, extent));
                }
            });
            v.positive("width_m", r.width_m);
            if let Some(sh) = r.shoulder_m {
                v.in_range("shoulder_m", sh, 0.0, MAX_METRES);
            }
            if v.finite("preserve_weight", r.preserve_weight) && !(0.0..=1e6).contains(&r.preserve_weight) {
                v.error("preserve_weight", "must be between 0 and 1000000");
            }
            if r.width_m.is_finite() && r.width_m > MAX_METRES {
                v.error("width_m", format!("must be at most {MAX_METRES} m"));
            }
            // A road and its shoulders wider than the terrain make every cell a road cell.
            if let Some((w, d)) = extent {
                let span = w.max(d);
                if r.width_m.is_finite() && r.width_m > span / 2.0 {
                    v.error("width_m", format!("must be at most half the terrain's extent ({} m)", span / 2.0));
                }
                if let Some(sh) = r.shoulder_m.filter(|s| s.is_finite() && *s > span / 2.0) {
                    v.error(
                        "shoulder_m",
                        format!("must be at most half the terrain's extent ({} m, got {sh})", span / 2.0),
                    );
                }
            }
            v.field("height", |v| match &r.height {
                RoadHeight::Constant(h) => v.in_range("constant", *h, -MAX_METRES, MAX_METRES),
                RoadHeight::Profile(p) => v.field("profile", |v| {
                    v.positive("max_gradient_percent", p.max_gradient_percent);
                    if p.max_gradient_percent > 1000.0 {
                        v.error("max_gradient_percent", "must be at most 1000");
                    }
                }),
            });
        }
        Constraint::EdgeMatch(e) => {
            same_size(v, "terrain", &e.terrain, dims, limits);
            if e.edges.is_empty() {
                v.error("edges", "needs at least one edge");
            }
            if e.edges.iter().enumerate().any(|(i, edge)| e.edges[..i].contains(edge)) {
                v.error("edges", "names an edge twice");
            }
            band(v, e.band_cells, dims);
        }
        Constraint::Tileable(t) => band(v, t.band_cells, dims),
        Constraint::Terraces(t) => {
            if t.regions.is_empty() {
                v.error("regions", "needs at least one region");
            } else if t.regions.len() > MAX_REGIONS {
                v.too_large("regions", format!("more than {MAX_REGIONS} regions"));
            }
            if t.regions.iter().map(|r| r.polygon_m.len()).sum::<usize>() > MAX_OUTLINE_VERTICES {
                v.too_large("regions", format!("more than {MAX_OUTLINE_VERTICES} polygon vertices in all"));
            }
            v.field("regions", |v| {
                for (i, r) in t.regions.iter().enumerate() {
                    v.index(i, |v| {
                        if r.polygon_m.len() < 3 {
                            v.error("polygon_m", "a polygon needs at least 3 vertices");
                        }
                        let bad = |x: f64| !x.is_finite() || x.abs() > MAX_METRES;
                        if r.polygon_m.iter().any(|q| bad(q.x) || bad(q.z)) {
                            v.error("polygon_m", "coordinates must be finite metres within ±1000000");
                        }
                        v.in_range("level_m", r.level_m, -MAX_METRES, MAX_METRES);
                    });
                }
            });
        }
        Constraint::Points(p) => {
            if p.points.is_empty() {
                v.error("points", "needs at least one point");
            } else if p.points.len() > MAX_VERTICES {
                v.too_large("points", format!("more than {MAX_VERTICES} points"));
            }
            v.field("points", |v| {
                for (i, pt) in p.points.iter().enumerate() {
                    v.index(i, |v| {
                        on_grid(v, pt.x, pt.z, extent);
                        v.in_range("height", pt.height, -MAX_METRES, MAX_METRES);
                    });
                }
            });
        }
        Constraint::Preserve(_) => {}
    }
}

fn band(v: &mut Validator, band_cells: u32, dims: Option<(u64, u64)>) {
    if band_cells == 0 {
        v.error("band_cells", "must be at least 1");
    } else if let Some((c, r)) = dims {
        if band_cells as u64 > c.min(r) / 2 {
            v.error("band_cells", format!("must be at most half the grid ({} cells)", c.min(r) / 2));
        }
    }
}
