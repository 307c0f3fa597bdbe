//! The library of landform primitives (paper §2.2): each a function z = f(x, z) over its own
//! footprint, with parameters a designer thinks in.

use std::f64::consts::{FRAC_PI_2, TAU};

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::apply::{apply, Bounds, Footprint, Frame};
use super::combine::Operator;
use super::params::{metres, PlanPoint, Sign, Window};
use crate::terrain::Heightfield;
use crate::validate::{Limits, Validate, Validator};

/// A landform primitive: exactly one of the shapes. Every shape's relief is measured from
/// its `base_m` (default 0), which matters to the `max`, `min`, `average` and `replace`
/// operators; `add` and `subtract` use the relief alone.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
#[schema(as = BulldozeShape)]
pub enum Shape {
    /// A superellipse dome.
    Mound(Mound),
    /// A ridge along a straight or circular axis, tapering in height and width (Figure 3).
    Berm(Berm),
    /// A berm's shape as a trough: the same parameters, `h1`/`h2` its depths.
    Swale(Berm),
    /// A ring ridge.
    Torus(Torus),
    /// A flat-topped rectangular block.
    Box(BoxShape),
    /// A cone, or a truncated cone when `top_radius_m` > 0.
    Cone(Cone),
    /// Half a cylinder lying on the ground.
    HalfCylinder(HalfCylinder),
    /// A planar top rising linearly along its length; equal heights make a level plane.
    Ramp(Ramp),
}

fn default_mound_curvature() -> f32 {
    2.0
}

/// A dome whose profile is the superellipse (d/R)^c + (y/H)^c = 1.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeMound)]
pub struct Mound {
    /// Centre of the footprint.
    pub center: PlanPoint,
    /// Radius of the footprint, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub radius_m: f32,
    /// Height at the centre, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub height_m: f32,
    /// Superellipse exponent c: 1 a cone, 2 round (a hemisphere when height = radius),
    /// larger values flatter-topped.
    #[serde(default = "default_mound_curvature")]
    #[schema(default = 2.0, exclusive_minimum = 0.0)]
    pub curvature: f32,
    /// Height of the ground plane the mound stands on, metres.
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(default = 0.0, minimum = -1e6, maximum = 1e6)]
    pub base_m: f32,
}

fn default_berm_c2() -> f32 {
    2.0
}

/// The paper's parameterised berm (Figure 3). Its axis starts at `start`, heads
/// `direction_deg` and runs `l` metres, straight or along a circular arc. At axis parameter
/// t ∈ [0, 1] the crest is h1 + (h2 − h1)·t high and the base half-width r1 + (r2 − r1)·t;
/// the cross-section is the superellipse (|d|/r)^c2 + (y/h)^c2 = 1. The footprint is every
/// point whose projection on the axis has t ∈ [0, 1] and lies within the half-width.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeBerm)]
pub struct Berm {
    /// Start of the axis.
    pub start: PlanPoint,
    /// Heading of the axis at its start, degrees from +X toward +Z.
    #[serde(default)]
    #[schema(default = 0.0)]
    pub direction_deg: f32,
    /// Length of the axis, metres (arc length when curved).
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub l: f32,
    /// Height (berm) or depth (swale) at the start, metres.
    // 1e6 = MAX_METRES
    #[schema(minimum = 0.0, maximum = 1e6)]
    pub h1: f32,
    /// Half-width of the base at the start, metres.
    // 1e6 = MAX_METRES
    #[schema(minimum = 0.0, maximum = 1e6)]
    pub r1: f32,
    /// Height (berm) or depth (swale) at the end, metres. `h1` or `h2` must be greater than 0.
    // 1e6 = MAX_METRES
    #[schema(minimum = 0.0, maximum = 1e6)]
    pub h2: f32,
    /// Half-width of the base at the end, metres. `r1` or `r2` must be greater than 0.
    // 1e6 = MAX_METRES
    #[schema(minimum = 0.0, maximum = 1e6)]
    pub r2: f32,
    /// Plan curvature of the axis, 1/m: 0 straight, otherwise a circular arc of radius 1/|c|
    /// turning toward increasing heading (for an axis heading +X, toward +Z) when positive.
    /// When not 0: |c| · l at most 2π (no more than a full circle), and 1/|c| greater than
    /// both `r1` and `r2`.
    #[serde(default)]
    #[schema(default = 0.0)]
    pub c: f32,
    /// Exponent of the cross-section above the ground plane, as a mound's curvature.
    #[serde(default = "default_berm_c2")]
    #[schema(default = 2.0, exclusive_minimum = 0.0)]
    pub c2: f32,
    /// Height of the ground plane, metres.
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(default = 0.0, minimum = -1e6, maximum = 1e6)]
    pub base_m: f32,
}

/// A ring ridge: at distance e from the ring of radius `major_radius_m`, the relief is
/// `height_m · sqrt(1 − (e / minor_radius_m)²)` (a half torus when the two are equal).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeTorus)]
pub struct Torus {
    /// Centre of the footprint.
    pub center: PlanPoint,
    /// Radius of the ring's crest line, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub major_radius_m: f32,
    /// Half-width of the ring's cross-section, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub minor_radius_m: f32,
    /// Height of the crest, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub height_m: f32,
    /// Height of the ground plane the shape stands on, metres (its base).
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(default = 0.0, minimum = -1e6, maximum = 1e6)]
    pub base_m: f32,
}

/// A flat-topped block.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeBox)]
pub struct BoxShape {
    /// Centre of the footprint.
    pub center: PlanPoint,
    /// Extent along the box's own X axis, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub size_x_m: f32,
    /// Extent along the box's own Z axis, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub size_z_m: f32,
    /// Height of the top above the base, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub height_m: f32,
    /// Rotation about the vertical, degrees from +X toward +Z.
    #[serde(default)]
    #[schema(default = 0.0)]
    pub rotation_deg: f32,
    /// Height of the ground plane the shape stands on, metres (its base).
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(default = 0.0, minimum = -1e6, maximum = 1e6)]
    pub base_m: f32,
}

/// A cone with a straight flank from the rim to the top.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeCone)]
pub struct Cone {
    /// Centre of the footprint.
    pub center: PlanPoint,
    /// Radius of the base, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub radius_m: f32,
    /// Height of the top above the base, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub height_m: f32,
    /// Radius of the flat top, metres, below `radius_m` (strictly); 0 a pointed cone.
    #[serde(default)]
    // 1e6 = MAX_METRES
    #[schema(default = 0.0, minimum = 0.0, maximum = 1e6)]
    pub top_radius_m: f32,
    /// Height of the ground plane the shape stands on, metres (its base).
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(default = 0.0, minimum = -1e6, maximum = 1e6)]
    pub base_m: f32,
}

/// Half a cylinder lying along an axis: relief sqrt(r² − d²) at distance d from the axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeHalfCylinder)]
pub struct HalfCylinder {
    /// One end of the axis.
    pub start: PlanPoint,
    /// Heading of the axis, degrees from +X toward +Z.
    #[serde(default)]
    #[schema(default = 0.0)]
    pub direction_deg: f32,
    /// Length along the axis, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub length_m: f32,
    /// Radius, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub radius_m: f32,
    /// Height of the ground plane the shape stands on, metres (its base).
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(default = 0.0, minimum = -1e6, maximum = 1e6)]
    pub base_m: f32,
}

/// A ramp: a planar top `start_height_m` high at `start`, rising (or falling) linearly to
/// `end_height_m` after `length_m` metres along `direction_deg`; 7 m over 100 m is a 7 %
/// ramp. Its plan is a trapezoid `width_m` wide at the start and `end_width_m` at the end.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeRamp)]
pub struct Ramp {
    /// Middle of the ramp's starting edge.
    pub start: PlanPoint,
    /// Heading of the ramp, degrees from +X toward +Z.
    #[serde(default)]
    #[schema(default = 0.0)]
    pub direction_deg: f32,
    /// Length along the axis, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub length_m: f32,
    /// Width at the start, metres.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub width_m: f32,
    /// Width at the end, metres; absent (null): the same as `width_m`.
    #[serde(default)]
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub end_width_m: Option<f32>,
    /// Height of the top above the base at the start, metres.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub start_height_m: f32,
    /// Height of the top above the base at the end, metres.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub end_height_m: f32,
    /// Height of the ground plane the shape stands on, metres (its base).
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(default = 0.0, minimum = -1e6, maximum = 1e6)]
    pub base_m: f32,
}

fn plan_point(v: &mut Validator, name: &str, p: &PlanPoint) {
    v.field(name, |v| {
        metres(v, "x", p.x, Sign::Any);
        metres(v, "z", p.z, Sign::Any);
    });
}

impl Validate for Shape {
    fn validate(&self, v: &mut Validator, _limits: &Limits) {
        match self {
            Shape::Mound(m) => v.field("mound", |v| {
                plan_point(v, "center", &m.center);
                metres(v, "radius_m", m.radius_m, Sign::Positive);
                metres(v, "height_m", m.height_m, Sign::Positive);
                v.positive("curvature", m.curvature as f64);
                metres(v, "base_m", m.base_m, Sign::Any);
            }),
            Shape::Berm(b) => v.field("berm", |v| b.validate(v)),
            Shape::Swale(b) => v.field("swale", |v| b.validate(v)),
            Shape::Torus(t) => v.field("torus", |v| {
                plan_point(v, "center", &t.center);
                metres(v, "major_radius_m", t.major_radius_m, Sign::Positive);
                metres(v, "minor_radius_m", t.minor_radius_m, Sign::Positive);
                metres(v, "height_m", t.height_m, Sign::Positive);
                metres(v, "base_m", t.base_m, Sign::Any);
            }),
            Shape::Box(b) => v.field("box", |v| {
                plan_point(v, "center", &b.center);
                metres(v, "size_x_m", b.size_x_m, Sign::Positive);
                metres(v, "size_z_m", b.size_z_m, Sign::Positive);
                metres(v, "height_m", b.height_m, Sign::Positive);
                v.finite("rotation_deg", b.rotation_deg as f64);
                metres(v, "base_m", b.base_m, Sign::Any);
            }),
            Shape::Cone(c) => v.field("cone", |v| {
                plan_point(v, "center", &c.center);
                metres(v, "radius_m", c.radius_m, Sign::Positive);
                metres(v, "height_m", c.height_m, Sign::Positive);
                metres(v, "top_radius_m", c.top_radius_m, Sign::NonNegative);
                if c.top_radius_m >= c.radius_m && c.radius_m > 0.0 {
                    v.error("top_radius_m", "must be smaller than radius_m");
                }
                metres(v, "base_m", c.base_m, Sign::Any);
            }),
            Shape::HalfCylinder(h) => v.field("half_cylinder", |v| {
                plan_point(v, "start", &h.start);
                v.finite("direction_deg", h.direction_deg as f64);
                metres(v, "length_m", h.length_m, Sign::Positive);
                metres(v, "radius_m", h.radius_m, Sign::Positive);
                metres(v, "base_m", h.base_m, Sign::Any);
            }),
            Shape::Ramp(r) => v.field("ramp", |v| {
                plan_point(v, "start", &r.start);
                v.finite("direction_deg", r.direction_deg as f64);
                metres(v, "length_m", r.length_m, Sign::Positive);
                metres(v, "width_m", r.width_m, Sign::Positive);
                if let Some(w) = r.end_width_m {
                    metres(v, "end_width_m", w, Sign::Positive);
                }
                metres(v, "start_height_m", r.start_height_m, Sign::Any);
                metres(v, "end_height_m", r.end_height_m, Sign::Any);
                metres(v, "base_m", r.base_m, Sign::Any);
            }),
        }
    }
}

impl Berm {
    fn validate(&self, v: &mut Validator) {
        plan_point(v, "start", &self.start);
        v.finite("direction_deg", self.direction_deg as f64);
        metres(v, "l", self.l, Sign::Positive);
        metres(v, "h1", self.h1, Sign::NonNegative);
        metres(v, "r1", self.r1, Sign::NonNegative);
        metres(v, "h2", self.h2, Sign::NonNegative);
        metres(v, "r2", self.r2, Sign::NonNegative);
        if self.h1 == 0.0 && self.h2 == 0.0 {
            v.error("h2", "h1 or h2 must be greater than 0");
        }
        if self.r1 == 0.0 && self.r2 == 0.0 {
            v.error("r2", "r1 or r2 must be greater than 0");
        }
        v.positive("c2", self.c2 as f64);
        if v.finite("c", self.c as f64) && self.c != 0.0 {
            let radius = 1.0 / (self.c as f64).abs();
            if (self.c as f64).abs() * self.l as f64 > TAU {
                v.error("c", "the axis would turn more than a full circle (|c| · l must be at most 2π)");
            } else if (self.r1.max(self.r2) as f64) >= radius {
                v.error(
                    "c",
                    format!("the axis's radius of curvature ({radius} m) must exceed the half-widths r1 and r2"),
                );
            }
        }
    }
}

/// The superellipse (q)^c + (y)^c = 1 solved for y, q in [0, 1].
#[inline]
fn superellipse(q: f64, c: f64) -> f64 {
    if c == 2.0 {
        (1.0 - q * q).max(0.0).sqrt()
    } else if c == 1.0 {
        1.0 - q
    } else {
        (1.0 - q.powf(c)).max(0.0).powf(1.0 / c)
    }
}

fn frame_at(p: &PlanPoint, direction_deg: f32) -> Frame {
    Frame::heading(p.x as f64, p.z as f64, (direction_deg as f64).to_radians())
}

struct MoundGeometry {
    cx: f64,
    cz: f64,
    radius: f64,
    height: f64,
    c: f64,
    base: f64,
}

impl From<&Mound> for MoundGeometry {
    fn from(m: &Mound) -> Self {
        MoundGeometry {
            cx: m.center.x as f64,
            cz: m.center.z as f64,
            radius: m.radius_m as f64,
            height: m.height_m as f64,
            c: m.curvature as f64,
            base: m.base_m as f64,
        }
    }
}

impl Footprint for MoundGeometry {
    fn bounds(&self) -> Bounds {
        Bounds::square(self.cx, self.cz, self.radius)
    }

    #[inline]
    fn sample(&self, x: f64, z: f64) -> Option<(f64, f64)> {
        let (dx, dz) = (x - self.cx, z - self.cz);
        let d2 = dx * dx + dz * dz;
        if d2 > self.radius * self.radius {
            return None;
        }
        let relief = if self.c == 2.0 {
            self.height * (1.0 - d2 / (self.radius * self.radius)).max(0.0).sqrt()
        } else {
            self.height * superellipse(d2.sqrt() / self.radius, self.c)
        };
        Some((self.base, relief))
    }
}

/// A berm's or swale's axis: a straight line or a circular arc.
enum Axis {
    Straight(Frame),
    Arc {
        /// Centre of the circle.
        cx: f64,
        cz: f64,
        radius: f64,
        /// Polar angle of the start about the centre.
        start_angle: f64,
        /// +1 if the polar angle grows along the axis, −1 if it shrinks.
        turn: f64,
    },
}

pub(crate) struct BermGeometry {
    axis: Axis,
    length: f64,
    h1: f64,
    h2: f64,
    r1: f64,
    r2: f64,
    c2: f64,
    /// +1 for a berm, −1 for a swale.
    sign: f64,
    base: f64,
    bounds: Bounds,
}

impl BermGeometry {
    pub(crate) fn new(b: &Berm, sign: f64) -> Self {
        let (sx, sz) = (b.start.x as f64, b.start.z as f64);
        let heading = (b.direction_deg as f64).to_radians();
        let length = b.l as f64;
        let (r1, r2) = (b.r1 as f64, b.r2 as f64);
        let r_max = r1.max(r2);
        // An arc whose sagitta (c·l²/8) is under a tenth of a millimetre is straight for every
        // purpose, and its far-away centre would cost all precision.
        let c = if (b.c as f64).abs() * length * length / 8.0 < 1e-4 { 0.0 } else { b.c as f64 };
        let (axis, bounds) = if c == 0.0 {
            let frame = Frame::heading(sx, sz, heading);
            let bounds = Bounds::around([
                frame.world(0.0, -r1),
                frame.world(0.0, r1),
                frame.world(length, -r2),
                frame.world(length, r2),
            ]);
            (Axis::Straight(frame), bounds)
        } else {
            // The centre lies 1/c along the start's right-hand normal: to the right when the
            // heading grows (c > 0), to the left otherwise.
            let radius = 1.0 / c.abs();
            let (cx, cz) = Frame::heading(sx, sz, heading).world(0.0, 1.0 / c);
            let start_angle = (sz - cz).atan2(sx - cx);
            let turn = c.signum();
            let sweep = c.abs() * length;
            let at = |angle: f64, r: f64| (cx + r * angle.cos(), cz + r * angle.sin());
            let end_angle = start_angle + turn * sweep;
            let mut points = vec![
                at(start_angle, radius - r_max),
                at(start_angle, radius + r_max),
                at(end_angle, radius - r_max),
                at(end_angle, radius + r_max),
            ];
            // The outer rim's extremes in x and z, where the arc passes them.
            for k in 0..4 {
                let angle = k as f64 * FRAC_PI_2;
                if ((angle - start_angle) * turn).rem_euclid(TAU) <= sweep {
                    points.push(at(angle, radius + r_max));
                }
            }
            let mut bounds = Bounds::around(points);
            let pad = 1e-9 * (radius + r_max);
            bounds.min_x -= pad;
            bounds.min_z -= pad;
            bounds.max_x += pad;
            bounds.max_z += pad;
            (Axis::Arc { cx, cz, radius, start_angle, turn }, bounds)
        };
        BermGeometry {
            axis,
            length,
            h1: b.h1 as f64,
            h2: b.h2 as f64,
            r1,
            r2,
            c2: b.c2 as f64,
            sign,
            base: b.base_m as f64,
            bounds,
        }
    }

    /// Axis parameter t (0 at the start, 1 at the end) and distance from the axis of a point.
    #[inline]
    fn project(&self, x: f64, z: f64) -> (f64, f64) {
        match &self.axis {
            Axis::Straight(frame) => {
                let (s, d) = frame.local(x, z);
                (s / self.length, d)
            }
            Axis::Arc { cx, cz, radius, start_angle, turn } => {
                let (dx, dz) = (x - cx, z - cz);
                let swept = ((dz.atan2(dx) - start_angle) * turn).rem_euclid(TAU);
                (swept * radius / self.length, dx.hypot(dz) - radius)
            }
        }
    }
}

impl Footprint for BermGeometry {
    fn bounds(&self) -> Bounds {
        self.bounds
    }

    #[inline]
    fn sample(&self, x: f64, z: f64) -> Option<(f64, f64)> {
        let (t, d) = self.project(x, z);
        if !(0.0..=1.0).contains(&t) {
            return None;
        }
        let r = self.r1 + (self.r2 - self.r1) * t;
        if r <= 0.0 || d.abs() > r {
            return None;
        }
        let h = self.h1 + (self.h2 - self.h1) * t;
        Some((self.base, self.sign * h * superellipse(d.abs() / r, self.c2)))
    }
}

struct TorusGeometry {
    cx: f64,
    cz: f64,
    major: f64,
    minor: f64,
    height: f64,
    base: f64,
}

impl From<&Torus> for TorusGeometry {
    fn from(t: &Torus) -> Self {
        TorusGeometry {
            cx: t.center.x as f64,
            cz: t.center.z as f64,
            major: t.major_radius_m as f64,
            minor: t.minor_radius_m as f64,
            height: t.height_m as f64,
            base: t.base_m as f64,
        }
    }
}

impl Footprint for TorusGeometry {
    fn bounds(&self) -> Bounds {
        Bounds::square(self.cx, self.cz, self.major + self.minor)
    }

    #[inline]
    fn sample(&self, x: f64, z: f64) -> Option<(f64, f64)> {
        let e = ((x - self.cx).hypot(z - self.cz) - self.major).abs();
        if e > self.minor {
            return None;
        }
        let q = e / self.minor;
        Some((self.base, self.height * (1.0 - q * q).max(0.0).sqrt()))
    }
}

struct BoxGeometry {
    frame: Frame,
    half_x: f64,
    half_z: f64,
    height: f64,
    base: f64,
}

impl From<&BoxShape> for BoxGeometry {
    fn from(b: &BoxShape) -> Self {
        BoxGeometry {
            frame: frame_at(&b.center, b.rotation_deg),
            half_x: b.size_x_m as f64 / 2.0,
            half_z: b.size_z_m as f64 / 2.0,
            height: b.height_m as f64,
            base: b.base_m as f64,
        }
    }
}

impl Footprint for BoxGeometry {
    fn bounds(&self) -> Bounds {
        let f = &self.frame;
        Bounds::around(
            [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
                .map(|(a, b)| f.world(a * self.half_x, b * self.half_z)),
        )
    }

    #[inline]
    fn sample(&self, x: f64, z: f64) -> Option<(f64, f64)> {
        let (lx, lz) = self.frame.local(x, z);
        (lx.abs() <= self.half_x && lz.abs() <= self.half_z).then_some((self.base, self.height))
    }
}

struct ConeGeometry {
    cx: f64,
    cz: f64,
    radius: f64,
    top: f64,
    height: f64,
    base: f64,
}

impl From<&Cone> for ConeGeometry {
    fn from(c: &Cone) -> Self {
        ConeGeometry {
            cx: c.center.x as f64,
            cz: c.center.z as f64,
            radius: c.radius_m as f64,
            top: c.top_radius_m as f64,
            height: c.height_m as f64,
            base: c.base_m as f64,
        }
    }
}

impl Footprint for ConeGeometry {
    fn bounds(&self) -> Bounds {
        Bounds::square(self.cx, self.cz, self.radius)
    }

    #[inline]
    fn sample(&self, x: f64, z: f64) -> Option<(f64, f64)> {
        let d = (x - self.cx).hypot(z - self.cz);
        if d > self.radius {
            return None;
        }
        let relief =
            if d <= self.top { self.height } else { self.height * (self.radius - d) / (self.radius - self.top) };
        Some((self.base, relief))
    }
}

struct HalfCylinderGeometry {
    frame: Frame,
    length: f64,
    radius: f64,
    base: f64,
}

impl From<&HalfCylinder> for HalfCylinderGeometry {
    fn from(h: &HalfCylinder) -> Self {
        HalfCylinderGeometry {
            frame: frame_at(&h.start, h.direction_deg),
            length: h.length_m as f64,
            radius: h.radius_m as f64,
            base: h.base_m as f64,
        }
    }
}

impl Footprint for HalfCylinderGeometry {
    fn bounds(&self) -> Bounds {
        let (f, l, r) = (&self.frame, self.length, self.radius);
        Bounds::around([f.world(0.0, -r), f.world(0.0, r), f.world(l, -r), f.world(l, r)])
    }

    #[inline]
    fn sample(&self, x: f64, z: f64) -> Option<(f64, f64)> {
        let (s, d) = self.frame.local(x, z);
        if !(0.0..=self.length).contains(&s) || d.abs() > self.radius {
            return None;
        }
        Some((self.base, (self.radius * self.radius - d * d).max(0.0).sqrt()))
    }
}

struct RampGeometry {
    frame: Frame,
    length: f64,
    w0: f64,
    w1: f64,
    h0: f64,
    h1: f64,
    base: f64,
}

impl From<&Ramp> for RampGeometry {
    fn from(r: &Ramp) -> Self {
        RampGeometry {
            frame: frame_at(&r.start, r.direction_deg),
            length: r.length_m as f64,
            w0: r.width_m as f64,
            w1: r.end_width_m.unwrap_or(r.width_m) as f64,
            h0: r.start_height_m as f64,
            h1: r.end_height_m as f64,
            base: r.base_m as f64,
        }
    }
}

impl Footprint for RampGeometry {
    fn bounds(&self) -> Bounds {
        let (f, l) = (&self.frame, self.length);
        let (a, b) = (self.w0 / 2.0, self.w1 / 2.0);
        Bounds::around([f.world(0.0, -a), f.world(0.0, a), f.world(l, -b), f.world(l, b)])
    }

    #[inline]
    fn sample(&self, x: f64, z: f64) -> Option<(f64, f64)> {
        let (s, d) = self.frame.local(x, z);
        if !(0.0..=self.length).contains(&s) {
            return None;
        }
        let t = s / self.length;
        if d.abs() > 0.5 * (self.w0 + (self.w1 - self.w0) * t) {
            return None;
        }
        Some((self.base, self.h0 + (self.h1 - self.h0) * t))
    }
}

/// A shape's footprint, ready to rasterise. (Dispatching once a sample costs nothing
/// measurable beside the shapes' own arithmetic.)
fn geometry(shape: &Shape) -> Box<dyn Footprint> {
    match shape {
        Shape::Mound(m) => Box::new(MoundGeometry::from(m)),
        Shape::Berm(b) => Box::new(BermGeometry::new(b, 1.0)),
        Shape::Swale(b) => Box::new(BermGeometry::new(b, -1.0)),
        Shape::Torus(t) => Box::new(TorusGeometry::from(t)),
        Shape::Box(b) => Box::new(BoxGeometry::from(b)),
        Shape::Cone(c) => Box::new(ConeGeometry::from(c)),
        Shape::HalfCylinder(h) => Box::new(HalfCylinderGeometry::from(h)),
        Shape::Ramp(r) => Box::new(RampGeometry::from(r)),
    }
}

/// A rectangle holding the shape's whole footprint, metres.
pub(super) fn shape_bounds(shape: &Shape) -> super::apply::Bounds {
    geometry(shape).bounds()
}

/// Combine a primitive with the surface (one step).
pub fn apply_shape(hf: &mut Heightfield, shape: &Shape, operator: Operator, window: Option<&Window>) {
    apply(hf, geometry(shape).as_ref(), operator, window);
}

/// The shape's name as it appears in requests, for progress messages.
pub fn shape_name(shape: &Shape) -> &'static str {
    match shape {
        Shape::Mound(_) => "mound",
        Shape::Berm(_) => "berm",
        Shape::Swale(_) => "swale",
        Shape::Torus(_) => "torus",
        Shape::Box(_) => "box",
        Shape::Cone(_) => "cone",
        Shape::HalfCylinder(_) => "half_cylinder",
        Shape::Ramp(_) => "ramp",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(x: f32, z: f32) -> PlanPoint {
        PlanPoint { x, z }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-4
    }

    #[test]
    fn each_operator_combines_a_mound_with_flat_terrain_as_documented() {
        // A round mound 8 m high, radius 20 m, standing on a plane at 5 m, over terrain at 10 m.
        let mound = Shape::Mound(Mound {
            center: point(30.0, 30.0),
            radius_m: 20.0,
            height_m: 8.0,
            curvature: 2.0,
            base_m: 5.0,
        });
        let relief = |q: f64| 8.0 * (1.0 - q * q).sqrt();
        // Centre, half the radius, 0.9 of it (where the mound's surface, 8.49 m, is below the
        // terrain), and outside.
        let probes = [(30usize, 0.0), (40, 0.5), (48, 0.9)];
        type Rule = fn(f64, f64) -> f64;
        let cases: [(Operator, Rule); 6] = [
            (Operator::Add, |z, r| z + r),
            (Operator::Subtract, |z, r| z - r),
            (Operator::Max, |z, r| z.max(5.0 + r)),
            (Operator::Min, |z, r| z.min(5.0 + r)),
            (Operator::Average, |z, r| (z + 5.0 + r) / 2.0),
            (Operator::Replace, |_, r| 5.0 + r),
        ];
        for (operator, rule) in cases {
            let mut hf = Heightfield::flat(61, 61, 1.0, 10.0);
            apply_shape(&mut hf, &mound, operator, None);
            for (col, q) in probes {
                let got = hf.get(col, 30) as f64;
                assert!(close(got, rule(10.0, relief(q))), "{operator:?} at q = {q}: {got}");
            }
            assert_eq!(hf.get(51, 30), 10.0, "{operator:?} outside the footprint");
            assert_eq!(hf.get(30, 9), 10.0, "{operator:?} outside the footprint");
        }
    }

    #[test]
    fn mound_curvature_shapes_the_profile() {
        let at_half = |curvature: f32| {
            let g = MoundGeometry { cx: 0.0, cz: 0.0, radius: 10.0, height: 10.0, c: curvature as f64, base: 0.0 };
            g.sample(5.0, 0.0).unwrap().1
        };
        assert!(close(at_half(1.0), 5.0));
        assert!(close(at_half(2.0), 10.0 * 0.75f64.sqrt()));
        assert!(close(at_half(4.0), 10.0 * (1.0 - 0.0625f64).powf(0.25)));
        assert!(at_half(8.0) > at_half(4.0));
    }

    fn berm(c: f32) -> Berm {
        Berm {
            start: point(50.0, 50.0),
            direction_deg: 0.0,
            l: 40.0,
            h1: 4.0,
            r1: 6.0,
            h2: 2.0,
            r2: 3.0,
            c,
            c2: 3.0,
            base_m: 0.0,
        }
    }

    #[test]
    fn a_straight_berm_matches_its_parameters() {
        let g = BermGeometry::new(&berm(0.0), 1.0);
        let relief = |x: f64, z: f64| g.sample(x, z).map(|s| s.1);
        // Heights h1 and h2 at the ends of the axis, and in between linearly.
        assert!(close(relief(50.0, 50.0).unwrap(), 4.0));
        assert!(close(relief(90.0, 50.0).unwrap(), 2.0));
        assert!(close(relief(70.0, 50.0).unwrap(), 3.0));
        assert_eq!(relief(49.99, 50.0), None);
        assert_eq!(relief(90.01, 50.0), None);
        // Half-widths r1 at the start and r2 at the end (the axis heads +X, right is +Z).
        assert!(relief(50.0, 55.99).is_some() && relief(50.0, 56.01).is_none());
        assert!(relief(50.0, 44.01).is_some() && relief(50.0, 43.99).is_none());
        assert!(relief(90.0, 52.99).is_some() && relief(90.0, 53.01).is_none());
        // The cross-section at d = r/2 is the c2 superellipse: h (1 − (1/2)^c2)^(1/c2).
        let want = |h: f64| h * (1.0 - 0.5f64.powi(3)).powf(1.0 / 3.0);
        assert!(close(relief(50.0, 53.0).unwrap(), want(4.0)));
        assert!(close(relief(70.0, 50.0 - 2.25).unwrap(), want(3.0)));

        // A swale is the same shape, downwards.
        let s = BermGeometry::new(&berm(0.0), -1.0);
        assert!(close(s.sample(50.0, 53.0).unwrap().1, -want(4.0)));
    }

    #[test]
    fn a_berm_with_a_vanishing_curvature_is_straight() {
        let straight = BermGeometry::new(&berm(0.0), 1.0);
        let nearly = BermGeometry::new(&berm(1e-30), 1.0);
        for (x, z) in [(53.0, 50.5), (60.0, 49.0), (69.0, 50.0), (89.5, 50.0), (95.0, 50.0)] {
            assert_eq!(straight.sample(x, z), nearly.sample(x, z), "at ({x}, {z})");
        }
    }

    #[test]
    fn a_curved_berm_follows_its_arc() {
        // Curvature 1/40 turning from +X toward +Z: a quarter circle of radius 40 about
        // (50, 90), from (50, 50) to (90, 90).
        let quarter = 40.0 * std::f32::consts::FRAC_PI_2;
        let b = Berm { l: quarter, ..berm(1.0 / 40.0) };
        let g = BermGeometry::new(&b, 1.0);
        let relief = |x: f64, z: f64| g.sample(x, z).map(|s| s.1);
        let mid = std::f64::consts::FRAC_PI_4;
        let (mx, mz) = (50.0 + 40.0 * mid.cos(), 90.0 - 40.0 * mid.sin());
        assert!(close(relief(mx, mz).unwrap(), 3.0), "the axis passes through the arc's midpoint");
        assert!(close(relief(90.0, 90.0).unwrap(), 2.0), "and ends at h2");
        // Half-width at the middle is 4.5 m, measured along the radius.
        let out = |r: f64| (50.0 + r * mid.cos(), 90.0 - r * mid.sin());
        let (x, z) = out(44.49);
        assert!(relief(x, z).is_some());
        let (x, z) = out(44.51);
        assert!(relief(x, z).is_none());
        // The straight berm's axis would have gone on along z = 50; the arc does not.
        assert_eq!(relief(85.0, 50.0), None);
        // The bounds hold every point of the footprint, and not much more.
        let bounds = g.bounds();
        let mut inside = 0;
        for i in 0..=1000 {
            for j in 0..=1000 {
                let (x, z) = (30.0 + i as f64 * 0.08, 30.0 + j as f64 * 0.08);
                if g.sample(x, z).is_some() {
                    inside += 1;
                    assert!(bounds.contains(x, z), "({x}, {z}) outside {bounds:?}");
                }
            }
        }
        assert!(inside > 10_000);
        assert!(bounds.min_x > 49.9 && bounds.max_x < 96.1 && bounds.min_z > 43.9 && bounds.max_z < 90.1, "{bounds:?}");
        // A left turn mirrors it.
        let left = BermGeometry::new(&Berm { l: quarter, ..berm(-1.0 / 40.0) }, 1.0);
        assert!(close(left.sample(mx, 100.0 - mz).unwrap().1, 3.0));
    }

    #[test]
    fn the_other_shapes_have_their_documented_profiles() {
        let torus = TorusGeometry { cx: 0.0, cz: 0.0, major: 20.0, minor: 4.0, height: 3.0, base: 0.0 };
        assert!(close(torus.sample(20.0, 0.0).unwrap().1, 3.0));
        assert!(close(torus.sample(0.0, -22.0).unwrap().1, 3.0 * 0.75f64.sqrt()));
        assert!(torus.sample(0.0, 0.0).is_none() && torus.sample(24.5, 0.0).is_none());

        let boxed =
            BoxGeometry { frame: frame_at(&point(0.0, 0.0), 90.0), half_x: 10.0, half_z: 2.0, height: 3.0, base: 1.0 };
        assert_eq!(boxed.sample(0.0, 9.0), Some((1.0, 3.0)), "rotated 90°, its X side lies along Z");
        assert_eq!(boxed.sample(9.0, 0.0), None);

        let cone = ConeGeometry { cx: 0.0, cz: 0.0, radius: 10.0, top: 4.0, height: 6.0, base: 0.0 };
        assert!(close(cone.sample(3.0, 0.0).unwrap().1, 6.0));
        assert!(close(cone.sample(7.0, 0.0).unwrap().1, 3.0));
        assert!(cone.sample(10.5, 0.0).is_none());

        let half =
            HalfCylinderGeometry { frame: frame_at(&point(0.0, 0.0), 0.0), length: 30.0, radius: 5.0, base: 0.0 };
        assert!(close(half.sample(10.0, 3.0).unwrap().1, 4.0));
        assert!(half.sample(31.0, 0.0).is_none());

        // "A long straight ramp at 7%, widening at the top."
        let ramp = RampGeometry {
            frame: frame_at(&point(0.0, 0.0), 0.0),
            length: 100.0,
            w0: 6.0,
            w1: 12.0,
            h0: 0.0,
            h1: 7.0,
            base: 0.0,
        };
        assert!(close(ramp.sample(50.0, 0.0).unwrap().1, 3.5));
        assert!(ramp.sample(50.0, 4.4).is_some() && ramp.sample(50.0, 4.6).is_none());
        assert!(ramp.sample(100.0, 5.9).is_some() && ramp.sample(0.0, 3.1).is_none());
    }

    #[test]
    fn impossible_shapes_are_refused_naming_the_field() {
        let check = |shape: Shape| {
            let mut v = Validator::new();
            shape.validate(&mut v, &Limits::default());
            v.errors.into_iter().map(|e| e.field).collect::<Vec<_>>()
        };
        assert_eq!(check(Shape::Berm(Berm { r1: 0.0, r2: 0.0, ..berm(0.0) })), vec!["berm.r2"]);
        assert_eq!(check(Shape::Swale(Berm { c: 0.2, ..berm(0.0) })), vec!["swale.c"]);
        assert_eq!(check(Shape::Berm(Berm { c: 0.01, l: 1000.0, ..berm(0.0) })), vec!["berm.c"]);
        let cone = Cone { center: point(0.0, 0.0), radius_m: 5.0, height_m: 2.0, top_radius_m: 5.0, base_m: 0.0 };
        assert_eq!(check(Shape::Cone(cone)), vec!["cone.top_radius_m"]);
        let mound = Mound { center: point(f32::NAN, 0.0), radius_m: 0.0, height_m: 1.0, curvature: 2.0, base_m: 0.0 };
        assert_eq!(check(Shape::Mound(mound)), vec!["mound.center.x", "mound.radius_m"]);
    }
}
