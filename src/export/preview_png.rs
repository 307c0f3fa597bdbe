//! The picture a person looks at: hypsometric tint times hillshade, as an 8-bit RGB PNG.
//!
//! Seen from above with north up: image row 0 is grid row 0 (z = 0) and image column 0 is grid
//! column 0 (x = 0), the same layout as `heightmap.png`, so "north" is −Z and "east" is +X.
//! The sun stands at azimuth 315° (north-west), altitude 45°, as in GDAL's `hillshade`. A scale
//! bar sits in the bottom-left corner (see `scale_bar.rs`).

use rayon::prelude::*;

use super::hypsometric::Tint;
use super::scale_bar::draw_scale_bar;
use crate::terrain::Heightfield;

const SUN_AZIMUTH_DEG: f32 = 315.0;
const SUN_ALTITUDE_DEG: f32 = 45.0;
/// Relief reads best when typical slopes at the picture's scale are around this steep; flatter
/// terrain is exaggerated towards it, within [`MAX_EXAGGERATION`].
const TARGET_MEDIAN_SLOPE: f32 = 0.3;
const MAX_EXAGGERATION: f32 = 10.0;
/// Share of brightness kept in full shadow, so slopes facing away from the sun keep their tint.
const AMBIENT: f32 = 0.3;

/// Render the shaded relief at most `max_side_px` pixels on the longer side (area-averaged
/// when the grid is larger; one pixel per sample otherwise), water below `sea_level_m`. Identical whatever the thread
/// count.
///
/// # Panics
/// On an empty grid (no rows or columns), which no terrain source produces.
pub fn preview_png(hf: &Heightfield, max_side_px: u32, sea_level_m: f32) -> Vec<u8> {
    assert!(hf.cols > 0 && hf.rows > 0, "preview of an empty {}x{} grid", hf.cols, hf.rows);
    let (z_min, z_max) = hf.min_max();
    let tint = Tint::with_sea_level(z_min, z_max, sea_level_m);
    let picture = area_average(hf, max_side_px.max(1) as usize);
    let exaggeration = exaggeration_for(&picture);
    let light = sun_direction();
    // Lambert shading of flat ground equals sin(altitude); dividing by it keeps flat ground at
    // its true tint and lets sun-facing slopes brighten.
    let flat = SUN_ALTITUDE_DEG.to_radians().sin();

    let (w, h) = (picture.cols, picture.rows);
    let mut rgb = vec![0u8; w * h * 3];
    rgb.par_chunks_mut(w * 3).enumerate().for_each(|(r, row)| {
        for (c, px) in row.chunks_exact_mut(3).enumerate() {
            let (dx, dz) = picture.gradient(c, r);
            let (dx, dz) = (dx * exaggeration, dz * exaggeration);
            let n_len = (dx * dx + 1.0 + dz * dz).sqrt();
            let lambert = ((-dx * light[0] + light[1] - dz * light[2]) / n_len).max(0.0);
            let lit = (AMBIENT + (1.0 - AMBIENT) * lambert / flat).min(1.25);
            let height = picture.get(c, r);
            // Water is shaded gently: bathymetry shows without looking like land.
            let lit = if tint.is_water(height) { 1.0 + (lit - 1.0) * 0.35 } else { lit };
            let color = tint.srgb(height);
            for k in 0..3 {
                px[k] = (color[k] * lit).round().clamp(0.0, 255.0) as u8;
            }
        }
    });

    // The picture's cell size is the grid's stretched to the picture (see `area_average`).
    draw_scale_bar(&mut rgb, w, h, f64::from(picture.cell_size_m));

    let mut png_bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut png_bytes, w as u32, h as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    encoder.add_text_chunk("Software".to_string(), "Landform".to_string()).expect("valid Latin-1 keyword");
    let mut writer = encoder.write_header().expect("PNG header for a non-empty picture");
    writer.write_image_data(&rgb).expect("PNG encoding into memory");
    writer.finish().expect("PNG encoding into memory");
    png_bytes
}

/// Unit vector towards the sun in world axes (x east, y up, z south).
fn sun_direction() -> [f32; 3] {
    let (az, alt) = (SUN_AZIMUTH_DEG.to_radians(), SUN_ALTITUDE_DEG.to_radians());
    [alt.cos() * az.sin(), alt.sin(), -alt.cos() * az.cos()]
}

/// The heightfield at picture resolution: each pixel the mean of the samples it covers, its
/// cell size stretched to match so slopes keep their true steepness.
fn area_average(hf: &Heightfield, max_side: usize) -> Heightfield {
    let longest = hf.cols.max(hf.rows);
    if longest <= max_side {
        return hf.clone();
    }
    let out_side = |n: usize| ((n * max_side + longest / 2) / longest).clamp(1, n);
    let (w, h) = (out_side(hf.cols), out_side(hf.rows));
    // Pixel k covers samples [k * n / out, (k + 1) * n / out): never empty since out <= n.
    let span = |k: usize, n: usize, out: usize| (k * n / out)..((k + 1) * n / out);
    let mut heights_m = vec![0.0f32; w * h];
    heights_m.par_chunks_mut(w).enumerate().for_each(|(r, out_row)| {
        let rows = span(r, hf.rows, h);
        for (c, out) in out_row.iter_mut().enumerate() {
            let cols = span(c, hf.cols, w);
            let mut sum = 0.0f64;
            for src_r in rows.clone() {
                let start = src_r * hf.cols;
                sum += hf.heights_m[start + cols.start..start + cols.end].iter().map(|&v| v as f64).sum::<f64>();
            }
            *out = (sum / (rows.len() * cols.len()) as f64) as f32;
        }
    });
    // Pixels are square only when the aspect ratio survives rounding; the mean spacing is
    // close enough for shading.
    let stretch = (hf.cols as f32 / w as f32 + hf.rows as f32 / h as f32) / 2.0;
    Heightfield { cols: w, rows: h, cell_size_m: hf.cell_size_m * stretch, heights_m }
}

/// Vertical exaggeration that brings the median slope up to [`TARGET_MEDIAN_SLOPE`]; never
/// below 1 (true relief), at most [`MAX_EXAGGERATION`].
fn exaggeration_for(picture: &Heightfield) -> f32 {
    let mut slopes: Vec<f32> = (0..picture.rows)
        .into_par_iter()
        .flat_map_iter(|r| {
            (0..picture.cols).map(move |c| {
                let (dx, dz) = picture.gradient(c, r);
                (dx * dx + dz * dz).sqrt()
            })
        })
        .collect();
    let mid = slopes.len() / 2;
    let (_, &mut median, _) = slopes.select_nth_unstable_by(mid, f32::total_cmp);
    if median > 0.0 {
        (TARGET_MEDIAN_SLOPE / median).clamp(1.0, MAX_EXAGGERATION)
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::test_png::decode;

    fn hills(cols: usize, rows: usize) -> Heightfield {
        Heightfield::from_fn(cols, rows, 10.0, |x, z| 300.0 * (x * 0.004).sin() * (z * 0.003).cos() + 50.0)
    }

    #[test]
    fn large_grid_is_downsampled_to_the_side_limit_as_rgb8() {
        let (info, rgb) = decode(&preview_png(&hills(1000, 500), 256, 0.0));
        assert_eq!((info.width, info.height), (256, 128));
        assert_eq!((info.color_type, info.bit_depth), (png::ColorType::Rgb, png::BitDepth::Eight));
        assert_eq!(rgb.len(), 256 * 128 * 3);
    }

    #[test]
    fn small_grid_keeps_one_pixel_per_sample() {
        let (info, _) = decode(&preview_png(&hills(40, 30), 1024, 0.0));
        assert_eq!((info.width, info.height), (40, 30));
    }

    #[test]
    fn slopes_facing_the_sun_are_brighter() {
        // A ridge from the north-east corner to the south-west one: its north-west face (top
        // left in the picture) looks at the sun, its south-east face away.
        let hf = Heightfield::from_fn(64, 64, 1.0, |x, z| 20.0 - (x + z - 63.0).abs() * 0.5);
        let (_, rgb) = decode(&preview_png(&hf, 64, 0.0));
        let luma = |c: usize, r: usize| rgb[(r * 64 + c) * 3..][..3].iter().map(|&v| v as u32).sum::<u32>();
        let (sunny, shaded) = (luma(20, 20), luma(43, 43));
        assert!(sunny > shaded + 100, "sunny {sunny} vs shaded {shaded}");
    }

    #[test]
    fn water_is_blue() {
        let hf = Heightfield::from_fn(32, 32, 1.0, |x, _| x - 16.0);
        let (_, rgb) = decode(&preview_png(&hf, 32, 0.0));
        let px = &rgb[(16 * 32 + 2) * 3..][..3];
        assert!(px[2] > px[0] && px[2] > px[1], "water pixel {px:?}");
    }

    #[test]
    fn water_begins_at_the_sea_level_given() {
        // Heights 0–127 m west to east; pixel (25, 20) is at 25 m.
        let hf = Heightfield::from_fn(128, 128, 1.0, |x, _| x);
        let px = |png: &[u8]| decode(png).1[(20 * 128 + 25) * 3..][..3].to_vec();
        let (sea, land) = (px(&preview_png(&hf, 128, 50.0)), px(&preview_png(&hf, 128, 0.0)));
        assert!(sea[2] > sea[0] && sea[2] > sea[1], "below a 50 m sea: {sea:?}");
        assert!(land[1] > land[2], "with the sea at 0 m: {land:?}");
    }

    #[test]
    fn same_bytes_on_one_thread_or_many() {
        let hf = hills(700, 300);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        assert_eq!(preview_png(&hf, 200, 0.0), pool.install(|| preview_png(&hf, 200, 0.0)));
    }
}
