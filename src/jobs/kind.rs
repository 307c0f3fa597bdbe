//! The one trait every job kind implements, and the typed form kinds write against.

use std::sync::atomic::{AtomicBool, Ordering};

use serde::{de::DeserializeOwned, Deserialize, Serialize};
use serde_json::Value;
use utoipa::openapi::{RefOr, Schema};
use utoipa::ToSchema;

pub use crate::export::Artifact;
pub use crate::model::{Cost, Progress};
use crate::terrain::{Heightfield, ImageUpload, TerrainError, TerrainLookup, TerrainSource};
use crate::validate::{FieldError, Limits, Validate, Validator};

/// What a run or a replay produced: kind-specific summary figures, the recorded sequence, and
/// the artifacts (the adapter adds `sequence.json`).
#[derive(Debug)]
pub struct Outcome<S> {
    pub result: Value,
    pub sequence: S,
    pub artifacts: Vec<Artifact>,
}

/// Why a run stopped without a result.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("cancelled")]
    Cancelled,
    #[error("{message}")]
    Invalid { field: String, message: String },
    #[error(transparent)]
    Terrain(#[from] TerrainError),
    #[error("{0}")]
    Failed(String),
}

impl From<crate::stop::Stopped> for SimError {
    fn from(_: crate::stop::Stopped) -> Self {
        SimError::Cancelled
    }
}

/// Receives progress from a running job. Implemented by the engine.
pub trait ProgressSink: Sync {
    fn progress(&self, progress: Progress);
    /// Whether a live snapshot would be taken now (they are rate-limited to about 1/s).
    fn snapshot_due(&self) -> bool;
    /// Publish a live snapshot (PNG bytes) with the progress it belongs to.
    fn snapshot(&self, png: Vec<u8>, progress: Progress);
}

/// A sink that drops progress and never asks for snapshots: for unit tests and benchmarks.
pub struct SilentProgress;

impl ProgressSink for SilentProgress {
    fn progress(&self, _progress: Progress) {}
    fn snapshot_due(&self) -> bool {
        false
    }
    fn snapshot(&self, _png: Vec<u8>, _progress: Progress) {}
}

/// What a simulation may touch while it runs: cancellation, progress, earlier jobs' terrain.
pub struct RunContext<'a> {
    pub cancel: &'a AtomicBool,
    pub sink: &'a dyn ProgressSink,
    pub terrain: &'a dyn TerrainLookup,
    pub limits: &'a Limits,
    /// How glb artifacts are written (the request's `compression` and `lods`).
    pub mesh: crate::export::MeshSettings,
    /// A draft (`POST /v1/drafts/{kind}`): terrain sources are read at a coarser grid (see
    /// [`DRAFT_MAX_SIDE`]), on top of the kind's own [`Simulation::draft`] rule.
    pub draft: bool,
}

/// Most samples along a draft terrain's longer side: a source with more is resampled (bilinear,
/// over the same extent) to this, so a draft of a 257² fractal works on 129² samples.
pub const DRAFT_MAX_SIDE: usize = 129;

impl RunContext<'_> {
    /// Err(Cancelled) once the job was cancelled or ran past its time limit; call between steps.
    pub fn check_cancelled(&self) -> Result<(), SimError> {
        if self.cancel.load(Ordering::Relaxed) {
            Err(SimError::Cancelled)
        } else {
            Ok(())
        }
    }

    /// The job's stop request, for meshing and export to look at between chunks.
    pub fn stop(&self) -> crate::stop::Stop<'_> {
        crate::stop::Stop::new(self.cancel)
    }

    pub fn report(&self, stage: &str, step: u64, steps: u64, message: impl Into<String>) {
        self.sink.progress(progress(stage, step, steps, message.into()));
    }

    /// Report progress and, if one is due, a live snapshot rendered by `render` (PNG bytes; a
    /// render the job's stop request cut short publishes progress alone).
    pub fn report_with_snapshot(
        &self,
        stage: &str,
        step: u64,
        steps: u64,
        message: impl Into<String>,
        render: impl FnOnce() -> Result<Vec<u8>, crate::stop::Stopped>,
    ) {
        let p = progress(stage, step, steps, message.into());
        if self.sink.snapshot_due() {
            match render() {
                Ok(png) => self.sink.snapshot(png, p),
                Err(crate::stop::Stopped) => self.sink.progress(p),
            }
        } else {
            self.sink.progress(p);
        }
    }

    pub fn resolve_terrain(&self, source: &TerrainSource) -> Result<Heightfield, SimError> {
        let terrain = crate::terrain::resolve(source, self.terrain, self.limits)?;
        if !self.draft {
            return Ok(terrain);
        }
        Ok(draft_terrain(terrain))
    }
}

/// A terrain as a draft reads it: at most [`DRAFT_MAX_SIDE`] samples a side (bilinear), over
/// the same extent — the last sample of each row and column on the far edge.
pub fn draft_terrain(terrain: Heightfield) -> Heightfield {
    let longest = terrain.cols.max(terrain.rows);
    if longest <= DRAFT_MAX_SIDE {
        return terrain;
    }
    let (width, depth) = (terrain.width_m(), terrain.depth_m());
    let cell = width.max(depth) / (DRAFT_MAX_SIDE - 1) as f32;
    // Rounded, not floored: a spacing a hair off the exact one must not lose the far edge.
    let cols = ((width / cell).round() as usize + 1).clamp(2, DRAFT_MAX_SIDE);
    let rows = ((depth / cell).round() as usize + 1).clamp(2, DRAFT_MAX_SIDE);
    Heightfield::from_fn(cols, rows, cell, |x, z| terrain.sample(x.min(width), z.min(depth)))
}

fn progress(stage: &str, step: u64, steps: u64, message: String) -> Progress {
    let fraction = if steps == 0 { 0.0 } else { (step as f64 / steps as f64).clamp(0.0, 1.0) };
    Progress { fraction, step, steps, stage: stage.to_string(), message }
}

/// A recorded operation sequence: replayable in full or up to a step.
pub trait Sequence: Serialize + DeserializeOwned + Send + Sync {
    /// Number of steps a replay can stop after.
    fn steps(&self) -> u64;
}

/// A job kind written against typed parameters and a typed sequence. `Kind<S>` turns one into
/// a [`JobKind`]; the registry holds those.
pub trait Simulation: Send + Sync + 'static {
    /// The path segment: `POST /v1/jobs/{KIND}`.
    const KIND: &'static str;
    /// One line for the API docs.
    const SUMMARY: &'static str;
    /// The version of the kind's generator: every sequence it records carries it, and a
    /// sequence recorded by another version is refused on replay (it would not give the same
    /// bytes). Raise it with any change that alters what a recorded sequence replays to.
    /// Sequences recorded before versions were kept count as version 1.
    const GENERATOR_VERSION: u32;
    type Params: Serialize + DeserializeOwned + ToSchema + Validate + Send + Sync;
    type Sequence: Sequence;

    /// The terrain sources in the parameters, each with its JSON path. The adapter reads the
    /// earlier jobs and uploads they name from them, and moves inline uploads into the store.
    /// Kinds without a terrain source (volumes, caves) keep the default: none.
    fn terrain_sources(_params: &mut Self::Params) -> Vec<(String, &mut TerrainSource)> {
        Vec::new()
    }

    /// Other PNGs the parameters carry (e.g. a joint map), each with its JSON path; stored and
    /// referenced like uploaded heightmaps.
    fn image_uploads(_params: &mut Self::Params) -> Vec<(String, &mut ImageUpload)> {
        Vec::new()
    }

    /// The job's cost from its validated parameters: peak memory (an upper bound of the real
    /// peak, at most 3 × it) and work, every derived size included. Terrain sources are sized
    /// through `terrain` (uploads and earlier jobs without reading their heights); `seed` is the
    /// run's, for a kind whose size depends on what it draws (a cave's crowded drip sites).
    fn estimate(params: &Self::Params, seed: u64, terrain: &dyn TerrainLookup) -> Result<Cost, SimError>;

    fn run(params: &Self::Params, seed: u64, ctx: &RunContext) -> Result<Outcome<Self::Sequence>, SimError>;

    /// The kind's draft rule (`POST /v1/drafts/{kind}`): lower what sets the kind's work (a
    /// grid, iterations, samples) so that the draft of its defaults answers in about a second,
    /// keeping the shapes the request asks for. Terrain sources are coarsened by the run
    /// context (`RunContext::draft`). The drafted parameters must still validate.
    fn draft(_params: &mut Self::Params) {}

    /// What [`Simulation::draft`] does, in a sentence for the API document.
    const DRAFT_RULE: &'static str = "the terrain is read at most 129 samples a side";

    /// Rebuild from a recorded sequence without searching or sampling; `until_step` keeps the
    /// first k steps.
    fn replay(
        params: &Self::Params,
        sequence: &Self::Sequence,
        until_step: Option<u64>,
        ctx: &RunContext,
    ) -> Result<Outcome<Self::Sequence>, SimError>;
}

/// A request that passed validation.
#[derive(Debug)]
pub struct Prepared {
    /// The kind's parameters with every default filled in (without `seed` and `label`), inline
    /// uploads replaced by their sha256.
    pub params: Value,
    pub references: References,
}

/// What a request reads besides itself, each with the JSON path it came from.
#[derive(Debug, Default, PartialEq)]
pub struct References {
    /// (field, job id): earlier jobs whose heightfields it starts from.
    pub jobs: Vec<(String, String)>,
    /// (field, sha256): uploads it names without sending.
    pub inputs: Vec<(String, String)>,
    /// (sha256, bytes): uploads it sent inline, to store before the job.
    pub uploads: Vec<(String, Vec<u8>)>,
}

impl References {
    /// Record a PNG at `field` (`….png_sha256` / `….png_base64`): the upload it names, or the
    /// one it sent, taken out of the request.
    fn add_png(
        &mut self,
        field: &str,
        named: Option<String>,
        taken: Result<Option<(String, Vec<u8>)>, crate::terrain::HeightmapDecodeError>,
    ) -> Result<(), RequestError> {
        if let Some(sha) = named {
            self.inputs.push((format!("{field}.png_sha256"), sha));
        }
        let upload = taken.map_err(|e| RequestError::Invalid {
            errors: vec![FieldError { field: format!("{field}.png_base64"), message: e.to_string() }],
            too_large: false,
        })?;
        self.uploads.extend(upload);
        Ok(())
    }
}

/// Why a request body was refused.
#[derive(Debug)]
pub enum RequestError {
    /// Not JSON at all (400).
    Malformed(String),
    /// Wrong shapes or values (422), or sizes over a cap (413).
    Invalid { errors: Vec<FieldError>, too_large: bool },
}

/// A job's final output as the engine stores it.
#[derive(Debug)]
pub struct JobOutput {
    pub result: Value,
    pub artifacts: Vec<Artifact>,
}

/// A request body's schema: its name, the schema, and every schema it refers to by name.
pub type RequestSchema = (String, RefOr<Schema>, Vec<(String, RefOr<Schema>)>);

/// The object-safe face of a job kind, used by the engine, the HTTP layer and the CLI.
pub trait JobKind: Send + Sync {
    fn name(&self) -> &'static str;
    fn summary(&self) -> &'static str;
    /// Parse and validate the kind's parameters (the body without `seed` and `label`).
    fn prepare(&self, params: Value, limits: &Limits) -> Result<Prepared, RequestError>;
    /// The cost of a prepared request (see [`Simulation::estimate`]).
    fn estimate(&self, params: &Value, seed: u64, terrain: &dyn TerrainLookup) -> Result<Cost, SimError>;
    fn run(&self, params: &Value, seed: u64, ctx: &RunContext) -> Result<JobOutput, SimError>;
    /// Prepared parameters with the kind's draft rule applied (still valid under `limits`).
    fn draft(&self, params: &Value, limits: &Limits) -> Result<Value, SimError>;
    /// The kind's draft rule in a sentence.
    fn draft_rule(&self) -> &'static str;
    /// Number of steps in a stored `sequence.json`; `Invalid` when another version of the
    /// kind's generator recorded it.
    fn sequence_steps(&self, sequence_json: &[u8]) -> Result<u64, SimError>;
    fn replay(
        &self,
        params: &Value,
        sequence_json: &[u8],
        until_step: Option<u64>,
        ctx: &RunContext,
    ) -> Result<JobOutput, SimError>;
    /// The request body's schema (name, schema) and every schema it refers to.
    fn request_schema(&self) -> RequestSchema;
}

/// Adapts a [`Simulation`] to [`JobKind`].
pub struct Kind<S>(std::marker::PhantomData<S>);

impl<S> Default for Kind<S> {
    fn default() -> Self {
        Self(std::marker::PhantomData)
    }
}

/// A serde path as the `field` of a problem: `operations[0].pass.blade`, empty for the root.
pub fn path_string(path: &serde_path_to_error::Path) -> String {
    let s = path.to_string();
    if s == "." {
        String::new()
    } else {
        s
    }
}

/// Deserialize with the JSON path of the first bad field.
pub fn parse_params<T: DeserializeOwned>(value: Value) -> Result<T, RequestError> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        // serde_path_to_error's path already ends at an unknown field's own name.
        let field = path_string(e.path());
        let mut message = e.inner().to_string();
        if let Some(near) = did_you_mean(&message) {
            message.push_str(&format!(" — did you mean `{near}`?"));
        }
        RequestError::Invalid { errors: vec![FieldError { field, message }], too_large: false }
    })
}

/// Longest unknown name a suggestion is looked for (field names are far shorter).
const MAX_GUESSED_NAME: usize = 64;

/// For serde's "unknown field `x`, expected one of `a`, `b`" (or "unknown variant"): the expected
/// name nearest to `x`, when one is near (an edit distance of at most a third of its length, and
/// at most 3) — a typo named where it was made.
fn did_you_mean(message: &str) -> Option<String> {
    let rest = message.strip_prefix("unknown field `").or_else(|| message.strip_prefix("unknown variant `"))?;
    let (word, expected) = rest.split_once('`')?;
    let len = word.chars().count();
    // "3" is one edit from "0": too short for a guess to mean anything. And a name longer than
    // any field by more than the distance allowed cannot be near one: the client's key (up to a
    // body's megabytes) is never compared character by character.
    if !(3..=MAX_GUESSED_NAME).contains(&len) {
        return None;
    }
    let names = expected.split('`').skip(1).step_by(2);
    let limit = (len / 3).clamp(1, 3);
    let word = word.to_lowercase();
    names
        .filter(|n| n.chars().count().abs_diff(len) <= limit)
        .map(|n| (edit_distance(&word, &n.to_lowercase()), n))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, _)| *d)
        .map(|(_, n)| n.to_string())
}

/// Levenshtein distance in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut row = vec![i + 1];
        for (j, cb) in b.iter().enumerate() {
            row.push((prev[j + 1] + 1).min(row[j] + 1).min(prev[j] + usize::from(ca != *cb)));
        }
        prev = row;
    }
    prev[b.len()]
}

/// Typed parameters as the job keeps them: written as JSON text and read back, so an `f32` is
/// kept as its shortest text (`0.1`, not the `0.10000000149011612` of its `f64` widening, which
/// `serde_json::to_value` gives), and whole numbers without a fraction (`2`, not `2.0`). A
/// stored request is then about the size of the body it came from (the engine bounds it) and
/// reads back into the same parameters, bit for bit.
///
/// Members that are `null` are left out: every optional parameter of every kind reads a missing
/// member as `None` (`#[serde(default)]`, tested over every example), and a path of 50 000
/// points would otherwise gain `"height":null` at each.
pub fn stored_form<T: Serialize>(typed: &T) -> Result<Value, serde_json::Error> {
    let mut value: Value = serde_json::from_slice(&serde_json::to_vec(typed)?)?;
    compact(&mut value);
    Ok(value)
}

/// Floats with no fraction as integers, where that is exact (|x| < 2^53, and not -0.0: its
/// sign matters to the parameters it is read into; an `f32` or `f64` field reads an integer as
/// the same value); `null` members dropped.
fn compact(value: &mut Value) {
    const EXACT: f64 = 9_007_199_254_740_992.0;
    match value {
        Value::Number(n) if n.is_f64() => {
            let x = n.as_f64().unwrap_or(f64::NAN);
            if x.fract() == 0.0 && x.abs() < EXACT && !(x == 0.0 && x.is_sign_negative()) {
                *value = if x >= 0.0 { Value::from(x as u64) } else { Value::from(x as i64) };
            }
        }
        Value::Array(items) => items.iter_mut().for_each(compact),
        Value::Object(map) => {
            map.retain(|_, v| !v.is_null());
            map.values_mut().for_each(compact);
        }
        _ => {}
    }
}

/// The key of `sequence.json` that names what recorded it: `{"kind": …, "version": …}`.
const GENERATOR_KEY: &str = "generator";

/// `sequence.json`: the kind's sequence with the generator that recorded it.
fn sequence_artifact<S: Simulation>(sequence: &S::Sequence) -> Result<Artifact, SimError> {
    let failed = |e: serde_json::Error| SimError::Failed(e.to_string());
    let mut value = serde_json::to_value(sequence).map_err(failed)?;
    let Value::Object(fields) = &mut value else {
        return Err(SimError::Failed(format!("{} records a sequence that is not an object", S::KIND)));
    };
    let generator = serde_json::json!({"kind": S::KIND, "version": S::GENERATOR_VERSION});
    fields.insert(GENERATOR_KEY.into(), generator);
    let bytes = serde_json::to_vec_pretty(&value).map_err(failed)?;
    Ok(Artifact::new("sequence.json", "application/json", bytes))
}

/// The result gains `sequence_steps`, the steps a replay can stop after, so a client (the
/// playground's timeline) knows the range of `until_step` without reading the sequence.
fn finish<S: Simulation>(outcome: Outcome<S::Sequence>) -> Result<JobOutput, SimError> {
    let mut artifacts = outcome.artifacts;
    artifacts.push(sequence_artifact::<S>(&outcome.sequence)?);
    let mut result = outcome.result;
    if let Value::Object(figures) = &mut result {
        figures.insert("sequence_steps".into(), Value::from(outcome.sequence.steps()));
    }
    Ok(JobOutput { result, artifacts })
}

/// Read from the stored value in place (`&Value` is a deserializer): a clone of a request of
/// megabytes would double what estimating and running it hold.
fn stored_params<T: DeserializeOwned>(params: &Value) -> Result<T, SimError> {
    T::deserialize(params).map_err(|e| SimError::Failed(format!("stored request unreadable: {e}")))
}

/// A stored `sequence.json`, after checking that this server's generator recorded it: one of
/// another version answers `Invalid` on `sequence`, saying which (a replay would not give the
/// recorded bytes).
fn stored_sequence<S: Simulation>(json: &[u8]) -> Result<S::Sequence, SimError> {
    let unreadable = |e: serde_json::Error| SimError::Failed(format!("stored sequence unreadable: {e}"));
    let mut value: Value = serde_json::from_slice(json).map_err(unreadable)?;
    let generator = match &mut value {
        Value::Object(fields) => fields.remove(GENERATOR_KEY),
        _ => None,
    };
    let version = generator.as_ref().map_or(Some(1), |g| g.get("version").and_then(Value::as_u64));
    if version != Some(u64::from(S::GENERATOR_VERSION)) {
        let recorded = version.map_or_else(|| "an unknown version".to_string(), |v| format!("version {v}"));
        return Err(SimError::Invalid {
            field: "sequence".into(),
            message: format!(
                "the sequence was recorded by {} generator {recorded}; this server runs version {} and would not \
                 rebuild the same result from it (run the request again for a new result)",
                S::KIND,
                S::GENERATOR_VERSION
            ),
        });
    }
    S::Sequence::deserialize(value).map_err(unreadable)
}

impl<S: Simulation> JobKind for Kind<S> {
    fn name(&self) -> &'static str {
        S::KIND
    }

    fn summary(&self) -> &'static str {
        S::SUMMARY
    }

    fn prepare(&self, params: Value, limits: &Limits) -> Result<Prepared, RequestError> {
        let mut typed: S::Params = parse_params(params)?;
        let mut v = Validator::new();
        typed.validate(&mut v, limits);
        if !v.is_ok() {
            let too_large = v.only_too_large();
            return Err(RequestError::Invalid { errors: v.errors, too_large });
        }
        let mut references = References::default();
        for (path, source) in S::terrain_sources(&mut typed) {
            if let Some(id) = source.job_ref() {
                references.jobs.push((format!("{path}.job"), id.to_string()));
            }
            let sha = source.input_ref().map(str::to_string);
            references.add_png(&format!("{path}.heightmap"), sha, source.take_upload())?;
        }
        for (path, image) in S::image_uploads(&mut typed) {
            let sha = image.input_ref().map(str::to_string);
            references.add_png(&path, sha, image.take_upload())?;
        }
        let params = stored_form(&typed).map_err(|e| RequestError::Malformed(e.to_string()))?;
        Ok(Prepared { params, references })
    }

    fn estimate(&self, params: &Value, seed: u64, terrain: &dyn TerrainLookup) -> Result<Cost, SimError> {
        S::estimate(&stored_params(params)?, seed, terrain)
    }

    fn run(&self, params: &Value, seed: u64, ctx: &RunContext) -> Result<JobOutput, SimError> {
        finish::<S>(S::run(&stored_params(params)?, seed, ctx)?)
    }

    fn draft(&self, params: &Value, limits: &Limits) -> Result<Value, SimError> {
        let mut typed: S::Params = stored_params(params)?;
        S::draft(&mut typed);
        let mut v = Validator::new();
        typed.validate(&mut v, limits);
        if let Some(e) = v.errors.into_iter().next() {
            // A rule that breaks a bound is the server's fault, not the request's.
            return Err(SimError::Failed(format!("the draft rule of {} broke {}: {}", S::KIND, e.field, e.message)));
        }
        stored_form(&typed).map_err(|e| SimError::Failed(e.to_string()))
    }

    fn draft_rule(&self) -> &'static str {
        S::DRAFT_RULE
    }

    fn sequence_steps(&self, sequence_json: &[u8]) -> Result<u64, SimError> {
        Ok(stored_sequence::<S>(sequence_json)?.steps())
    }

    fn replay(
        &self,
        params: &Value,
        sequence_json: &[u8],
        until_step: Option<u64>,
        ctx: &RunContext,
    ) -> Result<JobOutput, SimError> {
        let sequence = stored_sequence::<S>(sequence_json)?;
        finish::<S>(S::replay(&stored_params(params)?, &sequence, until_step, ctx)?)
    }

    fn request_schema(&self) -> RequestSchema {
        let mut refs = Vec::new();
        <S::Params as ToSchema>::schemas(&mut refs);
        (<S::Params as ToSchema>::name().into_owned(), <S::Params as utoipa::PartialSchema>::schema(), refs)
    }
}

#[cfg(test)]
mod tests {
    use super::{did_you_mean, edit_distance};

    #[test]
    fn a_near_name_is_suggested_and_a_far_one_is_not() {
        let m = "unknown field `stepz`, expected one of `grid`, `steps`, `rate`";
        assert_eq!(did_you_mean(m).as_deref(), Some("steps"));
        let m = "unknown variant `sphre`, expected one of `sphere`, `ellipsoid`, `gumdrop`";
        assert_eq!(did_you_mean(m).as_deref(), Some("sphere"));
        assert_eq!(did_you_mean("unknown field `colour`, expected one of `grid`, `steps`"), None);
        assert_eq!(did_you_mean("invalid type: string, expected u32"), None);
        assert_eq!(did_you_mean("unknown variant `3`, expected one of `0`, `1`, `2`"), None);
        let long = format!("unknown field `{}`, expected one of `steps`", "s".repeat(1 << 20));
        assert_eq!(did_you_mean(&long), None);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
    }

    #[test]
    fn a_draft_terrain_keeps_its_extent_to_the_far_edge() {
        use crate::terrain::Heightfield;
        // 193 samples 1.5 m apart: 288 m. Drafted, 129 samples 2.25 m apart, the last on the
        // far edge, heights those of the plane the terrain is.
        let plane = |x: f32, z: f32| 0.25 * x - 0.1 * z + 3.0;
        for (cols, rows, cell) in [(193, 193, 1.5), (161, 161, 3.0), (200, 120, 1.7), (1025, 513, 0.5)] {
            let t = Heightfield::from_fn(cols, rows, cell, plane);
            let (w, d) = (t.width_m(), t.depth_m());
            let draft = super::draft_terrain(t);
            assert!(draft.cols.max(draft.rows) <= super::DRAFT_MAX_SIDE, "{}x{}", draft.cols, draft.rows);
            assert!((draft.width_m() - w).abs() <= 1e-3 * w, "width {} of {w}", draft.width_m());
            assert!((draft.depth_m() - d).abs() <= 0.5 * draft.cell_size_m, "depth {} of {d}", draft.depth_m());
            let (c, r) = (draft.cols - 1, draft.rows - 1);
            let far = draft.get(c, r);
            let expect = plane((c as f32 * draft.cell_size_m).min(w), (r as f32 * draft.cell_size_m).min(d));
            assert!((far - expect).abs() < 1e-3, "far corner {far} vs {expect}");
        }
    }
}
