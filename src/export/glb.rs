//! Binary glTF 2.0 (`.glb`) from a [`Scene`]: the mesh format every kind delivers.
//!
//! glTF is Y-up, right-handed, in metres, counter-clockwise front faces: our conventions, so
//! positions go out as they are. One buffer holds, per node, separate (non-interleaved)
//! position, normal, texcoord, optional colour and index views, each starting on a 4-byte
//! boundary. Indices are u16 while every index fits below the primitive-restart value 65535,
//! else u32. Output bytes depend only on the scene.

use std::borrow::Cow;

use gltf::json;
use json::validation::{Checked::Valid, USize64};
use rayon::prelude::*;

use super::srgb::{srgb_to_linear, srgb_to_linear_u8};
use crate::mesh::{MaterialKind, Mesh, Scene};

/// Most vertices a mesh may have and still use u16 indices (65535 itself means "restart").
pub const MAX_U16_INDEXED_VERTICES: usize = 65_535;

/// Encode a scene as a glb. Nodes keep their order and names; a node whose mesh has no
/// triangles is written as an empty node. Normals are renormalised on the way out (the format
/// requires unit length), with +Y standing in for a zero normal.
///
/// # Panics
/// If a mesh fails [`Mesh::check`] (mismatched arrays or out-of-range indices) or the file
/// would exceed glb's 4 GiB limit: both are bugs in the caller.
pub fn write_glb(scene: &Scene) -> Vec<u8> {
    let mut root = json::Root {
        asset: json::Asset { generator: Some("Landform".into()), ..Default::default() },
        ..Default::default()
    };
    let mut materials: Vec<(MaterialKind, bool)> = Vec::new();
    let mut layouts = Vec::new();
    let mut offset = 0usize;

    let mut node_indices = Vec::with_capacity(scene.nodes.len());
    for node in &scene.nodes {
        let mesh = &node.mesh;
        if let Err(e) = mesh.check() {
            panic!("mesh of node {:?} is malformed: {e}", node.name);
        }
        let mut gltf_node = json::Node { name: Some(node.name.clone()), ..Default::default() };
        // glTF forbids empty accessors, so a node without triangles carries no mesh.
        if mesh.triangle_count() > 0 {
            let layout = Layout::new(mesh, &mut offset);
            let key = (node.material, mesh.colors.is_some());
            let material = match materials.iter().position(|m| *m == key) {
                Some(i) => json::Index::new(i as u32),
                None => {
                    materials.push(key);
                    root.push(pbr_material(key.0, key.1))
                }
            };
            let primitive = layout.push_json(&mut root, mesh, material);
            gltf_node.mesh = Some(root.push(json::Mesh {
                extensions: None,
                extras: Default::default(),
                name: Some(node.name.clone()),
                primitives: vec![primitive],
                weights: None,
            }));
            layouts.push((layout, mesh));
        }
        node_indices.push(root.push(gltf_node));
    }

    let scene_index =
        root.push(json::Scene { extensions: None, extras: Default::default(), name: None, nodes: node_indices });
    root.scene = Some(scene_index);

    let bin = fill_buffer(offset, &layouts);
    if !bin.is_empty() {
        let buffer = root.push(json::Buffer {
            byte_length: USize64::from(bin.len()),
            name: None,
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        debug_assert_eq!(buffer.value(), 0, "views refer to buffer 0");
    }

    let json_text = json::serialize::to_vec(&root).expect("glTF JSON serialises");
    let length = 12 + 8 + json_text.len().next_multiple_of(4) + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: u32::try_from(length).expect("glb larger than 4 GiB"),
        },
        json: Cow::Owned(json_text),
        bin: (!bin.is_empty()).then_some(Cow::Owned(bin)),
    };
    glb.to_vec().expect("glb encoding into memory")
}

/// The PBR material for a node: non-metallic, and fully rough except water.
fn pbr_material(kind: MaterialKind, has_colors: bool) -> json::Material {
    let linear = |srgb: [u8; 3]| srgb.map(srgb_to_linear);
    let (name, base, roughness) = match kind {
        // COLOR_0 multiplies the base colour, so white lets the vertex colours through.
        MaterialKind::VertexColors if has_colors => ("vertex_colors".to_string(), [1.0; 3], 1.0),
        MaterialKind::VertexColors => ("light_grey".to_string(), linear([200; 3]), 1.0),
        MaterialKind::Matte { srgb: [r, g, b] } => (format!("matte_{r:02x}{g:02x}{b:02x}"), linear([r, g, b]), 1.0),
        MaterialKind::Water => ("water".to_string(), linear([30, 90, 140]), 0.15),
    };
    json::Material {
        name: Some(name),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([base[0], base[1], base[2], 1.0]),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(roughness),
            ..Default::default()
        },
        double_sided: false,
        ..Default::default()
    }
}

/// Where one mesh's arrays sit in the buffer (byte offsets, each a multiple of 4).
struct Layout {
    positions: usize,
    normals: usize,
    uvs: usize,
    colors: Option<usize>,
    indices: usize,
    wide_indices: bool,
    end: usize,
}

impl Layout {
    fn new(mesh: &Mesh, offset: &mut usize) -> Self {
        let n = mesh.vertex_count();
        let wide_indices = n > MAX_U16_INDEXED_VERTICES;
        let mut take = |bytes: usize| {
            let at = *offset;
            *offset += bytes.next_multiple_of(4);
            at
        };
        let positions = take(n * 12);
        let normals = take(n * 12);
        let uvs = take(n * 8);
        let colors = mesh.colors.as_ref().map(|_| take(n * 4));
        let indices = take(mesh.indices.len() * if wide_indices { 4 } else { 2 });
        Self { positions, normals, uvs, colors, indices, wide_indices, end: *offset }
    }

    /// Views, accessors and the primitive for this mesh.
    fn push_json(
        &self,
        root: &mut json::Root,
        mesh: &Mesh,
        material: json::Index<json::Material>,
    ) -> json::mesh::Primitive {
        use json::accessor::{ComponentType, Type};
        use json::buffer::Target;
        use json::mesh::Semantic;

        let n = mesh.vertex_count();
        let (min, max) = mesh.bounds().expect("a mesh with triangles has vertices");
        let mut attributes = std::collections::BTreeMap::new();
        let mut attribute = |root: &mut json::Root, semantic, at, bytes, component, ty, normalized, bounds| {
            let view = push_view(root, at, bytes, Target::ArrayBuffer);
            let accessor = push_accessor(root, view, n, component, ty, normalized, bounds);
            attributes.insert(Valid(semantic), accessor);
        };
        let bounds = Some((json::Value::from(min.to_vec()), json::Value::from(max.to_vec())));
        attribute(root, Semantic::Positions, self.positions, n * 12, ComponentType::F32, Type::Vec3, false, bounds);
        attribute(root, Semantic::Normals, self.normals, n * 12, ComponentType::F32, Type::Vec3, false, None);
        attribute(root, Semantic::TexCoords(0), self.uvs, n * 8, ComponentType::F32, Type::Vec2, false, None);
        if let Some(at) = self.colors {
            attribute(root, Semantic::Colors(0), at, n * 4, ComponentType::U8, Type::Vec4, true, None);
        }

        let (index_type, index_bytes) =
            if self.wide_indices { (ComponentType::U32, 4) } else { (ComponentType::U16, 2) };
        let view = push_view(root, self.indices, mesh.indices.len() * index_bytes, Target::ElementArrayBuffer);
        let indices = push_accessor(root, view, mesh.indices.len(), index_type, Type::Scalar, false, None);

        json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: Default::default(),
            indices: Some(indices),
            material: Some(material),
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
        }
    }
}

fn push_view(
    root: &mut json::Root,
    offset: usize,
    bytes: usize,
    target: json::buffer::Target,
) -> json::Index<json::buffer::View> {
    root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(bytes),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        name: None,
        target: Some(Valid(target)),
        extensions: None,
        extras: Default::default(),
    })
}

#[allow(clippy::too_many_arguments)]
fn push_accessor(
    root: &mut json::Root,
    view: json::Index<json::buffer::View>,
    count: usize,
    component: json::accessor::ComponentType,
    ty: json::accessor::Type,
    normalized: bool,
    bounds: Option<(json::Value, json::Value)>,
) -> json::Index<json::Accessor> {
    let (min, max) = bounds.unzip();
    root.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Valid(json::accessor::GenericComponentType(component)),
        extensions: None,
        extras: Default::default(),
        type_: Valid(ty),
        min,
        max,
        name: None,
        normalized,
        sparse: None,
    })
}

/// The binary chunk: every mesh's arrays, little-endian, at their layout offsets (gaps zero).
fn fill_buffer(len: usize, layouts: &[(Layout, &Mesh)]) -> Vec<u8> {
    let mut bin = vec![0u8; len];
    let mut rest = bin.as_mut_slice();
    let mut base = 0;
    for (layout, mesh) in layouts {
        let (region, tail) = rest.split_at_mut(layout.end - base);
        let local = |at: usize| at - base;
        let n = mesh.vertex_count();
        put_floats(&mut region[local(layout.positions)..][..n * 12], &mesh.positions);
        put_unit_normals(&mut region[local(layout.normals)..][..n * 12], &mesh.normals);
        put_floats(&mut region[local(layout.uvs)..][..n * 8], &mesh.uvs);
        if let (Some(at), Some(colors)) = (layout.colors, &mesh.colors) {
            put_linear_colors(&mut region[local(at)..][..n * 4], colors);
        }
        let indices = &mut region[local(layout.indices)..];
        if layout.wide_indices {
            indices[..mesh.indices.len() * 4]
                .par_chunks_mut(4)
                .zip(mesh.indices.par_iter())
                .for_each(|(out, &i)| out.copy_from_slice(&i.to_le_bytes()));
        } else {
            indices[..mesh.indices.len() * 2]
                .par_chunks_mut(2)
                .zip(mesh.indices.par_iter())
                .for_each(|(out, &i)| out.copy_from_slice(&(i as u16).to_le_bytes()));
        }
        base = layout.end;
        rest = tail;
    }
    bin
}

fn put_floats<const N: usize>(out: &mut [u8], values: &[[f32; N]]) {
    out.par_chunks_mut(4 * N).zip(values.par_iter()).for_each(|(out, v)| {
        for (bytes, x) in out.chunks_exact_mut(4).zip(v) {
            bytes.copy_from_slice(&x.to_le_bytes());
        }
    });
}

fn put_unit_normals(out: &mut [u8], normals: &[[f32; 3]]) {
    out.par_chunks_mut(12).zip(normals.par_iter()).for_each(|(out, &[x, y, z])| {
        // Scale in f64 so the stored f32s are as close to unit length as f32 allows.
        let len = ((x as f64).powi(2) + (y as f64).powi(2) + (z as f64).powi(2)).sqrt();
        let unit = if len > 1e-12 && len.is_finite() {
            [x as f64 / len, y as f64 / len, z as f64 / len].map(|v| v as f32)
        } else {
            [0.0, 1.0, 0.0]
        };
        for (bytes, v) in out.chunks_exact_mut(4).zip(unit) {
            bytes.copy_from_slice(&v.to_le_bytes());
        }
    });
}

/// glTF vertex colours are linear; [`Mesh::colors`] are sRGB as people pick them.
fn put_linear_colors(out: &mut [u8], colors: &[[u8; 4]]) {
    out.par_chunks_mut(4).zip(colors.par_iter()).for_each(|(out, &[r, g, b, a])| {
        out.copy_from_slice(&[srgb_to_linear_u8(r), srgb_to_linear_u8(g), srgb_to_linear_u8(b), a]);
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{heightfield_mesh, SceneNode};
    use crate::terrain::Heightfield;

    fn terrain_mesh(cols: usize, rows: usize, colors: bool) -> Mesh {
        let hf = Heightfield::from_fn(cols, rows, 0.5, |x, z| (x * 0.1).sin() * 4.0 + z * 0.05);
        let color = |h: f32, _: f32| [(h * 10.0) as u8, 100, 50, 255];
        heightfield_mesh(&hf, 4097, colors.then_some(&color as _)).mesh
    }

    struct Parsed {
        document: gltf::Document,
        blob: Vec<u8>,
    }

    fn parse(bytes: &[u8]) -> Parsed {
        let gltf = gltf::Gltf::from_slice(bytes).expect("glb parses");
        let blob = gltf.blob.clone().expect("glb has a BIN chunk");
        Parsed { document: gltf.document, blob }
    }

    fn read_floats<const N: usize>(p: &Parsed, accessor: &gltf::Accessor) -> Vec<[f32; N]> {
        let view = accessor.view().unwrap();
        let start = view.offset() + accessor.offset();
        p.blob[start..start + accessor.count() * N * 4]
            .chunks_exact(N * 4)
            .map(|c| std::array::from_fn(|k| f32::from_le_bytes(c[k * 4..k * 4 + 4].try_into().unwrap())))
            .collect()
    }

    #[test]
    fn accessors_match_the_mesh() {
        let mesh = terrain_mesh(21, 13, true);
        let p = parse(&write_glb(&Scene::single("terrain", mesh.clone())));
        assert_eq!(p.document.as_json().asset.generator.as_deref(), Some("Landform"));
        let node = p.document.nodes().next().unwrap();
        assert_eq!(node.name(), Some("terrain"));
        let prim = node.mesh().unwrap().primitives().next().unwrap();
        let n = mesh.vertex_count();

        let pos = prim.get(&gltf::Semantic::Positions).unwrap();
        assert_eq!(pos.count(), n);
        let (lo, hi) = mesh.bounds().unwrap();
        let bound = |v: Option<gltf::json::Value>| -> Vec<f32> {
            v.unwrap().as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32).collect()
        };
        assert_eq!(bound(pos.min()), lo.to_vec());
        assert_eq!(bound(pos.max()), hi.to_vec());
        assert_eq!(read_floats::<3>(&p, &pos), mesh.positions);

        let normals = prim.get(&gltf::Semantic::Normals).unwrap();
        for v in read_floats::<3>(&p, &normals) {
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-6);
        }
        assert_eq!(read_floats::<2>(&p, &prim.get(&gltf::Semantic::TexCoords(0)).unwrap()), mesh.uvs);

        let colors = prim.get(&gltf::Semantic::Colors(0)).unwrap();
        assert_eq!(colors.data_type(), gltf::accessor::DataType::U8);
        assert_eq!(colors.dimensions(), gltf::accessor::Dimensions::Vec4);
        assert!(colors.normalized());

        let indices = prim.indices().unwrap();
        assert_eq!(indices.count(), mesh.indices.len());
        assert_eq!(indices.data_type(), gltf::accessor::DataType::U16);

        let material = prim.material();
        let pbr = material.pbr_metallic_roughness();
        assert_eq!(pbr.base_color_factor(), [1.0; 4]);
        assert_eq!((pbr.metallic_factor(), pbr.roughness_factor()), (0.0, 1.0));
        assert!(!material.double_sided());

        for view in p.document.views() {
            assert_eq!(view.offset() % 4, 0);
            assert!(view.target().is_some());
        }
    }

    #[test]
    fn indices_widen_past_65535_vertices() {
        // 65535 = 257 * 255 vertices still fit u16; one more row of 257 does not.
        for (rows, expected) in [(255, gltf::accessor::DataType::U16), (256, gltf::accessor::DataType::U32)] {
            let mesh = terrain_mesh(257, rows, false);
            let p = parse(&write_glb(&Scene::single("t", mesh.clone())));
            let prim = p.document.meshes().next().unwrap().primitives().next().unwrap();
            let indices = prim.indices().unwrap();
            assert_eq!(indices.data_type(), expected, "{} vertices", mesh.vertex_count());
            let view = indices.view().unwrap();
            let width = if expected == gltf::accessor::DataType::U16 { 2 } else { 4 };
            let last = &p.blob[view.offset() + (indices.count() - 1) * width..][..width];
            let last = if width == 2 {
                u16::from_le_bytes([last[0], last[1]]) as u32
            } else {
                u32::from_le_bytes(last.try_into().unwrap())
            };
            assert_eq!(last, *mesh.indices.last().unwrap());
        }
    }

    #[test]
    fn scene_keeps_node_order_names_and_shares_materials() {
        let scene = Scene {
            nodes: vec![
                SceneNode::new("ground", terrain_mesh(5, 5, true), MaterialKind::VertexColors),
                SceneNode::new("sea", terrain_mesh(3, 3, false), MaterialKind::Water),
                SceneNode::new("rock", terrain_mesh(4, 4, true), MaterialKind::VertexColors),
                SceneNode::new("empty", Mesh::default(), MaterialKind::Water),
            ],
        };
        let p = parse(&write_glb(&scene));
        let names: Vec<_> = p.document.nodes().map(|n| n.name().unwrap().to_string()).collect();
        assert_eq!(names, ["ground", "sea", "rock", "empty"]);
        assert_eq!(p.document.materials().count(), 2);
        assert!(p.document.nodes().nth(3).unwrap().mesh().is_none());
        assert_eq!(p.document.scenes().next().unwrap().nodes().count(), 4);
    }

    #[test]
    fn colors_are_stored_linear() {
        let mut out = [0u8; 8];
        put_linear_colors(&mut out, &[[255, 188, 0, 200], [128, 64, 32, 255]]);
        assert_eq!(out, [255, 128, 0, 200, 55, 13, 4, 255]);
    }

    #[test]
    fn bytes_are_deterministic_across_thread_counts() {
        let scene = Scene::single("t", terrain_mesh(300, 250, true));
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        assert_eq!(write_glb(&scene), pool.install(|| write_glb(&scene)));
    }
}
