//! Tiles as a game engine streams them: a bulldozed hillside cut into 3 × 2 tiles with three
//! levels of detail, run by the real binary in each compression form. Neighbouring tiles must
//! hold the same edge vertices bit for bit at every level (positions, normals, texcoords,
//! colours, as stored in the files), every level must keep all of level 0's edge vertices, and
//! the tiles of level 0 together must be `mesh.glb`'s triangles exactly (checked on the stored
//! bytes of the `none` and `quantize` forms). The Khronos validator finds no error in any tile,
//! and three.js loads the compressed ones with the counts the index states.
//!
//! Needs `npm ci --prefix tests/gltf-validator` first (as tests/glb_valid.rs does).

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use common::cli::{example_body, load_in_three, run_job, three_counts};
use common::gltf_validator::validate_glb;
use serde_json::{json, Value};

const LODS: [f64; 3] = [0.002, 0.008, 0.032];

/// `api/bulldoze/hillside-road.json` in `form`, cut into 3 × 2 tiles, run into `out`: the
/// job's result.
fn run(form: &str, out: &Path) -> Value {
    let mut body = example_body("bulldoze", "hillside-road");
    body["compression"] = form.into();
    body["lods"] = json!(LODS);
    body["tiles"] = json!({ "count": [3, 2] });
    run_job("bulldoze", &body, out).unwrap_or_else(|| panic!("hillside-road in form {form}"))["result"].clone()
}

/// One vertex as the file stores it: the bytes of each of its attributes, position first.
type Stored = Vec<Vec<u8>>;

/// A glb's one mesh as stored: the node's transform (bits), its vertices and its triangles.
struct Read {
    transform: Vec<u32>,
    vertices: Vec<Stored>,
    /// Each vertex's position in metres (the node's transform applied), for finding edges.
    metres: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
}

fn read(path: &Path) -> Read {
    let bytes = std::fs::read(path).unwrap();
    let gltf = gltf::Gltf::from_slice_without_validation(&bytes).expect("glb parses");
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    let node = gltf.nodes().find(|n| n.mesh().is_some()).expect("a node with a mesh");
    let (translation, _, scale) = node.transform().decomposed();
    let prim = node.mesh().unwrap().primitives().next().unwrap();
    let raw = |accessor: gltf::Accessor| -> Vec<Vec<u8>> {
        let view = accessor.view().expect("a buffer view");
        let size = accessor.size();
        let stride = view.stride().unwrap_or(size);
        let start = view.offset() + accessor.offset();
        (0..accessor.count()).map(|i| blob[start + i * stride..start + i * stride + size].to_vec()).collect()
    };
    let mut attributes: Vec<(String, gltf::Accessor)> =
        prim.attributes().map(|(semantic, a)| (semantic.to_string(), a)).collect();
    attributes.sort_by_key(|(s, _)| if s == "POSITION" { String::new() } else { s.clone() });
    let position = attributes[0].1.clone();
    let columns: Vec<Vec<Vec<u8>>> = attributes.into_iter().map(|(_, a)| raw(a)).collect();
    let n = columns[0].len();
    let vertices: Vec<Stored> = (0..n).map(|i| columns.iter().map(|c| c[i].clone()).collect()).collect();
    let metres = columns[0]
        .iter()
        .map(|p| {
            let q: [f64; 3] = match position.data_type() {
                gltf::accessor::DataType::F32 => {
                    std::array::from_fn(|k| f64::from(f32::from_le_bytes(p[4 * k..4 * k + 4].try_into().unwrap())))
                }
                gltf::accessor::DataType::U16 => {
                    std::array::from_fn(|k| f64::from(u16::from_le_bytes(p[2 * k..2 * k + 2].try_into().unwrap())))
                }
                other => panic!("positions as {other:?}"),
            };
            std::array::from_fn(|k| f64::from(translation[k]) + f64::from(scale[k]) * q[k])
        })
        .collect();
    let indices: Vec<u32> = prim.reader(|_| Some(blob)).read_indices().unwrap().into_u32().collect();
    let transform = translation.iter().chain(&scale).map(|v| v.to_bits()).collect();
    Read { transform, vertices, metres, triangles: indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect() }
}

/// The stored vertices of `tile` on the side where coordinate `axis` is lowest or highest.
fn side(tile: &Read, axis: usize, highest: bool) -> BTreeSet<Stored> {
    let values = tile.metres.iter().map(|p| p[axis]);
    let edge = if highest { values.fold(f64::MIN, f64::max) } else { values.fold(f64::MAX, f64::min) };
    tile.vertices.iter().zip(&tile.metres).filter(|(_, p)| p[axis] == edge).map(|(v, _)| v.clone()).collect()
}

/// Every triangle as its corners' stored positions, starting from the least, in turn.
fn triangle_set(mesh: &Read) -> BTreeMap<[Vec<u8>; 3], usize> {
    let mut out = BTreeMap::new();
    for t in &mesh.triangles {
        let corners = t.map(|i| mesh.vertices[i as usize][0].clone());
        let first = (0..3).min_by_key(|&k| corners[k].clone()).unwrap();
        let turned = std::array::from_fn(|k| corners[(first + k) % 3].clone());
        *out.entry(turned).or_insert(0) += 1;
    }
    out
}

fn check_form(form: &str) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join(form);
    let result = run(form, &out);
    let tiles = &result["tiles"];
    assert_eq!(tiles["count"], json!([3, 2]), "{tiles}");
    let index: Value = serde_json::from_slice(&std::fs::read(out.join("tiles/index.json")).unwrap()).unwrap();
    // The same figures (one may write 0 where the other writes 0.0).
    let numbers = |v: &Value| -> Vec<Vec<f64>> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|l| l.as_object().unwrap().values().map(|n| n.as_f64().unwrap()).collect())
            .collect()
    };
    assert_eq!(numbers(&index["levels"]), numbers(&tiles["levels"]));
    assert_eq!(index["form"], form);
    let levels = index["levels"].as_array().unwrap();
    assert_eq!(levels.len(), 1 + LODS.len());
    for level in levels {
        let (bound, worst) = (level["error_bound_m"].as_f64().unwrap(), level["max_deviation_m"].as_f64().unwrap());
        assert!(worst <= bound, "{form}: level {level}");
    }
    let entries = index["tiles"].as_array().unwrap();
    assert_eq!(entries.len(), 6);
    // tiles[level][(x, z)]
    let mut by_level: Vec<BTreeMap<(u64, u64), Read>> = (0..levels.len()).map(|_| BTreeMap::new()).collect();
    let mut transform = None;
    for entry in entries {
        let place = (entry["x"].as_u64().unwrap(), entry["z"].as_u64().unwrap());
        for (level, figures) in entry["levels"].as_array().unwrap().iter().enumerate() {
            let file = out.join(figures["file"].as_str().unwrap());
            assert_eq!(figures["file"], format!("tiles/{level}/{}_{}.glb", place.0, place.1));
            let report = validate_glb(&std::fs::read(&file).unwrap());
            assert_eq!(report.errors, 0, "{form} {file:?}: {}", report.summary());
            if form == "meshopt" {
                // The glTF crate does not decode compressed views: three.js does, below.
                continue;
            }
            let tile = read(&file);
            assert_eq!(tile.vertices.len() as u64, figures["vertices"].as_u64().unwrap(), "{file:?}");
            assert_eq!(tile.triangles.len() as u64, figures["triangles"].as_u64().unwrap(), "{file:?}");
            // One frame for every tile: shared bytes decode to the same floats.
            assert_eq!(*transform.get_or_insert(tile.transform.clone()), tile.transform, "{file:?}");
            by_level[level].insert(place, tile);
        }
    }
    if form == "meshopt" {
        check_in_three(&out, entries);
        return;
    }
    for (level, tiles) in by_level.iter().enumerate() {
        for (&(x, z), tile) in tiles {
            // X runs along the columns (axis 0), Z along the rows (axis 2).
            for (axis, neighbour) in [(0, (x + 1, z)), (2, (x, z + 1))] {
                let Some(other) = tiles.get(&neighbour) else { continue };
                let (mine, theirs) = (side(tile, axis, true), side(other, axis, false));
                assert!(mine.len() > 2, "{form} level {level} tile {x}_{z}: an edge of {} vertices", mine.len());
                assert_eq!(mine, theirs, "{form} level {level}: tiles {x}_{z} and {neighbour:?} differ on their edge");
                let full = side(&by_level[0][&(x, z)], axis, true);
                assert_eq!(mine, full, "{form} level {level} tile {x}_{z}: the edge lost vertices");
            }
        }
        if level + 1 < by_level.len() {
            let count = |l: &BTreeMap<_, Read>| l.values().map(|t| t.triangles.len()).sum::<usize>();
            assert!(count(&by_level[level + 1]) <= count(tiles), "{form}: level {} has more triangles", level + 1);
        }
    }
    // Level 0 reassembles into mesh.glb: the same triangles, each once.
    let whole = triangle_set(&read(&out.join("mesh.glb")));
    let mut together = BTreeMap::new();
    for tile in by_level[0].values() {
        for (t, n) in triangle_set(tile) {
            *together.entry(t).or_insert(0) += n;
        }
    }
    assert_eq!(together.len(), whole.len(), "{form}: triangles of the tiles against mesh.glb's");
    assert!(together == whole, "{form}: the tiles at level 0 are not mesh.glb's mesh");
}

/// three.js (with `MeshoptDecoder`) builds from every tile file the counts the index states.
fn check_in_three(out: &Path, entries: &[Value]) {
    let levels = |e: &Value| e["levels"].as_array().unwrap().clone();
    let files: Vec<PathBuf> =
        entries.iter().flat_map(|e| levels(e).into_iter().map(|l| out.join(l["file"].as_str().unwrap()))).collect();
    let expected: Vec<(u64, u64)> = entries
        .iter()
        .flat_map(|e| {
            levels(e).into_iter().map(|l| (l["vertices"].as_u64().unwrap(), l["triangles"].as_u64().unwrap()))
        })
        .collect();
    assert_eq!(
        load_in_three(&files).iter().map(three_counts).collect::<Vec<_>>(),
        expected,
        "three.js's counts against the index"
    );
}

#[test]
fn float_tiles_meet_and_reassemble() {
    check_form("none");
}

#[test]
fn quantized_tiles_meet_and_reassemble() {
    check_form("quantize");
}

/// The compressed form holds the quantised form's data (the edges are checked there).
#[test]
fn compressed_tiles_load_in_three_js() {
    check_form("meshopt");
}

/// The service serves every tile under its folder name, with the sha256 the job lists, and the
/// index names the files the job has.
#[tokio::test]
async fn the_service_serves_tiles_by_their_folder_names() {
    use sha2::Digest;
    let server = common::server::TestServer::start().await;
    let mut body = common::bodies::small_bulldoze();
    body["tiles"] = json!({ "count": [2, 2] });
    body["lods"] = json!([0.01]);
    let job = server.run("bulldoze", &body).await;
    assert_eq!(job["status"], "succeeded", "{job}");
    let listed: BTreeMap<String, String> = common::server::artifact_hashes(&job).into_iter().collect();
    let index: Value =
        serde_json::from_slice(&server.artifact(job["id"].as_str().unwrap(), "tiles/index.json").await).unwrap();
    let files: Vec<&str> = index["tiles"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|t| t["levels"].as_array().unwrap().iter().map(|l| l["file"].as_str().unwrap()))
        .collect();
    assert_eq!(files.len(), 2 * 2 * 2);
    for file in files {
        let bytes = server.artifact(job["id"].as_str().unwrap(), file).await;
        assert_eq!(Some(&format!("{:x}", sha2::Sha256::digest(&bytes))), listed.get(file), "{file}");
    }
}

/// A triangle as its corners' positions in metres.
type Corners = [[f64; 3]; 3];

/// A tile's triangles split into its surface and its skirt (the walls standing on the sides of
/// the tile's box seen from above: every corner on one side), each as corner positions in
/// metres.
fn surface_and_skirt(tile: &Read) -> (Vec<Corners>, Vec<Corners>) {
    let (lo, hi) = tile.metres.iter().fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
        (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
    });
    let corners = |t: &[u32; 3]| t.map(|i| tile.metres[i as usize]);
    tile.triangles.iter().map(corners).partition(|t| {
        ![(0, lo[0]), (0, hi[0]), (2, lo[2]), (2, hi[2])].iter().any(|&(k, at)| t.iter().all(|p| p[k] == at))
    })
}

/// The surface's border along the tile side where coordinate `axis` is `at`: (position along
/// it, height) of the surface's vertices there, in order.
fn border_profile(surface: &[Corners], axis: usize, at: f64) -> Vec<(f64, f64)> {
    let along = 2 - axis;
    let mut out: Vec<(f64, f64)> =
        surface.iter().flatten().filter(|p| (p[axis] - at).abs() < 1e-6).map(|p| (p[along], p[1])).collect();
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-9);
    out
}

/// The height of a border profile at `u`, linear between its vertices.
fn height_at(profile: &[(f64, f64)], u: f64) -> f64 {
    let k = profile.partition_point(|p| p.0 < u - 1e-9).min(profile.len() - 1);
    if k == 0 || (profile[k].0 - u).abs() < 1e-9 {
        return profile[k].1;
    }
    let ((u0, h0), (u1, h1)) = (profile[k - 1], profile[k]);
    h0 + (h1 - h0) * (u - u0) / (u1 - u0)
}

/// With `skirt_m`, coarse tiles are not mostly border, and the skirts hide every gap between
/// neighbours at any two levels side by side: measured at every full-grid vertex along each
/// shared side against the depth the index states; level 0 less its skirts is `mesh.glb`.
#[test]
fn skirted_tiles_simplify_their_borders_and_their_skirts_cover_every_gap() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("skirted");
    let mut body = example_body("bulldoze", "hillside-road");
    body["lods"] = json!(LODS);
    body["tiles"] = json!({ "count": [2, 2], "skirt_m": 0.25 });
    run_job("bulldoze", &body, &out).expect("hillside-road with skirts");
    let index: Value = serde_json::from_slice(&std::fs::read(out.join("tiles/index.json")).unwrap()).unwrap();
    let depth = index["skirt_m"].as_f64().expect("the skirt's depth");
    let entries = index["tiles"].as_array().unwrap();
    let drift = entries
        .iter()
        .flat_map(|e| e["levels"].as_array().unwrap().iter().map(|l| l["border_drift_m"].as_f64().unwrap()))
        .fold(0.0, f64::max);
    assert!(depth >= 0.25 && depth >= 2.0 * drift - 1e-3, "skirt {depth} m, largest drift {drift} m");
    // tiles[(x, z)][level] = (surface, skirt)
    let mut tiles: BTreeMap<(u64, u64), Vec<_>> = BTreeMap::new();
    for entry in entries {
        let place = (entry["x"].as_u64().unwrap(), entry["z"].as_u64().unwrap());
        for figures in entry["levels"].as_array().unwrap() {
            let file = out.join(figures["file"].as_str().unwrap());
            let report = validate_glb(&std::fs::read(&file).unwrap());
            assert_eq!(report.errors, 0, "{file:?}: {}", report.summary());
            let (surface, skirt) = surface_and_skirt(&read(&file));
            assert_eq!(surface.len() as u64, figures["triangles"].as_u64().unwrap(), "{file:?}");
            // Two skirt triangles per border edge of the surface, each `depth` tall.
            let mut edges: BTreeMap<[u64; 6], usize> = BTreeMap::new();
            for t in &surface {
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    let (a, b) = if a < b { (a, b) } else { (b, a) };
                    let key: [u64; 6] = std::array::from_fn(|i| if i < 3 { a[i] } else { b[i - 3] }.to_bits());
                    *edges.entry(key).or_insert(0) += 1;
                }
            }
            let border = edges.values().filter(|&&n| n == 1).count();
            assert_eq!(skirt.len(), 2 * border, "{file:?}");
            for t in &skirt {
                let (lo, hi) = t.iter().fold((f64::MAX, f64::MIN), |(l, h), p| (l.min(p[1]), h.max(p[1])));
                assert!(hi - lo >= depth - 1e-3, "{file:?}: a wall {} m tall", hi - lo);
            }
            tiles.entry(place).or_default().push(surface);
        }
    }
    for (&(x, z), levels) in &tiles {
        let (lo, hi) = levels[0].iter().flatten().fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
            (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
        });
        // Coarse levels are not mostly border: at most a quarter of a level's vertices lie on
        // its border once it has 256 or more (held borders kept all 512 of this tile's at every
        // level, 80–94 % of a level-3 tile); below that, where even an even grid of n vertices
        // has 4 (√n − 1) of them on its border, at most 1.5 times that share.
        for (level, surface) in levels.iter().enumerate().skip(1) {
            let vertices: BTreeSet<[u64; 3]> = surface.iter().flatten().map(|p| p.map(f64::to_bits)).collect();
            let on_border = vertices
                .iter()
                .filter(|p| {
                    let p = p.map(f64::from_bits);
                    [(0, lo[0]), (0, hi[0]), (2, lo[2]), (2, hi[2])].iter().any(|&(k, v)| p[k] == v)
                })
                .count();
            let n = vertices.len() as f64;
            let allowed = if n >= 256.0 { 0.25 } else { 1.5 * 4.0 * (n.sqrt() - 1.0) / n };
            println!("tile {x}_{z} level {level}: {on_border} of {n} vertices on the border");
            assert!(
                on_border as f64 <= allowed * n,
                "tile {x}_{z} level {level}: {on_border} of {n} vertices on its border"
            );
        }
        // Each shared side: at every vertex of the full grid along it, the gap between this
        // tile's border and its neighbour's, at any two levels, is within the skirt.
        for (axis, neighbour) in [(0, (x + 1, z)), (2, (x, z + 1))] {
            let Some(other) = tiles.get(&neighbour) else { continue };
            let at = hi[axis];
            let grid: Vec<f64> = border_profile(&levels[0], axis, at).iter().map(|p| p.0).collect();
            assert!(grid.len() > 10, "tile {x}_{z}: {} grid vertices along its side", grid.len());
            for (a, mine) in levels.iter().enumerate() {
                for (b, theirs) in other.iter().enumerate() {
                    let (p, q) = (border_profile(mine, axis, at), border_profile(theirs, axis, at));
                    let gap = grid.iter().map(|&u| (height_at(&p, u) - height_at(&q, u)).abs()).fold(0.0, f64::max);
                    assert!(gap <= depth + 1e-4, "tiles {x}_{z} level {a} and {neighbour:?} level {b}: a {gap} m gap");
                }
            }
        }
    }
    // Level 0 less its skirts is mesh.glb's surface, triangle for triangle.
    let key = |t: &Corners| {
        let mut c = t.map(|p| p.map(|v| (v * 1e4).round() as i64));
        c.sort();
        c
    };
    let whole: BTreeSet<_> = surface_and_skirt(&read(&out.join("mesh.glb"))).0.iter().map(key).collect();
    let together: BTreeSet<_> = tiles.values().flat_map(|l| l[0].iter().map(key)).collect();
    assert_eq!(together.len(), tiles.values().map(|l| l[0].len()).sum::<usize>(), "no triangle in two tiles");
    assert!(together == whole, "the tiles at level 0 less their skirts are not mesh.glb's mesh");
}

/// A skirt asked deeper than the terrain's relief is as deep as its height span, in the
/// quantised form too: the frame (and so every tile's quantisation step) stays the terrain's
/// size, every wall is that deep, and the tiles' surfaces decode to the float form's within a
/// step.
#[test]
fn a_deep_skirt_stops_at_the_terrains_height_in_the_quantised_form() {
    let dir = tempfile::tempdir().unwrap();
    let mut body = example_body("bulldoze", "hillside-road");
    body["lods"] = json!([0.01]);
    body["tiles"] = json!({ "count": [2, 1], "skirt_m": 10000.0 });
    let outputs: Vec<(Value, PathBuf)> = ["none", "quantize"]
        .iter()
        .map(|form| {
            let out = dir.path().join(form);
            let mut body = body.clone();
            body["compression"] = json!(form);
            run_job("bulldoze", &body, &out).expect("hillside-road with a deep skirt");
            (serde_json::from_slice(&std::fs::read(out.join("tiles/index.json")).unwrap()).unwrap(), out)
        })
        .collect();
    let mesh = read(&outputs[0].1.join("mesh.glb"));
    let (low, high) = mesh.metres.iter().fold((f64::MAX, f64::MIN), |(l, h), p| (l.min(p[1]), h.max(p[1])));
    let span = high - low;
    assert!(span > 1.0, "hillside-road rises {span} m");
    for (index, out) in &outputs {
        let depth = index["skirt_m"].as_f64().unwrap();
        assert!((depth - span).abs() < 1e-2, "skirt {depth} m on a terrain {span} m high");
        let frame_height = index["frame"]["max"][1].as_f64().unwrap() - index["frame"]["min"][1].as_f64().unwrap();
        assert!((frame_height - (span + depth)).abs() < 1e-2, "frame {frame_height} m high");
        for entry in index["tiles"].as_array().unwrap() {
            for figures in entry["levels"].as_array().unwrap() {
                let file = out.join(figures["file"].as_str().unwrap());
                let (surface, skirt) = surface_and_skirt(&read(&file));
                assert_eq!(surface.len() as u64, figures["triangles"].as_u64().unwrap(), "{file:?}");
                assert!(!skirt.is_empty(), "{file:?}");
                for t in &skirt {
                    let (lo, hi) = t.iter().fold((f64::MAX, f64::MIN), |(l, h), p| (l.min(p[1]), h.max(p[1])));
                    assert!(hi - lo >= depth - 1e-2 && lo >= low - depth - 1e-2, "{file:?}: a wall {lo}..{hi}");
                }
            }
        }
    }
    // The quantised tiles' surfaces are the float tiles', within a step of the frame's longest
    // side (16 bits).
    let frame = &outputs[1].0["frame"];
    let longest =
        (0..3).map(|k| frame["max"][k].as_f64().unwrap() - frame["min"][k].as_f64().unwrap()).fold(0.0, f64::max);
    let step = longest / 65535.0 + 1e-6;
    for entry in outputs[0].0["tiles"].as_array().unwrap() {
        for figures in entry["levels"].as_array().unwrap() {
            let file = figures["file"].as_str().unwrap();
            let (float, _) = surface_and_skirt(&read(&outputs[0].1.join(file)));
            let (quantised, _) = surface_and_skirt(&read(&outputs[1].1.join(file)));
            assert_eq!(float.len(), quantised.len(), "{file}");
            for (a, b) in float.iter().flatten().zip(quantised.iter().flatten()) {
                assert!((0..3).all(|k| (a[k] - b[k]).abs() <= step), "{file}: {a:?} and {b:?}");
            }
        }
    }
}
