use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::heightmap_png::decode_base64;
use super::{decode_heightmap_png, generate_fractal, Heightfield};
use crate::validate::{Limits, Validate, Validator};

/// Where a heightfield kind's starting terrain comes from: exactly one of the three.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum TerrainSource {
    /// Seeded fractal (fBm) terrain.
    Fractal(FractalParams),
    /// An uploaded 8- or 16-bit grayscale PNG, black = `z_min`, white = `z_max`.
    Heightmap(HeightmapUpload),
    /// The heightfield an earlier, succeeded job produced (its id, a UUID).
    Job(String),
}

fn default_size() -> u32 {
    257
}
fn default_cell_size() -> f32 {
    1.0
}
fn default_relief() -> f32 {
    120.0
}
fn default_octaves() -> u32 {
    8
}
fn default_roughness() -> f32 {
    0.5
}
fn default_fractal_seed() -> u64 {
    7
}
fn default_z_max() -> f32 {
    100.0
}

/// Fractal Brownian motion terrain: `octaves` layers of gradient noise, each at twice the
/// frequency and `roughness` times the amplitude of the one before.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FractalParams {
    /// Samples along each side (the grid is size × size). size × size must be at most the
    /// server's grid cap (4097 × 4097 samples by default; more is answered with 413).
    #[serde(default = "default_size")]
    // 4097: the default grid cap's side (a server with a larger cap takes more).
    #[schema(default = 257, minimum = 2, maximum = 4097)]
    pub size: u32,
    /// Metres between samples.
    #[serde(default = "default_cell_size")]
    // 10000 = MAX_CELL_SIZE_M
    #[schema(default = 1.0, exclusive_minimum = 0.0, maximum = 10000.0)]
    pub cell_size: f32,
    /// Height range in metres from the lowest to the highest possible point.
    #[serde(default = "default_relief")]
    // 100000 = MAX_RELIEF_M
    #[schema(default = 120.0, minimum = 0.0, maximum = 100000.0)]
    pub relief: f32,
    #[serde(default = "default_octaves")]
    #[schema(default = 8, minimum = 1, maximum = 16)]
    pub octaves: u32,
    /// Amplitude ratio between successive octaves, in (0, 1].
    #[serde(default = "default_roughness")]
    #[schema(default = 0.5, exclusive_minimum = 0.0, maximum = 1.0)]
    pub roughness: f32,
    #[serde(default = "default_fractal_seed")]
    #[schema(default = 7)]
    pub seed: u64,
    /// Shape the terrain into an island: land in the middle, sea (height < 0) at the edges.
    #[serde(default)]
    pub island: bool,
    /// The generator's version. A version, once released, gives the same heights on every
    /// later server (pinned by golden hashes in its tests), so a stored sequence replays
    /// exactly; a new generator is a new number and the old ones keep working. Absent means 1,
    /// always (not "the newest"), so requests and sequences stored without it keep their terrain.
    #[serde(default = "default_generator")]
    #[schema(default = 1, minimum = 1, maximum = 1)]
    pub generator: u32,
}

/// The fractal generator versions this server has.
pub const FRACTAL_GENERATORS: std::ops::RangeInclusive<u32> = 1..=1;

fn default_generator() -> u32 {
    1
}

impl Default for FractalParams {
    fn default() -> Self {
        serde_json::from_str("{}").expect("defaults")
    }
}

/// An uploaded heightmap: the PNG sent inline (`png_base64`), or named by the sha256 of one
/// sent before (`png_sha256`) — exactly one of the two.
///
/// An inline PNG is stored once, by content, when the job is accepted; the job's `request` and
/// recorded sequence then carry its `png_sha256` instead of the file, and later requests can
/// name it the same way without sending it again.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct HeightmapUpload {
    /// The PNG file, base64-encoded (standard alphabet): grayscale, 8 or 16 bits (1, 2 and 4
    /// bits are read too). Its width × height must be at most the server's grid cap (4097 ×
    /// 4097 samples by default; more is answered with 413).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub png_base64: Option<String>,
    /// The sha256 (lowercase hex) of a PNG this server was sent before.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(pattern = "^[0-9a-f]{64}$")]
    pub png_sha256: Option<String>,
    /// Metres between samples.
    #[serde(default = "default_cell_size")]
    // 10000 = MAX_CELL_SIZE_M
    #[schema(default = 1.0, exclusive_minimum = 0.0, maximum = 10000.0)]
    pub cell_size: f32,
    /// Height in metres of a black pixel.
    #[serde(default)]
    // ±1e6 = MAX_HEIGHTMAP_Z_M
    #[schema(default = 0.0, minimum = -1e6, maximum = 1e6)]
    pub z_min: f32,
    /// Height in metres of a white pixel; not below `z_min`.
    #[serde(default = "default_z_max")]
    // ±1e6 = MAX_HEIGHTMAP_Z_M
    #[schema(default = 100.0, minimum = -1e6, maximum = 1e6)]
    pub z_max: f32,
}

/// Why a terrain source could not give a heightfield.
#[derive(Debug, thiserror::Error)]
pub enum TerrainError {
    #[error("{0}")]
    Heightmap(#[from] super::HeightmapDecodeError),
    #[error("uploaded heightmap: {0}")]
    Input(String),
    #[error("terrain job {id}: {reason}")]
    Job { id: String, reason: String },
    #[error("the terrain would have {cells} samples, more than the cap of {cap}")]
    TooLarge { cells: u64, cap: u64 },
}

/// What terrain sources read from the store: earlier jobs' heightfields and uploaded files.
pub trait TerrainLookup: Sync {
    /// The final heightfield of a succeeded job, or why there is none.
    fn job_heightfield(&self, job_id: &str) -> Result<Heightfield, String>;
    /// An uploaded file by its sha256, or why there is none.
    fn input(&self, sha256: &str) -> Result<Vec<u8>, String>;
    /// An artifact of a succeeded job that made a heightfield (its `splatmap.png`, say), or why
    /// there is none. A lookup that holds no jobs has none.
    fn job_artifact(&self, job_id: &str, name: &str) -> Result<Vec<u8>, String> {
        Err(format!("no job with id {job_id} to read {name} from"))
    }
    /// The size of a succeeded job's final heightfield. The store reads it from the job's
    /// result without the heights; this default builds the heightfield.
    fn job_extent(&self, job_id: &str) -> Result<super::TerrainExtent, String> {
        let hf = self.job_heightfield(job_id)?;
        let (lo, hi) = hf.min_max();
        Ok(super::TerrainExtent {
            cols: hf.cols as u64,
            rows: hf.rows as u64,
            cell_size_m: hf.cell_size_m as f64,
            z_span_m: (hi - lo) as f64,
        })
    }
}

/// Build the heightfield a source describes.
pub fn resolve(
    source: &TerrainSource,
    lookup: &dyn TerrainLookup,
    limits: &Limits,
) -> Result<Heightfield, TerrainError> {
    let hf = match source {
        TerrainSource::Fractal(p) => generate_fractal(p),
        TerrainSource::Heightmap(u) => {
            let png = match (&u.png_base64, &u.png_sha256) {
                (Some(text), _) => decode_base64(text)?,
                (None, Some(sha)) => lookup.input(sha).map_err(TerrainError::Input)?,
                (None, None) => return Err(TerrainError::Input("the heightmap names no PNG".into())),
            };
            decode_heightmap_png(u, &png, limits)?
        }
        TerrainSource::Job(id) => {
            lookup.job_heightfield(id).map_err(|reason| TerrainError::Job { id: id.clone(), reason })?
        }
    };
    let cells = hf.cols as u64 * hf.rows as u64;
    if cells > limits.max_grid_cells {
        return Err(TerrainError::TooLarge { cells, cap: limits.max_grid_cells });
    }
    Ok(hf)
}

impl TerrainSource {
    /// The id of the earlier job this source reads.
    pub fn job_ref(&self) -> Option<&str> {
        match self {
            TerrainSource::Job(id) => Some(id),
            _ => None,
        }
    }

    /// The sha256 of an upload this source names without sending it.
    pub fn input_ref(&self) -> Option<&str> {
        match self {
            TerrainSource::Heightmap(HeightmapUpload { png_base64: None, png_sha256: Some(sha), .. }) => Some(sha),
            _ => None,
        }
    }

    /// Take an inline PNG out of the source, leaving its sha256 in its place: returns
    /// `(sha256, png bytes)` for the store. Call after validation.
    pub fn take_upload(&mut self) -> Result<Option<(String, Vec<u8>)>, super::HeightmapDecodeError> {
        let TerrainSource::Heightmap(u) = self else { return Ok(None) };
        let Some(text) = u.png_base64.take() else { return Ok(None) };
        let png = decode_base64(&text)?;
        let sha = hex::encode(<sha2::Sha256 as sha2::Digest>::digest(&png));
        u.png_sha256 = Some(sha.clone());
        Ok(Some((sha, png)))
    }

    /// Extent in samples (cols, rows) when it is known without a store, for cap checks.
    pub fn known_dimensions(&self) -> Option<(u64, u64)> {
        match self {
            TerrainSource::Fractal(p) => Some((p.size as u64, p.size as u64)),
            TerrainSource::Heightmap(u) => {
                u.png_base64.as_deref().and_then(|text| super::heightmap_png::png_dimensions(text).ok())
            }
            TerrainSource::Job(_) => None,
        }
    }

    /// Metres between samples when known without a store.
    pub fn known_cell_size(&self) -> Option<f32> {
        match self {
            TerrainSource::Fractal(p) => Some(p.cell_size),
            TerrainSource::Heightmap(u) => Some(u.cell_size),
            TerrainSource::Job(_) => None,
        }
    }
}

/// Largest `cell_size`, metres: a 4097-sample side then spans 41 km.
const MAX_CELL_SIZE_M: f32 = 10_000.0;
/// Largest fractal `relief`, metres.
const MAX_RELIEF_M: f32 = 100_000.0;
/// Largest magnitude of a heightmap's `z_min` and `z_max`, metres.
const MAX_HEIGHTMAP_Z_M: f32 = 1e6;

/// Refuse a finite value above `max_m`: such inputs pass the finite checks but overflow to
/// non-finite geometry downstream.
fn at_most(v: &mut Validator, leaf: &str, value: f32, max_m: f32) {
    if value.is_finite() && value > max_m {
        v.error(leaf, format!("must be at most {max_m} m (got {value})"));
    }
}

impl Validate for TerrainSource {
    fn validate(&self, v: &mut Validator, limits: &Limits) {
        match self {
            TerrainSource::Fractal(p) => v.field("fractal", |v| {
                if p.size < 2 {
                    v.error("size", "must be at least 2");
                } else if (p.size as u64).pow(2) > limits.max_grid_cells {
                    v.too_large(
                        "size",
                        format!("{0}×{0} samples is more than the cap of {1}", p.size, limits.max_grid_cells),
                    );
                }
                v.positive("cell_size", p.cell_size as f64);
                at_most(v, "cell_size", p.cell_size, MAX_CELL_SIZE_M);
                v.non_negative("relief", p.relief as f64);
                at_most(v, "relief", p.relief, MAX_RELIEF_M);
                if !(1..=16).contains(&p.octaves) {
                    v.error("octaves", "must be between 1 and 16");
                }
                v.in_range("roughness", p.roughness as f64, 0.0, 1.0);
                if p.roughness <= 0.0 {
                    v.error("roughness", "must be greater than 0");
                }
                if !FRACTAL_GENERATORS.contains(&p.generator) {
                    let (lo, hi) = (FRACTAL_GENERATORS.start(), FRACTAL_GENERATORS.end());
                    v.error("generator", format!("this server has fractal generators {lo} to {hi}"));
                }
            }),
            TerrainSource::Heightmap(u) => v.field("heightmap", |v| {
                v.positive("cell_size", u.cell_size as f64);
                at_most(v, "cell_size", u.cell_size, MAX_CELL_SIZE_M);
                let max_z = MAX_HEIGHTMAP_Z_M as f64;
                v.in_range("z_min", u.z_min as f64, -max_z, max_z);
                v.in_range("z_max", u.z_max as f64, -max_z, max_z);
                if u.z_min.is_finite() && u.z_max.is_finite() && u.z_max < u.z_min {
                    v.error("z_max", "must not be below z_min");
                }
                super::image_upload::validate_png_pair(
                    v,
                    u.png_base64.as_deref(),
                    u.png_sha256.as_deref(),
                    limits.max_grid_cells,
                    "samples",
                );
            }),
            TerrainSource::Job(id) => {
                if uuid::Uuid::parse_str(id).is_err() {
                    v.error("job", "is not a job id");
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use base64::Engine;
    use serde_json::json;

    use super::*;

    /// A 2 × 2 8-bit grayscale PNG, base64-encoded.
    fn tiny_png() -> String {
        let mut out = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut out, 2, 2);
            encoder.set_color(png::ColorType::Grayscale);
            encoder.set_depth(png::BitDepth::Eight);
            encoder.write_header().unwrap().write_image_data(&[0, 64, 128, 255]).unwrap();
        }
        base64::engine::general_purpose::STANDARD.encode(out)
    }

    fn errors(source: serde_json::Value) -> Vec<(String, String)> {
        let source: TerrainSource = serde_json::from_value(source).expect("parses");
        let mut v = Validator::new();
        source.validate(&mut v, &Limits::default());
        v.errors.into_iter().map(|e| (e.field, e.message)).collect()
    }

    fn fields(source: serde_json::Value) -> Vec<String> {
        errors(source).into_iter().map(|(field, _)| field).collect()
    }

    #[test]
    fn fractal_sizes_that_would_overflow_the_geometry_are_refused() {
        let fractal =
            |cell_size: f32, relief: f32| json!({"fractal": {"size": 33, "cell_size": cell_size, "relief": relief}});
        assert_eq!(fields(fractal(10_000.0, 100_000.0)), Vec::<String>::new());
        assert_eq!(
            errors(fractal(1e38, 120.0)),
            vec![("fractal.cell_size".to_string(), format!("must be at most 10000 m (got {})", 1e38f32))]
        );
        assert_eq!(fields(fractal(10_001.0, 1e38)), vec!["fractal.cell_size", "fractal.relief"]);
        // Below zero is one error, not two.
        assert_eq!(errors(fractal(-1e38, 1.0)).len(), 1);
    }

    #[test]
    fn heightmap_sizes_that_would_overflow_the_geometry_are_refused() {
        let heightmap = |cell_size: f32, z_min: f32, z_max: f32| json!({"heightmap": {"png_base64": tiny_png(), "cell_size": cell_size, "z_min": z_min, "z_max": z_max}});
        assert_eq!(fields(heightmap(10_000.0, -1e6, 1e6)), Vec::<String>::new());
        assert_eq!(fields(heightmap(2e4, 0.0, 10.0)), vec!["heightmap.cell_size"]);
        assert_eq!(fields(heightmap(1.0, -3e38, 3e38)), vec!["heightmap.z_min", "heightmap.z_max"]);
        assert_eq!(fields(heightmap(1.0, 0.0, 2e6)), vec!["heightmap.z_max"]);
        let (_, message) = &errors(heightmap(1.0, -2e6, 0.0))[0];
        assert!(message.contains("between -1000000 and 1000000"), "{message}");
    }
}
