//! File writers every kind uses: glb meshes, 16-bit heightmaps, preview pictures, and the
//! exact `.npy` heights that let one job's terrain feed the next.

mod artifact;
mod glb;
mod heightmap_png;
mod heightmap_r16;
mod hypsometric;
mod interior;
mod mesh_glbs;
mod normalmap_png;
mod npy;
mod preview_png;
mod render;
mod scale_bar;
mod splatmap_png;
mod srgb;
mod tiles;

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
pub use glb::{
    screen_coverage, write_glb, write_glb_in_frame, write_glb_with_levels, GlbForm, MAX_U16_INDEXED_VERTICES,
};
pub use heightmap_png::{heightmap_png16, scalar_png16};
pub use heightmap_r16::{heightmap_r16, r16_summary};
pub use hypsometric::Tint;
pub use interior::{render_inside_png, InsideView};
pub use mesh_glbs::{lod_cost, mesh_glbs, MeshSettings, DEFAULT_LODS, LOD_FRACTION_RANGE, MAX_LODS, SUGGESTED_LODS};
pub use normalmap_png::normalmap_png;
pub use npy::{heightfield_npy, read_heightfield_npy};
pub use preview_png::preview_png;
pub use render::{render_png, render_png_framed, View};
pub use scale_bar::metres_text;
pub use splatmap_png::splatmap_png;
pub use tiles::{tile_artifacts, TileGrid, MAX_TILES_PER_SIDE};

use serde_json::{json, Value};

use crate::mesh::{heightfield_mesh, MaterialKind, Scene, SceneNode, DEFAULT_MAX_SIDE_SAMPLES};
use crate::stop::{Stop, Stopped};
use crate::terrain::Heightfield;

/// Longest side of `preview.png`.
pub const PREVIEW_MAX_SIDE_PX: u32 = 1024;
/// Longest side of a live snapshot: small enough to send about once a second.
pub const SNAPSHOT_MAX_SIDE_PX: u32 = 256;

/// The standard outputs of a heightfield kind and the figures for its job `result`.
#[derive(Debug)]
pub struct HeightfieldArtifacts {
    /// `heightmap.png`, `preview.png`, `mesh.glb`, `heightfield.npy`, `heightmap.r16`,
    /// `normalmap.png`, `splatmap.png`, then `mesh_lod1.glb`, …, then the tiles and
    /// `tiles/index.json` when asked for, in that order.
    pub artifacts: Vec<Artifact>,
    /// `{"z_min", "z_max", "grid": {"cols", "rows", "cell_size_m"}, "mesh": {"vertices",
    /// "triangles", "stride"}, "heightmap_r16": {…}, "glb": {…}, "tiles": {…}}`, metres; z_min/z_max are the same decimals
    /// as the PNG's text.
    pub summary: Value,
}

/// What a heightfield kind tells the export besides the heights.
#[derive(Clone, Debug, Default)]
pub struct HeightfieldExport<'a> {
    /// The kind's own material weight per sample (0–255; `splatmap.png`'s alpha), where it
    /// knows one.
    pub material: Option<&'a [u8]>,
    /// The kind's own rock weight per sample (0–255), combined with the slope's rock by the
    /// larger in `splatmap.png`'s G, where it knows one.
    pub rock: Option<&'a [u8]>,
    /// How `mesh.glb` stores its vertices, and its levels of detail.
    pub mesh: MeshSettings,
    /// Below it the preview and the vertex colours show water, and `splatmap.png` a bed of
    /// deposit (0 m unless the kind knows one).
    pub sea_level_m: f32,
    /// The request's `tiles`: the mesh cut into tiles at every level too.
    pub tiles: Option<TileGrid>,
    /// The job's stop request: levels of detail and tiles look at it while they are made.
    pub stop: Stop<'a>,
}

impl<'a> HeightfieldExport<'a> {
    /// The request's compression, levels of detail and tiles; no material, sea at 0 m.
    pub fn new(mesh: &MeshSettings, tiles: Option<TileGrid>, stop: Stop<'a>) -> Self {
        Self { mesh: mesh.clone(), tiles, stop, ..Default::default() }
    }
}

/// Everything a heightfield kind delivers for its final terrain, built in parallel; the bytes
/// depend only on the heightfield and `options`. Stopped on request while making levels of
/// detail and tiles.
pub fn heightfield_artifacts(hf: &Heightfield, options: &HeightfieldExport) -> Result<HeightfieldArtifacts, Stopped> {
    let HeightfieldExport { material, rock, ref mesh, sea_level_m, tiles, stop } = *options;
    let (z_min, z_max) = hf.min_max();
    let (((heightmap, preview), (r16, (normals, splat))), (((glbs, tiled), mesh_summary), npy)) = rayon::join(
        || {
            rayon::join(
                || rayon::join(|| heightmap_png16(hf), || preview_png(hf, PREVIEW_MAX_SIDE_PX, sea_level_m)),
                || {
                    rayon::join(
                        || heightmap_r16(hf),
                        || rayon::join(|| normalmap_png(hf), || splatmap_png(hf, material, rock, sea_level_m)),
                    )
                },
            )
        },
        || {
            rayon::join(
                || {
                    let tint = Tint::with_sea_level(z_min, z_max, sea_level_m);
                    let color = |height_m: f32, _slope_deg: f32| tint.srgba8(height_m);
                    let meshed = heightfield_mesh(hf, DEFAULT_MAX_SIDE_SAMPLES, Some(&color));
                    let summary = json!({
                        "vertices": meshed.mesh.vertex_count(),
                        "triangles": meshed.mesh.triangle_count(),
                        "stride": meshed.stride,
                    });
                    let terrain =
                        SceneNode::new("terrain", meshed.mesh, MaterialKind::default()).with_grid(meshed.vertices);
                    let scene = Scene { nodes: vec![terrain] };
                    let glbs = rayon::join(
                        || mesh_glbs(&scene, mesh, stop),
                        || {
                            tiles.map(|grid| {
                                let longest = mesh_glbs::longest_side(&scene);
                                tile_artifacts(&scene.nodes[0].mesh, meshed.vertices, grid, mesh, longest, stop)
                            })
                        },
                    );
                    (glbs, summary)
                },
                || heightfield_npy(hf),
            )
        },
    );
    let (glbs, glb_figures) = glbs?;
    let tiled = tiled.transpose()?;
    let summary = json!({
        "z_min": short_decimal(z_min),
        "z_max": short_decimal(z_max),
        "grid": { "cols": hf.cols, "rows": hf.rows, "cell_size_m": short_decimal(hf.cell_size_m) },
        "mesh": mesh_summary,
        "heightmap_r16": r16_summary(hf),
        "glb": glb_figures,
    });
    let (tile_files, summary) = match tiled {
        Some((files, figures)) => {
            let mut summary = summary;
            summary["tiles"] = figures;
            (files, summary)
        }
        None => (Vec::new(), summary),
    };
    let mut glbs = glbs.into_iter();
    let mut artifacts = vec![
        Artifact::new("heightmap.png", "image/png", heightmap),
        Artifact::new("preview.png", "image/png", preview),
        glbs.next().expect("mesh.glb comes first"),
        Artifact::new("heightfield.npy", "application/octet-stream", npy),
        Artifact::new("heightmap.r16", "application/octet-stream", r16),
        Artifact::new("normalmap.png", "image/png", normals),
        Artifact::new("splatmap.png", "image/png", splat),
    ];
    artifacts.extend(glbs);
    artifacts.extend(tile_files);
    Ok(HeightfieldArtifacts { artifacts, summary })
}

/// Peak bytes [`heightfield_artifacts`] allocates for a `cols × rows` grid, with every writer
/// running at once: the 16-bit samples and their deflated PNG, the preview (a copy of the grid
/// when it is small enough, its slopes, RGB and PNG), the decimated mesh three times over
/// (mesh, glb buffer, glb file), the `.npy`, the `.r16`, the normal map (RGB and its PNG) and
/// the splat map (RGBA and its PNG); with `tiles`, the tiles' meshes and files as well (the
/// mesh twice more).
pub fn heightfield_artifacts_peak_bytes(cols: u64, rows: u64, tiles: bool) -> u64 {
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
    let (nx, nz) = mesh_samples(cols, rows);
    let mesh = 36 * nx * nz + 24 * (nx - 1) * (nz - 1);
    let meshes = if tiles { 5 } else { 3 };
    cells.saturating_mul(10 + 2 + 6 + 8) + preview + meshes * mesh
}

/// Bytes levels of detail of a heightfield add at the peak per triangle they start from: the
/// deviation's hierarchy over the one full mesh, meshoptimizer's arrays and the levels kept
/// until written (measured 20–66 by `tests/cost_estimates.rs` since the hierarchy replaced the
/// search grid, which took 96–239).
pub const HEIGHTFIELD_LOD_BYTES_PER_TRIANGLE: u64 = 80;

/// Triangles levels of detail start from for a `cols × rows` grid: the decimated mesh of
/// `mesh.glb`, and with `tiles` its tiles (the same triangles again, simplified tile by tile).
pub fn heightfield_lod_triangles(cols: u64, rows: u64, tiles: bool) -> u64 {
    let (nx, nz) = mesh_samples(cols, rows);
    let triangles = 2 * (nx - 1) * (nz - 1);
    if tiles {
        2 * triangles
    } else {
        triangles
    }
}

/// Samples along each side of the decimated mesh of a `cols × rows` grid.
fn mesh_samples(cols: u64, rows: u64) -> (u64, u64) {
    let longest = cols.max(rows).max(1);
    let stride = longest.saturating_sub(1).div_ceil(DEFAULT_MAX_SIDE_SAMPLES as u64 - 1).max(1);
    (cols.saturating_sub(1).div_ceil(stride) + 1, rows.saturating_sub(1).div_ceil(stride) + 1)
}

/// A small preview for live progress snapshots.
pub fn snapshot_png(hf: &Heightfield) -> Vec<u8> {
    preview_png(hf, SNAPSHOT_MAX_SIDE_PX, 0.0)
}

/// An f32 as the JSON number with its shortest decimal (`0.1`, not `0.10000000149011612`), so
/// the summary matches the heightmap's text chunks.
pub(crate) fn short_decimal(value: f32) -> Value {
    heightmap_png::decimal(value).parse::<f64>().map(Value::from).unwrap_or(Value::Null)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn artifacts_come_in_order_with_a_summary() {
        let hf = Heightfield::from_fn(65, 33, 0.1, |x, z| x * 2.0 - z + 0.3);
        let out = heightfield_artifacts(&hf, &HeightfieldExport::default()).unwrap();
        let names: Vec<_> = out.artifacts.iter().map(|a| (a.name.as_str(), a.media_type.as_str())).collect();
        assert_eq!(
            names,
            [
                ("heightmap.png", "image/png"),
                ("preview.png", "image/png"),
                ("mesh.glb", "model/gltf-binary"),
                ("heightfield.npy", "application/octet-stream"),
                ("heightmap.r16", "application/octet-stream"),
                ("normalmap.png", "image/png"),
                ("splatmap.png", "image/png"),
                ("mesh_lod1.glb", "model/gltf-binary"),
                ("mesh_lod2.glb", "model/gltf-binary"),
                ("mesh_lod3.glb", "model/gltf-binary"),
            ]
        );
        let (z_min, z_max) = hf.min_max();
        assert_eq!(out.summary["z_min"], json!(z_min.to_string().parse::<f64>().unwrap()));
        assert_eq!(out.summary["z_max"].as_f64().unwrap() as f32, z_max);
        assert_eq!(out.summary["grid"], json!({"cols": 65, "rows": 33, "cell_size_m": 0.1}));
        assert_eq!(out.summary["mesh"], json!({"vertices": 65 * 33, "triangles": 64 * 32 * 2, "stride": 1}));
        let back = read_heightfield_npy(&out.artifacts[3].bytes, hf.cell_size_m).unwrap();
        assert_eq!(back, hf);

        // The raw heights read back from the summary's sizes and range agree with the .npy's to
        // within one 16-bit step.
        let r16 = &out.summary["heightmap_r16"];
        let (w, h) = (r16["width"].as_u64().unwrap() as usize, r16["height"].as_u64().unwrap() as usize);
        let (lo, range) = (r16["z_min"].as_f64().unwrap(), r16["height_range_m"].as_f64().unwrap());
        let raw = &out.artifacts[4].bytes;
        assert_eq!(raw.len(), 2 * w * h);
        let step = range / 65535.0;
        for (pair, &height) in raw.chunks_exact(2).zip(&back.heights_m) {
            let read = lo + f64::from(u16::from_le_bytes([pair[0], pair[1]])) * step;
            assert!((read - f64::from(height)).abs() <= step, "{read} for {height}");
        }
    }

    #[test]
    fn artifacts_are_byte_identical_across_runs_and_thread_counts() {
        let hf = Heightfield::from_fn(200, 120, 1.0, |x, z| (x * 0.05).sin() * 30.0 + (z * 0.07).cos() * 20.0 - 5.0);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let one = pool.install(|| heightfield_artifacts(&hf, &HeightfieldExport::default()).unwrap());
        let many = heightfield_artifacts(&hf, &HeightfieldExport::default()).unwrap();
        assert_eq!(one.artifacts, many.artifacts);
        assert_eq!(one.summary, many.summary);
    }
}
