//! The job as a whole: runs, replays, resolution, window, figures, and the example requests.

use std::sync::atomic::Ordering;

use serde_json::{json, Value};

use super::*;
use crate::jobs::{JobKind, Kind};
use crate::sims::test_support::{job_terrain, TestContext};
use crate::validate::Limits;

fn hills(size: usize, cell_size_m: f32) -> Heightfield {
    Heightfield::from_fn(size, size, cell_size_m, |x, z| 12.0 + 6.0 * (x * 0.07).sin() * (z * 0.05).cos() + 0.04 * x)
}

fn params(extra: Value) -> BulldozeParams {
    let mut body = json!({"terrain": job_terrain()});
    body.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
    serde_json::from_value(body).expect("a valid request")
}

/// A request that uses every kind of operation and both kinds of path height.
fn busy_request() -> BulldozeParams {
    params(json!({
        "window": {"min_x": 4.0, "min_z": 2.0, "max_x": 120.0, "max_z": 124.0},
        "operations": [
            {"primitive": {"shape": {"mound": {"center": {"x": 60, "z": 60}, "radius_m": 30, "height_m": 15}}}},
            {"pass": {
                "path": [{"x": 10, "z": 20}, {"x": 40, "z": 35}, {"x": 70, "z": 30, "height": 14.0},
                         {"x": 100, "z": 55}, {"x": 95, "z": 90}, {"x": 60, "z": 100}],
                "blade": {"width_m": 9, "profile": [[-1, 0.5], [-0.4, -1.5], [0.4, -1.5], [1, 0.5]]},
                "operator": "replace"}},
            {"primitive": {"shape": {"berm": {"start": {"x": 20, "z": 70}, "direction_deg": 10, "l": 60,
                "h1": 3, "r1": 5, "h2": 6, "r2": 8, "c": 0.01, "c2": 3}}, "operator": "max"}},
            {"pass": {
                "path": [{"x": 30, "z": 110, "height": 18}, {"x": 80, "z": 110, "height": 10},
                         {"x": 110, "z": 80}, {"x": 30, "z": 112, "height": 9}],
                "blade": {"width_m": 7, "profile": [[-1, 0], [0, -2], [1, 0]], "offset_m": 1.5, "angle_deg": 20},
                "operator": "min"}},
            {"primitive": {"shape": {"swale": {"start": {"x": 10, "z": 10}, "direction_deg": 45, "l": 80,
                "h1": 1, "r1": 3, "h2": 2, "r2": 4}}, "operator": "add"}},
            {"primitive": {"shape": {"box": {"center": {"x": 90, "z": 20}, "size_x_m": 20, "size_z_m": 8,
                "height_m": 4, "rotation_deg": 30, "base_m": 13}}, "operator": "replace"}},
            {"pass": {
                "path": [{"x": 5, "z": 60}, {"x": 125, "z": 64}],
                "blade": {"width_m": 5, "profile": [[-1, -1], [1, -1]]},
                "operator": "add"}},
            {"primitive": {"shape": {"torus": {"center": {"x": 60, "z": 60}, "major_radius_m": 20,
                "minor_radius_m": 4, "height_m": 3}}, "operator": "average"}},
            {"local": {"vertices": [{"x": 60, "z": 60, "set_m": 30}, {"x": 61, "z": 60, "offset_m": -1}]}},
            {"global": {"exaggerate": {"factor": 1.3, "about_m": 12}}},
            {"global": {"curve": [[0, 0], [14, 14], [20, 16], [40, 30]]}}
        ]
    }))
}

fn bits(hf: &Heightfield) -> Vec<u32> {
    hf.heights_m.iter().map(|h| h.to_bits()).collect()
}

/// The sequence as the engine stores and reads it back.
fn stored(sequence: &BulldozeSequence) -> BulldozeSequence {
    serde_json::from_slice(&serde_json::to_vec_pretty(sequence).unwrap()).unwrap()
}

/// The request holding only the operations that made the first `k` steps of `p`: a pass cut
/// short keeps the path vertices of its first moves.
fn truncated(p: &BulldozeParams, k: u64) -> BulldozeParams {
    let mut left = k as usize;
    let mut operations = Vec::new();
    for op in &p.operations {
        if left == 0 {
            break;
        }
        match op {
            Operation::Primitive(_) | Operation::Local(_) | Operation::Global(_) | Operation::Refine(_) => {
                operations.push(op.clone());
                left -= 1;
            }
            Operation::Pass(pass) => {
                let moves = (pass.path.len() - 1).min(left);
                let mut pass = pass.clone();
                pass.path.truncate(moves + 1);
                operations.push(Operation::Pass(pass));
                left -= moves;
            }
        }
    }
    BulldozeParams { operations, ..p.clone() }
}

#[test]
fn a_full_replay_is_bit_identical_to_the_run() {
    let t = TestContext::new(hills(129, 1.0));
    let p = busy_request();
    let run = run_edit(&p, &t.ctx()).unwrap();
    assert_eq!(run.sequence.steps.len() as u64, p.step_count());
    assert_eq!(run.tally.moves, 5 + 3 + 1);
    let replay = replay_edit(&stored(&run.sequence), None, &t.ctx()).unwrap();
    assert_eq!(bits(&replay.hf), bits(&run.hf));
    assert_eq!(replay.sequence, run.sequence);
    assert_eq!(replay.figures(), run.figures());
    assert!(run.figures()["changed_samples"].as_u64().unwrap() > 3000);
}

#[test]
fn a_replay_until_k_equals_a_run_of_the_operations_that_made_those_steps() {
    let t = TestContext::new(hills(129, 1.0));
    let p = busy_request();
    let sequence = stored(&run_edit(&p, &t.ctx()).unwrap().sequence);
    for k in 0..=p.step_count() {
        let replay = replay_edit(&sequence, Some(k), &t.ctx()).unwrap();
        let direct = run_edit(&truncated(&p, k), &t.ctx()).unwrap();
        assert_eq!(bits(&replay.hf), bits(&direct.hf), "after {k} steps");
        assert_eq!(replay.sequence, direct.sequence, "after {k} steps");
        assert_eq!(replay.figures(), direct.figures(), "after {k} steps");
    }
}

#[test]
fn a_job_and_its_full_replay_give_byte_identical_artifacts() {
    let t = TestContext::new(hills(97, 1.0));
    let kind = Kind::<Bulldoze>::default();
    let body = serde_json::to_value(busy_request()).unwrap();
    let prepared = kind.prepare(body, &t.limits).expect("valid");
    assert_eq!(
        prepared.references.jobs,
        vec![("terrain.job".to_string(), "0190a0f4-4a9e-7c3e-8000-000000000001".to_string())]
    );
    let run = kind.run(&prepared.params, 0, &t.ctx()).unwrap();
    let names: Vec<&str> = run.artifacts.iter().map(|a| a.name.as_str()).collect();
    assert!(names.contains(&"sequence.json") && names.contains(&"mesh.glb"), "{names:?}");
    for key in ["z_min", "z_max", "grid", "operations", "steps", "changed_samples", "cut_volume_m3", "fill_volume_m3"] {
        assert!(run.result.get(key).is_some(), "{key} in {}", run.result);
    }
    let sequence = &run.artifacts.iter().find(|a| a.name == "sequence.json").unwrap().bytes;
    assert_eq!(kind.sequence_steps(sequence).unwrap(), busy_request().step_count());
    let replay = kind.replay(&prepared.params, sequence, None, &t.ctx()).unwrap();
    assert_eq!(replay.result, run.result);
    assert_eq!(replay.artifacts, run.artifacts);
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let t = TestContext::new(hills(129, 1.0));
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| run_edit(&busy_request(), &t.ctx()).unwrap())
    };
    let (one, four) = (on(1), on(4));
    assert_eq!(bits(&one.hf), bits(&four.hf));
    assert_eq!(one.figures(), four.figures());
}

#[test]
fn relative_path_heights_are_recorded_and_not_looked_up_again() {
    let t = TestContext::new(hills(65, 1.0));
    let p = params(json!({"operations": [
        {"pass": {"path": [{"x": 10, "z": 10}, {"x": 50, "z": 30.5}], "blade": {"width_m": 4}}}
    ]}));
    let run = run_edit(&p, &t.ctx()).unwrap();
    let Step::Move(m) = &run.sequence.steps[0] else { panic!("a move") };
    let start = hills(65, 1.0);
    assert_eq!(m.from.height, start.sample(10.0, 10.0));
    assert_eq!(m.to.height, start.sample(50.0, 30.5));

    // A replay over different terrain still cuts at the recorded heights.
    let flat = TestContext::new(Heightfield::flat(65, 65, 1.0, 0.0));
    let replay = replay_edit(&run.sequence, None, &flat.ctx()).unwrap();
    assert_eq!(replay.hf.get(10, 10), m.from.height);
}

#[test]
fn resolution_resamples_the_terrain() {
    let start = hills(65, 1.0);
    let t = TestContext::new(start.clone());
    let p = params(json!({
        "resolution": 2.0,
        "operations": [{"primitive": {"shape": {"cone": {"center": {"x": 32, "z": 32}, "radius_m": 10, "height_m": 5}}}}]
    }));
    let edit = run_edit(&p, &t.ctx()).unwrap();
    assert_eq!((edit.hf.cols, edit.hf.rows, edit.hf.cell_size_m), (33, 33, 2.0));
    assert_eq!(edit.sequence.resolution_m, 2.0);
    let resampled = start.resampled(2.0);
    assert_eq!(edit.hf.get(3, 5), resampled.get(3, 5));
    assert_eq!(edit.hf.get(3, 5), start.get(6, 10));
    assert!((edit.hf.get(16, 16) - (start.get(32, 32) + 5.0)).abs() < 1e-5);
    // The cone reaches 10 m: five samples of 2 m either side of its centre.
    assert_ne!(edit.hf.get(20, 16), resampled.get(20, 16));
    assert_eq!(edit.hf.get(21, 16), resampled.get(21, 16));

    // Without one, the grid keeps the terrain's own cell size.
    let p = params(json!({"operations": []}));
    let edit = run_edit(&p, &t.ctx()).unwrap();
    assert_eq!((edit.hf.cols, edit.sequence.resolution_m), (65, 1.0));
    assert_eq!(edit.hf, start);
}

#[test]
fn a_resolution_too_fine_for_an_earlier_jobs_terrain_is_refused_at_run_time() {
    let mut t = TestContext::new(hills(65, 1.0));
    t.limits = Limits { max_grid_cells: 10_000, ..Limits::default() };
    let p = params(json!({"resolution": 0.5, "operations": []}));
    match run_edit(&p, &t.ctx()) {
        Err(SimError::Invalid { field, message }) => {
            assert_eq!(field, "resolution");
            assert!(message.contains("129×129"), "{message}");
        }
        other => panic!("expected a refusal, got {:?}", other.map(|e| e.tally)),
    }
}

#[test]
fn the_window_restricts_every_operation() {
    let t = TestContext::new(Heightfield::flat(81, 81, 1.0, 0.0));
    let p = params(json!({
        "window": {"min_x": 30, "min_z": 35, "max_x": 50, "max_z": 45},
        "operations": [
            {"primitive": {"shape": {"mound": {"center": {"x": 40, "z": 40}, "radius_m": 30, "height_m": 10}}}},
            {"pass": {"path": [{"x": 0, "z": 40, "height": 20}, {"x": 80, "z": 40, "height": 20}], "blade": {"width_m": 4}}}
        ]
    }));
    let edit = run_edit(&p, &t.ctx()).unwrap();
    for r in 0..81 {
        for c in 0..81 {
            let inside = (30..=50).contains(&c) && (35..=45).contains(&r);
            assert_eq!(edit.hf.get(c, r) != 0.0, inside, "at ({c}, {r})");
        }
    }
    assert_eq!(edit.hf.get(30, 40), 20.0);
    assert_eq!(edit.figures()["changed_samples"], 21 * 11);
}

#[test]
fn figures_count_steps_changes_and_volumes() {
    let t = TestContext::new(Heightfield::flat(41, 41, 0.5, 3.0));
    let p = params(json!({"operations": [
        {"primitive": {"shape": {"box": {"center": {"x": 10, "z": 10}, "size_x_m": 5, "size_z_m": 5, "height_m": 2}}}},
        {"pass": {"path": [{"x": 0, "z": 2}, {"x": 10, "z": 2}, {"x": 20, "z": 2}],
                  "blade": {"width_m": 2, "profile": [[-1, -1], [1, -1]]}, "operator": "add"}}
    ]}));
    let figures = run_edit(&p, &t.ctx()).unwrap().figures();
    // The box covers 11 × 11 samples, 2 m up; the cut is 41 × 5 samples, 1 m down.
    assert_eq!(figures["operations"], 2);
    assert_eq!(figures["steps"], 3);
    assert_eq!(
        (figures["passes"].clone(), figures["primitives"].clone(), figures["moves"].clone()),
        (json!(1), json!(1), json!(2))
    );
    assert_eq!(figures["changed_samples"], 121 + 205);
    assert_eq!(figures["fill_volume_m3"], 121.0 * 2.0 * 0.25);
    assert_eq!(figures["cut_volume_m3"], 205.0 * 0.25);
}

/// `splatmap.png`'s A is the bulldozer's work: every cell the box filled and the road cut,
/// counted by hand from the shapes, and nothing else; the rest is ground on this flat land.
#[test]
fn the_splat_maps_material_is_the_cells_the_bulldozer_shaped() {
    let t = TestContext::new(Heightfield::flat(41, 41, 0.5, 3.0));
    let p = params(json!({"operations": [
        {"primitive": {"shape": {"box": {"center": {"x": 10, "z": 10}, "size_x_m": 5, "size_z_m": 5, "height_m": 2}}}},
        {"pass": {"path": [{"x": 0, "z": 2}, {"x": 10, "z": 2}, {"x": 20, "z": 2}],
                  "blade": {"width_m": 2, "profile": [[-1, -1], [1, -1]]}, "operator": "add"}}
    ]}));
    let kind = Kind::<Bulldoze>::default();
    let run = kind.run(&serde_json::to_value(&p).unwrap(), 0, &t.ctx()).unwrap();
    let splat = &run.artifacts.iter().find(|a| a.name == "splatmap.png").expect("splatmap.png").bytes;
    let (info, rgba) = crate::export::test_png::decode(splat);
    assert_eq!((info.width, info.height), (41, 41));
    // The box: x and z 7.5–12.5 m, samples 15–25; the road: z 1–3 m, samples 2–6, every column.
    for (i, px) in rgba.chunks_exact(4).enumerate() {
        let (c, r) = (i % 41, i / 41);
        let shaped = (15..=25).contains(&c) && (15..=25).contains(&r) || (2..=6).contains(&r);
        assert_eq!(px[3], if shaped { 255 } else { 0 }, "sample ({c}, {r})");
    }
    assert_eq!(rgba[4 * (35 * 41 + 35)..][..4], [255, 0, 0, 0], "untouched flat ground");
}

#[test]
fn a_cancelled_job_stops() {
    let t = TestContext::new(hills(33, 1.0));
    t.cancel.store(true, Ordering::Relaxed);
    assert!(matches!(run_edit(&busy_request(), &t.ctx()), Err(SimError::Cancelled)));
}

#[test]
fn the_request_schema_is_named_for_the_kind() {
    let (name, _, refs) = Kind::<Bulldoze>::default().request_schema();
    assert_eq!(name, "BulldozeParams");
    let names: Vec<&str> = refs.iter().map(|(n, _)| n.as_str()).collect();
    for expected in ["BulldozeBlade", "BulldozeOperator", "BulldozeShape", "BulldozeBerm", "BulldozePathVertex"] {
        assert!(names.contains(&expected), "{expected} in {names:?}");
    }
}

/// The example requests, without the common `seed` and `label` fields: (file name, body).
fn examples() -> Vec<(String, Value)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("api/bulldoze");
    let mut out = Vec::new();
    for entry in std::fs::read_dir(&dir).expect("api/bulldoze exists") {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("json") {
            continue;
        }
        let mut body: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let fields = body.as_object_mut().unwrap();
        fields.remove("seed");
        fields.remove("label");
        out.push((path.file_name().unwrap().to_string_lossy().into_owned(), body));
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

#[test]
fn every_example_runs() {
    let t = TestContext::new(Heightfield::flat(2, 2, 1.0, 0.0));
    let kind = Kind::<Bulldoze>::default();
    for (name, body) in examples() {
        let prepared = kind.prepare(body, &t.limits).unwrap_or_else(|e| panic!("{name}: {e:?}"));
        let run = kind.run(&prepared.params, 0, &t.ctx()).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(run.result["changed_samples"].as_u64().unwrap() > 1000, "{name}: {}", run.result);
    }
}

#[test]
fn every_example_request_parses_and_validates() {
    let mut seen = Vec::new();
    for (name, body) in examples() {
        let prepared = Kind::<Bulldoze>::default().prepare(body, &Limits::default());
        assert!(prepared.is_ok(), "{name}: {:?}", prepared.err());
        seen.push(name);
    }
    for expected in
        ["hillside-road.json", "mound-box-add.json", "mound-box-subtract.json", "ramp-7-percent.json", "ziggurat.json"]
    {
        assert!(seen.iter().any(|s| s == expected), "{expected} in {seen:?}");
    }
}

/// Two boxes 3e38 m high stacked with `add`: each is finite, their sum is not.
fn overflowing_boxes() -> Vec<Value> {
    let block = json!({"primitive": {"shape": {"box": {"center": {"x": 20, "z": 20}, "size_x_m": 10,
        "size_z_m": 10, "height_m": 3e38}}, "operator": "add"}});
    vec![block.clone(), block]
}

#[test]
fn heights_that_overflow_fail_as_invalid_operations_in_a_run_and_a_replay() {
    let t = TestContext::new(hills(41, 1.0));
    let refused = |result: Result<Edit, SimError>| match result {
        Err(SimError::Invalid { field, message }) => {
            assert_eq!(field, "operations");
            assert!(message.contains("x = 15 m, z = 15 m"), "{message}");
        }
        other => panic!("expected a refusal, got {:?}", other.map(|e| e.tally)),
    };
    // Unvalidated on purpose: validation caps heights, and this is the guard behind it.
    refused(run_edit(&params(json!({"operations": overflowing_boxes()})), &t.ctx()));

    let steps: Vec<Step> = serde_json::from_value(Value::Array(overflowing_boxes())).unwrap();
    let sequence = BulldozeSequence { terrain: job_terrain(), resolution_m: 1.0, window: None, steps };
    refused(replay_edit(&sequence, None, &t.ctx()));
    assert!(replay_edit(&sequence, Some(1), &t.ctx()).is_ok(), "one box alone is finite");
}
