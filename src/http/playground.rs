//! The playground at `/`: the page built from `web/` (Vite + TypeScript + three.js). The built
//! bundle is committed in `web/dist` and embedded into the binary when it is compiled, so the
//! server needs no Node and no files beside it; `tests/web_bundle.rs` fails when the bundle is
//! stale against `web/src`.

use axum::extract::Path;
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

use super::Problem;

#[derive(rust_embed::RustEmbed)]
#[folder = "web/dist/"]
struct Bundle;

/// What the page may load: only this origin, blobs for artifacts fetched with a key, and
/// WebAssembly compilation for three.js's meshopt decoder.
const CSP: &str = "default-src 'self'; script-src 'self' 'wasm-unsafe-eval'; style-src 'self'; \
    img-src 'self' blob: data:; connect-src 'self'; worker-src 'self' blob:; object-src 'none'; \
    base-uri 'none'; frame-ancestors 'none'";

pub async fn index(headers: HeaderMap) -> Response {
    serve("index.html", "no-cache", &headers)
}

pub async fn asset(Path(path): Path<String>, headers: HeaderMap) -> Response {
    // Vite names every asset by its content's hash: it never changes under its name.
    serve(&format!("assets/{path}"), "public, max-age=31536000, immutable", &headers)
}

fn serve(name: &str, cache: &'static str, headers: &HeaderMap) -> Response {
    let Some(file) = Bundle::get(name) else {
        return Problem::not_found(format!("no file {name} in the playground")).into_response();
    };
    let etag = format!("\"{}\"", hex(&file.metadata.sha256_hash()));
    let mut response = if headers.get(header::IF_NONE_MATCH).is_some_and(|v| v.as_bytes() == etag.as_bytes()) {
        StatusCode::NOT_MODIFIED.into_response()
    } else {
        ([(header::CONTENT_TYPE, content_type(name))], file.data.into_owned()).into_response()
    };
    let h = response.headers_mut();
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static(cache));
    h.insert(header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    h.insert(header::CONTENT_SECURITY_POLICY, HeaderValue::from_static(CSP));
    if let Ok(v) = HeaderValue::from_str(&etag) {
        h.insert(header::ETAG, v);
    }
    response
}

fn content_type(name: &str) -> &'static str {
    match name.rsplit('.').next() {
        Some("html") => "text/html; charset=utf-8",
        Some("js") => "text/javascript; charset=utf-8",
        Some("css") => "text/css; charset=utf-8",
        Some("svg") => "image/svg+xml",
        Some("png") => "image/png",
        Some("json") => "application/json",
        Some("wasm") => "application/wasm",
        _ => "application/octet-stream",
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
