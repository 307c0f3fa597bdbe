//! A heightfield's exact f32 heights as a NumPy `.npy` file (format version 1.0).
//!
//! This is how one job's terrain feeds the next (`{"job": id}`): the heights round-trip bit
//! for bit, and `numpy.load` reads the file as a `(rows, cols)` float32 array in C order.

use crate::terrain::Heightfield;

const MAGIC: &[u8] = b"\x93NUMPY\x01\x00";
/// Magic, version and the u16 header length come before the header text.
const PREAMBLE_LEN: usize = MAGIC.len() + 2;
/// NumPy pads the header so the data starts on a 64-byte boundary.
const ALIGN: usize = 64;

/// The preamble and header NumPy itself writes for a little-endian f32 array of this shape,
/// byte for byte (`numpy.lib.format._wrap_header`).
fn header(rows: usize, cols: usize) -> Vec<u8> {
    let dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({rows}, {cols}), }}");
    let unpadded = dict.len() + 1; // the closing newline
                                   // NumPy adds a whole block when already aligned, so this is never zero.
    let pad = ALIGN - (PREAMBLE_LEN + unpadded) % ALIGN;
    let header_len = unpadded + pad;
    let mut out = Vec::with_capacity(PREAMBLE_LEN + header_len);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(header_len as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.resize(out.len() + pad, b' ');
    out.push(b'\n');
    out
}

/// The heights as `.npy`: dtype `<f4`, shape `(rows, cols)`, C order (row-major, like
/// [`Heightfield::heights_m`]). The cell size is not stored; the caller records it.
pub fn heightfield_npy(hf: &Heightfield) -> Vec<u8> {
    let mut out = header(hf.rows, hf.cols);
    out.reserve_exact(hf.heights_m.len() * 4);
    for h in &hf.heights_m {
        out.extend_from_slice(&h.to_le_bytes());
    }
    out
}

/// Read what [`heightfield_npy`] wrote. Strict: anything but a version 1.0 header laid out
/// exactly as NumPy writes it for a 2-D `<f4` C-order array, followed by exactly its data, is
/// refused, as are non-finite heights.
pub fn read_heightfield_npy(bytes: &[u8], cell_size_m: f32) -> Result<Heightfield, String> {
    if !(cell_size_m.is_finite() && cell_size_m > 0.0) {
        return Err(format!("cell size {cell_size_m} m is not a positive number"));
    }
    if bytes.len() < PREAMBLE_LEN || &bytes[..MAGIC.len()] != MAGIC {
        return Err("not a NumPy .npy version 1.0 file".into());
    }
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let data_start = PREAMBLE_LEN + header_len;
    let text = bytes
        .get(PREAMBLE_LEN..data_start)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or("truncated or non-text .npy header")?;
    let (rows, cols) = parse_shape(text).ok_or_else(|| format!("unsupported .npy header {:?}", text.trim_end()))?;
    if header(rows, cols) != bytes[..data_start] {
        return Err(format!("unsupported .npy header layout {:?}", text.trim_end()));
    }
    let count = rows.checked_mul(cols).filter(|&n| n > 0).ok_or("empty or oversized .npy shape")?;
    let data = &bytes[data_start..];
    if Some(data.len()) != count.checked_mul(4) {
        return Err(format!("{} data bytes for shape ({rows}, {cols}) of f32", data.len()));
    }
    let heights_m: Vec<f32> = data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    if let Some(i) = heights_m.iter().position(|h| !h.is_finite()) {
        return Err(format!("height at row {}, column {} is not finite", i / cols, i % cols));
    }
    Ok(Heightfield { cols, rows, cell_size_m, heights_m })
}

/// `(rows, cols)` from a header of the one form [`header`] writes; the caller compares the
/// whole header afterwards, so this only needs to find the numbers.
fn parse_shape(text: &str) -> Option<(usize, usize)> {
    let rest = text.strip_prefix("{'descr': '<f4', 'fortran_order': False, 'shape': (")?;
    let (shape, _) = rest.split_once(')')?;
    let (rows, cols) = shape.split_once(", ")?;
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    if !digits(rows) || !digits(cols) {
        return None;
    }
    Some((rows.parse().ok()?, cols.parse().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Heightfield {
        Heightfield::from_fn(7, 3, 0.5, |x, z| x * 1.1e-3 - z * 123.456 + f32::EPSILON)
    }

    #[test]
    fn round_trip_is_bit_exact() {
        let hf = sample();
        let back = read_heightfield_npy(&heightfield_npy(&hf), 0.5).unwrap();
        assert_eq!(back.cols, 7);
        assert_eq!(back.rows, 3);
        let bits = |v: &[f32]| v.iter().map(|h| h.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&back.heights_m), bits(&hf.heights_m));
    }

    #[test]
    fn header_is_what_numpy_writes() {
        let bytes = heightfield_npy(&sample());
        // np.save(f, np.zeros((3, 7), '<f4')) writes this 128-byte preamble.
        let text = "{'descr': '<f4', 'fortran_order': False, 'shape': (3, 7), }";
        let mut expected = b"\x93NUMPY\x01\x00\x76\x00".to_vec();
        expected.extend_from_slice(text.as_bytes());
        expected.resize(127, b' ');
        expected.push(b'\n');
        assert_eq!(&bytes[..128], &expected[..]);
        assert_eq!(bytes.len(), 128 + 21 * 4);
    }

    #[test]
    fn refuses_other_layouts() {
        let good = heightfield_npy(&sample());
        let reject = |bytes: &[u8]| read_heightfield_npy(bytes, 0.5).unwrap_err();

        let mut big_endian = good.clone();
        let at = big_endian.windows(3).position(|w| w == b"<f4").unwrap();
        big_endian[at] = b'>';
        reject(&big_endian);
        let mut fortran = good.clone();
        let at = fortran.windows(5).position(|w| w == b"False").unwrap();
        fortran[at..at + 5].copy_from_slice(b"True ");
        reject(&fortran);
        let mut v2 = good.clone();
        v2[6] = 2;
        reject(&v2);
        reject(&good[..good.len() - 1]);
        let mut longer = good.clone();
        longer.extend_from_slice(&[0; 4]);
        reject(&longer);
        let mut nan = good.clone();
        let end = nan.len();
        nan[end - 4..].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(reject(&nan).contains("not finite"));
        assert!(read_heightfield_npy(&good, 0.0).is_err());
    }
}
