use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::Response;

use crate::http::body::{canonical_sha256, json_body, prefer_wait};
use crate::http::{AppState, Problem};
use crate::jobs::Submitted;

/// Longest Idempotency-Key accepted.
const MAX_KEY_LEN: usize = 256;

/// `POST /v1/jobs/{kind}`: validate the kind's parameters and queue the job. Documented per kind
/// in the OpenAPI document (see `openapi.rs`).
pub async fn submit_job(
    State(state): State<AppState>,
    Path(kind): Path<String>,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, Problem> {
    if !state.engine.has_kind(&kind) {
        return Err(Problem::not_found(format!(
            "no job kind named {kind}; kinds: {}",
            state.engine.kind_names().join(", ")
        )));
    }
    let key = match headers.get("idempotency-key") {
        None => None,
        Some(v) => {
            Some(v.to_str().ok().filter(|k| !k.is_empty() && k.len() <= MAX_KEY_LEN).map(str::to_string).ok_or_else(
                || Problem::bad_request(format!("Idempotency-Key must be 1 to {MAX_KEY_LEN} visible ASCII characters")),
            )?)
        }
    };
    // Parsing and hashing a body of many megabytes is CPU work: off the async threads.
    let scope = kind.clone();
    let (body, idempotency) = tokio::task::spawn_blocking(move || {
        let body =
            json_body(body)?.ok_or_else(|| Problem::bad_request("the body is empty; send the job's parameters"))?;
        let idempotency = key.map(|k| (format!("{scope}:{k}"), canonical_sha256(&body)));
        Ok::<_, Problem>((body, idempotency))
    })
    .await
    .map_err(|_| crate::http::problem::internal())??;
    let wait = prefer_wait(&headers);
    match state.engine.submit(&kind, body, idempotency).await? {
        Submitted::Created(job) => super::accepted(&state, job, wait, false).await,
        Submitted::Existing(job) => super::accepted(&state, job, wait, true).await,
    }
}
