//! sRGB ↔ linear light: glTF base colours and vertex colours are linear, while people (and
//! our tints) pick colours in sRGB.

/// Linear value of an sRGB byte, in [0, 1].
pub(crate) fn srgb_to_linear(c: u8) -> f32 {
    SRGB_TO_LINEAR[c as usize] as f32 / 65535.0
}

/// Linear value of an sRGB byte, rounded to a byte (as glTF's normalised UNSIGNED_BYTE colours).
pub(crate) fn srgb_to_linear_u8(c: u8) -> u8 {
    ((SRGB_TO_LINEAR[c as usize] as u32 * 255 + 32767) / 65535) as u8
}

/// sRGB byte → linear value scaled to 0..=65535 (IEC 61966-2-1), computed at compile time so
/// every platform gets the same bytes.
static SRGB_TO_LINEAR: [u16; 256] = srgb_to_linear_table();

const fn srgb_to_linear_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let c = i as f64 / 255.0;
        let linear = if c <= 0.04045 { c / 12.92 } else { powf_const((c + 0.055) / 1.055, 2.4) };
        table[i] = (linear * 65535.0 + 0.5) as u16;
        i += 1;
    }
    table
}

/// `x^y` for x in (0, 1], y > 0, via exp(y ln x) with series that converge there; accurate to
/// far better than one part in 65535.
const fn powf_const(x: f64, y: f64) -> f64 {
    // ln x = 2 artanh((x - 1) / (x + 1)).
    let t = (x - 1.0) / (x + 1.0);
    let t2 = t * t;
    let mut term = t;
    let mut ln = 0.0;
    let mut k = 1.0;
    while k < 200.0 {
        ln += term / k;
        term *= t2;
        k += 2.0;
    }
    let z = 2.0 * ln * y;
    let mut sum = 1.0;
    let mut term = 1.0;
    let mut n = 1.0;
    while n < 60.0 {
        term *= z / n;
        sum += term;
        n += 1.0;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_follows_iec_61966_2_1() {
        assert_eq!(SRGB_TO_LINEAR[0], 0);
        assert_eq!(SRGB_TO_LINEAR[255], 65535);
        for c in 0..=255u8 {
            let s = c as f64 / 255.0;
            let exact = if s <= 0.04045 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) };
            assert!((srgb_to_linear(c) as f64 - exact).abs() < 1.0 / 65535.0, "sRGB {c}");
        }
        assert_eq!(srgb_to_linear_u8(188), 128);
    }
}
