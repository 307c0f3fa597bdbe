//! Blender's glTF importer (Debian's Blender 3.4) ignores `MSFT_lod` and makes each level of
//! detail a visible object on top of the full one; the `landform` add-on (`clients/blender`)
//! puts them in a collection of their own, hidden in the viewport and in renders. Imported
//! headless through `tests/blender/import.py`, a grow-cave job's `mesh.glb` (one node a piece,
//! three levels each) without and with the add-on.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use serde_json::{json, Value};

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Blender's report of importing `glb`, with the add-on enabled or not.
fn import(glb: &Path, addon: bool) -> Value {
    let mut blender = Command::new("blender");
    blender.args(["-b", "--factory-startup", "-P"]).arg(repo().join("tests/blender/import.py")).arg("--").arg(glb);
    if addon {
        blender.env("LANDFORM_BLENDER_ADDON", repo().join("clients/blender"));
    } else {
        blender.env_remove("LANDFORM_BLENDER_ADDON");
    }
    let output = blender.output().unwrap_or_else(|e| panic!("cannot run `blender` ({e}); scripts/test installs it"));
    let line = String::from_utf8_lossy(&output.stdout)
        .lines()
        .find_map(|l| l.strip_prefix("LANDFORM ").map(str::to_string))
        .unwrap_or_else(|| panic!("no report from Blender: {}", String::from_utf8_lossy(&output.stderr)));
    let report: Value = serde_json::from_str(&line).unwrap();
    assert_eq!(report["result"], json!(["FINISHED"]), "{report}");
    report
}

/// Mesh objects by name.
fn meshes(report: &Value) -> BTreeMap<String, Value> {
    report["objects"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|o| o["type"] == "MESH")
        .map(|o| (o["name"].as_str().unwrap().to_string(), o.clone()))
        .collect()
}

#[test]
fn the_addon_hides_the_levels_of_detail_blender_imports_as_objects() {
    let dir = tempfile::tempdir().unwrap();
    let mut body: Value =
        serde_json::from_str(&std::fs::read_to_string(repo().join("api/grow-cave/columns.json")).unwrap()).unwrap();
    body.as_object_mut().unwrap().remove("lods");
    let request = dir.path().join("request.json");
    std::fs::write(&request, body.to_string()).unwrap();
    let out = dir.path().join("out");
    let status = Command::new(env!("CARGO_BIN_EXE_landform"))
        .arg("run")
        .arg(&request)
        .arg("--out")
        .arg(&out)
        .args(["--kind", "grow-cave", "--database"])
        .arg(dir.path().join("db.sqlite"))
        .status()
        .unwrap();
    assert!(status.success());
    let job: Value = serde_json::from_str(&std::fs::read_to_string(out.join("job.json")).unwrap()).unwrap();
    let levels = job["result"]["glb"]["levels"].as_array().unwrap().len();
    assert_eq!(levels, 4, "the full mesh and three levels");
    let glb = out.join("mesh.glb");

    // Without the add-on every level is an object in view, over its full piece.
    let plain = meshes(&import(&glb, false));
    let pieces = plain.keys().filter(|n| !n.contains(" lod")).count();
    assert!(pieces > 10, "{pieces} pieces");
    assert_eq!(plain.len(), pieces * levels);
    assert!(plain.values().all(|o| o["shown"] == json!(true)));

    // With it the same objects, the full pieces in view and rendered, each level hidden in the
    // levels' collection and naming the piece it is a level of.
    let with = meshes(&import(&glb, true));
    assert_eq!(with.keys().collect::<Vec<_>>(), plain.keys().collect::<Vec<_>>());
    for (name, object) in &with {
        match name.rsplit_once(" lod") {
            None => {
                assert_eq!(object["shown"], json!(true), "{name}");
                assert_eq!(object["rendered"], json!(true), "{name}");
                assert_eq!(object["lod_of"], Value::Null, "{name}");
            }
            Some((piece, level)) => {
                assert_eq!(object["shown"], json!(false), "{name}");
                assert_eq!(object["rendered"], json!(false), "{name}");
                assert_eq!(object["collections"], json!(["Landform levels of detail"]), "{name}");
                assert_eq!(object["lod_of"], json!(piece), "{name}");
                assert_eq!(object["lod_level"].to_string(), level, "{name}");
                assert_eq!(object["triangles"], plain[name]["triangles"], "{name}");
            }
        }
    }
}
