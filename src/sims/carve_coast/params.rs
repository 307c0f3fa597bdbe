//! The request: a terrain source, the sea level, the voxel size for meshing, the seed's
//! `CoastalErosionSettings`, the number of passes and the warp operator.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::terrain::TerrainSource;
use crate::validate::{Limits, Validate, Validator};

/// Most erosion passes.
pub const MAX_PASSES: u32 = 16;
/// Most spheres one job may carve.
pub const MAX_SPHERES: usize = 200_000;
/// Largest sphere radius, metres.
pub const MAX_RADIUS_M: f32 = 1_000.0;
/// Most growth steps per seed and spheres per step.
pub const MAX_GROWTH: u32 = 64;

fn default_passes() -> u32 {
    3
}
fn default_min_slope() -> f32 {
    35.0
}
fn default_elevation_range() -> [f32; 2] {
    [-3.0, 8.0]
}
fn default_probability() -> f32 {
    0.08
}
fn default_radius_range() -> [f32; 2] {
    [1.5, 4.0]
}
fn default_growth_steps() -> [u32; 2] {
    [2, 6]
}
fn default_growth_spheres() -> [u32; 2] {
    [1, 3]
}
fn default_true() -> bool {
    true
}

/// The seed's `CoastalErosionSettings`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Erosion {
    /// Least slope of a seed's surface, degrees from horizontal.
    #[serde(default = "default_min_slope")]
    #[schema(default = 35.0, minimum = 0.0, maximum = 90.0)]
    pub seed_min_slope: f32,
    /// `[low, high]` metres relative to `sea_level` within which seeds are taken (and sphere
    /// centres stay); low ≤ high, both within ±100 000 m.
    #[serde(default = "default_elevation_range")]
    #[schema(default = json!([-3.0, 8.0]), min_items = 2, max_items = 2, minimum = -1e5, maximum = 1e5)]
    pub seed_elevation_range: [f32; 2],
    /// Chance that a qualifying surface point becomes a seed, in [0, 1].
    #[serde(default = "default_probability")]
    #[schema(default = 0.08, minimum = 0.0, maximum = 1.0)]
    pub seed_acceptance_probability: f32,
    /// `[min, max]` sphere radius, metres; 0 < min ≤ max ≤ 1000.
    #[serde(default = "default_radius_range")]
    // 1000 = MAX_RADIUS_M
    #[schema(default = json!([1.5, 4.0]), min_items = 2, max_items = 2, exclusive_minimum = 0.0, maximum = 1000.0)]
    pub radius_range: [f32; 2],
    /// `[min, max]` growth steps per seed; min ≤ max ≤ 64.
    #[serde(default = "default_growth_steps")]
    // 64 = MAX_GROWTH
    #[schema(default = json!([2, 6]), min_items = 2, max_items = 2, maximum = 64)]
    pub growth_step_range: [u32; 2],
    /// `[min, max]` spheres carved at each growth step; min ≤ max ≤ 64.
    #[serde(default = "default_growth_spheres")]
    // 64 = MAX_GROWTH
    #[schema(default = json!([1, 3]), min_items = 2, max_items = 2, maximum = 64)]
    pub growth_sphere_range: [u32; 2],
}

impl Default for Erosion {
    fn default() -> Self {
        serde_json::from_str("{}").expect("defaults")
    }
}

/// The warp operator: points pushed along the heightfield's horizontal gradient by a 1D noise
/// of height — horizontal strata and overhangs on cliffs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Warp {
    /// Metres of push per unit of gradient at the noise's peaks.
    #[schema(minimum = 0.0, maximum = 1e4)]
    pub amplitude_m: f32,
    /// Noise cycles per metre of height.
    #[schema(minimum = 0.0, maximum = 1e3)]
    pub frequency_per_m: f32,
}

/// Most authored carvings in one request.
pub const MAX_AUTHORED: usize = 1000;

/// When an authored carving is made: before the erosion passes (their seeds then see it and
/// erode it further) or after them (as placed).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum When {
    Before,
    #[default]
    After,
}

/// A carving a person places (the seed's manual carving: an arch, a sea cave, a blowhole).
/// Coordinates are metres on the terrain: x along its columns, z along its rows, y up (the
/// terrain's heights); with `warp` they are carved where the warped terrain is.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum AuthoredCarving {
    /// A sphere of air.
    Sphere {
        #[schema(min_items = 3, max_items = 3, minimum = -1e6, maximum = 1e6)]
        centre: [f32; 3],
        /// Metres, greater than 0 and at most 1000.
        #[schema(exclusive_minimum = 0.0, maximum = 1000.0)]
        radius_m: f32,
        #[serde(default)]
        when: When,
    },
    /// A capsule of air: the segment `from`–`to` swept by a sphere of `radius_m` (a tunnel, an
    /// arch's opening, a blowhole's shaft).
    Capsule {
        #[schema(min_items = 3, max_items = 3, minimum = -1e6, maximum = 1e6)]
        from: [f32; 3],
        #[schema(min_items = 3, max_items = 3, minimum = -1e6, maximum = 1e6)]
        to: [f32; 3],
        /// Metres, greater than 0 and at most 1000.
        #[schema(exclusive_minimum = 0.0, maximum = 1000.0)]
        radius_m: f32,
        #[serde(default)]
        when: When,
    },
}

impl AuthoredCarving {
    pub fn radius(&self) -> f32 {
        match self {
            AuthoredCarving::Sphere { radius_m, .. } | AuthoredCarving::Capsule { radius_m, .. } => *radius_m,
        }
    }
    pub fn when(&self) -> When {
        match self {
            AuthoredCarving::Sphere { when, .. } | AuthoredCarving::Capsule { when, .. } => *when,
        }
    }
}

/// `POST /v1/jobs/carve-coast`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CarveCoastParams {
    pub terrain: TerrainSource,
    /// Metres; must lie within the terrain's heights. Absent: the height a quarter of the
    /// terrain's samples lie below (so a terrain from another job has a coast); the result's
    /// `sea_level_m` says which.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sea_level: Option<f32>,
    /// Edge of a meshing voxel, metres; default the terrain's cell size. The meshing box (the
    /// terrain's footprint by its relief plus margins) must hold at most the server's voxel cap
    /// (192 × 1024 × 1024 = 201 326 592 voxels by default; more is answered with 413).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(exclusive_minimum = 0.0)]
    pub voxel_size_m: Option<f32>,
    #[serde(default)]
    pub erosion: Erosion,
    #[serde(default = "default_passes")]
    // 16 = MAX_PASSES
    #[schema(default = 3, minimum = 1, maximum = 16)]
    pub passes: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warp: Option<Warp>,
    /// Carvings placed by hand, before or after the erosion passes, in order (at most 1000).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schema(max_items = 1000)]
    pub carve: Vec<AuthoredCarving>,
    /// Remove rock that floats free of the ground after carving and warping.
    #[serde(default = "default_true")]
    #[schema(default = true)]
    pub remove_fragments: bool,
}

fn range_ok(v: &mut Validator, leaf: &str, r: [f32; 2], min: f32, max: f32) {
    if !r.iter().all(|x| x.is_finite()) {
        v.error(leaf, "must be finite numbers");
    } else if r[0] > r[1] {
        v.error(leaf, format!("is inverted: {} > {}", r[0], r[1]));
    } else if r[0] < min || r[1] > max {
        v.error(leaf, format!("must lie within [{min}, {max}]"));
    }
}

fn count_range_ok(v: &mut Validator, leaf: &str, r: [u32; 2]) {
    if r[0] > r[1] {
        v.error(leaf, format!("is inverted: {} > {}", r[0], r[1]));
    } else if r[1] > MAX_GROWTH {
        v.too_large(leaf, format!("must be at most {MAX_GROWTH}"));
    }
}

impl Validate for CarveCoastParams {
    fn validate(&self, v: &mut Validator, limits: &Limits) {
        v.field("terrain", |v| self.terrain.validate(v, limits));
        if let Some(level) = self.sea_level {
            v.finite("sea_level", level as f64);
        }
        if let Some(size) = self.voxel_size_m {
            v.positive("voxel_size_m", size as f64);
        }
        // The default voxel is the terrain's cell; either way the box must fit the voxel cap.
        let voxel = self.voxel_size_m.or(self.terrain.known_cell_size());
        if let (Some((cols, rows)), Some(cell), Some(relief), Some(size)) =
            (self.terrain.known_dimensions(), self.terrain.known_cell_size(), self.known_relief(), voxel)
        {
            if size > 0.0 && size.is_finite() {
                let relief = relief * if self.island() { 1.2 } else { 1.0 };
                let voxels = estimate_voxels(cols, rows, cell, relief, size, self.max_radius(), self.warp_amplitude());
                if voxels > limits.max_voxels {
                    v.too_large(
                        "voxel_size_m",
                        format!("meshing would take about {voxels} voxels, more than the cap of {}", limits.max_voxels),
                    );
                }
            }
        }
        v.field("erosion", |v| {
            let e = &self.erosion;
            v.in_range("seed_min_slope", e.seed_min_slope as f64, 0.0, 90.0);
            let big = 1e5;
            range_ok(v, "seed_elevation_range", e.seed_elevation_range, -big, big);
            v.in_range("seed_acceptance_probability", e.seed_acceptance_probability as f64, 0.0, 1.0);
            range_ok(v, "radius_range", e.radius_range, 0.0, MAX_RADIUS_M);
            if e.radius_range[0] <= 0.0 && e.radius_range[0].is_finite() {
                v.error("radius_range", "must be greater than 0");
            }
            count_range_ok(v, "growth_step_range", e.growth_step_range);
            count_range_ok(v, "growth_sphere_range", e.growth_sphere_range);
        });
        if self.passes == 0 {
            v.error("passes", "must be at least 1");
        } else if self.passes > MAX_PASSES {
            v.error("passes", format!("must be at most {MAX_PASSES} (got {})", self.passes));
        }
        if self.carve.len() > MAX_AUTHORED {
            v.too_large("carve", format!("must hold at most {MAX_AUTHORED} carvings (got {})", self.carve.len()));
        }
        v.field("carve", |v| {
            for (i, c) in self.carve.iter().enumerate().take(MAX_AUTHORED) {
                v.index(i, |v| {
                    let (name, points): (&str, Vec<(&str, [f32; 3])>) = match c {
                        AuthoredCarving::Sphere { centre, .. } => ("sphere", vec![("centre", *centre)]),
                        AuthoredCarving::Capsule { from, to, .. } => ("capsule", vec![("from", *from), ("to", *to)]),
                    };
                    v.field(name, |v| {
                        for (leaf, p) in points {
                            if !p.iter().all(|c| c.is_finite() && c.abs() <= 1e6) {
                                v.error(leaf, "must be three finite numbers within ±1000000 m");
                            }
                        }
                        let r = c.radius();
                        if !(r.is_finite() && r > 0.0 && r <= MAX_RADIUS_M) {
                            v.error("radius_m", format!("must be greater than 0 and at most {MAX_RADIUS_M}"));
                        }
                    });
                });
            }
        });
        if let Some(w) = &self.warp {
            v.field("warp", |v| {
                v.in_range("amplitude_m", w.amplitude_m as f64, 0.0, 1e4);
                v.in_range("frequency_per_m", w.frequency_per_m as f64, 0.0, 1e3);
            });
        }
    }
}

impl CarveCoastParams {
    /// The sea level the run uses: after [`CarveCoastParams::with_sea_level`], the request's or
    /// the terrain's default.
    pub fn sea_level(&self) -> f32 {
        self.sea_level.unwrap_or(0.0)
    }

    /// These parameters with the sea level set: the request's, else the height a quarter of
    /// `terrain`'s samples lie below.
    pub fn with_sea_level(&self, terrain: &crate::terrain::Heightfield) -> std::borrow::Cow<'_, Self> {
        if self.sea_level.is_some() {
            return std::borrow::Cow::Borrowed(self);
        }
        let mut heights: Vec<f32> = terrain.heights_m.iter().copied().filter(|h| h.is_finite()).collect();
        let level = if heights.is_empty() {
            0.0
        } else {
            let k = heights.len() / 4;
            *heights.select_nth_unstable_by(k, f32::total_cmp).1
        };
        std::borrow::Cow::Owned(Self { sea_level: Some(level), ..self.clone() })
    }

    /// The fractal's relief, when the terrain is one.
    fn known_relief(&self) -> Option<f32> {
        match &self.terrain {
            TerrainSource::Fractal(f) => Some(f.relief),
            _ => None,
        }
    }

    fn island(&self) -> bool {
        matches!(&self.terrain, TerrainSource::Fractal(f) if f.island)
    }

    /// The largest radius any carving may have: eroded or authored.
    pub fn max_radius(&self) -> f32 {
        self.carve
            .iter()
            .map(AuthoredCarving::radius)
            .filter(|r| r.is_finite())
            .fold(self.erosion.radius_range[1], f32::max)
    }

    /// How far the warp can push a point, metres per unit of gradient.
    pub fn warp_amplitude(&self) -> f32 {
        self.warp.as_ref().map_or(0.0, |w| w.amplitude_m)
    }
}

/// Voxels of the meshing box: the terrain's footprint by its relief plus margins (the largest
/// sphere and twice the warp's reach), saturating: no request overflows it.
pub fn estimate_voxels(
    cols: u64,
    rows: u64,
    cell_m: f32,
    relief_m: f32,
    voxel_m: f32,
    max_radius_m: f32,
    warp_amplitude_m: f32,
) -> u64 {
    let side = |n: u64| ((n.saturating_sub(1)) as f64 * cell_m as f64 / voxel_m as f64).ceil() as u64;
    let reach = relief_m as f64 + 2.0 * max_radius_m as f64 + 2.0 * warp_amplitude_m as f64;
    let height = ((reach / voxel_m as f64).ceil() as u64).saturating_add(8);
    side(cols).saturating_add(1).saturating_mul(side(rows).saturating_add(1)).saturating_mul(height)
}
