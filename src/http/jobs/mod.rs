//! Handlers of `/v1/jobs`, one action a file.

pub mod artifacts;
pub mod cancel;
pub mod delete;
pub mod events;
pub mod get;
pub mod list;
pub mod live;
pub mod replay;
pub mod sequence;
pub mod submit;

use std::time::Duration;

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;

use super::{AppState, Problem};
use crate::jobs::Job;

/// Answer for a newly accepted job: 202 with its Location, or, after `Prefer: wait`, 200 when
/// it has ended by then.
pub(super) async fn accepted(
    state: &AppState,
    job: Job,
    wait: Option<Duration>,
    replayed: bool,
) -> Result<Response, Problem> {
    let job = match wait {
        Some(d) if !job.status.is_terminal() => state.engine.wait(&job.id, d).await?,
        _ => job.with_hrefs(),
    };
    // 200 only for a job that has ended; one still queued or running is 202 whoever asks.
    let status =
        if job.status.is_terminal() && (replayed || wait.is_some()) { StatusCode::OK } else { StatusCode::ACCEPTED };
    let location = format!("/v1/jobs/{}", job.id);
    // The job as a summary: a request of megabytes is not echoed back (GET the job for it), so
    // a client that never reads its answer holds no copy of its own body.
    let mut res = (status, Json(job.summarised())).into_response();
    if let Ok(v) = HeaderValue::from_str(&location) {
        res.headers_mut().insert(header::LOCATION, v);
    }
    if let Some(d) = wait {
        if let Ok(v) = HeaderValue::from_str(&format!("wait={}", d.as_secs())) {
            res.headers_mut().insert("preference-applied", v);
        }
    }
    if replayed {
        res.headers_mut().insert("idempotent-replayed", HeaderValue::from_static("true"));
    }
    Ok(res)
}
