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

use crate::http::{AppState, Problem};
use crate::jobs::{EventFeed, JobEvent, LiveJob};

#[derive(Debug, Deserialize)]
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
        (status = 200, description = "Server-sent events: `progress` (with `snapshot` when a live picture is new), `status` on each change, and a final `done` carrying the Job; keep-alive comments while idle", content_type = "text/event-stream", body = String),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn job_events(
    State(state): State<AppState>,
    Path(id): Path<String>,
    query: Result<Query<EventsQuery>, axum::extract::rejection::QueryRejection>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let Query(q) = query.map_err(|_| Problem::field("last_event_id", "must be an event id (an unsigned integer)"))?;
    let last = headers
        .get("last-event-id")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok())
        .or(q.last_event_id);
    let keep_alive = KeepAlive::new().interval(Duration::from_secs(15)).text("keep-alive");
    Ok(match state.engine.events(&id, last).await? {
        EventFeed::Ended(job) => {
            let data = serde_json::to_string(&job).unwrap_or_default();
            let done =
                Event::default().event("done").id(last.map_or(1, |l| l.saturating_add(1)).to_string()).data(data);
            Sse::new(stream::iter([Ok::<_, Infallible>(done)])).keep_alive(keep_alive).into_response()
        }
        EventFeed::Live { backlog, rx, live } => {
            Sse::new(live_stream(backlog, rx, live, last.unwrap_or(0))).keep_alive(keep_alive).into_response()
        }
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
