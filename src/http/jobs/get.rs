use axum::extract::{Path, State};
use axum::Json;

use crate::http::{AppState, Caller, Problem};
use crate::jobs::Job;

#[utoipa::path(
    get, path = "/v1/jobs/{id}", tag = "jobs",
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 200, description = "The job", body = Job),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn get_job(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<Json<Job>, Problem> {
    Ok(Json(state.engine.get(&id, caller.owner()).await?))
}
