//! axum's own extractors answer a bad path, query or header with `text/plain` (a path segment
//! that is not UTF-8, a query that does not parse). Every error this service sends is
//! problem+json, so such answers are rewritten on their way out.

use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};

use super::Problem;

/// Largest plain-text error body read to make its problem's detail (axum's are one line).
const MOST_TEXT: usize = 4096;

pub async fn as_problem(response: Response) -> Response {
    let status = response.status();
    let plain = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("text/plain"));
    if !(status.is_client_error() || status.is_server_error()) || !plain {
        return response;
    }
    let (parts, body) = response.into_parts();
    let text = axum::body::to_bytes(body, MOST_TEXT).await.map(|b| String::from_utf8_lossy(&b).into_owned());
    let detail = super::problem::clip(text.unwrap_or_default());
    let (slug, title) = match status {
        StatusCode::BAD_REQUEST => ("malformed-request", "Malformed request"),
        StatusCode::UNPROCESSABLE_ENTITY => ("invalid-request", "Invalid request"),
        StatusCode::PAYLOAD_TOO_LARGE => ("body-too-large", "Request body too large"),
        StatusCode::UNSUPPORTED_MEDIA_TYPE => ("unsupported-media-type", "Unsupported media type"),
        _ => ("http-error", status.canonical_reason().unwrap_or("Error")),
    };
    let mut problem = Problem::new(status, slug, title, detail).into_response();
    // Keep what the original answer said besides its body (Allow, WWW-Authenticate, …).
    for (name, value) in parts.headers.iter() {
        if name != header::CONTENT_TYPE && name != header::CONTENT_LENGTH {
            problem.headers_mut().entry(name.clone()).or_insert(value.clone());
        }
    }
    problem
}
