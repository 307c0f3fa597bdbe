//! Measured on the sampled field and the mesh: no overhang without carving, overhangs only near
//! sea level with it, no floating fragment, closed meshes, replay, thread-count determinism.

use crate::export::MeshSettings;
use serde_json::{json, Value};

use super::field::{bands, columns, grid_for, sample_planes};
use super::outputs::{build, sample, surface, topology};
use super::*;
use crate::sims::test_support::TestContext;
use crate::terrain::generate_fractal;
use crate::validate::{Validate, Validator};

fn params(v: Value) -> CarveCoastParams {
    let p: CarveCoastParams = serde_json::from_value(v).expect("parses");
    let mut val = Validator::new();
    p.validate(&mut val, &Limits::default());
    assert!(val.is_ok(), "{:?}", val.errors);
    p
}

fn island(size: u32, probability: f32) -> CarveCoastParams {
    params(json!({
        "terrain": {"fractal": {"size": size, "cell_size": 1.0, "relief": 60.0, "seed": 3, "island": true}},
        "sea_level": 0.0,
        "erosion": {"seed_acceptance_probability": probability, "radius_range": [1.5, 3.5]},
        "passes": 2,
    }))
}

fn terrain(p: &CarveCoastParams) -> Heightfield {
    match &p.terrain {
        TerrainSource::Fractal(f) => generate_fractal(f),
        _ => unreachable!("tests use fractal terrain"),
    }
}

fn no_progress(_: usize, _: usize) -> Result<(), SimError> {
    Ok(())
}

#[test]
fn without_carving_or_warp_every_column_crosses_once_at_the_heightfield() {
    let p = island(65, 0.0);
    let hf = terrain(&p);
    let spheres = carve(&p, &hf, 1, 1.0, Stop::NEVER, &mut |_, _| Ok(())).unwrap();
    assert!(spheres.is_empty());
    let implicit = Implicit::new(&hf, &spheres, None, 1);
    let s = sample(&implicit, &p, 1.0, false, &mut no_progress).unwrap();
    let (crossings, top) = columns(&s.values, &s.grid);
    let g = s.grid;
    let mut worst = 0.0f32;
    for z in 1..g.nz - 1 {
        for x in 1..g.nx - 1 {
            let k = x + g.nx * z;
            assert_eq!(crossings[k], 1, "column {x},{z}");
            worst = worst.max((top.heights_m[k] - hf.sample(x as f32, z as f32)).abs());
        }
    }
    assert!(worst <= 0.5 * g.voxel_m, "topmost surface off by {worst} m");
    let mesh = surface(&s, Stop::NEVER).unwrap();
    assert!(mesh.is_closed());
    assert_eq!(topology(&mesh), (1, 0), "one solid, no through-hole");
    // The caps lie flat just inside the box (1/1024 of a voxel, where the extraction keeps
    // vertices off the box's samples): nothing below its bottom or beyond its walls.
    let (lo, hi) = mesh.bounds().unwrap();
    let inset = crate::mesh::MIN_CROSSING * g.voxel_m;
    assert_eq!(lo[1], g.bottom_y + inset);
    assert!(lo[0] >= 0.0 && lo[2] >= 0.0 && hi[0] <= hf.width_m() && hi[2] <= hf.depth_m());
    let bottom = mesh.positions.iter().filter(|p| p[1] < g.bottom_y + 0.5 * g.voxel_m).count();
    let flat = mesh.positions.iter().filter(|p| p[1] == lo[1]).count();
    assert_eq!(bottom, flat, "every bottom vertex on the bottom plane");
    assert_eq!(mesh.degeneracies(), (0, 0), "no zero-area triangle, no shared position");
}

#[test]
fn carving_makes_overhangs_only_around_sea_level() {
    let p = island(129, 0.15);
    let hf = terrain(&p);
    let spheres = carve(&p, &hf, 2, 1.0, Stop::NEVER, &mut |_, _| Ok(())).unwrap();
    assert!(spheres.len() > 20, "{} spheres", spheres.len());
    assert!(spheres.iter().any(|s| s.pass() == 2), "the second pass seeds on the carved surface");
    let implicit = Implicit::new(&hf, &spheres, None, 2);
    let (result, _) =
        build(&implicit, &p, &spheres, 1.0, &mut no_progress, Stop::NEVER, &MeshSettings::default()).unwrap();
    assert!(result["overhangs"]["with_overhang"].as_u64().unwrap() > 0, "{result}");
    assert_eq!(result["mesh"]["closed"], true);
    // Compare carved and uncarved fields sample by sample.
    let plain = Implicit::new(&hf, &[], None, 2);
    let grid = grid_for(&hf, 1.0, 1.0);
    let dense = bands(&implicit, &grid, 0.0, true);
    let mut a = vec![0f32; grid.len()];
    let mut b = vec![0f32; grid.len()];
    sample_planes(&implicit, &grid, &dense, 0..grid.ny, &mut a);
    sample_planes(&plain, &grid, &dense, 0..grid.ny, &mut b);
    let r = p.erosion.radius_range[1];
    let (lo, hi) = (p.erosion.seed_elevation_range[0] - r, p.erosion.seed_elevation_range[1] + r);
    let mut carved = 0;
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        if (*x > 0.0) != (*y > 0.0) {
            carved += 1;
            let height = grid.y_m(i / grid.plane());
            assert!((lo..=hi).contains(&height), "carved at {height} m, outside {lo}..{hi}");
        }
    }
    assert!(carved > 100, "{carved} samples carved");
}

#[test]
fn floating_fragments_are_removed() {
    // A pillar whose foot a sphere cuts through: its top floats.
    let hf =
        Heightfield::from_fn(
            33,
            33,
            1.0,
            |x, z| if (x - 16.0).abs() <= 2.0 && (z - 16.0).abs() <= 2.0 { 20.0 } else { 0.0 },
        );
    let spheres = [Sphere([16.0, 6.0, 16.0, 4.5], 1)];
    let mut p = island(33, 0.0);
    p.sea_level = 1.0;
    let implicit = Implicit::new(&hf, &spheres, None, 1);
    let (kept, _) = build(
        &implicit,
        &CarveCoastParams { remove_fragments: false, ..p.clone() },
        &spheres,
        1.0,
        &mut no_progress,
        Stop::NEVER,
        &MeshSettings::default(),
    )
    .unwrap();
    assert!(kept["pieces"].as_u64().unwrap() >= 2, "{kept}");
    let (result, _) =
        build(&implicit, &p, &spheres, 1.0, &mut no_progress, Stop::NEVER, &MeshSettings::default()).unwrap();
    assert_eq!(result["pieces"], 1, "{result}");
    assert!(result["fragments_removed"].as_u64().unwrap() >= 1);
    assert_eq!(result["mesh"]["closed"], true);
}

#[test]
fn warp_makes_strata_on_cliffs() {
    let mut p = island(65, 0.0);
    p.warp = Some(params::Warp { amplitude_m: 2.5, frequency_per_m: 0.3 });
    let hf = terrain(&p);
    let implicit = Implicit::new(&hf, &[], p.warp.as_ref(), 4);
    let (result, _) = build(&implicit, &p, &[], 1.0, &mut no_progress, Stop::NEVER, &MeshSettings::default()).unwrap();
    assert_eq!(result["mesh"]["closed"], true, "{result}");
    assert_eq!(result["pieces"], 1, "{result}");
    assert!(result["overhangs"]["with_overhang"].as_u64().unwrap() > 0, "{result}");
}

fn ctx() -> TestContext {
    TestContext::new(Heightfield::from_fn(2, 2, 1.0, |_, _| 0.0))
}

fn hashes(o: &Outcome<CoastSequence>) -> Vec<(String, String)> {
    o.artifacts
        .iter()
        .map(|a| (a.name.clone(), hex::encode(<sha2::Sha256 as sha2::Digest>::digest(&a.bytes))))
        .collect()
}

#[test]
fn replay_until_k_carves_only_the_first_k_spheres() {
    let t = ctx();
    let p = island(65, 0.2);
    let full = CarveCoast::run(&p, 5, &t.ctx()).unwrap();
    assert!(full.sequence.spheres.len() > 10);
    let again = CarveCoast::replay(&p, &full.sequence, None, &t.ctx()).unwrap();
    assert_eq!(hashes(&again), hashes(&full));
    assert_eq!(again.result, full.result);
    let k = 6;
    let part = CarveCoast::replay(&p, &full.sequence, Some(k), &t.ctx()).unwrap();
    let hf = terrain(&p);
    let first = &full.sequence.spheres[..k as usize];
    let implicit = Implicit::new(&hf, first, None, 5);
    let (result, artifacts) =
        build(&implicit, &p, first, 1.0, &mut no_progress, Stop::NEVER, &MeshSettings::default()).unwrap();
    assert_eq!(part.result, result);
    assert_eq!(part.artifacts, artifacts);
    assert_ne!(hashes(&part), hashes(&full));
}

#[test]
fn one_and_two_threads_give_identical_artifacts() {
    let mut p = island(65, 0.2);
    p.warp = Some(params::Warp { amplitude_m: 1.0, frequency_per_m: 0.2 });
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| CarveCoast::run(&p, 6, &ctx().ctx()).unwrap())
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(hashes(&one), hashes(&two));
    assert_eq!(one.sequence, two.sequence);
}
