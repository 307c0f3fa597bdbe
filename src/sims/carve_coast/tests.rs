//! Measured on the sampled field and the mesh: no overhang without carving, overhangs only near
//! sea level with it, no floating fragment, closed meshes, replay, thread-count determinism.

use crate::export::MeshSettings;
use serde_json::{json, Value};

use super::field::{bands, columns, grid_for, sample_planes};
use super::implicit::Capsule;
use super::outputs::{build, sample, surface, topology};
use super::*;
use crate::sims::test_support::TestContext;
use crate::terrain::generate_fractal;
use crate::validate::Limits;
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
    let implicit = Implicit::new(&hf, &spheres, None, 1, 2.0);
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
    // The caps lie flat just inside the box (the least crossing, where the extraction keeps
    // vertices off the box's samples): nothing below its bottom or beyond its walls.
    let (lo, hi) = mesh.bounds().unwrap();
    let inset = crate::mesh::min_crossing([g.nx, g.ny, g.nz]) * g.voxel_m;
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
    let implicit = Implicit::new(&hf, &spheres, None, 2, 2.0);
    let (result, _) =
        build(&implicit, &p, &spheres, 1.0, &mut no_progress, &|_| {}, Stop::NEVER, &MeshSettings::default()).unwrap();
    assert!(result["overhangs"]["with_overhang"].as_u64().unwrap() > 0, "{result}");
    assert_eq!(result["mesh"]["closed"], true);
    // Compare carved and uncarved fields sample by sample.
    let plain = Implicit::new(&hf, &[], None, 2, 2.0);
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
    let spheres = [Carving::Sphere(Sphere([16.0, 6.0, 16.0, 4.5], 1))];
    let mut p = island(33, 0.0);
    p.sea_level = Some(1.0);
    let implicit = Implicit::new(&hf, &spheres, None, 1, 2.0);
    let (kept, _) = build(
        &implicit,
        &CarveCoastParams { remove_fragments: false, ..p.clone() },
        &spheres,
        1.0,
        &mut no_progress,
        &|_| {},
        Stop::NEVER,
        &MeshSettings::default(),
    )
    .unwrap();
    assert!(kept["pieces"].as_u64().unwrap() >= 2, "{kept}");
    let (result, _) =
        build(&implicit, &p, &spheres, 1.0, &mut no_progress, &|_| {}, Stop::NEVER, &MeshSettings::default()).unwrap();
    assert_eq!(result["pieces"], 1, "{result}");
    assert!(result["fragments_removed"].as_u64().unwrap() >= 1);
    assert_eq!(result["mesh"]["closed"], true);
}

#[test]
fn warp_makes_strata_on_cliffs() {
    let mut p = island(65, 0.0);
    p.warp = Some(params::Warp { amplitude_m: 2.5, frequency_per_m: 0.3 });
    let hf = terrain(&p);
    let implicit = Implicit::new(&hf, &[], p.warp.as_ref(), 4, 2.0);
    let (result, _) =
        build(&implicit, &p, &[], 1.0, &mut no_progress, &|_| {}, Stop::NEVER, &MeshSettings::default()).unwrap();
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
    let implicit = Implicit::new(&hf, first, None, 5, 2.0);
    let (result, artifacts) =
        build(&implicit, &p, first, 1.0, &mut no_progress, &|_| {}, Stop::NEVER, &MeshSettings::default()).unwrap();
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

/// Random carvings (spheres, and every fifth a capsule) on a terrain, and points around them,
/// many on the index's bin edges.
fn spheres_and_points(hf: &Heightfield, n: usize, seed: u64) -> (Vec<Carving>, Vec<[f32; 3]>) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (w, d) = (hf.width_m(), hf.depth_m());
    let spheres: Vec<Carving> = (0..n)
        .map(|k| {
            let (x, z) = (rng.random_range(0.0..w), rng.random_range(0.0..d));
            let y = hf.sample(x, z) + rng.random_range(-2.0..1.0f32);
            let r = rng.random_range(0.3..4.0f32);
            if k % 5 == 0 {
                let to = [
                    x + rng.random_range(-12.0..12.0f32),
                    y + rng.random_range(-2.0..2.0f32),
                    z + rng.random_range(-12.0..12.0f32),
                ];
                Carving::Capsule(Capsule([x, y, z, to[0], to[1], to[2], r], 1))
            } else {
                Carving::Sphere(Sphere([x, y, z, r], 1))
            }
        })
        .collect();
    let cell = 8.0; // the index's bins: twice the largest radius
    let points = (0..20_000)
        .map(|k| {
            let mut x = rng.random_range(0.0..w);
            let mut z = rng.random_range(0.0..d);
            if k % 2 == 0 {
                // Just either side of a bin edge.
                x = (x / cell).round() * cell + rng.random_range(-0.05..0.05f32);
                z = (z / cell).round() * cell + rng.random_range(-0.05..0.05f32);
            }
            [
                x.clamp(0.0, w),
                hf.sample(x.clamp(0.0, w), z.clamp(0.0, d)) + rng.random_range(-4.0..3.0f32),
                z.clamp(0.0, d),
            ]
        })
        .collect();
    (spheres, points)
}

#[test]
fn the_sphere_index_misses_no_sphere_that_reaches_a_point_near_the_surface() {
    let p = island(65, 0.0);
    let hf = terrain(&p);
    for (seed, warp) in [(1, None), (2, Some(params::Warp { amplitude_m: 2.0, frequency_per_m: 0.4 }))] {
        let (spheres, points) = spheres_and_points(&hf, 300, seed);
        let exact = 1.5;
        let implicit = Implicit::new(&hf, &spheres, warp.as_ref(), 3, exact);
        let (mut near, mut checked) = (0, 0);
        for q in points {
            let (indexed, brute) = (implicit.distance(q), implicit.distance_brute(q));
            // The sign everywhere; the value itself wherever the surface is within `exact`.
            assert_eq!(indexed > 0.0, brute > 0.0, "sign at {q:?}: {indexed} vs {brute}");
            if brute.abs() <= exact {
                assert_eq!(indexed, brute, "at {q:?}");
                near += 1;
            }
            checked += 1;
        }
        assert!(near > checked / 10, "{near} of {checked} points near the surface");
    }
}

/// A cliff: sea floor at −6 m, a ramp up to a plateau 30 m high (far above the seeding range
/// of −3 to 8 m), along X.
fn cliff() -> Heightfield {
    let mut hf = Heightfield::flat(72, 40, 1.0, 0.0);
    for row in 0..hf.rows {
        for col in 0..hf.cols {
            let x = col as f32;
            let h = if x < 20.0 {
                -6.0
            } else if x < 27.0 {
                -6.0 + (x - 20.0) / 7.0 * 36.0
            } else {
                30.0
            };
            hf.set(col, row, h);
        }
    }
    hf
}

fn cliff_params(passes: u32, warp: Option<params::Warp>) -> CarveCoastParams {
    let mut p = params(json!({
        "terrain": {"fractal": {"size": 9}},
        "sea_level": 0.0,
        "erosion": {"seed_acceptance_probability": 0.3, "radius_range": [1.5, 3.0], "growth_step_range": [3, 5]},
        "passes": passes,
    }));
    p.warp = warp;
    p
}

#[test]
fn later_passes_seed_caves_under_ground_higher_than_the_range_and_deepen_them() {
    let hf = cliff();
    let p = cliff_params(4, None);
    let spheres = carve(&p, &hf, 9, 1.0, Stop::NEVER, &mut |_, _| Ok(())).unwrap();
    let e = &p.erosion;
    let (hi, reach) = (p.sea_level() + e.seed_elevation_range[1], e.radius_range[1] * 2.0);
    // Seeds of passes 2 and later on columns whose original ground stands above the range by
    // more than the old scan's reach: only a scan of the carved surface finds them.
    let mut under_high_ground = 0;
    for pass in 2..=p.passes {
        let before: Vec<Carving> = spheres.iter().copied().filter(|s| s.pass() < pass).collect();
        let implicit = Implicit::new(&hf, &before, None, 9, 2.0);
        let found = erosion::seeds(&implicit, &p, 9, pass, 1.0, Stop::NEVER).unwrap();
        under_high_ground += found.iter().filter(|s| hf.sample(s.point[0], s.point[2]) > hi + reach).count();
    }
    assert!(under_high_ground > 0, "no seed under the plateau after the first pass");
    // The caves reach further inland pass by pass: the deepest sphere's inland edge (x + r).
    let inland = |upto: u32| {
        spheres.iter().filter(|s| s.pass() <= upto).map(|s| s.centre()[0] + s.radius()).fold(0.0f32, f32::max)
    };
    let (first, last) = (inland(1), inland(p.passes));
    assert!(last > first + 4.0, "inland reach after pass 1: {first} m, after pass {}: {last} m", p.passes);
}

/// The spheres whose every point lies in rock of the final field without them: carved where no
/// air reaches, so filled back as air pockets.
fn buried(implicit: &Implicit, spheres: &[Carving]) -> usize {
    let dirs: Vec<[f32; 3]> = (-1..=1)
        .flat_map(|x| (-1..=1).flat_map(move |y| (-1..=1).map(move |z| [x as f32, y as f32, z as f32])))
        .collect();
    (0..spheres.len())
        .filter(|&i| {
            let s = spheres[i];
            let c = s.centre();
            dirs.iter().all(|d| {
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1.0);
                let q = [0, 1, 2].map(|k| c[k] + d[k] / len * s.radius() * 0.999);
                let others = spheres
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != i)
                    .map(|(_, t)| t.distance(q))
                    .fold(f32::INFINITY, f32::min);
                implicit.terrain_distance_at(q).max(-others) < 0.0
            })
        })
        .count()
}

#[test]
fn warped_cliffs_are_carved_where_the_warped_surface_is() {
    let warp = params::Warp { amplitude_m: 3.0, frequency_per_m: 0.35 };
    let hf = cliff();
    let p = cliff_params(2, Some(warp.clone()));
    let r_min = p.erosion.radius_range[0];
    let spheres = carve(&p, &hf, 4, 1.0, Stop::NEVER, &mut |_, _| Ok(())).unwrap();
    let implicit = Implicit::new(&hf, &spheres, p.warp.as_ref(), 4, 2.0);
    assert!(spheres.len() > 50);
    // No sphere lies wholly in rock of the field it carves, read where the field reads it.
    let buried = buried(&implicit, &spheres);
    assert_eq!(buried, 0, "{buried} of {} spheres buried in rock on the warped cliff", spheres.len());
    // Every first-pass seed lies on the warped surface (within the scan's step of 1 m, less
    // than the smallest radius), and its sphere is centred where the field reads that point,
    // so it straddles the surface.
    let uncarved = Implicit::new(&hf, &[], Some(&warp), 4, 2.0);
    let seeds = erosion::seeds(&uncarved, &p, 4, 1, 1.0, Stop::NEVER).unwrap();
    assert!(seeds.len() > 10);
    // (Within 2 m of the box's walls the field may be the wall's, not the terrain's: those
    // seeds are left out.)
    let inside = |s: &&erosion::SeedPoint| {
        let [x, _, z] = s.point;
        x.min(z).min(hf.width_m() - x).min(hf.depth_m() - z) >= 2.0
    };
    for s in seeds.iter().filter(inside) {
        let c = uncarved.warp(s.point);
        assert!(uncarved.distance(s.point).abs() <= 1.0, "seed off the warped surface");
        assert!(spheres.iter().any(|t| t.centre() == c), "no sphere centred at the seed's warped point");
        assert!(uncarved.terrain_distance_at(c).abs() <= 1.0);
    }
    // The old way, measured: seeds on the unwarped surface, spheres left unwarped, lie off the
    // warped surface by more than the smallest radius (missing the rock, or buried) this often.
    let flat = Implicit::new(&hf, &[], None, 4, 2.0);
    let old = erosion::seeds(&flat, &p, 4, 1, 1.0, Stop::NEVER).unwrap();
    let old: Vec<_> = old.iter().filter(inside).collect();
    let off = old.iter().filter(|s| uncarved.distance(s.point).abs() > r_min).count();
    eprintln!("unwarped seeding: {off} of {} seeds lie more than {r_min} m off the warped surface", old.len());
    assert!(off * 5 > old.len(), "the warp moves the cliff too little for this test to mean anything");
}

/// Carve `p` on `hf` and measure the result.
fn carve_and_measure(p: &CarveCoastParams, hf: &Heightfield) -> (Vec<Carving>, Value) {
    let carvings = carve(p, hf, 5, 1.0, Stop::NEVER, &mut |_, _| Ok(())).unwrap();
    let implicit = Implicit::new(hf, &carvings, p.warp.as_ref(), 5, 2.0);
    let (result, _) =
        build(&implicit, p, &carvings, 1.0, &mut no_progress, &|_| {}, Stop::NEVER, &MeshSettings::default()).unwrap();
    assert_eq!(result["mesh"]["closed"], true, "{result}");
    (carvings, result)
}

fn authored_params(carve: Value) -> CarveCoastParams {
    params(json!({
        "terrain": {"fractal": {"size": 9}},
        "sea_level": 0.0,
        "erosion": {"seed_acceptance_probability": 0.0},
        "passes": 1,
        "carve": carve,
    }))
}

#[test]
fn an_authored_capsule_through_a_headland_makes_an_arch() {
    // A ridge 8 m wide and 15 m high standing out of a sea floor at −6 m, along X.
    let hf = Heightfield::from_fn(72, 40, 1.0, |x, z| {
        if (z - 20.0).abs() <= 4.0 && (8.0..64.0).contains(&x) {
            15.0
        } else {
            -6.0
        }
    });
    let (_, plain) = carve_and_measure(&authored_params(json!([])), &hf);
    assert_eq!((plain["arches"].as_i64(), plain["sea_caves"].as_u64()), (Some(0), Some(0)), "{plain}");
    // A tunnel across it at the waterline: rock stays above it, so the ridge becomes an arch.
    let tunnel = json!([{"capsule": {"from": [36.0, 1.5, 10.0], "to": [36.0, 1.5, 30.0], "radius_m": 2.5}}]);
    let (carvings, arch) = carve_and_measure(&authored_params(tunnel), &hf);
    assert_eq!(carvings.len(), 1);
    eprintln!("arch: arches {} sea caves {} passages {}", arch["arches"], arch["sea_caves"], arch["covered_passages"]);
    assert_eq!(arch["arches"], 1, "{arch}");
    assert_eq!(arch["pieces"], 1, "{arch}");
    assert_eq!(arch["sea_caves"], 0, "{arch}");
    assert!(arch["covered_passages"].as_u64().unwrap() >= 1, "{arch}");
    assert_eq!(arch["authored"], json!({"before": 0, "after": 1}));
}

#[test]
fn an_authored_tunnel_into_a_cliff_is_a_sea_cave() {
    let hf = cliff();
    let (_, plain) = carve_and_measure(&authored_params(json!([])), &hf);
    assert_eq!((plain["arches"].as_i64(), plain["sea_caves"].as_u64()), (Some(0), Some(0)), "{plain}");
    // From the sea in front of the cliff 13 m into the plateau, at the waterline; and a sphere
    // high on the cliff face, a notch, not a cave at sea level.
    let carve = json!([
        {"capsule": {"from": [18.0, 1.0, 20.0], "to": [40.0, 1.0, 20.0], "radius_m": 2.0}},
        {"sphere": {"centre": [25.0, 22.0, 8.0], "radius_m": 2.5}},
    ]);
    let (_, cave) = carve_and_measure(&authored_params(carve), &hf);
    eprintln!("cave: arches {} sea caves {} passages {}", cave["arches"], cave["sea_caves"], cave["covered_passages"]);
    assert_eq!(cave["sea_caves"], 1, "{cave}");
    assert_eq!(cave["arches"], 0, "{cave}");
    assert_eq!(cave["covered_passages"], 0, "{cave}");
}

#[test]
fn authored_carvings_before_the_passes_are_eroded_after_them_are_not() {
    let hf = cliff();
    let erode = |shapes: Value| {
        let mut p = cliff_params(2, None);
        p.carve = serde_json::from_value(shapes).unwrap();
        carve(&p, &hf, 5, 1.0, Stop::NEVER, &mut |_, _| Ok(())).unwrap()
    };
    let shape = |when: &str| json!([{"capsule": {"from": [18.0, 1.0, 12.0], "to": [38.0, 1.0, 28.0], "radius_m": 2.0, "when": when}}]);
    let none = erode(json!([]));
    let after = erode(shape("after"));
    let before = erode(shape("before"));
    // After: the same erosion, the capsule last (pass passes + 1).
    assert_eq!(after[..after.len() - 1], none[..]);
    assert!(matches!(after.last(), Some(Carving::Capsule(c)) if c.1 == 3));
    // Before: the capsule first (pass 0), and the passes seed on the walls it opened.
    assert!(matches!(before.first(), Some(Carving::Capsule(c)) if c.1 == 0));
    assert_ne!(before[1..], none[..]);
    let inside = |s: &&Carving| s.pass() == 1 && s.centre()[0] > 30.0 && (s.centre()[2] - 20.0).abs() < 8.0;
    let (deep_before, deep_none) = (before.iter().filter(inside).count(), none.iter().filter(inside).count());
    assert!(
        deep_before > deep_none,
        "first-pass spheres deep in the cliff: {deep_before} with the tunnel, {deep_none} without"
    );
}

#[test]
fn the_heightmap_border_is_the_terrain_surface_not_the_box_bottom() {
    // No warp: where no carving reaches, the topmost surface is the heightfield itself, so the
    // border of heightfield.npy must equal the input's heights there (the field is linear in y
    // along a column, so the interpolated crossing is exact up to rounding).
    let p = island(129, 0.2);
    let hf = terrain(&p);
    let out = CarveCoast::run(&p, 5, &ctx().ctx()).unwrap();
    let npy = out.artifacts.iter().find(|a| a.name == crate::jobs::HEIGHTFIELD_ARTIFACT).unwrap();
    let top = crate::export::read_heightfield_npy(&npy.bytes, 1.0).unwrap();
    assert_eq!((top.cols, top.rows), (129, 129));
    let untouched = |x: f32, z: f32| {
        out.sequence.spheres.iter().all(|s| {
            let (a, b) = s.bounds();
            x < a[0] - 1.0 || x > b[0] + 1.0 || z < a[2] - 1.0 || z > b[2] + 1.0
        })
    };
    let (mut checked, mut worst) = (0, 0.0f32);
    for k in 0..top.cols * top.rows {
        let (c, r) = (k % top.cols, k / top.cols);
        if c != 0 && r != 0 && c != top.cols - 1 && r != top.rows - 1 {
            continue;
        }
        let (x, z) = (c as f32, r as f32);
        if untouched(x, z) {
            checked += 1;
            worst = worst.max((top.heights_m[k] - hf.sample(x, z)).abs());
        }
    }
    assert!(checked > 400, "{checked} of 512 border samples untouched by carving");
    assert!(worst < 1e-3, "border off the terrain by {worst} m");
    let (lo, _) = top.min_max();
    assert_eq!(out.result["z_min"], json!(lo));
    assert!(lo >= hf.min_max().0 - 1.0, "z_min {lo} below the terrain's lowest point {:?}", hf.min_max());
}

/// Like the heightfield kinds, the coast writes `heightmap.r16`, `normalmap.png` and
/// `splatmap.png` of its topmost surface; the splat map's A is the rock the sea cut away: all
/// of it where the surface lies 1.5 voxels or more below the source terrain, none where no
/// sphere reached; the untouched sea bed is deposit.
#[test]
fn the_coast_writes_heightfield_maps_and_its_splat_material_is_the_rock_the_sea_cut() {
    let p = island(129, 0.2);
    let hf = terrain(&p);
    let out = CarveCoast::run(&p, 5, &ctx().ctx()).unwrap();
    let get = |name: &str| &out.artifacts.iter().find(|a| a.name == name).unwrap_or_else(|| panic!("{name}")).bytes;
    let top = crate::export::read_heightfield_npy(get(crate::jobs::HEIGHTFIELD_ARTIFACT), 1.0).unwrap();
    assert_eq!(get("heightmap.r16").len(), 2 * 129 * 129);
    assert_eq!(
        (out.result["heightmap_r16"]["width"].as_u64(), out.result["heightmap_r16"]["height"].as_u64()),
        (Some(129), Some(129))
    );
    let (info, _) = crate::export::test_png::decode(get("normalmap.png"));
    assert_eq!((info.width, info.height), (129, 129));
    let (info, rgba) = crate::export::test_png::decode(get("splatmap.png"));
    assert_eq!((info.width, info.height), (129, 129));
    let near_a_sphere = |x: f32, z: f32| {
        out.sequence.spheres.iter().any(|s| {
            let (a, b) = s.bounds();
            x >= a[0] - 1.0 && x <= b[0] + 1.0 && z >= a[2] - 1.0 && z <= b[2] + 1.0
        })
    };
    let (mut cut, mut bed) = (0, 0);
    for (k, px) in rgba.chunks_exact(4).enumerate() {
        let (x, z) = ((k % 129) as f32, (k / 129) as f32);
        let depth = hf.sample(x, z) - top.heights_m[k];
        if depth >= 1.5 {
            assert_eq!(px[3], 255, "({x}, {z}) cut {depth} m");
            cut += 1;
        } else if !near_a_sphere(x, z) {
            assert_eq!(px[3], 0, "({x}, {z}) untouched, {depth} m");
            if top.heights_m[k] < p.sea_level() && px[1] == 0 {
                assert_eq!(px[..3], [0, 0, 255], "({x}, {z}): the sea bed");
                bed += 1;
            }
        }
    }
    assert!(cut > 20 && bed > 100, "{cut} samples cut, {bed} of sea bed");
}

#[test]
fn a_sequence_names_its_generator_and_terrain_and_another_versions_is_refused() {
    use crate::jobs::{JobKind, Kind};
    let t = ctx();
    let kind = Kind::<CarveCoast>::default();
    let body = serde_json::to_value(island(65, 0.2)).unwrap();
    let prepared = kind.prepare(body, &t.limits).expect("valid");
    let run = kind.run(&prepared.params, 5, &t.ctx()).unwrap();
    let bytes = &run.artifacts.iter().find(|a| a.name == "sequence.json").unwrap().bytes;
    let mut stored: Value = serde_json::from_slice(bytes).unwrap();
    assert_eq!(stored["generator"], json!({"kind": "carve-coast", "version": CarveCoast::GENERATOR_VERSION}));
    let terrain = |v: &Value| serde_json::from_value::<TerrainSource>(v.clone()).unwrap();
    assert_eq!(terrain(&stored["terrain"]), terrain(&prepared.params["terrain"]), "the terrain it started from");
    let steps = kind.sequence_steps(bytes).unwrap();
    assert!(steps > 10);
    // The same sequence stamped by another version, or by none (recorded before versions were
    // kept: version 1), is refused with the versions named, not rebuilt into other bytes.
    for (stamp, recorded) in [(json!({"kind": "carve-coast", "version": 1}), "version 1"), (Value::Null, "version 1")] {
        if stamp.is_null() {
            stored.as_object_mut().unwrap().remove("generator");
        } else {
            stored["generator"] = stamp;
        }
        let old = serde_json::to_vec(&stored).unwrap();
        for err in
            [kind.sequence_steps(&old).unwrap_err(), kind.replay(&prepared.params, &old, None, &t.ctx()).unwrap_err()]
        {
            let SimError::Invalid { field, message } = err else { panic!("{err:?}") };
            assert_eq!(field, "sequence");
            assert!(message.contains(recorded) && message.contains("version 2"), "{message}");
        }
    }
}
