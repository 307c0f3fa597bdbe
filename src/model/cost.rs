//! What a job will cost, estimated from its validated request before it runs: the engine admits
//! jobs by it (memory against the budget, work against the time limit).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// A job's estimated cost: the peak heap memory it may use and the work it will do.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Cost {
    /// Upper bound of the job's peak heap memory, bytes (measured to be at most 3 × the real peak).
    pub memory_bytes: u64,
    /// The request field whose value drives the memory most.
    pub memory_field: String,
    /// Work in the kind's own unit (`work_unit`).
    pub work: u64,
    pub work_unit: String,
    /// The request field whose value drives the work most.
    pub work_field: String,
    /// Seconds `work` takes at the kind's fastest rate (measured here, with a margin for faster
    /// machines): the least time the job needs when it does all the work its parameters allow
    /// (every iteration, every step). Over the job time limit, a request is refused (422).
    pub min_seconds: f64,
    /// Triangles the levels of detail start from (the full mesh, and the tiles' meshes when the
    /// request cuts tiles): a request with `lods` adds the levels' time from it.
    #[serde(default)]
    pub lod_triangles: u64,
    /// Bytes a request with `lods` adds at the peak (the levels' working arrays and the levels
    /// kept until written, as the kind's meshes make them).
    #[serde(default)]
    pub lod_bytes: u64,
}

impl Cost {
    /// This cost with a stage that runs after the rest (levels of detail): `bytes` more at the
    /// peak and `seconds` more of least time, named by `field` where it outweighs the rest.
    pub fn with_stage(mut self, field: &str, bytes: u64, seconds: f64) -> Self {
        if bytes > self.memory_bytes {
            self.memory_field = field.to_string();
        }
        if seconds > self.min_seconds {
            self.work_field = field.to_string();
        }
        self.memory_bytes = self.memory_bytes.saturating_add(bytes);
        self.min_seconds += seconds;
        self
    }
}

/// Bytes, for estimates: saturating arithmetic so that no request can overflow one.
pub fn bytes(count: u64, each: u64) -> u64 {
    count.saturating_mul(each)
}

/// What a kind's estimate is made of, term by term, so each term names the field behind it.
#[derive(Debug, Default)]
pub struct CostBuilder {
    memory: u64,
    largest_term: (u64, String),
    work: u64,
    work_field: String,
    lod_triangles: u64,
    lod_bytes: u64,
}

impl CostBuilder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Add `bytes` of memory alive at the peak, driven by `field`.
    pub fn memory(&mut self, field: &str, bytes: u64) -> &mut Self {
        self.memory = self.memory.saturating_add(bytes);
        if bytes > self.largest_term.0 || self.largest_term.1.is_empty() {
            self.largest_term = (bytes, field.to_string());
        }
        self
    }

    /// Set the work and the field that drives it.
    pub fn work(&mut self, field: &str, work: u64) -> &mut Self {
        self.work = work;
        self.work_field = field.to_string();
        self
    }

    /// The triangles of the meshes levels of detail would be made from, and the bytes the
    /// levels add at the peak per triangle (measured per kind: it depends on how the kind's
    /// pieces are simplified and on what else is alive then).
    pub fn lods(&mut self, triangles: u64, bytes_per_triangle: u64) -> &mut Self {
        self.lod_triangles = triangles;
        self.lod_bytes = triangles.saturating_mul(bytes_per_triangle);
        self
    }

    /// Bytes the kind frees before its levels are made (a field dropped once meshed), which the
    /// levels reuse: they add only what is beyond them at the peak.
    pub fn lods_reuse(&mut self, freed_bytes: u64) -> &mut Self {
        self.lod_bytes = self.lod_bytes.saturating_sub(freed_bytes);
        self
    }

    /// Finish with the kind's work unit and its fastest rate (units per second).
    pub fn build(&self, work_unit: &str, work_per_second: f64) -> Cost {
        Cost {
            memory_bytes: self.memory,
            memory_field: self.largest_term.1.clone(),
            work: self.work,
            work_unit: work_unit.to_string(),
            work_field: self.work_field.clone(),
            min_seconds: self.work as f64 / work_per_second.max(f64::MIN_POSITIVE),
            lod_triangles: self.lod_triangles,
            lod_bytes: self.lod_bytes,
        }
    }
}
