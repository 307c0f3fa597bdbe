//! Operations endpoints: liveness, readiness, metrics, and the 404 for unknown routes.

use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::json;

use super::{AppState, Problem};

#[utoipa::path(get, path = "/healthz", tag = "operations",
    responses((status = 200, description = "The process is up", body = Object)))]
pub async fn healthz() -> Json<serde_json::Value> {
    Json(json!({ "status": "ok" }))
}

#[utoipa::path(get, path = "/readyz", tag = "operations",
    responses(
        (status = 200, description = "The store answers; jobs can be accepted", body = Object),
        (status = 503, description = "The store does not answer", body = Problem, content_type = "application/problem+json"),
    ))]
pub async fn readyz(State(state): State<AppState>) -> Response {
    if state.engine.ready().await {
        Json(json!({ "status": "ready", "queue_depth": state.engine.queue_depth() })).into_response()
    } else {
        Problem::new(StatusCode::SERVICE_UNAVAILABLE, "not-ready", "Not ready", "the job store does not answer")
            .into_response()
    }
}

#[utoipa::path(get, path = "/metrics", tag = "operations",
    responses((status = 200, description = "Prometheus text format: landform_jobs{kind,status}, landform_queue_depth, landform_jobs_running, landform_job_duration_seconds", content_type = "text/plain", body = String)))]
pub async fn metrics(State(state): State<AppState>) -> Result<Response, Problem> {
    let text = state.engine.metrics_text().await?;
    Ok(([(header::CONTENT_TYPE, "text/plain; version=0.0.4; charset=utf-8")], text).into_response())
}

/// 405 (axum adds `Allow`), except a POST to `/v1/jobs/<name>` that names no kind: that is a
/// kind that does not exist, 404.
pub async fn method_not_allowed(
    State(state): State<AppState>,
    method: axum::http::Method,
    uri: axum::http::Uri,
) -> Problem {
    if let Some(name) = uri.path().strip_prefix("/v1/jobs/").filter(|n| !n.contains('/')) {
        if method == axum::http::Method::POST {
            return Problem::not_found(format!(
                "no job kind named {name}; kinds: {}",
                state.engine.kind_names().join(", ")
            ));
        }
    }
    Problem::new(
        StatusCode::METHOD_NOT_ALLOWED,
        "method-not-allowed",
        "Method not allowed",
        "see /docs for what this path takes",
    )
}

/// What the API docs page may load: its own scripts and styles (Swagger UI sets inline styles
/// and data: images), no framing by other sites.
const DOCS_CSP: &str = "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; \
    img-src 'self' data:; connect-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; \
    frame-ancestors 'none'";

pub async fn docs_headers(mut response: Response) -> Response {
    let h = response.headers_mut();
    h.insert(header::CONTENT_SECURITY_POLICY, axum::http::HeaderValue::from_static(DOCS_CSP));
    h.insert(header::X_FRAME_OPTIONS, axum::http::HeaderValue::from_static("DENY"));
    h.insert(header::X_CONTENT_TYPE_OPTIONS, axum::http::HeaderValue::from_static("nosniff"));
    response
}

pub async fn not_found() -> Problem {
    Problem::not_found("no such route; see /docs")
}
