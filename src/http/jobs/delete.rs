use axum::extract::{Path, State};
use axum::http::StatusCode;

use crate::http::{AppState, Caller, Problem};

#[utoipa::path(
    delete, path = "/v1/jobs/{id}", tag = "jobs",
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 204, description = "Cancelled if it was running, then removed with its artifacts"),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn delete_job(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<StatusCode, Problem> {
    state.engine.delete(&id, caller.owner()).await?;
    Ok(StatusCode::NO_CONTENT)
}
