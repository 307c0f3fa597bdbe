use axum::extract::{Path, State};
use axum::http::{header, HeaderMap};
use axum::response::{IntoResponse, Response};

use crate::http::{AppState, Caller, Problem};

#[utoipa::path(
    get, path = "/v1/jobs/{id}/live.png", tag = "jobs",
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 200, description = "The latest live snapshot while the job runs; the final preview once it has succeeded", content_type = "image/png", body = Vec<u8>),
        (status = 404, description = "No such job, or no picture yet", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn live_png(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    if let Some((_, png)) = state.engine.live_snapshot(&id, caller.owner()).await? {
        return Ok(([(header::CONTENT_TYPE, "image/png"), (header::CACHE_CONTROL, "no-store")], png).into_response());
    }
    let job = state.engine.get(&id, caller.owner()).await?;
    super::artifacts::serve_artifact(&state, &job, "preview.png", &headers).await.unwrap_or_else(|| {
        Err(Problem::not_found(format!("job {id} has no picture yet (it is {})", job.status.as_str())))
    })
}
