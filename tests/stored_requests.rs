//! How a request is kept (issue 28, item 2): numbers as short as they were sent (an `f32` as its
//! own shortest text, not its `f64` widening), no `null` members, every default filled in; the
//! stored form reads back into the same parameters, and a request of numbers stays about the
//! size of its body.

use std::path::Path;

use landform::validate::Limits;
use serde_json::{json, Value};

const COMMON: [&str; 4] = ["seed", "label", "compression", "lods"];

fn params(mut body: Value) -> Value {
    for k in COMMON {
        body.as_object_mut().unwrap().remove(k);
    }
    body
}

fn examples() -> Vec<(String, String, Value)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("api");
    let mut out = Vec::new();
    for kind in std::fs::read_dir(&root).unwrap().flatten().filter(|e| e.path().is_dir()) {
        // Request bodies only (erode's `chains/` folder holds sequences of them).
        for file in std::fs::read_dir(kind.path())
            .unwrap()
            .flatten()
            .filter(|f| f.path().extension().is_some_and(|e| e == "json"))
        {
            let body: Value = serde_json::from_slice(&std::fs::read(file.path()).unwrap()).unwrap();
            out.push((kind.file_name().to_string_lossy().into(), file.file_name().to_string_lossy().into(), body));
        }
    }
    out.sort_by(|a, b| (&a.0, &a.1).cmp(&(&b.0, &b.1)));
    out
}

fn prepare(kind: &str, params: Value) -> Value {
    let registry = landform::sims::registry();
    let k = registry.iter().find(|k| k.name() == kind).unwrap_or_else(|| panic!("no kind {kind}"));
    match k.prepare(params, &Limits::default()) {
        Ok(p) => p.params,
        Err(e) => panic!("{kind}: {e:?}"),
    }
}

/// Stored once and read again, every example's parameters come out the same: a member left out
/// for being `null` reads back as the `None` it was, whole numbers written without a fraction read
/// back as the same floats.
#[test]
fn every_example_is_stored_in_a_form_that_reads_back_the_same() {
    let all = examples();
    assert!(all.len() >= 20, "{} examples", all.len());
    for (kind, name, body) in all {
        let once = prepare(&kind, params(body));
        let twice = prepare(&kind, once.clone());
        assert_eq!(once, twice, "{kind}/{name}");
        let text = serde_json::to_string(&once).unwrap();
        assert!(!text.contains("null"), "{kind}/{name}: {text}");
    }
}

/// The case the issue measured: `0.1` in an `f32` field was stored as `0.10000000149011612`.
#[test]
fn an_f32_is_stored_as_its_own_shortest_text() {
    let stored = prepare(
        "bulldoze",
        json!({"terrain": {"fractal": {"size": 65}}, "operations": [
            {"primitive": {"shape": {"mound": {"center": {"x": 0.1, "z": 12.345}, "radius_m": 3.3, "height_m": 0.1}}, "operator": "add"}}]}),
    );
    let mound = &stored["operations"][0]["primitive"]["shape"]["mound"];
    assert_eq!(mound["center"]["x"].to_string(), "0.1");
    assert_eq!(mound["center"]["z"].to_string(), "12.345");
    assert_eq!(mound["radius_m"].to_string(), "3.3");
    // Defaults are filled in, as integers when whole.
    assert_eq!(mound["curvature"].to_string(), "2");
}

/// A bulldoze body of 50 000 path points with decimals (the shape of the 63 MB body)
/// is stored within 1.2 × its size.
#[test]
fn a_path_of_decimal_points_is_stored_within_1_2_times_its_body() {
    let path: Vec<Value> = (0..50_000)
        .map(|i: u64| json!({"x": ((i * 7919) % 12800) as f64 / 100.0 + 0.1, "z": ((i * 104_729) % 12800) as f64 / 100.0 + 0.1}))
        .collect();
    let body = json!({"terrain": {"fractal": {"size": 129}}, "operations": [
        {"pass": {"path": path, "blade": {"width_m": 2.5}, "operator": "replace"}}]});
    let sent = serde_json::to_vec(&body).unwrap().len();
    let stored = serde_json::to_vec(&prepare("bulldoze", body)).unwrap().len();
    eprintln!("a body of {sent} bytes is stored as {stored}");
    assert!(stored as f64 <= 1.2 * sent as f64, "{stored} stored for {sent} sent");
}
