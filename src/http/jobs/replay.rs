use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::Response;
use serde::Deserialize;
use utoipa::ToSchema;

use crate::http::body::{json_body, prefer_wait};
use crate::http::{AppState, Caller, Problem};
use crate::jobs::parse_params;

/// What to replay of a job's recorded sequence.
#[derive(Debug, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ReplayRequest {
    /// Stop after this many steps of the sequence (default: all of them). At most the number of
    /// steps the job's recorded sequence has (more is answered with 422).
    pub until_step: Option<u64>,
}

#[utoipa::path(
    post, path = "/v1/jobs/{id}/replay", tag = "jobs",
    params(
        ("id" = String, Path, description = "The job to replay"),
        ("Prefer" = Option<String>, Header, description = "`wait=N` (N ≤ 60): hold the answer until the job ends or N seconds pass"),
    ),
    request_body(content = Option<ReplayRequest>, description = "Optional; an empty body replays everything"),
    responses(
        (status = 202, description = "A new job rebuilding the result from the recorded sequence, without searching or sampling", body = crate::jobs::Job),
        (status = 200, description = "With Prefer: wait, the replay has already ended", body = crate::jobs::Job),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The job has not succeeded", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "until_step beyond the sequence", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "The queue is full; see Retry-After", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn replay_job(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, Problem> {
    // No body, or `null` (the schema's optional body), replays everything.
    let req: ReplayRequest = match json_body(body)? {
        None | Some(serde_json::Value::Null) => ReplayRequest::default(),
        Some(v) => parse_params(v)?,
    };
    let who = crate::http::auth::submitter(&state, &caller)?;
    let job = state.engine.replay(&id, req.until_step, &who).await?;
    super::accepted(&state, job, prefer_wait(&headers), false).await
}
