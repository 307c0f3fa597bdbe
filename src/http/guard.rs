//! What a browser may send from another site without asking first. A page anywhere can make a
//! visitor's browser POST a "simple" request (a form, or `fetch` with `text/plain`) with no CORS
//! preflight; CORS only stops the page reading the answer, not the request taking effect. So a
//! request that changes state is refused when it comes from an origin the server does not allow,
//! and a body is read only when it says it is JSON (a type no simple request can carry).

use axum::extract::{Request, State};
use axum::http::{header, HeaderMap, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::{AppState, Problem};

/// Refuses cross-origin state changes from origins outside `--cors-origins`, and request bodies
/// that are not `application/json`.
pub async fn refuse_cross_site(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let changes_state = !matches!(*req.method(), Method::GET | Method::HEAD | Method::OPTIONS);
    if changes_state {
        if let Some(origin) = req.headers().get(header::ORIGIN) {
            let origin = origin.to_str().unwrap_or("");
            if !origin_allowed(origin, req.headers(), &state.config.cors_origins) {
                return Problem::new(
                    StatusCode::FORBIDDEN,
                    "cross-origin",
                    "Cross-origin request refused",
                    "this server does not take requests that change state from pages of other origins; its \
                     operator can allow an origin with --cors-origins",
                )
                .into_response();
            }
        }
        if has_body(req.headers()) && !is_json(req.headers()) {
            return Problem::new(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "unsupported-media-type",
                "Unsupported media type",
                "send the body as JSON, with Content-Type: application/json",
            )
            .into_response();
        }
    }
    next.run(req).await
}

/// A page's own origin (the playground) is always allowed; others only when listed (or `*`).
fn origin_allowed(origin: &str, headers: &HeaderMap, allowed: &[String]) -> bool {
    if allowed.iter().any(|a| a == "*" || a.eq_ignore_ascii_case(origin)) {
        return true;
    }
    // Same origin: the Origin's authority is the Host the request was sent to.
    let authority = origin.split_once("://").map_or("", |(_, rest)| rest);
    let host = headers.get(header::HOST).and_then(|h| h.to_str().ok()).unwrap_or("");
    !authority.is_empty() && authority.eq_ignore_ascii_case(host)
}

/// Whether the request carries a body: a non-zero Content-Length, or a chunked one.
fn has_body(headers: &HeaderMap) -> bool {
    let length = headers.get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok()?.trim().parse::<u64>().ok());
    match length {
        Some(n) => n > 0,
        None => headers.contains_key(header::TRANSFER_ENCODING),
    }
}

/// `application/json` or a `+json` type, with any parameters (`; charset=utf-8`).
fn is_json(headers: &HeaderMap) -> bool {
    let Some(value) = headers.get(header::CONTENT_TYPE).and_then(|v| v.to_str().ok()) else {
        return false;
    };
    let essence = value.split(';').next().unwrap_or("").trim().to_ascii_lowercase();
    essence == "application/json" || (essence.starts_with("application/") && essence.ends_with("+json"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn headers(pairs: &[(&'static str, &'static str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.insert(*k, HeaderValue::from_static(v));
        }
        h
    }

    #[test]
    fn only_listed_or_same_origins_may_change_state() {
        let h = headers(&[("host", "127.0.0.1:8080")]);
        assert!(origin_allowed("http://127.0.0.1:8080", &h, &[]));
        assert!(!origin_allowed("https://evil.example", &h, &[]));
        assert!(origin_allowed("https://tool.example", &h, &["https://tool.example".into()]));
        assert!(origin_allowed("https://evil.example", &h, &["*".into()]));
        assert!(!origin_allowed("null", &h, &[]));
    }

    #[test]
    fn json_is_recognised_with_parameters_and_suffixes() {
        assert!(is_json(&headers(&[("content-type", "application/json")])));
        assert!(is_json(&headers(&[("content-type", "Application/JSON; charset=utf-8")])));
        assert!(is_json(&headers(&[("content-type", "application/merge-patch+json")])));
        assert!(!is_json(&headers(&[("content-type", "text/plain")])));
        assert!(!is_json(&headers(&[("content-type", "application/x-www-form-urlencoded")])));
        assert!(!is_json(&headers(&[])));
        assert!(has_body(&headers(&[("content-length", "2")])));
        assert!(!has_body(&headers(&[("content-length", "0")])));
        assert!(has_body(&headers(&[("transfer-encoding", "chunked")])));
    }
}
