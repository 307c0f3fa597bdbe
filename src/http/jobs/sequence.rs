use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::Response;

use crate::http::{AppState, Caller, Problem};

#[utoipa::path(
    get, path = "/v1/jobs/{id}/sequence", tag = "jobs",
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 200, description = "The recorded operation sequence (also the artifact sequence.json)", content_type = "application/json", body = Object),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The job has no sequence (it has not succeeded)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn get_sequence(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let job = state.engine.get(&id, caller.owner()).await?;
    super::artifacts::serve_artifact(&state, &job, "sequence.json", &headers).await.unwrap_or_else(|| {
        Err(crate::jobs::EngineError::Conflict(format!(
            "job {id} has no recorded sequence (it is {})",
            job.status.as_str()
        ))
        .into())
    })
}
