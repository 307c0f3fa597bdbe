//! `GET /v1/presets`: the examples of `api/<kind>/<name>.json` (one complete request body each,
//! the playground's presets too), embedded when the binary is compiled, so a client (the
//! Blender add-on, a game tool) can offer them without a copy of the repository.

use axum::extract::{Query, State};
use axum::Json;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use utoipa::{IntoParams, ToSchema};

use crate::http::{AppState, Problem};

#[derive(rust_embed::RustEmbed)]
#[folder = "api/"]
struct Examples;

#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct PresetQuery {
    /// Only this kind's presets (empty: every kind's).
    kind: Option<String>,
}

/// One example request.
#[derive(Debug, Serialize, ToSchema)]
pub struct Preset {
    /// The job kind it is a request of (`POST /v1/jobs/{kind}`).
    pub kind: String,
    /// Its name, unique within the kind (the example's file name).
    pub name: String,
    /// The body's `label`: what the example shows.
    pub label: Option<String>,
    /// The whole request body, ready to post.
    #[schema(value_type = Object)]
    pub body: Value,
}

/// Every preset, by kind then name.
#[derive(Debug, Serialize, ToSchema)]
pub struct PresetList {
    pub items: Vec<Preset>,
}

#[utoipa::path(
    get, path = "/v1/presets", tag = "jobs",
    params(PresetQuery),
    responses(
        (status = 200, description = "Example requests of every kind (or one), ready to post", body = PresetList),
        (status = 422, description = "An unknown kind", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn list_presets(
    State(state): State<AppState>,
    query: Result<Query<PresetQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Json<PresetList>, Problem> {
    let Query(q) = query.map_err(|e| Problem::bad_request(e.body_text()))?;
    let only = q.kind.filter(|k| !k.is_empty());
    if let Some(k) = only.as_deref() {
        state.check_kind(k)?;
    }
    Ok(Json(PresetList {
        items: presets(|kind| state.engine.has_kind(kind) && only.as_deref().is_none_or(|k| k == kind)),
    }))
}

/// The embedded examples of the kinds `wanted` accepts, sorted by kind then name (rust-embed's
/// order is the file system's).
fn presets(wanted: impl Fn(&str) -> bool) -> Vec<Preset> {
    let mut items: Vec<Preset> = Examples::iter()
        .filter_map(|path| {
            let (kind, file) = path.split_once('/')?;
            let name = file.strip_suffix(".json").filter(|n| !n.contains('/'))?;
            if !wanted(kind) {
                return None;
            }
            let body: Value = serde_json::from_slice(&Examples::get(&path)?.data).ok()?;
            let label = body.get("label").and_then(Value::as_str).map(str::to_string);
            Some(Preset { kind: kind.to_string(), name: name.to_string(), label, body })
        })
        .collect();
    items.sort_by(|a, b| (&a.kind, &a.name).cmp(&(&b.kind, &b.name)));
    items
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Read back from the files themselves (not the embedding): every example of `api/` is a
    /// preset, with its body and label.
    #[test]
    fn every_example_file_is_a_preset_with_its_body() {
        let mut expected = Vec::new();
        for kind_dir in std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/api")).unwrap() {
            let kind_dir = kind_dir.unwrap().path();
            if !kind_dir.is_dir() {
                continue; // api/README.md
            }
            for file in std::fs::read_dir(&kind_dir).unwrap() {
                let file = file.unwrap().path();
                if file.extension().is_some_and(|e| e == "json") {
                    let body: Value = serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
                    let kind = kind_dir.file_name().unwrap().to_str().unwrap().to_string();
                    let name = file.file_stem().unwrap().to_str().unwrap().to_string();
                    expected.push((kind, name, body));
                }
            }
        }
        expected.sort_by(|a, b| (&a.0, &a.1).cmp(&(&b.0, &b.1)));
        let got = presets(|_| true);
        assert!(got.len() > 20, "{} presets", got.len());
        assert_eq!(got.len(), expected.len());
        for (p, (kind, name, body)) in got.iter().zip(&expected) {
            assert_eq!((&p.kind, &p.name, &p.body), (kind, name, body));
            assert_eq!(p.label.as_deref(), body["label"].as_str());
        }
        assert!(presets(|k| k == "bulldoze").iter().all(|p| p.kind == "bulldoze"));
    }
}
