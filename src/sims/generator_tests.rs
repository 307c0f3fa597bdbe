//! Versioned terrain generators across the kinds that start from fractal terrain: a request
//! names the version (absent = 1), an unknown one is refused naming the field, every recorded
//! sequence names the version it used, and a stored sequence replays to the heights pinned here
//! (golden hashes: a change to the generator or to a kind's replay that would move a stored
//! terrain fails these, and must come as a new version instead).

use serde_json::{json, Value};
use sha2::{Digest, Sha256};

use super::{bulldoze::Bulldoze, carve_coast::CarveCoast, deform_terrain::DeformTerrain};
use crate::jobs::{JobKind, Kind, RequestError, Simulation};
use crate::sims::test_support::TestContext;
use crate::terrain::Heightfield;
use crate::validate::Limits;

fn fractal(generator: Option<u32>) -> Value {
    let mut f = json!({"size": 65, "cell_size": 2.0, "relief": 40.0, "seed": 11, "island": true});
    if let Some(g) = generator {
        f["generator"] = json!(g);
    }
    json!({"fractal": f})
}

fn deform(terrain: Value) -> Value {
    json!({"terrain": terrain, "constraints": [{"points": {"points": [{"x": 64.0, "z": 64.0, "height": 30.0}]}}], "max_iterations": 20})
}

fn bulldoze(terrain: Value) -> Value {
    json!({"terrain": terrain, "resolution": 2.0, "operations": [
        {"primitive": {"shape": {"mound": {"center": {"x": 40.0, "z": 60.0}, "radius_m": 20.0, "height_m": 6.0}}, "operator": "add"}},
        {"pass": {"path": [{"x": 10.0, "z": 20.0}, {"x": 110.0, "z": 30.0}], "blade": {"width_m": 8.0}}}
    ]})
}

fn carve(terrain: Value) -> Value {
    json!({"terrain": terrain, "sea_level": 0.0, "passes": 1, "erosion": {"radius_range": [2.0, 4.0]}})
}

fn refused_fields<S: Simulation>(body: Value) -> Vec<String> {
    match Kind::<S>::default().prepare(body, &Limits::default()) {
        Ok(_) => Vec::new(),
        Err(RequestError::Invalid { errors, .. }) => errors.into_iter().map(|e| e.field).collect(),
        Err(RequestError::Malformed(m)) => panic!("malformed: {m}"),
    }
}

#[test]
fn every_fractal_kind_refuses_an_unknown_generator_and_takes_version_1() {
    for (kind, make) in
        [("deform-terrain", deform as fn(Value) -> Value), ("bulldoze", bulldoze), ("carve-coast", carve)]
    {
        let fields = |body: Value| match kind {
            "deform-terrain" => refused_fields::<DeformTerrain>(body),
            "bulldoze" => refused_fields::<Bulldoze>(body),
            _ => refused_fields::<CarveCoast>(body),
        };
        assert_eq!(fields(make(fractal(None))), Vec::<String>::new(), "{kind}");
        assert_eq!(fields(make(fractal(Some(1)))), Vec::<String>::new(), "{kind}");
        for g in [0, 2, 99] {
            assert_eq!(fields(make(fractal(Some(g)))), vec!["terrain.fractal.generator".to_string()], "{kind} {g}");
        }
    }
}

fn heights_sha256(npy: &[u8], cell_m: f32) -> String {
    let hf: Heightfield = crate::export::read_heightfield_npy(npy, cell_m).unwrap();
    let mut sha = Sha256::new();
    for h in &hf.heights_m {
        sha.update(h.to_le_bytes());
    }
    hex::encode(sha.finalize())
}

fn npy(artifacts: &[crate::export::Artifact]) -> &[u8] {
    &artifacts.iter().find(|a| a.name == "heightfield.npy").expect("heightfield.npy").bytes
}

/// A deform-terrain sequence as stored before generators had numbers (no `generator`): three
/// deformations on the island.
const STORED_DEFORM: &str = r#"{
  "terrain": {"fractal": {"size": 65, "cell_size": 2.0, "relief": 40.0, "octaves": 8, "roughness": 0.5, "seed": 11, "island": true}},
  "operations": [
    {"x": 64.0, "z": 64.0, "col": 32, "row": 32, "amplitude": 30.0, "radius_cells": 6, "radius_m": 12.0},
    {"x": 20.0, "z": 100.0, "col": 10, "row": 50, "amplitude": -3.5, "radius_cells": 3, "radius_m": 6.0},
    {"x": 64.0, "z": 70.0, "col": 32, "row": 35, "amplitude": 12.25, "radius_cells": 8, "radius_m": 16.0}
  ]
}"#;

#[test]
fn a_stored_deform_sequence_replays_to_its_pinned_heights() {
    let sequence: super::deform_terrain::DeformSequence = serde_json::from_str(STORED_DEFORM).unwrap();
    // Its request as stored then: without limits (they were off by default; stored requests
    // keep every field, so one stored later carries them explicitly). The fractal's heights
    // are what is pinned here; the service refuses the sequence itself as generator 1's.
    let mut body = deform(fractal(None));
    body["max_free_change"] = json!(1.0);
    body["max_slope_ratio"] = json!(100.0);
    body["keep_weight"] = json!(0.0);
    let params = serde_json::from_value(body).unwrap();
    let t = TestContext::new(Heightfield::from_fn(2, 2, 1.0, |_, _| 0.0));
    let out = DeformTerrain::replay(&params, &sequence, None, &t.ctx()).unwrap();
    assert_eq!(
        heights_sha256(npy(&out.artifacts), 2.0),
        "f2f520875231b50b154c919a02d2d1192c2c281a4e40545a6c956934fb3223fc"
    );
    // Recorded again, the sequence names the version it used.
    assert_eq!(serde_json::to_value(&out.sequence).unwrap()["terrain"]["fractal"]["generator"], json!(1));
}

#[test]
fn stored_requests_and_sequences_name_the_version_and_bulldoze_replays_to_its_pinned_heights() {
    let t = TestContext::new(Heightfield::from_fn(2, 2, 1.0, |_, _| 0.0));
    let params = serde_json::from_value(bulldoze(fractal(None))).unwrap();
    let run = Bulldoze::run(&params, 1, &t.ctx()).unwrap();
    let recorded = serde_json::to_value(&run.sequence).unwrap();
    assert_eq!(recorded["terrain"]["fractal"]["generator"], json!(1));
    let stored = serde_json::from_value(recorded).unwrap();
    let again = Bulldoze::replay(&params, &stored, None, &t.ctx()).unwrap();
    assert_eq!(
        heights_sha256(npy(&again.artifacts), 2.0),
        "a85b87582afb520d8d7a24fe43fd5dd9182d2a6881f93808e2ffa4f2d1029a9a"
    );

    // carve-coast's sequence holds the carvings; the terrain is in the stored request, which
    // has every default filled in.
    for (kind, body) in [("carve-coast", carve(fractal(None))), ("bulldoze", bulldoze(fractal(None)))] {
        let prepared = match kind {
            "carve-coast" => Kind::<CarveCoast>::default().prepare(body, &Limits::default()),
            _ => Kind::<Bulldoze>::default().prepare(body, &Limits::default()),
        };
        let Ok(stored) = prepared.map(|p| p.params) else { panic!("{kind}: a valid request") };
        assert_eq!(stored["terrain"]["fractal"]["generator"], json!(1), "{kind}");
    }
}
