//! A heightfield kind's terrain in tiles (the request's `tiles`): `tiles/{level}/{x}_{z}.glb`
//! for level 0 (the full grid) and every level of detail, and `tiles/index.json` with each
//! tile's place and bounds.
//!
//! Tiles are rectangles of the terrain mesh's vertex grid; neighbours share their edge
//! vertices, as engines' terrain tiles do. At level 0 they hold the grid's own vertices and
//! triangles, so together they are `mesh.glb`'s mesh exactly. Each level simplifies each tile
//! on its own within the level's error bound (see [`simplify_levels_with`]):
//!
//! - without a skirt, with the tile's border held in place, so every border vertex of every
//!   level is the grid's own and the same in both tiles that share it;
//! - with `skirt_m`, with the border free to simplify along itself (corners held), so a coarse
//!   tile is not mostly border; neighbours' borders then part by up to both tiles' vertical
//!   drift ([`border_drift`]), and a wall hanging from every border edge ([`with_skirt`]), at
//!   least twice the largest drift deep, hides the gap.
//!
//! Every tile is quantised in the whole terrain's frame (its box, down to the skirts' feet),
//! so a shared vertex also decodes to the same floats in both files.

use std::borrow::Cow;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use super::glb::{write_glb_in_frame, MESHOPT_POSITION_BITS};
use super::mesh_glbs::{round_mm, round_up_mm};
use super::{short_decimal, Artifact, MeshSettings};
use crate::mesh::{
    border_drift, bottom_centre, grid_patch, simplify_levels_with, sliver_height, tile_edges, with_skirt, without_fins,
    Border, MaterialKind, Mesh, Scene, SceneNode,
};
use crate::stop::{Stop, Stopped};
use crate::validate::{Limits, Validate, Validator};

/// Most tiles along one side.
pub const MAX_TILES_PER_SIDE: u32 = 16;

/// How a heightfield's mesh is cut into tiles.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TileGrid {
    /// Tiles along X (the grid's columns) and along Z (its rows).
    pub count: [u32; 2],
    /// With a skirt, metres: each tile's border is free to simplify like its inside, and a
    /// wall at least this deep hangs from it to hide where neighbours part.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skirt_m: Option<f32>,
}

/// Deepest skirt a request may ask for, metres (deeper than any terrain's relief is useless).
pub const MAX_SKIRT_M: f32 = 10_000.0;
/// The deepest skirt on flat ground, as a share of the terrain's longest side.
const SKIRT_SHARE_ON_FLAT: f32 = 0.01;

impl utoipa::ToSchema for TileGrid {
    fn name() -> Cow<'static, str> {
        "TileGrid".into()
    }
}

/// Written out, so the counts' bounds are stated.
impl utoipa::PartialSchema for TileGrid {
    fn schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
        use utoipa::openapi::schema::{ArrayBuilder, ObjectBuilder, SchemaType, Type};
        let count = ArrayBuilder::new()
            .items(
                ObjectBuilder::new()
                    .schema_type(SchemaType::new(Type::Integer))
                    .minimum(Some(1))
                    .maximum(Some(MAX_TILES_PER_SIDE)),
            )
            .min_items(Some(2))
            .max_items(Some(2))
            .description(Some(format!(
                "Tiles along X (the grid's columns) and along Z (its rows), 1 to {MAX_TILES_PER_SIDE} each. Tile edges fall on the mesh's vertex grid (the heightfield's samples, or every stride-th where `mesh.stride` > 1), as evenly as whole cells allow; a side with fewer cells than tiles gets one tile per cell."
            )));
        ObjectBuilder::new()
            .description(Some(
                "Cut the terrain's mesh into tiles: `tiles/{level}/{x}_{z}.glb` for level 0 (the full mesh) and each level of `lods`, x counting along X and z along Z from 0, and `tiles/index.json` giving each tile's vertex range, bounds (metres) and, per level, file, vertices, triangles and measured deviation. Without `skirt_m`, neighbouring tiles share their edge vertices, bit for bit in every level and every compression form (borders are held in place when simplifying; every tile is quantised in the whole terrain's box); at level 0 the tiles together are `mesh.glb`'s mesh exactly (with skirts, less the skirts). In the `none` form every tile's node origin is one pivot, the middle of the bottom of the terrain's box (`pivot` in the index). Texture coordinates are the whole terrain's, so the maps apply to every tile as they are.",
            ))
            .property("count", count)
            .property(
                "skirt_m",
                ObjectBuilder::new()
                    .schema_type(SchemaType::new(Type::Number))
                    .exclusive_minimum(Some(0.0))
                    .maximum(Some(f64::from(MAX_SKIRT_M)))
                    .description(Some(format!(
                        "Skirts, metres (more than 0, at most {MAX_SKIRT_M}): each tile's border simplifies like its inside (vertices move only along the border, the corners stay), so a coarse tile is not mostly border, and from every border edge a vertical wall hangs down, outward-facing, as deep as this (but no deeper than the terrain's height span, or a hundredth of its longest side on flat ground) or twice the largest vertical gap any level's border has from the full grid, whichever is more (so tiles at any two levels side by side show no crack); `tiles/index.json` states the depth used (`skirt_m`) and each tile level's `border_drift_m`. Without it, borders are held in place at every level and neighbours meet exactly."
                    ))),
            )
            .required("count")
            .examples([json!({ "count": [4, 4] }), json!({ "count": [4, 4], "skirt_m": 2.0 })])
            .into()
    }
}

impl Validate for TileGrid {
    fn validate(&self, v: &mut Validator, _limits: &Limits) {
        if self.count.iter().any(|c| !(1..=MAX_TILES_PER_SIDE).contains(c)) {
            v.error("count", format!("each count must be from 1 to {MAX_TILES_PER_SIDE}"));
        }
        if let Some(skirt) = self.skirt_m {
            if !(skirt > 0.0 && skirt <= MAX_SKIRT_M) {
                v.error("skirt_m", format!("must be more than 0 and at most {MAX_SKIRT_M} m"));
            }
        }
    }
}

/// One tile at every level: its meshes, then its glbs, and its figures.
struct Tile {
    x: usize,
    z: usize,
    first: [usize; 2],
    last: [usize; 2],
    bounds: ([f32; 3], [f32; 3]),
    meshes: Vec<Mesh>,
    files: Vec<Vec<u8>>,
    /// Per level: vertices, triangles, measured deviation and border drift (metres); the
    /// counts are the surface's, without a skirt.
    figures: Vec<(usize, usize, f32, f32)>,
}

/// The tiles of `grid`, a heightfield's grid mesh of `vertices[0] × vertices[1]` vertices row
/// by row, at level 0 and at each of `settings.lods` (fractions of `longest_m`, the scene's
/// longest side, as `mesh_lodN.glb`'s). Returns the glbs level by level, each level's row by
/// row, then `tiles/index.json`; and the result's summary.
pub fn tile_artifacts(
    grid: &Mesh,
    vertices: [usize; 2],
    tiles: TileGrid,
    settings: &MeshSettings,
    longest_m: f64,
    stop: Stop,
) -> Result<(Vec<Artifact>, Value), Stopped> {
    let terrain_box = grid.bounds().unwrap_or_default();
    let xs = tile_edges(vertices[0], tiles.count[0] as usize);
    let zs = tile_edges(vertices[1], tiles.count[1] as usize);
    let places: Vec<(usize, usize)> = (0..zs.len() - 1).flat_map(|z| (0..xs.len() - 1).map(move |x| (x, z))).collect();
    let bounds_m: Vec<f32> = settings.lods.iter().map(|f| (f * longest_m) as f32).collect();
    // With a skirt a tile's border simplifies too, and the skirt hides the gaps.
    let border = if tiles.skirt_m.is_some() { Border::Free } else { Border::Shared };
    let sliver = sliver_height(longest_m, MESHOPT_POSITION_BITS);
    // Every tile is quantised in the whole terrain's box, reaching down to the skirts' feet,
    // and has one pivot, the middle of the bottom of the terrain's box: a vertex two tiles
    // share decodes to the same floats in both, and every tile drops in place with one origin.
    let pivot = bottom_centre(terrain_box.0, terrain_box.1);
    let frame_of = |skirt_m: Option<f32>| {
        ([terrain_box.0[0], terrain_box.0[1] - skirt_m.unwrap_or(0.0), terrain_box.0[2]], terrain_box.1)
    };
    let write = |mesh: Mesh, skirt_m: Option<f32>| {
        let frame = frame_of(skirt_m);
        let mesh = match skirt_m {
            Some(depth) => with_skirt(&mesh, depth),
            None => mesh,
        };
        let node = SceneNode::new("terrain", mesh, MaterialKind::default()).with_pivot(pivot);
        write_glb_in_frame(&Scene { nodes: vec![node] }, settings.form, Some(frame))
    };
    let mut made: Vec<Tile> = places
        .par_iter()
        .map(|&(x, z)| {
            let (first, last) = ([xs[x], zs[z]], [xs[x + 1], zs[z + 1]]);
            let full = grid_patch(grid, vertices[0], first[0]..=last[0], first[1]..=last[1]);
            let bounds = full.bounds().unwrap_or_default();
            let mut levels = simplify_levels_with(&full, &bounds_m, border, sliver, stop)?;
            if border == Border::Free {
                // Dropping a fin leaves the surface as it was seen from above, within the bound.
                levels.iter_mut().for_each(|l| l.mesh = without_fins(&l.mesh, bounds));
            }
            let mut figures = vec![(full.vertex_count(), full.triangle_count(), 0.0, 0.0)];
            figures.extend(levels.iter().map(|l| {
                (l.mesh.vertex_count(), l.mesh.triangle_count(), l.deviation_m, border_drift(&full, &l.mesh))
            }));
            let mut meshes = vec![full];
            meshes.extend(levels.into_iter().map(|l| l.mesh));
            // Without a skirt a tile is written at once; a skirt's depth waits for every tile.
            let (meshes, files) = match tiles.skirt_m {
                Some(_) => (meshes, Vec::new()),
                None => (Vec::new(), meshes.into_iter().map(|m| write(m, None)).collect()),
            };
            Ok(Tile { x, z, first, last, bounds, meshes, files, figures })
        })
        .collect::<Result<_, Stopped>>()?;
    // A skirt deep enough for the widest gap two tiles can open, at any two levels side by
    // side: twice the largest drift of any border. Deeper than the terrain's height span (or a
    // hundredth of its longest side, on flat ground) hides nothing more, and would stretch the
    // quantised forms' frame: every tile's step grows with it.
    let drift = made.iter().flat_map(|t| t.figures.iter().map(|f| f.3)).fold(0.0f32, f32::max);
    let deepest = (terrain_box.1[1] - terrain_box.0[1]).max(longest_m as f32 * SKIRT_SHARE_ON_FLAT);
    let skirt_m = tiles.skirt_m.map(|s| s.min(deepest).max(2.0 * drift));
    if skirt_m.is_some() {
        made.par_iter_mut().for_each(|t| {
            t.files = std::mem::take(&mut t.meshes).into_iter().map(|mesh| write(mesh, skirt_m)).collect();
        });
    }

    let file = |level: usize, t: &Tile| format!("tiles/{level}/{}_{}.glb", t.x, t.z);
    let level_count = bounds_m.len() + 1;
    let mut artifacts = Vec::with_capacity(made.len() * level_count + 1);
    for level in 0..level_count {
        for t in &mut made {
            let bytes = std::mem::take(&mut t.files[level]);
            artifacts.push(Artifact::new(&file(level, t), "model/gltf-binary", bytes));
        }
    }
    let corner = |p: [f32; 3]| p.map(short_decimal).to_vec();
    let index_tiles: Vec<Value> = made
        .iter()
        .map(|t| {
            let levels: Vec<Value> = (0..level_count)
                .map(|level| {
                    let (vertices, triangles, deviation, drift) = t.figures[level];
                    json!({
                        "file": file(level, t),
                        "vertices": vertices,
                        "triangles": triangles,
                        "max_deviation_m": round_up_mm(f64::from(deviation)),
                        "border_drift_m": round_up_mm(f64::from(drift)),
                    })
                })
                .collect();
            json!({
                "x": t.x,
                "z": t.z,
                "first_vertex": t.first,
                "last_vertex": t.last,
                "bounds": { "min": corner(t.bounds.0), "max": corner(t.bounds.1) },
                "levels": levels,
            })
        })
        .collect();
    let summary_levels: Vec<Value> = (0..level_count)
        .map(|level| {
            let worst = made.iter().map(|t| f64::from(t.figures[level].2)).fold(0.0, f64::max);
            json!({
                "level": level,
                "error_bound_m": if level == 0 { 0.0 } else { round_mm(f64::from(bounds_m[level - 1])) },
                "max_deviation_m": round_up_mm(worst),
                "triangles": made.iter().map(|t| t.figures[level].1).sum::<usize>(),
            })
        })
        .collect();
    let count = [xs.len() - 1, zs.len() - 1];
    let frame = frame_of(skirt_m);
    let index = json!({
        "count": count,
        "vertices": vertices,
        "form": settings.form.name(),
        "frame": { "min": corner(frame.0), "max": corner(frame.1) },
        "pivot": corner(pivot),
        "skirt_m": skirt_m.map(|d| round_up_mm(f64::from(d))),
        "levels": summary_levels,
        "tiles": index_tiles,
    });
    let index_bytes = serde_json::to_vec_pretty(&index).expect("the index serialises");
    artifacts.push(Artifact::new(INDEX, "application/json", index_bytes));
    let summary = json!({ "index": INDEX, "count": count, "files": artifacts.len() - 1, "levels": summary_levels });
    Ok((artifacts, summary))
}

/// The tiles' index artifact.
pub const INDEX: &str = "tiles/index.json";
