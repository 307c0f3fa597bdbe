//! What a cost estimate needs to know of a terrain before it is built: its grid and the span of
//! its heights. Known from the request for fractal terrain, from the PNG header for an upload,
//! and from the earlier job's result for `{"job": id}`.

use super::heightmap_png::{png_dimensions, png_header_dimensions};
use super::{TerrainLookup, TerrainSource};

/// The size of a terrain, without its heights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TerrainExtent {
    pub cols: u64,
    pub rows: u64,
    pub cell_size_m: f64,
    /// Highest minus lowest height the terrain can have, metres.
    pub z_span_m: f64,
}

impl TerrainExtent {
    pub fn cells(&self) -> u64 {
        self.cols.saturating_mul(self.rows)
    }
}

/// How far below 0 an island's sea floor reaches, as a share of the relief (see `fractal.rs`).
const ISLAND_SEA_DEPTH_SHARE: f64 = 0.2;

impl TerrainSource {
    /// The terrain's extent; uploads named by sha256 and earlier jobs are read from `lookup`.
    pub fn extent(&self, lookup: &dyn TerrainLookup) -> Result<TerrainExtent, String> {
        match self {
            TerrainSource::Fractal(p) => {
                let share = if p.island { 1.0 + ISLAND_SEA_DEPTH_SHARE } else { 1.0 };
                Ok(TerrainExtent {
                    cols: p.size as u64,
                    rows: p.size as u64,
                    cell_size_m: p.cell_size as f64,
                    z_span_m: p.relief as f64 * share,
                })
            }
            TerrainSource::Heightmap(u) => {
                let (cols, rows) = match (&u.png_base64, &u.png_sha256) {
                    (Some(text), _) => png_dimensions(text),
                    (None, Some(sha)) => png_header_dimensions(&lookup.input(sha)?),
                    (None, None) => return Err("the heightmap names no PNG".into()),
                }
                .map_err(|e| e.to_string())?;
                Ok(TerrainExtent {
                    cols,
                    rows,
                    cell_size_m: u.cell_size as f64,
                    z_span_m: (u.z_max - u.z_min).abs() as f64,
                })
            }
            TerrainSource::Job(id) => lookup.job_extent(id),
        }
    }
}
