//! The game-asset pipeline's stages on two large meshes, each stage timed once:
//!
//! - the 513 × 513 fractal island carved with three passes (the carve-coast bench's case,
//!   about 4.9 M triangles), read back from its `mesh.glb`;
//! - a 4097 × 4097 fractal heightfield, meshed as the service meshes it (every fourth sample:
//!   1025² vertices, 2.1 M triangles).
//!
//! Stages: vertex cache and fetch order (`GpuOrder`), each level of detail by meshoptimizer's
//! simplifier with its measured deviation (`simplify_within`, and the measuring alone once
//! more), the heightfield's levels by RTIN straight from the grid as the other method, and
//! `mesh.glb` written in each compression form. Prints Markdown tables. Run with
//! `cargo bench --bench assets`.

use std::time::Instant;

use serde_json::json;

use landform::export::{write_glb, GlbForm};
use landform::jobs::Simulation;
use landform::mesh::{
    heightfield_mesh, max_deviation, simplify_within, vertical_deviation, GpuOrder, Mesh, Rtin, Scene,
    DEFAULT_MAX_SIDE_SAMPLES,
};
use landform::sims::carve_coast::{CarveCoast, CarveCoastParams};
use landform::stop::Stop;
use landform::terrain::TerrainSource;
use landform::validate::Limits;

#[path = "support/mod.rs"]
mod support;

const LODS: [f32; 3] = [0.002, 0.008, 0.032];

fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let started = Instant::now();
    let out = f();
    (out, started.elapsed().as_secs_f64())
}

/// The largest node of a glb written with f32 positions.
fn largest_node(glb: &[u8]) -> Mesh {
    let gltf = gltf::Gltf::from_slice_without_validation(glb).expect("glb parses");
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    gltf.meshes()
        .map(|m| {
            let primitive = m.primitives().next().expect("a primitive");
            let reader = primitive.reader(|_| Some(blob));
            let positions: Vec<[f32; 3]> = reader.read_positions().expect("f32 positions").collect();
            let normals: Vec<[f32; 3]> = reader.read_normals().expect("normals").collect();
            let n = positions.len();
            Mesh {
                positions,
                normals,
                uvs: vec![[0.0; 2]; n],
                colors: None,
                indices: reader.read_indices().expect("indices").into_u32().collect(),
            }
        })
        .max_by_key(Mesh::triangle_count)
        .expect("a mesh")
}

fn carved_coast() -> Mesh {
    let params: CarveCoastParams = serde_json::from_value(json!({
        "terrain": {"fractal": {"size": 513, "cell_size": 1.0, "relief": 120.0, "seed": 11, "island": true}},
        "sea_level": 0.0,
        "passes": 3,
    }))
    .expect("parses");
    let limits = Limits { max_voxels: 1 << 30, ..Limits::default() };
    let (out, seconds) = timed(|| {
        support::with_limits(&limits, |ctx| {
            let ctx = landform::jobs::RunContext {
                mesh: landform::export::MeshSettings { form: GlbForm::None, lods: Vec::new() },
                draft: false,
                ..*ctx
            };
            CarveCoast::run(&params, 1, &ctx).expect("runs")
        })
    });
    let glb = out.artifacts.iter().find(|a| a.name == "mesh.glb").expect("mesh.glb");
    let mesh = largest_node(&glb.bytes);
    println!("carve-coast 513², 3 passes, whole job: {seconds:.2} s");
    mesh
}

fn heightfield_4097() -> (Mesh, usize) {
    let source: TerrainSource =
        serde_json::from_value(json!({"fractal": {"size": 4097, "cell_size": 1.0, "relief": 600.0, "seed": 5}}))
            .expect("parses");
    let limits = Limits::default();
    let (hf, seconds) = timed(|| support::with_limits(&limits, |ctx| ctx.resolve_terrain(&source).expect("terrain")));
    println!("fractal 4097²: {seconds:.2} s");
    let (meshed, seconds) = timed(|| heightfield_mesh(&hf, DEFAULT_MAX_SIDE_SAMPLES, None));
    println!(
        "heightfield mesh (stride {}, {} × {} vertices): {seconds:.2} s",
        meshed.stride, meshed.vertices[0], meshed.vertices[1]
    );
    (meshed.mesh, meshed.vertices[0])
}

fn longest_side(mesh: &Mesh) -> f32 {
    let (lo, hi) = mesh.bounds().expect("vertices");
    (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f32::max)
}

fn stages(label: &str, mesh: &Mesh, rtin_size: Option<usize>) {
    let longest = longest_side(mesh);
    println!(
        "\n### {label}: {} vertices, {} triangles, longest side {longest:.1} m\n",
        mesh.vertex_count(),
        mesh.triangle_count()
    );
    let (_, order_s) = timed(|| GpuOrder::for_compression(mesh));
    println!("vertex cache and fetch order: {order_s:.3} s\n");

    println!("| level | method | bound (m) | triangles | measured deviation (m) | simplify + measure (s) | measure alone (s) |");
    println!("|---|---|---:|---:|---:|---:|---:|");
    let mut level_one = None;
    for (level, fraction) in LODS.iter().enumerate() {
        let bound = fraction * longest;
        let (lod, total_s) = timed(|| simplify_within(mesh, bound, Stop::NEVER).unwrap());
        let (_, measure_s) = timed(|| max_deviation(mesh, &lod.mesh, lod.sample_spacing_m, Stop::NEVER).unwrap());
        println!(
            "| {} | meshopt simplify | {bound:.3} | {} | {:.4} | {total_s:.2} | {measure_s:.2} |",
            level + 1,
            lod.mesh.triangle_count(),
            lod.deviation_m
        );
        if level == 0 {
            level_one = Some(lod.mesh);
        }
    }
    if let Some(size) = rtin_size {
        // The service's own heightfield levels (`grid_levels`): the grid triangulated within
        // each bound and measured exactly, no tries.
        let heights: Vec<f32> = mesh.positions.iter().map(|p| p[1]).collect();
        let (rtin, errors_s) = timed(|| Rtin::new(&heights, size, size).expect("a grid"));
        for (level, fraction) in LODS.iter().enumerate() {
            let bound = fraction * longest;
            let ((triangles, (deviation, measure_s)), total_s) = timed(|| {
                let triangles = rtin.triangles(bound);
                let measured = timed(|| vertical_deviation(&heights, size, size, &triangles));
                (triangles, measured)
            });
            println!(
                "| {} | RTIN, measured exactly ({errors_s:.2} s for the errors, once) | {bound:.3} | {} | {deviation:.4} | {total_s:.2} | {measure_s:.2} |",
                level + 1,
                triangles.len() / 3,
            );
        }
    }
    println!("\n| mesh | form | glb bytes | write (s) |\n|---|---|---:|---:|");
    let full = Scene::single("mesh", mesh.clone());
    let first = Scene::single("mesh", level_one.expect("level 1"));
    for (name, scene) in [("full", &full), ("level 1", &first)] {
        for form in [GlbForm::None, GlbForm::Quantize, GlbForm::Meshopt] {
            let (bytes, s) = timed(|| write_glb(scene, form));
            println!("| {name} | {} | {} | {s:.2} |", form.name(), bytes.len());
        }
    }
}

fn main() {
    let coast = carved_coast();
    stages("carve-coast 513², 3 passes", &coast, None);
    drop(coast);
    let (hf, size) = heightfield_4097();
    stages("heightfield 4097² (its 1025² mesh)", &hf, Some(size));
}
