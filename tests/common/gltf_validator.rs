//! Runs the Khronos glTF validator (npm package `gltf-validator`, pinned in
//! `tests/gltf-validator/package-lock.json`) over glb bytes.
//!
//! Needs node and `npm ci --prefix tests/gltf-validator` first; without them this panics
//! rather than letting a test pass unchecked.

use std::io::Write;
use std::path::PathBuf;
use std::process::Command;

/// The validator's verdict: issue counts by severity and one line per issue.
#[derive(Debug)]
pub struct ValidatorReport {
    pub errors: u64,
    pub warnings: u64,
    pub infos: u64,
    pub hints: u64,
    /// `SEVERITY CODE at POINTER: message`, as the validator words them.
    pub messages: Vec<String>,
}

impl ValidatorReport {
    /// Counts and every issue, one a line, for assertion messages.
    pub fn summary(&self) -> String {
        format!(
            "{} errors, {} warnings, {} infos, {} hints:\n  {}",
            self.errors,
            self.warnings,
            self.infos,
            self.hints,
            self.messages.join("\n  ")
        )
    }
}

fn harness_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests").join("gltf-validator")
}

/// Validate glb bytes; panics with instructions if node or the npm package is missing.
pub fn validate_glb(bytes: &[u8]) -> ValidatorReport {
    let dir = harness_dir();
    assert!(
        dir.join("node_modules").join("gltf-validator").is_dir(),
        "the glTF validator is not installed: run `npm ci --prefix tests/gltf-validator` (needs node and npm)"
    );
    let mut file = tempfile::Builder::new().suffix(".glb").tempfile().expect("temporary .glb file");
    file.write_all(bytes).expect("write temporary .glb");
    file.flush().expect("flush temporary .glb");

    let output = Command::new("node")
        .arg(dir.join("validate.mjs"))
        .arg(file.path())
        .current_dir(&dir)
        .output()
        .unwrap_or_else(|e| panic!("cannot run `node` for the glTF validator ({e}); install Node.js 18 or later"));
    assert!(
        output.status.success(),
        "the glTF validator failed to run ({}):\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap_or_else(|e| {
        panic!("the glTF validator printed no JSON report ({e}):\n{}", String::from_utf8_lossy(&output.stdout))
    });

    let issues = &report["issues"];
    let count =
        |key: &str| issues[key].as_u64().unwrap_or_else(|| panic!("validator report lacks issues.{key}:\n{report:#}"));
    let messages = issues["messages"].as_array().map(|list| list.iter().map(describe).collect()).unwrap_or_default();
    ValidatorReport {
        errors: count("numErrors"),
        warnings: count("numWarnings"),
        infos: count("numInfos"),
        hints: count("numHints"),
        messages,
    }
}

/// One issue as `SEVERITY CODE at WHERE: message`.
fn describe(issue: &serde_json::Value) -> String {
    let level = match issue["severity"].as_u64() {
        Some(0) => "ERROR",
        Some(1) => "WARNING",
        Some(2) => "INFO",
        Some(3) => "HINT",
        _ => "?",
    };
    let code = issue["code"].as_str().unwrap_or("?");
    let message = issue["message"].as_str().unwrap_or("");
    let place = match (issue["pointer"].as_str(), issue["offset"].as_u64()) {
        (Some(pointer), _) => format!(" at {pointer}"),
        (None, Some(offset)) => format!(" at byte {offset}"),
        (None, None) => String::new(),
    };
    format!("{level} {code}{place}: {message}")
}
