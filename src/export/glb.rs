//! Binary glTF 2.0 (`.glb`) from a [`Scene`]: the mesh format every kind delivers.
//!
//! glTF is Y-up, right-handed, in metres, counter-clockwise front faces: our conventions. One
//! buffer holds one view per kind of array (positions, normals, texcoords, colours, indices of
//! each width), every node's array one after another in it (as gltfpack lays a scene out), each
//! view starting on a 4-byte boundary. Indices are u16 while every index fits
//! below the primitive-restart value 65535, else u32. Output bytes depend only on the scene and
//! the form:
//!
//! - [`GlbForm::None`]: f32 positions, normals and texcoords. Each node's `translation` is its
//!   pivot ([`SceneNode::pivot`]: the piece's base) and its positions are relative to it, so
//!   an importer shows every piece at its place with its origin at its base and scale 1.
//! - [`GlbForm::Quantize`] (`KHR_mesh_quantization`, declared used and required): positions as
//!   unsigned 16-bit steps from the scene's lowest corner, one step (the longest side of the
//!   box around every node ÷ 65535; one grid for all nodes) on every axis, which each node's
//!   `translation` and uniform `scale`
//!   turn back into metres (the same step on every axis keeps normals right under the node's
//!   transform; the error is at most half a step; the node's origin is that corner, not the
//!   piece's pivot, since the extension puts dequantisation on the node and its unsigned steps
//!   start at the origin); normals as normalised signed bytes;
//!   texcoords as normalised unsigned 16-bit when they lie in [0, 1], else f32. Every importer
//!   that reads glTF 2.0 meshes in engines and Blender reads it.
//! - [`GlbForm::Meshopt`]: the quantised arrays above, each buffer view compressed with
//!   meshoptimizer's codecs (`EXT_meshopt_compression`: vertex codec version 0, index codec
//!   version 1, the versions the extension defines). No fallback buffer is written (it would
//!   hold the uncompressed data again), so the extension is declared required beside
//!   `KHR_mesh_quantization`, as `gltfpack -c` does: buffer 0 is the BIN chunk with the
//!   compressed views, buffer 1 the fallback buffer with no data, which the views name.

use std::borrow::Cow;

use gltf::json;
use json::validation::{Checked::Valid, USize64};
use rayon::prelude::*;

use super::srgb::{srgb_to_linear, srgb_to_linear_u8};
use crate::mesh::{GpuOrder, MaterialKind, Mesh, Scene, SceneNode};

/// Most vertices a mesh may have and still use u16 indices (65535 itself means "restart").
pub const MAX_U16_INDEXED_VERTICES: usize = 65_535;

/// How a glb's vertex data is stored (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GlbForm {
    /// f32 positions, normals and texcoords: the default, as every importer reads it without an
    /// extension and every node keeps scale 1 (Blender 3.4 refuses `meshopt`, and shows the
    /// quantised form's dequantisation as each object's scale).
    #[default]
    None,
    /// `KHR_mesh_quantization`: 16-bit positions, 8-bit normals, 16-bit texcoords.
    Quantize,
    /// The quantised arrays compressed by `EXT_meshopt_compression`.
    Meshopt,
}

impl GlbForm {
    pub const NAMES: [&'static str; 3] = ["none", "quantize", "meshopt"];

    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "none" => Some(Self::None),
            "quantize" => Some(Self::Quantize),
            "meshopt" => Some(Self::Meshopt),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Quantize => "quantize",
            Self::Meshopt => "meshopt",
        }
    }

    fn quantizes(self) -> bool {
        self != Self::None
    }
}

const QUANTIZATION: &str = "KHR_mesh_quantization";
const MESHOPT: &str = "EXT_meshopt_compression";
/// Bits per position coordinate in the meshopt form (gltfpack's default): an error of at most
/// half of the scene's longest side ÷ 16383.
pub(super) const MESHOPT_POSITION_BITS: u32 = 14;

/// A mesh's quantisation: positions are `origin + q × step` for q in 0..=`top`.
struct Quantized {
    origin: [f32; 3],
    step: f32,
    /// The largest step number: 2^bits − 1.
    top: f64,
    /// Texcoords written (in every form), all in [0, 1] so normalised u16 holds them.
    uvs: Option<bool>,
    /// Normals through meshoptimizer's octahedral filter (the meshopt form).
    oct_normals: bool,
}

impl Quantized {
    fn of(mesh: &Mesh, (lo, hi): ([f32; 3], [f32; 3]), form: GlbForm) -> Self {
        let meshopt = form == GlbForm::Meshopt;
        let top = if meshopt { f64::from((1u32 << MESHOPT_POSITION_BITS) - 1) } else { 65535.0 };
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max);
        let step = if extent > 0.0 && extent.is_finite() { (f64::from(extent) / top) as f32 } else { 1.0 };
        let unit_uvs = mesh.uvs.iter().flatten().all(|v| (0.0..=1.0).contains(v));
        Self { origin: lo, step, top, uvs: Some(unit_uvs), oct_normals: meshopt }
    }

    fn position(&self, p: [f32; 3]) -> [u16; 3] {
        std::array::from_fn(|k| {
            ((f64::from(p[k]) - f64::from(self.origin[k])) / f64::from(self.step)).round().clamp(0.0, self.top) as u16
        })
    }
}

/// Encode a scene as a glb. Nodes keep their order and names; a node whose mesh has no
/// triangles is written as an empty node. Normals are renormalised on the way out (the format
/// requires unit length), with +Y standing in for a zero normal.
///
/// # Panics
/// If a mesh fails [`Mesh::check`] (mismatched arrays or out-of-range indices) or the file
/// would exceed glb's 4 GiB limit: both are bugs in the caller.
pub fn write_glb(scene: &Scene, form: GlbForm) -> Vec<u8> {
    write_glb_in_frame(scene, form, scene_bounds(scene))
}

/// The box around every node's vertices, if any. Quantised in it, all nodes share one grid of
/// steps (as gltfpack quantises a scene): a small node gets the whole scene's precision rather
/// than finer steps nobody sees, which compress worse (grow-cave's many speleothems: 17 % more
/// position bytes each in a frame of its own).
fn scene_bounds(scene: &Scene) -> Option<([f32; 3], [f32; 3])> {
    scene
        .nodes
        .iter()
        .filter(|n| n.mesh.triangle_count() > 0)
        .filter_map(|n| n.mesh.bounds())
        .reduce(|(lo, hi), (l, h)| (std::array::from_fn(|k| lo[k].min(l[k])), std::array::from_fn(|k| hi[k].max(h[k]))))
}

/// [`write_glb`], quantising every node in one frame, the box `(lowest, highest corner)`,
/// which must hold every vertex (`None`: each node in its own box). Meshes written in one
/// frame decode a position they share to the same floats: the tiles of a terrain meet exactly.
pub fn write_glb_in_frame(scene: &Scene, form: GlbForm, frame: Option<([f32; 3], [f32; 3])>) -> Vec<u8> {
    encode(scene, &[], form, frame)
}

/// [`write_glb`] carrying levels of detail (`MSFT_lod`): each of `levels` is the scene
/// simplified, node for node, with its error bound in metres (increasing). Every node of the
/// scene names its levels' nodes (out of the scene, same transform, quantised in the same
/// frame) in `extensions.MSFT_lod.ids`, with `extras.MSFT_screencoverage` the screen shares
/// below which each next level is shown ([`screen_coverage`]). Loaders without the extension
/// show the full nodes; the extension is used, not required.
pub fn write_glb_with_levels(scene: &Scene, levels: &[(&Scene, f64)], form: GlbForm) -> Vec<u8> {
    for (level, _) in levels {
        assert_eq!(level.nodes.len(), scene.nodes.len(), "a level has every node of the scene");
    }
    encode(scene, levels, form, scene_bounds(scene))
}

/// A node of the scene for `MSFT_lod`: its index, its bounding diameter (metres), and its
/// levels' node indices with their error bounds (metres).
type NodeLevels = (u32, f64, Vec<(u32, f64)>);

/// The MSFT_lod extension's name.
const LOD: &str = "MSFT_lod";
/// Rows of the view the screen-coverage hints assume (a 1080p screen).
const SCREEN_ROWS: f64 = 1080.0;

/// `MSFT_screencoverage` for a node of bounding diameter `diameter_m` whose levels have error
/// bounds `bounds_m`: level k + 1 takes over when the node covers less than
/// (diameter ÷ (bound × 1080))² of the screen, where its error is a pixel of a 1080-row view
/// at most, and the last value (0) keeps the coarsest level however small the node.
pub fn screen_coverage(diameter_m: f64, bounds_m: &[f64]) -> Vec<f64> {
    let mut values: Vec<f64> = bounds_m
        .iter()
        .map(|&b| if b > 0.0 { (diameter_m / (b * SCREEN_ROWS)).powi(2).min(1.0) } else { 1.0 })
        .map(|c| (c * 1e6).round() / 1e6)
        .collect();
    values.push(0.0);
    values
}

fn encode(scene: &Scene, levels: &[(&Scene, f64)], form: GlbForm, frame: Option<([f32; 3], [f32; 3])>) -> Vec<u8> {
    let mut root = json::Root {
        asset: json::Asset { generator: Some("Landform".into()), ..Default::default() },
        ..Default::default()
    };
    let mut materials: Vec<(MaterialKind, bool)> = Vec::new();
    // First every mesh's place in the shared views, then the views, then the JSON per node.
    let mut groups: Vec<Group> = Vec::new();
    // Each node of the scene, then its levels' nodes.
    // Each node of the scene, then its levels' nodes, with the scene node's pivot (a level
    // keeps its node's transform, as MSFT_lod loaders show a level in the node's place).
    let entries: Vec<(usize, &SceneNode)> = (0..scene.nodes.len())
        .flat_map(|i| {
            std::iter::once((0, &scene.nodes[i]))
                .chain(levels.iter().enumerate().map(move |(k, (l, _))| (k + 1, &l.nodes[i])))
        })
        .collect();
    let pivots: Vec<[f32; 3]> = scene.nodes.iter().map(SceneNode::pivot).collect();
    let entry_pivot = |e: usize| pivots[e / (levels.len() + 1)];
    let mut layouts: Vec<Option<Layout>> = Vec::with_capacity(entries.len());
    for (e, (_, node)) in entries.iter().enumerate() {
        let mesh = &node.mesh;
        if let Err(e) = mesh.check() {
            panic!("mesh of node {:?} is malformed: {e}", node.name);
        }
        // glTF forbids empty accessors, so a node without triangles carries no mesh.
        layouts.push((mesh.triangle_count() > 0).then(|| {
            let bounds = mesh.bounds().expect("a mesh with triangles has vertices");
            let placement = match form.quantizes() {
                true => Placement::Quantized(Quantized::of(mesh, frame.unwrap_or(bounds), form)),
                false => Placement::Pivot(entry_pivot(e)),
            };
            Layout::new(mesh, bounds, placement, &mut groups)
        }));
    }
    let len = place_groups(&mut groups);
    let oct_normals = form == GlbForm::Meshopt;
    let view_indices: Vec<json::Index<json::buffer::View>> = groups.iter().map(|g| push_view(&mut root, g)).collect();
    let views: Vec<ViewData> = groups
        .iter()
        .map(|g| ViewData {
            offset: g.offset,
            stride: g.stride,
            count: g.count,
            indices: g.slot == Slot::Indices,
            filter: (oct_normals && g.slot == Slot::Normals).then_some("OCTAHEDRAL"),
        })
        .collect();

    let mut node_indices = Vec::with_capacity(scene.nodes.len());
    let mut lods: Vec<NodeLevels> = Vec::new();
    for ((level, node), layout) in entries.iter().zip(&layouts) {
        let mesh = &node.mesh;
        let name = if *level == 0 { node.name.clone() } else { format!("{} lod{level}", node.name) };
        let mut gltf_node = json::Node { name: Some(name), ..Default::default() };
        if let Some(layout) = layout {
            match &layout.placement {
                Placement::Quantized(q) => {
                    gltf_node.translation = Some(q.origin);
                    gltf_node.scale = Some([q.step; 3]);
                    if root.extensions_used.is_empty() {
                        root.extensions_used.push(QUANTIZATION.into());
                        root.extensions_required.push(QUANTIZATION.into());
                    }
                }
                Placement::Pivot(pivot) => gltf_node.translation = Some(*pivot),
            }
            let key = (node.material, mesh.colors.is_some());
            let material = match materials.iter().position(|m| *m == key) {
                Some(i) => json::Index::new(i as u32),
                None => {
                    materials.push(key);
                    root.push(pbr_material(key.0, key.1))
                }
            };
            let primitive = layout.push_json(&mut root, &view_indices, mesh, material);
            gltf_node.mesh = Some(root.push(json::Mesh {
                extensions: None,
                extras: Default::default(),
                name: gltf_node.name.clone(),
                primitives: vec![primitive],
                weights: None,
            }));
        }
        let has_mesh = gltf_node.mesh.is_some();
        let index = root.push(gltf_node);
        if *level == 0 {
            node_indices.push(index);
            let diameter = mesh.bounds().map_or(0.0, |(lo, hi)| {
                (0..3).map(|k| (f64::from(hi[k]) - f64::from(lo[k])).powi(2)).sum::<f64>().sqrt()
            });
            lods.push((index.value() as u32, diameter, Vec::new()));
        } else if has_mesh {
            // A level that kept no triangle is left out: loaders want a mesh on every level.
            let (_, _, ids) = lods.last_mut().expect("a level follows its node");
            ids.push((index.value() as u32, levels[level - 1].1));
        }
    }

    let scene_index =
        root.push(json::Scene { extensions: None, extras: Default::default(), name: None, nodes: node_indices });
    root.scene = Some(scene_index);

    let meshes: Vec<(&Layout, &Mesh)> =
        layouts.iter().zip(&entries).filter_map(|(l, (_, n))| l.as_ref().map(|l| (l, &n.mesh))).collect();
    let mut bin = fill_buffer(len, &groups, &meshes);
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

    let lods: Vec<_> = lods.into_iter().filter(|(_, _, ids)| !ids.is_empty()).collect();
    let json_text = if (form == GlbForm::Meshopt && !bin.is_empty()) || !lods.is_empty() {
        // gltf-json models neither extension: they are added to the JSON as values.
        // Through the text, so numbers keep the short form the glTF serialiser gives f32s.
        let text = json::serialize::to_vec(&root).expect("glTF JSON serialises");
        let mut value: serde_json::Value = serde_json::from_slice(&text).expect("glTF JSON parses");
        if form == GlbForm::Meshopt && !bin.is_empty() {
            bin = meshopt_compressed(&mut value, &views, &bin);
        }
        add_lods(&mut value, &lods);
        serde_json::to_vec(&value).expect("glTF JSON serialises")
    } else {
        json::serialize::to_vec(&root).expect("glTF JSON serialises")
    };
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

/// Bytes per vertex of positions, normals and texcoords (0: none written) in a form.
fn strides(quantized: Option<&Quantized>) -> (usize, usize, usize) {
    match quantized {
        None => (12, 12, 8),
        Some(q) => (8, 4, q.uvs.map_or(0, |unit| if unit { 4 } else { 8 })),
    }
}

/// Which array of a mesh a buffer view holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Slot {
    Positions,
    Normals,
    TexCoords,
    Colors,
    Indices,
}

/// One buffer view: every mesh's array of one slot and element size, one after another (as
/// gltfpack lays them out). Fewer views make a smaller JSON chunk and, compressed, fewer
/// streams.
struct Group {
    slot: Slot,
    stride: usize,
    /// Bytes from the buffer's start (a multiple of 4), once placed.
    offset: usize,
    len: usize,
    count: usize,
}

/// An array's place: its view (group) and its byte offset in it.
#[derive(Clone, Copy, Debug)]
struct Member {
    group: usize,
    at: usize,
}

/// Give the array of `count` elements of `stride` bytes a place in its slot's view.
fn join_group(groups: &mut Vec<Group>, slot: Slot, stride: usize, count: usize) -> Member {
    let group = match groups.iter().position(|g| g.slot == slot && g.stride == stride) {
        Some(g) => g,
        None => {
            groups.push(Group { slot, stride, offset: 0, len: 0, count: 0 });
            groups.len() - 1
        }
    };
    let g = &mut groups[group];
    // Vertex strides are multiples of 4; index arrays hold whole triangles, so every array
    // starts on a multiple of its component size.
    let at = g.len;
    g.len += count * stride;
    g.count += count;
    Member { group, at }
}

/// Lay the views out in the buffer by slot (each from a 4-byte boundary); the buffer's length.
fn place_groups(groups: &mut [Group]) -> usize {
    let mut order: Vec<usize> = (0..groups.len()).collect();
    order.sort_by_key(|&g| (groups[g].slot, groups[g].stride));
    let mut offset = 0;
    for g in order {
        groups[g].offset = offset;
        offset += groups[g].len.next_multiple_of(4);
    }
    offset
}

/// How a mesh's positions are stored against its node's transform.
enum Placement {
    /// f32 positions less the pivot, the node's translation (scale 1).
    Pivot([f32; 3]),
    /// Steps of a quantisation frame, whose origin and step are the node's translation and
    /// scale (KHR_mesh_quantization dequantises on the node; a mesh has no transform).
    Quantized(Quantized),
}

impl Placement {
    fn quantized(&self) -> Option<&Quantized> {
        match self {
            Self::Quantized(q) => Some(q),
            Self::Pivot(_) => None,
        }
    }
}

/// A world position relative to `pivot`: the difference taken in f64 (exact for f32 inputs of
/// like magnitude) and rounded once, so a loader's `pivot + relative` is within half an f32 step of `p`.
fn relative(p: [f32; 3], pivot: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|k| (f64::from(p[k]) - f64::from(pivot[k])) as f32)
}

/// Where one mesh's arrays sit in the shared views.
struct Layout {
    /// The mesh's bounding box (lowest and highest corner).
    bounds: ([f32; 3], [f32; 3]),
    placement: Placement,
    positions: Member,
    normals: Member,
    uvs: Option<Member>,
    colors: Option<Member>,
    indices: Member,
    wide_indices: bool,
}

impl Layout {
    fn new(mesh: &Mesh, bounds: ([f32; 3], [f32; 3]), placement: Placement, groups: &mut Vec<Group>) -> Self {
        let n = mesh.vertex_count();
        let wide_indices = n > MAX_U16_INDEXED_VERTICES;
        let (position_bytes, normal_bytes, uv_bytes) = strides(placement.quantized());
        let positions = join_group(groups, Slot::Positions, position_bytes, n);
        let normals = join_group(groups, Slot::Normals, normal_bytes, n);
        let uvs = (uv_bytes > 0).then(|| join_group(groups, Slot::TexCoords, uv_bytes, n));
        let colors = mesh.colors.as_ref().map(|_| join_group(groups, Slot::Colors, 4, n));
        let index_bytes = if wide_indices { 4 } else { 2 };
        let indices = join_group(groups, Slot::Indices, index_bytes, mesh.indices.len());
        Self { bounds, placement, positions, normals, uvs, colors, indices, wide_indices }
    }

    fn strides(&self) -> (usize, usize, usize) {
        strides(self.placement.quantized())
    }

    /// Accessors (into the shared `views`) and the primitive for this mesh.
    fn push_json(
        &self,
        root: &mut json::Root,
        views: &[json::Index<json::buffer::View>],
        mesh: &Mesh,
        material: json::Index<json::Material>,
    ) -> json::mesh::Primitive {
        use json::accessor::{ComponentType, Type};
        use json::mesh::Semantic;

        let n = mesh.vertex_count();
        let (min, max) = self.bounds;
        let mut attributes = std::collections::BTreeMap::new();
        let mut attribute = |root: &mut json::Root, semantic, at: Member, component, ty, normalized, bounds| {
            let accessor = push_accessor(root, views[at.group], at.at, n, component, ty, normalized, bounds);
            attributes.insert(Valid(semantic), accessor);
        };
        match &self.placement {
            Placement::Pivot(pivot) => {
                // Subtracting the pivot keeps order, so the corners give the data's bounds.
                let corner = |p: [f32; 3]| json::Value::from(relative(p, *pivot).to_vec());
                let bounds = Some((corner(min), corner(max)));
                attribute(root, Semantic::Positions, self.positions, ComponentType::F32, Type::Vec3, false, bounds);
                attribute(root, Semantic::Normals, self.normals, ComponentType::F32, Type::Vec3, false, None);
            }
            Placement::Quantized(q) => {
                // Rounding keeps order, so the corners' steps are the data's bounds.
                let steps = |p: [f32; 3]| json::Value::from(q.position(p).map(u32::from).to_vec());
                let bounds = Some((steps(min), steps(max)));
                attribute(root, Semantic::Positions, self.positions, ComponentType::U16, Type::Vec3, false, bounds);
                attribute(root, Semantic::Normals, self.normals, ComponentType::I8, Type::Vec3, true, None);
            }
        }
        if let Some(at) = self.uvs {
            let (uv_type, uv_normalized) =
                if self.strides().2 == 4 { (ComponentType::U16, true) } else { (ComponentType::F32, false) };
            attribute(root, Semantic::TexCoords(0), at, uv_type, Type::Vec2, uv_normalized, None);
        }
        if let Some(at) = self.colors {
            attribute(root, Semantic::Colors(0), at, ComponentType::U8, Type::Vec4, true, None);
        }
        let index_type = if self.wide_indices { ComponentType::U32 } else { ComponentType::U16 };
        let indices = push_accessor(
            root,
            views[self.indices.group],
            self.indices.at,
            mesh.indices.len(),
            index_type,
            Type::Scalar,
            false,
            None,
        );

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

/// One buffer view's data in the uncompressed buffer: `count` elements of `stride` bytes from
/// `offset`, vertex attributes or triangle indices.
struct ViewData {
    offset: usize,
    stride: usize,
    count: usize,
    indices: bool,
    /// The meshopt filter the data went through, as the extension names it.
    filter: Option<&'static str>,
}

impl ViewData {
    /// This view's data through meshoptimizer's codec for its kind.
    fn compress(&self, bin: &[u8]) -> Vec<u8> {
        let data = &bin[self.offset..][..self.count * self.stride];
        if self.indices {
            let indices: Vec<u32> = if self.stride == 2 {
                data.chunks_exact(2).map(|b| u32::from(u16::from_le_bytes([b[0], b[1]]))).collect()
            } else {
                data.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
            };
            let vertex_count = indices.iter().max().map_or(0, |&m| m as usize + 1);
            meshopt::encode_index_buffer(&indices, vertex_count).expect("index buffer encodes")
        } else {
            encode_vertices(data, self.count, self.stride)
        }
    }
}

/// meshoptimizer's vertex codec, format version 0 (the one `EXT_meshopt_compression` defines)
/// whatever the library's default.
fn encode_vertices(data: &[u8], count: usize, stride: usize) -> Vec<u8> {
    // SAFETY: the bound has no preconditions; the encoder reads count × stride bytes of `data`
    // (checked) and writes at most `out.len()` bytes.
    unsafe {
        assert_eq!(data.len(), count * stride);
        let mut out = vec![0u8; meshopt::ffi::meshopt_encodeVertexBufferBound(count, stride)];
        let len = meshopt::ffi::meshopt_encodeVertexBufferLevel(
            out.as_mut_ptr(),
            out.len(),
            data.as_ptr().cast(),
            count,
            stride,
            2,
            0,
        );
        assert!(len > 0, "the vertex encoder had room");
        out.truncate(len);
        out
    }
}

/// The `EXT_meshopt_compression` form of a glb whose JSON is `root` and whose uncompressed
/// buffer is `bin` (views in `views`' order): the compressed BIN chunk (buffer 0, each view's
/// data from a 4-byte boundary) and the JSON text, in which buffer 1 is the fallback buffer
/// with no data and every view names it, its data in buffer 0 through the extension.
fn meshopt_compressed(value: &mut serde_json::Value, views: &[ViewData], bin: &[u8]) -> Vec<u8> {
    let parts: Vec<Vec<u8>> = views.par_iter().map(|v| v.compress(bin)).collect();
    let mut compressed = Vec::with_capacity(parts.iter().map(|p| p.len() + 3).sum());
    let json_views = value["bufferViews"].as_array_mut().expect("the views");
    assert_eq!(json_views.len(), views.len(), "one view per array");
    for ((json_view, view), part) in json_views.iter_mut().zip(views).zip(&parts) {
        let at = compressed.len();
        compressed.extend_from_slice(part);
        compressed.resize(compressed.len().next_multiple_of(4), 0);
        json_view["buffer"] = 1.into();
        let mut ext = serde_json::json!({
            "buffer": 0,
            "byteOffset": at,
            "byteLength": part.len(),
            "byteStride": view.stride,
            "count": view.count,
            "mode": if view.indices { "TRIANGLES" } else { "ATTRIBUTES" },
        });
        if let Some(filter) = view.filter {
            ext["filter"] = filter.into();
        }
        json_view["extensions"] = serde_json::json!({ MESHOPT: ext });
    }
    value["buffers"] = serde_json::json!([
        { "byteLength": compressed.len() },
        { "byteLength": bin.len(), "extensions": { MESHOPT: { "fallback": true } } },
    ]);
    for list in ["extensionsUsed", "extensionsRequired"] {
        value[list].as_array_mut().expect("quantisation is declared").push(MESHOPT.into());
    }
    compressed
}

/// `MSFT_lod` on each node of `lods` (its index, diameter and its levels' node indices and
/// bounds), with its screen-coverage hints, and the extension declared used.
fn add_lods(value: &mut serde_json::Value, lods: &[NodeLevels]) {
    if lods.is_empty() {
        return;
    }
    for (node, diameter, levels) in lods {
        let bounds: Vec<f64> = levels.iter().map(|l| l.1).collect();
        let json_node = &mut value["nodes"][*node as usize];
        json_node["extensions"] = serde_json::json!({ LOD: { "ids": levels.iter().map(|l| l.0).collect::<Vec<_>>() } });
        json_node["extras"] = serde_json::json!({ "MSFT_screencoverage": screen_coverage(*diameter, &bounds) });
    }
    match value.get_mut("extensionsUsed").and_then(serde_json::Value::as_array_mut) {
        Some(used) => used.push(LOD.into()),
        None => value["extensionsUsed"] = serde_json::json!([LOD]),
    }
}

/// A group's view: vertex views state their stride (several accessors share them).
fn push_view(root: &mut json::Root, group: &Group) -> json::Index<json::buffer::View> {
    use json::buffer::Target;
    let indices = group.slot == Slot::Indices;
    root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(group.len),
        byte_offset: Some(USize64::from(group.offset)),
        byte_stride: (!indices).then_some(json::buffer::Stride(group.stride)),
        name: None,
        target: Some(Valid(if indices { Target::ElementArrayBuffer } else { Target::ArrayBuffer })),
        extensions: None,
        extras: Default::default(),
    })
}

#[allow(clippy::too_many_arguments)]
fn push_accessor(
    root: &mut json::Root,
    view: json::Index<json::buffer::View>,
    offset: usize,
    count: usize,
    component: json::accessor::ComponentType,
    ty: json::accessor::Type,
    normalized: bool,
    bounds: Option<(json::Value, json::Value)>,
) -> json::Index<json::Accessor> {
    let (min, max) = bounds.unzip();
    root.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: (offset > 0).then(|| USize64::from(offset)),
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

/// The binary chunk: every mesh's arrays, little-endian, at their places in the views (gaps
/// zero), vertices and triangles in the mesh's GPU order.
fn fill_buffer(len: usize, groups: &[Group], meshes: &[(&Layout, &Mesh)]) -> Vec<u8> {
    let mut bin = vec![0u8; len];
    for (layout, mesh) in meshes {
        let n = mesh.vertex_count();
        let (ps, ns, us) = layout.strides();
        let order = match layout.placement.quantized() {
            Some(q) if q.oct_normals => GpuOrder::for_compression(mesh),
            _ => GpuOrder::of(mesh),
        };
        let positions = region(&mut bin, groups, layout.positions, n * ps);
        match &layout.placement {
            Placement::Pivot(pivot) => {
                put(positions, ps, &order, &mesh.positions, |p| f32s::<3, 12>(relative(p, *pivot)))
            }
            Placement::Quantized(q) => put(positions, ps, &order, &mesh.positions, |p| u16s::<3, 6>(q.position(p))),
        }
        let normals = region(&mut bin, groups, layout.normals, n * ns);
        match layout.placement.quantized() {
            None => put(normals, ns, &order, &mesh.normals, |v| f32s::<3, 12>(unit(v))),
            Some(q) if q.oct_normals => oct_normals(normals, &order, &mesh.normals),
            Some(_) => put(normals, ns, &order, &mesh.normals, |v| {
                unit(v).map(|c| ((f64::from(c) * 127.0).round() as i8) as u8)
            }),
        }
        if let Some(at) = layout.uvs {
            let uvs = region(&mut bin, groups, at, n * us);
            if us == 4 {
                put(uvs, us, &order, &mesh.uvs, |uv| {
                    u16s::<2, 4>(uv.map(|c| (f64::from(c) * 65535.0).round().clamp(0.0, 65535.0) as u16))
                });
            } else {
                put(uvs, us, &order, &mesh.uvs, f32s::<2, 8>);
            }
        }
        if let (Some(at), Some(colors)) = (layout.colors, &mesh.colors) {
            put(region(&mut bin, groups, at, n * 4), 4, &order, colors, linear_color);
        }
        if layout.wide_indices {
            region(&mut bin, groups, layout.indices, order.indices.len() * 4)
                .par_chunks_mut(4)
                .zip(order.indices.par_iter())
                .for_each(|(out, &i)| out.copy_from_slice(&i.to_le_bytes()));
        } else {
            region(&mut bin, groups, layout.indices, order.indices.len() * 2)
                .par_chunks_mut(2)
                .zip(order.indices.par_iter())
                .for_each(|(out, &i)| out.copy_from_slice(&(i as u16).to_le_bytes()));
        }
    }
    bin
}

/// The bytes of one mesh's array in the buffer.
fn region<'a>(bin: &'a mut [u8], groups: &[Group], at: Member, bytes: usize) -> &'a mut [u8] {
    let start = groups[at.group].offset + at.at;
    &mut bin[start..start + bytes]
}

/// Write each vertex's `values` in the new order, `encode`d, at the start of its `stride`.
fn put<T: Copy + Sync, const W: usize>(
    out: &mut [u8],
    stride: usize,
    order: &GpuOrder,
    values: &[T],
    encode: impl Fn(T) -> [u8; W] + Sync,
) {
    out.par_chunks_mut(stride).enumerate().for_each(|(k, out)| {
        out[..W].copy_from_slice(&encode(order.at(values, k)));
    });
}

/// Unit normals in the new order through meshoptimizer's octahedral filter at 8 bits: four
/// signed bytes per vertex that `meshopt_decodeFilterOct` turns back into a normalised vector.
fn oct_normals(out: &mut [u8], order: &GpuOrder, normals: &[[f32; 3]]) {
    let floats: Vec<f32> = (0..out.len() / 4)
        .flat_map(|k| {
            let [x, y, z] = unit(order.at(normals, k));
            [x, y, z, 0.0]
        })
        .collect();
    // SAFETY: `floats` holds four floats per vertex and `out` four bytes per vertex.
    unsafe { meshopt::ffi::meshopt_encodeFilterOct(out.as_mut_ptr().cast(), out.len() / 4, 4, 8, floats.as_ptr()) }
}

fn f32s<const N: usize, const W: usize>(v: [f32; N]) -> [u8; W] {
    std::array::from_fn(|b| v[b / 4].to_le_bytes()[b % 4])
}

fn u16s<const N: usize, const W: usize>(v: [u16; N]) -> [u8; W] {
    std::array::from_fn(|b| v[b / 2].to_le_bytes()[b % 2])
}

/// A normal at unit length, +Y standing in for a zero one. Scaled in f64 so the f32s are as
/// close to unit length as f32 allows.
fn unit([x, y, z]: [f32; 3]) -> [f32; 3] {
    let len = ((x as f64).powi(2) + (y as f64).powi(2) + (z as f64).powi(2)).sqrt();
    if len > 1e-12 && len.is_finite() {
        [x as f64 / len, y as f64 / len, z as f64 / len].map(|v| v as f32)
    } else {
        [0.0, 1.0, 0.0]
    }
}

/// glTF vertex colours are linear; [`Mesh::colors`] are sRGB as people pick them.
fn linear_color([r, g, b, a]: [u8; 4]) -> [u8; 4] {
    [srgb_to_linear_u8(r), srgb_to_linear_u8(g), srgb_to_linear_u8(b), a]
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
        let p = parse(&write_glb(&Scene::single("terrain", mesh.clone()), GlbForm::None));
        assert_eq!(p.document.as_json().asset.generator.as_deref(), Some("Landform"));
        let node = p.document.nodes().next().unwrap();
        assert_eq!(node.name(), Some("terrain"));
        let prim = node.mesh().unwrap().primitives().next().unwrap();
        let n = mesh.vertex_count();

        let order = GpuOrder::of(&mesh);
        let pos = prim.get(&gltf::Semantic::Positions).unwrap();
        assert_eq!(pos.count(), n);
        // The node's origin is the middle of the bottom of the mesh's box, scale 1, and the
        // positions are relative to it.
        let (lo, hi) = mesh.bounds().unwrap();
        let pivot = [(lo[0] + hi[0]) / 2.0, lo[1], (lo[2] + hi[2]) / 2.0];
        let (translation, rotation, scale) = node.transform().decomposed();
        assert!(translation.iter().zip(pivot).all(|(a, b)| (a - b).abs() < 1e-5), "{translation:?} ≠ {pivot:?}");
        let pivot = translation;
        assert_eq!((rotation, scale), ([0.0, 0.0, 0.0, 1.0], [1.0; 3]));
        let bound = |v: Option<gltf::json::Value>| -> Vec<f32> {
            v.unwrap().as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32).collect()
        };
        let less_pivot = |p: [f32; 3]| -> [f32; 3] { std::array::from_fn(|k| p[k] - pivot[k]) };
        assert_eq!(bound(pos.min()), less_pivot(lo).to_vec());
        assert_eq!(bound(pos.max()), less_pivot(hi).to_vec());
        // The same vertices, in the GPU order (tested in mesh::gpu_order), back in place
        // within an f32 rounding of a metre-sized coordinate.
        let read = read_floats::<3>(&p, &pos);
        for (k, q) in read.iter().enumerate() {
            let want = order.at(&mesh.positions, k);
            for c in 0..3 {
                assert!((f64::from(q[c] + pivot[c]) - f64::from(want[c])).abs() < 1e-5, "{q:?} + {pivot:?} ≠ {want:?}");
            }
        }

        let normals = prim.get(&gltf::Semantic::Normals).unwrap();
        for v in read_floats::<3>(&p, &normals) {
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-6);
        }
        let uvs: Vec<[f32; 2]> = (0..n).map(|k| order.at(&mesh.uvs, k)).collect();
        assert_eq!(read_floats::<2>(&p, &prim.get(&gltf::Semantic::TexCoords(0)).unwrap()), uvs);

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
            let p = parse(&write_glb(&Scene::single("t", mesh.clone()), GlbForm::None));
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
            assert_eq!(last, *GpuOrder::of(&mesh).indices.last().unwrap());
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
        let p = parse(&write_glb(&scene, GlbForm::None));
        let names: Vec<_> = p.document.nodes().map(|n| n.name().unwrap().to_string()).collect();
        assert_eq!(names, ["ground", "sea", "rock", "empty"]);
        assert_eq!(p.document.materials().count(), 2);
        assert!(p.document.nodes().nth(3).unwrap().mesh().is_none());
        assert_eq!(p.document.scenes().next().unwrap().nodes().count(), 4);
    }

    #[test]
    fn quantized_positions_come_back_within_half_a_step_and_normals_within_half_a_degree() {
        // 21 × 13 samples 0.5 m apart: 10 m along x is the longest side (heights span < 4 m,
        // z 6 m), so one step is 10 m / 65535 on every axis.
        let mesh = terrain_mesh(21, 13, true);
        let plain = write_glb(&Scene::single("terrain", mesh.clone()), GlbForm::None);
        let glb = write_glb(&Scene::single("terrain", mesh.clone()), GlbForm::Quantize);
        let gltf = gltf::Gltf::from_slice_without_validation(&glb).unwrap();
        let json = gltf.document.as_json();
        assert_eq!(json.extensions_required, ["KHR_mesh_quantization"]);
        assert_eq!(json.extensions_used, ["KHR_mesh_quantization"]);
        let blob = gltf.blob.as_deref().unwrap();
        let node = gltf.document.nodes().next().unwrap();
        let gltf::scene::Transform::Decomposed { translation, scale, .. } = node.transform() else { panic!() };
        let step = 10.0f32 / 65535.0;
        assert_eq!(scale, [step; 3]);
        assert_eq!(translation, mesh.bounds().unwrap().0);

        let prim = node.mesh().unwrap().primitives().next().unwrap();
        // Vertex k of the file is vertex `source[k]` of the mesh (the GPU order).
        let order = GpuOrder::of(&mesh);
        let in_order = |k: usize| order.source[k] as usize;
        let read = |semantic: gltf::Semantic, width: usize| -> Vec<Vec<u8>> {
            let a = prim.get(&semantic).unwrap();
            let view = a.view().unwrap();
            let stride = view.stride().unwrap_or(width);
            (0..a.count()).map(|i| blob[view.offset() + i * stride..][..width].to_vec()).collect()
        };
        for (k, bytes) in read(gltf::Semantic::Positions, 6).iter().enumerate() {
            let p = mesh.positions[in_order(k)];
            for k in 0..3 {
                let q = u16::from_le_bytes([bytes[2 * k], bytes[2 * k + 1]]);
                let back = translation[k] + f32::from(q) * scale[k];
                assert!((back - p[k]).abs() <= 0.5 * step + 1e-5, "{back} for {}", p[k]);
            }
        }
        for (k, bytes) in read(gltf::Semantic::Normals, 3).iter().enumerate() {
            let n = &mesh.normals[in_order(k)];
            let q = [0, 1, 2].map(|k| f64::from(bytes[k] as i8) / 127.0);
            let len = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            let u = unit(*n).map(f64::from);
            let cos = (q[0] * u[0] + q[1] * u[1] + q[2] * u[2]) / len;
            assert!(cos >= 0.5f64.to_radians().cos(), "{q:?} for {u:?}");
        }
        for (k, bytes) in read(gltf::Semantic::TexCoords(0), 4).iter().enumerate() {
            let uv = mesh.uvs[in_order(k)];
            for k in 0..2 {
                let back = f32::from(u16::from_le_bytes([bytes[2 * k], bytes[2 * k + 1]])) / 65535.0;
                assert!((back - uv[k]).abs() <= 0.5 / 65535.0 + 1e-7);
            }
        }
        // Per vertex: positions 12 → 8 bytes, normals 12 → 4, texcoords 8 → 4; the JSON grows a
        // little (the extension, the transform, strides).
        let saved = plain.len() as i64 - glb.len() as i64;
        let expected = 16 * mesh.vertex_count() as i64;
        assert!((saved - expected).abs() < 400, "saved {saved} bytes, expected about {expected}");
    }

    #[test]
    fn meshopt_views_decode_to_the_mesh() {
        let scene = Scene {
            nodes: vec![
                SceneNode::new("big", terrain_mesh(300, 250, true), MaterialKind::VertexColors),
                SceneNode::new("small", terrain_mesh(30, 20, false), MaterialKind::Water),
            ],
        };
        let quantized_bytes = write_glb(&scene, GlbForm::Quantize);
        let packed_bytes = write_glb(&scene, GlbForm::Meshopt);
        let packed = gltf::binary::Glb::from_slice(&packed_bytes).unwrap();
        let m: serde_json::Value = serde_json::from_slice(&packed.json).unwrap();
        let required = [QUANTIZATION, MESHOPT];
        assert_eq!(m["extensionsRequired"], serde_json::json!(required));
        assert_eq!(m["extensionsUsed"], serde_json::json!(required));
        let bin = packed.bin.unwrap();
        assert_eq!(m["buffers"][0]["byteLength"], bin.len());
        assert_eq!(m["buffers"][1]["extensions"][MESHOPT]["fallback"], true);
        assert!(m["buffers"][1].get("uri").is_none(), "the fallback buffer holds no data");

        // Decode every view as a loader does, and check each node's arrays against its mesh.
        let decode = |view: usize| -> (Vec<u8>, usize) {
            let view = &m["bufferViews"][view];
            assert_eq!(view["buffer"], 1);
            let ext = &view["extensions"][MESHOPT];
            let get = |k: &str| ext[k].as_u64().unwrap() as usize;
            let (at, len, stride, count) = (get("byteOffset"), get("byteLength"), get("byteStride"), get("count"));
            assert_eq!(at % 4, 0);
            let source = &bin[at..at + len];
            let mut out = vec![0u8; count * stride];
            // SAFETY: `out` holds count × stride bytes; the decoders only read `source`.
            let status = unsafe {
                if ext["mode"] == "TRIANGLES" {
                    assert_eq!(source[0], 0xe1, "index codec version 1");
                    meshopt::ffi::meshopt_decodeIndexBuffer(
                        out.as_mut_ptr().cast(),
                        count,
                        stride,
                        source.as_ptr(),
                        len,
                    )
                } else {
                    assert_eq!(source[0], 0xa0, "vertex codec version 0");
                    let status = meshopt::ffi::meshopt_decodeVertexBuffer(
                        out.as_mut_ptr().cast(),
                        count,
                        stride,
                        source.as_ptr(),
                        len,
                    );
                    if ext["filter"] == "OCTAHEDRAL" {
                        meshopt::ffi::meshopt_decodeFilterOct(out.as_mut_ptr().cast(), count, stride);
                    }
                    status
                }
            };
            assert_eq!(status, 0, "decodes");
            (out, stride)
        };
        for (n, node) in scene.nodes.iter().enumerate() {
            let mesh = &node.mesh;
            let order = GpuOrder::for_compression(mesh);
            let json_node = &m["nodes"][n];
            let scale = json_node["scale"][0].as_f64().unwrap();
            let translation: Vec<f64> = (0..3).map(|k| json_node["translation"][k].as_f64().unwrap()).collect();
            let (lo, hi) = scene_bounds(&scene).unwrap();
            let longest = (0..3).map(|k| f64::from(hi[k] - lo[k])).fold(0.0, f64::max);
            assert!((scale - longest / 16383.0).abs() < 1e-9, "14-bit steps of the scene's box");
            let prim = &m["meshes"][n]["primitives"][0];
            // An accessor's elements: its view decoded, from its offset in it (views are shared).
            let view_of = |accessor: &serde_json::Value| -> (Vec<u8>, usize) {
                let a = &m["accessors"][accessor.as_u64().unwrap() as usize];
                let (data, stride) = decode(a["bufferView"].as_u64().unwrap() as usize);
                let at = a["byteOffset"].as_u64().unwrap_or(0) as usize;
                let count = a["count"].as_u64().unwrap() as usize;
                (data[at..at + count * stride].to_vec(), stride)
            };
            let (uvs, stride) = view_of(&prim["attributes"]["TEXCOORD_0"]);
            for k in 0..mesh.vertex_count() {
                let uv = order.at(&mesh.uvs, k);
                for c in 0..2 {
                    let q = u16::from_le_bytes([uvs[k * stride + 2 * c], uvs[k * stride + 2 * c + 1]]);
                    let back = f64::from(q) / 65535.0;
                    assert!((back - f64::from(uv[c])).abs() <= 0.5 / 65535.0 + 1e-9, "texcoord {k}");
                }
            }
            let (positions, stride) = view_of(&prim["attributes"]["POSITION"]);
            for k in 0..mesh.vertex_count() {
                let p = order.at(&mesh.positions, k);
                for c in 0..3 {
                    let q = u16::from_le_bytes([positions[k * stride + 2 * c], positions[k * stride + 2 * c + 1]]);
                    let back = translation[c] + f64::from(q) * scale;
                    assert!((back - f64::from(p[c])).abs() <= 0.5 * scale + 1e-5, "{back} for {}", p[c]);
                }
            }
            let (normals, stride) = view_of(&prim["attributes"]["NORMAL"]);
            for k in 0..mesh.vertex_count() {
                let q: Vec<f64> = (0..3).map(|c| f64::from(normals[k * stride + c] as i8) / 127.0).collect();
                let len = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                let u = unit(order.at(&mesh.normals, k)).map(f64::from);
                let cos = (q[0] * u[0] + q[1] * u[1] + q[2] * u[2]) / len;
                assert!(cos >= 2f64.to_radians().cos(), "{q:?} for {u:?}");
            }
            if let Some(colors) = &mesh.colors {
                let (decoded, _) = view_of(&prim["attributes"]["COLOR_0"]);
                let expected: Vec<u8> =
                    (0..mesh.vertex_count()).flat_map(|k| linear_color(order.at(colors, k))).collect();
                assert!(decoded == expected, "colours");
            }
            let (indices, stride) = view_of(&prim["indices"]);
            // The index codec may rotate a triangle's corners (winding kept): compare each
            // triangle from its smallest index.
            let canonical = |indices: Vec<u32>| -> Vec<[u32; 3]> {
                indices
                    .chunks_exact(3)
                    .map(|t| {
                        let first = (0..3).min_by_key(|&k| t[k]).unwrap();
                        [t[first], t[(first + 1) % 3], t[(first + 2) % 3]]
                    })
                    .collect()
            };
            let read: Vec<u32> = indices
                .chunks_exact(stride)
                .map(|b| {
                    if stride == 2 {
                        u32::from(u16::from_le_bytes([b[0], b[1]]))
                    } else {
                        u32::from_le_bytes(b.try_into().unwrap())
                    }
                })
                .collect();
            assert!(canonical(read) == canonical(order.indices.clone()), "the same triangles, wound the same");
        }
        assert!(packed_bytes.len() * 3 < quantized_bytes.len(), "{} of {}", packed_bytes.len(), quantized_bytes.len());
    }

    #[test]
    fn colors_are_stored_linear() {
        assert_eq!(linear_color([255, 188, 0, 200]), [255, 128, 0, 200]);
        assert_eq!(linear_color([128, 64, 32, 255]), [55, 13, 4, 255]);
    }

    #[test]
    fn bytes_are_deterministic_across_thread_counts() {
        let scene = Scene::single("t", terrain_mesh(300, 250, true));
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        for form in [GlbForm::None, GlbForm::Quantize, GlbForm::Meshopt] {
            assert_eq!(write_glb(&scene, form), pool.install(|| write_glb(&scene, form)));
        }
    }

    #[test]
    fn screen_coverage_by_hand() {
        // A 100 m node: level 1 (0.1 m) once it covers under (100 / 108)² of the screen, level
        // 2 (1 m) under (100 / 1080)², and the coarsest however small.
        assert_eq!(screen_coverage(100.0, &[0.1, 1.0]), [0.857339, 0.008573, 0.0]);
        assert_eq!(screen_coverage(1e4, &[0.1]), [1.0, 0.0], "at most the whole screen");
    }

    #[test]
    fn every_node_names_its_levels_with_msft_lod() {
        let terrain = terrain_mesh(65, 65, false);
        let mut small = terrain_mesh(9, 9, false);
        small.positions.iter_mut().for_each(|p| p[1] += 40.0);
        let scene = Scene {
            nodes: vec![
                SceneNode::new("terrain", terrain.clone(), MaterialKind::VertexColors),
                SceneNode::new("rock", small.clone(), MaterialKind::VertexColors),
            ],
        };
        let bounds = [0.05f32, 0.4];
        let levels: Vec<Vec<crate::mesh::Lod>> = [&terrain, &small]
            .iter()
            .map(|m| crate::mesh::simplify_levels(m, &bounds, crate::stop::Stop::NEVER).unwrap())
            .collect();
        let level_scenes: Vec<Scene> = (0..bounds.len())
            .map(|k| Scene {
                nodes: scene
                    .nodes
                    .iter()
                    .zip(&levels)
                    .map(|(n, l)| SceneNode::new(n.name.clone(), l[k].mesh.clone(), n.material))
                    .collect(),
            })
            .collect();
        let with: Vec<(&Scene, f64)> = level_scenes.iter().zip(bounds).map(|(s, b)| (s, f64::from(b))).collect();
        for form in [GlbForm::None, GlbForm::Quantize, GlbForm::Meshopt] {
            let glb = write_glb_with_levels(&scene, &with, form);
            let json: serde_json::Value = serde_json::from_slice(&gltf::Glb::from_slice(&glb).unwrap().json).unwrap();
            assert!(json["extensionsUsed"].as_array().unwrap().contains(&"MSFT_lod".into()), "{form:?}");
            let required = json["extensionsRequired"].as_array().cloned().unwrap_or_default();
            assert!(!required.contains(&"MSFT_lod".into()), "a loader without it shows level 0");
            let in_scene: Vec<u64> =
                json["scenes"][0]["nodes"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap()).collect();
            assert_eq!(in_scene.len(), 2);
            let nodes = json["nodes"].as_array().unwrap();
            assert_eq!(nodes.len(), 2 * (1 + bounds.len()));
            for (i, &n) in in_scene.iter().enumerate() {
                let node = &nodes[n as usize];
                let ids: Vec<u64> = node["extensions"]["MSFT_lod"]["ids"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_u64().unwrap())
                    .collect();
                assert_eq!(ids.len(), bounds.len());
                let coverage: Vec<f64> = node["extras"]["MSFT_screencoverage"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap())
                    .collect();
                assert_eq!(coverage.len(), ids.len() + 1);
                assert!(coverage.windows(2).all(|w| w[0] >= w[1]) && coverage.iter().all(|c| (0.0..=1.0).contains(c)));
                assert_eq!(coverage.last(), Some(&0.0));
                for (k, &id) in ids.iter().enumerate() {
                    assert!(!in_scene.contains(&id), "level nodes stay out of the scene");
                    let level = &nodes[id as usize];
                    assert_eq!(level["translation"], node["translation"], "{form:?}: same transform");
                    assert_eq!(level["scale"], node["scale"]);
                    let mesh = &json["meshes"][level["mesh"].as_u64().unwrap() as usize];
                    let indices = &json["accessors"][mesh["primitives"][0]["indices"].as_u64().unwrap() as usize];
                    assert_eq!(
                        indices["count"].as_u64().unwrap() as usize,
                        3 * levels[i][k].mesh.triangle_count(),
                        "{form:?}: node {i} level {}",
                        k + 1
                    );
                }
            }
            // Without levels, the bytes are write_glb's.
            assert_eq!(write_glb_with_levels(&scene, &[], form), write_glb(&scene, form));
        }
    }
}
