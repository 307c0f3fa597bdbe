//! The request: the chamber, the drip sites, the geological conditions of Table 2, the
//! minerals of Table 1, wind, and the manual mode (paper section 4).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::validate::{Limits, Validate, Validator};

/// Most rings (passes) a speleothem may grow.
pub const MAX_RINGS: u32 = 256;
/// Most vertices around a ring.
pub const MAX_SEGMENTS: u32 = 64;
pub const MIN_SEGMENTS: u32 = 3;
/// Most drip sites.
pub const MAX_SITES: usize = 5000;
/// Largest chamber side or height, metres.
pub const MAX_CHAMBER_M: f32 = 10_000.0;
/// Most samples along a side of the roof and floor heightfields.
pub const MAX_SURFACE_SAMPLES: u32 = 513;

fn default_width() -> f32 {
    12.0
}
fn default_height() -> f32 {
    5.0
}
fn default_samples() -> u32 {
    65
}
fn default_rings() -> u32 {
    48
}
fn default_segments() -> u32 {
    16
}
fn default_stalactite_radius() -> f32 {
    0.08
}
fn default_stalagmite_radius() -> f32 {
    0.14
}
fn default_radius_step() -> f32 {
    0.004
}
fn default_height_step() -> f32 {
    0.03
}
fn default_kf() -> f32 {
    0.01
}
fn default_coating() -> f32 {
    0.5
}
fn default_canal() -> f32 {
    0.02
}
fn default_straw() -> f32 {
    0.09
}
fn default_intensity() -> f32 {
    1.0
}
fn default_wind_scale() -> f32 {
    1.0
}

/// A roof or floor: flat, or relief from seeded noise.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Surface {
    /// Peak-to-peak relief in metres (0 = flat). The roof hangs down by it, the floor rises.
    /// The roof's and the floor's relief together must stay below the chamber's `height_m`.
    #[serde(default)]
    #[schema(minimum = 0.0)]
    pub relief_m: f32,
    /// Noise features per metre.
    #[serde(default = "default_frequency")]
    #[schema(default = 0.15, minimum = 0.0, maximum = 100.0)]
    pub frequency_per_m: f32,
}

fn default_frequency() -> f32 {
    0.15
}

/// The chamber: floor at y = 0, roof at `height_m`, X and Z from 0 to its width and depth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Chamber {
    /// Metres.
    #[serde(default = "default_width")]
    // 10000 = MAX_CHAMBER_M
    #[schema(default = 12.0, exclusive_minimum = 0.0, maximum = 10000.0)]
    pub width_m: f32,
    /// Metres.
    #[serde(default = "default_width")]
    // 10000 = MAX_CHAMBER_M
    #[schema(default = 12.0, exclusive_minimum = 0.0, maximum = 10000.0)]
    pub depth_m: f32,
    /// Floor to roof where both are flat, metres; greater than the roof's and the floor's
    /// `relief_m` together.
    #[serde(default = "default_height")]
    // 10000 = MAX_CHAMBER_M
    #[schema(default = 5.0, exclusive_minimum = 0.0, maximum = 10000.0)]
    pub height_m: f32,
    #[serde(default)]
    pub roof: Surface,
    #[serde(default)]
    pub floor: Surface,
    /// The four walls: relief pushes them outwards into the rock (the chamber's free space
    /// never shrinks below width × depth), `frequency_per_m` along the wall and up it.
    #[serde(default)]
    pub walls: Surface,
    /// A way in: a passage through one wall from the floor up. Without it the chamber is one
    /// closed surface.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub opening: Option<Opening>,
    /// Samples along each side of the roof and floor meshes.
    #[serde(default = "default_samples")]
    // 513 = MAX_SURFACE_SAMPLES
    #[schema(default = 65, minimum = 2, maximum = 513)]
    pub samples: u32,
}

impl Default for Chamber {
    fn default() -> Self {
        serde_json::from_str("{}").expect("defaults")
    }
}

/// Which wall an opening goes through: `west` at x = 0, `east` at x = width, `north` at
/// z = 0, `south` at z = depth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    West,
    East,
    North,
    South,
}

/// A passage out of the chamber: a rectangular hole in one wall, from the floor up, carried
/// outwards through the rock as a straight tunnel that is open at its far end.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Opening {
    pub wall: Side,
    /// Where along the wall its middle lies, metres from the wall's lower-x (or lower-z) end.
    /// The hole snaps to the wall's samples and keeps a sample clear of each corner.
    #[schema(minimum = 0.0, maximum = 10000.0)]
    pub centre_m: f32,
    /// Metres; at least two of the wall's cells, within the wall.
    #[schema(exclusive_minimum = 0.0, maximum = 10000.0)]
    pub width_m: f32,
    /// Metres above the floor; below the roof.
    #[schema(exclusive_minimum = 0.0, maximum = 10000.0)]
    pub height_m: f32,
    /// How far the tunnel runs out through the rock, metres.
    #[serde(default = "default_tunnel")]
    #[schema(default = 2.0, exclusive_minimum = 0.0, maximum = 10000.0)]
    pub length_m: f32,
}

fn default_tunnel() -> f32 {
    2.0
}

/// The pluviometric index level: 0 no rain (nothing grows), 1 stalactites without dripping,
/// 2 dripping — a stalagmite grows on the floor below.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Pluviometric {
    #[serde(rename = "0")]
    Level0,
    #[serde(rename = "1")]
    Level1,
    #[serde(rename = "2")]
    Level2,
    /// Drawn anew for every ring.
    Random,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum DripInterval {
    Dry,
    Standard,
    Wet,
    /// Drawn anew for every ring.
    Random,
    /// Follows the pluviometric index, inversely (section 4.1): the more of the last three
    /// passes dripped (level 2), the shorter the interval — three `wet`, two `standard`, one
    /// `dry`.
    Pluviometric,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Co2 {
    Low,
    Normal,
    High,
    /// Drawn anew for every ring.
    Random,
}

/// The geological conditions of Table 2.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Conditions {
    /// "0", "1", "2" or "random".
    #[schema(value_type = String, example = "2", pattern = "^(0|1|2|random)$")]
    pub pluviometric_index: Pluviometric,
    pub drip_interval: DripInterval,
    pub co2: Co2,
}

impl Default for Conditions {
    fn default() -> Self {
        Self { pluviometric_index: Pluviometric::Level2, drip_interval: DripInterval::Standard, co2: Co2::Normal }
    }
}

/// Table 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Mineral {
    Calcareous,
    Iron,
    Manganese,
    Copper,
    Malachite,
    /// One of the five, drawn per drip site.
    Random,
}

impl Mineral {
    pub const ALL: [Mineral; 5] =
        [Mineral::Calcareous, Mineral::Iron, Mineral::Manganese, Mineral::Copper, Mineral::Malachite];

    /// Table 1's RGB value (0–1).
    pub fn rgb(self) -> [f32; 3] {
        match self {
            Mineral::Calcareous | Mineral::Random => [0.8, 0.8, 0.8],
            Mineral::Iron => [0.87, 0.62, 0.34],
            Mineral::Manganese => [0.32, 0.44, 0.54],
            Mineral::Copper => [0.05, 0.7, 0.7],
            Mineral::Malachite => [0.67, 0.82, 0.75],
        }
    }
}

/// The air flow: a horizontal direction and an intensity, each fixed or drawn per ring.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Wind {
    /// `[x, z]`, any length but zero; omitted = a random direction per ring.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(min_items = 2, max_items = 2)]
    pub direction: Option<[f32; 2]>,
    /// In [0, 1]; omitted = random in [0, 1] per ring.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 0.0, maximum = 1.0)]
    pub intensity: Option<f32>,
    /// How far an intensity-1 wind moves a ring sideways, as a multiple of the ring's height
    /// step (1 = 45° at full intensity).
    #[serde(default = "default_wind_scale")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 10.0)]
    pub scale: f32,
}

/// One ring of the manual mode: the radius it has and how far it grows from the ring before.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ManualRing {
    /// Metres; a stalactite's rings never widen (each at most the radius before it, the first
    /// at most `stalactite_radius_m`).
    #[schema(minimum = 0.0)]
    pub radius_m: f32,
    /// Metres.
    #[schema(minimum = 0.0)]
    pub height_m: f32,
}

/// The paper's interactive controls: every ring's radius and height given instead of sampled.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Manual {
    /// Rings of each stalactite, after its initial ring; radii must not grow. At most 256.
    #[serde(default)]
    // 256 = MAX_RINGS
    #[schema(max_items = 256)]
    pub stalactite: Vec<ManualRing>,
    /// Rings of each stalagmite, after its initial ring (grown only at pluviometric index 2).
    /// At most 256.
    #[serde(default)]
    // 256 = MAX_RINGS
    #[schema(max_items = 256)]
    pub stalagmite: Vec<ManualRing>,
}

/// A drip site on the roof, with optional conditions and mineral of its own.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Site {
    /// Metres, on the roof: from 0 to the chamber's `width_m`.
    // 10000 = MAX_CHAMBER_M, the largest width_m
    #[schema(minimum = 0.0, maximum = 10000.0)]
    pub x_m: f32,
    /// Metres, on the roof: from 0 to the chamber's `depth_m`.
    // 10000 = MAX_CHAMBER_M, the largest depth_m
    #[schema(minimum = 0.0, maximum = 10000.0)]
    pub z_m: f32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub conditions: Option<Conditions>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mineral: Option<Mineral>,
}

/// Where water drips from the roof: listed, or scattered by count from the seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Sites {
    /// At least 1 site and at most 5000 (fewer if the server's operation cap is lower; more is
    /// answered with 413).
    Explicit(Vec<Site>),
    Scatter {
        /// At least 1 and at most 5000 (fewer if the server's operation cap is lower; more is
        /// answered with 413).
        // 5000 = MAX_SITES
        #[schema(minimum = 1, maximum = 5000)]
        count: u32,
        /// Keep sites at least this far apart, metres (best effort).
        #[serde(default)]
        #[schema(minimum = 0.0)]
        min_spacing_m: f32,
    },
}

/// `POST /v1/jobs/grow-cave`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct GrowCaveParams {
    #[serde(default)]
    pub chamber: Chamber,
    pub sites: Sites,
    /// Conditions at every site that does not set its own.
    #[serde(default)]
    pub conditions: Conditions,
    #[serde(default = "default_mineral")]
    pub mineral: Mineral,
    /// How much of the mineral is in the solution, 0 (calcareous white) to 1 (Table 1's colour).
    #[serde(default = "default_intensity")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 1.0)]
    pub intensity: f32,
    /// Passes: the most rings a speleothem grows. Sites × 2 × (rings + 2) × segments must stay
    /// within the server's grid cap (4097 × 4097 = 16 785 409 by default; more is answered
    /// with 413).
    #[serde(default = "default_rings")]
    // 256 = MAX_RINGS
    #[schema(default = 48, minimum = 1, maximum = 256)]
    pub rings: u32,
    /// Vertices around each ring.
    #[serde(default = "default_segments")]
    // 3 = MIN_SEGMENTS, 64 = MAX_SEGMENTS
    #[schema(default = 16, minimum = 3, maximum = 64)]
    pub segments: u32,
    /// The base primitive's radius for stalactites (the initial calcite ring), metres; at most
    /// the chamber's `height_m`.
    #[serde(default = "default_stalactite_radius")]
    // 10000 = MAX_CHAMBER_M, the largest height_m
    #[schema(default = 0.08, exclusive_minimum = 0.0, maximum = 10000.0)]
    pub stalactite_radius_m: f32,
    /// The first ring of a stalagmite, metres; at most the chamber's `height_m`.
    #[serde(default = "default_stalagmite_radius")]
    // 10000 = MAX_CHAMBER_M, the largest height_m
    #[schema(default = 0.14, exclusive_minimum = 0.0, maximum = 10000.0)]
    pub stalagmite_radius_m: f32,
    /// Table 2's "x1" radius step, metres (each ring draws 50–150 % of it).
    #[serde(default = "default_radius_step")]
    #[schema(default = 0.004, minimum = 0.0, maximum = 0.1)]
    pub radius_step_m: f32,
    /// Table 2's "x1" height step, metres (each ring draws 50–150 % of it); at most the
    /// chamber's `height_m`.
    #[serde(default = "default_height_step")]
    // 10000 = MAX_CHAMBER_M, the largest height_m
    #[schema(default = 0.03, exclusive_minimum = 0.0, maximum = 10000.0)]
    pub height_step_m: f32,
    /// kf of vd = kf · arr / irr, metres: the horizontal displacement of low CO₂ growth; a
    /// quarter of it roughens the surface at other concentrations.
    #[serde(default = "default_kf")]
    #[schema(default = 0.01, minimum = 0.0, maximum = 10.0)]
    pub kf_m: f32,
    /// Horizontal growth (section 3.3): every pass with water adds this share of
    /// `radius_step_m` to the radius of every ring already grown — half of it for the film
    /// running over a stalactite at levels 1 and 2, all of it for the drip's splash over a
    /// stalagmite at level 2 (half for a dry drip interval, 2.5 × for a wet one) — and goes on
    /// after vertical growth stops, so bases widen with age. Never so far that two drip sites'
    /// speleothems touch. 0 = none.
    #[serde(default = "default_coating")]
    #[schema(default = 0.5, minimum = 0.0, maximum = 4.0)]
    pub coating_share: f32,
    /// The central canal of a young stalactite (the paper's thin hollow cylinder), metres; at
    /// most half a ring's radius. 0 = solid stalactites.
    #[serde(default = "default_canal")]
    #[schema(default = 0.02, minimum = 0.0, maximum = 10000.0)]
    pub canal_radius_m: f32,
    /// A stalactite's rings stay hollow while their radius, with coating, is below this; the
    /// canal closes from the roof down as the stalactite thickens, and a column or a tip closed
    /// to a point has none.
    #[serde(default = "default_straw")]
    #[schema(default = 0.09, minimum = 0.0, maximum = 10000.0)]
    pub straw_max_radius_m: f32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wind: Option<Wind>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub manual: Option<Manual>,
}

/// The opening must lie within its wall, at least two wall cells wide, and below the roof.
fn validate_opening(v: &mut Validator, c: &Chamber, o: &Opening) {
    let along = match o.wall {
        Side::West | Side::East => c.depth_m,
        Side::North | Side::South => c.width_m,
    };
    let (cols, rows, cell) = super::chamber::surface_grid(c);
    let samples = if matches!(o.wall, Side::West | Side::East) { rows } else { cols };
    if samples < 4 {
        v.error("wall", format!("has {samples} samples along it; an opening needs at least 4 (raise chamber.samples)"));
    }
    for (leaf, value) in [("width_m", o.width_m), ("height_m", o.height_m), ("length_m", o.length_m)] {
        v.positive(leaf, value as f64);
        if value.is_finite() && value > MAX_CHAMBER_M {
            v.error(leaf, format!("must be at most {MAX_CHAMBER_M} m"));
        }
    }
    if v.finite("centre_m", o.centre_m as f64)
        && o.width_m.is_finite()
        && (o.centre_m - o.width_m / 2.0 < 0.0 || o.centre_m + o.width_m / 2.0 > along)
    {
        v.error("centre_m", format!("puts the opening outside its wall (0 to {along} m)"));
    }
    if o.width_m.is_finite() && o.width_m < 2.0 * cell {
        v.error("width_m", format!("must be at least two wall cells ({} m)", 2.0 * cell));
    }
    let free = c.height_m - c.roof.relief_m - c.floor.relief_m;
    if o.height_m.is_finite() && free.is_finite() && o.height_m >= free {
        v.error("height_m", format!("must stay below the lowest roof over the highest floor ({free} m)"));
    }
}

fn default_mineral() -> Mineral {
    Mineral::Calcareous
}

impl Validate for GrowCaveParams {
    fn validate(&self, v: &mut Validator, limits: &Limits) {
        let c = &self.chamber;
        v.field("chamber", |v| {
            for (leaf, value) in [("width_m", c.width_m), ("depth_m", c.depth_m), ("height_m", c.height_m)] {
                v.positive(leaf, value as f64);
                if value.is_finite() && value > MAX_CHAMBER_M {
                    v.error(leaf, format!("must be at most {MAX_CHAMBER_M} m"));
                }
            }
            for (name, s) in [("roof", &c.roof), ("floor", &c.floor)] {
                v.field(name, |v| {
                    v.non_negative("relief_m", s.relief_m as f64);
                    v.in_range("frequency_per_m", s.frequency_per_m as f64, 0.0, 100.0);
                });
            }
            if c.roof.relief_m.is_finite()
                && c.floor.relief_m.is_finite()
                && c.roof.relief_m + c.floor.relief_m >= c.height_m
            {
                v.error("height_m", "must exceed the roof's and the floor's relief together");
            }
            v.field("walls", |v| {
                v.non_negative("relief_m", c.walls.relief_m as f64);
                v.in_range("frequency_per_m", c.walls.frequency_per_m as f64, 0.0, 100.0);
                if c.walls.relief_m.is_finite() && c.walls.relief_m > MAX_CHAMBER_M {
                    v.error("relief_m", format!("must be at most {MAX_CHAMBER_M} m"));
                }
            });
            if let Some(o) = &c.opening {
                v.field("opening", |v| validate_opening(v, c, o));
            }
            if c.samples < 2 {
                v.error("samples", "must be at least 2");
            } else if c.samples > MAX_SURFACE_SAMPLES {
                v.too_large("samples", format!("must be at most {MAX_SURFACE_SAMPLES} (got {})", c.samples));
            }
        });
        let max_sites = (MAX_SITES as u64).min(limits.max_operations) as usize;
        match &self.sites {
            Sites::Explicit(sites) => {
                if sites.is_empty() {
                    v.error("sites.explicit", "needs at least one site");
                } else if sites.len() > max_sites {
                    v.too_large("sites.explicit", format!("at most {max_sites} sites (got {})", sites.len()));
                }
                v.field("sites", |v| {
                    v.field("explicit", |v| {
                        for (i, s) in sites.iter().enumerate().take(max_sites) {
                            v.index(i, |v| {
                                for (leaf, value, extent) in [("x_m", s.x_m, c.width_m), ("z_m", s.z_m, c.depth_m)] {
                                    if v.finite(leaf, value as f64) && !(0.0..=extent).contains(&value) {
                                        v.error(leaf, format!("is outside the roof (0 to {extent} m)"));
                                    }
                                }
                            });
                        }
                    })
                });
            }
            Sites::Scatter { count, min_spacing_m } => v.field("sites", |v| {
                v.field("scatter", |v| {
                    if *count == 0 {
                        v.error("count", "must be at least 1");
                    } else if *count as usize > max_sites {
                        v.too_large("count", format!("at most {max_sites} sites (got {count})"));
                    }
                    v.non_negative("min_spacing_m", *min_spacing_m as f64);
                })
            }),
        }
        v.in_range("intensity", self.intensity as f64, 0.0, 1.0);
        if self.rings == 0 {
            v.error("rings", "must be at least 1");
        } else if self.rings > MAX_RINGS {
            v.too_large("rings", format!("must be at most {MAX_RINGS} (got {})", self.rings));
        }
        if self.segments < MIN_SEGMENTS {
            v.error("segments", format!("must be at least {MIN_SEGMENTS}"));
        } else if self.segments > MAX_SEGMENTS {
            v.too_large("segments", format!("must be at most {MAX_SEGMENTS} (got {})", self.segments));
        }
        let sites = match &self.sites {
            Sites::Explicit(s) => s.len() as u64,
            Sites::Scatter { count, .. } => *count as u64,
        };
        let vertices = sites * 2 * (self.rings as u64 + 2) * self.segments as u64;
        if vertices > limits.max_grid_cells {
            v.too_large(
                "rings",
                format!(
                    "sites × rings × segments make {vertices} vertices, more than the cap of {}",
                    limits.max_grid_cells
                ),
            );
        }
        for (leaf, value) in [
            ("stalactite_radius_m", self.stalactite_radius_m),
            ("stalagmite_radius_m", self.stalagmite_radius_m),
            ("height_step_m", self.height_step_m),
        ] {
            v.positive(leaf, value as f64);
            if value.is_finite() && value > c.height_m.max(0.0) {
                v.error(leaf, "must be less than the chamber's height");
            }
        }
        // 25 × Table 2's step: wider rings than any speleothem grows in a pass.
        v.non_negative("radius_step_m", self.radius_step_m as f64);
        if self.radius_step_m > 0.1 {
            v.error("radius_step_m", "must be at most 0.1");
        }
        v.in_range("coating_share", self.coating_share as f64, 0.0, 4.0);
        for (leaf, value) in [("canal_radius_m", self.canal_radius_m), ("straw_max_radius_m", self.straw_max_radius_m)]
        {
            v.non_negative(leaf, value as f64);
            if value.is_finite() && value > c.height_m.max(0.0) {
                v.error(leaf, "must be less than the chamber's height");
            }
        }
        v.non_negative("kf_m", self.kf_m as f64);
        if self.kf_m.is_finite() && self.kf_m > 10.0 {
            v.error("kf_m", "must be at most 10 m");
        }
        if let Some(w) = &self.wind {
            v.field("wind", |v| {
                if let Some(d) = w.direction {
                    if !d.iter().all(|x| x.is_finite()) || d[0] * d[0] + d[1] * d[1] == 0.0 {
                        v.error("direction", "must be a finite, non-zero [x, z] vector");
                    }
                }
                if let Some(i) = w.intensity {
                    v.in_range("intensity", i as f64, 0.0, 1.0);
                }
                v.in_range("scale", w.scale as f64, 0.0, 10.0);
            });
        }
        if let Some(m) = &self.manual {
            v.field("manual", |v| {
                for (name, rings, first) in [
                    ("stalactite", &m.stalactite, self.stalactite_radius_m),
                    ("stalagmite", &m.stalagmite, self.stalagmite_radius_m),
                ] {
                    if rings.len() > MAX_RINGS as usize {
                        v.too_large(name, format!("at most {MAX_RINGS} rings (got {})", rings.len()));
                        continue;
                    }
                    v.field(name, |v| {
                        let mut previous = first;
                        for (i, r) in rings.iter().enumerate() {
                            v.index(i, |v| {
                                v.non_negative("radius_m", r.radius_m as f64);
                                v.non_negative("height_m", r.height_m as f64);
                                if name == "stalactite" && r.radius_m > previous {
                                    v.error(
                                        "radius_m",
                                        format!(
                                            "grows ({} m after {previous} m): a stalactite's rings never widen",
                                            r.radius_m
                                        ),
                                    );
                                }
                            });
                            previous = r.radius_m;
                        }
                    });
                }
            });
        }
    }
}
