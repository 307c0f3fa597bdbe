//! Issue 50's measures of deform-terrain with the limits at their defaults, each by the test's
//! own calculation (`tests/deform_support/measures.rs`: central-difference slopes, its own
//! Priority-Flood, its own marching squares), on requests of our own at 129² with 2 m cells:
//! the faces beside a road or a pad keep to the cut and fill slopes asked for, the road's
//! cells keep their height, the ground no constraint needs stays put; a mask's sea has no
//! more closed pits than the input and its coast follows the polygon; a target that cannot be
//! met beside a road is named, and the road holds.

use serde_json::{json, Value};

use landform::jobs::Simulation;
use landform::sims::deform_terrain::{DeformTerrain, DeformTerrainParams};
use landform::terrain::resolve;

#[path = "../benches/support/mod.rs"]
mod support;

#[path = "deform_support/measures.rs"]
mod measures;
use measures::*;

struct Run {
    input: Vec<f64>,
    out: Vec<f64>,
    n: usize,
    cell: f64,
    result: Value,
}

impl Run {
    fn grids(&self) -> (Grid<'_>, Grid<'_>) {
        let g = |h| Grid { h, cols: self.n, rows: self.n, cell_m: self.cell };
        (g(&self.input), g(&self.out))
    }
}

fn run(body: Value) -> Run {
    let p: DeformTerrainParams = serde_json::from_value(body).expect("parses");
    support::with_context(|ctx| {
        let input = resolve(&p.terrain, ctx.terrain, ctx.limits).expect("terrain");
        let outcome = DeformTerrain::run(&p, 1, ctx).expect("runs");
        let npy = outcome.artifacts.iter().find(|a| a.name == "heightfield.npy").expect("npy");
        let hf = landform::export::read_heightfield_npy(&npy.bytes, input.cell_size_m).expect("npy");
        assert_eq!((hf.cols, hf.rows), (input.cols, input.rows));
        Run {
            input: input.heights_m.iter().map(|&v| v as f64).collect(),
            out: hf.heights_m.iter().map(|&v| v as f64).collect(),
            n: hf.cols,
            cell: hf.cell_size_m as f64,
            result: outcome.result,
        }
    })
}

/// The S-road's hills (the example's fractal) at 129² of 2 m.
fn hills() -> Value {
    json!({"fractal": {"size": 129, "cell_size": 2.0, "relief": 120.0, "octaves": 8, "roughness": 0.5, "seed": 7}})
}

/// The S-road example's path (metres).
fn s_path() -> Vec<(f64, f64)> {
    let body: Value = serde_json::from_str(include_str!("../api/deform-terrain/s-road.json")).unwrap();
    body["constraints"][0]["road"]["path"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p["x"].as_f64().unwrap(), p["z"].as_f64().unwrap()))
        .collect()
}

fn path_json(path: &[(f64, f64)]) -> Value {
    Value::Array(path.iter().map(|&(x, z)| json!({"x": x, "z": z})).collect())
}

/// Samples moved more than a metre within 25 m of the features, and the share of them steeper
/// than their face's slope + 5°; the largest change farther than `far_m` from every feature.
fn measure(r: &Run, distance: &dyn Fn(f64, f64) -> f64, cut_deg: f64, fill_deg: f64, far_m: f64) -> (Earthworks, f64) {
    let (a, b) = r.grids();
    let e = earthworks(&a, &b, distance, 25.0, 1.0, cut_deg, fill_deg, 5.0);
    let mut far = 0.0f64;
    for i in 0..r.n * r.n {
        let (x, z) = ((i % r.n) as f64 * r.cell, (i / r.n) as f64 * r.cell);
        if distance(x, z) > far_m {
            far = far.max((r.out[i] - r.input[i]).abs());
        }
    }
    (e, far)
}

#[test]
fn cuttings_and_embankments_keep_to_their_slopes_and_the_road_to_its_height() {
    let path = s_path();
    let road_distance = |x: f64, z: f64| (to_path(&path, x, z) - 3.0).max(0.0);
    // The defaults (cut 1V:1.5H, fill 1V:2H), then slopes of our own: cuttings at 45°, fills
    // at 1V:3H.
    for (earthworks, cut_deg, fill_deg) in [
        (None, degrees_of(1.5), degrees_of(2.0)),
        (Some(json!({"cut_slope": {"degrees": 45.0}, "fill_slope": {"h_per_v": 3.0}})), 45.0, degrees_of(3.0)),
    ] {
        let mut body = json!({
            "terrain": hills(),
            "constraints": [{"road": {"path": path_json(&path), "width_m": 6.0, "height": {"constant": 70.0}}}],
            "max_iterations": 1000
        });
        if let Some(e) = &earthworks {
            body["earthworks"] = e.clone();
        }
        let r = run(body);
        let (e, far) = measure(&r, &road_distance, cut_deg, fill_deg, 80.0);
        eprintln!("{earthworks:?}: {e:?}, far {far} m, limits {}", r.result["limits"]);
        assert!(e.moved > 500, "{} samples moved beside the road", e.moved);
        assert!(e.steep_share() <= 0.10, "{:.1} % of moved samples too steep: {e:?}", 100.0 * e.steep_share());
        // The road's cells (within 2.9 m of the centreline, clear of the edge's rounding) on
        // their 70 m, on the f32 heights.
        let worst = (0..r.n * r.n)
            .filter(|&i| to_path(&path, (i % r.n) as f64 * r.cell, (i / r.n) as f64 * r.cell) <= 2.9)
            .fold(0.0f64, |m, i| m.max((r.out[i] - 70.0).abs()));
        assert!(worst <= 1e-3, "road cells up to {worst} m off 70 m");
        // Ground farther than 80 m from the road (past every cutting on these hills) within
        // a tenth of the relief of its input.
        assert!(far <= 12.0, "ground far from the road moved {far} m");
        assert_eq!(r.result["conflicts"], json!([]), "{}", r.result["conflicts"]);
    }
}

#[test]
fn a_switchback_and_a_pad_beside_a_road_keep_to_the_default_slopes() {
    let legs = vec![(40.0, 40.0), (210.0, 60.0), (60.0, 110.0), (210.0, 160.0), (50.0, 215.0)];
    let switchback = run(json!({
        "terrain": hills(),
        "constraints": [{"road": {"path": path_json(&legs), "width_m": 5.0, "height": {"profile": {"max_gradient_percent": 8.0}}}}]
    }));
    let (e, far) =
        measure(&switchback, &|x, z| (to_path(&legs, x, z) - 2.5).max(0.0), degrees_of(1.5), degrees_of(2.0), 60.0);
    eprintln!("switchback: {e:?}, far {far} m");
    assert!(e.moved > 500 && e.steep_share() <= 0.10, "{e:?}");
    // Both legs of every hairpin on their profile: no conflict, even where the legs touch.
    assert_eq!(switchback.result["conflicts"], json!([]));
    assert_eq!(switchback.result["constraints"][0]["max_error_of_relief"], json!(0.0));

    // A pad 30 m × 50 m, 11 m off a road graded 6 %, at the ground's height on the road beside it.
    let road = vec![(20.0, 128.0), (236.0, 128.0)];
    let pad = vec![(100.0, 145.0), (150.0, 145.0), (150.0, 180.0), (100.0, 180.0)];
    let hills_input = support::with_context(|ctx| {
        resolve(&serde_json::from_value(hills()).unwrap(), ctx.terrain, ctx.limits).unwrap()
    });
    let level = hills_input.heights_m[64 * 129 + 62].round() as f64;
    let r = run(json!({
        "terrain": hills(),
        "constraints": [
            {"road": {"path": path_json(&road), "width_m": 6.0, "height": {"profile": {"max_gradient_percent": 6.0}}}},
            {"terraces": {"regions": [{"polygon_m": path_json(&pad), "level_m": level}]}}
        ]
    }));
    let distance = |x: f64, z: f64| (to_path(&road, x, z) - 3.0).max(0.0).min(to_polygon(&pad, x, z));
    let (e, far) = measure(&r, &distance, degrees_of(1.5), degrees_of(2.0), 60.0);
    eprintln!("pad: {e:?}, far {far} m, conflicts {}", r.result["conflicts"]);
    assert!(e.moved > 300 && e.steep_share() <= 0.10, "{e:?}");
    // The pad's inside (a cell in from its edge) on its level.
    let mut worst = 0.0f64;
    for i in 0..r.n * r.n {
        let (x, z) = ((i % r.n) as f64 * r.cell, (i / r.n) as f64 * r.cell);
        if (104.0..=146.0).contains(&x) && (149.0..=176.0).contains(&z) {
            worst = worst.max((r.out[i] - level).abs());
        }
    }
    assert!(worst <= 1e-3, "pad up to {worst} m off its {level} m");
}

#[test]
fn a_masks_sea_digs_no_pits_and_its_coast_follows_the_polygon() {
    // The star island example's mask and fractal, at 129² of 2 m.
    let mut body: Value = serde_json::from_str(include_str!("../api/deform-terrain/star-island.json")).unwrap();
    body.as_object_mut().unwrap().remove("label");
    body.as_object_mut().unwrap().remove("seed");
    body["terrain"]["fractal"]["size"] = json!(129);
    body["terrain"]["fractal"]["cell_size"] = json!(2.0);
    let r = run(body);
    let level = r.result["constraints"][0]["water_level_m"].as_f64().unwrap();
    let (a, b) = r.grids();
    let (pits_in, pits_out) = (sea_pit_share(&a, level, 0.5), sea_pit_share(&b, level, 0.5));
    let ((rough_in, n_in), (rough_out, n_out)) = (coast_roughness(&a, level, 2.0), coast_roughness(&b, level, 2.0));
    eprintln!("pits {pits_in} → {pits_out}; coast roughness {rough_in} ({n_in} points) → {rough_out} ({n_out})");
    assert!(pits_out <= 2.0 * pits_in + 0.01, "sea in pits: {pits_out} against the input's {pits_in}");
    assert!(n_in > 100 && n_out > 100);
    assert!(rough_out <= 1.5 * rough_in, "coast roughness {rough_out} against the input's {rough_in}");
    assert_eq!(r.result["constraints"][0]["correct_side_share"], json!(1.0));
}

#[test]
fn a_point_high_above_a_road_beside_it_is_named_and_the_road_holds() {
    let body = json!({
        "terrain": {"fractal": {"size": 65, "cell_size": 2.0, "relief": 40.0, "seed": 11}},
        "constraints": [
            {"road": {"path": [{"x": 10, "z": 64}, {"x": 118, "z": 64}], "width_m": 6.0, "height": {"constant": 20.0}}},
            {"points": {"points": [{"x": 64, "z": 74, "height": 60.0}]}}
        ]
    });
    let r = run(body);
    let (_, b) = r.grids();
    let road = (0..r.n * r.n)
        .filter(|&i| {
            let (x, z) = ((i % r.n) as f64 * r.cell, (i / r.n) as f64 * r.cell);
            (10.0..=118.0).contains(&x) && (z - 64.0).abs() <= 2.9
        })
        .fold(0.0f64, |m, i| m.max((b.h[i] - 20.0).abs()));
    assert!(road <= 1e-3, "the road up to {road} m off its height");
    // The point 8 m from the road's nearest cell (z 66 m): the cutting's face at 1V:1.5H from
    // it lets the point rise to 20 + 8 / 1.5 = 25.33 m (a path over the grid up to 3 % longer).
    let point = b.h[37 * r.n + 32];
    assert!((20.0 + 8.0 / 1.5 - 0.01..=20.0 + 8.0 * 1.03 / 1.5).contains(&point), "the point at {point} m");
    let conflicts = r.result["conflicts"].as_array().unwrap();
    assert_eq!(conflicts.len(), 1, "{conflicts:?}");
    let c = &conflicts[0];
    assert_eq!((c["kind"].as_str(), c["constraint"].as_u64()), (Some("points"), Some(1)));
    assert_eq!((c["held_by"]["kind"].as_str(), c["held_by"]["constraint"].as_u64()), (Some("road"), Some(0)));
    assert!((c["missed_by_m"].as_f64().unwrap() - (point - 60.0)).abs() < 1e-3, "{c}");
    assert_eq!((c["at"]["x_m"].as_f64(), c["at"]["z_m"].as_f64()), (Some(64.0), Some(74.0)));
}
