//! A job's meshes as glb files: `mesh.glb` and its levels of detail `mesh_lod1.glb`, … (the
//! request's `lods`), each level every node simplified within an error bound that is a fraction
//! of the scene's longest side, and the figures of every level for the job's result.

use rayon::prelude::*;
use serde_json::{json, Value};

use super::glb::MESHOPT_POSITION_BITS;
use super::{write_glb, write_glb_with_levels, Artifact, GlbForm};
use crate::mesh::{grid_levels, simplify_levels_with, sliver_height, Border, Lod, Scene, SceneNode};
use crate::stop::{Stop, Stopped};

/// The levels a request gets when it names none: [`SUGGESTED_LODS`]. `lods: []` turns them off.
pub const DEFAULT_LODS: [f64; 3] = SUGGESTED_LODS;
/// Three levels with error bounds of 0.2 %, 0.8 % and 3.2 % of the scene's longest side
/// (0.5 m, 2 m and 8 m on a 256 m terrain).
pub const SUGGESTED_LODS: [f64; 3] = [0.002, 0.008, 0.032];
/// Triangles a second one level's simplification and measuring get through at best: a lower
/// bound of the time, so only levels no machine could make in the time limit are refused (this
/// 2-core machine measured 55 000 a second on island-defaults, 2.2 M triangles and three levels
/// in 121 s, and 157 000 on a 257² heightfield; the margin is for faster machines and for
/// issue 31's faster levels).
pub const LOD_TRIANGLES_PER_SECOND: f64 = 5e6;

/// What making `levels` levels of detail adds to a job of cost `cost`: (bytes at the peak,
/// least seconds).
pub fn lod_cost(cost: &crate::model::Cost, levels: usize) -> (u64, f64) {
    if levels == 0 {
        return (0, 0.0);
    }
    (cost.lod_bytes, cost.lod_triangles as f64 * levels as f64 / LOD_TRIANGLES_PER_SECOND)
}

/// Most levels of detail a request may ask for.
pub const MAX_LODS: usize = 4;
/// The smallest and largest error bound a level may have, as fractions of the longest side.
pub const LOD_FRACTION_RANGE: (f64, f64) = (0.0005, 0.25);

/// How a job writes its meshes: the glb form and the levels of detail.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshSettings {
    pub form: GlbForm,
    /// Error bounds of `mesh_lod1.glb`, `mesh_lod2.glb`, … as fractions of the scene's longest
    /// side, increasing.
    pub lods: Vec<f64>,
}

impl Default for MeshSettings {
    fn default() -> Self {
        Self { form: GlbForm::default(), lods: DEFAULT_LODS.to_vec() }
    }
}

impl MeshSettings {
    /// The `lods` field of a request: a list of at most [`MAX_LODS`] increasing fractions in
    /// [`LOD_FRACTION_RANGE`]; `Err` says what is wrong.
    pub fn parse_lods(value: &Value) -> Result<Vec<f64>, String> {
        let (lo, hi) = LOD_FRACTION_RANGE;
        let list = value.as_array().ok_or("must be a list of error bounds (fractions of the mesh's longest side)")?;
        if list.len() > MAX_LODS {
            return Err(format!("must have at most {MAX_LODS} levels"));
        }
        let mut lods = Vec::with_capacity(list.len());
        for v in list {
            let f = v
                .as_f64()
                .filter(|f| (lo..=hi).contains(f))
                .ok_or(format!("each level must be a number in [{lo}, {hi}]"))?;
            if lods.last().is_some_and(|&last| f <= last) {
                return Err("levels must increase".into());
            }
            lods.push(f);
        }
        Ok(lods)
    }
}

/// `mesh.glb` (with its levels of detail as `MSFT_lod`) and one glb per level of detail, and `{"form", "levels": [{"file", "vertices",
/// "triangles", "error_bound_m", "max_deviation_m", "sample_spacing_m", "unreduced", "tries"}, …]}` (level 0, the
/// full mesh, first) for the result. Stopped on request between and within levels.
pub fn mesh_glbs(scene: &Scene, settings: &MeshSettings, stop: Stop) -> Result<(Vec<Artifact>, Value), Stopped> {
    let longest = longest_side(scene);
    // The full scene is borrowed, not copied: a copy would raise every job's peak memory.
    let bounds: Vec<f64> = settings.lods.iter().map(|&fraction| fraction * longest).collect();
    let simplified = simplified(scene, &bounds, stop)?;
    stop.check()?;
    let levels: Vec<(&Scene, LevelFigures)> = std::iter::once((scene, LevelFigures::default()))
        .chain(simplified.iter().map(|(scene, figures)| (scene, figures.clone())))
        .collect();
    // `mesh.glb` carries its levels (MSFT_lod); each level is also a glb of its own.
    let with_levels: Vec<(&Scene, f64)> = simplified.iter().zip(&bounds).map(|((s, _), &b)| (s, b)).collect();
    let (full, lone) = rayon::join(
        || write_glb_with_levels(scene, &with_levels, settings.form),
        || simplified.par_iter().map(|(scene, _)| write_glb(scene, settings.form)).collect::<Vec<_>>(),
    );
    let files: Vec<Vec<u8>> = std::iter::once(full).chain(lone).collect();
    let mut artifacts = Vec::with_capacity(files.len());
    let mut figures = Vec::with_capacity(files.len());
    for (level, ((scene, level_figures), bytes)) in levels.iter().zip(files).enumerate() {
        let name = if level == 0 { "mesh.glb".to_string() } else { format!("mesh_lod{level}.glb") };
        let vertices: usize = scene.nodes.iter().map(|n| n.mesh.vertex_count()).sum();
        let triangles: usize = scene.nodes.iter().map(|n| n.mesh.triangle_count()).sum();
        figures.push(json!({
            "file": name,
            "vertices": vertices,
            "triangles": triangles,
            "error_bound_m": level_figures.bound_m,
            "max_deviation_m": level_figures.deviation_m,
            "sample_spacing_m": level_figures.spacing_m,
            "unreduced": level_figures.unreduced,
            "tries": level_figures.tries,
        }));
        artifacts.push(Artifact::new(&name, "model/gltf-binary", bytes));
    }
    Ok((artifacts, json!({ "form": settings.form.name(), "levels": figures })))
}

#[derive(Clone, Debug, Default)]
struct LevelFigures {
    bound_m: f64,
    deviation_m: f64,
    spacing_m: f64,
    /// `[{"node", "reason"}]`: nodes this level keeps as the level before, and why.
    unreduced: Vec<Value>,
    /// The most tries of meshoptimizer any node's level took (more than one: the first missed
    /// the bound or crowded an edge, and the next held vertices around where it did).
    tries: u32,
}

/// Every node of `scene` simplified within each of `bounds_m` (a cascade per node, see
/// [`simplify_levels`]), and each level's worst measured deviation.
fn simplified(scene: &Scene, bounds_m: &[f64], stop: Stop) -> Result<Vec<(Scene, LevelFigures)>, Stopped> {
    let bounds: Vec<f32> = bounds_m.iter().map(|&b| b as f32).collect();
    // A triangle the coarsest grid a glb stores positions on would flatten is a sliver.
    let sliver = sliver_height(longest_side(scene), MESHOPT_POSITION_BITS);
    let per_node: Vec<Vec<Lod>> = scene
        .nodes
        .par_iter()
        .map(|node| match node.grid.and_then(|grid| grid_levels(&node.mesh, grid, &bounds, stop)) {
            Some(levels) => levels,
            None => simplify_levels_with(&node.mesh, &bounds, Border::Held, sliver, stop),
        })
        .collect::<Result<_, _>>()?;
    let mut per_node: Vec<std::vec::IntoIter<Lod>> = per_node.into_iter().map(Vec::into_iter).collect();
    let mut levels = Vec::with_capacity(bounds.len());
    for &bound_m in bounds_m {
        let lods: Vec<Lod> = per_node.iter_mut().map(|l| l.next().expect("one level per bound")).collect();
        let deviation_m = lods.iter().map(|l| f64::from(l.deviation_m)).fold(0.0, f64::max);
        // The spacing of the nodes that were simplified (a two-triangle sea stays as it is).
        let spacing_m = lods
            .iter()
            .zip(&scene.nodes)
            .filter(|(lod, node)| lod.mesh.triangle_count() < node.mesh.triangle_count())
            .map(|(lod, _)| f64::from(lod.sample_spacing_m))
            .fold(0.0, f64::max);
        let tries = lods.iter().map(|l| l.tries).max().unwrap_or(0);
        let unreduced = lods
            .iter()
            .zip(&scene.nodes)
            .filter_map(|(lod, node)| Some(json!({"node": node.name, "reason": lod.unreduced.as_ref()?})))
            .collect();
        let nodes = scene
            .nodes
            .iter()
            .zip(lods)
            .map(|(node, lod)| SceneNode {
                name: node.name.clone(),
                mesh: lod.mesh,
                material: node.material,
                pivot: Some(node.pivot()),
                grid: None,
            })
            .collect();
        levels.push((
            Scene { nodes },
            LevelFigures {
                bound_m: round_mm(bound_m),
                deviation_m: round_up_mm(deviation_m),
                spacing_m: round_mm(spacing_m),
                unreduced,
                tries,
            },
        ));
    }
    Ok(levels)
}

/// The longest side of the box around every node's vertices (1 m for an empty scene).
pub(super) fn longest_side(scene: &Scene) -> f64 {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for (l, h) in scene.nodes.iter().filter_map(|n| n.mesh.bounds()) {
        for k in 0..3 {
            lo[k] = lo[k].min(l[k]);
            hi[k] = hi[k].max(h[k]);
        }
    }
    let side = (0..3).map(|k| f64::from(hi[k] - lo[k])).fold(0.0, f64::max);
    if side.is_finite() && side > 0.0 {
        side
    } else {
        1.0
    }
}

/// Metres to a tenth of a millimetre, for the result.
pub(super) fn round_mm(m: f64) -> f64 {
    (m * 1e4).round() / 1e4
}

/// Upwards, so a figure shown is never below what was measured.
pub(super) fn round_up_mm(m: f64) -> f64 {
    (m * 1e4).ceil() / 1e4
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::heightfield_mesh;
    use crate::terrain::Heightfield;

    #[test]
    fn lods_parse_within_bounds() {
        assert_eq!(MeshSettings::parse_lods(&json!([0.001, 0.01])), Ok(vec![0.001, 0.01]));
        assert_eq!(MeshSettings::parse_lods(&json!([])), Ok(vec![]));
        assert!(MeshSettings::parse_lods(&json!([0.01, 0.001])).unwrap_err().contains("increase"));
        assert!(MeshSettings::parse_lods(&json!([0.5])).unwrap_err().contains("[0.0005, 0.25]"));
        assert!(MeshSettings::parse_lods(&json!([0.001, 0.002, 0.003, 0.004, 0.005])).unwrap_err().contains("at most"));
        assert!(MeshSettings::parse_lods(&json!("0.01")).is_err());
    }

    #[test]
    fn every_level_is_written_with_its_figures() {
        // 64 m square: bounds 0.128 m and 2.048 m.
        let hf = Heightfield::from_fn(65, 65, 1.0, |x, z| (x * 0.13).sin() * 6.0 + (z * 0.1).cos() * 4.0);
        let scene = Scene::single("terrain", heightfield_mesh(&hf, 4097, None).mesh);
        let settings = MeshSettings { form: GlbForm::Quantize, lods: vec![0.002, 0.032] };
        let (artifacts, figures) = mesh_glbs(&scene, &settings, Stop::NEVER).unwrap();
        let names: Vec<_> = artifacts.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, ["mesh.glb", "mesh_lod1.glb", "mesh_lod2.glb"]);
        let levels = figures["levels"].as_array().unwrap();
        assert_eq!(levels[0]["triangles"], 2 * 64 * 64);
        assert_eq!(levels[0]["max_deviation_m"], 0.0);
        assert_eq!(levels[1]["error_bound_m"], 0.128);
        assert_eq!(levels[2]["error_bound_m"], 2.048);
        for l in &levels[1..] {
            assert!(l["max_deviation_m"].as_f64().unwrap() <= l["error_bound_m"].as_f64().unwrap(), "{l}");
        }
        assert!(levels[2]["triangles"].as_u64() < levels[1]["triangles"].as_u64());
        assert!(levels[1]["triangles"].as_u64() < levels[0]["triangles"].as_u64());
        assert_eq!(figures["form"], "quantize");
    }
}
