//! The least time levels of detail can add to a job whose meshes are simplified (the volume
//! kinds: grow-cave, weather-column, carve-coast), whatever else they do: per example, the
//! whole job without levels (`landform run` with `lods: []`, wall time) against meshoptimizer's
//! simplifier alone making the default three levels of every node of its `mesh.glb` (a
//! cascade, each level from the one before, the first try's target as the service aims it:
//! the bound ÷ `SIMPLIFIER_MARGIN`, the border held; no measuring, no retry, no writing),
//! divided by the cores. The last column is the ratio a job with levels could reach at best:
//! over 1.3 where meshoptimizer alone costs more than 30 % of the job. Prints a Markdown
//! table. Run with `cargo bench --bench lod_floor [-- EXAMPLE.json …]` (every volume example
//! by default); `cargo test --bench lod_floor` runs it on the debug build.

use std::path::{Path, PathBuf};
use std::time::Instant;

use landform::export::DEFAULT_LODS;
use landform::mesh::SIMPLIFIER_MARGIN;

const KINDS: [&str; 3] = ["grow-cave", "weather-column", "carve-coast"];

/// A node's positions (in its own frame) and triangles.
type Node = (Vec<[f32; 3]>, Vec<u32>);

/// Each node of a glb in `none` form: positions (in the node's frame) and indices, and the
/// world box's longest side.
fn nodes(glb: &[u8]) -> (Vec<Node>, f32) {
    let gltf = gltf::Gltf::from_slice_without_validation(glb).expect("glb parses");
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    let scene = gltf.default_scene().or_else(|| gltf.scenes().next()).expect("a scene");
    let mut out = Vec::new();
    for node in scene.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let t = node.transform().decomposed().0;
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|_| Some(blob));
            let positions: Vec<[f32; 3]> = reader.read_positions().expect("f32 positions").collect();
            for p in &positions {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k] + t[k]);
                    hi[k] = hi[k].max(p[k] + t[k]);
                }
            }
            out.push((positions, reader.read_indices().expect("indices").into_u32().collect()));
        }
    }
    let longest = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f32::max);
    (out, longest)
}

/// Seconds meshoptimizer takes for the default levels of every node, one after another.
fn simplifier_alone(nodes: &[Node], longest: f32) -> f64 {
    let started = Instant::now();
    for (positions, indices) in nodes {
        let adapter = meshopt::VertexDataAdapter::new(meshopt::typed_to_bytes(positions), 12, 0).expect("vertices");
        let mut source = indices.clone();
        for fraction in DEFAULT_LODS {
            let target = fraction as f32 * longest / SIMPLIFIER_MARGIN;
            source = meshopt::simplify(
                &source,
                &adapter,
                0,
                target,
                meshopt::SimplifyOptions::ErrorAbsolute | meshopt::SimplifyOptions::LockBorder,
                None,
            );
        }
        std::hint::black_box(&source);
    }
    started.elapsed().as_secs_f64()
}

fn examples(root: &Path) -> Vec<PathBuf> {
    let named: Vec<PathBuf> = std::env::args().skip(1).filter(|a| a.ends_with(".json")).map(PathBuf::from).collect();
    if !named.is_empty() {
        return named;
    }
    let mut all: Vec<PathBuf> = KINDS
        .iter()
        .flat_map(|kind| std::fs::read_dir(root.join("api").join(kind)).expect("api folder"))
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    all.sort();
    all
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let binary = env!("CARGO_BIN_EXE_landform");
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("| example | job without levels | meshoptimizer alone, 3 levels | least ratio ({cores} cores) |");
    println!("| --- | ---: | ---: | ---: |");
    for example in examples(root) {
        let kind =
            example.parent().and_then(Path::file_name).and_then(|k| k.to_str()).expect("api/<kind>/").to_string();
        let name = example.file_stem().and_then(|n| n.to_str()).expect("a name").to_string();
        let mut body: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&example).expect("example")).expect("json");
        body["lods"] = serde_json::json!([]);
        body["compression"] = serde_json::json!("none");
        let work = tempfile::tempdir().expect("tempdir");
        let request = work.path().join("request.json");
        std::fs::write(&request, body.to_string()).expect("write");
        let started = Instant::now();
        let out = work.path().join("out");
        let status = std::process::Command::new(binary)
            .args(["run", request.to_str().unwrap(), "--out", out.to_str().unwrap(), "--kind", &kind])
            .arg("--database")
            .arg(work.path().join("db.sqlite"))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .status()
            .expect("landform runs");
        let job_s = started.elapsed().as_secs_f64();
        assert!(status.success(), "{kind}/{name} failed");
        let (nodes, longest) = nodes(&std::fs::read(out.join("mesh.glb")).expect("mesh.glb"));
        let simplify_s = simplifier_alone(&nodes, longest);
        let least = (job_s + simplify_s / cores as f64) / job_s;
        println!("| {kind}/{name} | {job_s:.3} s | {simplify_s:.3} s | {least:.2}× |");
    }
}
