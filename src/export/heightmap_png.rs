//! 16-bit grayscale heightmap PNG, the interchange format game engines import.
//!
//! Sample value 0 is `z_min` and 65535 is `z_max`; both, and the cell size, travel in `tEXt`
//! chunks (`z_min`, `z_max`, `cell_size_m`, metres as decimal text) so the file alone rebuilds
//! the terrain to within one step of `(z_max - z_min) / 65535`. Row 0 of the image is grid row
//! 0 (z = 0), column 0 is grid column 0 (x = 0).

use rayon::prelude::*;

use crate::terrain::Heightfield;

/// Shortest decimal that reads back as the same f32, so the text chunks and the job's JSON
/// summary agree and parse back exactly.
pub(crate) fn decimal(value: f32) -> String {
    format!("{value}")
}

/// The heightfield's samples as 16-bit steps from `z_min` (0) to `z_max` (65535), row after
/// row from grid row 0, each written with `bytes` (the byte order); a flat field is all zeros.
/// `heightmap.png` and `heightmap.r16` share it, so the two agree sample for sample.
pub(crate) fn samples_u16(hf: &Heightfield, bytes: fn(u16) -> [u8; 2]) -> Vec<u8> {
    let (z_min, z_max) = hf.min_max();
    let span = (z_max - z_min) as f64;
    let scale = if span > 0.0 { 65535.0 / span } else { 0.0 };
    let mut samples = vec![0u8; hf.heights_m.len() * 2];
    samples.par_chunks_mut(hf.cols.max(1) * 2).zip(hf.heights_m.par_chunks(hf.cols.max(1))).for_each(|(out, row)| {
        for (pair, &h) in out.chunks_exact_mut(2).zip(row) {
            let v = ((h as f64 - z_min as f64) * scale).round().clamp(0.0, 65535.0) as u16;
            pair.copy_from_slice(&bytes(v));
        }
    });
    samples
}

/// Encode the heightfield as a 16-bit grayscale PNG (see the module docs for the mapping). A
/// flat field is all zeros.
///
/// # Panics
/// On an empty grid (no rows or columns), which no terrain source produces.
pub fn heightmap_png16(hf: &Heightfield) -> Vec<u8> {
    assert!(hf.cols > 0 && hf.rows > 0, "heightmap of an empty {}x{} grid", hf.cols, hf.rows);
    let (z_min, z_max) = hf.min_max();
    // PNG stores 16-bit samples big-endian.
    let samples = samples_u16(hf, u16::to_be_bytes);

    let texts = [
        ("z_min", decimal(z_min)),
        ("z_max", decimal(z_max)),
        ("cell_size_m", decimal(hf.cell_size_m)),
        ("Software", "Landform".to_string()),
    ];
    grid_png(hf.cols, hf.rows, png::ColorType::Grayscale, png::BitDepth::Sixteen, &texts, &samples)
}

/// A map of one non-negative value per grid sample (row-major like the grid) as a 16-bit
/// grayscale PNG laid out as `heightmap.png`: 0 is black, `max` (the largest value, in the
/// `max` text chunk with its `unit`) white, linear between. An all-zero map is black.
///
/// # Panics
/// On an empty grid or `values` of another length: bugs in the caller.
pub fn scalar_png16(cols: usize, rows: usize, values: &[f32], unit: &str, description: &str) -> Vec<u8> {
    assert!(cols > 0 && rows > 0 && values.len() == cols * rows, "a map of {} values for {cols}x{rows}", values.len());
    let max = values.iter().copied().filter(|v| v.is_finite()).fold(0.0f32, f32::max);
    let scale = if max > 0.0 { 65535.0 / f64::from(max) } else { 0.0 };
    let samples: Vec<u8> = values
        .iter()
        .flat_map(|&v| ((f64::from(v.max(0.0)) * scale).round().min(65535.0) as u16).to_be_bytes())
        .collect();
    let texts = [
        ("max", decimal(max)),
        ("unit", unit.to_string()),
        ("Description", description.to_string()),
        ("Software", "Landform".to_string()),
    ];
    grid_png(cols, rows, png::ColorType::Grayscale, png::BitDepth::Sixteen, &texts, &samples)
}

/// A PNG of one pixel per grid sample: `data` row by row, the `texts` as tEXt chunks. The
/// Paeth filter, since neighbouring samples of a terrain are alike, and fast deflate.
pub(crate) fn grid_png(
    cols: usize,
    rows: usize,
    color: png::ColorType,
    depth: png::BitDepth,
    texts: &[(&str, String)],
    data: &[u8],
) -> Vec<u8> {
    let mut png_bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut png_bytes, cols as u32, rows as u32);
    encoder.set_color(color);
    encoder.set_depth(depth);
    encoder.set_filter(png::FilterType::Paeth);
    encoder.set_compression(png::Compression::Fast);
    for (key, text) in texts {
        encoder.add_text_chunk(key.to_string(), text.clone()).expect("tEXt keywords are valid Latin-1");
    }
    let mut writer = encoder.write_header().expect("PNG header for a non-empty grid");
    writer.write_image_data(data).expect("PNG encoding into memory");
    writer.finish().expect("PNG encoding into memory");
    png_bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Decoded {
        info_bits: png::BitDepth,
        color: png::ColorType,
        width: u32,
        height: u32,
        samples: Vec<u16>,
        text: Vec<(String, String)>,
    }

    fn decode(bytes: &[u8]) -> Decoded {
        let mut reader = png::Decoder::new(bytes).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let frame = reader.next_frame(&mut buf).unwrap();
        buf.truncate(frame.buffer_size());
        let info = reader.info();
        Decoded {
            info_bits: info.bit_depth,
            color: info.color_type,
            width: info.width,
            height: info.height,
            samples: buf.chunks_exact(2).map(|b| u16::from_be_bytes([b[0], b[1]])).collect(),
            text: info.uncompressed_latin1_text.iter().map(|t| (t.keyword.clone(), t.text.clone())).collect(),
        }
    }

    fn text<'a>(d: &'a Decoded, key: &str) -> &'a str {
        &d.text.iter().find(|(k, _)| k == key).unwrap_or_else(|| panic!("no {key} text chunk")).1
    }

    #[test]
    fn round_trip_within_one_step() {
        let hf = Heightfield::from_fn(33, 17, 1.5, |x, z| (x * 0.21).sin() * 40.0 - z * 0.7 + 3.25);
        let d = decode(&heightmap_png16(&hf));
        assert_eq!((d.info_bits, d.color), (png::BitDepth::Sixteen, png::ColorType::Grayscale));
        assert_eq!((d.width, d.height), (33, 17));

        let z_min: f32 = text(&d, "z_min").parse().unwrap();
        let z_max: f32 = text(&d, "z_max").parse().unwrap();
        assert_eq!((z_min, z_max), hf.min_max());
        assert_eq!(text(&d, "cell_size_m"), "1.5");
        assert_eq!(text(&d, "Software"), "Landform");

        let step = (z_max - z_min) / 65535.0;
        assert!(d.samples.contains(&0) && d.samples.contains(&65535));
        for (&v, &h) in d.samples.iter().zip(&hf.heights_m) {
            let back = z_min + v as f32 * step;
            assert!((back - h).abs() <= step, "{h} came back as {back}");
        }
    }

    #[test]
    fn flat_field_is_all_zero() {
        let d = decode(&heightmap_png16(&Heightfield::flat(4, 3, 1.0, 12.5)));
        assert!(d.samples.iter().all(|&v| v == 0));
        assert_eq!(text(&d, "z_min"), "12.5");
        assert_eq!(text(&d, "z_max"), "12.5");
    }

    #[test]
    fn bytes_are_deterministic() {
        let hf = Heightfield::from_fn(300, 200, 1.0, |x, z| (x * z).sqrt());
        assert_eq!(heightmap_png16(&hf), heightmap_png16(&hf));
    }
}
