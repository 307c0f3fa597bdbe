//! Request validation: every kind's parameters report bad values with the JSON path of the
//! field, so the HTTP edge can answer with a problem+json `errors` list.

use serde::Serialize;
use utoipa::ToSchema;

/// Server-side caps on sizes a client controls.
#[derive(Clone, Debug)]
pub struct Limits {
    /// Most samples a heightfield may have (cols × rows).
    pub max_grid_cells: u64,
    /// Most operations (primitives, path vertices, …) one request may carry.
    pub max_operations: u64,
    /// Most voxels a volumetric kind may allocate.
    pub max_voxels: u64,
}

pub const DEFAULT_MAX_GRID_CELLS: u64 = 4097 * 4097;
pub const DEFAULT_MAX_OPERATIONS: u64 = 100_000;
pub const DEFAULT_MAX_VOXELS: u64 = 192 * 1024 * 1024;

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_grid_cells: DEFAULT_MAX_GRID_CELLS,
            max_operations: DEFAULT_MAX_OPERATIONS,
            max_voxels: DEFAULT_MAX_VOXELS,
        }
    }
}

/// One bad field: its JSON path (e.g. `operations[2].pass.blade.width_m`) and what is wrong.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize, ToSchema)]
pub struct FieldError {
    pub field: String,
    pub message: String,
}

/// Collects field errors while walking a request; the path grows as it descends.
#[derive(Debug, Default)]
pub struct Validator {
    path: Vec<String>,
    pub errors: Vec<FieldError>,
    /// Set when a size exceeds a configured cap.
    pub too_large: bool,
    /// How many of `errors` are sizes over a cap.
    size_errors: usize,
}

impl Validator {
    pub fn new() -> Self {
        Self::default()
    }

    fn path_with(&self, leaf: &str) -> String {
        let mut out = String::new();
        for seg in self.path.iter().map(String::as_str).chain(std::iter::once(leaf)) {
            if seg.is_empty() {
                continue;
            }
            if !out.is_empty() && !seg.starts_with('[') {
                out.push('.');
            }
            out.push_str(seg);
        }
        out
    }

    /// Validate inside the named field.
    pub fn field(&mut self, name: &str, f: impl FnOnce(&mut Self)) {
        self.path.push(name.to_string());
        f(self);
        self.path.pop();
    }

    /// Validate inside element `i` of the current list.
    pub fn index(&mut self, i: usize, f: impl FnOnce(&mut Self)) {
        self.path.push(format!("[{i}]"));
        f(self);
        self.path.pop();
    }

    /// Report an error at the current path joined with `leaf` (may be empty).
    pub fn error(&mut self, leaf: &str, message: impl Into<String>) {
        let field = self.path_with(leaf);
        self.errors.push(FieldError { field, message: message.into() });
    }

    /// Report a size over a configured cap (HTTP 413).
    pub fn too_large(&mut self, leaf: &str, message: impl Into<String>) {
        self.too_large = true;
        self.size_errors += 1;
        self.error(leaf, message);
    }

    /// The answer is 413 when every error is a size over a cap; any other bad value makes it
    /// 422, as a request that is wrong is wrong whatever its size.
    pub fn only_too_large(&self) -> bool {
        self.too_large && self.size_errors == self.errors.len()
    }

    pub fn finite(&mut self, leaf: &str, v: f64) -> bool {
        if v.is_finite() {
            true
        } else {
            self.error(leaf, "must be a finite number");
            false
        }
    }

    /// `v > 0` and finite.
    pub fn positive(&mut self, leaf: &str, v: f64) {
        if self.finite(leaf, v) && v <= 0.0 {
            self.error(leaf, format!("must be greater than 0 (got {v})"));
        }
    }

    /// `v >= 0` and finite.
    pub fn non_negative(&mut self, leaf: &str, v: f64) {
        if self.finite(leaf, v) && v < 0.0 {
            self.error(leaf, format!("must not be negative (got {v})"));
        }
    }

    /// `lo <= v <= hi` and finite.
    pub fn in_range(&mut self, leaf: &str, v: f64, lo: f64, hi: f64) {
        if self.finite(leaf, v) && !(lo..=hi).contains(&v) {
            self.error(leaf, format!("must be between {lo} and {hi} (got {v})"));
        }
    }

    pub fn is_ok(&self) -> bool {
        self.errors.is_empty()
    }
}

/// Implemented by every request type: report each bad field to the validator.
pub trait Validate {
    fn validate(&self, v: &mut Validator, limits: &Limits);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_join_fields_and_indices() {
        let mut v = Validator::new();
        v.field("operations", |v| v.index(2, |v| v.field("pass", |v| v.positive("width_m", 0.0))));
        assert_eq!(v.errors[0].field, "operations[2].pass.width_m");
    }
}
