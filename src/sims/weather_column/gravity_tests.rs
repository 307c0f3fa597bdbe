//! Gravity measured: a cap whose soft pedestal weathers through drops as one rigid piece by the
//! recorded distance onto what is below (checked cell by cell against the same run without
//! gravity), its centre of mass lower, nothing left floating at any step; it keeps weathering
//! where it lies; replay until k is a run of k steps before, at and after the fall; threads
//! don't change the bytes.

use serde_json::json;

use super::gravity::{all_grounded, component, replay_cells};
use super::grid::ROCK;
use super::tests::{ctx, hashes};
use super::*;
use crate::stop::Stop;
use crate::validate::{Limits, Validate, Validator};

/// A cylinder on the ground: a base, a thin soft neck, a hard cap above.
fn toppling(gravity: bool, steps: u32) -> WeatherColumnParams {
    let p: WeatherColumnParams = serde_json::from_value(json!({
        "grid": {"x": 22, "y": 40, "z": 22},
        "voxel_size_m": 0.1,
        "column": {"profile": {"cylinder": {"radius_m": 0.8}}, "height_m": 3.4},
        "layers": [
            {"top_m": 0.6, "resistance": 2.0, "bubble": {"sphere": {"radius": 3}}},
            {"top_m": 1.0, "resistance": 0.12, "bubble": {"sphere": {"radius": 3}}},
            {"top_m": 3.4, "resistance": 3.0, "bubble": {"sphere": {"radius": 3}}},
        ],
        "rate": 0.3,
        "ratio_exponent": 2.0,
        "steps": steps,
        "gravity": gravity,
        "mesh": {"smoothing_iterations": 2},
    }))
    .expect("parses");
    let mut v = Validator::new();
    p.validate(&mut v, &Limits::default());
    assert!(v.is_ok(), "{:?}", v.errors);
    p
}

fn weather(p: &WeatherColumnParams) -> (Rock, weathering::History) {
    simulate(p, 3, None, Stop::NEVER, &mut |_, _, _| Ok(())).expect("weathers")
}

fn centre_y(g: &grid::Grid, cells: &[usize]) -> f64 {
    cells.iter().map(|&i| g.coords(i).1 as f64).sum::<f64>() / cells.len() as f64
}

#[test]
fn a_cap_cut_loose_falls_as_one_piece_onto_what_is_below_and_nothing_floats() {
    let (rock, _) = weather(&toppling(true, 400));
    let g = &rock.grid;
    let gravity = rock.gravity.as_ref().unwrap();
    let first = gravity.falls.first().copied().expect("the cap fell");
    let s = first.step;
    // The same column without gravity, to the step of the first fall: identical until then,
    // and there the cap floats.
    let (without, _) = weather(&toppling(false, s));
    assert!(!all_grounded(g, &without.state), "the neck was cut at step {s}");
    let record = &gravity.record;
    let (before, _) = replay_cells(g, record, &[], (s - 1) as u16);
    let (at, _) = replay_cells(g, record, &gravity.falls, s as u16);
    for fall in gravity.falls.iter().filter(|f| f.step == s) {
        // The piece as it hung: the no-gravity rock connected to the fall's voxel.
        let piece = component(g, &without.state, fall.voxel as usize);
        assert!(piece.len() > 200, "{} voxels", piece.len());
        let shift = fall.dy as usize * g.plane();
        let moved: Vec<usize> = piece.iter().map(|&c| c - shift).collect();
        // Moved rigidly: every cell down by dy is rock now; every cell it left is air.
        for (&c, &m) in piece.iter().zip(&moved) {
            assert_eq!(at[m], ROCK);
            if moved.binary_search(&c).is_err() {
                assert_ne!(at[c], ROCK, "cell {c} was left");
            }
        }
        // It rests: some cell of it now sits on rock outside it, or on the ground.
        let rests = moved.iter().any(|&c| {
            let (_, y, _) = g.coords(c);
            y == 0 || (at[c - g.plane()] == ROCK && moved.binary_search(&(c - g.plane())).is_err())
        });
        assert!(rests, "the piece hangs in the air");
        // Its centre of mass is lower, by the drop.
        let (from, to) = (centre_y(g, &piece), centre_y(g, &moved));
        assert!((from - to - fall.dy as f64).abs() < 1e-9 && to < from, "{from} -> {to}");
        // Before the step it was joined to the ground.
        assert!(all_grounded(g, &before));
    }
    // Nothing floats, after any step of the run.
    for k in [s, s + 1, rock.gravity.as_ref().unwrap().falls.last().unwrap().step, 400] {
        let (cells, _) = replay_cells(g, record, &gravity.falls, k as u16);
        assert!(all_grounded(g, &cells), "something floats after step {k}");
    }
    assert!(all_grounded(g, &rock.state));
    // It keeps weathering where it lies: voxels of the fallen cap removed after the fall.
    let cap: Vec<usize> = component(g, &without.state, first.voxel as usize);
    let later = cap.iter().filter(|&&c| record[c] != ROCK && record[c] as u32 > s).count();
    assert!(later > 20, "{later} voxels of the cap weathered after it fell");
}

#[test]
fn replay_until_k_equals_a_run_of_k_steps_across_the_fall() {
    let t = ctx();
    let full = WeatherColumn::run(&toppling(true, 300), 3, &t.ctx()).unwrap();
    let s = full.sequence.falls.first().expect("a fall").step as u64;
    let again = WeatherColumn::replay(&toppling(true, 300), &full.sequence, None, &t.ctx()).unwrap();
    assert_eq!(hashes(&again), hashes(&full));
    assert_eq!(again.result, full.result);
    assert_eq!(again.sequence, full.sequence);
    for k in [s - 1, s, s + 7] {
        let part = WeatherColumn::replay(&toppling(true, 300), &full.sequence, Some(k), &t.ctx()).unwrap();
        let short = WeatherColumn::run(&toppling(true, k as u32), 3, &t.ctx()).unwrap();
        assert_eq!(hashes(&part), hashes(&short), "until {k}");
        assert_eq!(part.result, short.result);
        assert_eq!(part.sequence, short.sequence);
        // And a replay of that replay gives it again.
        let twice = WeatherColumn::replay(&toppling(true, 300), &part.sequence, None, &t.ctx()).unwrap();
        assert_eq!(hashes(&twice), hashes(&part));
    }
}

#[test]
fn falls_are_the_same_on_one_and_two_threads() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| WeatherColumn::run(&toppling(true, 250), 3, &ctx().ctx()).unwrap())
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(hashes(&one), hashes(&two));
    assert_eq!(one.sequence, two.sequence);
    assert!(!one.sequence.falls.is_empty());
}

#[test]
fn gravity_needs_the_synchronized_update() {
    let mut p = toppling(true, 10);
    p.update = params::Update::EventBased;
    let mut v = Validator::new();
    p.validate(&mut v, &Limits::default());
    assert!(v.errors.iter().any(|e| e.field == "gravity"), "{:?}", v.errors);
}
