//! `POST /v1/drafts/{kind}`: a request run at once at the kind's draft resolution, answered
//! with its mesh (glb) and nothing stored. For pages that show a result while it is edited;
//! `POST /v1/jobs/{kind}` with the same body makes the full job.

use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::http::{header, HeaderValue};
use axum::response::{IntoResponse, Response};

use crate::http::body::json_body;
use crate::http::{AppState, Caller, Problem};
use crate::jobs::EngineError;

/// Drafts run at once in one process; another is answered 503 (Retry-After 1): a page asks
/// again with its next edit, and full jobs keep the rest of the machine.
pub const DRAFTS_AT_ONCE: usize = 2;

pub async fn run_draft(
    state: AppState,
    caller: Caller,
    kind: String,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, Problem> {
    let who = crate::http::auth::submitter(&state, &caller)?;
    let Ok(_turn) = state.drafts.try_acquire() else {
        return Err(EngineError::Busy(format!("{DRAFTS_AT_ONCE} drafts are running; ask again in a moment")).into());
    };
    let units = state.preparing_units(body.as_ref().map_or(0, |b| b.len()));
    let preparing = state.preparing.acquire_many(units).await.map_err(|_| crate::http::problem::internal())?;
    let body = tokio::task::spawn_blocking(move || json_body(body))
        .await
        .map_err(|_| crate::http::problem::internal())??
        .ok_or_else(|| Problem::bad_request("the body is empty; send the job's parameters"))?;
    drop(preparing);
    let draft = state.engine.draft(&kind, body, &who).await?;
    let mut res = ([(header::CONTENT_TYPE, "model/gltf-binary")], draft.glb).into_response();
    let h = res.headers_mut();
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    if let Ok(v) = HeaderValue::from_str(&format!("{:.3}", draft.seconds)) {
        h.insert("landform-draft-seconds", v);
    }
    // The result's figures, small, as one JSON line: a page can show them beside the mesh.
    if let Ok(v) = HeaderValue::from_str(&serde_json::to_string(&draft.result).unwrap_or_default()) {
        if v.len() <= 8 << 10 {
            h.insert("landform-draft-result", v);
        }
    }
    Ok(res)
}
