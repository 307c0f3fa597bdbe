//! Maps a designer paints over the terrain to vary the erosion from place to place (Gaea's and
//! World Machine's masks, Cordonnier et al. 2016's painted uplift): a grayscale PNG stretched
//! over the terrain's extent, or one channel of an earlier job's `splatmap.png` (the rock a
//! weathering left bare, a bulldozer's cut). Black reads `black`, white reads `white`, linearly
//! between; the map is sampled bilinearly at each cell, so a coarse painting gives smooth rates.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::grid::Grid;
use crate::jobs::SimError;
use crate::terrain::{png_header_dimensions, ImageUpload, TerrainLookup};
use crate::validate::{Limits, Validator};

/// A map over the terrain: exactly one of `png` and `splat_of`, and what black and white mean.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = ErodePaintedMap)]
pub struct PaintedMap {
    /// A grayscale PNG (8 or 16 bits), stretched over the terrain's extent: its first pixel on
    /// the first sample, its last on the last. Its shape must be the terrain's (width − 1 over
    /// height − 1 within a pixel of columns − 1 over rows − 1); its size need not be.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub png: Option<ImageUpload>,
    /// Or one channel of an earlier job's `splatmap.png` (the job's terrain covering the same
    /// extent as this one's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub splat_of: Option<SplatChannel>,
    /// What black (0) stands for.
    pub black: f64,
    /// What white (full) stands for.
    pub white: f64,
}

/// One channel of an earlier job's splat map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = ErodeSplatChannel)]
pub struct SplatChannel {
    /// The earlier job's id (a succeeded job that made a heightfield).
    pub job: String,
    /// The channel: `r`, `g`, `b` or `a`.
    pub channel: Channel,
}

/// A colour channel of an RGBA image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
#[schema(as = ErodeChannel)]
pub enum Channel {
    R,
    G,
    B,
    A,
}

impl PaintedMap {
    /// Check the map's own fields inside the validator's current field; `black` and `white`
    /// must lie in `lo..=hi`.
    pub fn validate(&self, v: &mut Validator, limits: &Limits, lo: f64, hi: f64) {
        match (&self.png, &self.splat_of) {
            (Some(_), Some(_)) => v.error("splat_of", "give png or splat_of, not both"),
            (None, None) => v.error("png", "is missing (or read a channel of an earlier job's splat map: splat_of)"),
            (Some(png), None) => v.field("png", |v| {
                png.validate_in(v, limits);
            }),
            (None, Some(s)) => v.field("splat_of", |v| {
                if uuid::Uuid::parse_str(&s.job).is_err() {
                    v.error("job", "is not a job id");
                }
            }),
        }
        v.in_range("black", self.black, lo, hi);
        v.in_range("white", self.white, lo, hi);
    }

    /// The earlier job this map reads, if any.
    pub fn job(&self) -> Option<&str> {
        self.splat_of.as_ref().map(|s| s.job.as_str())
    }

    /// Check, before the job runs, that the map is there and fits a terrain of `cols × rows`
    /// samples `cell_m` apart; errors name `field` (the map's path). Returns the pixels its
    /// decoding holds, for the cost.
    pub fn check(
        &self,
        field: &str,
        lookup: &dyn TerrainLookup,
        cols: u64,
        rows: u64,
        cell_m: f64,
    ) -> Result<u64, SimError> {
        let invalid = |leaf: &str, message: String| SimError::Invalid { field: format!("{field}.{leaf}"), message };
        if let Some(png) = &self.png {
            let bytes = png.bytes(lookup).map_err(|e| invalid("png", e.to_string()))?;
            let (w, h) = png_header_dimensions(&bytes).map_err(|e| invalid("png", e.to_string()))?;
            // The map's shape against the terrain's: its last pixel within one of the last sample.
            let expected = (h - 1) as f64 * (cols.max(2) - 1) as f64 / (rows.max(2) - 1) as f64;
            if (expected - (w - 1) as f64).abs() > 1.0 {
                return Err(invalid(
                    "png",
                    format!(
                        "is {w} × {h} pixels; the terrain is {cols} × {rows} samples: the map must have the terrain's \
                         shape (about {} × {h} pixels)",
                        expected.round() as u64 + 1
                    ),
                ));
            }
            return Ok(w * h);
        }
        let Some(s) = &self.splat_of else { return Ok(0) };
        let span = |n: u64| (n.max(1) - 1) as f64 * cell_m;
        let e = super::keep::check_extent(lookup, &s.job, &format!("{field}.splat_of.job"), span(cols), span(rows))?;
        Ok(e.cols.saturating_mul(e.rows))
    }

    /// The map's value at every cell of `grid`: `black + (white − black) · v`, v in 0..1.
    pub fn sample(&self, field: &str, grid: &Grid, lookup: &dyn TerrainLookup) -> Result<Vec<f32>, SimError> {
        let (w, h, values): (usize, usize, Vec<f32>) = match (&self.png, &self.splat_of) {
            (Some(png), _) => {
                let invalid = |message: String| SimError::Invalid { field: format!("{field}.png"), message };
                let bytes = png.bytes(lookup).map_err(|e| invalid(e.to_string()))?;
                let image = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
                    .map_err(|e| invalid(format!("is not a readable PNG image: {e}")))?;
                let grey = image.to_luma16();
                let (w, h) = grey.dimensions();
                (w as usize, h as usize, grey.into_raw().into_iter().map(|p| f32::from(p) / 65535.0).collect())
            }
            (None, Some(s)) => {
                let invalid = |message: String| SimError::Invalid { field: format!("{field}.splat_of.job"), message };
                let bytes = lookup.job_artifact(&s.job, "splatmap.png").map_err(invalid)?;
                let image = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
                    .map_err(|e| invalid(format!("job {}'s splatmap.png: {e}", s.job)))?;
                let rgba = image.to_rgba8();
                let (w, h) = rgba.dimensions();
                let k = s.channel as usize;
                (w as usize, h as usize, rgba.into_raw().chunks_exact(4).map(|p| f32::from(p[k]) / 255.0).collect())
            }
            (None, None) => {
                return Err(SimError::Invalid { field: format!("{field}.png"), message: "is missing".into() })
            }
        };
        let (black, white) = (self.black as f32, self.white as f32);
        let at = |x: usize, y: usize| values[y.min(h - 1) * w + x.min(w - 1)];
        let scale = |n: usize, of: usize, to: usize| n as f64 / (of.max(2) - 1) as f64 * (to.max(1) - 1) as f64;
        Ok((0..grid.cells())
            .map(|i| {
                let (x, y) = (scale(i % grid.cols, grid.cols, w), scale(i / grid.cols, grid.rows, h));
                let (x0, y0) = (x.floor() as usize, y.floor() as usize);
                let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
                let top = at(x0, y0) + fx * (at(x0 + 1, y0) - at(x0, y0));
                let bottom = at(x0, y0 + 1) + fx * (at(x0 + 1, y0 + 1) - at(x0, y0 + 1));
                let v = top + fy * (bottom - top);
                black + (white - black) * v
            })
            .collect())
    }
}
