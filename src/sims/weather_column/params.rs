//! The request: the column's profile and height, bedding layers with their resistance and
//! bubble, the weathering rate and how long to run (paper sections 4–5).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::terrain::ImageUpload;
use crate::validate::{Limits, Validate, Validator};

/// Most steps a run may take: removal steps are recorded in 16 bits.
pub const MAX_STEPS: u32 = 65_000;
/// Largest bubble radius, voxels (the paper measured 1 to 8).
pub const MAX_BUBBLE_RADIUS: f32 = 8.0;
pub const MIN_BUBBLE_RADIUS: f32 = 1.0;
/// Most bedding layers.
pub const MAX_LAYERS: usize = 64;
/// Most vertices of a polygon profile.
pub const MAX_POLYGON_POINTS: usize = 1024;
/// Longest side of the grid, voxels.
pub const MAX_GRID_SIDE: u32 = 4096;
/// Most smoothing iterations of the exported mesh.
pub const MAX_SMOOTHING_ITERATIONS: u32 = 200;
/// Largest in-layer noise amplitude: resistance stays at least 5 % of the layer's.
pub const MAX_NOISE_AMPLITUDE: f32 = 0.95;

fn default_voxel_size() -> f32 {
    0.1
}
fn default_rate() -> f32 {
    0.05
}
fn default_ratio_exponent() -> f32 {
    1.0
}
fn default_steps() -> u32 {
    200
}
fn default_smoothing() -> u32 {
    20
}
fn default_radius() -> f32 {
    4.0
}
fn default_resistance() -> f32 {
    1.0
}

/// Voxels along each axis (Y is up), at most 4096 each; x × y × z at most the server's voxel
/// cap (192 × 1024 × 1024 = 201 326 592 by default; more is answered with 413).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct GridSize {
    // 4096 = MAX_GRID_SIDE
    #[schema(minimum = 1, maximum = 4096)]
    pub x: u32,
    // 4096 = MAX_GRID_SIDE
    #[schema(minimum = 1, maximum = 4096)]
    pub y: u32,
    // 4096 = MAX_GRID_SIDE
    #[schema(minimum = 1, maximum = 4096)]
    pub z: u32,
}

impl GridSize {
    pub fn voxels(&self) -> u64 {
        self.x as u64 * self.y as u64 * self.z as u64
    }
}

/// The column's horizontal profile, seen from above; it is extruded straight up from the ground.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Profile {
    /// A rectangle centred in the grid; the grid's whole footprint when no size is given.
    Box(BoxProfile),
    /// A circle centred in the grid.
    Cylinder(CylinderProfile),
    /// A simple polygon, `[x, z]` metres from the grid's centre (even-odd fill).
    Polygon(PolygonProfile),
    /// The paper's input: a grayscale PNG stretched over the grid's footprint (image row 0 at
    /// z = 0, column 0 at x = 0); dark pixels (below mid-grey) are no rock.
    JointMap(ImageUpload),
    /// A joint map generated from a seed (the paper's Figure 6 input, for a whole valley): two
    /// orthogonal sets of vertical joints cut the footprint into blocks, each of which weathers
    /// into its own goblin.
    Joints(JointSystem),
}

fn default_jitter() -> f32 {
    0.3
}

/// Two orthogonal joint sets: joints across X (planes of constant x) every `spacing_m[0]` and
/// across Z every `spacing_m[1]`, each moved from its regular place by up to ± `jitter` / 2 of
/// the spacing and wandering sideways by up to `wander_m` along its length; `width_m` open.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct JointSystem {
    /// Metres between neighbouring joints of each set `[along X, along Z]`; each more than
    /// `width_m` and at least 4 voxels.
    #[schema(min_items = 2, max_items = 2, exclusive_minimum = 0.0, maximum = 1e4)]
    pub spacing_m: [f32; 2],
    /// Open width of every joint, metres: at least one voxel (`voxel_size_m`), so that every
    /// joint cuts the rock.
    #[schema(exclusive_minimum = 0.0, maximum = 1e4)]
    pub width_m: f32,
    /// How far a joint may sit from its regular place, as a share of the spacing: each joint is
    /// moved by a uniform draw in ± jitter / 2. In [0, 0.9].
    #[serde(default = "default_jitter")]
    #[schema(default = 0.3, minimum = 0.0, maximum = 0.9)]
    pub jitter: f32,
    /// Sideways wander along each joint, metres (a sine of random phase, three spacings long);
    /// 0 keeps joints straight. At most a quarter of the smaller spacing.
    #[serde(default)]
    #[schema(default = 0.0, minimum = 0.0, maximum = 2.5e3)]
    pub wander_m: f32,
    /// Seed of the joints' places (the same seed, the same valley).
    #[serde(default)]
    #[schema(default = 0, minimum = 0)]
    pub seed: u64,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct BoxProfile {
    /// Along X, metres; default the grid's width. At most the grid's width
    /// (`grid.x` × `voxel_size_m`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(exclusive_minimum = 0.0)]
    pub width_m: Option<f32>,
    /// Along Z, metres; default the grid's depth. At most the grid's depth
    /// (`grid.z` × `voxel_size_m`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(exclusive_minimum = 0.0)]
    pub depth_m: Option<f32>,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CylinderProfile {
    /// Metres; default half the grid's shorter horizontal side. At most half the grid's longer
    /// horizontal side.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(exclusive_minimum = 0.0)]
    pub radius_m: Option<f32>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PolygonProfile {
    /// At least three `[x, z]` points and at most 1024, metres from the grid's centre.
    // 1024 = MAX_POLYGON_POINTS
    #[schema(min_items = 3, max_items = 1024)]
    pub points_m: Vec<[f32; 2]>,
}

/// The rock before weathering.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Column {
    pub profile: Profile,
    /// Metres from the bottom of the grid; default the grid's full height. At least one voxel
    /// (after rounding) and at most the grid's height (`grid.y` × `voxel_size_m`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(exclusive_minimum = 0.0)]
    pub height_m: Option<f32>,
    /// Rock with air beneath it, so weathering acts on every side (the paper's cube-to-sphere
    /// check). Otherwise the column stands on ground that does not weather and is not air.
    #[serde(default)]
    pub floating: bool,
}

/// The volume around a voxel in which air is counted (paper Figure 5); sizes in voxels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Bubble {
    Sphere {
        // 1 = MIN_BUBBLE_RADIUS, 8 = MAX_BUBBLE_RADIUS
        #[serde(default = "default_radius")]
        #[schema(default = 4.0, minimum = 1.0, maximum = 8.0)]
        radius: f32,
    },
    /// Axis-aligned, radii along X, Y and Z.
    Ellipsoid {
        // 1 = MIN_BUBBLE_RADIUS, 8 = MAX_BUBBLE_RADIUS (each radius)
        #[schema(min_items = 3, max_items = 3, minimum = 1.0, maximum = 8.0)]
        radii: [f32; 3],
    },
    /// A round top and a flat bottom (Figure 7c): the upper half of a sphere, cut at the
    /// voxel's own level, so rock below a voxel does not shelter it and air below does not
    /// weather it.
    Gumdrop {
        // 1 = MIN_BUBBLE_RADIUS, 8 = MAX_BUBBLE_RADIUS
        #[serde(default = "default_radius")]
        #[schema(default = 4.0, minimum = 1.0, maximum = 8.0)]
        radius: f32,
    },
}

impl Default for Bubble {
    fn default() -> Self {
        Bubble::Sphere { radius: default_radius() }
    }
}

/// In-layer variation of resistance: coherent (Perlin) noise, resistance × (1 + amplitude × n).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LayerNoise {
    /// Relative, in [0, 0.95].
    #[serde(default)]
    // 0.95 = MAX_NOISE_AMPLITUDE
    #[schema(minimum = 0.0, maximum = 0.95)]
    pub amplitude: f32,
    /// Cycles per metre; at most half a cycle per voxel (0.5 / `voxel_size_m`), the finest
    /// noise the voxels resolve. The noise is sampled on a rotated, offset lattice, so no voxel
    /// grid lines up with the noise's own lattice (where gradient noise is zero).
    #[serde(default)]
    #[schema(minimum = 0.0, maximum = 1e4)]
    pub frequency_per_m: f32,
}

/// A bedding plane layer: from the layer below's top (or the ground) up to `top_m`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Layer {
    /// Metres above the bottom of the grid, greater than 0 and greater than the layer before's.
    /// The last layer also holds any rock above its top.
    #[schema(exclusive_minimum = 0.0)]
    pub top_m: f32,
    /// Resistance to weathering (> 0, at most 1 000 000): a voxel's decimation per step is
    /// divided by it.
    #[serde(default = "default_resistance")]
    #[schema(default = 1.0, exclusive_minimum = 0.0, maximum = 1e6)]
    pub resistance: f32,
    #[serde(default)]
    pub noise: LayerNoise,
    #[serde(default)]
    pub bubble: Bubble,
}

/// How removals are scheduled (paper section 5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Update {
    /// Find every voxel fully decimated in a step, then remove them all (the default).
    #[default]
    Synchronized,
    /// Remove each voxel the moment it is fully decimated, in continuous time; neighbours
    /// change rate at once. Slower and more sensitive to noise.
    EventBased,
}

/// The exported mesh.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct MeshOptions {
    /// Taubin smoothing passes (the paper smoothed in Maya); 0 keeps the voxel-derived surface.
    #[serde(default = "default_smoothing")]
    // 200 = MAX_SMOOTHING_ITERATIONS
    #[schema(default = 20, maximum = 200)]
    pub smoothing_iterations: u32,
}

impl Default for MeshOptions {
    fn default() -> Self {
        Self { smoothing_iterations: default_smoothing() }
    }
}

/// `POST /v1/jobs/weather-column`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WeatherColumnParams {
    pub grid: GridSize,
    /// Edge of a voxel, metres.
    #[serde(default = "default_voxel_size")]
    #[schema(default = 0.1, exclusive_minimum = 0.0, maximum = 100.0)]
    pub voxel_size_m: f32,
    pub column: Column,
    /// Bottom to top, `top_m` strictly increasing; at least one, at most 64.
    // 64 = MAX_LAYERS
    #[schema(min_items = 1, max_items = 64)]
    pub layers: Vec<Layer>,
    /// Decimation per step of an exposed voxel whose bubble, centred on the surface, holds as
    /// much air as rock (a flat face), at resistance 1; a voxel starts at level 1 and is removed
    /// at 0. The synchronized update removes a step's voxels together, so a rate at which
    /// corners go within one step (above about 0.1) blurs the difference between a corner and
    /// an edge: 0.05 rounds a cube to the digital sphere, 0.25 leaves it 10 % rougher.
    #[serde(default = "default_rate")]
    #[schema(default = 0.05, exclusive_minimum = 0.0, maximum = 100.0)]
    pub rate: f32,
    /// The decimation grows with the air-to-rock ratio raised to this power. 1 is the paper's
    /// product, which turns a floating cube into a sphere by a tenth of its volume (its Figure
    /// 7). Higher values make weathering follow curvature more sharply: corners go at once and
    /// the rock rounds sooner, at the cost of the bubble's finer shape.
    #[serde(default = "default_ratio_exponent")]
    #[schema(default = 1.0, minimum = 1.0, maximum = 16.0)]
    pub ratio_exponent: f32,
    #[serde(default)]
    pub update: Update,
    /// Rock no longer connected to the ground falls straight down after each step until it
    /// rests on rock or the ground, then keeps weathering where it lies (the paper's future
    /// work; its Figure 2d). Synchronized update only; a floating column has no ground, so
    /// nothing falls.
    #[serde(default)]
    pub gravity: bool,
    /// Most weathering steps: at most 65 000, and at most the server's operation cap (100 000
    /// by default).
    #[serde(default = "default_steps")]
    // 65000 = MAX_STEPS
    #[schema(default = 200, minimum = 1, maximum = 65000)]
    pub steps: u32,
    /// Stop once the remaining rock is at most this fraction of the initial volume (0 = run
    /// every step, or until nothing is left). The default, 0.3, keeps a goblin: with the other
    /// defaults most columns weather away entirely in 200 steps (the presets stop at 0.1–0.5).
    #[serde(default = "default_stop_at_fraction")]
    #[schema(default = 0.3, minimum = 0.0, maximum = 1.0)]
    pub stop_at_fraction: f32,
    #[serde(default)]
    pub mesh: MeshOptions,
}

fn default_stop_at_fraction() -> f32 {
    0.3
}

impl WeatherColumnParams {
    /// Height of the column in voxels.
    pub fn column_voxels(&self) -> u32 {
        match self.column.height_m {
            Some(h) => ((h / self.voxel_size_m).round().max(0.0) as u32).min(self.grid.y),
            None => self.grid.y,
        }
    }
}

impl Bubble {
    /// Radii along X, Y, Z in voxels.
    pub fn radii(&self) -> [f32; 3] {
        match *self {
            Bubble::Sphere { radius } | Bubble::Gumdrop { radius } => [radius; 3],
            Bubble::Ellipsoid { radii } => radii,
        }
    }
}

impl Validate for WeatherColumnParams {
    fn validate(&self, v: &mut Validator, limits: &Limits) {
        if self.gravity && self.update == Update::EventBased {
            v.error("gravity", "needs the synchronized update (falls happen between steps)");
        }
        let g = self.grid;
        v.field("grid", |v| {
            for (leaf, side) in [("x", g.x), ("y", g.y), ("z", g.z)] {
                if side == 0 {
                    v.error(leaf, "must be at least 1");
                } else if side > MAX_GRID_SIDE {
                    v.too_large(leaf, format!("must be at most {MAX_GRID_SIDE} voxels (got {side})"));
                }
            }
        });
        if g.voxels() > limits.max_voxels {
            v.too_large(
                "grid",
                format!(
                    "{}×{}×{} = {} voxels is more than the cap of {}",
                    g.x,
                    g.y,
                    g.z,
                    g.voxels(),
                    limits.max_voxels
                ),
            );
        }
        v.positive("voxel_size_m", self.voxel_size_m as f64);
        if self.voxel_size_m.is_finite() && self.voxel_size_m > 100.0 {
            v.error("voxel_size_m", "must be at most 100 m");
        }
        let size = self.voxel_size_m;
        let width_m = g.x as f32 * size;
        let depth_m = g.z as f32 * size;
        v.field("column", |v| {
            if let Some(h) = self.column.height_m {
                v.positive("height_m", h as f64);
                if h.is_finite() && size > 0.0 && h > g.y as f32 * size * 1.0001 {
                    v.error("height_m", format!("is taller than the grid ({} m)", g.y as f32 * size));
                } else if h.is_finite() && size > 0.0 && (h / size).round() < 1.0 {
                    v.error("height_m", "is less than one voxel");
                }
            }
            v.field("profile", |v| {
                validate_profile(&self.column.profile, v, limits, width_m, depth_m, self.voxel_size_m)
            });
        });
        if self.layers.is_empty() {
            v.error("layers", "needs at least one layer");
        } else if self.layers.len() > MAX_LAYERS {
            v.too_large("layers", format!("at most {MAX_LAYERS} layers (got {})", self.layers.len()));
        }
        v.field("layers", |v| {
            let mut below: Option<f32> = None;
            for (i, layer) in self.layers.iter().enumerate().take(MAX_LAYERS) {
                v.index(i, |v| {
                    if v.finite("top_m", layer.top_m as f64) {
                        if layer.top_m <= 0.0 {
                            v.error("top_m", "must be above the ground (greater than 0)");
                        }
                        match below {
                            Some(b) if layer.top_m < b => v.error(
                                "top_m",
                                format!("is below the layer before it ({b} m): list layers bottom to top"),
                            ),
                            Some(b) if layer.top_m == b => {
                                v.error("top_m", format!("overlaps the layer before it (both end at {b} m)"))
                            }
                            _ => {}
                        }
                        below = Some(layer.top_m);
                    }
                    v.positive("resistance", layer.resistance as f64);
                    if layer.resistance.is_finite() && layer.resistance > 1e6 {
                        v.error("resistance", "must be at most 1000000");
                    }
                    let voxel = self.voxel_size_m;
                    v.field("noise", |v| {
                        v.in_range("amplitude", layer.noise.amplitude as f64, 0.0, MAX_NOISE_AMPLITUDE as f64);
                        v.in_range("frequency_per_m", layer.noise.frequency_per_m as f64, 0.0, 1e4);
                        // Finer noise than the voxels resolve only aliases (and at whole cycles
                        // per voxel it would vanish at every voxel centre).
                        let finest = 0.5 / voxel;
                        if voxel.is_finite() && voxel > 0.0 && layer.noise.frequency_per_m > finest {
                            v.error(
                                "frequency_per_m",
                                format!(
                                    "must be at most {finest} cycles per metre: half a cycle per voxel of {voxel} m is the finest noise the voxels resolve"
                                ),
                            );
                        }
                    });
                    v.field("bubble", |v| validate_bubble(&layer.bubble, v));
                });
            }
        });
        v.positive("rate", self.rate as f64);
        if self.rate.is_finite() && self.rate > 100.0 {
            v.error("rate", "must be at most 100");
        }
        v.in_range("ratio_exponent", self.ratio_exponent as f64, 1.0, 16.0);
        let max_steps = MAX_STEPS.min(limits.max_operations.min(u32::MAX as u64) as u32);
        if self.steps == 0 {
            v.error("steps", "must be at least 1");
        } else if self.steps > max_steps {
            v.error("steps", format!("must be at most {max_steps} (got {})", self.steps));
        }
        v.in_range("stop_at_fraction", self.stop_at_fraction as f64, 0.0, 1.0);
        v.field("mesh", |v| {
            if self.mesh.smoothing_iterations > MAX_SMOOTHING_ITERATIONS {
                v.error(
                    "smoothing_iterations",
                    format!("must be at most {MAX_SMOOTHING_ITERATIONS} (got {})", self.mesh.smoothing_iterations),
                );
            }
        });
    }
}

fn validate_bubble(bubble: &Bubble, v: &mut Validator) {
    let check = |v: &mut Validator, leaf: &str, r: f32| {
        v.in_range(leaf, r as f64, MIN_BUBBLE_RADIUS as f64, MAX_BUBBLE_RADIUS as f64);
    };
    match bubble {
        Bubble::Sphere { radius } => v.field("sphere", |v| check(v, "radius", *radius)),
        Bubble::Gumdrop { radius } => v.field("gumdrop", |v| check(v, "radius", *radius)),
        Bubble::Ellipsoid { radii } => v.field("ellipsoid", |v| {
            for (i, r) in radii.iter().enumerate() {
                check(v, &format!("radii[{i}]"), *r);
            }
        }),
    }
}

fn validate_profile(profile: &Profile, v: &mut Validator, limits: &Limits, width_m: f32, depth_m: f32, voxel: f32) {
    match profile {
        Profile::Box(b) => v.field("box", |v| {
            for (leaf, value, extent) in [("width_m", b.width_m, width_m), ("depth_m", b.depth_m, depth_m)] {
                if let Some(value) = value {
                    v.positive(leaf, value as f64);
                    if value.is_finite() && value > extent * 1.0001 {
                        v.error(leaf, format!("is wider than the grid ({extent} m)"));
                    }
                }
            }
        }),
        Profile::Cylinder(c) => v.field("cylinder", |v| {
            if let Some(r) = c.radius_m {
                v.positive("radius_m", r as f64);
                if r.is_finite() && 2.0 * r > width_m.max(depth_m) * 1.0001 {
                    v.error("radius_m", "is wider than the grid");
                }
            }
        }),
        Profile::Polygon(p) => v.field("polygon", |v| {
            if p.points_m.len() < 3 {
                v.error("points_m", "needs at least 3 points");
            } else if p.points_m.len() > MAX_POLYGON_POINTS {
                v.too_large("points_m", format!("at most {MAX_POLYGON_POINTS} points (got {})", p.points_m.len()));
            }
            if let Some(i) = p.points_m.iter().position(|q| !q.iter().all(|c| c.is_finite())) {
                v.error(&format!("points_m[{i}]"), "must be finite numbers");
            }
        }),
        Profile::Joints(j) => v.field("joints", |v| {
            let min_spacing = 4.0 * voxel;
            for (i, spacing) in j.spacing_m.iter().enumerate() {
                let leaf = format!("spacing_m[{i}]");
                if !(spacing.is_finite() && *spacing >= min_spacing && *spacing <= 1e4) {
                    v.error(&leaf, format!("must be at least 4 voxels ({min_spacing} m) and at most 10000 m"));
                } else if *spacing <= j.width_m {
                    v.error(&leaf, format!("must be more than the joints' width ({} m)", j.width_m));
                }
            }
            if !(j.width_m.is_finite() && j.width_m >= voxel && j.width_m <= 1e4) {
                v.error("width_m", format!("must be at least one voxel ({voxel} m), or a joint cuts no voxel centre"));
            }
            v.in_range("jitter", j.jitter as f64, 0.0, 0.9);
            let smaller = j.spacing_m[0].min(j.spacing_m[1]);
            if !(j.wander_m.is_finite() && j.wander_m >= 0.0 && j.wander_m <= smaller / 4.0) {
                v.error(
                    "wander_m",
                    format!("must be between 0 and a quarter of the smaller spacing ({} m)", smaller / 4.0),
                );
            }
        }),
        Profile::JointMap(image) => v.field("joint_map", |v| {
            if image.validate_in(v, limits).is_some() {
                if let Some(Ok(bytes)) = image.inline_bytes() {
                    if let Err(message) = super::shape::check_joint_map(&bytes) {
                        v.error("png_base64", message);
                    }
                }
            }
        }),
    }
}

/// The draft rule (see `Simulation::draft`): half the voxels each way, each twice the size, and
/// what is counted in voxels or steps halved with them, so the column keeps its metres.
pub fn draft(p: &mut WeatherColumnParams) {
    let half = |n: u32| n.div_ceil(2).max(1);
    p.grid = GridSize { x: half(p.grid.x), y: half(p.grid.y), z: half(p.grid.z) };
    p.voxel_size_m = (p.voxel_size_m * 2.0).min(100.0);
    p.steps = half(p.steps);
    let radius = |r: f32| (r / 2.0).max(1.0);
    for layer in &mut p.layers {
        layer.bubble = match std::mem::take(&mut layer.bubble) {
            Bubble::Sphere { radius: r } => Bubble::Sphere { radius: radius(r) },
            Bubble::Gumdrop { radius: r } => Bubble::Gumdrop { radius: radius(r) },
            Bubble::Ellipsoid { radii } => Bubble::Ellipsoid { radii: radii.map(radius) },
        };
    }
}
