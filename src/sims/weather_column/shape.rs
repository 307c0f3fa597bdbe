//! The rock before weathering: the profile extruded from the ground up to the column's height
//! (paper section 4: "the rock begins as a column with vertical straight sides").

use super::grid::{Grid, NEVER_ROCK, ROCK};
use super::params::{JointSystem, Profile, WeatherColumnParams};
use crate::jobs::SimError;

/// Pixels at or above this grey (of 255) are rock; darker ones are joints (no rock).
const ROCK_GREY: u8 = 128;

/// The horizontal footprint, `x + nx * z`: true where the column has rock.
pub fn footprint(
    params: &WeatherColumnParams,
    grid: &Grid,
    joint_map_png: Option<&[u8]>,
) -> Result<Vec<bool>, SimError> {
    let (nx, nz) = (grid.nx, grid.nz);
    let s = grid.voxel_size_m;
    let (cx, cz) = (nx as f32 * s / 2.0, nz as f32 * s / 2.0);
    // Voxel centre relative to the grid's centre, metres.
    let centre = |x: usize, z: usize| ((x as f32 + 0.5) * s - cx, (z as f32 + 0.5) * s - cz);
    let mut out = vec![false; nx * nz];
    match &params.column.profile {
        Profile::Box(b) => {
            let hw = b.width_m.unwrap_or(nx as f32 * s) / 2.0;
            let hd = b.depth_m.unwrap_or(nz as f32 * s) / 2.0;
            fill(&mut out, nx, |x, z| {
                let (px, pz) = centre(x, z);
                px.abs() < hw && pz.abs() < hd
            });
        }
        Profile::Cylinder(c) => {
            let r = c.radius_m.unwrap_or(nx.min(nz) as f32 * s / 2.0);
            fill(&mut out, nx, |x, z| {
                let (px, pz) = centre(x, z);
                px * px + pz * pz < r * r
            });
        }
        Profile::Polygon(p) => {
            fill(&mut out, nx, |x, z| {
                let (px, pz) = centre(x, z);
                inside_polygon(&p.points_m, px, pz)
            });
        }
        Profile::Joints(j) => {
            let joints = JointLines::new(j, nx as f32 * s, nz as f32 * s);
            fill(&mut out, nx, |x, z| !joints.open((x as f32 + 0.5) * s, (z as f32 + 0.5) * s));
        }
        Profile::JointMap(_) => {
            let png = joint_map_png.ok_or_else(|| SimError::Failed("the joint map was not read".into()))?;
            let map = decode_joint_map(png).map_err(|message| SimError::Invalid {
                field: "column.profile.joint_map.png_sha256".into(),
                message,
            })?;
            fill(&mut out, nx, |x, z| {
                let px = ((x as u64 * 2 + 1) * map.width as u64 / (2 * nx as u64)) as usize;
                let pz = ((z as u64 * 2 + 1) * map.height as u64 / (2 * nz as u64)) as usize;
                map.rock[px + map.width * pz]
            });
        }
    }
    if !out.iter().any(|&r| r) {
        return Err(SimError::Invalid {
            field: "column.profile".into(),
            message: "holds no rock on this grid (the profile covers no voxel centre)".into(),
        });
    }
    Ok(out)
}

/// The joints of a [`JointSystem`] over a footprint `width` × `depth` metres (from its corner).
pub struct JointLines {
    /// Per set (across X, across Z): each joint's regular-plus-jitter place and wander phase.
    sets: [Vec<(f32, f32)>; 2],
    half_width: f32,
    wander: f32,
    /// Wander wavelength per set, metres.
    wavelength: [f32; 2],
    spacing: [f32; 2],
}

impl JointLines {
    pub fn new(j: &JointSystem, width: f32, depth: f32) -> Self {
        let set = |k: u64, spacing: f32, extent: f32| -> Vec<(f32, f32)> {
            // Joints from one spacing before the footprint to one after, so jitter leaves no
            // edge uncut.
            let n = (extent / spacing).ceil() as i64 + 1;
            (-1..=n)
                .map(|i| {
                    let u = unit(j.seed, k, (i + 1) as u64 * 2);
                    let phase = unit(j.seed, k, (i + 1) as u64 * 2 + 1) * std::f32::consts::TAU;
                    ((i as f32 + 0.5) * spacing + (u - 0.5) * j.jitter * spacing, phase)
                })
                .collect()
        };
        Self {
            sets: [set(0, j.spacing_m[0], width), set(1, j.spacing_m[1], depth)],
            half_width: j.width_m / 2.0,
            wander: j.wander_m,
            wavelength: [3.0 * j.spacing_m[0], 3.0 * j.spacing_m[1]],
            spacing: j.spacing_m,
        }
    }

    /// Whether (x, z) lies in an open joint. Jitter (≤ 0.45 spacing), wander (≤ 0.25 spacing)
    /// and half the width (< 0.5 spacing) keep a joint within 1.2 spacings of its regular place,
    /// so only the joints whose regular places are within two spacings are looked at.
    pub fn open(&self, x: f32, z: f32) -> bool {
        let near = |k: usize, along: f32, across: f32| {
            let set = &self.sets[k];
            let spacing = self.spacing[k];
            // Joint i of the set sits regularly at (i − 1 + 0.5) · spacing (the set starts one
            // spacing before the footprint).
            let i = ((across / spacing).floor() as i64 + 1).clamp(0, set.len() as i64 - 1) as usize;
            set[i.saturating_sub(2)..(i + 3).min(set.len())].iter().any(|&(at, phase)| {
                let centre = at + self.wander * (std::f32::consts::TAU * along / self.wavelength[k] + phase).sin();
                (across - centre).abs() < self.half_width
            })
        };
        near(0, z, x) || near(1, x, z)
    }
}

/// A uniform number in [0, 1) from (seed, set, index): splitmix64.
fn unit(seed: u64, set: u64, index: u64) -> f32 {
    let mut z = seed ^ set.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}

fn fill(out: &mut [bool], nx: usize, f: impl Fn(usize, usize) -> bool) {
    for (i, cell) in out.iter_mut().enumerate() {
        *cell = f(i % nx, i / nx);
    }
}

/// Even-odd rule.
fn inside_polygon(points: &[[f32; 2]], x: f32, z: f32) -> bool {
    let mut inside = false;
    let mut j = points.len() - 1;
    for i in 0..points.len() {
        let (a, b) = (points[i], points[j]);
        if (a[1] > z) != (b[1] > z) && x < (b[0] - a[0]) * (z - a[1]) / (b[1] - a[1]) + a[0] {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// The state volume of the initial column: `ROCK` inside, `NEVER_ROCK` elsewhere.
pub fn initial_state(footprint: &[bool], grid: &Grid, column_voxels: usize) -> Vec<u16> {
    let plane = grid.nx * grid.nz;
    let mut state = vec![NEVER_ROCK; grid.len()];
    for y in 0..column_voxels.min(grid.ny) {
        for (cell, &rock) in state[y * plane..(y + 1) * plane].iter_mut().zip(footprint) {
            if rock {
                *cell = ROCK;
            }
        }
    }
    state
}

#[derive(Debug)]
pub struct JointMap {
    pub width: usize,
    pub height: usize,
    pub rock: Vec<bool>,
}

/// Most pixels a joint map may have: its header is read before the pixels are.
const MAX_JOINT_MAP_PIXELS: u64 = 4096 * 4096;

/// Decode a joint map PNG (any colour type; read as grey): rock where the pixel is at least
/// mid-grey. Errors complete "png_base64 …".
pub fn decode_joint_map(png: &[u8]) -> Result<JointMap, String> {
    let reader = image::ImageReader::with_format(std::io::Cursor::new(png), image::ImageFormat::Png);
    let (w, h) = reader.into_dimensions().map_err(|e| format!("is not a PNG image: {e}"))?;
    if w as u64 * h as u64 > MAX_JOINT_MAP_PIXELS {
        return Err(format!("{w}×{h} pixels is more than the cap of {MAX_JOINT_MAP_PIXELS} pixels"));
    }
    let image = image::load_from_memory_with_format(png, image::ImageFormat::Png)
        .map_err(|e| format!("is not a readable PNG image: {e}"))?;
    let grey = image.to_luma8();
    let rock: Vec<bool> = grey.as_raw().iter().map(|&p| p >= ROCK_GREY).collect();
    if !rock.iter().any(|&r| r) {
        return Err("holds no rock: every pixel is darker than mid-grey (black = no rock)".into());
    }
    Ok(JointMap { width: w as usize, height: h as usize, rock })
}

/// Validation-time check of an inline joint map.
pub fn check_joint_map(png: &[u8]) -> Result<(), String> {
    decode_joint_map(png).map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygon_even_odd() {
        let square = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
        assert!(inside_polygon(&square, 0.0, 0.0));
        assert!(!inside_polygon(&square, 1.5, 0.0));
    }

    #[test]
    fn joint_map_of_black_pixels_has_no_rock() {
        let mut png = Vec::new();
        {
            let mut e = png::Encoder::new(&mut png, 2, 2);
            e.set_color(png::ColorType::Grayscale);
            e.write_header().unwrap().write_image_data(&[0, 10, 0, 127]).unwrap();
        }
        assert!(decode_joint_map(&png).unwrap_err().contains("no rock"));
        assert!(decode_joint_map(b"GIF89a").unwrap_err().contains("PNG"));
    }
}
