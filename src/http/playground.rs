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

/// For working on the page: `LANDFORM_PLAYGROUND_DIR` names a built bundle (`web/dist`) served
/// from disk instead of the embedded one, so a changed page needs `npm run build` and a reload,
/// not a recompile of the server. Read once, when the first page is asked for.
fn override_dir() -> Option<&'static std::path::Path> {
    static DIR: std::sync::OnceLock<Option<std::path::PathBuf>> = std::sync::OnceLock::new();
    DIR.get_or_init(|| std::env::var_os("LANDFORM_PLAYGROUND_DIR").map(Into::into)).as_deref()
}

/// A file of the bundle: from the override folder when one is set (a name with anything but
/// plain components is refused there), else embedded.
fn file(name: &str) -> Option<(Vec<u8>, [u8; 32])> {
    let Some(dir) = override_dir() else {
        return Bundle::get(name).map(|f| (f.data.into_owned(), f.metadata.sha256_hash()));
    };
    let relative = std::path::Path::new(name);
    if !relative.components().all(|c| matches!(c, std::path::Component::Normal(_))) {
        return None;
    }
    let data = std::fs::read(dir.join(relative)).ok()?;
    let hash = <sha2::Sha256 as sha2::Digest>::digest(&data).into();
    Some((data, hash))
}

fn serve(name: &str, cache: &'static str, headers: &HeaderMap) -> Response {
    let Some((data, sha256)) = file(name) else {
        return Problem::not_found(format!("no file {name} in the playground")).into_response();
    };
    let etag = format!("\"{}\"", hex(&sha256));
    let mut response = if headers.get(header::IF_NONE_MATCH).is_some_and(|v| v.as_bytes() == etag.as_bytes()) {
        StatusCode::NOT_MODIFIED.into_response()
    } else {
        ([(header::CONTENT_TYPE, content_type(name))], data).into_response()
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
