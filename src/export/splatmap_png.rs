//! `splatmap.png`: four material weights per grid sample for a terrain shader to blend
//! textures by, as an 8-bit RGBA image laid out as `heightmap.png` (row 0 is grid row 0 at the
//! top). The four weights of a pixel always sum to 255. Every layer comes from the ground's
//! shape (slope, curvature), the water level or what the job did; none from height alone,
//! which would paint the top of every small mound like a summit.
//!
//! - **A — the kind's material**: what the job itself made of the ground, where the kind knows
//!   it (deform-terrain: its roads; bulldoze: the cells it shaped; erode: the sediment it laid;
//!   carve-coast: the rock the sea cut away); 0 elsewhere.
//! - **G — rock**: by slope, from none at 30° to all at 45° (smoothstep), or the kind's own rock
//!   weight where it knows one and it is larger (erode: bedrock the rivers laid bare), where no
//!   material is.
//! - **B — deposit**: loose material where it collects: in hollows, valley floors and the feet
//!   of slopes, by the ground's concavity (the change of slope across [`CURVATURE_CELLS`]
//!   cells, from none at [`CONCAVE`]`.0` to all at [`CONCAVE`]`.1`), and on the bed under the
//!   water level; on what is neither rock nor material.
//! - **R — ground** (soil, grass): what is left.
//!
//! Slopes come from the same central differences as `normalmap.png`.

use rayon::prelude::*;

use super::heightmap_png::grid_png;
use super::normalmap_png::gradient;
use crate::terrain::Heightfield;

/// Slope (degrees) where rock starts, and where it is all rock.
const ROCK_DEG: (f64, f64) = (30.0, 45.0);
/// Concavity where deposit starts and where it is all deposit: the change of slope across the
/// stencil, summed over both axes (a valley whose sides rise 1 in 10 each way reads 0.2).
pub const CONCAVE: (f64, f64) = (0.04, 0.2);
/// Half the width of the curvature stencil, in cells: wide enough that a single noisy sample
/// is not a hollow.
pub const CURVATURE_CELLS: usize = 2;

fn smoothstep(edges: (f64, f64), x: f64) -> f64 {
    let t = ((x - edges.0) / (edges.1 - edges.0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// How concave the ground is at sample (`c`, `r`): over each axis, the rise to the two samples
/// [`CURVATURE_CELLS`] away (fewer at the border) divided by that distance, which is the
/// change of slope across the stencil, summed over the axes: positive in a hollow, negative on
/// a crest.
pub fn concavity(hf: &Heightfield, c: usize, r: usize) -> f64 {
    let h = |c: usize, r: usize| f64::from(hf.heights_m[r * hf.cols + c]);
    let here = h(c, r);
    let axis = |at: usize, len: usize, get: &dyn Fn(usize) -> f64| -> f64 {
        let reach = CURVATURE_CELLS.min(at).min(len - 1 - at);
        if reach == 0 {
            return 0.0;
        }
        let rise = (get(at - reach) - here) + (get(at + reach) - here);
        rise / (reach as f64 * f64::from(hf.cell_size_m))
    };
    axis(c, hf.cols, &|k| h(k, r)) + axis(r, hf.rows, &|k| h(c, k))
}

/// The RGBA weights of one sample: `deposit` is its deposit weight (0–1) from its concavity
/// and the water, `material` the kind's weight (0–1) for channel A, `rock` its rock weight
/// (0–1), combined with the slope's by the larger.
fn weights(slope_deg: f64, deposit: f64, material: f64, rock: f64) -> [u8; 4] {
    let a = material.clamp(0.0, 1.0);
    let g = (1.0 - a) * smoothstep(ROCK_DEG, slope_deg).max(rock.clamp(0.0, 1.0));
    let b = (1.0 - a - g) * deposit.clamp(0.0, 1.0);
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
/// the grid), when it has one, and `rock` its rock weight; samples below `water_level_m` are
/// the bed of its sea or lake.
///
/// # Panics
/// On an empty grid, or a `material` or `rock` of another length than the grid: bugs in the
/// caller.
pub fn splatmap_png(hf: &Heightfield, material: Option<&[u8]>, rock: Option<&[u8]>, water_level_m: f32) -> Vec<u8> {
    assert!(hf.cols > 0 && hf.rows > 0, "splat map of an empty {}x{} grid", hf.cols, hf.rows);
    for m in material.iter().chain(rock.iter()) {
        assert_eq!(m.len(), hf.heights_m.len(), "one weight per sample");
    }
    let cols = hf.cols;
    let mut rgba = vec![0u8; hf.heights_m.len() * 4];
    rgba.par_chunks_mut(cols * 4).enumerate().for_each(|(r, out)| {
        for (c, px) in out.chunks_exact_mut(4).enumerate() {
            let i = r * cols + c;
            let (dx, dz) = gradient(hf, c, r);
            let slope_deg = (dx * dx + dz * dz).sqrt().atan().to_degrees();
            let under_water = hf.heights_m[i] < water_level_m;
            let deposit = if under_water { 1.0 } else { smoothstep(CONCAVE, concavity(hf, c, r)) };
            let m = material.map_or(0.0, |m| f64::from(m[i]) / 255.0);
            let g = rock.map_or(0.0, |g| f64::from(g[i]) / 255.0);
            px.copy_from_slice(&weights(slope_deg, deposit, m, g));
        }
    });
    let texts = [("Description", "weights: R ground, G rock, B deposit, A the kind's material".to_string())];
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

    /// The sea far below: no sample is under water.
    const DRY: f32 = -1e6;

    #[test]
    fn slopes_and_materials_pick_their_channels_and_height_alone_picks_none() {
        // A plane rising 1 in 10 (5.7°): ground everywhere, top as bottom.
        let ramp = pixels(&splatmap_png(&Heightfield::from_fn(6, 4, 1.0, |x, _| 0.1 * x), None, None, DRY));
        assert!(ramp.iter().all(|p| *p == [255, 0, 0, 0]), "{ramp:?}");
        // 2 in 1 (63.4°): rock.
        assert!(pixels(&splatmap_png(&Heightfield::from_fn(6, 4, 1.0, |x, _| 2.0 * x), None, None, DRY))
            .iter()
            .all(|p| *p == [0, 255, 0, 0]));
        // A plateau 100 m up: its flat top is ground like the floor (no snow by height), the
        // cliff rock; the cliff's foot is a hollow (deposit) where it is not rock.
        let hf = Heightfield::from_fn(16, 5, 1.0, |x, _| if x < 8.0 { 0.0 } else { 100.0 + 0.01 * x });
        let px = pixels(&splatmap_png(&hf, None, None, DRY));
        let at = |c: usize| px[2 * 16 + c];
        assert_eq!(at(0), [255, 0, 0, 0]);
        assert_eq!(at(15), [255, 0, 0, 0], "the plateau's top");
        assert_eq!(at(7)[1], 255, "the cliff's foot: 50 m over 2 m is rock");
        assert_eq!(at(6), [0, 0, 255, 0], "two cells out from the cliff: a hollow, 50 m over 2 m");
        // The kind's material wins where it is whole.
        let mut material = vec![0u8; 80];
        material[2 * 16 + 15] = 255;
        material[2 * 16] = 128;
        let px = pixels(&splatmap_png(&hf, Some(&material), None, DRY));
        assert_eq!(px[2 * 16 + 15], [0, 0, 0, 255]);
        assert_eq!(px[2 * 16], [127, 0, 0, 128]);
        assert!(px.iter().all(|p| p.iter().map(|&v| u32::from(v)).sum::<u32>() == 255));
    }

    #[test]
    fn a_mound_is_ground_on_top_and_deposit_at_its_foot_and_a_lake_bed_is_deposit() {
        // A 6 m mound (Gaussian, 8 m wide) on flat ground, 1 m cells.
        let mound = |x: f32, z: f32| 6.0 * (-((x - 32.0).powi(2) + (z - 32.0).powi(2)) / (2.0 * 8.0 * 8.0)).exp();
        let hf = Heightfield::from_fn(65, 65, 1.0, mound);
        let px = pixels(&splatmap_png(&hf, None, None, DRY));
        let at = |c: usize, r: usize| px[r * 65 + c];
        assert_eq!(at(32, 32), [255, 0, 0, 0], "the top is convex: ground");
        assert_eq!(at(0, 0), [255, 0, 0, 0], "flat ground far away");
        // Past the inflection at one width (8 m) the foot is concave: 14 m out, by hand, the
        // rises to ±2 m along the radius and across it, over 2 m (about 0.043, as
        // 6 e^(−14²/128) (14²/8⁴ − 1/8²) × 2 m gives along less the fall across).
        let radial = |d: f32| mound(32.0 + d, 32.0);
        let along = ((radial(12.0) - radial(14.0)) + (radial(16.0) - radial(14.0))) / 2.0;
        let across = (mound(46.0, 30.0) - radial(14.0)) * 2.0 / 2.0;
        let by_hand = f64::from(along + across);
        assert!((concavity(&hf, 46, 32) - by_hand).abs() < 1e-5, "{} vs {by_hand}", concavity(&hf, 46, 32));
        assert!((0.03..0.06).contains(&by_hand), "{by_hand}");
        assert!(concavity(&hf, 32, 32) < 0.0, "the top is convex");
        // A V-shaped valley, its sides 3 in 10 (16.7°, no rock): its floor changes slope by
        // 0.6 across the stencil, all deposit; its sides are straight, ground.
        let valley =
            pixels(&splatmap_png(&Heightfield::from_fn(33, 5, 1.0, |x, _| 0.3 * (x - 16.0).abs()), None, None, DRY));
        assert_eq!(valley[2 * 33 + 16], [0, 0, 255, 0]);
        assert_eq!(valley[2 * 33 + 8], [255, 0, 0, 0]);
        // Under a lake at 2 m: the flat bed is all deposit, the mound above it unchanged.
        let px = pixels(&splatmap_png(&hf, None, None, 2.0));
        assert_eq!(px[0], [0, 0, 255, 0]);
        assert_eq!(px[32 * 65 + 32], [255, 0, 0, 0]);
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
