//! `normalmap.png`: the terrain's tangent-space normals as an 8-bit RGB image, OpenGL
//! convention (green points up the image), one pixel per grid sample, laid out as
//! `heightmap.png` (row 0 is grid row 0, z = 0, at the top; column 0 is x = 0).
//!
//! Tangent space of a heightfield seen from above: +X (east, right in the image) is the tangent,
//! up the image is −Z (north) and the normal's third axis is +Y. With the gradient from central
//! differences (one-sided on the border), the world normal is (−∂h/∂x, 1, −∂h/∂z) normalised, so
//! the pixel stores (−∂h/∂x, ∂h/∂z, 1) normalised, each component c as round((c + 1) / 2 · 255).
//! A flat terrain is (128, 128, 255). For the DirectX convention flip green (255 − G).

use rayon::prelude::*;

use super::heightmap_png::grid_png;
use crate::terrain::Heightfield;

/// (∂h/∂x, ∂h/∂z) at sample (`c`, `r`): central differences inside, one-sided on the border,
/// over the distance actually spanned; 0 along an axis of a single sample.
pub(super) fn gradient(hf: &Heightfield, c: usize, r: usize) -> (f64, f64) {
    let (cols, rows) = (hf.cols, hf.rows);
    let h = |c: usize, r: usize| f64::from(hf.heights_m[r * cols + c]);
    let span = |lo: usize, hi: usize| (hi - lo) as f64 * f64::from(hf.cell_size_m);
    let (x0, x1) = (c.saturating_sub(1), (c + 1).min(cols - 1));
    let (z0, z1) = (r.saturating_sub(1), (r + 1).min(rows - 1));
    let dx = if x1 == x0 { 0.0 } else { (h(x1, r) - h(x0, r)) / span(x0, x1) };
    let dz = if z1 == z0 { 0.0 } else { (h(c, z1) - h(c, z0)) / span(z0, z1) };
    (dx, dz)
}

/// Encode the normal map (see the module docs).
///
/// # Panics
/// On an empty grid, which no terrain source produces.
pub fn normalmap_png(hf: &Heightfield) -> Vec<u8> {
    assert!(hf.cols > 0 && hf.rows > 0, "normal map of an empty {}x{} grid", hf.cols, hf.rows);
    let (cols, rows) = (hf.cols, hf.rows);
    let mut rgb = vec![0u8; cols * rows * 3];
    rgb.par_chunks_mut(cols * 3).enumerate().for_each(|(r, out)| {
        for (c, px) in out.chunks_exact_mut(3).enumerate() {
            let (dx, dz) = gradient(hf, c, r);
            let n = [-dx, dz, 1.0];
            let len = (n[0] * n[0] + n[1] * n[1] + 1.0).sqrt();
            for (p, v) in px.iter_mut().zip(n) {
                *p = ((v / len + 1.0) * 0.5 * 255.0).round().clamp(0.0, 255.0) as u8;
            }
        }
    });
    let texts = [("Description", "tangent-space normals, OpenGL convention (+Y up the image)".to_string())];
    grid_png(cols, rows, png::ColorType::Rgb, png::BitDepth::Eight, &texts, &rgb)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixels(png: &[u8]) -> (u32, u32, Vec<[u8; 3]>) {
        let mut reader = png::Decoder::new(png).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let frame = reader.next_frame(&mut buf).unwrap();
        assert_eq!((frame.color_type, frame.bit_depth), (png::ColorType::Rgb, png::BitDepth::Eight));
        buf.truncate(frame.buffer_size());
        (frame.width, frame.height, buf.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect())
    }

    #[test]
    fn a_plane_has_the_normal_worked_out_by_hand_everywhere() {
        // h = 0.5 x − 0.25 z: (−0.5, −0.25, 1) / √1.3125 = (−0.4364, −0.2182, 0.8729)
        // → ((c + 1) / 2 · 255) = (71.86, 99.68, 238.79) → (72, 100, 239).
        let hf = Heightfield::from_fn(7, 5, 2.0, |x, z| 0.5 * x - 0.25 * z);
        let (w, h, px) = pixels(&normalmap_png(&hf));
        assert_eq!((w, h), (7, 5));
        assert!(px.iter().all(|&p| p == [72, 100, 239]), "{px:?}");
    }

    #[test]
    fn a_flat_terrain_points_straight_out_and_slopes_face_downhill() {
        let (_, _, flat) = pixels(&normalmap_png(&Heightfield::flat(4, 4, 1.0, 30.0)));
        assert!(flat.iter().all(|&p| p == [128, 128, 255]));
        // Rising to the east: the normal leans west (red below 128). Rising to the south
        // (+z, down the image): it leans north, up the image (green above 128).
        let (_, _, east) = pixels(&normalmap_png(&Heightfield::from_fn(4, 4, 1.0, |x, _| x)));
        assert!(east.iter().all(|p| p[0] < 128 && p[1] == 128));
        let (_, _, south) = pixels(&normalmap_png(&Heightfield::from_fn(4, 4, 1.0, |_, z| z)));
        assert!(south.iter().all(|p| p[0] == 128 && p[1] > 128));
    }
}
