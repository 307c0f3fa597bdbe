use axum::body::{Body, Bytes};
use axum::extract::{Path, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use futures::stream::{self, StreamExt};

use crate::http::{AppState, Caller, Problem};
use crate::jobs::{EngineError, Job};
use crate::model::ArtifactMeta;
use crate::store::CHUNK_BYTES;

#[utoipa::path(
    get, path = "/v1/jobs/{id}/artifacts/{name}", tag = "jobs",
    params(
        ("id" = String, Path, description = "Job id"),
        ("name" = String, Path, description = "Artifact name, e.g. mesh.glb, heightmap.png, preview.png, sequence.json, tiles/0/1_2.glb (a name may hold folders: send it as it is, or with its slashes percent-encoded)"),
        ("If-None-Match" = Option<String>, Header, description = "An ETag from before: 304 when it still matches"),
        ("Range" = Option<String>, Header, description = "`bytes=FIRST-LAST`, `bytes=FIRST-` or `bytes=-SUFFIX` (one range): 206 with that part. Other forms are ignored (the whole artifact)"),
    ),
    responses(
        (status = 200, description = "The bytes; ETag is their sha256; immutable", content_type = "application/octet-stream", body = Vec<u8>),
        (status = 206, description = "The requested range of the bytes, with Content-Range", content_type = "application/octet-stream", body = Vec<u8>),
        (status = 304, description = "Not modified"),
        (status = 416, description = "The range lies past the end; Content-Range gives the length", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such job or artifact", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn get_artifact(
    State(state): State<AppState>,
    caller: Caller,
    Path((id, name)): Path<(String, String)>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let job = state.engine.get(&id, caller.owner()).await?;
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
    Some(serve_immutable(state, &job.id, meta, headers).await)
}

/// The bytes streamed from the store a chunk at a time (never whole in memory), with
/// `Content-Length`, and one `Range` honoured.
async fn serve_immutable(
    state: &AppState,
    id: &str,
    meta: &ArtifactMeta,
    headers: &HeaderMap,
) -> Result<Response, Problem> {
    let name = meta.name.as_str();
    let etag = format!("\"{}\"", meta.sha256);
    let cache = HeaderValue::from_static("public, max-age=31536000, immutable");
    let etag_value = HeaderValue::from_str(&etag).map_err(|_| crate::http::problem::internal())?;
    if let Some(inm) = headers.get(header::IF_NONE_MATCH).and_then(|v| v.to_str().ok()) {
        if inm.split(',').map(str::trim).any(|t| t == etag || t == "*" || t.trim_start_matches("W/") == etag) {
            return Ok((StatusCode::NOT_MODIFIED, [(header::ETAG, etag_value), (header::CACHE_CONTROL, cache)])
                .into_response());
        }
    }
    let len = meta.bytes;
    let range = headers.get(header::RANGE).and_then(|v| v.to_str().ok()).and_then(parse_range);
    // `bounds`: the inclusive byte range to send, None for an empty artifact.
    let (status, bounds) = match range.map(|r| r.within(len)) {
        None => (StatusCode::OK, len.checked_sub(1).map(|last| (0, last))),
        Some(Some(bounds)) => (StatusCode::PARTIAL_CONTENT, Some(bounds)),
        Some(None) => {
            let mut res = Problem::new(
                StatusCode::RANGE_NOT_SATISFIABLE,
                "range-not-satisfiable",
                "Range not satisfiable",
                format!("{name} has {len} bytes"),
            )
            .into_response();
            if let Ok(v) = HeaderValue::from_str(&format!("bytes */{len}")) {
                res.headers_mut().insert(header::CONTENT_RANGE, v);
            }
            return Ok(res);
        }
    };
    let body = match bounds {
        None => Body::empty(),
        Some((first, last)) => {
            // The first piece is read before answering, so an artifact missing from the store
            // is a 404, not a stream that breaks.
            let piece =
                |offset: u64| Piece { state: state.clone(), id: id.to_string(), name: name.to_string(), offset, last };
            let (head, next) = piece(first)
                .read()
                .await?
                .ok_or_else(|| Problem::not_found(format!("job {id} has no artifact named {name}")))?;
            let rest = stream::try_unfold(next.map(piece), |p| async move {
                let Some(p) = p else { return Ok(None) };
                let read = p.read().await.map_err(|e| io_error(e.to_string()))?;
                let (bytes, next) = read.ok_or_else(|| io_error(format!("{} vanished from the store", p.name)))?;
                Ok::<_, std::io::Error>(Some((bytes, next.map(|offset| Piece { offset, ..p }))))
            });
            Body::from_stream(stream::once(async { Ok(head) }).chain(rest))
        }
    };
    let mut res = (status, body).into_response();
    let h = res.headers_mut();
    h.insert(header::CONTENT_LENGTH, HeaderValue::from(bounds.map_or(0, |(first, last)| last + 1 - first)));
    if let (StatusCode::PARTIAL_CONTENT, Some((first, last))) = (status, bounds) {
        if let Ok(v) = HeaderValue::from_str(&format!("bytes {first}-{last}/{len}")) {
            h.insert(header::CONTENT_RANGE, v);
        }
    }
    let content_type =
        HeaderValue::from_str(&meta.media_type).unwrap_or(HeaderValue::from_static("application/octet-stream"));
    h.insert(header::CONTENT_TYPE, content_type);
    h.insert(header::ETAG, etag_value);
    h.insert(header::CACHE_CONTROL, cache);
    h.insert(header::ACCEPT_RANGES, HeaderValue::from_static("bytes"));
    Ok(res)
}

/// The next piece of a download: from `offset` to the end of its stored chunk, or to `last`.
struct Piece {
    state: AppState,
    id: String,
    name: String,
    offset: u64,
    last: u64,
}

impl Piece {
    /// The piece's bytes and where the next one starts (None after `last`); None when the
    /// artifact is not in the store.
    async fn read(&self) -> Result<Option<(Bytes, Option<u64>)>, EngineError> {
        let chunk = CHUNK_BYTES as u64;
        let len = (chunk - self.offset % chunk).min(self.last + 1 - self.offset);
        let Some(bytes) = self.state.engine.artifact_piece(&self.id, &self.name, self.offset, len as usize).await?
        else {
            return Ok(None);
        };
        if bytes.len() as u64 != len {
            return Err(EngineError::Internal(format!(
                "{}: {} of {len} bytes at {}",
                self.name,
                bytes.len(),
                self.offset
            )));
        }
        let next = self.offset + len;
        Ok(Some((Bytes::from(bytes), (next <= self.last).then_some(next))))
    }
}

fn io_error(message: String) -> std::io::Error {
    std::io::Error::other(message)
}

/// One byte range of RFC 9110 §14.1.2.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ByteRange {
    /// `first-last` (last inclusive) or `first-` (last: None).
    From(u64, Option<u64>),
    /// `-n`: the last n bytes.
    Suffix(u64),
}

impl ByteRange {
    /// The inclusive bounds within `len` bytes, or None when the range lies past the end.
    fn within(self, len: u64) -> Option<(u64, u64)> {
        match self {
            ByteRange::From(first, _) if first >= len => None,
            ByteRange::From(first, last) => Some((first, last.map_or(len - 1, |l| l.min(len - 1)))),
            ByteRange::Suffix(0) => None,
            ByteRange::Suffix(_) if len == 0 => None,
            ByteRange::Suffix(n) => Some((len.saturating_sub(n), len - 1)),
        }
    }
}

/// A single `bytes=` range; anything else (several ranges, other units, bad syntax) is None,
/// and the whole artifact is sent, as RFC 9110 lets a server do.
fn parse_range(value: &str) -> Option<ByteRange> {
    let spec = value.trim().strip_prefix("bytes=")?.trim();
    if spec.contains(',') {
        return None;
    }
    let (a, b) = spec.split_once('-')?;
    let number = |t: &str| -> Option<u64> {
        let t = t.trim();
        (!t.is_empty() && t.bytes().all(|c| c.is_ascii_digit())).then(|| t.parse().ok()).flatten()
    };
    match (a.trim().is_empty(), b.trim().is_empty()) {
        (true, false) => number(b).map(ByteRange::Suffix),
        (false, true) => number(a).map(|first| ByteRange::From(first, None)),
        (false, false) => {
            let (first, last) = (number(a)?, number(b)?);
            (first <= last).then_some(ByteRange::From(first, Some(last)))
        }
        (true, true) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_and_fit_the_length_as_rfc_9110_says() {
        assert_eq!(parse_range("bytes=0-99"), Some(ByteRange::From(0, Some(99))));
        assert_eq!(parse_range("bytes=100-"), Some(ByteRange::From(100, None)));
        assert_eq!(parse_range("bytes=-5"), Some(ByteRange::Suffix(5)));
        for bad in ["bytes=5-1", "bytes=0-1,3-4", "items=0-1", "bytes=-", "bytes=a-b", "0-1"] {
            assert_eq!(parse_range(bad), None, "{bad}");
        }
        let len = 10;
        assert_eq!(ByteRange::From(0, Some(99)).within(len), Some((0, 9)));
        assert_eq!(ByteRange::From(3, None).within(len), Some((3, 9)));
        assert_eq!(ByteRange::Suffix(4).within(len), Some((6, 9)));
        assert_eq!(ByteRange::Suffix(40).within(len), Some((0, 9)));
        assert_eq!(ByteRange::From(10, None).within(len), None);
        assert_eq!(ByteRange::Suffix(0).within(len), None);
    }
}
