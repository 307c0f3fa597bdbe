use axum::extract::{Query, State};
use axum::Json;
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use crate::http::{AppState, Caller, Problem};
use crate::jobs::{Job, JobStatus};
use crate::store::ListFilter;

const DEFAULT_LIMIT: u32 = 20;
const MAX_LIMIT: u32 = 100;

#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct ListQuery {
    /// Only jobs of this kind (empty: any).
    kind: Option<String>,
    /// Only jobs in this status (empty: any).
    status: Option<String>,
    /// Page size, 1 to 100 (default 20).
    #[param(value_type = Option<u32>, minimum = 1, maximum = 100)]
    limit: Option<String>,
    /// `next_cursor` of the previous page (a job id).
    #[param(pattern = "^[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}$")]
    cursor: Option<String>,
    /// `false`: leave out replays (jobs with `replay_of`), filtered by the server so a page
    /// holds `limit` of the others. Default `true`.
    #[param(value_type = Option<bool>)]
    replays: Option<String>,
}

/// A page of jobs, newest first.
#[derive(Debug, Serialize, ToSchema)]
pub struct JobPage {
    pub items: Vec<Job>,
    /// Pass as `cursor` for the next page; null on the last page.
    pub next_cursor: Option<String>,
}

#[utoipa::path(
    get, path = "/v1/jobs", tag = "jobs",
    params(ListQuery),
    responses(
        (status = 200, description = "Jobs, newest first", body = JobPage),
        (status = 422, description = "A bad filter", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn list_jobs(
    State(state): State<AppState>,
    caller: Caller,
    query: Result<Query<ListQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Json<JobPage>, Problem> {
    // Every parameter is read as text, so a bad one is reported by its own name.
    let Query(q) = query.map_err(|e| Problem::bad_request(e.body_text()))?;
    let status =
        match q.status.as_deref() {
            None | Some("") => None,
            Some(s) => Some(JobStatus::parse(s).ok_or_else(|| {
                Problem::field("status", "must be one of queued, running, succeeded, failed, cancelled")
            })?),
        };
    if let Some(k) = q.kind.as_deref().filter(|k| !k.is_empty()) {
        state.check_kind(k)?;
    }
    let limit = match q.limit.as_deref() {
        // An empty `limit=` is not a number: the schema says integer, so it is refused too.
        None => DEFAULT_LIMIT,
        Some(s) => s
            .parse()
            .ok()
            .filter(|n| (1..=MAX_LIMIT).contains(n))
            .ok_or_else(|| Problem::field("limit", format!("must be a whole number between 1 and {MAX_LIMIT}")))?,
    };
    if let Some(c) = q.cursor.as_deref() {
        if uuid::Uuid::parse_str(c).is_err() {
            return Err(Problem::field("cursor", "is not a cursor this server gave"));
        }
    }
    let no_replays = match q.replays.as_deref() {
        None | Some("true") => false,
        Some("false") => true,
        Some(_) => return Err(Problem::field("replays", "must be true or false")),
    };
    let filter = ListFilter {
        kind: q.kind.filter(|k| !k.is_empty()),
        status,
        before_id: q.cursor,
        limit,
        owner: caller.owner().map(str::to_string),
        no_replays,
    };
    let items = state.engine.list(filter).await?;
    let next_cursor = if items.len() == limit as usize { items.last().map(|j| j.id.clone()) } else { None };
    Ok(Json(JobPage { items, next_cursor }))
}
