//! What a designer keeps: areas the erosion leaves at the heights they had when it started — a
//! polygon drawn on the terrain, or the cells an earlier job worked (a bulldozer's cut and fill,
//! deform-terrain's roads: the material channel, A, of that job's `splatmap.png`) — each with a
//! shoulder over which the erosion fades back in, so a kept road sits in its own embankment and
//! not on a wall.
//!
//! Rivers still run across a kept area and hillslopes still shed onto it; after every iteration
//! each kept cell is set back towards its starting height by its weight (1 inside, falling
//! linearly to 0 across the shoulder). What that adds or takes away is counted in the mass
//! balance (`held_m3`).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::grid::Grid;
use crate::jobs::SimError;
use crate::terrain::{Heightfield, TerrainLookup};
use crate::validate::Validator;

/// Most areas one request keeps.
pub const MAX_KEEP: usize = 16;
/// Most corners of one kept polygon.
pub const MAX_POLYGON_POINTS: usize = 4096;
/// Widest shoulder, m.
pub const MAX_SHOULDER_M: f64 = 1000.0;
/// A splat map's material weight (of 255) from which a cell counts as worked.
const WORKED_ALPHA: u8 = 128;

/// An area the erosion keeps at its starting heights.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
#[schema(as = ErodeKeep)]
pub enum Keep {
    /// A polygon on the terrain, in metres.
    Polygon(KeepPolygon),
    /// The cells an earlier job worked: its splat map's material channel (A) at half weight or
    /// more — a bulldoze job's cut and fill, a deform-terrain job's roads. The job's terrain must
    /// cover the same extent as this one's (its grid may be finer or coarser: a draft's is).
    WorkedBy(KeepWorked),
}

/// A kept polygon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = ErodeKeepPolygon)]
pub struct KeepPolygon {
    /// Corners, metres on the grid (x east from the first column, z south from the first row),
    /// 3 to 4 096 of them; inside by the even–odd rule.
    pub points_m: Vec<KeepPoint>,
    /// Metres beyond the polygon over which the erosion fades back in (0 to 1 000).
    #[serde(default)]
    #[schema(default = 0.0, minimum = 0.0, maximum = 1000.0)]
    pub shoulder_m: f64,
}

/// Cells an earlier job worked.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = ErodeKeepWorked)]
pub struct KeepWorked {
    /// The earlier job's id (a succeeded bulldoze or deform-terrain job, or any heightfield job
    /// whose splat map marks its own work).
    pub job: String,
    /// Metres beyond the worked cells over which the erosion fades back in (0 to 1 000).
    #[serde(default)]
    #[schema(default = 0.0, minimum = 0.0, maximum = 1000.0)]
    pub shoulder_m: f64,
}

/// A point of a kept polygon, metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = ErodeKeepPoint)]
pub struct KeepPoint {
    /// Metres east of the first column (within ±10 000 000).
    pub x: f64,
    /// Metres south of the first row (within ±10 000 000).
    pub z: f64,
}

impl Keep {
    fn shoulder_m(&self) -> f64 {
        match self {
            Keep::Polygon(p) => p.shoulder_m,
            Keep::WorkedBy(w) => w.shoulder_m,
        }
    }

    /// The earlier job this area reads, if any.
    pub fn job(&self) -> Option<&str> {
        match self {
            Keep::WorkedBy(w) => Some(&w.job),
            Keep::Polygon(_) => None,
        }
    }
}

/// Check every kept area's own fields (under `keep`).
pub fn validate(keep: &[Keep], v: &mut Validator) {
    if keep.len() > MAX_KEEP {
        v.too_large("keep", format!("at most {MAX_KEEP} areas (got {})", keep.len()));
        return;
    }
    v.field("keep", |v| {
        for (i, k) in keep.iter().enumerate() {
            v.index(i, |v| match k {
                Keep::Polygon(p) => v.field("polygon", |v| {
                    let n = p.points_m.len();
                    if n > MAX_POLYGON_POINTS {
                        v.too_large("points_m", format!("at most {MAX_POLYGON_POINTS} points (got {n})"));
                        return;
                    }
                    if n < 3 {
                        v.error("points_m", format!("needs at least 3 points (got {n})"));
                    }
                    v.field("points_m", |v| {
                        for (j, q) in p.points_m.iter().enumerate() {
                            v.index(j, |v| {
                                v.in_range("x", q.x, -1e7, 1e7);
                                v.in_range("z", q.z, -1e7, 1e7);
                            });
                        }
                    });
                    v.in_range("shoulder_m", p.shoulder_m, 0.0, MAX_SHOULDER_M);
                }),
                Keep::WorkedBy(w) => v.field("worked_by", |v| {
                    if uuid::Uuid::parse_str(&w.job).is_err() {
                        v.error("job", "is not a job id");
                    }
                    v.in_range("shoulder_m", w.shoulder_m, 0.0, MAX_SHOULDER_M);
                }),
            });
        }
    });
}

/// The field of area `i`'s job, for errors.
fn job_field(i: usize) -> String {
    format!("keep[{i}].worked_by.job")
}

/// Check, before the job runs, that every earlier job named is there and covers `width_m` ×
/// `depth_m` (within a cell of either grid).
pub fn check_jobs(keep: &[Keep], terrain: &dyn TerrainLookup, width_m: f64, depth_m: f64) -> Result<(), SimError> {
    for (i, k) in keep.iter().enumerate() {
        if let Some(id) = k.job() {
            check_extent(terrain, id, &job_field(i), width_m, depth_m)?;
        }
    }
    Ok(())
}

/// Check that job `id` is there and its terrain covers `width_m` × `depth_m` (within a cell of
/// either grid); errors name `field`. Returns the job's extent.
pub fn check_extent(
    terrain: &dyn TerrainLookup,
    id: &str,
    field: &str,
    width_m: f64,
    depth_m: f64,
) -> Result<crate::terrain::TerrainExtent, SimError> {
    let e = terrain.job_extent(id).map_err(|message| SimError::Invalid { field: field.into(), message })?;
    let (w, d) = ((e.cols.max(1) - 1) as f64 * e.cell_size_m, (e.rows.max(1) - 1) as f64 * e.cell_size_m);
    let slack = e.cell_size_m.max(width_m / 4096.0) * 1.01;
    if (w - width_m).abs() > slack || (d - depth_m).abs() > slack {
        return Err(SimError::Invalid {
            field: field.into(),
            message: format!(
                "job {id}'s terrain is {w} × {d} m; this erosion's is {width_m} × {depth_m} m: a map or kept area \
                 must come from a job on the same extent"
            ),
        });
    }
    Ok(e)
}

/// Each cell's keep weight on `hf`'s grid (0 where nothing is kept), or None when nothing is.
pub fn weights(keep: &[Keep], hf: &Heightfield, terrain: &dyn TerrainLookup) -> Result<Option<Vec<f32>>, SimError> {
    if keep.is_empty() {
        return Ok(None);
    }
    let grid = Grid::new(hf.cols, hf.rows, f64::from(hf.cell_size_m));
    let mut out = vec![0.0f32; grid.cells()];
    for (i, k) in keep.iter().enumerate() {
        let core = match k {
            Keep::Polygon(p) => polygon_cells(&grid, &p.points_m),
            Keep::WorkedBy(w) => worked_cells(&grid, &w.job, terrain, i)?,
        };
        let distance = distance_m(&grid, &core);
        let shoulder = k.shoulder_m();
        for (o, &d) in out.iter_mut().zip(&distance) {
            let w = if d <= 0.0 {
                1.0
            } else if d < shoulder {
                1.0 - d / shoulder
            } else {
                0.0
            };
            *o = o.max(w as f32);
        }
    }
    Ok(Some(out))
}

/// Cells inside the polygon (even–odd), row by row: where the row crosses the edges.
fn polygon_cells(grid: &Grid, points: &[KeepPoint]) -> Vec<bool> {
    let mut inside = vec![false; grid.cells()];
    let mut xs = Vec::new();
    for r in 0..grid.rows {
        let z = r as f64 * grid.cell;
        xs.clear();
        let mut j = points.len() - 1;
        for i in 0..points.len() {
            let (a, b) = (points[i], points[j]);
            if (a.z > z) != (b.z > z) {
                xs.push(a.x + (z - a.z) / (b.z - a.z) * (b.x - a.x));
            }
            j = i;
        }
        xs.sort_by(f64::total_cmp);
        for pair in xs.chunks_exact(2) {
            let from = (pair[0] / grid.cell).ceil().max(0.0) as usize;
            let to = (pair[1] / grid.cell).floor();
            if to < 0.0 {
                continue;
            }
            for c in from..=(to as usize).min(grid.cols - 1) {
                inside[r * grid.cols + c] = true;
            }
        }
    }
    inside
}

/// Cells the job worked: its splat map's material channel, read at each cell's position.
fn worked_cells(grid: &Grid, job: &str, terrain: &dyn TerrainLookup, i: usize) -> Result<Vec<bool>, SimError> {
    let invalid = |message: String| SimError::Invalid { field: job_field(i), message };
    let png = terrain.job_artifact(job, "splatmap.png").map_err(invalid)?;
    let decoder = png::Decoder::new(std::io::Cursor::new(&png));
    let mut reader = decoder.read_info().map_err(|e| invalid(format!("job {job}'s splatmap.png: {e}")))?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let frame = reader.next_frame(&mut buf).map_err(|e| invalid(format!("job {job}'s splatmap.png: {e}")))?;
    if frame.color_type != png::ColorType::Rgba
        || frame.bit_depth != png::BitDepth::Eight
        || frame.width < 2
        || frame.height < 2
    {
        return Err(invalid(format!("job {job}'s splatmap.png is not the 8-bit RGBA splat map of a heightfield")));
    }
    let (w, h) = (frame.width as usize, frame.height as usize);
    let alpha = |c: usize, r: usize| buf[(r * w + c) * 4 + 3];
    // The splat map spans the same extent: sample it at the nearest pixel.
    let scale =
        |n: usize, of: usize, to: usize| ((n as f64 / (of - 1).max(1) as f64) * (to - 1) as f64).round() as usize;
    Ok((0..grid.cells())
        .map(|k| {
            let (c, r) = (k % grid.cols, k / grid.cols);
            alpha(scale(c, grid.cols, w).min(w - 1), scale(r, grid.rows, h).min(h - 1)) >= WORKED_ALPHA
        })
        .collect())
}

/// Metres from each cell to the nearest `core` cell (0 inside; two chamfer passes with 1 and
/// √2 steps, within 8 % of the straight distance).
fn distance_m(grid: &Grid, core: &[bool]) -> Vec<f64> {
    let (cols, rows) = (grid.cols, grid.rows);
    let mut d: Vec<f64> = core.iter().map(|&k| if k { 0.0 } else { f64::INFINITY }).collect();
    let (a, b) = (grid.cell, grid.cell * std::f64::consts::SQRT_2);
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            let mut best = d[i];
            if c > 0 {
                best = best.min(d[i - 1] + a);
            }
            if r > 0 {
                best = best.min(d[i - cols] + a);
                if c > 0 {
                    best = best.min(d[i - cols - 1] + b);
                }
                if c + 1 < cols {
                    best = best.min(d[i - cols + 1] + b);
                }
            }
            d[i] = best;
        }
    }
    for r in (0..rows).rev() {
        for c in (0..cols).rev() {
            let i = r * cols + c;
            let mut best = d[i];
            if c + 1 < cols {
                best = best.min(d[i + 1] + a);
            }
            if r + 1 < rows {
                best = best.min(d[i + cols] + a);
                if c + 1 < cols {
                    best = best.min(d[i + cols + 1] + b);
                }
                if c > 0 {
                    best = best.min(d[i + cols - 1] + b);
                }
            }
            d[i] = best;
        }
    }
    d
}
