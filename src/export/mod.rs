//! File writers every kind uses: glb meshes, 16-bit heightmaps, preview pictures, and the
//! exact `.npy` heights that let one job's terrain feed the next.

mod artifact;
mod glb;
mod heightmap_png;
mod hypsometric;
mod npy;
mod preview_png;
mod render;
mod srgb;

#[cfg(test)]
pub(crate) mod test_png {
    /// Decode a PNG for a test: its header and pixel bytes.
    pub fn decode(bytes: &[u8]) -> (png::OutputInfo, Vec<u8>) {
        let mut reader = png::Decoder::new(bytes).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        (info, buf)
    }
}

pub use artifact::Artifact;
pub use glb::{write_glb, MAX_U16_INDEXED_VERTICES};
pub use heightmap_png::heightmap_png16;
pub use hypsometric::Tint;
pub use npy::{heightfield_npy, read_heightfield_npy};
pub use preview_png::preview_png;
pub use render::{render_png, View};

use serde_json::{json, Value};

use crate::mesh::{heightfield_mesh, Scene, DEFAULT_MAX_SIDE_SAMPLES};
use crate::terrain::Heightfield;

/// Longest side of `preview.png`.
pub const PREVIEW_MAX_SIDE_PX: u32 = 1024;
/// Longest side of a live snapshot: small enough to send about once a second.
pub const SNAPSHOT_MAX_SIDE_PX: u32 = 256;

/// The standard outputs of a heightfield kind and the figures for its job `result`.
#[derive(Debug)]
pub struct HeightfieldArtifacts {
    /// `heightmap.png`, `preview.png`, `mesh.glb`, `heightfield.npy`, in that order.
    pub artifacts: Vec<Artifact>,
    /// `{"z_min", "z_max", "grid": {"cols", "rows", "cell_size_m"}, "mesh": {"vertices",
    /// "triangles", "stride"}}`, metres; z_min/z_max are the same decimals as the PNG's text.
    pub summary: Value,
}

/// Everything a heightfield kind delivers for its final terrain, built in parallel; the bytes
/// depend only on the heightfield.
pub fn heightfield_artifacts(hf: &Heightfield) -> HeightfieldArtifacts {
    let (z_min, z_max) = hf.min_max();
    let ((heightmap, preview), ((glb, mesh_summary), npy)) = rayon::join(
        || rayon::join(|| heightmap_png16(hf), || preview_png(hf, PREVIEW_MAX_SIDE_PX)),
        || {
            rayon::join(
                || {
                    let tint = Tint::new(z_min, z_max);
                    let color = |height_m: f32, _slope_deg: f32| tint.srgba8(height_m);
                    let meshed = heightfield_mesh(hf, DEFAULT_MAX_SIDE_SAMPLES, Some(&color));
                    let summary = json!({
                        "vertices": meshed.mesh.vertex_count(),
                        "triangles": meshed.mesh.triangle_count(),
                        "stride": meshed.stride,
                    });
                    (write_glb(&Scene::single("terrain", meshed.mesh)), summary)
                },
                || heightfield_npy(hf),
            )
        },
    );
    let summary = json!({
        "z_min": short_decimal(z_min),
        "z_max": short_decimal(z_max),
        "grid": { "cols": hf.cols, "rows": hf.rows, "cell_size_m": short_decimal(hf.cell_size_m) },
        "mesh": mesh_summary,
    });
    HeightfieldArtifacts {
        artifacts: vec![
            Artifact::new("heightmap.png", "image/png", heightmap),
            Artifact::new("preview.png", "image/png", preview),
            Artifact::new("mesh.glb", "model/gltf-binary", glb),
            Artifact::new("heightfield.npy", "application/octet-stream", npy),
        ],
        summary,
    }
}

/// Peak bytes [`heightfield_artifacts`] allocates for a `cols × rows` grid, with every writer
/// running at once: the 16-bit samples and their deflated PNG, the preview (a copy of the grid
/// when it is small enough, its slopes, RGB and PNG), the decimated mesh three times over
/// (mesh, glb buffer, glb file) and the `.npy`.
pub fn heightfield_artifacts_peak_bytes(cols: u64, rows: u64) -> u64 {
    let cells = cols.saturating_mul(rows);
    let longest = cols.max(rows).max(1);
    let max_side = PREVIEW_MAX_SIDE_PX as u64;
    let (w, h) = if longest <= max_side {
        (cols, rows)
    } else {
        let side = |n: u64| ((n * max_side + longest / 2) / longest).clamp(1, n);
        (side(cols), side(rows))
    };
    let preview = 18 * w * h + if longest <= max_side { 4 * cells } else { 0 };
    let stride = longest.saturating_sub(1).div_ceil(DEFAULT_MAX_SIDE_SAMPLES as u64 - 1).max(1);
    let (nx, nz) = (cols.saturating_sub(1).div_ceil(stride) + 1, rows.saturating_sub(1).div_ceil(stride) + 1);
    let mesh = 36 * nx * nz + 24 * (nx - 1) * (nz - 1);
    cells.saturating_mul(10) + preview + 3 * mesh
}

/// A small preview for live progress snapshots.
pub fn snapshot_png(hf: &Heightfield) -> Vec<u8> {
    preview_png(hf, SNAPSHOT_MAX_SIDE_PX)
}

/// An f32 as the JSON number with its shortest decimal (`0.1`, not `0.10000000149011612`), so
/// the summary matches the heightmap's text chunks.
fn short_decimal(value: f32) -> Value {
    heightmap_png::decimal(value).parse::<f64>().map(Value::from).unwrap_or(Value::Null)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn artifacts_come_in_order_with_a_summary() {
        let hf = Heightfield::from_fn(65, 33, 0.1, |x, z| x * 2.0 - z + 0.3);
        let out = heightfield_artifacts(&hf);
        let names: Vec<_> = out.artifacts.iter().map(|a| (a.name.as_str(), a.media_type.as_str())).collect();
        assert_eq!(
            names,
            [
                ("heightmap.png", "image/png"),
                ("preview.png", "image/png"),
                ("mesh.glb", "model/gltf-binary"),
                ("heightfield.npy", "application/octet-stream"),
            ]
        );
        let (z_min, z_max) = hf.min_max();
        assert_eq!(out.summary["z_min"], json!(z_min.to_string().parse::<f64>().unwrap()));
        assert_eq!(out.summary["z_max"].as_f64().unwrap() as f32, z_max);
        assert_eq!(out.summary["grid"], json!({"cols": 65, "rows": 33, "cell_size_m": 0.1}));
        assert_eq!(out.summary["mesh"], json!({"vertices": 65 * 33, "triangles": 64 * 32 * 2, "stride": 1}));
        let back = read_heightfield_npy(&out.artifacts[3].bytes, hf.cell_size_m).unwrap();
        assert_eq!(back, hf);
    }

    #[test]
    fn artifacts_are_byte_identical_across_runs_and_thread_counts() {
        let hf = Heightfield::from_fn(200, 120, 1.0, |x, z| (x * 0.05).sin() * 30.0 + (z * 0.07).cos() * 20.0 - 5.0);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let one = pool.install(|| heightfield_artifacts(&hf));
        let many = heightfield_artifacts(&hf);
        assert_eq!(one.artifacts, many.artifacts);
        assert_eq!(one.summary, many.summary);
    }
}
