//! The blade (paper §2.1): a 2-D profile swept along a path.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::params::{metres, Sign};
use crate::validate::{Limits, Validate, Validator};

fn default_profile() -> Vec<[f32; 2]> {
    vec![[-1.0, 0.0], [1.0, 0.0]]
}

/// Largest angle of the blade away from perpendicular to the path, degrees (exclusive).
pub const MAX_ANGLE_DEG: f32 = 80.0;
/// Most points of a blade profile: every move of a pass records a copy of it.
pub const MAX_PROFILE_POINTS: usize = 64;

/// The blade: a cross-section profile pushed along the path.
///
/// Across the blade the coordinate u runs from −1 at its left edge to +1 at its right edge,
/// as seen facing the direction of travel; a point at u lies `u · width_m / 2` metres from
/// the blade's centre. "Right" is the travel direction turned 90° clockwise seen from above
/// (−90° about +Y): travelling along +X, right is +Z.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeBlade)]
pub struct Blade {
    /// Width of the blade in metres, edge to edge.
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub width_m: f32,
    /// The profile: points `[u, height_m]`, u strictly increasing from exactly −1 (left edge)
    /// to exactly +1 (right edge), height in metres relative to the path's height, linear
    /// between points. At least 2 points and at most 64; each point is exactly 2 numbers, u in
    /// [−1, 1] and height_m within ±1 000 000 m.
    #[serde(default = "default_profile")]
    #[schema(schema_with = profile_schema)]
    pub profile: Vec<[f32; 2]>,
    /// Sideways shift of the blade's centre from the path, metres; positive to the right of
    /// travel.
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(default = 0.0, minimum = -1e6, maximum = 1e6)]
    pub offset_m: f32,
    /// Rotation of the blade about the vertical away from perpendicular to the path, degrees,
    /// |angle| < 80 (exclusive); positive brings the blade's right end ahead of its centre.
    #[serde(default)]
    // ±80 = MAX_ANGLE_DEG, exclusive
    #[schema(default = 0.0, exclusive_minimum = -80.0, exclusive_maximum = 80.0)]
    pub angle_deg: f32,
}

impl Validate for Blade {
    fn validate(&self, v: &mut Validator, _limits: &Limits) {
        metres(v, "width_m", self.width_m, Sign::Positive);
        metres(v, "offset_m", self.offset_m, Sign::Any);
        if v.finite("angle_deg", self.angle_deg as f64) && self.angle_deg.abs() >= MAX_ANGLE_DEG {
            v.error(
                "angle_deg",
                format!("must be between -{MAX_ANGLE_DEG} and {MAX_ANGLE_DEG}, exclusive (got {})", self.angle_deg),
            );
        }
        validate_profile(v, &self.profile);
    }
}

/// Check a profile: 2 to 64 points `[u, height_m]`, u strictly increasing from exactly −1 to
/// exactly +1, heights in range. Errors go under `profile`.
/// A profile's schema: 2 to 64 points, each `[u, height_m]` with its own bounds (an array of
/// pairs whose items share one range would state ±1e6 for u, whose rule is [−1, 1]).
pub fn profile_schema() -> utoipa::openapi::schema::Schema {
    use utoipa::openapi::schema::{ArrayBuilder, ObjectBuilder, Type};
    let number = |lo: f64, hi: f64, what: &str| {
        ObjectBuilder::new()
            .schema_type(Type::Number)
            .format(Some(utoipa::openapi::SchemaFormat::KnownFormat(utoipa::openapi::KnownFormat::Float)))
            .minimum(Some(lo))
            .maximum(Some(hi))
            .description(Some(what))
    };
    let point = ArrayBuilder::new()
        .prefix_items([
            number(-1.0, 1.0, "u: −1 the blade's left edge, +1 its right edge"),
            // 1e6 = MAX_METRES
            number(-1e6, 1e6, "height_m: metres relative to the path's height"),
        ])
        .items(utoipa::openapi::schema::ArrayItems::False)
        .min_items(Some(2))
        .max_items(Some(2));
    ArrayBuilder::new()
        .items(point)
        // 64 = MAX_PROFILE_POINTS
        .min_items(Some(2))
        .max_items(Some(64))
        .default(Some(serde_json::json!([[-1.0, 0.0], [1.0, 0.0]])))
        .description(Some(
            "The profile: points `[u, height_m]`, u strictly increasing from exactly −1 (left edge) to exactly +1 (right edge), height in metres relative to the path's height, linear between points. At least 2 points and at most 64.",
        ))
        .into()
}

pub fn validate_profile(v: &mut Validator, p: &[[f32; 2]]) {
    if p.len() < 2 {
        v.error("profile", format!("needs at least 2 points (got {})", p.len()));
        return;
    }
    if p.len() > MAX_PROFILE_POINTS {
        v.error("profile", format!("may have at most {MAX_PROFILE_POINTS} points (got {})", p.len()));
        return;
    }
    v.field("profile", |v| {
        let mut all_finite = true;
        for (i, [u, h]) in p.iter().enumerate() {
            v.index(i, |v| {
                all_finite &= v.finite("[0]", *u as f64) & metres(v, "[1]", *h, Sign::Any);
            });
        }
        if !all_finite {
            return;
        }
        if p[0][0] != -1.0 {
            v.error("[0][0]", format!("the first point must be at u = -1, the blade's left edge (got {})", p[0][0]));
        }
        let last = p.len() - 1;
        if p[last][0] != 1.0 {
            v.error(
                &format!("[{last}][0]"),
                format!("the last point must be at u = 1, the blade's right edge (got {})", p[last][0]),
            );
        }
        for i in 1..p.len() {
            if p[i][0] <= p[i - 1][0] {
                v.error(&format!("[{i}][0]"), "u must increase strictly along the profile");
            }
        }
    });
}

/// A validated blade ready to evaluate.
#[derive(Clone, Debug)]
pub struct BladeGeometry {
    pub half_width_m: f64,
    pub offset_m: f64,
    pub cos_angle: f64,
    pub sin_angle: f64,
    u: Vec<f64>,
    height_m: Vec<f64>,
}

impl BladeGeometry {
    pub fn new(blade: &Blade) -> Self {
        let (sin_angle, cos_angle) = (blade.angle_deg as f64).to_radians().sin_cos();
        Self {
            half_width_m: blade.width_m as f64 / 2.0,
            offset_m: blade.offset_m as f64,
            cos_angle,
            sin_angle,
            u: blade.profile.iter().map(|p| p[0] as f64).collect(),
            height_m: blade.profile.iter().map(|p| p[1] as f64).collect(),
        }
    }

    /// Profile height at `u` in [−1, 1], linear between the profile's points.
    #[inline]
    pub fn profile(&self, u: f64) -> f64 {
        let n = self.u.len();
        // First point with u_i > u, kept so that [i − 1, i] is a valid span.
        let i = self.u.partition_point(|&ui| ui <= u).clamp(1, n - 1);
        let (u0, u1) = (self.u[i - 1], self.u[i]);
        let (h0, h1) = (self.height_m[i - 1], self.height_m[i]);
        h0 + (h1 - h0) * ((u - u0) / (u1 - u0))
    }

    /// The blade's plan position relative to its centre's track: a point at blade coordinate
    /// u lies `(along, across)` = `(a · sin, offset + a · cos)` from the track point, with
    /// a = u · width / 2.
    #[inline]
    pub fn end(&self, u: f64) -> (f64, f64) {
        let a = u * self.half_width_m;
        (a * self.sin_angle, self.offset_m + a * self.cos_angle)
    }

    /// Where a point at `(along, across)` of a segment's frame meets the blade: the blade's
    /// coordinate u and the distance along the segment its centre had reached, or `None` past
    /// the blade's edges.
    #[inline]
    pub fn locate(&self, along: f64, across: f64) -> Option<(f64, f64)> {
        let a = (across - self.offset_m) / self.cos_angle;
        let u = a / self.half_width_m;
        if u.abs() > 1.0 {
            return None;
        }
        Some((u, along - a * self.sin_angle))
    }
}

/// The profile `t` of the way from `a` to `b` (0 ≤ t ≤ 1): at every u, (1 − t)·a(u) + t·b(u),
/// on the union of their points (both piecewise linear, so this is exact between them).
pub fn blend_profiles(a: &[[f32; 2]], b: &[[f32; 2]], t: f64) -> Vec<[f32; 2]> {
    let (ga, gb) = (profile_geometry(a), profile_geometry(b));
    let mut us: Vec<f32> = a.iter().chain(b).map(|p| p[0]).collect();
    us.sort_by(f32::total_cmp);
    us.dedup();
    us.iter().map(|&u| [u, ((1.0 - t) * ga.profile(u as f64) + t * gb.profile(u as f64)) as f32]).collect()
}

fn profile_geometry(profile: &[[f32; 2]]) -> BladeGeometry {
    BladeGeometry::new(&Blade { width_m: 2.0, profile: profile.to_vec(), offset_m: 0.0, angle_deg: 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blade(profile: Vec<[f32; 2]>) -> Blade {
        Blade { width_m: 4.0, profile, offset_m: 0.0, angle_deg: 0.0 }
    }

    #[test]
    fn profile_interpolates_linearly() {
        let g = BladeGeometry::new(&blade(vec![[-1.0, 0.0], [0.0, -2.0], [1.0, 1.0]]));
        assert_eq!(g.profile(-1.0), 0.0);
        assert_eq!(g.profile(-0.5), -1.0);
        assert_eq!(g.profile(0.0), -2.0);
        assert_eq!(g.profile(0.5), -0.5);
        assert_eq!(g.profile(1.0), 1.0);
    }

    #[test]
    fn profiles_must_span_the_blade_in_order() {
        let check = |b: Blade| {
            let mut v = Validator::new();
            b.validate(&mut v, &Limits::default());
            v.errors.into_iter().map(|e| e.field).collect::<Vec<_>>()
        };
        assert!(check(blade(vec![[-1.0, 0.0], [1.0, 0.0]])).is_empty());
        assert_eq!(check(blade(vec![[-1.0, 0.0]])), vec!["profile"]);
        assert_eq!(check(blade(vec![[-0.5, 0.0], [1.0, 0.0]])), vec!["profile[0][0]"]);
        assert_eq!(check(blade(vec![[-1.0, 0.0], [0.2, 0.0], [0.1, 0.0], [1.0, 0.0]])), vec!["profile[2][0]"]);
        assert_eq!(check(blade(vec![[-1.0, 0.0], [0.9, 0.0]])), vec!["profile[1][0]"]);
        let mut b = blade(vec![[-1.0, 0.0], [1.0, 0.0]]);
        b.angle_deg = 80.0;
        b.width_m = -1.0;
        assert_eq!(check(b), vec!["width_m", "angle_deg"]);
    }
}
