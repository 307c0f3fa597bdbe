use axum::extract::{Path, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

use crate::http::{AppState, Problem};
use crate::jobs::Job;

#[utoipa::path(
    get, path = "/v1/jobs/{id}/artifacts/{name}", tag = "jobs",
    params(
        ("id" = String, Path, description = "Job id"),
        ("name" = String, Path, description = "Artifact name, e.g. mesh.glb, heightmap.png, preview.png, sequence.json"),
        ("If-None-Match" = Option<String>, Header, description = "An ETag from before: 304 when it still matches"),
    ),
    responses(
        (status = 200, description = "The bytes; ETag is their sha256; immutable", content_type = "application/octet-stream", body = Vec<u8>),
        (status = 304, description = "Not modified"),
        (status = 404, description = "No such job or artifact", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn get_artifact(
    State(state): State<AppState>,
    Path((id, name)): Path<(String, String)>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let job = state.engine.get(&id).await?;
    serve_artifact(&state, &job, &name, &headers)
        .await
        .unwrap_or_else(|| Err(Problem::not_found(format!("job {id} has no artifact named {name}"))))
}

/// A job's artifact with its sha256 as ETag, cached for ever, 304 on a matching If-None-Match;
/// None when the job has no artifact of that name.
pub(super) async fn serve_artifact(
    state: &AppState,
    job: &Job,
    name: &str,
    headers: &HeaderMap,
) -> Option<Result<Response, Problem>> {
    let meta = job.artifacts.iter().find(|a| a.name == name)?;
    Some(serve_immutable(state, &job.id, name, &meta.sha256, headers).await)
}

async fn serve_immutable(
    state: &AppState,
    id: &str,
    name: &str,
    sha256: &str,
    headers: &HeaderMap,
) -> Result<Response, Problem> {
    let etag = format!("\"{sha256}\"");
    let cache = HeaderValue::from_static("public, max-age=31536000, immutable");
    let etag_value = HeaderValue::from_str(&etag).map_err(|_| crate::http::problem::internal())?;
    if let Some(inm) = headers.get(header::IF_NONE_MATCH).and_then(|v| v.to_str().ok()) {
        if inm.split(',').map(str::trim).any(|t| t == etag || t == "*" || t.trim_start_matches("W/") == etag) {
            return Ok((StatusCode::NOT_MODIFIED, [(header::ETAG, etag_value), (header::CACHE_CONTROL, cache)])
                .into_response());
        }
    }
    let (media_type, bytes) = state
        .engine
        .artifact(id, name)
        .await?
        .ok_or_else(|| Problem::not_found(format!("job {id} has no artifact named {name}")))?;
    let content_type =
        HeaderValue::from_str(&media_type).unwrap_or(HeaderValue::from_static("application/octet-stream"));
    Ok((
        StatusCode::OK,
        [(header::CONTENT_TYPE, content_type), (header::ETAG, etag_value), (header::CACHE_CONTROL, cache)],
        bytes,
    )
        .into_response())
}
