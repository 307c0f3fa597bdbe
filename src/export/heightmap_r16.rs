//! `heightmap.r16`: raw 16-bit heights as Unity's and Unreal's terrain importers read them —
//! unsigned, little-endian, no header, `cols` samples a row, rows from grid row 0 (z = 0) on.
//!
//! With +X east and +Y up in glTF's right-handed frame, −Z is north, so grid row 0 is the
//! northern edge and the rows run north to south, as those importers expect; columns run west
//! to east. Sample 0 is `z_min` and 65535 is `z_max`, the same steps as `heightmap.png`; the file
//! carries no sizes, so the job's result gives them (`heightmap_r16`: width, height, z_min,
//! z_max and the height range an importer asks for).

use serde_json::{json, Value};

use super::heightmap_png::{decimal, samples_u16};
use crate::terrain::Heightfield;

/// The raw file.
pub fn heightmap_r16(hf: &Heightfield) -> Vec<u8> {
    samples_u16(hf, u16::to_le_bytes)
}

/// What an importer needs besides the file: its size in samples and the heights its 0 and
/// 65535 stand for, in metres (the same decimals as `heightmap.png`'s text chunks).
pub fn r16_summary(hf: &Heightfield) -> Value {
    let (z_min, z_max) = hf.min_max();
    json!({
        "width": hf.cols,
        "height": hf.rows,
        "byte_order": "little-endian",
        "z_min": decimal(z_min).parse::<f64>().unwrap_or(f64::from(z_min)),
        "z_max": decimal(z_max).parse::<f64>().unwrap_or(f64::from(z_max)),
        "height_range_m": decimal(z_max - z_min).parse::<f64>().unwrap_or(f64::from(z_max - z_min)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_little_endian_rows_from_z0_within_one_step() {
        // Heights chosen so the steps are exact: 0 m, 65.535 m, with 1 mm a step.
        let hf =
            Heightfield::from_fn(3, 2, 1.0, |x, z| if x == 2.0 && z == 1.0 { 65.535 } else { x * 0.001 + z * 10.0 });
        let raw = heightmap_r16(&hf);
        assert_eq!(raw.len(), 3 * 2 * 2);
        let samples: Vec<u16> = raw.chunks_exact(2).map(|b| u16::from_le_bytes([b[0], b[1]])).collect();
        // Row 0 (z = 0): 0, 1 mm, 2 mm → 0, 1, 2 steps; row 1: 10 m, 10.001 m, the top.
        assert_eq!(samples, vec![0, 1, 2, 10_000, 10_001, 65_535]);
        let s = r16_summary(&hf);
        assert_eq!((s["width"].as_u64(), s["height"].as_u64()), (Some(3), Some(2)));
        assert_eq!(s["z_min"], 0.0);
        assert!((s["height_range_m"].as_f64().unwrap() - 65.535).abs() < 1e-4, "{s}");
    }
}
