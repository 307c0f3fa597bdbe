//! `POST /v1/drafts/{kind}`: a request run at once at reduced resolution, answered with its
//! mesh and nothing stored. Each kind's draft is measured against the full job of the same
//! body: a valid glb, fewer triangles, and the same extent (the same shapes, coarser).

mod common;

use common::gltf_validator::validate_glb;
use common::server::{example, Options, TestServer};
use serde_json::{json, Value};

/// The scene of a glb (compression `none`: nodes at scale 1, translated): its triangles and its
/// bounds in metres.
fn scene(glb: &[u8]) -> (usize, [f32; 3], [f32; 3]) {
    let gltf = gltf::Gltf::from_slice_without_validation(glb).expect("glb parses");
    let (mut triangles, mut lo, mut hi) = (0, [f32::MAX; 3], [f32::MIN; 3]);
    for node in gltf.default_scene().expect("a default scene").nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let (t, _, s) = node.transform().decomposed();
        for prim in mesh.primitives() {
            triangles += prim.indices().map_or(0, |a| a.count()) / 3;
            let b = prim.bounding_box();
            for k in 0..3 {
                lo[k] = lo[k].min(t[k] + s[k] * b.min[k]);
                hi[k] = hi[k].max(t[k] + s[k] * b.max[k]);
            }
        }
    }
    (triangles, lo, hi)
}

async fn draft(server: &TestServer, kind: &str, body: &Value) -> reqwest::Response {
    server.client.post(server.url(&format!("/v1/drafts/{kind}"))).json(body).send().await.expect("POST draft")
}

/// The small bodies: each kind's preset, shrunk where the full job would be slow in a debug
/// build; every one is still a grid or volume the draft rule coarsens.
fn bodies() -> Vec<(&'static str, Value)> {
    let mut erode = example("erode", "eroded-island");
    erode["iterations"] = json!(20);
    let mut deform = example("deform-terrain", "terraces");
    deform["max_iterations"] = json!(200);
    let mut coast = example("carve-coast", "small-island-one-pass");
    coast["seed"] = json!(3);
    vec![
        ("bulldoze", example("bulldoze", "ziggurat")),
        ("erode", erode),
        ("deform-terrain", deform),
        ("carve-coast", coast),
        ("grow-cave", example("grow-cave", "soda-straws")),
        ("weather-column", example("weather-column", "cube-to-sphere")),
    ]
}

#[tokio::test(flavor = "multi_thread")]
async fn each_kinds_draft_is_its_full_job_coarser() {
    let server = TestServer::start().await;
    for (kind, body) in bodies() {
        let res = draft(&server, kind, &body).await;
        assert_eq!(res.status(), 200, "{kind}: {:?}", res.text().await);
        assert_eq!(res.headers()["content-type"], "model/gltf-binary", "{kind}");
        let seconds: f64 = res.headers()["landform-draft-seconds"].to_str().unwrap().parse().unwrap();
        assert!(seconds > 0.0, "{kind}");
        let glb = res.bytes().await.unwrap().to_vec();
        let report = validate_glb(&glb);
        assert_eq!(report.errors, 0, "{kind}: {:?}", report.messages);
        let (d_tris, d_lo, d_hi) = scene(&glb);

        let job = server.run(kind, &body).await;
        let full = server.artifact(job["id"].as_str().unwrap(), "mesh.glb").await;
        let (f_tris, f_lo, f_hi) = scene(&full);
        assert!(d_tris > 0 && d_tris * 10 < f_tris * 7, "{kind}: draft {d_tris} triangles, full {f_tris}");
        // The same extent: each side of the box within 10 % of the full job's longest side; a
        // heightfield's plan to a thousandth (the draft grid ends on the terrain's far edge).
        let longest = (0..3).map(|k| f_hi[k] - f_lo[k]).fold(0.0, f32::max);
        let heightfield = ["bulldoze", "erode", "deform-terrain"].contains(&kind);
        for k in 0..3 {
            let off = (d_lo[k] - f_lo[k]).abs().max((d_hi[k] - f_hi[k]).abs());
            let allowed = if heightfield && k != 1 { 1e-3 * longest } else { 0.1 * longest };
            assert!(off <= allowed, "{kind}: axis {k} draft {d_lo:?}..{d_hi:?} full {f_lo:?}..{f_hi:?}");
        }
        println!("{kind}: draft {d_tris} triangles in {seconds:.2} s, full {f_tris}");
    }
    // Nothing stored: the jobs listed are the full ones only.
    let (_, list) = server.get_json("/v1/jobs?limit=100").await;
    assert_eq!(list["items"].as_array().unwrap().len(), bodies().len(), "{list}");
}

#[tokio::test(flavor = "multi_thread")]
async fn a_draft_is_deterministic_and_checked_like_a_job() {
    let server = TestServer::start().await;
    let body = example("weather-column", "cube-to-sphere");
    let a = draft(&server, "weather-column", &body).await.bytes().await.unwrap();
    let b = draft(&server, "weather-column", &body).await.bytes().await.unwrap();
    assert!(a == b, "two drafts of one body differ");

    // A bad field: 422 naming it, as the submission would.
    let mut bad = body.clone();
    bad["steps"] = json!(0);
    let res = draft(&server, "weather-column", &bad).await;
    assert_eq!(res.status(), 422);
    let problem: Value = res.json().await.unwrap();
    assert_eq!(problem["errors"][0]["field"], "steps", "{problem}");
    let mut unknown = body.clone();
    unknown["stepz"] = json!(3);
    let problem: Value = draft(&server, "weather-column", &unknown).await.json().await.unwrap();
    assert_eq!(problem["errors"][0]["field"], "stepz", "{problem}");
    // A terrain from a job that does not exist: 422 on the field, as for a job.
    let mut missing = example("bulldoze", "ziggurat");
    missing["terrain"] = json!({"job": "0190a0a0-0000-7000-8000-000000000000"});
    let res = draft(&server, "bulldoze", &missing).await;
    assert_eq!(res.status(), 422);
    let problem: Value = res.json().await.unwrap();
    assert_eq!(problem["errors"][0]["field"], "terrain.job", "{problem}");
    // No such kind.
    assert_eq!(draft(&server, "nope", &body).await.status(), 404);
    // A draft of an earlier job's terrain reads it (coarser).
    let job = server.run("bulldoze", &example("bulldoze", "mound-box-add")).await;
    let mut on_it = example("erode", "eroded-island");
    on_it["terrain"] = json!({"job": job["id"]});
    on_it["iterations"] = json!(5);
    let res = draft(&server, "erode", &on_it).await;
    assert_eq!(res.status(), 200, "{:?}", res.text().await);
    // And nothing of the drafts was stored.
    let (_, list) = server.get_json("/v1/jobs").await;
    assert_eq!(list["items"].as_array().unwrap().len(), 1, "{list}");
}

/// Every example of `api/` drafts (the work cap refuses none of them), and a request of many
/// seconds' work even as a draft is refused naming the field that makes it so.
#[tokio::test(flavor = "multi_thread")]
async fn every_example_drafts_and_a_huge_request_is_refused() {
    // The service's own grid cap (the tests' default is smaller), so a cave of thousands of
    // sites is within the bounds and only the drafts' work cap refuses it.
    let options = Options { max_grid_cells: 4097 * 4097, ..Options::default() };
    let server = TestServer::start_with(options).await;
    let api = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("api");
    let mut kinds: Vec<_> = std::fs::read_dir(&api).unwrap().flatten().filter(|e| e.path().is_dir()).collect();
    kinds.sort_by_key(|e| e.file_name());
    let mut drafted = 0;
    for kind in kinds {
        let kind_name = kind.file_name().to_string_lossy().to_string();
        let mut files: Vec<_> = std::fs::read_dir(kind.path()).unwrap().flatten().map(|e| e.path()).collect();
        files.sort();
        for file in files.iter().filter(|f| f.extension().is_some_and(|x| x == "json")) {
            let body: Value = serde_json::from_slice(&std::fs::read(file).unwrap()).unwrap();
            let res = draft(&server, &kind_name, &body).await;
            assert_eq!(res.status(), 200, "{}: {:?}", file.display(), res.text().await);
            drafted += 1;
        }
    }
    assert!(drafted >= 40, "{drafted} examples");

    // Many seconds of work even as a draft (the job would take minutes): the work cap, on
    // `rings`, the field that makes it so.
    let long = json!({"chamber": {"width_m": 20, "depth_m": 20, "height_m": 5}, "sites": {"scatter": {"count": 2000}}, "rings": 256});
    let res = draft(&server, "grow-cave", &long).await;
    assert_eq!(res.status(), 422);
    let problem: Value = res.json().await.unwrap();
    assert_eq!(problem["errors"][0]["field"], "rings", "{problem}");
    assert!(problem["errors"][0]["message"].as_str().unwrap().contains("submit it as a job"), "{problem}");
}
