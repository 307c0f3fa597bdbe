//! The cave as a glTF scene (floor, roof, one node per speleothem), a picture of it, and the
//! job's figures. Everything here follows from the recorded sequence and the request.

use rayon::prelude::*;
use serde_json::{json, Value};

use super::chamber::ChamberShape;
use super::chamber_mesh::chamber_mesh;
use super::neighbours::{bin_size, Bodies};
use super::params::Chamber;
use super::params::{GrowCaveParams, Mineral};
use super::profile::{site_profiles, Context, SiteProfiles};
use super::sequence::{CaveSequence, RecordedSite};
use super::speleothem_mesh::{profile_mesh, Profile};
use crate::export::{mesh_glbs, metres_text, render_inside_png, Artifact, InsideView, MeshSettings};
use crate::mesh::{MaterialKind, Mesh, Scene, SceneNode};
use crate::stop::{Stop, Stopped};

/// Limestone walls.
const ROCK_SRGB: [u8; 3] = [120, 108, 96];
/// Pictures' sizes in pixels: the preview's and a live snapshot's.
const PREVIEW_PX: (u32, u32) = (1024, 768);
const SNAPSHOT_PX: (u32, u32) = (256, 192);

/// The view of a person standing inside the chamber near one corner (low x, high z), looking
/// across it and a little down, with a lamp above and beside the head: the roof stays on, and
/// what is lit is what a caver would see.
fn inside_view(chamber: &Chamber, (width_px, height_px): (u32, u32)) -> InsideView {
    let (w, d) = (chamber.width_m, chamber.depth_m);
    let (lo, hi) = (chamber.floor.relief_m, chamber.height_m - chamber.roof.relief_m);
    let free = hi - lo;
    let eye = [0.015 * w, lo + 0.5 * free, 0.985 * d];
    let target = [0.65 * w, lo + 0.2 * free, 0.3 * d];
    // Above the eye and a little to its right (the view runs towards +x, −z).
    let lamp = [eye[0] + 0.02 * w, eye[1] + 0.3 * free, eye[2] + 0.02 * d];
    InsideView { width_px, height_px, eye, target, fov_deg: 70.0, lamp, lamp_reach_m: 0.5 * w.hypot(d) }
}

/// The chamber's size (width × depth × height) for the picture's corner.
fn chamber_label(chamber: &Chamber) -> String {
    // The corner font has digits, `x`, `m` and the point only.
    format!("{} x {} x {} m", metres_text(chamber.width_m), metres_text(chamber.depth_m), metres_text(chamber.height_m))
}

/// The cave from inside, as [`inside_view`] stands.
fn picture(params: &GrowCaveParams, scene: &Scene, size: (u32, u32), stop: Stop) -> Result<Vec<u8>, Stopped> {
    render_inside_png(scene, &inside_view(&params.chamber, size), &chamber_label(&params.chamber), stop)
}

/// fv_c's mc: Table 1's colour mixed with calcareous white by the intensity.
pub fn mineral_colour(mineral: Mineral, intensity: f32) -> [f32; 3] {
    let (base, mc) = (Mineral::Calcareous.rgb(), mineral.rgb());
    [0, 1, 2].map(|k| base[k] + (mc[k] - base[k]) * intensity)
}

/// Every site's profiles.
fn profiles(params: &GrowCaveParams, sequence: &CaveSequence, bodies: &Bodies) -> Vec<SiteProfiles> {
    let shape = ChamberShape::new(&params.chamber, sequence.seed);
    let ctx = Context { params, bodies, shape: &shape };
    sequence.sites.par_iter().enumerate().map(|(i, s)| site_profiles(&ctx, i as u32, &s.growth)).collect()
}

/// The speleothems of one site, as named nodes: a column, or a stalactite and a stalagmite.
fn site_nodes(params: &GrowCaveParams, index: usize, site: &RecordedSite, profiles: &SiteProfiles) -> Vec<SceneNode> {
    let colour = mineral_colour(site.mineral, params.intensity);
    let segments = params.segments as usize;
    let node = |name: &str, mesh: Mesh| SceneNode::new(format!("{name} {index}"), mesh, MaterialKind::VertexColors);
    // Each piece's pivot is its root: where the drip site meets the roof (a stalactite) or
    // the floor (a stalagmite, and a column, which stands on it).
    let g = &site.growth;
    let (on_roof, on_floor) = ([g.x_m, g.roof_y_m, g.z_m], [g.x_m, g.floor_y_m, g.z_m]);
    // Roughness keys: the stalactite (and a column) 2i, the stalagmite 2i + 1.
    let key = index as u64 * 2;
    match profiles {
        SiteProfiles::Column(p) => vec![node("column", profile_mesh(p, key, segments, colour)).with_pivot(on_floor)],
        SiteProfiles::Apart { stalactite, stalagmite } => {
            let mut out = Vec::new();
            if let Some(p) = stalactite {
                out.push(node("stalactite", profile_mesh(p, key, segments, colour)).with_pivot(on_roof));
            }
            if let Some(p) = stalagmite {
                out.push(node("stalagmite", profile_mesh(p, key + 1, segments, colour)).with_pivot(on_floor));
            }
            out
        }
    }
}

/// Every site's speleothems as capsules, for the clearances the coating keeps.
pub fn bodies(params: &GrowCaveParams, sequence: &CaveSequence) -> Bodies {
    let c = &params.chamber;
    Bodies::of_sites(sequence.sites.iter().map(|s| &s.growth), [c.width_m, c.depth_m, c.height_m], bin_size(params))
}

/// The scene: the chamber, then each site's speleothems in site order.
pub fn scene(params: &GrowCaveParams, sequence: &CaveSequence) -> Scene {
    scene_of(params, sequence, &profiles(params, sequence, &bodies(params, sequence)))
}

fn scene_of(params: &GrowCaveParams, sequence: &CaveSequence, profiles: &[SiteProfiles]) -> Scene {
    let shape = ChamberShape::new(&params.chamber, sequence.seed);
    let chamber = SceneNode::new("chamber", chamber_mesh(&shape), MaterialKind::Matte { srgb: ROCK_SRGB });
    let speleothems: Vec<Vec<SceneNode>> =
        sequence.sites.par_iter().zip(profiles).enumerate().map(|(i, (s, p))| site_nodes(params, i, s, p)).collect();
    let mut nodes = vec![chamber];
    nodes.extend(speleothems.into_iter().flatten());
    Scene { nodes }
}

/// A small picture of the cave so far, for live progress.
pub fn snapshot_png(params: &GrowCaveParams, sequence: &CaveSequence, stop: Stop) -> Result<Vec<u8>, Stopped> {
    stop.check()?;
    picture(params, &scene(params, sequence), SNAPSHOT_PX, stop)
}

#[derive(Default)]
struct Stats {
    lengths: Vec<f64>,
    radii: Vec<f64>,
}

impl Stats {
    fn push(&mut self, length: f32, radius: f32) {
        self.lengths.push(length as f64);
        self.radii.push(radius as f64);
    }

    fn summary(&self) -> Value {
        let span = |v: &[f64]| {
            if v.is_empty() {
                return Value::Null;
            }
            let min = v.iter().copied().fold(f64::INFINITY, f64::min);
            let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            json!({"min": min, "mean": v.iter().sum::<f64>() / v.len() as f64, "max": max})
        };
        json!({"count": self.lengths.len(), "length_m": span(&self.lengths), "base_radius_m": span(&self.radii)})
    }
}

/// How the drip sites kept apart: how many merged into an earlier one at the start, and the
/// narrowest gap left between two sites' bodies (their capsules; null with fewer than two).
fn neighbour_figures(params: &GrowCaveParams, sequence: &CaveSequence, bodies: &Bodies) -> Value {
    let merged = sequence.sites.iter().filter(|s| s.growth.merged_into.is_some()).count();
    let reach = 4.0 * bin_size(params);
    let gap = sequence
        .sites
        .par_iter()
        .enumerate()
        .map(|(i, s)| {
            super::neighbours::site_capsules(&s.growth)
                .iter()
                .map(|(_, _, c)| bodies.gap(i as u32, c, reach))
                .fold(f32::INFINITY, f32::min)
        })
        .reduce(|| f32::INFINITY, f32::min);
    json!({"merged_sites": merged, "min_gap_m": if gap.is_finite() { json!(gap) } else { Value::Null }})
}

/// `mesh.glb` and `preview.png` of the cave the sequence describes, and the figures.
pub fn build(
    params: &GrowCaveParams,
    sequence: &CaveSequence,
    stop: Stop,
    mesh_settings: &MeshSettings,
) -> Result<(Value, Vec<Artifact>), Stopped> {
    let bodies = bodies(params, sequence);
    let profiles = profiles(params, sequence, &bodies);
    let scene = scene_of(params, sequence, &profiles);
    stop.check()?;
    let (glbs, preview) =
        rayon::join(|| mesh_glbs(&scene, mesh_settings, stop), || picture(params, &scene, PREVIEW_PX, stop));
    let (glbs, glb_figures) = glbs?;
    let preview = preview?;
    let (mut stalactites, mut stalagmites, mut columns) = (Stats::default(), Stats::default(), Stats::default());
    // Base radii as built: the first ring with the coating of every pass since.
    let base = |p: &Profile| p.sections[1].radius;
    for (s, p) in sequence.sites.iter().zip(&profiles) {
        let g = &s.growth;
        match p {
            SiteProfiles::Column(c) => {
                let bottom = c.sections[c.sections.len() - 2].radius;
                columns.push(g.roof_y_m - g.floor_y_m, base(c).max(bottom));
            }
            SiteProfiles::Apart { stalactite, stalagmite } => {
                if let Some(p) = stalactite {
                    stalactites.push(g.roof_y_m - g.stalactite_tip_y(), base(p));
                }
                if let Some(p) = stalagmite {
                    stalagmites.push(g.stalagmite_top_y() - g.floor_y_m, base(p));
                }
            }
        }
    }
    let speleothem = |n: &SceneNode| n.name != "chamber";
    let triangles: usize = scene.nodes.iter().filter(|n| speleothem(n)).map(|n| n.mesh.triangle_count()).sum();
    let all_triangles: usize = scene.nodes.iter().map(|n| n.mesh.triangle_count()).sum();
    let result = json!({
        "passes": sequence.passes,
        "sites": sequence.sites.len(),
        "stalactites": stalactites.summary(),
        "stalagmites": stalagmites.summary(),
        "columns": columns.summary(),
        "triangles": { "speleothems": triangles, "total": all_triangles },
        "neighbours": neighbour_figures(params, sequence, &bodies),
        "glb": glb_figures,
    });
    let mut glbs = glbs.into_iter();
    let mut artifacts =
        vec![glbs.next().expect("mesh.glb comes first"), Artifact::new("preview.png", "image/png", preview)];
    artifacts.extend(glbs);
    Ok((result, artifacts))
}
