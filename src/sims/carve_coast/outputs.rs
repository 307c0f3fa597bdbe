//! The carved terrain as outputs: the closed mesh coloured by material with a sea plane, a
//! lit preview that shows the overhangs, the topmost surface as a 16-bit heightmap (and the
//! exact heights for the next job), and the figures.

use rayon::prelude::*;
use serde_json::{json, Value};

use super::caves;
use super::field::{bands, columns, grid_for, remove_fragments, sample_planes, surface_at_walls, Grid};
use super::implicit::{Carving, Implicit};
use super::params::CarveCoastParams;
use crate::export::{
    heightfield_npy, heightmap_png16, heightmap_r16, mesh_glbs, normalmap_png, r16_summary, render_png,
    render_png_framed, splatmap_png, Artifact, MeshSettings, View,
};
use crate::jobs::{SimError, HEIGHTFIELD_ARTIFACT};
use crate::mesh::{extract_isosurface, MaterialKind, Mesh, ScalarField, Scene, SceneNode};
use crate::stop::{Stop, Stopped};
use crate::terrain::Heightfield;

const PREVIEW: View = View { width_px: 1024, height_px: 768, azimuth_deg: 35.0, elevation_deg: 28.0 };
const SNAPSHOT: View = View { width_px: 256, height_px: 192, azimuth_deg: 35.0, elevation_deg: 28.0 };
const ROCK: [u8; 4] = [132, 120, 108, 255];
const SAND: [u8; 4] = [214, 196, 150, 255];
const GRASS: [u8; 4] = [96, 138, 70, 255];
/// Faces steeper than this from horizontal are bare rock.
const ROCK_SLOPE_DEG: f32 = 40.0;
/// Metres above sea level that are beach.
const BEACH_M: f32 = 1.5;
/// Field chunks (groups of planes) sampled between progress reports.
const CHUNKS: usize = 64;

/// The sampled field and what it took.
pub struct Sampled {
    pub grid: Grid,
    pub values: Vec<f32>,
    pub fragments: usize,
    pub pockets: usize,
}

/// Sample the implicit terrain over its box at `voxel_m`; `on_chunk(done, of)` after each chunk
/// of planes (it may stop the run).
pub fn sample(
    implicit: &Implicit,
    params: &CarveCoastParams,
    voxel_m: f32,
    dense: bool,
    on_chunk: &mut dyn FnMut(usize, usize) -> Result<(), SimError>,
) -> Result<Sampled, SimError> {
    let headroom = params.warp_amplitude() * 2.0 + voxel_m;
    let grid = grid_for(implicit.hf, voxel_m, headroom);
    let bands = bands(implicit, &grid, params.warp_amplitude(), dense);
    let plane = grid.plane();
    let mut values = vec![0f32; grid.len()];
    let per_chunk = grid.ny.div_ceil(CHUNKS);
    for (c, chunk) in values.chunks_mut(plane * per_chunk).enumerate() {
        let first = c * per_chunk;
        sample_planes(implicit, &grid, &bands, first..first + chunk.len() / plane, chunk);
        on_chunk(c + 1, grid.ny.div_ceil(per_chunk))?;
    }
    let (fragments, pockets) =
        if params.remove_fragments { remove_fragments(&mut values, &grid, &bands) } else { (0, 0) };
    Ok(Sampled { grid, values, fragments, pockets })
}

/// The closed surface of the sampled field, metres.
pub fn surface(s: &Sampled, stop: Stop) -> Result<Mesh, Stopped> {
    let g = &s.grid;
    let field = ScalarField {
        dims: [g.nx, g.ny, g.nz],
        origin_m: [0.0, g.bottom_y, 0.0],
        spacing_m: g.voxel_m,
        values: &s.values,
    };
    extract_isosurface(&field, 0.0, stop)
}

/// Colour by material: rock on steep or carved faces, sand near sea level, grass above. Each
/// vertex asks the carving spheres, seconds on a large island: `stop` is looked at throughout.
fn colour(mesh: &mut Mesh, implicit: &Implicit, sea_level: f32, voxel_m: f32, stop: Stop) -> Result<(), Stopped> {
    let steep = ROCK_SLOPE_DEG.to_radians().cos();
    let colours = mesh
        .positions
        .par_iter()
        .zip(mesh.normals.par_iter())
        .map(|(p, n)| {
            if stop.requested() {
                return ROCK;
            }
            let carved = implicit.sphere_distance(*p).abs() < voxel_m;
            if carved || n[1] < steep {
                ROCK
            } else if p[1] < sea_level + BEACH_M {
                SAND
            } else {
                GRASS
            }
        })
        .collect();
    stop.check()?;
    mesh.colors = Some(colours);
    Ok(())
}

/// A flat quad at sea level over the terrain's footprint, facing up.
/// What the preview frames: the land the waves carve, i.e. the mesh's vertices above the sea
/// (the sea floor, however near the surface, is left out), widened by a tenth of their
/// footprint (at least 3 voxels) on each side so the shore's water shows; `None` when nothing
/// stands above the sea.
fn coastline_bounds(mesh: &Mesh, sea_level: f32, voxel_m: f32) -> Option<([f32; 3], [f32; 3])> {
    let floor = sea_level + 0.5 * voxel_m;
    let mut above = mesh.positions.iter().filter(|p| p[1] >= floor);
    let first = *above.next()?;
    let (mut lo, mut hi) = above.fold((first, first), |(lo, hi), p| {
        (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
    });
    let pad = ((hi[0] - lo[0]).max(hi[2] - lo[2]) / 10.0).max(3.0 * voxel_m);
    for k in [0, 2] {
        lo[k] -= pad;
        hi[k] += pad;
    }
    lo[1] = lo[1].min(sea_level);
    Some((lo, hi))
}

/// A box by its lowest and highest corner, metres.
type Box3 = ([f32; 3], [f32; 3]);

/// Vertices whose normal points this far down (its y) face the water from beneath an overhang.
const UNDERSIDE_NORMAL_Y: f32 = -0.3;
/// The close-up's window is this share of the land's footprint on a side (at least
/// [`CLOSE_UP_MIN_VOXELS`]), low enough to look into the caves.
const CLOSE_UP_SHARE: f32 = 1.0 / 3.0;
const CLOSE_UP_MIN_VOXELS: f32 = 24.0;
const CLOSE_UP_ELEVATION_DEG: f32 = 14.0;
/// The close-up frames land up to this share of its window's side above the sea.
const CLOSE_UP_MAX_HEIGHT_SHARE: f32 = 0.5;

/// The preview's view of the coast where the waves carved most: a window of a third of the
/// land's footprint around the densest cluster of overhang undersides (vertices above the sea
/// whose normals point down), seen low from the sea, looking inland (away from the land's
/// centre through the window). From there a person sees the overhangs and the sea caves'
/// mouths rather than the island's top. `None` when nothing overhangs: the whole coastline
/// is framed instead.
fn close_up(mesh: &Mesh, sea_level: f32, voxel_m: f32) -> Option<(View, Box3)> {
    let floor = sea_level + 0.5 * voxel_m;
    let land: Vec<[f32; 3]> = mesh.positions.iter().copied().filter(|p| p[1] >= floor).collect();
    let under: Vec<[f32; 3]> = mesh
        .positions
        .iter()
        .zip(&mesh.normals)
        .filter(|(p, n)| p[1] >= floor && n[1] < UNDERSIDE_NORMAL_Y)
        .map(|(p, _)| *p)
        .collect();
    if under.is_empty() {
        return None;
    }
    let (lo, hi) = land.iter().fold(([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]), |(lo, hi), p| {
        ([lo[0].min(p[0]), lo[1].min(p[2])], [hi[0].max(p[0]), hi[1].max(p[2])])
    });
    let side = ((hi[0] - lo[0]).max(hi[1] - lo[1]) * CLOSE_UP_SHARE).max(CLOSE_UP_MIN_VOXELS * voxel_m);
    // Undersides binned by window-sized cells; the fullest cell (first in row order on a tie).
    let cells = [((hi[0] - lo[0]) / side).floor() as usize + 1, ((hi[1] - lo[1]) / side).floor() as usize + 1];
    let cell_of = |p: &[f32; 3]| {
        let c = |k: usize, v: f32| (((v - lo[k]) / side).floor().max(0.0) as usize).min(cells[k] - 1);
        c(1, p[2]) * cells[0] + c(0, p[0])
    };
    let mut counts = vec![0usize; cells[0] * cells[1]];
    for p in &under {
        counts[cell_of(p)] += 1;
    }
    let best = (0..counts.len()).max_by_key(|&i| (counts[i], std::cmp::Reverse(i)))?;
    let chosen: Vec<&[f32; 3]> = under.iter().filter(|p| cell_of(p) == best).collect();
    let mean = |k: usize| chosen.iter().map(|p| f64::from(p[k])).sum::<f64>() / chosen.len() as f64;
    let centre = [mean(0) as f32, mean(2) as f32];
    let half = 0.5 * side;
    let (wlo, whi) = ([centre[0] - half, centre[1] - half], [centre[0] + half, centre[1] + half]);
    let top = land
        .iter()
        .filter(|p| (wlo[0]..=whi[0]).contains(&p[0]) && (wlo[1]..=whi[1]).contains(&p[2]))
        .map(|p| p[1])
        .fold(floor, f32::max)
        // Higher ground is cut off by the picture's top: the shore fills the frame.
        .min(sea_level + CLOSE_UP_MAX_HEIGHT_SHARE * side);
    // Looking inland: the camera stands out to sea, beyond the window from the land's centre.
    let land_centre = [0, 2].map(|k| (land.iter().map(|p| f64::from(p[k])).sum::<f64>() / land.len() as f64) as f32);
    let out = [centre[0] - land_centre[0], centre[1] - land_centre[1]];
    let azimuth_deg =
        if out[0].hypot(out[1]) > voxel_m { out[0].atan2(out[1]).to_degrees() } else { PREVIEW.azimuth_deg };
    let view = View { azimuth_deg, elevation_deg: CLOSE_UP_ELEVATION_DEG, ..PREVIEW };
    Some((view, ([wlo[0], sea_level, wlo[1]], [whi[0], top, whi[1]])))
}

fn sea_plane(hf: &Heightfield, sea_level: f32) -> Mesh {
    let (w, d) = (hf.width_m(), hf.depth_m());
    Mesh {
        positions: vec![[0.0, sea_level, 0.0], [w, sea_level, 0.0], [w, sea_level, d], [0.0, sea_level, d]],
        normals: vec![[0.0, 1.0, 0.0]; 4],
        uvs: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        colors: None,
        indices: vec![0, 2, 1, 0, 3, 2],
    }
}

/// Connected pieces and genus of a closed mesh (Euler: V − E + F = 2·(pieces − genus)).
pub fn topology(mesh: &Mesh) -> (usize, i64) {
    let n = mesh.vertex_count();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    }
    for t in mesh.indices.chunks_exact(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2])] {
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            if ra != rb {
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
    }
    let mut used = vec![false; n];
    for &i in &mesh.indices {
        used[i as usize] = true;
    }
    let pieces = (0..n as u32).filter(|&i| used[i as usize] && find(&mut parent, i) == i).count();
    let (v, f) = (used.iter().filter(|&&u| u).count() as i64, mesh.triangle_count() as i64);
    let euler = v - f * 3 / 2 + f;
    (pieces, pieces as i64 - euler / 2)
}

/// A small picture of the carved terrain, meshed coarsely, for live progress.
pub fn snapshot_png(
    implicit: &Implicit,
    params: &CarveCoastParams,
    voxel_m: f32,
    stop: Stop,
) -> Result<Vec<u8>, Stopped> {
    let coarse = voxel_m * 4.0;
    let s = sample(implicit, params, coarse, false, &mut |_, _| Ok(stop.check()?)).map_err(|_| Stopped)?;
    let terrain = surface(&s, stop)?;
    let scene = Scene {
        nodes: vec![
            SceneNode::new("terrain", terrain, MaterialKind::Matte { srgb: [170, 150, 120] }),
            SceneNode::new("sea", sea_plane(implicit.hf, params.sea_level()), MaterialKind::Water),
        ],
    };
    render_png(&scene, &SNAPSHOT, stop)
}

/// Everything the job delivers for the terrain carved by `spheres`. `on_chunk` hears of the
/// sampling's chunks, `on_stage` of the stages after it.
#[allow(clippy::too_many_arguments)]
pub fn build(
    implicit: &Implicit,
    params: &CarveCoastParams,
    spheres: &[Carving],
    voxel_m: f32,
    on_chunk: &mut dyn FnMut(usize, usize) -> Result<(), SimError>,
    on_stage: &dyn Fn(&str),
    stop: Stop,
    mesh_settings: &MeshSettings,
) -> Result<(Value, Vec<Artifact>), SimError> {
    let sampled = sample(implicit, params, voxel_m, false, on_chunk)?;
    stop.check()?;
    on_stage("extracting the surface");
    let (crossings, mut top) = columns(&sampled.values, &sampled.grid);
    surface_at_walls(implicit, &sampled.grid, &mut top);
    let mut mesh = surface(&sampled, stop)?;
    let caves = caves::count(&sampled.values, &sampled.grid, &top, params.sea_level());
    drop(sampled.values);
    colour(&mut mesh, implicit, params.sea_level(), voxel_m, stop)?;
    let closed = mesh.is_closed();
    stop.check()?;
    let (pieces, genus) = topology(&mesh);
    stop.check()?;
    let triangles = mesh.triangle_count();
    // Shoreline columns: the original ground within the seed elevation range.
    let e = &params.erosion;
    let (lo, hi) = (params.sea_level() + e.seed_elevation_range[0], params.sea_level() + e.seed_elevation_range[1]);
    let g = &sampled.grid;
    let (mut shore, mut overhung) = (0u64, 0u64);
    for (k, &c) in crossings.iter().enumerate() {
        let h = implicit.hf.sample((k % g.nx) as f32 * g.voxel_m, (k / g.nx) as f32 * g.voxel_m);
        if (lo..=hi).contains(&h) {
            shore += 1;
            overhung += (c > 1) as u64;
        }
    }
    let mut per_pass = vec![0u64; params.passes as usize];
    let (mut authored_before, mut authored_after) = (0u64, 0u64);
    for s in spheres {
        match s.pass() {
            0 => authored_before += 1,
            p if p > params.passes => authored_after += 1,
            p => per_pass[p as usize - 1] += 1,
        }
    }
    let (view, focus) = match close_up(&mesh, params.sea_level(), voxel_m) {
        Some((view, focus)) => (view, Some(focus)),
        None => (PREVIEW, coastline_bounds(&mesh, params.sea_level(), voxel_m)),
    };
    let scene = Scene {
        nodes: vec![
            SceneNode::new("terrain", mesh, MaterialKind::VertexColors),
            SceneNode::new("sea", sea_plane(implicit.hf, params.sea_level()), MaterialKind::Water),
        ],
    };
    on_stage(if mesh_settings.lods.is_empty() {
        "writing the mesh"
    } else {
        "writing the mesh and its levels of detail"
    });
    let carved = sea_worn(&top, implicit.hf, voxel_m);
    let ((glbs, preview), ((heightmap, npy), (r16, (normals, splat)))) = rayon::join(
        || rayon::join(|| mesh_glbs(&scene, mesh_settings, stop), || render_png_framed(&scene, &view, focus, stop)),
        || {
            rayon::join(
                || rayon::join(|| heightmap_png16(&top), || heightfield_npy(&top)),
                || {
                    rayon::join(
                        || heightmap_r16(&top),
                        || {
                            rayon::join(
                                || normalmap_png(&top),
                                || splatmap_png(&top, Some(&carved), None, params.sea_level()),
                            )
                        },
                    )
                },
            )
        },
    );
    let (glbs, glb_figures) = glbs?;
    let preview = preview?;
    let (z_min, z_max) = top.min_max();
    let result = json!({
        "sea_level_m": params.sea_level(),
        "spheres": { "total": spheres.len(), "per_pass": per_pass },
        "authored": { "before": authored_before, "after": authored_after },
        "overhangs": { "shoreline_columns": shore, "with_overhang": overhung,
                       "share": if shore == 0 { 0.0 } else { overhung as f64 / shore as f64 } },
        // Arches: the solid's genus (each arch or tunnel through the rock adds one).
        "through_holes": genus,
        "arches": genus,
        "sea_caves": caves.sea_caves,
        "covered_passages": caves.passages,
        "pieces": pieces,
        "fragments_removed": sampled.fragments,
        "air_pockets_filled": sampled.pockets,
        "mesh": { "triangles": triangles, "closed": closed },
        "voxels": { "x": g.nx, "y": g.ny, "z": g.nz, "voxel_m": g.voxel_m },
        // The topmost surface's grid, as heightfield kinds report it, so later jobs can read it.
        "grid": { "cols": top.cols, "rows": top.rows, "cell_size_m": top.cell_size_m },
        "z_min": z_min, "z_max": z_max,
        "heightmap_r16": r16_summary(&top),
        "glb": glb_figures,
    });
    let mut glbs = glbs.into_iter();
    let mut artifacts = vec![
        glbs.next().expect("mesh.glb comes first"),
        Artifact::new("preview.png", "image/png", preview),
        Artifact::new("heightmap.png", "image/png", heightmap),
        Artifact::new(HEIGHTFIELD_ARTIFACT, "application/octet-stream", npy),
        Artifact::new("heightmap.r16", "application/octet-stream", r16),
        Artifact::new("normalmap.png", "image/png", normals),
        Artifact::new("splatmap.png", "image/png", splat),
    ];
    artifacts.extend(glbs);
    Ok((result, artifacts))
}

/// Depth of cut (in voxels) over which the splat map's material goes from none to all: less
/// than half a voxel is the sampling's own error against the source terrain.
const WORN_VOXELS: (f32, f32) = (0.5, 1.5);

/// `splatmap.png`'s material for the coast: the rock the sea cut away (cliff faces, wave-cut
/// platforms, cave mouths seen from above), 0–255 by how far the topmost surface `top` lies
/// below the source terrain `source` at each sample, from [`WORN_VOXELS`] voxels.
fn sea_worn(top: &Heightfield, source: &Heightfield, voxel_m: f32) -> Vec<u8> {
    let (lo, hi) = (WORN_VOXELS.0 * voxel_m, WORN_VOXELS.1 * voxel_m);
    top.heights_m
        .par_iter()
        .enumerate()
        .map(|(k, &h)| {
            let (x, z) = ((k % top.cols) as f32 * top.cell_size_m, (k / top.cols) as f32 * top.cell_size_m);
            let t = ((source.sample(x, z) - h - lo) / (hi - lo)).clamp(0.0, 1.0);
            (t * t * (3.0 - 2.0 * t) * 255.0).round() as u8
        })
        .collect()
}

#[cfg(test)]
mod framing_tests {
    use super::*;

    #[test]
    fn the_preview_frames_what_stands_above_the_sea() {
        // Sea at 2 m, voxels 1 m: the floor at 1.9 m is left out; land from x 10–30, z 20–25.
        let positions = vec![[0.0, 1.9, 0.0], [64.0, 1.0, 64.0], [10.0, 5.0, 20.0], [30.0, 2.6, 25.0]];
        let mesh = Mesh { normals: vec![[0.0, 1.0, 0.0]; 4], uvs: vec![[0.0; 2]; 4], positions, ..Mesh::default() };
        // Footprint 20 m: a tenth is 2 m, under 3 voxels, so 3 m each side; down to the sea.
        assert_eq!(coastline_bounds(&mesh, 2.0, 1.0), Some(([7.0, 2.0, 17.0], [33.0, 5.0, 28.0])));
        assert_eq!(coastline_bounds(&mesh, 6.0, 1.0), None);
        // Nothing faces down: no close-up.
        assert!(close_up(&mesh, 2.0, 1.0).is_none());
    }

    #[test]
    fn the_close_up_looks_inland_at_the_densest_overhangs() {
        // Land from x 0–100, z 0–100 at 10 m; undersides (normals down) at 5 m: three near
        // (90, 50) on the east shore, one at (10, 10).
        let mut positions = vec![[0.0, 10.0, 0.0], [100.0, 10.0, 0.0], [0.0, 10.0, 100.0], [100.0, 10.0, 100.0]];
        let mut normals = vec![[0.0, 1.0, 0.0]; 4];
        for p in [[88.0, 5.0, 48.0], [92.0, 5.0, 52.0], [90.0, 6.0, 50.0], [10.0, 5.0, 10.0]] {
            positions.push(p);
            normals.push([1.0, -0.7, 0.0]);
        }
        let n = positions.len();
        let mesh = Mesh { positions, normals, uvs: vec![[0.0; 2]; n], ..Mesh::default() };
        let (view, (lo, hi)) = close_up(&mesh, 0.0, 1.0).expect("a close-up");
        // A third of 100 m: windows of 33.3 m; the undersides' mean is (90, 50).
        let side = 100.0 / 3.0;
        for (got, want) in [
            (lo[0], 90.0 - side / 2.0),
            (hi[0], 90.0 + side / 2.0),
            (lo[2], 50.0 - side / 2.0),
            (hi[2], 50.0 + side / 2.0),
        ] {
            assert!((got - want).abs() < 1e-3, "{lo:?} {hi:?}");
        }
        assert_eq!((lo[1], hi[1]), (0.0, 6.0), "from the sea to the window's highest land");
        // The land's vertices average (60, 45): out to sea is (30, 5) from there, so the
        // camera stands east-south-east (azimuth atan2(30, 5) ≈ 80.5°) and looks inland.
        assert!((view.azimuth_deg - 30f32.atan2(5.0).to_degrees()).abs() < 1e-3, "{}", view.azimuth_deg);
        assert_eq!(view.elevation_deg, CLOSE_UP_ELEVATION_DEG);
    }
}
