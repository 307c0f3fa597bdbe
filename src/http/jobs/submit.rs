use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::http::HeaderMap;
use axum::response::Response;

use crate::http::body::{canonical_sha256, json_body, prefer_wait};
use crate::http::{AppState, Caller, Problem};
use crate::jobs::Submitted;

/// Longest Idempotency-Key accepted.
const MAX_KEY_LEN: usize = 256;

/// `POST /v1/jobs/{kind}`: validate the kind's parameters and queue the job. Documented per kind
/// in the OpenAPI document (see `openapi.rs`).
///
/// Each kind has its own route, `/v1/jobs/<kind>`, so `Allow` on that path says POST only.
pub async fn submit_job(
    state: AppState,
    caller: Caller,
    kind: String,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, Problem> {
    let key = match headers.get("idempotency-key") {
        None => None,
        Some(v) => {
            Some(v.to_str().ok().filter(|k| !k.is_empty() && k.len() <= MAX_KEY_LEN).map(str::to_string).ok_or_else(
                || Problem::bad_request(format!("Idempotency-Key must be 1 to {MAX_KEY_LEN} visible ASCII characters")),
            )?)
        }
    };
    let who = crate::http::auth::submitter(&state, &caller)?;
    // Idempotency keys are per API key: one key's retry never finds another key's job.
    let scope = match caller.owner() {
        Some(owner) => format!("{owner}/{kind}"),
        None => kind.clone(),
    };
    // One large body at a time is parsed and prepared (see `App::preparing`); a client that
    // goes away while waiting gives its turn up.
    let units = state.preparing_units(body.as_ref().map_or(0, |b| b.len()));
    let preparing = state.preparing.acquire_many(units).await.map_err(|_| crate::http::problem::internal())?;
    // Parsing and hashing a body of many megabytes is CPU work: off the async threads.
    let (body, body_bytes, idempotency) = tokio::task::spawn_blocking(move || {
        let body_bytes = body.as_ref().map_or(0, |b| b.len());
        let body =
            json_body(body)?.ok_or_else(|| Problem::bad_request("the body is empty; send the job's parameters"))?;
        let idempotency = key.map(|k| (format!("{scope}:{k}"), canonical_sha256(&body)));
        Ok::<_, Problem>((body, body_bytes, idempotency))
    })
    .await
    .map_err(|_| crate::http::problem::internal())??;
    let wait = prefer_wait(&headers);
    let submitted = state.engine.submit(&kind, body, body_bytes, idempotency, &who).await;
    let (job, replayed) = match submitted {
        Ok(Submitted::Created(job)) => (job, false),
        Ok(Submitted::Existing(job)) => (job, true),
        Err(e) => return Err(e.into()),
    };
    if wait.is_some() {
        // Waiting for the job to end must not hold up other submissions.
        drop(preparing);
        return super::accepted(&state, job, wait, replayed).await;
    }
    // The job holds the parsed request (a few hundred megabytes for the largest bodies) until
    // its answer is built: the turn is given up only then, so the next large body is parsed
    // after this one's memory is gone, not beside it (four 7 MB bodies at once peaked at three
    // bodies' worth about one time in three).
    let answer = super::accepted(&state, job, None, replayed).await;
    drop(preparing);
    answer
}
