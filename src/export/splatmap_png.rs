//! `splatmap.png`: four material weights per grid sample for a terrain shader to blend
//! textures by, as an 8-bit RGBA image laid out as `heightmap.png` (row 0 is grid row 0 at the
//! top). The four weights of a pixel always sum to 255.
//!
//! - **A — the kind's material**: cells the job itself shaped as something other than ground,
//!   where the kind knows them (deform-terrain: the cells of its road constraints); 0 elsewhere.
//! - **G — rock**: by slope, from none at 30° to all at 45° (smoothstep), or the kind's own rock
//!   weight where it knows one and it is larger (erode: bedrock the rivers laid bare), where no
//!   material is.
//! - **B — snow**: by height, from none at 75 % of the terrain's height range to all at 90 %,
//!   on what is neither rock nor material.
//! - **R — ground** (soil, grass): what is left.
//!
//! Slopes come from the same central differences as `normalmap.png`.

use rayon::prelude::*;

use super::heightmap_png::grid_png;
use super::normalmap_png::gradient;
use crate::terrain::Heightfield;

/// Slope (degrees) where rock starts, and where it is all rock.
const ROCK_DEG: (f64, f64) = (30.0, 45.0);
/// Fraction of the height range where snow starts, and where it is all snow.
const SNOW_AT: (f64, f64) = (0.75, 0.90);

fn smoothstep(edges: (f64, f64), x: f64) -> f64 {
    let t = ((x - edges.0) / (edges.1 - edges.0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The RGBA weights of one sample: `material` is the kind's weight (0–1) for channel A, `rock`
/// its rock weight (0–1), combined with the slope's by the larger.
fn weights(slope_deg: f64, height_fraction: f64, material: f64, rock: f64) -> [u8; 4] {
    let a = material.clamp(0.0, 1.0);
    let g = (1.0 - a) * smoothstep(ROCK_DEG, slope_deg).max(rock.clamp(0.0, 1.0));
    let b = (1.0 - a - g) * smoothstep(SNOW_AT, height_fraction);
    let [a, g, b] = [a, g, b].map(|w| (w * 255.0).round() as u16);
    // Rounding can push the three past 255 by at most one each: take it off the largest.
    let r = 255i32 - i32::from(a + g + b);
    let mut px = [r.max(0) as u8, g.min(255) as u8, b.min(255) as u8, a.min(255) as u8];
    if r < 0 {
        let k = (1..4).max_by_key(|&k| px[k]).unwrap_or(1);
        px[k] -= (-r) as u8;
    }
    px
}

/// Encode the splat map; `material` holds the kind's weight per sample (0–255, row-major like
/// the grid), when it has one, and `rock` its rock weight.
///
/// # Panics
/// On an empty grid, or a `material` or `rock` of another length than the grid: bugs in the
/// caller.
pub fn splatmap_png(hf: &Heightfield, material: Option<&[u8]>, rock: Option<&[u8]>) -> Vec<u8> {
    assert!(hf.cols > 0 && hf.rows > 0, "splat map of an empty {}x{} grid", hf.cols, hf.rows);
    for m in material.iter().chain(rock.iter()) {
        assert_eq!(m.len(), hf.heights_m.len(), "one weight per sample");
    }
    let (z_min, z_max) = hf.min_max();
    let span = f64::from(z_max - z_min);
    let cols = hf.cols;
    let mut rgba = vec![0u8; hf.heights_m.len() * 4];
    rgba.par_chunks_mut(cols * 4).enumerate().for_each(|(r, out)| {
        for (c, px) in out.chunks_exact_mut(4).enumerate() {
            let i = r * cols + c;
            let (dx, dz) = gradient(hf, c, r);
            let slope_deg = (dx * dx + dz * dz).sqrt().atan().to_degrees();
            let fraction = if span > 0.0 { f64::from(hf.heights_m[i] - z_min) / span } else { 0.0 };
            let m = material.map_or(0.0, |m| f64::from(m[i]) / 255.0);
            let g = rock.map_or(0.0, |g| f64::from(g[i]) / 255.0);
            px.copy_from_slice(&weights(slope_deg, fraction, m, g));
        }
    });
    let texts = [("Description", "weights: R ground, G rock, B snow, A the kind's material".to_string())];
    grid_png(cols, hf.rows, png::ColorType::Rgba, png::BitDepth::Eight, &texts, &rgba)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixels(png: &[u8]) -> Vec<[u8; 4]> {
        let mut reader = png::Decoder::new(png).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let frame = reader.next_frame(&mut buf).unwrap();
        assert_eq!(frame.color_type, png::ColorType::Rgba);
        buf.truncate(frame.buffer_size());
        buf.chunks_exact(4).map(|p| [p[0], p[1], p[2], p[3]]).collect()
    }

    #[test]
    fn slopes_heights_and_materials_pick_their_channels_and_always_sum_to_255() {
        // 1 in 10 (5.7°): ground up to 75 % of the range (columns 0–3 of 0–5), snow at the top;
        // 2 in 1 (63.4°): rock, however high.
        let ramp = pixels(&splatmap_png(&Heightfield::from_fn(6, 4, 1.0, |x, _| 0.1 * x), None, None));
        assert!((0..4).all(|c| ramp[c] == [255, 0, 0, 0]), "{ramp:?}");
        // Column 4 is at 80 %: smoothstep((0.8 − 0.75) / 0.15) = 0.259 → 66 of snow.
        assert_eq!(ramp[4], [189, 0, 66, 0]);
        assert_eq!(ramp[5], [0, 0, 255, 0]);
        assert!(pixels(&splatmap_png(&Heightfield::from_fn(6, 4, 1.0, |x, _| 2.0 * x), None, None))
            .iter()
            .all(|p| *p == [0, 255, 0, 0]));
        // A flat-topped plateau (tan⁻¹ of its gentle rise ≈ 0.6°) above 90 % of the range is
        // snow; the cliff below it rock; the flat floor ground.
        let hf = Heightfield::from_fn(12, 3, 1.0, |x, _| if x < 6.0 { 0.0 } else { 100.0 + 0.01 * x });
        let px = pixels(&splatmap_png(&hf, None, None));
        assert_eq!(px[0], [255, 0, 0, 0]);
        assert_eq!(px[5], [0, 255, 0, 0], "the cliff's foot: 50 m over 2 m");
        assert_eq!(px[11], [0, 0, 255, 0]);
        // The kind's material wins where it is whole.
        let mut material = vec![0u8; 36];
        material[11] = 255;
        material[0] = 128;
        let px = pixels(&splatmap_png(&hf, Some(&material), None));
        assert_eq!(px[11], [0, 0, 0, 255]);
        assert_eq!(px[0], [127, 0, 0, 128]);
        assert!(px.iter().all(|p| p.iter().map(|&v| u32::from(v)).sum::<u32>() == 255));
    }

    #[test]
    fn weights_sum_to_255_at_every_blend() {
        for slope in (0..=90).step_by(3) {
            for f in 0..=20 {
                for m in [0.0, 0.3, 0.5, 1.0] {
                    for rock in [0.0, 0.4, 1.0] {
                        let w = weights(f64::from(slope), f64::from(f) / 20.0, m, rock);
                        assert_eq!(w.iter().map(|&v| u32::from(v)).sum::<u32>(), 255, "{slope}° {f} {m} {rock}: {w:?}");
                    }
                }
            }
        }
    }
}
