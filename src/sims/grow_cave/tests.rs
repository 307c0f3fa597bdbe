//! Table 2 row by row, the stop conditions, columns, wind, Table 1's colours, closed meshes,
//! replay and thread-count determinism.

use serde_json::{json, Value};

use super::growth::Ring;
use super::params::{Co2, DripInterval, Mineral};
use super::*;
use crate::sims::test_support::TestContext;
use crate::terrain::Heightfield;
use crate::validate::{Limits, Validate, Validator};

pub(super) fn params(v: Value) -> GrowCaveParams {
    let p: GrowCaveParams = serde_json::from_value(v).expect("parses");
    let mut val = Validator::new();
    p.validate(&mut val, &Limits::default());
    assert!(val.is_ok(), "{:?}", val.errors);
    p
}

/// One drip site in a tall chamber, fixed conditions, no wind, no displacement.
fn one_site(level: &str, drip: &str, co2: &str, rings: u32) -> GrowCaveParams {
    params(json!({
        "chamber": {"width_m": 4, "depth_m": 4, "height_m": 40},
        "sites": {"explicit": [{"x_m": 2, "z_m": 2}]},
        "conditions": {"pluviometric_index": level, "drip_interval": drip, "co2": co2},
        "rings": rings,
        "kf_m": 0.0,
    }))
}

fn grown(p: &GrowCaveParams, seed: u64) -> CaveSequence {
    grow(p, seed, &mut |_, _| Ok(())).expect("grows")
}

/// Check each ring after the first against (radius step multiple, height multiple).
fn assert_row(rings: &[Ring], row: (i32, u32), p: &GrowCaveParams, what: &str) {
    assert!(rings.len() > 3, "{what}: {} rings", rings.len());
    let (dr, dh) = (p.radius_step_m, p.height_step_m);
    for w in rings.windows(2) {
        let (before, ring) = (w[0], w[1]);
        let h = ring.height() / (row.1 as f32 * dh);
        assert!((0.5 - 1e-4..=1.5 + 1e-4).contains(&h), "{what}: height {} is {h} × its step", ring.height());
        let change = ring.radius() - before.radius();
        match row.0 {
            0 => assert_eq!(change, 0.0, "{what}: radius stays"),
            k => {
                let steps = change / (k as f32 * dr);
                // A ring clamped at radius 0 shrinks by less than a full step.
                let clamped = ring.radius() == 0.0 && steps > 0.0;
                assert!(
                    clamped || (0.5 - 1e-3..=1.5 + 1e-3).contains(&steps),
                    "{what}: radius change {change} is {steps} × {k} steps"
                );
            }
        }
    }
}

fn stalactite_row_holds(co2: &str, row: (i32, u32)) {
    let p = one_site("1", "standard", co2, 12);
    let s = &grown(&p, 1).sites[0].growth;
    assert!(s.stalagmite.is_empty(), "level 1 does not drip");
    assert_row(&s.stalactite, row, &p, &format!("stalactite at {co2} CO2"));
}

fn stalagmite_row_holds(drip: &str, co2: &str, row: (i32, u32)) {
    let p = one_site("2", drip, co2, 12);
    let s = &grown(&p, 2).sites[0].growth;
    assert_row(&s.stalagmite, row, &p, &format!("stalagmite {drip} {co2}"));
    assert_eq!(s.stalagmite[0].pass(), s.stalactite[0].pass(), "the drip falls from the first pass");
}

/// One test per row of Table 2: (radius direction × multiple, height multiple).
macro_rules! table_2 {
    ($($name:ident: $check:expr;)*) => { $( #[test] fn $name() { $check } )* };
}

table_2! {
    table_2_level_1_low_co2_stalactite_radius_down_2_height_1: stalactite_row_holds("low", (-2, 1));
    table_2_level_1_normal_co2_stalactite_radius_down_1_height_2: stalactite_row_holds("normal", (-1, 2));
    table_2_level_1_high_co2_stalactite_radius_same_height_3: stalactite_row_holds("high", (0, 3));
    table_2_level_2_dry_low_stalagmite_radius_down_1_height_1: stalagmite_row_holds("dry", "low", (-1, 1));
    table_2_level_2_standard_low_stalagmite_radius_same_height_1: stalagmite_row_holds("standard", "low", (0, 1));
    table_2_level_2_wet_low_stalagmite_radius_up_1_height_1: stalagmite_row_holds("wet", "low", (1, 1));
    table_2_level_2_dry_normal_stalagmite_radius_down_1_height_2: stalagmite_row_holds("dry", "normal", (-1, 2));
    table_2_level_2_standard_normal_stalagmite_radius_same_height_2: stalagmite_row_holds("standard", "normal", (0, 2));
    table_2_level_2_wet_normal_stalagmite_radius_up_1_height_2: stalagmite_row_holds("wet", "normal", (1, 2));
    table_2_level_2_dry_high_stalagmite_radius_down_1_height_3: stalagmite_row_holds("dry", "high", (-1, 3));
    table_2_level_2_standard_high_stalagmite_radius_same_height_3: stalagmite_row_holds("standard", "high", (0, 3));
    table_2_level_2_wet_high_stalagmite_radius_up_1_height_3: stalagmite_row_holds("wet", "high", (1, 3));
}

#[test]
fn the_rows_drawn_are_table_2s() {
    assert_eq!(growth::stalactite_row(Co2::Normal), (-1, 2));
    assert_eq!(growth::stalagmite_row(DripInterval::Wet, Co2::High), (1, 3));
}

#[test]
fn level_0_grows_nothing() {
    let p = one_site("0", "standard", "normal", 10);
    let seq = grown(&p, 1);
    assert!(seq.sites[0].growth.stalactite.is_empty() && seq.sites[0].growth.stalagmite.is_empty());
    let (result, _) =
        outputs::build(&p, &seq, crate::stop::Stop::NEVER, &crate::export::MeshSettings::default()).unwrap();
    assert_eq!(result["stalactites"]["count"], 0);
    assert_eq!(result["stalagmites"]["count"], 0);
    assert_eq!(result["triangles"]["speleothems"], 0);
}

#[test]
fn a_stalactite_meeting_its_stalagmite_becomes_one_column_and_stops() {
    let mut p = one_site("2", "standard", "high", 60);
    p.chamber.height_m = 1.2;
    let seq = grown(&p, 3);
    let g = &seq.sites[0].growth;
    let at = g.column_at.expect("they met");
    assert!((g.stalactite_tip_y() - g.stalagmite_top_y()).abs() < 1e-4, "the column is continuous");
    let rings = (g.stalactite.len(), g.stalagmite.len());
    assert_eq!(g.stalactite.last().unwrap().pass(), at);
    // More passes grow nothing more.
    let mut longer = p.clone();
    longer.rings = 100;
    let again = grown(&longer, 3);
    assert_eq!((again.sites[0].growth.stalactite.len(), again.sites[0].growth.stalagmite.len()), rings);
    let (result, _) =
        outputs::build(&p, &seq, crate::stop::Stop::NEVER, &crate::export::MeshSettings::default()).unwrap();
    assert_eq!(result["columns"]["count"], 1);
    assert_eq!(result["stalactites"]["count"], 0);
    assert!((result["columns"]["length_m"]["max"].as_f64().unwrap() - 1.2).abs() < 1e-4);
}

#[test]
fn wind_moves_rings_along_its_direction_only() {
    let mut p = one_site("2", "standard", "normal", 20);
    p.wind = Some(serde_json::from_value(json!({"direction": [1.0, 0.0], "intensity": 0.6})).unwrap());
    let g = grown(&p, 4).sites[0].growth.clone();
    for ring in &g.stalactite[1..] {
        let [dx, dz] = ring.shift();
        assert!(dx > 0.0 && dz.abs() < 1e-6, "shift {dx}, {dz}");
        assert!((dx - 0.6 * ring.height()).abs() < 1e-5);
    }
    // The stalagmite is not blown: it follows the drip point downwind.
    assert!(g.stalagmite.iter().all(|r| r.shift()[0] >= 0.0 && r.shift()[1].abs() < 1e-6));
    assert!(g.stalagmite_top_xz()[0] > g.x_m);
    // Random intensity per ring: never against the wind, sometimes calm.
    p.wind = Some(serde_json::from_value(json!({"direction": [0.0, -2.0]})).unwrap());
    let g = grown(&p, 4).sites[0].growth.clone();
    assert!(g.stalactite.iter().all(|r| r.shift()[1] <= 0.0 && r.shift()[0].abs() < 1e-6));
    assert!(g.stalactite.iter().map(|r| r.shift()[1]).sum::<f32>() < 0.0);
}

#[test]
fn low_co2_displaces_the_surface_by_kf_times_radius_ratio() {
    let mut p = one_site("1", "standard", "low", 8);
    p.kf_m = 0.02;
    let g = grown(&p, 5).sites[0].growth.clone();
    for ring in &g.stalactite[1..] {
        let expected = p.kf_m * ring.radius() / p.stalactite_radius_m;
        assert!((ring.displacement() - expected).abs() < 1e-6);
    }
}

#[test]
fn each_minerals_tip_colour_is_table_1s() {
    for (mineral, rgb) in [
        (Mineral::Calcareous, [0.8, 0.8, 0.8]),
        (Mineral::Iron, [0.87, 0.62, 0.34]),
        (Mineral::Manganese, [0.32, 0.44, 0.54]),
        (Mineral::Copper, [0.05, 0.7, 0.7]),
        (Mineral::Malachite, [0.67, 0.82, 0.75]),
    ] {
        let mut p = one_site("1", "standard", "normal", 10);
        p.mineral = mineral;
        let seq = grown(&p, 6);
        let scene = outputs::scene(&p, &seq);
        let node = scene.nodes.iter().find(|n| n.name.starts_with("stalactite")).expect("a stalactite");
        let m = &node.mesh;
        // The tip: the lowest vertex.
        let tip = (0..m.vertex_count()).min_by(|&a, &b| m.positions[a][1].total_cmp(&m.positions[b][1])).unwrap();
        let want = rgb.map(|c: f32| (c * 255.0).round() as u8);
        assert_eq!(&m.colors.as_ref().unwrap()[tip][..3], &want[..], "{mineral:?}");
        // The base is darker: fv_c = mc · (arID / rc).
        let base = (0..m.vertex_count()).max_by(|&a, &b| m.positions[a][1].total_cmp(&m.positions[b][1])).unwrap();
        let sum = |c: &[u8]| c.iter().map(|&v| v as u32).sum::<u32>();
        assert!(sum(&m.colors.as_ref().unwrap()[base][..3]) < sum(&want));
    }
}

fn random_cave(sites: u32, rings: u32) -> GrowCaveParams {
    params(json!({
        "chamber": {"width_m": 8, "depth_m": 6, "height_m": 5, "roof": {"relief_m": 0.6}, "floor": {"relief_m": 0.4}},
        "sites": {"scatter": {"count": sites, "min_spacing_m": 0.6}},
        "conditions": {"pluviometric_index": "random", "drip_interval": "random", "co2": "random"},
        "mineral": "random",
        "rings": rings,
        "segments": 12,
        "height_step_m": 0.06,
        "wind": {"scale": 0.5},
    }))
}

#[test]
fn every_speleothem_mesh_is_closed_and_faces_out() {
    let p = random_cave(30, 60);
    let seq = grown(&p, 7);
    let scene = outputs::scene(&p, &seq);
    let mut kinds = std::collections::BTreeMap::new();
    for node in &scene.nodes[2..] {
        assert!(node.mesh.check().is_ok());
        assert!(node.mesh.is_closed(), "{} is not closed", node.name);
        assert!(node.mesh.signed_volume() > 0.0, "{} faces inwards", node.name);
        *kinds.entry(node.name.split(' ').next().unwrap().to_string()).or_insert(0) += 1;
    }
    assert!(kinds.len() >= 2, "{kinds:?}");
}

/// Each speleothem's origin in a glb is its root: the drip site's point on the roof (a
/// stalactite) or the floor (a stalagmite, a column standing on it), recomputed here from the
/// chamber's relief, to 1 mm; and the piece's own surface crosses that level around it.
#[test]
fn each_piece_pivots_at_its_root_on_the_roof_or_floor() {
    let p = random_cave(30, 60);
    let seq = grown(&p, 7);
    let scene = outputs::scene(&p, &seq);
    let shape = ChamberShape::new(&p.chamber, seq.seed);
    let mut kinds = std::collections::BTreeMap::new();
    for node in &scene.nodes[1..] {
        let (kind, index) = node.name.split_once(' ').expect("kind and site");
        let site = &seq.sites[index.parse::<usize>().expect("a site number")].growth;
        let y = if kind == "stalactite" { shape.roof_y(site.x_m, site.z_m) } else { shape.floor_y(site.x_m, site.z_m) };
        let pivot = node.pivot();
        let off = [pivot[0] - site.x_m, pivot[1] - y, pivot[2] - site.z_m];
        assert!(off.iter().map(|d| d * d).sum::<f32>().sqrt() < 1e-3, "{}: pivot {pivot:?} is {off:?} off", node.name);
        // The surface runs from inside the rock past the pivot's level, and the vertices
        // nearest that level surround the pivot.
        let (lo, hi) = node.mesh.bounds().expect("a mesh");
        assert!(lo[1] < pivot[1] && pivot[1] < hi[1], "{}: {lo:?}..{hi:?} misses {pivot:?}", node.name);
        let mut by_level: Vec<[f32; 3]> = node.mesh.positions.clone();
        by_level.sort_by(|a, b| (a[1] - pivot[1]).abs().total_cmp(&(b[1] - pivot[1]).abs()));
        let ring = &by_level[..p.segments as usize];
        let (mut xz_lo, mut xz_hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for v in ring {
            for (k, c) in [v[0], v[2]].into_iter().enumerate() {
                xz_lo[k] = xz_lo[k].min(c);
                xz_hi[k] = xz_hi[k].max(c);
            }
        }
        let inside = (0..2).all(|k| xz_lo[k] <= [pivot[0], pivot[2]][k] && [pivot[0], pivot[2]][k] <= xz_hi[k]);
        assert!(inside, "{}: pivot {pivot:?} outside its ring {xz_lo:?}..{xz_hi:?}", node.name);
        *kinds.entry(kind.to_string()).or_insert(0) += 1;
    }
    assert!(kinds.len() >= 2, "{kinds:?}");
    // The chamber has no pivot of its own: the middle of the bottom of its box.
    let (lo, hi) = scene.nodes[0].mesh.bounds().expect("the chamber");
    let want = [(lo[0] + hi[0]) / 2.0, lo[1], (lo[2] + hi[2]) / 2.0];
    assert!(scene.nodes[0].pivot().iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-5), "{want:?}");
}

#[test]
fn manual_rings_are_used_as_given() {
    let mut p = one_site("2", "standard", "normal", 10);
    p.manual = Some(
        serde_json::from_value(json!({
            "stalactite": [{"radius_m": 0.07, "height_m": 0.1}, {"radius_m": 0.05, "height_m": 0.2}],
            "stalagmite": [{"radius_m": 0.2, "height_m": 0.05}],
        }))
        .unwrap(),
    );
    let g = grown(&p, 8).sites[0].growth.clone();
    let radii: Vec<f32> = g.stalactite.iter().map(Ring::radius).collect();
    assert_eq!(radii, [0.08, 0.07, 0.05]);
    assert_eq!(g.stalactite[2].height(), 0.2);
    assert_eq!(g.stalagmite.len(), 2);
    assert_eq!(g.stalagmite[1].radius(), 0.2);
}

fn ctx() -> TestContext {
    TestContext::new(Heightfield::from_fn(2, 2, 1.0, |_, _| 0.0))
}

/// Artifact names and sha256s.
pub(super) fn bytes(o: &Outcome<CaveSequence>) -> Vec<(String, String)> {
    o.artifacts
        .iter()
        .map(|a| (a.name.clone(), hex::encode(<sha2::Sha256 as sha2::Digest>::digest(&a.bytes))))
        .collect()
}

#[test]
fn replay_until_k_equals_a_run_of_k_passes() {
    let t = ctx();
    let p = random_cave(12, 40);
    let full = GrowCave::run(&p, 9, &t.ctx()).unwrap();
    let again = GrowCave::replay(&p, &full.sequence, None, &t.ctx()).unwrap();
    assert_eq!(bytes(&again), bytes(&full));
    assert_eq!(again.result, full.result);
    let k = 15;
    let part = GrowCave::replay(&p, &full.sequence, Some(k), &t.ctx()).unwrap();
    let short = GrowCave::run(&GrowCaveParams { rings: k as u32, ..p.clone() }, 9, &t.ctx()).unwrap();
    assert_eq!(bytes(&part), bytes(&short));
    assert_eq!(part.result, short.result);
    assert_eq!(serde_json::to_value(&part.sequence).unwrap(), serde_json::to_value(&short.sequence).unwrap());
    assert_ne!(bytes(&part), bytes(&full));
}

#[test]
fn one_and_two_threads_give_identical_artifacts() {
    let p = random_cave(40, 30);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| GrowCave::run(&p, 10, &ctx().ctx()).unwrap())
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(bytes(&one), bytes(&two));
    assert_eq!(one.result, two.result);
}

#[test]
fn each_pass_can_publish_a_live_snapshot_of_the_cave() {
    use crate::jobs::Simulation;
    let p = random_cave(12, 30);
    let test = TestContext::new(Heightfield::from_fn(2, 2, 1.0, |_, _| 0.0));
    let sink = crate::sims::test_support::EverySnapshot::default();
    let out = GrowCave::run(&p, 3, &test.ctx_reporting_to(&sink)).expect("grows");
    let snapshots = sink.0.into_inner().unwrap();
    assert_eq!(snapshots.len() as u64, out.sequence.passes as u64, "one per pass");
    let (info, _) = crate::export::test_png::decode(snapshots.last().unwrap());
    assert_eq!((info.width, info.height), (256, 192));
}

/// A wet, windy cave of many sites in a low chamber: columns, touching tips, speleothems
/// stopped at the roof or floor.
fn windy_cave() -> GrowCaveParams {
    params(json!({
        "chamber": {"width_m": 6, "depth_m": 6, "height_m": 1.6, "roof": {"relief_m": 0.3}, "floor": {"relief_m": 0.2}},
        "sites": {"scatter": {"count": 12, "min_spacing_m": 0.8}},
        "conditions": {"pluviometric_index": "random", "drip_interval": "random", "co2": "random"},
        "rings": 40,
        "height_step_m": 0.05,
        "wind": {"scale": 0.6},
    }))
}

#[test]
fn stalagmites_grow_under_the_drip_point_and_never_overlap_their_stalactite() {
    let (mut columns, mut checked) = (0, 0);
    for seed in 0..50 {
        let p = windy_cave();
        let seq = grown(&p, seed);
        for site in &seq.sites {
            let g = &site.growth;
            columns += g.column_at.is_some() as usize;
            for k in 1..=p.rings {
                let then = g.until(k);
                // Never past each other: the tip hangs at or above the stalagmite's top.
                if !then.stalactite.is_empty() && !then.stalagmite.is_empty() {
                    assert!(then.stalactite_tip_y() >= then.stalagmite_top_y() - 1e-4, "seed {seed}, pass {k}");
                }
                // A stalagmite ring grown in pass k stands under the drip point of pass k.
                if then.stalagmite.last().is_some_and(|r| r.pass() == k) {
                    let (drip, top) = (then.drip_point(), then.stalagmite_top_xz());
                    assert!(
                        (drip[0] - top[0]).abs() < 1e-4 && (drip[1] - top[1]).abs() < 1e-4,
                        "seed {seed}, pass {k}: {drip:?} vs {top:?}"
                    );
                    checked += 1;
                }
            }
            // Joined or touching, they meet exactly.
            if g.column_at.is_some() {
                assert!((g.stalactite_tip_y() - g.stalagmite_top_y()).abs() < 1e-4);
            }
        }
    }
    assert!(columns > 20 && checked > 500, "{columns} columns, {checked} stalagmite rings checked");
}

#[test]
fn a_run_of_k_passes_is_the_first_k_passes_of_a_longer_run() {
    for seed in 0..50 {
        let p = windy_cave();
        let full = grown(&p, seed);
        for k in [1, 5, 12, 25] {
            let short = grown(&GrowCaveParams { rings: k, ..p.clone() }, seed);
            for (a, b) in short.sites.iter().zip(&full.sites) {
                let cut = b.growth.until(k);
                assert_eq!(
                    serde_json::to_value(&a.growth).unwrap(),
                    serde_json::to_value(&cut).unwrap(),
                    "seed {seed}, k {k}"
                );
            }
        }
    }
}

/// Scattered sites and their merges found through the grid of near points are those of the
/// plain search against every earlier site (written out here as it was), so a cave keeps its
/// shape: crowded and sparse, several seeds.
#[test]
fn scattered_sites_and_merges_match_the_search_against_every_site() {
    use rand::Rng;
    for (count, spacing, seed) in
        [(3000u32, 0.25f32, 3u64), (800, 0.6, 11), (200, 0.0, 5), (1500, 2.0, 7), (300, 1e-30, 9)]
    {
        let p = params(json!({"sites": {"scatter": {"count": count, "min_spacing_m": spacing}}}));
        let c = &p.chamber;
        let margin = p.stalactite_radius_m.max(p.stalagmite_radius_m).min(c.width_m.min(c.depth_m) / 4.0);
        let mut rng = growth::site_rng(seed, usize::MAX - 1);
        let mut expected: Vec<(f32, f32)> = Vec::new();
        for _ in 0..count {
            let mut best: Option<(f32, f32, f32)> = None;
            for _ in 0..30 {
                let x = rng.random_range(margin..=c.width_m - margin);
                let z = rng.random_range(margin..=c.depth_m - margin);
                let gap = expected.iter().map(|s| (s.0 - x).hypot(s.1 - z)).fold(f32::INFINITY, f32::min);
                if best.is_none_or(|(_, _, g)| gap > g) {
                    best = Some((x, z, gap));
                }
                if gap >= spacing {
                    break;
                }
            }
            let (x, z, _) = best.unwrap();
            expected.push((x, z));
        }
        let placed: Vec<(f32, f32)> = chamber::drip_sites(&p, seed).iter().map(|s| (s.x_m, s.z_m)).collect();
        assert_eq!(placed, expected, "{count} sites {spacing} m apart, seed {seed}");

        let radius = p.stalactite_radius_m + p.kf_m;
        let reach = 2.0 * radius + neighbours::MARGIN_M;
        let mut merged: Vec<Option<u32>> = vec![None; placed.len()];
        for i in 0..placed.len() {
            let (x, z) = placed[i];
            merged[i] = (0..i)
                .find(|&j| merged[j].is_none() && (placed[j].0 - x).hypot(placed[j].1 - z) < reach)
                .map(|j| j as u32);
        }
        assert_eq!(neighbours::merges(&placed, radius), merged);
        assert!(merged.iter().any(Option::is_some) || spacing >= reach, "the case merges nothing: {count}, {spacing}");
    }
}
