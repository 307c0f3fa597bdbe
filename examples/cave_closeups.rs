//! Close-up renders of every grow-cave example, for looking at the speleothems' shapes (rounded
//! tops, drip tips, column waists, hollow straws) as a caver with a lamp would:
//!
//! ```text
//! cargo run --example cave_closeups -- docs/grow-cave/closeups
//! ```
//!
//! For each `api/grow-cave/*.json` it grows the cave and frames one speleothem: a column if
//! there is one, else the longest stalagmite with its stalactite, else the longest stalactite's
//! tip, seen from the side nearer the chamber's middle.

use std::path::Path;

use landform::export::{render_inside_png, InsideView};
use landform::mesh::SceneNode;
use landform::sims::grow_cave::{grow, scene, GrowCaveParams};
use landform::stop::Stop;

fn main() {
    let out = std::env::args().nth(1).unwrap_or_else(|| "docs/grow-cave/closeups".into());
    std::fs::create_dir_all(&out).expect("the output folder");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("api/grow-cave");
    let mut files: Vec<_> = std::fs::read_dir(&dir).expect("api/grow-cave").map(|e| e.unwrap().path()).collect();
    files.sort();
    for path in files.iter().filter(|p| p.extension().is_some_and(|e| e == "json")) {
        let mut body: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
        let fields = body.as_object_mut().unwrap();
        let seed = fields.remove("seed").and_then(|s| s.as_u64()).unwrap_or(0);
        fields.remove("label");
        let params: GrowCaveParams = serde_json::from_value(body).expect("a grow-cave request");
        let sequence = grow(&params, seed, &mut |_, _| Ok(())).expect("grows");
        let scene = scene(&params, &sequence);
        let view = framing(&params, &scene.nodes[1..]);
        let png = render_inside_png(&scene, &view, "", Stop::NEVER).expect("renders");
        let name = path.file_stem().unwrap().to_string_lossy();
        std::fs::write(Path::new(&out).join(format!("{name}.png")), png).unwrap();
        println!("{name}: {} nodes", scene.nodes.len());
    }
}

/// The height span of a node.
fn span(n: &SceneNode) -> f32 {
    n.mesh.bounds().map_or(0.0, |(lo, hi)| hi[1] - lo[1])
}

fn longest<'a>(nodes: &'a [SceneNode], kind: &str) -> Option<&'a SceneNode> {
    nodes.iter().filter(|n| n.name.starts_with(kind)).max_by(|a, b| span(a).total_cmp(&span(b)))
}

fn framing(params: &GrowCaveParams, nodes: &[SceneNode]) -> InsideView {
    let c = &params.chamber;
    let middle = [c.width_m / 2.0, c.depth_m / 2.0];
    let (target, tall, look_up) = if let Some(n) = longest(nodes, "column") {
        (n, true, false)
    } else if let Some(n) = longest(nodes, "stalagmite") {
        (n, true, false)
    } else {
        (longest(nodes, "stalactite").expect("something grew"), false, true)
    };
    let (lo, hi) = target.mesh.bounds().unwrap();
    // Stalagmites with the stalactite above: frame from the floor to the roof there.
    let (bottom, top) = if tall { (lo[1], c.height_m.min(hi[1] + 0.6 * (c.height_m - hi[1]))) } else { (lo[1], hi[1]) };
    let centre = [(lo[0] + hi[0]) / 2.0, (lo[2] + hi[2]) / 2.0];
    let (dx, dz) = (middle[0] - centre[0], middle[1] - centre[1]);
    let len = dx.hypot(dz).max(1e-3);
    let (ux, uz) = if len > 0.05 { (dx / len, dz / len) } else { (0.7, 0.7) };
    // A tip seen from a little below and beside; a whole column from its middle height.
    let size = if look_up { 0.6 * (top - bottom).clamp(0.3, 0.8) } else { (top - bottom).max(0.4) };
    let distance = 1.1 * size;
    let aim_y = if look_up { bottom + 0.15 * size } else { (bottom + top) / 2.0 };
    let eye_y = if look_up { bottom - 0.35 * size } else { aim_y };
    let eye = [centre[0] + ux * distance, eye_y.max(c.floor.relief_m + 0.05), centre[1] + uz * distance];
    let lamp = [eye[0] - 0.3 * uz * size, eye[1] + 0.4 * size, eye[2] + 0.3 * ux * size];
    InsideView {
        width_px: 512,
        height_px: 512,
        eye,
        target: [centre[0], aim_y, centre[1]],
        fov_deg: 55.0,
        lamp,
        lamp_reach_m: 2.0 * size,
    }
}
