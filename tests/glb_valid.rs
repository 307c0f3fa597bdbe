//! Our glb files pass the Khronos glTF validator with no errors and no warnings, in every form.
//!
//! Needs `npm ci --prefix tests/gltf-validator` first (see tests/common/gltf_validator.rs).

mod common;

use common::gltf_validator::{validate_glb, ValidatorReport};
use landform::export::{heightfield_artifacts, write_glb, GlbForm};
use landform::mesh::{heightfield_mesh, MaterialKind, Scene, SceneNode, DEFAULT_MAX_SIDE_SAMPLES};
use landform::terrain::Heightfield;

fn hills(cols: usize, rows: usize) -> Heightfield {
    Heightfield::from_fn(cols, rows, 2.0, |x, z| (x * 0.05).sin() * 20.0 + (z * 0.03).cos() * 15.0 - 5.0)
}

fn assert_clean(what: &str, report: &ValidatorReport) {
    assert_eq!((report.errors, report.warnings), (0, 0), "{what}: {}", report.summary());
}

fn index_type(glb: &[u8]) -> gltf::accessor::DataType {
    let gltf = gltf::Gltf::from_slice_without_validation(glb).expect("glb parses");
    let prim = gltf.meshes().next().expect("a mesh").primitives().next().expect("a primitive");
    prim.indices().expect("indexed").data_type()
}

#[test]
fn small_heightfield_mesh_with_u16_indices_is_valid() {
    let color = |h: f32, _slope: f32| [(h.abs() * 5.0) as u8, 160, 90, 255];
    let mesh = heightfield_mesh(&hills(33, 21), DEFAULT_MAX_SIDE_SAMPLES, Some(&color)).mesh;
    for form in [GlbForm::None, GlbForm::Quantize, GlbForm::Meshopt] {
        let glb = write_glb(&Scene::single("terrain", mesh.clone()), form);
        assert_eq!(index_type(&glb), gltf::accessor::DataType::U16);
        assert_clean(&format!("33x21 heightfield, {form:?}"), &validate_glb(&glb));
    }
}

#[test]
fn heightfield_mesh_over_65535_vertices_with_u32_indices_is_valid() {
    let mesh = heightfield_mesh(&hills(300, 250), DEFAULT_MAX_SIDE_SAMPLES, None).mesh;
    assert!(mesh.vertex_count() > 65_535);
    for form in [GlbForm::None, GlbForm::Quantize, GlbForm::Meshopt] {
        let glb = write_glb(&Scene::single("terrain", mesh.clone()), form);
        assert_eq!(index_type(&glb), gltf::accessor::DataType::U32);
        assert_clean(&format!("300x250 heightfield, {form:?}"), &validate_glb(&glb));
    }
}

#[test]
fn two_node_scene_with_ground_and_sea_is_valid() {
    let ground = heightfield_mesh(&hills(40, 40), DEFAULT_MAX_SIDE_SAMPLES, None).mesh;
    let sea = heightfield_mesh(&Heightfield::flat(2, 2, 78.0, 0.0), DEFAULT_MAX_SIDE_SAMPLES, None).mesh;
    let scene = Scene {
        nodes: vec![
            SceneNode::new("ground", ground, MaterialKind::Matte { srgb: [194, 140, 96] }),
            SceneNode::new("sea", sea, MaterialKind::Water),
        ],
    };
    for form in [GlbForm::None, GlbForm::Quantize, GlbForm::Meshopt] {
        let glb = write_glb(&scene, form);
        let gltf = gltf::Gltf::from_slice_without_validation(&glb).expect("glb parses");
        let names: Vec<_> = gltf.nodes().map(|n| n.name().unwrap_or_default().to_string()).collect();
        assert_eq!(names, ["ground", "sea"]);
        assert_clean(&format!("two-node scene, {form:?}"), &validate_glb(&glb));
    }
}

#[test]
fn heightfield_artifacts_mesh_is_valid() {
    let out = heightfield_artifacts(&hills(129, 97), &Default::default()).unwrap();
    let glb = out.artifacts.iter().find(|a| a.name == "mesh.glb").expect("mesh.glb");
    assert_clean("mesh.glb artifact", &validate_glb(&glb.bytes));
}
