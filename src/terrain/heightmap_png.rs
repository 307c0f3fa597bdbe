//! Uploaded heightmaps: a base64 PNG of grayscale samples, black = `z_min`, white = `z_max`.
//!
//! Accepted: grayscale PNGs of 8 or 16 bits per sample, and also 1, 2 or 4 bits (they are
//! grayscale too, and map the same way: the largest value is white). Colour (RGB, RGBA,
//! indexed) and grayscale with an alpha channel are refused; a grayscale image's `tRNS`
//! transparency is ignored. Interlaced images are fine; of an animated PNG the default image is
//! read.
//!
//! The base64 text uses the standard alphabet; ASCII whitespace, missing `=` padding and a
//! `data:image/png;base64,` prefix are tolerated. Image row 0 becomes heightfield row 0 (z = 0),
//! column 0 column 0 (x = 0).
//!
//! Error messages complete a sentence about the field (`png_base64 is not valid base64: …`):
//! they become `errors[].message` for `terrain.heightmap.png_base64`.

use std::io::Cursor;
use std::ops::ControlFlow;

use base64::engine::general_purpose::{GeneralPurpose, GeneralPurposeConfig};
use base64::engine::DecodePaddingMode;
use base64::Engine as _;
use png::ColorType;
use rayon::prelude::*;

use super::{Heightfield, HeightmapUpload};
use crate::validate::Limits;

/// Why an uploaded heightmap can't be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HeightmapDecodeError {
    #[error("is empty")]
    Empty,
    #[error("is not valid base64: {0}")]
    NotBase64(String),
    #[error("is not a PNG image (it does not start with the PNG signature)")]
    NotPng,
    #[error("is not a readable PNG: {0}")]
    Corrupt(String),
    #[error("must be grayscale (an 8- or 16-bit grayscale PNG); this PNG is {0}")]
    NotGrayscale(&'static str),
    #[error("{width}×{height} pixels is more than the cap of {cap} samples")]
    TooLarge { width: u64, height: u64, cap: u64 },
    #[error("is {width}×{height} pixels; a heightmap needs at least 2×2")]
    TooSmall { width: u64, height: u64 },
}

/// The PNG file signature.
const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1A, b'\n'];
/// Signature (8) + IHDR chunk (4 length + 4 type + 13 data + 4 CRC): all a header read needs.
const HEADER_BYTES: usize = 33;
/// Largest width or height the PNG format allows (2³¹ − 1).
const PNG_MAX_SIDE: u64 = (1 << 31) - 1;
/// Room for the decoder's own buffers beyond one 16-bit frame (ancillary chunks are skipped).
const DECODER_SLACK_BYTES: u64 = 1024 * 1024;

/// Standard alphabet; padding optional; non-zero trailing bits allowed (some encoders leave them).
const BASE64: GeneralPurpose = GeneralPurpose::new(
    &base64::alphabet::STANDARD,
    GeneralPurposeConfig::new()
        .with_decode_padding_mode(DecodePaddingMode::Indifferent)
        .with_decode_allow_trailing_bits(true),
);

/// Decode an uploaded heightmap into a heightfield of `width × height` samples,
/// `u.cell_size` metres apart, heights mapped linearly from `[0, max]` to `[z_min, z_max]`.
///
/// The size is checked against `limits.max_grid_cells` from the PNG header, before the pixel
/// buffer is allocated. `z_min`/`z_max`/`cell_size` are used as given (validation checks them).
pub fn decode_heightmap_png(
    u: &HeightmapUpload,
    bytes: &[u8],
    limits: &Limits,
) -> Result<Heightfield, HeightmapDecodeError> {
    let header = read_header(bytes)?;
    let cells = header.width * header.height;
    if cells > limits.max_grid_cells {
        return Err(HeightmapDecodeError::TooLarge {
            width: header.width,
            height: header.height,
            cap: limits.max_grid_cells,
        });
    }

    let decoder_bytes = limits.max_grid_cells.saturating_mul(2).saturating_add(DECODER_SLACK_BYTES);
    let mut decoder = png::Decoder::new_with_limits(
        Cursor::new(bytes),
        png::Limits { bytes: usize::try_from(decoder_bytes).unwrap_or(usize::MAX) },
    );
    decoder.set_ignore_text_chunk(true);
    decoder.set_ignore_iccp_chunk(true);
    let mut reader = decoder.read_info().map_err(png_error)?;
    let mut buf = vec![0u8; reader.output_buffer_size()];
    let frame = reader.next_frame(&mut buf).map_err(png_error)?;
    let (color, depth) = (frame.color_type, frame.bit_depth);
    if color != ColorType::Grayscale {
        // read_header checked the colour type; this guards against a changed default transform.
        return Err(HeightmapDecodeError::NotGrayscale(describe_colour(color)));
    }

    let (cols, rows) = (frame.width as usize, frame.height as usize);
    let bits = depth as u32;
    let max_value = ((1u32 << bits) - 1) as f64;
    let (z_min, z_max) = (u.z_min as f64, u.z_max as f64);
    let mut heights_m = vec![0.0f32; cols * rows];
    heights_m.par_chunks_mut(cols).zip(buf.par_chunks(frame.line_size)).for_each(|(out, line)| {
        for (c, h) in out.iter_mut().enumerate() {
            let t = sample(line, c, bits) as f64 / max_value;
            // This form gives exactly z_min at 0 and exactly z_max at the largest value.
            *h = (z_min * (1.0 - t) + z_max * t) as f32;
        }
    });
    Ok(Heightfield { cols, rows, cell_size_m: u.cell_size, heights_m })
}

/// (width, height) from the PNG header without decoding the pixels.
///
/// The whole text is checked to be base64 (in small pieces, without keeping the bytes), and
/// the header to be a grayscale PNG's, so a bad upload is refused when it is submitted; a
/// corrupt or truncated pixel stream is found only by [`decode_heightmap_png`].
pub fn png_dimensions(png_base64: &str) -> Result<(u64, u64), HeightmapDecodeError> {
    let mut head = Vec::with_capacity(HEADER_BYTES);
    stream_base64(png_base64, |piece| {
        let take = (HEADER_BYTES - head.len()).min(piece.len());
        head.extend_from_slice(&piece[..take]);
        ControlFlow::Continue(())
    })?;
    let header = read_header(&head)?;
    Ok((header.width, header.height))
}

/// Width and height from a PNG file's header, without decoding its pixels.
pub fn png_header_dimensions(png: &[u8]) -> Result<(u64, u64), HeightmapDecodeError> {
    let header = read_header(png)?;
    Ok((header.width, header.height))
}

struct Header {
    width: u64,
    height: u64,
}

/// Check the signature and IHDR; refuse anything but grayscale and images under 2×2.
fn read_header(bytes: &[u8]) -> Result<Header, HeightmapDecodeError> {
    if bytes.is_empty() {
        return Err(HeightmapDecodeError::Empty);
    }
    let signature_len = bytes.len().min(PNG_SIGNATURE.len());
    if bytes[..signature_len] != PNG_SIGNATURE[..signature_len] || bytes.len() < PNG_SIGNATURE.len() {
        return Err(HeightmapDecodeError::NotPng);
    }
    let head = &bytes[..bytes.len().min(HEADER_BYTES)];
    // The png crate reads IHDR's fields before its CRC; check it so a damaged header is not
    // taken at its word (e.g. for the size cap).
    if head.len() == HEADER_BYTES && &head[12..16] == b"IHDR" {
        let stored = u32::from_be_bytes([head[29], head[30], head[31], head[32]]);
        if crc32(&head[12..29]) != stored {
            return Err(HeightmapDecodeError::Corrupt("its header (IHDR) fails its checksum".to_string()));
        }
    }
    let mut decoder = png::Decoder::new(Cursor::new(head));
    let info = decoder.read_header_info().map_err(png_error)?;
    let (width, height) = (info.width as u64, info.height as u64);
    if width > PNG_MAX_SIDE || height > PNG_MAX_SIDE {
        return Err(HeightmapDecodeError::Corrupt(format!("{width}×{height} pixels is beyond the PNG format's limit")));
    }
    if info.color_type != ColorType::Grayscale {
        return Err(HeightmapDecodeError::NotGrayscale(describe_colour(info.color_type)));
    }
    if width < 2 || height < 2 {
        return Err(HeightmapDecodeError::TooSmall { width, height });
    }
    Ok(Header { width, height })
}

/// CRC-32 as PNG chunks use it (ISO 3309 / ITU-T V.42); only ever run over the 17 bytes of IHDR.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

fn describe_colour(color: ColorType) -> &'static str {
    match color {
        ColorType::Grayscale => "grayscale",
        ColorType::GrayscaleAlpha => "grayscale with an alpha channel",
        ColorType::Rgb => "RGB colour",
        ColorType::Rgba => "RGBA colour",
        ColorType::Indexed => "indexed colour (a palette image)",
    }
}

fn png_error(e: png::DecodingError) -> HeightmapDecodeError {
    use png::DecodingError as D;
    let why = match e {
        D::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "the data ends early (is the file truncated?)".to_string()
        }
        D::IoError(io) => io.to_string(),
        D::Format(f) => f.to_string(),
        D::LimitsExceeded => "it needs more memory to decode than its size allows".to_string(),
        D::Parameter(p) => p.to_string(),
    };
    HeightmapDecodeError::Corrupt(why)
}

/// Sample `c` of a packed row of `bits`-bit samples (big-endian when 16-bit, most significant
/// bits first when below 8).
#[inline]
fn sample(line: &[u8], c: usize, bits: u32) -> u32 {
    match bits {
        16 => u32::from(u16::from_be_bytes([line[2 * c], line[2 * c + 1]])),
        8 => u32::from(line[c]),
        _ => {
            let per_byte = (8 / bits) as usize;
            let byte = line[c / per_byte];
            let shift = 8 - bits * (1 + (c % per_byte) as u32);
            u32::from(byte >> shift) & ((1 << bits) - 1)
        }
    }
}

/// The upload's bytes.
pub(super) fn decode_base64(text: &str) -> Result<Vec<u8>, HeightmapDecodeError> {
    let mut bytes = Vec::with_capacity(text.len() / 4 * 3 + 3);
    stream_base64(text, |piece| {
        bytes.extend_from_slice(piece);
        ControlFlow::Continue(())
    })?;
    Ok(bytes)
}

/// Base64 characters decoded per piece (a multiple of 4).
const PIECE_CHARS: usize = 4096;

/// Decode `text` piece by piece into `sink`, skipping whitespace and a `data:` URL prefix.
fn stream_base64(text: &str, mut sink: impl FnMut(&[u8]) -> ControlFlow<()>) -> Result<(), HeightmapDecodeError> {
    let payload = strip_data_url(text)?;
    let mut chars = [0u8; PIECE_CHARS];
    let mut out = [0u8; PIECE_CHARS / 4 * 3];
    let mut filled = 0;
    // Position (whitespace not counted) of `chars[0]`, for error messages.
    let mut position = 0;
    let mut any = false;
    let decode = |piece: &[u8], position: usize, out: &mut [u8]| {
        BASE64.decode_slice(piece, out).map_err(|e| base64_error(e, position))
    };
    for &b in payload.as_bytes() {
        if b.is_ascii_whitespace() {
            continue;
        }
        any = true;
        if filled == PIECE_CHARS {
            // More follows, so this piece must not end in padding.
            if chars[PIECE_CHARS - 1] == b'=' {
                let at = position + chars.iter().position(|&c| c == b'=').unwrap_or(0);
                return Err(HeightmapDecodeError::NotBase64(format!(
                    "'=' padding at character {at} is not at the end"
                )));
            }
            let n = decode(&chars, position, &mut out)?;
            if sink(&out[..n]).is_break() {
                return Ok(());
            }
            position += filled;
            filled = 0;
        }
        chars[filled] = b;
        filled += 1;
    }
    if !any {
        return Err(HeightmapDecodeError::Empty);
    }
    let n = decode(&chars[..filled], position, &mut out)?;
    let _ = sink(&out[..n]);
    Ok(())
}

/// The base64 part of a `data:[<media type>];base64,<data>` URL, or the text itself.
fn strip_data_url(text: &str) -> Result<&str, HeightmapDecodeError> {
    let trimmed = text.trim_start();
    let is_data_url = trimmed.get(..5).is_some_and(|p| p.eq_ignore_ascii_case("data:"));
    if !is_data_url {
        return Ok(text);
    }
    let (head, data) = trimmed
        .split_once(',')
        .ok_or_else(|| HeightmapDecodeError::NotBase64("a data: URL needs a ',' before the data".to_string()))?;
    if !head.to_ascii_lowercase().ends_with(";base64") {
        return Err(HeightmapDecodeError::NotBase64("a data: URL must be ';base64,'-encoded".to_string()));
    }
    Ok(data)
}

fn base64_error(e: base64::DecodeSliceError, position: usize) -> HeightmapDecodeError {
    use base64::DecodeError as D;
    let why = match e {
        base64::DecodeSliceError::DecodeError(D::InvalidByte(at, byte)) => {
            let hint = if byte == b'-' || byte == b'_' {
                " (this looks like the URL-safe alphabet; use the standard one, with '+' and '/')"
            } else {
                ""
            };
            format!("invalid character {} at position {}{hint}", shown(byte), position + at)
        }
        base64::DecodeSliceError::DecodeError(D::InvalidLastSymbol(at, byte)) => {
            format!("invalid last character {} at position {}", shown(byte), position + at)
        }
        base64::DecodeSliceError::DecodeError(D::InvalidLength(_)) => {
            "its length is impossible for base64 (is it cut short?)".to_string()
        }
        base64::DecodeSliceError::DecodeError(D::InvalidPadding) => "invalid '=' padding".to_string(),
        base64::DecodeSliceError::OutputSliceTooSmall => "a piece decoded to more bytes than expected".to_string(),
    };
    HeightmapDecodeError::NotBase64(why)
}

fn shown(byte: u8) -> String {
    if byte.is_ascii_graphic() {
        format!("'{}'", byte as char)
    } else {
        format!("byte 0x{byte:02x}")
    }
}

#[cfg(test)]
mod tests {
    use png::BitDepth;

    use super::*;

    /// The whole path from an inline upload, as `terrain::resolve` takes it.
    fn decode_heightmap_png(u: &HeightmapUpload, limits: &Limits) -> Result<Heightfield, HeightmapDecodeError> {
        super::decode_heightmap_png(u, &decode_base64(u.png_base64.as_deref().unwrap_or(""))?, limits)
    }

    fn encode_png(width: u32, height: u32, color: ColorType, depth: BitDepth, data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut out, width, height);
            encoder.set_color(color);
            encoder.set_depth(depth);
            let mut writer = encoder.write_header().unwrap();
            writer.write_image_data(data).unwrap();
        }
        out
    }

    fn upload(png: &[u8], z_min: f32, z_max: f32) -> HeightmapUpload {
        HeightmapUpload {
            png_base64: Some(base64::engine::general_purpose::STANDARD.encode(png)),
            png_sha256: None,
            cell_size: 2.5,
            z_min,
            z_max,
        }
    }

    fn limits() -> Limits {
        Limits::default()
    }

    #[test]
    fn an_8_bit_heightmap_maps_black_to_z_min_and_white_to_z_max() {
        // 3 columns × 2 rows; row 0 is the image's top row.
        let png = encode_png(3, 2, ColorType::Grayscale, BitDepth::Eight, &[0, 51, 255, 255, 102, 0]);
        let hf = decode_heightmap_png(&upload(&png, -10.0, 40.0), &limits()).unwrap();
        assert_eq!((hf.cols, hf.rows, hf.cell_size_m), (3, 2, 2.5));
        assert_eq!(hf.heights_m, vec![-10.0, 0.0, 40.0, 40.0, 10.0, -10.0]);
        assert_eq!(png_dimensions(upload(&png, 0.0, 1.0).png_base64.as_deref().unwrap()).unwrap(), (3, 2));
    }

    #[test]
    fn a_16_bit_heightmap_keeps_its_precision() {
        let values: [u16; 4] = [0, 1, 32768, 65535];
        let data: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
        let png = encode_png(2, 2, ColorType::Grayscale, BitDepth::Sixteen, &data);
        let hf = decode_heightmap_png(&upload(&png, 0.0, 65535.0), &limits()).unwrap();
        assert_eq!(hf.heights_m, vec![0.0, 1.0, 32768.0, 65535.0]);
    }

    #[test]
    fn low_bit_depth_grayscale_is_expanded() {
        // 4-bit, 3×2: rows are byte-padded (0x0F, 0x70 | 0xF8, 0x10).
        let png = encode_png(3, 2, ColorType::Grayscale, BitDepth::Four, &[0x0F, 0x70, 0xF8, 0x10]);
        let hf = decode_heightmap_png(&upload(&png, 0.0, 15.0), &limits()).unwrap();
        assert_eq!(hf.heights_m, vec![0.0, 15.0, 7.0, 15.0, 8.0, 1.0]);
        // 1-bit, 9×2: the ninth sample is in a second byte.
        let png = encode_png(9, 2, ColorType::Grayscale, BitDepth::One, &[0b1000_0001, 0b1000_0000, 0, 0]);
        let hf = decode_heightmap_png(&upload(&png, 5.0, 6.0), &limits()).unwrap();
        assert_eq!(&hf.heights_m[..9], &[6.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0, 6.0, 6.0]);
        assert!(hf.heights_m[9..].iter().all(|&h| h == 5.0));
    }

    #[test]
    fn colour_and_alpha_images_are_refused_as_not_grayscale() {
        let cases = [
            (ColorType::Rgb, vec![0u8; 2 * 2 * 3], "RGB"),
            (ColorType::Rgba, vec![0u8; 2 * 2 * 4], "RGBA"),
            (ColorType::GrayscaleAlpha, vec![0u8; 2 * 2 * 2], "alpha"),
        ];
        for (color, data, word) in cases {
            let u = upload(&encode_png(2, 2, color, BitDepth::Eight, &data), 0.0, 1.0);
            let err = decode_heightmap_png(&u, &limits()).unwrap_err();
            assert!(matches!(err, HeightmapDecodeError::NotGrayscale(_)), "{err}");
            assert!(err.to_string().starts_with("must be grayscale") && err.to_string().contains(word), "{err}");
            assert_eq!(png_dimensions(u.png_base64.as_deref().unwrap()).unwrap_err(), err);
        }
        let mut out = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut out, 2, 2);
            encoder.set_color(ColorType::Indexed);
            encoder.set_depth(BitDepth::Eight);
            encoder.set_palette(vec![0, 0, 0, 255, 255, 255]);
            encoder.write_header().unwrap().write_image_data(&[0, 1, 1, 0]).unwrap();
        }
        let err = decode_heightmap_png(&upload(&out, 0.0, 1.0), &limits()).unwrap_err();
        assert_eq!(err, HeightmapDecodeError::NotGrayscale("indexed colour (a palette image)"));
    }

    #[test]
    fn garbage_is_refused_with_a_clear_reason() {
        let err = png_dimensions("this is not base64!").unwrap_err();
        assert!(matches!(&err, HeightmapDecodeError::NotBase64(m) if m.contains("' '") || m.contains("'!'")), "{err}");
        let url_safe = png_dimensions("iVBORw0KGgo-_").unwrap_err();
        assert!(url_safe.to_string().contains("URL-safe"), "{url_safe}");
        assert_eq!(png_dimensions("aGVsbG8gd29ybGQ=").unwrap_err(), HeightmapDecodeError::NotPng);
        assert_eq!(png_dimensions("").unwrap_err(), HeightmapDecodeError::Empty);
        assert_eq!(png_dimensions(" \n\t").unwrap_err(), HeightmapDecodeError::Empty);
        assert!(matches!(png_dimensions("QQ==QUJD").unwrap_err(), HeightmapDecodeError::NotBase64(_)));
        assert!(matches!(png_dimensions("QUJDR").unwrap_err(), HeightmapDecodeError::NotBase64(_)));
        let u = HeightmapUpload {
            png_base64: Some("%%%".into()),
            png_sha256: None,
            cell_size: 1.0,
            z_min: 0.0,
            z_max: 1.0,
        };
        assert!(matches!(decode_heightmap_png(&u, &limits()), Err(HeightmapDecodeError::NotBase64(_))));
    }

    #[test]
    fn a_truncated_png_is_refused_as_corrupt() {
        let data: Vec<u8> = (0..64u32 * 64).map(|i| (i * 7 % 251) as u8).collect();
        let png = encode_png(64, 64, ColorType::Grayscale, BitDepth::Eight, &data);
        let cut = &png[..png.len() / 2];
        let u = upload(cut, 0.0, 1.0);
        // The header alone is intact: dimensions are known, the pixels are not.
        assert_eq!(png_dimensions(u.png_base64.as_deref().unwrap()).unwrap(), (64, 64));
        let err = decode_heightmap_png(&u, &limits()).unwrap_err();
        assert!(matches!(err, HeightmapDecodeError::Corrupt(_)), "{err}");

        let header_only = upload(&png[..20], 0.0, 1.0);
        assert!(matches!(
            png_dimensions(header_only.png_base64.as_deref().unwrap()),
            Err(HeightmapDecodeError::Corrupt(_))
        ));

        let mut flipped = png.clone();
        flipped[20] ^= 0xFF; // the height's top byte: IHDR's CRC no longer matches
        let r = png_dimensions(upload(&flipped, 0.0, 1.0).png_base64.as_deref().unwrap());
        assert!(matches!(r, Err(HeightmapDecodeError::Corrupt(_))), "{r:?}");
    }

    #[test]
    fn an_oversized_png_is_refused_from_its_header() {
        // A header claiming 100 000 × 100 000 pixels and no pixel data at all: refusing it as too
        // large (not as corrupt) shows the size is checked before anything is decoded.
        let mut out = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut out, 100_000, 100_000);
            encoder.set_color(ColorType::Grayscale);
            encoder.set_depth(BitDepth::Sixteen);
            encoder.write_header().unwrap();
        }
        let u = upload(&out, 0.0, 1.0);
        assert_eq!(png_dimensions(u.png_base64.as_deref().unwrap()).unwrap(), (100_000, 100_000));
        let err = decode_heightmap_png(&u, &limits()).unwrap_err();
        assert_eq!(err, HeightmapDecodeError::TooLarge { width: 100_000, height: 100_000, cap: 4097 * 4097 });

        let small_cap = Limits { max_grid_cells: 99, ..limits() };
        let png = encode_png(10, 10, ColorType::Grayscale, BitDepth::Eight, &[0; 100]);
        let err = decode_heightmap_png(&upload(&png, 0.0, 1.0), &small_cap).unwrap_err();
        assert_eq!(err.to_string(), "10×10 pixels is more than the cap of 99 samples");
    }

    #[test]
    fn images_under_two_by_two_are_refused() {
        let png = encode_png(1, 5, ColorType::Grayscale, BitDepth::Eight, &[0; 5]);
        let err = decode_heightmap_png(&upload(&png, 0.0, 1.0), &limits()).unwrap_err();
        assert_eq!(err, HeightmapDecodeError::TooSmall { width: 1, height: 5 });
    }

    #[test]
    fn data_url_prefix_whitespace_and_missing_padding_are_tolerated() {
        let png = encode_png(2, 2, ColorType::Grayscale, BitDepth::Eight, &[0, 85, 170, 255]);
        let plain = base64::engine::general_purpose::STANDARD.encode(&png);
        let wrapped: String = plain
            .trim_end_matches('=')
            .as_bytes()
            .chunks(76)
            .map(|line| std::str::from_utf8(line).unwrap())
            .collect::<Vec<_>>()
            .join("\r\n");
        let text = format!("  DATA:image/png;base64,{wrapped}\n");
        let u = HeightmapUpload { png_base64: Some(text), png_sha256: None, cell_size: 1.0, z_min: 0.0, z_max: 3.0 };
        assert_eq!(png_dimensions(u.png_base64.as_deref().unwrap()).unwrap(), (2, 2));
        assert_eq!(decode_heightmap_png(&u, &limits()).unwrap().heights_m, vec![0.0, 1.0, 2.0, 3.0]);
        let not_base64 = png_dimensions(&format!("data:image/png,{plain}")).unwrap_err();
        assert!(not_base64.to_string().contains(";base64"), "{not_base64}");
    }

    #[test]
    fn long_uploads_decode_across_pieces() {
        // Larger than one base64 piece, with line breaks, so pieces split mid-line.
        let (w, h) = (300u32, 41u32);
        let data: Vec<u8> = (0..w * h).flat_map(|i| (i.wrapping_mul(2654435761) as u16).to_be_bytes()).collect();
        let png = encode_png(w, h, ColorType::Grayscale, BitDepth::Sixteen, &data);
        let mut u = upload(&png, 0.0, 65535.0);
        let text = u.png_base64.take().unwrap();
        assert!(text.len() > 2 * PIECE_CHARS);
        u.png_base64 =
            Some(text.as_bytes().chunks(64).map(|l| std::str::from_utf8(l).unwrap()).collect::<Vec<_>>().join("\n"));
        let hf = decode_heightmap_png(&u, &limits()).unwrap();
        assert_eq!((hf.cols, hf.rows), (300, 41));
        for (i, h) in hf.heights_m.iter().enumerate() {
            assert_eq!(*h, (i as u32).wrapping_mul(2654435761) as u16 as f32);
        }
        assert_eq!(png_dimensions(u.png_base64.as_deref().unwrap()).unwrap(), (300, 41));
    }
}
