//! The `bulldoze` request: a terrain, an optional window and resolution, and a list of
//! operations (landform primitives and blade passes) applied in order.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::blade::Blade;
use super::combine::Operator;
use super::contour::ContourPath;
use super::primitives::Shape;
use super::refine::Refine;
use super::scopes::{GlobalOp, LocalOp};
use crate::export::TileGrid;
use crate::terrain::TerrainSource;
use crate::validate::{Limits, Validate, Validator};

/// Edit a heightfield with landform primitives and blades swept along paths (Ervin &
/// Westort, "Procedural Terrain: A Virtual Bulldozer").
///
/// Axes: X along the grid's columns, Z along its rows, Y up; lengths and heights in metres. Every
/// operation has a *relief* r(x, z) (its own shape's height above its base) and a *base*
/// b(x, z); the absolute surface it describes is v = b + r. Each operation changes only the
/// samples inside its footprint (and inside `window`), combining the current height z with
/// it by its operator: `add` z + r, `subtract` z − r, `max` max(z, v), `min` min(z, v),
/// `average` (z + v) / 2, `replace` v.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeParams)]
pub struct BulldozeParams {
    /// The starting terrain.
    pub terrain: TerrainSource,
    /// The window of operation: operations change only samples inside it. Absent: the whole grid.
    #[serde(default)]
    pub window: Option<Window>,
    /// Metres between samples of the output grid. The terrain is resampled (bilinear) to it
    /// over the same extent — coarse for a quick sketch, fine for the final form. Absent: the
    /// terrain's own cell size.
    ///
    /// At most 1 000 000 m. The resampled grid must keep at least 2 × 2 samples and hold at most
    /// the server's grid cap (4097 × 4097 samples by default; larger is answered with 413).
    #[serde(default)]
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub resolution: Option<f32>,
    /// Primitives and passes, applied in order; each acts on the result of the ones before.
    ///
    /// Primitives and path vertices together may number at most the server's operation cap
    /// (100 000 by default; more is answered with 413).
    pub operations: Vec<Operation>,
    /// Cut the terrain's mesh into tiles as well, at every level of detail (`tiles/…`).
    /// Absent: no tiles.
    #[serde(default)]
    pub tiles: Option<TileGrid>,
}

/// A plan rectangle in metres (inclusive bounds).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeWindow)]
pub struct Window {
    /// Smallest x, metres.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub min_x: f32,
    /// Smallest z, metres.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub min_z: f32,
    /// Largest x, metres; greater than `min_x`.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub max_x: f32,
    /// Largest z, metres; greater than `min_z`.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub max_z: f32,
}

/// One operation, by the paper's scopes of action (§2): `local` (listed vertices), `primitive`
/// and `pass` (a move or a pass of moves over a footprint), `global` (every vertex).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
#[schema(as = BulldozeOperation)]
pub enum Operation {
    /// A parameterised landform primitive combined with the surface.
    Primitive(PrimitiveOp),
    /// A blade swept along a path: one move per path segment.
    Pass(PassOp),
    /// Listed vertices set or offset exactly.
    Local(LocalOp),
    /// A height transform of every vertex.
    Global(GlobalOp),
    /// From here on, a finer resolution and a window: detail worked inside a coarser whole.
    Refine(Refine),
}

fn default_primitive_operator() -> Operator {
    Operator::Add
}

fn default_pass_operator() -> Operator {
    Operator::Replace
}

/// A landform primitive and how it combines with the surface.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozePrimitive)]
pub struct PrimitiveOp {
    pub shape: Shape,
    /// How the primitive combines with the surface; `add` stacks its relief on the terrain.
    #[serde(default = "default_primitive_operator")]
    #[schema(default = "add")]
    pub operator: Operator,
}

/// A pass: the blade pushed along the path, one move per segment.
///
/// A move covers what the blade sweeps along its segment: base = the path's height where the
/// blade's centre is, relief = the profile. At each bend the blade also pivots about the
/// vertex from one heading to the next, filling the outside of the bend (base: the vertex's
/// height). All moves of a pass act on the surface as it was when the pass began (paper
/// §2.4); where two moves overlap (inside a bend, or where a spiral's turns meet) the later
/// move's result stands, so an `add` or `subtract` pass never cuts a sample twice.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozePass)]
pub struct PassOp {
    /// The path: at least 2 vertices, no two consecutive ones at the same place. At most the
    /// server's operation cap (100 000 by default; more is answered with 413). Exactly one of
    /// `path` and `contour`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub path: Vec<PathVertex>,
    /// The path traced along a contour of the terrain as the pass starts, its vertices at the
    /// contour's height. Exactly one of `path` and `contour`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contour: Option<ContourPath>,
    /// The blade's base between vertices: `linear` interpolates the vertices' heights; `ground`
    /// follows the terrain under the blade's centre (as the pass started), offset by the
    /// vertices' heights above it interpolated linearly — a relative path then rides the
    /// ground all the way, not only at its vertices.
    #[serde(default, skip_serializing_if = "PathBase::is_linear")]
    pub base: PathBase,
    pub blade: Blade,
    /// How each move combines with the surface; `replace` leaves the blade's profile, as a
    /// real bulldozer does. The move's base is the path's height, its relief the profile.
    #[serde(default = "default_pass_operator")]
    #[schema(default = "replace")]
    pub operator: Operator,
    /// A blade of changing profile along the path (the paper's "blade of continually changing
    /// profile along an exponential spiral"): profiles at path vertices, in increasing vertex
    /// order, at most one per vertex. The blade's own `profile` is the profile at vertex 0
    /// unless a keyframe is there; between two keyframes the profile at every point of the path
    /// is the pointwise linear blend (at every u) by arc length; after the last it holds.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub keyframes: Vec<ProfileKeyframe>,
}

/// How a move's base runs between its vertices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = BulldozePathBase)]
pub enum PathBase {
    #[default]
    Linear,
    Ground,
}

impl PathBase {
    pub fn is_linear(&self) -> bool {
        *self == PathBase::Linear
    }
}

/// The blade's profile at one path vertex.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeProfileKeyframe)]
pub struct ProfileKeyframe {
    /// Index of the path vertex (0-based).
    pub vertex: u32,
    /// As the blade's `profile`: 2 to 64 points `[u, height_m]`, u from −1 to +1.
    #[schema(schema_with = super::blade::profile_schema)]
    pub profile: Vec<[f32; 2]>,
}

/// A path vertex.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozePathVertex)]
pub struct PathVertex {
    /// Metres along X.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub x: f32,
    /// Metres along Z.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub z: f32,
    /// Absolute height of the path here, metres. Absent (null): relative — the height of the
    /// terrain at this vertex as it is when the pass starts (bilinear), as a real bulldozer
    /// riding on the ground. A path may mix both.
    #[serde(default)]
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub height: Option<f32>,
}

/// A horizontal position in metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozePoint)]
pub struct PlanPoint {
    /// Metres along X.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub x: f32,
    /// Metres along Z.
    // ±1e6 = MAX_METRES
    #[schema(minimum = -1e6, maximum = 1e6)]
    pub z: f32,
}

/// Largest magnitude of any length, height or coordinate in a request, metres: far beyond
/// any real terrain, and small enough that heights summed over every operation a request
/// may carry stay finite.
pub const MAX_METRES: f32 = 1e6;

/// The sign a value in metres must have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Sign {
    Any,
    Positive,
    NonNegative,
}

/// Check a length, height or coordinate: finite, of `sign`, and at most [`MAX_METRES`] in
/// magnitude. Reports the first thing wrong under `leaf`; returns whether it is fine.
pub(super) fn metres(v: &mut Validator, leaf: &str, value: f32, sign: Sign) -> bool {
    let problem = if !value.is_finite() {
        "must be a finite number".to_string()
    } else if sign == Sign::Positive && value <= 0.0 {
        format!("must be greater than 0 (got {value})")
    } else if sign == Sign::NonNegative && value < 0.0 {
        format!("must not be negative (got {value})")
    } else if value.abs() > MAX_METRES {
        match sign {
            Sign::Any => format!("must be between -{MAX_METRES} and {MAX_METRES} m (got {value})"),
            _ => format!("must be at most {MAX_METRES} m (got {value})"),
        }
    } else {
        return true;
    };
    v.error(leaf, problem);
    false
}

impl BulldozeParams {
    /// Number of recorded steps the operations make: one per primitive, one per move.
    pub fn step_count(&self) -> u64 {
        self.operations
            .iter()
            .map(|op| match op {
                Operation::Primitive(_) | Operation::Local(_) | Operation::Global(_) | Operation::Refine(_) => 1,
                Operation::Pass(p) => p.vertices().saturating_sub(1),
            })
            .fold(0u64, u64::saturating_add)
    }
}

/// Samples (cols, rows) of a grid resampled to `resolution_m`, computed as
/// `Heightfield::resampled` does.
pub(crate) fn resampled_dimensions(cols: u64, rows: u64, cell_size_m: f32, resolution_m: f32) -> (u64, u64) {
    let along = |n: u64| (((n.saturating_sub(1)) as f32 * cell_size_m / resolution_m).floor() as u64).saturating_add(1);
    (along(cols), along(rows))
}

/// Why a resampled grid is unusable, if it is: (message, whether it is over the cap).
pub(crate) fn check_resampled(cols: u64, rows: u64, limits: &Limits) -> Option<(String, bool)> {
    if cols < 2 || rows < 2 {
        Some((format!("is coarser than the terrain: the grid would have {cols}×{rows} samples"), false))
    } else if cols.saturating_mul(rows) > limits.max_grid_cells {
        Some((
            format!(
                "the resampled grid would have {cols}×{rows} samples, more than the cap of {}",
                limits.max_grid_cells
            ),
            true,
        ))
    } else {
        None
    }
}

impl Validate for BulldozeParams {
    fn validate(&self, v: &mut Validator, limits: &Limits) {
        v.field("terrain", |v| self.terrain.validate(v, limits));
        if let Some(tiles) = &self.tiles {
            v.field("tiles", |v| tiles.validate(v, limits));
        }
        if let Some(w) = &self.window {
            v.field("window", |v| w.validate(v, limits));
        }
        if let Some(res) = self.resolution {
            let fine = metres(v, "resolution", res, Sign::Positive);
            let dims = self.terrain.known_dimensions().zip(self.terrain.known_cell_size());
            if let (true, Some(((cols, rows), cell))) = (fine, dims) {
                if cell.is_finite() && cell > 0.0 {
                    let (c, r) = resampled_dimensions(cols, rows, cell, res);
                    match check_resampled(c, r, limits) {
                        Some((message, true)) => v.too_large("resolution", message),
                        Some((message, false)) => v.error("resolution", message),
                        None => {}
                    }
                }
            }
        }
        let steps: u64 = self
            .operations
            .iter()
            .map(|op| match op {
                Operation::Primitive(_) | Operation::Global(_) | Operation::Refine(_) => 1,
                Operation::Pass(p) => p.vertices(),
                Operation::Local(l) => l.vertices.len() as u64,
            })
            .fold(0u64, u64::saturating_add);
        if steps > limits.max_operations {
            v.too_large(
                "operations",
                format!(
                    "{steps} operations, path vertices and local vertices in all is more than the cap of {}",
                    limits.max_operations
                ),
            );
        }
        v.field("operations", |v| {
            for (i, op) in self.operations.iter().enumerate() {
                v.index(i, |v| op.validate(v, limits));
            }
        });
        // Each refine's grid, when the terrain's size is known: finer than the one before, and
        // within the cap.
        let dims = self.terrain.known_dimensions().zip(self.terrain.known_cell_size());
        if let Some(((cols, rows), cell)) = dims.filter(|(_, cell)| cell.is_finite() && *cell > 0.0) {
            let mut current = self.resolution.filter(|r| r.is_finite() && *r > 0.0).unwrap_or(cell);
            v.field("operations", |v| {
                for (i, op) in self.operations.iter().enumerate() {
                    let Operation::Refine(r) = op else { continue };
                    if !(r.resolution.is_finite() && r.resolution > 0.0) {
                        continue;
                    }
                    v.index(i, |v| {
                        v.field("refine", |v| {
                            if r.resolution > current {
                                v.error("resolution", format!("must not be coarser than the grid's {current} m"));
                            }
                            let (c, rr) = resampled_dimensions(cols, rows, cell, r.resolution);
                            match check_resampled(c, rr, limits) {
                                Some((message, true)) => v.too_large("resolution", message),
                                Some((message, false)) => v.error("resolution", message),
                                None => {}
                            }
                        })
                    });
                    current = current.min(r.resolution);
                }
            });
        }
    }
}

impl Validate for Window {
    fn validate(&self, v: &mut Validator, _limits: &Limits) {
        let ok = [("min_x", self.min_x), ("min_z", self.min_z), ("max_x", self.max_x), ("max_z", self.max_z)]
            .into_iter()
            .fold(true, |ok, (name, value)| metres(v, name, value, Sign::Any) && ok);
        if ok {
            if self.max_x <= self.min_x {
                v.error("max_x", "must be greater than min_x");
            }
            if self.max_z <= self.min_z {
                v.error("max_z", "must be greater than min_z");
            }
        }
    }
}

impl Validate for Operation {
    fn validate(&self, v: &mut Validator, limits: &Limits) {
        match self {
            Operation::Primitive(p) => v.field("primitive", |v| v.field("shape", |v| p.shape.validate(v, limits))),
            Operation::Pass(p) => v.field("pass", |v| p.validate(v, limits)),
            Operation::Local(l) => v.field("local", |v| l.validate(v, limits)),
            Operation::Global(g) => v.field("global", |v| g.validate(v, limits)),
            Operation::Refine(r) => v.field("refine", |v| r.validate(v, limits)),
        }
    }
}

impl PassOp {
    /// The path's vertices: as listed, or the most a contour may give.
    pub fn vertices(&self) -> u64 {
        self.contour.as_ref().map_or(self.path.len() as u64, ContourPath::max_vertices)
    }
}

impl Validate for PassOp {
    fn validate(&self, v: &mut Validator, limits: &Limits) {
        v.field("blade", |v| self.blade.validate(v, limits));
        if let Some(c) = &self.contour {
            if !self.path.is_empty() {
                v.error("path", "give either path or contour, not both");
            }
            if !self.keyframes.is_empty() {
                v.error("keyframes", "name vertices of a listed path; a contour's vertices are not known in advance");
            }
            v.field("contour", |v| c.validate(v, limits));
            return;
        }
        if self.path.len() < 2 {
            v.error("path", format!("needs at least 2 points (got {})", self.path.len()));
        } else if self.path.len() as u64 > limits.max_operations {
            v.too_large(
                "path",
                format!("{} points is more than the cap of {}", self.path.len(), limits.max_operations),
            );
        }
        v.field("keyframes", |v| {
            for (i, k) in self.keyframes.iter().enumerate() {
                v.index(i, |v| {
                    if k.vertex as usize >= self.path.len() {
                        v.error(
                            "vertex",
                            format!("must name a path vertex (0 to {})", self.path.len().saturating_sub(1)),
                        );
                    } else if i > 0 && k.vertex <= self.keyframes[i - 1].vertex {
                        v.error("vertex", "keyframes must follow the path, one per vertex at most");
                    }
                    super::blade::validate_profile(v, &k.profile);
                });
            }
        });
        v.field("path", |v| {
            for (i, p) in self.path.iter().enumerate() {
                v.index(i, |v| {
                    let finite = metres(v, "x", p.x, Sign::Any) & metres(v, "z", p.z, Sign::Any);
                    if let Some(h) = p.height {
                        metres(v, "height", h, Sign::Any);
                    }
                    if finite && i > 0 {
                        let prev = self.path[i - 1];
                        if prev.x == p.x && prev.z == p.z {
                            v.error("", "is at the same place as the point before it");
                        }
                    }
                });
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn validate(body: serde_json::Value) -> Validator {
        let params: BulldozeParams = serde_json::from_value(body).expect("parses");
        let mut v = Validator::new();
        params.validate(&mut v, &Limits::default());
        v
    }

    fn fields(v: &Validator) -> Vec<&str> {
        v.errors.iter().map(|e| e.field.as_str()).collect()
    }

    fn job_terrain() -> serde_json::Value {
        json!({"job": "0190a0f4-4a9e-7c3e-8000-000000000001"})
    }

    #[test]
    fn defaults_are_filled_in_and_shown() {
        let body = json!({
            "terrain": job_terrain(),
            "operations": [
                {"primitive": {"shape": {"mound": {"center": {"x": 1, "z": 2}, "radius_m": 5, "height_m": 2}}}},
                {"pass": {"path": [{"x": 0, "z": 0}, {"x": 5, "z": 0, "height": 3}], "blade": {"width_m": 4}}}
            ]
        });
        let params: BulldozeParams = serde_json::from_value(body).unwrap();
        let shown = serde_json::to_value(&params).unwrap();
        assert_eq!(shown["operations"][0]["primitive"]["operator"], "add");
        assert_eq!(shown["operations"][0]["primitive"]["shape"]["mound"]["curvature"], 2.0);
        assert_eq!(shown["operations"][0]["primitive"]["shape"]["mound"]["base_m"], 0.0);
        assert_eq!(shown["operations"][1]["pass"]["operator"], "replace");
        assert_eq!(shown["operations"][1]["pass"]["blade"]["profile"], json!([[-1.0, 0.0], [1.0, 0.0]]));
        assert_eq!(shown["operations"][1]["pass"]["path"][0]["height"], serde_json::Value::Null);
        assert_eq!(params.step_count(), 2);
        let again: BulldozeParams = serde_json::from_value(shown).unwrap();
        assert_eq!(again, params);
    }

    #[test]
    fn unknown_fields_are_refused() {
        let body = json!({
            "terrain": job_terrain(),
            "operations": [{"pass": {"path": [], "blade": {"width_m": 4, "colour": "red"}}}]
        });
        assert!(serde_json::from_value::<BulldozeParams>(body).is_err());
    }

    #[test]
    fn a_blade_with_no_width_and_a_short_path_name_their_fields() {
        let v = validate(json!({
            "terrain": job_terrain(),
            "operations": [
                {"primitive": {"shape": {"cone": {"center": {"x": 0, "z": 0}, "radius_m": 5, "height_m": 1}}}},
                {"pass": {"path": [{"x": 0, "z": 0}], "blade": {"width_m": 0}}}
            ]
        }));
        assert_eq!(fields(&v), vec!["operations[1].pass.blade.width_m", "operations[1].pass.path"]);
        assert!(!v.too_large);
    }

    #[test]
    fn repeated_path_points_and_bad_windows_are_refused() {
        let v = validate(json!({
            "terrain": job_terrain(),
            "window": {"min_x": 5, "min_z": 0, "max_x": 5, "max_z": 1},
            "operations": [{"pass": {"path": [{"x": 1, "z": 1}, {"x": 1, "z": 1}], "blade": {"width_m": 2}}}]
        }));
        assert_eq!(fields(&v), vec!["window.max_x", "operations[0].pass.path[1]"]);
    }

    #[test]
    fn too_many_operations_is_too_large() {
        let path: Vec<_> = (0..20).map(|i| json!({"x": i, "z": 0})).collect();
        let params: BulldozeParams = serde_json::from_value(json!({
            "terrain": job_terrain(),
            "operations": [{"pass": {"path": path, "blade": {"width_m": 2}}}]
        }))
        .unwrap();
        let mut v = Validator::new();
        params.validate(&mut v, &Limits { max_operations: 10, ..Limits::default() });
        assert!(v.too_large);
        assert_eq!(fields(&v), vec!["operations", "operations[0].pass.path"]);
    }

    #[test]
    fn resolution_is_checked_against_the_grid_cap() {
        let body = |res: f32| {
            json!({
                "terrain": {"fractal": {"size": 257, "cell_size": 1.0}},
                "resolution": res,
                "operations": []
            })
        };
        let params: BulldozeParams = serde_json::from_value(body(0.1)).unwrap();
        let mut v = Validator::new();
        params.validate(&mut v, &Limits { max_grid_cells: 1_000_000, ..Limits::default() });
        assert!(v.too_large);
        assert_eq!(fields(&v), vec!["resolution"]);

        let v = validate(body(0.5));
        assert!(v.is_ok(), "{:?}", v.errors);
        let v = validate(body(300.0));
        assert_eq!(fields(&v), vec!["resolution"]);
        assert!(!v.too_large);
        let v = validate(body(0.0));
        assert_eq!(fields(&v), vec!["resolution"]);
        let v = validate(body(1e-30));
        assert!(v.too_large);
    }

    #[test]
    fn lengths_heights_and_coordinates_beyond_a_million_metres_are_refused() {
        let v = validate(json!({
            "terrain": job_terrain(),
            "window": {"min_x": -2e6, "min_z": 0, "max_x": 10, "max_z": 10},
            "resolution": 2e6,
            "operations": [
                {"primitive": {"shape": {"mound": {
                    "center": {"x": 1e30, "z": 0}, "radius_m": 1e38, "height_m": 3e38, "base_m": -1e7}}}},
                {"primitive": {"shape": {"ramp": {"start": {"x": 0, "z": 0}, "length_m": 10, "width_m": 4,
                    "end_width_m": 2e6, "start_height_m": -3e38, "end_height_m": 1}}}},
                {"pass": {"path": [{"x": 0, "z": 1e30}, {"x": 5, "z": 0, "height": 3e38}],
                          "blade": {"width_m": 1e7, "offset_m": -1e7, "profile": [[-1, 0], [1, 3e38]]}}}
            ]
        }));
        let shape = |leaf: &str| format!("operations[0].primitive.shape.mound.{leaf}");
        let ramp = |leaf: &str| format!("operations[1].primitive.shape.ramp.{leaf}");
        let pass = |leaf: &str| format!("operations[2].pass.{leaf}");
        let want = [
            "window.min_x".to_string(),
            "resolution".to_string(),
            shape("center.x"),
            shape("radius_m"),
            shape("height_m"),
            shape("base_m"),
            ramp("end_width_m"),
            ramp("start_height_m"),
            pass("blade.width_m"),
            pass("blade.offset_m"),
            pass("blade.profile[1][1]"),
            pass("path[0].z"),
            pass("path[1].height"),
        ];
        assert_eq!(fields(&v), want);
        assert!(v.errors.iter().all(|e| e.message.contains("1000000 m")), "{:?}", v.errors);
        assert!(!v.too_large);

        // A million metres itself is allowed.
        let v = validate(json!({
            "terrain": job_terrain(),
            "operations": [{"primitive": {"shape": {"mound": {
                "center": {"x": -1e6, "z": 1e6}, "radius_m": 1e6, "height_m": 1e6, "base_m": -1e6}}}}]
        }));
        assert!(v.is_ok(), "{:?}", v.errors);
    }
}
