//! The `erode` request: a terrain, the sea level, how many iterations of how many years, and
//! the two processes (`hydraulic`, `thermal`), each on by default and off with `null`.

use std::fmt;

use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use utoipa::ToSchema;

use super::keep::{self, Keep};
use super::painted::PaintedMap;
use crate::export::TileGrid;
use crate::terrain::TerrainSource;
use crate::validate::{Limits, Validate, Validator};

/// Most iterations one job may run.
pub const MAX_ITERATIONS: u32 = 10_000;
/// Longest time step, years.
pub const MAX_TIME_STEP_YEARS: f64 = 1e6;
/// Largest creep diffusivity, m²/yr (a hundred times the fastest soil creep measured).
pub const MAX_DIFFUSIVITY: f64 = 10.0;

fn default_iterations() -> u32 {
    100
}
fn default_time_step() -> f64 {
    500.0
}
fn default_k() -> f64 {
    5e-5
}
fn default_m() -> f64 {
    0.45
}
fn default_n() -> f64 {
    1.0
}
fn default_g() -> f64 {
    1.0
}
fn default_flow_exponent() -> f64 {
    1.0
}
fn default_talus() -> f64 {
    45.0
}
fn default_diffusivity() -> f64 {
    0.0
}

/// Erode a heightfield: stream-power fluvial erosion with sediment deposition on a surface
/// kept free of pits, and talus-angle slope relaxation.
///
/// Each iteration is `time_step_years` long: uplift, drainage area by multiple flow directions
/// weighted by slope and contour length (Quinn et al. 1991), an implicit stream-power step
/// (Braun & Willett 2013) with Yuan et al. 2019's deposition term, sediment that reaches the
/// sea settled as a delta, then hillslope transport over the same years (creep that grows
/// towards the talus slope, Roering et al. 1999, solved implicitly, and failure of anything
/// steeper). Every rate is per year and per metre, so the landform does not depend on how the
/// years are cut into iterations or on the cell size beyond the methods' error. Sea cells (at
/// or below `sea_level`, found again every iteration) and the grid's border are outlets: the
/// fluvial step does not cut them. The terrain is filled once before the first iteration
/// (Priority-Flood+ε, Barnes et al. 2014), and every land cell keeps a lower neighbour after
/// every iteration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = ErodeParams)]
pub struct ErodeParams {
    /// The starting terrain.
    pub terrain: TerrainSource,
    /// Metres: cells at or below it are sea, where rivers end and sediment leaves the land.
    /// Within ±100 000 m.
    #[serde(default)]
    #[schema(default = 0.0, minimum = -1e5, maximum = 1e5)]
    pub sea_level: f32,
    /// Iterations (1 to 10 000); `until_step` replays the first k. Cells × iterations is
    /// bounded by the work cap (the cost estimate names it).
    #[serde(default = "default_iterations")]
    // 10000 = MAX_ITERATIONS
    #[schema(default = 100, minimum = 1, maximum = 10000)]
    pub iterations: u32,
    /// Years each iteration stands for (greater than 0, at most 1 000 000).
    #[serde(default = "default_time_step")]
    #[schema(default = 500.0, exclusive_minimum = 0.0, maximum = 1e6)]
    pub time_step_years: f64,
    /// Fluvial erosion and deposition; `null` (or `false`) turns it off, `true` or `{}` is the
    /// defaults.
    #[serde(default)]
    #[schema(value_type = Option<Hydraulic>, nullable = true)]
    pub hydraulic: Switch<Hydraulic>,
    /// Hillslope transport (creep and failure to the talus angle); `null` (or `false`) turns it
    /// off, `true` or `{}` is the defaults.
    #[serde(default)]
    #[schema(value_type = Option<Thermal>, nullable = true)]
    pub thermal: Switch<Thermal>,
    /// Where water leaves the map: `all` (the default) — the grid's border and the sea;
    /// `sea` — the sea only, so rivers that reach the map's edge on land turn back (an island
    /// or a coast cut from a larger map; the terrain must have sea); `none` — nothing leaves: a
    /// closed basin whose water gathers at its lowest point, where the sediment settles as a
    /// level lake bed (a playa), and the sea level only draws the exports' coast.
    #[serde(default, skip_serializing_if = "BaseLevel::is_all")]
    pub base_level: BaseLevel,
    /// Areas kept at their starting heights, each with a shoulder over which the erosion fades
    /// back in: polygons, or the cells an earlier job worked (a road a bulldozer or
    /// deform-terrain laid down). At most 16.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    // 16 = keep::MAX_KEEP
    #[schema(max_items = 16)]
    pub keep: Vec<Keep>,
    /// Cut the terrain's mesh into tiles as well, at every level of detail (`tiles/…`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tiles: Option<TileGrid>,
}

/// Stream-power erosion E = k·A^m·S^n (A drainage area in m², S slope) with deposition.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = ErodeHydraulic)]
pub struct Hydraulic {
    /// Erodibility k, in m^(1−2m)/yr for n = 1 (from 0 to 0.1). The default wears a fractal
    /// island by about a quarter of its mean height in 50 000 years.
    #[serde(default = "default_k")]
    #[schema(default = 5e-5, minimum = 0.0, maximum = 0.1)]
    pub k: f64,
    /// Area exponent m (0 to 2). Channels graded by erosion have a concavity θ near m / n.
    #[serde(default = "default_m")]
    #[schema(default = 0.45, minimum = 0.0, maximum = 2.0)]
    pub m: f64,
    /// Slope exponent n (0.5 to 2).
    #[serde(default = "default_n")]
    #[schema(default = 1.0, minimum = 0.5, maximum = 2.0)]
    pub n: f64,
    /// Rock uplift on land, metres a year (0 to 0.1): mountains that rise while they wear.
    #[serde(default)]
    #[schema(default = 0.0, minimum = 0.0, maximum = 0.1)]
    pub uplift_m_per_yr: f64,
    /// Deposition coefficient G (Yuan et al. 2019), 0 to 5: the share of the sediment carried
    /// from upstream that settles, per unit of area over flux. 0: all of it reaches the sea.
    #[serde(default = "default_g")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 5.0)]
    pub deposition_g: f64,
    /// How water splits between lower neighbours: by slope to this power (0 to 10). 1 is
    /// Quinn et al. 1991; larger values approach steepest descent.
    #[serde(default = "default_flow_exponent")]
    #[schema(default = 1.0, minimum = 0.0, maximum = 10.0)]
    pub flow_exponent: f64,
    /// Erodibility painted over the terrain: k is multiplied by the map's value (`black` and
    /// `white` from 0 to 100; 0 leaves rock the rivers cannot cut, 10 soft sediment).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub erodibility_map: Option<PaintedMap>,
    /// Uplift painted over the terrain, metres a year (`black` and `white` from 0 to 0.1), added
    /// to `uplift_m_per_yr` on land: raise a range where it is painted, and the rivers carve it
    /// as it rises (Cordonnier et al. 2016).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uplift_map: Option<PaintedMap>,
}

/// Where water leaves the map.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = ErodeBaseLevel)]
pub enum BaseLevel {
    /// The grid's border and the sea.
    #[default]
    All,
    /// The sea only: the border is a wall where it is land.
    Sea,
    /// Nothing: a closed basin draining to its lowest point.
    None,
}

impl BaseLevel {
    pub fn is_all(&self) -> bool {
        *self == BaseLevel::All
    }
}

/// Largest factor an erodibility map multiplies k by.
pub const MAX_ERODIBILITY_FACTOR: f64 = 100.0;
/// Largest painted uplift, m/yr (as `uplift_m_per_yr`).
pub const MAX_UPLIFT_M_PER_YR: f64 = 0.1;

/// Hillslope transport: soil creep q = −κ∇z / (1 − (|∇z|/S_c)²), which grows without bound as
/// the slope nears the talus slope S_c (Roering, Kirchner & Dietrich 1999), and failure of
/// anything steeper than S_c, measured on the gradient (not per neighbour). Material is
/// conserved; it runs under the sea as on land, and with the fluvial step on what moves into
/// the grid's border leaves the grid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = ErodeThermal)]
pub struct Thermal {
    /// Steepest stable slope, degrees (1 to 89): nothing stays steeper after a step.
    #[serde(default = "default_talus")]
    #[schema(default = 45.0, minimum = 1.0, maximum = 89.0)]
    pub talus_angle_deg: f64,
    /// Creep diffusivity κ, m²/yr (0 to 10): how fast gentle slopes round off. Measured soil
    /// creep is 0.002–0.04 m²/yr (Roering et al. 1999: 0.003); 0 leaves only failure.
    #[serde(default = "default_diffusivity")]
    // 10 = MAX_DIFFUSIVITY
    #[schema(default = 0.0, minimum = 0.0, maximum = 10.0)]
    pub diffusivity_m2_per_yr: f64,
}

impl Default for Hydraulic {
    fn default() -> Self {
        serde_json::from_str("{}").expect("defaults")
    }
}

impl Default for Thermal {
    fn default() -> Self {
        serde_json::from_str("{}").expect("defaults")
    }
}

/// A process that is on with its settings, or off. Absent means on with the defaults; `null`
/// and `false` mean off, and off is written as `false` (a stored request drops `null`s, and
/// absent would read back as on).
#[derive(Clone, Debug, PartialEq)]
pub enum Switch<T> {
    On(T),
    Off,
}

impl<T> Switch<T> {
    pub fn on(&self) -> Option<&T> {
        match self {
            Switch::On(t) => Some(t),
            Switch::Off => None,
        }
    }
}

impl<T: Default> Default for Switch<T> {
    fn default() -> Self {
        Switch::On(T::default())
    }
}

impl<T: Serialize> Serialize for Switch<T> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Switch::On(t) => t.serialize(s),
            Switch::Off => s.serialize_bool(false),
        }
    }
}

impl<'de, T: Deserialize<'de> + Default> Deserialize<'de> for Switch<T> {
    /// A visitor rather than an untagged enum: the settings object is read through the same
    /// map access, so an unknown or bad member is reported at its own path
    /// (`hydraulic.kk`), not as "did not match any variant".
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de> + Default> Visitor<'de> for Visit<T> {
            type Value = Switch<T>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("an object of settings, true (the defaults), or false or null (off)")
            }
            fn visit_bool<E: de::Error>(self, on: bool) -> Result<Self::Value, E> {
                Ok(if on { Switch::On(T::default()) } else { Switch::Off })
            }
            fn visit_unit<E: de::Error>(self) -> Result<Self::Value, E> {
                Ok(Switch::Off)
            }
            fn visit_none<E: de::Error>(self) -> Result<Self::Value, E> {
                Ok(Switch::Off)
            }
            fn visit_some<D2: Deserializer<'de>>(self, d: D2) -> Result<Self::Value, D2::Error> {
                d.deserialize_any(self)
            }
            fn visit_map<M: MapAccess<'de>>(self, map: M) -> Result<Self::Value, M::Error> {
                T::deserialize(de::value::MapAccessDeserializer::new(map)).map(Switch::On)
            }
        }
        d.deserialize_any(Visit(std::marker::PhantomData))
    }
}

impl Validate for ErodeParams {
    fn validate(&self, v: &mut Validator, limits: &Limits) {
        v.field("terrain", |v| self.terrain.validate(v, limits));
        v.in_range("sea_level", self.sea_level as f64, -1e5, 1e5);
        if self.iterations == 0 {
            v.error("iterations", "must be at least 1");
        } else if self.iterations > MAX_ITERATIONS {
            v.too_large("iterations", format!("must be at most {MAX_ITERATIONS} (got {})", self.iterations));
        }
        if v.finite("time_step_years", self.time_step_years)
            && !(self.time_step_years > 0.0 && self.time_step_years <= MAX_TIME_STEP_YEARS)
        {
            v.error(
                "time_step_years",
                format!("must be greater than 0 and at most 1000000 (got {})", self.time_step_years),
            );
        }
        if let Some(tiles) = &self.tiles {
            v.field("tiles", |v| tiles.validate(v, limits));
        }
        keep::validate(&self.keep, v);
        if self.base_level != BaseLevel::All && self.hydraulic.on().is_none() {
            v.error("base_level", "only the rivers have a base level: turn hydraulic on, or leave base_level at all");
        }
        if self.hydraulic.on().is_none() && self.thermal.on().is_none() {
            v.error("hydraulic", "hydraulic and thermal are both off: turn on at least one");
        }
        if let Switch::On(h) = &self.hydraulic {
            v.field("hydraulic", |v| {
                v.in_range("k", h.k, 0.0, 0.1);
                v.in_range("m", h.m, 0.0, 2.0);
                v.in_range("n", h.n, 0.5, 2.0);
                v.in_range("uplift_m_per_yr", h.uplift_m_per_yr, 0.0, 0.1);
                v.in_range("deposition_g", h.deposition_g, 0.0, 5.0);
                v.in_range("flow_exponent", h.flow_exponent, 0.0, 10.0);
                if let Some(map) = &h.erodibility_map {
                    v.field("erodibility_map", |v| map.validate(v, limits, 0.0, MAX_ERODIBILITY_FACTOR));
                }
                if let Some(map) = &h.uplift_map {
                    v.field("uplift_map", |v| map.validate(v, limits, 0.0, MAX_UPLIFT_M_PER_YR));
                }
            });
        }
        if let Switch::On(t) = &self.thermal {
            v.field("thermal", |v| {
                v.in_range("talus_angle_deg", t.talus_angle_deg, 1.0, 89.0);
                v.in_range("diffusivity_m2_per_yr", t.diffusivity_m2_per_yr, 0.0, MAX_DIFFUSIVITY);
            });
        }
    }
}
