use std::collections::VecDeque;
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::{Path, Query, State};
use axum::http::HeaderMap;
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use futures::stream::{self, Stream, StreamExt};
use serde::Deserialize;
use tokio::sync::broadcast::{error::RecvError, Receiver};

use crate::http::{AppState, Caller, Problem};
use crate::jobs::{until_changed, Engine, EventFeed, JobEvent, LiveJob};

/// One server-sent event as a client's parser sees it.
#[derive(utoipa::ToSchema)]
#[allow(dead_code)]
pub struct SseEvent {
    /// `progress`, `status` or `done`.
    #[schema(pattern = "^(progress|status|done)$")]
    event: Option<String>,
    /// The event id, to resume after with `Last-Event-ID`.
    #[schema(pattern = "^[0-9]{1,19}$")]
    id: Option<String>,
    /// JSON: the progress, the status, or (for `done`) the Job.
    data: String,
    retry: Option<u64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EventsQuery {
    /// For clients that cannot set the `Last-Event-ID` header (EventSource polyfills).
    last_event_id: Option<u64>,
}

#[utoipa::path(
    get, path = "/v1/jobs/{id}/events", tag = "jobs",
    params(
        ("id" = String, Path, description = "Job id"),
        ("Last-Event-ID" = Option<u64>, Header, description = "Resume after this event"),
    ),
    responses(
        (status = 200, description = "Server-sent events: `progress` (with `snapshot` when a live picture is new), `status` on each change, and a final `done` carrying the Job; keep-alive comments while idle", content_type = "text/event-stream", body = SseEvent),
        (status = 400, description = "A Last-Event-ID that is not an event id", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "A last_event_id query that is not an event id", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn job_events(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
    query: Result<Query<EventsQuery>, axum::extract::rejection::QueryRejection>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let Query(q) = query.map_err(|_| Problem::field("last_event_id", "must be an event id (an unsigned integer)"))?;
    let header = match headers.get("last-event-id") {
        None => None,
        Some(v) => Some(v.to_str().ok().and_then(parse_event_id).ok_or_else(|| {
            Problem::bad_request("Last-Event-ID must be an event id this server sent (1 to 19 digits)")
        })?),
    };
    let last = header.or(q.last_event_id);
    let keep_alive = KeepAlive::new().interval(Duration::from_secs(15)).text("keep-alive");
    Ok(match state.engine.events(&id, last, caller.owner()).await? {
        EventFeed::Ended(job) => {
            // A summary: a stream a client never reads holds a few KiB, not a large request.
            let data = serde_json::to_string(&job.summarised()).unwrap_or_default();
            let done =
                Event::default().event("done").id(last.map_or(1, |l| l.saturating_add(1)).to_string()).data(data);
            Sse::new(stream::iter([Ok::<_, Infallible>(done)])).keep_alive(keep_alive).into_response()
        }
        EventFeed::Live { backlog, rx, live } => {
            Sse::new(live_stream(backlog, rx, live, last.unwrap_or(0))).keep_alive(keep_alive).into_response()
        }
        EventFeed::Stored { after } => {
            let owner = caller.owner().map(str::to_string);
            Sse::new(stored_stream(state.engine.clone(), id, owner, after)).keep_alive(keep_alive).into_response()
        }
    })
}

/// A job running in another process, followed through the store: its events as they are
/// appended (ids from the store, so a client may resume on any replica), then its final
/// status and `done` once the job has ended. A job deleted meanwhile ends the stream.
fn stored_stream(
    engine: Engine,
    id: String,
    owner: Option<String>,
    after: u64,
) -> impl Stream<Item = Result<Event, Infallible>> {
    let notices = engine.notices();
    let state = (engine, id, owner, after, VecDeque::<Event>::new(), false, notices);
    stream::unfold(state, |(engine, id, owner, mut last, mut pending, mut ended, mut notices)| async move {
        loop {
            if let Some(ev) = pending.pop_front() {
                return Some((Ok(ev), (engine, id, owner, last, pending, ended, notices)));
            }
            if ended {
                return None;
            }
            match engine.stored_events(&id, last).await {
                Ok(events) if !events.is_empty() => {
                    last = queue_stored(&mut pending, events, last);
                    continue;
                }
                Ok(_) => {}
                Err(e) => {
                    tracing::warn!(job = %id, error = %e, "could not read a job's events");
                    return None;
                }
            }
            // The status alone, each time it may have changed; the job itself once, at its end.
            let ended_now = match engine.status_of(&id).await {
                Ok((status, job_owner)) if job_owner == owner => status.is_terminal(),
                _ => return None,
            };
            if !ended_now {
                until_changed(&id, &mut notices).await;
                continue;
            }
            match engine.summary(&id).await {
                Ok(job) => {
                    // Events appended between the last read and the end are still there.
                    if let Ok(events) = engine.stored_events(&id, last).await {
                        last = queue_stored(&mut pending, events, last);
                    }
                    let status = serde_json::json!({ "status": job.status }).to_string();
                    let done = serde_json::to_string(&job.summarised()).unwrap_or_default();
                    pending.push_back(Event::default().id((last + 1).to_string()).event("status").data(status));
                    pending.push_back(Event::default().id((last + 2).to_string()).event("done").data(done));
                    ended = true;
                }
                Err(_) => return None,
            }
        }
    })
}

/// An event id as the schema states it (`^[0-9]{1,19}$`): ids this server sends are clock-based
/// and have at most 19 digits, so anything longer — leading zeros included — is not one of them.
fn parse_event_id(v: &str) -> Option<u64> {
    let v = v.trim();
    (!v.is_empty() && v.len() <= 19 && v.bytes().all(|b| b.is_ascii_digit())).then(|| v.parse().ok()).flatten()
}

/// Queue stored events to send; returns the id of the last (or `last` when there are none).
fn queue_stored(pending: &mut VecDeque<Event>, events: Vec<crate::store::StoredEvent>, last: u64) -> u64 {
    events.into_iter().fold(last, |_, e| {
        pending.push_back(Event::default().id(e.id.to_string()).event(e.event).data(e.data));
        e.id
    })
}

struct Feed {
    pending: VecDeque<JobEvent>,
    rx: Receiver<JobEvent>,
    live: Arc<LiveJob>,
    last_id: u64,
    ended: bool,
}

/// Backlog first, then live events, ending after `done`.
fn live_stream(
    backlog: Vec<JobEvent>,
    rx: Receiver<JobEvent>,
    live: Arc<LiveJob>,
    last_id: u64,
) -> impl Stream<Item = Result<Event, Infallible>> {
    let feed = Feed { pending: backlog.into(), rx, live, last_id, ended: false };
    stream::unfold(feed, |mut f| async move {
        loop {
            if f.ended {
                return None;
            }
            if let Some(ev) = f.pending.pop_front() {
                // `done` always goes out: a client resuming with an id from before a restart
                // must still see the job end.
                if ev.id <= f.last_id && ev.event != "done" {
                    continue;
                }
                f.last_id = f.last_id.max(ev.id);
                f.ended = ev.event == "done";
                return Some((ev, f));
            }
            match f.rx.recv().await {
                Ok(ev) => f.pending.push_back(ev),
                // A slow reader fell behind the channel: catch up from the log.
                Err(RecvError::Lagged(_)) => f.pending.extend(f.live.events_after(f.last_id)),
                Err(RecvError::Closed) => return None,
            }
        }
    })
    .map(|ev| Ok(Event::default().id(ev.id.to_string()).event(ev.event).data(ev.data.to_string())))
}

#[cfg(test)]
mod tests {
    use super::parse_event_id;

    #[test]
    fn event_ids_are_one_to_nineteen_digits() {
        assert_eq!(parse_event_id("0"), Some(0));
        assert_eq!(parse_event_id(" 42 "), Some(42));
        assert_eq!(parse_event_id("9999999999999999999"), Some(9_999_999_999_999_999_999));
        for bad in ["", "00000000000000000000", "+1", "-1", "1e3", "١"] {
            assert_eq!(parse_event_id(bad), None, "{bad:?}");
        }
    }
}
