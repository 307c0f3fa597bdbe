//! A heightfield kind's terrain in tiles (the request's `tiles`): `tiles/{level}/{x}_{z}.glb`
//! for level 0 (the full grid) and every level of detail, and `tiles/index.json` with each
//! tile's place and bounds.
//!
//! Tiles are rectangles of the terrain mesh's vertex grid; neighbours share their edge
//! vertices, as engines' terrain tiles do (no skirts). At level 0 they hold the grid's own
//! vertices and triangles, so together they are `mesh.glb`'s mesh exactly. Each level
//! simplifies each tile on its own within the level's error bound with the tile's border held
//! in place (see [`simplify_levels`]), so every border vertex of every level is the grid's own
//! and the same in both tiles that share it. Every tile is quantised in the whole terrain's
//! frame (its box), so a shared vertex also decodes to the same floats in both files.

use std::borrow::Cow;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use super::glb::write_glb_in_frame;
use super::mesh_glbs::{round_mm, round_up_mm};
use super::{short_decimal, Artifact, MeshSettings};
use crate::mesh::{grid_patch, simplify_levels, tile_edges, Mesh, Scene};
use crate::stop::{Stop, Stopped};
use crate::validate::{Limits, Validate, Validator};

/// Most tiles along one side.
pub const MAX_TILES_PER_SIDE: u32 = 16;

/// How a heightfield's mesh is cut into tiles.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TileGrid {
    /// Tiles along X (the grid's columns) and along Z (its rows).
    pub count: [u32; 2],
}

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
                "Cut the terrain's mesh into tiles: `tiles/{level}/{x}_{z}.glb` for level 0 (the full mesh) and each level of `lods`, x counting along X and z along Z from 0, and `tiles/index.json` giving each tile's vertex range, bounds (metres) and, per level, file, vertices, triangles and measured deviation. Neighbouring tiles share their edge vertices, bit for bit in every level and every compression form (borders are held in place when simplifying; every tile is quantised in the whole terrain's box); at level 0 the tiles together are `mesh.glb`'s mesh exactly. Texture coordinates are the whole terrain's, so the maps apply to every tile as they are.",
            ))
            .property("count", count)
            .required("count")
            .examples([json!({ "count": [4, 4] })])
            .into()
    }
}

impl Validate for TileGrid {
    fn validate(&self, v: &mut Validator, _limits: &Limits) {
        if self.count.iter().any(|c| !(1..=MAX_TILES_PER_SIDE).contains(c)) {
            v.error("count", format!("each count must be from 1 to {MAX_TILES_PER_SIDE}"));
        }
    }
}

/// One tile at every level: its glbs and its figures.
struct Tile {
    x: usize,
    z: usize,
    first: [usize; 2],
    last: [usize; 2],
    bounds: ([f32; 3], [f32; 3]),
    files: Vec<Vec<u8>>,
    /// Per level: vertices, triangles, measured deviation (metres).
    figures: Vec<(usize, usize, f32)>,
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
    let frame = grid.bounds().unwrap_or_default();
    let xs = tile_edges(vertices[0], tiles.count[0] as usize);
    let zs = tile_edges(vertices[1], tiles.count[1] as usize);
    let places: Vec<(usize, usize)> = (0..zs.len() - 1).flat_map(|z| (0..xs.len() - 1).map(move |x| (x, z))).collect();
    let bounds_m: Vec<f32> = settings.lods.iter().map(|f| (f * longest_m) as f32).collect();
    let write = |mesh: Mesh| write_glb_in_frame(&Scene::single("terrain", mesh), settings.form, Some(frame));
    let mut made: Vec<Tile> = places
        .par_iter()
        .map(|&(x, z)| {
            let (first, last) = ([xs[x], zs[z]], [xs[x + 1], zs[z + 1]]);
            let full = grid_patch(grid, vertices[0], first[0]..=last[0], first[1]..=last[1]);
            let bounds = full.bounds().unwrap_or_default();
            let levels: Vec<(Mesh, f32)> =
                simplify_levels(&full, &bounds_m, stop)?.into_iter().map(|lod| (lod.mesh, lod.deviation_m)).collect();
            let mut figures = vec![(full.vertex_count(), full.triangle_count(), 0.0)];
            figures.extend(levels.iter().map(|(m, d)| (m.vertex_count(), m.triangle_count(), *d)));
            let mut files = vec![write(full)];
            files.extend(levels.into_iter().map(|(m, _)| write(m)));
            Ok(Tile { x, z, first, last, bounds, files, figures })
        })
        .collect::<Result<_, Stopped>>()?;

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
                    let (vertices, triangles, deviation) = t.figures[level];
                    json!({
                        "file": file(level, t),
                        "vertices": vertices,
                        "triangles": triangles,
                        "max_deviation_m": round_up_mm(f64::from(deviation)),
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
    let index = json!({
        "count": count,
        "vertices": vertices,
        "form": settings.form.name(),
        "frame": { "min": corner(frame.0), "max": corner(frame.1) },
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
