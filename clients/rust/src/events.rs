//! A job's server-sent events, resumed with `Last-Event-ID` when the connection drops.

use std::time::Duration;

use futures_util::Stream;
use serde_json::Value;

use crate::{error, Client, Error};

/// Reconnections in a row without an event before [`Events`] gives up.
const MAX_RECONNECTS: u32 = 10;
/// The wait before reconnecting when the server named none (`retry:`).
const DEFAULT_RETRY: Duration = Duration::from_millis(500);

/// One event: `progress`, `status` or `done`, its id, and its data (JSON text).
#[derive(Clone, Debug, PartialEq)]
pub struct Event {
    pub event: String,
    pub id: Option<String>,
    pub data: String,
}

impl Event {
    /// The data as JSON.
    pub fn json(&self) -> Result<Value, Error> {
        Ok(serde_json::from_str(&self.data)?)
    }
}

/// The events of one job, to its `done`: [`Events::next`], or [`Events::into_stream`].
pub struct Events {
    client: Client,
    path: String,
    last_id: Option<String>,
    body: Option<reqwest::Response>,
    buffer: String,
    retry: Duration,
    failures: u32,
    ended: bool,
}

impl Events {
    pub(crate) fn new(client: Client, id: &str, last_id: Option<String>) -> Self {
        Self {
            client,
            path: format!("/v1/jobs/{id}/events"),
            last_id,
            body: None,
            buffer: String::new(),
            retry: DEFAULT_RETRY,
            failures: 0,
            ended: false,
        }
    }

    /// The id of the last event read (what a resumption sends as `Last-Event-ID`).
    pub fn last_event_id(&self) -> Option<&str> {
        self.last_id.as_deref()
    }

    /// The next event; `None` after `done`. A dropped connection is opened again with
    /// `Last-Event-ID`, so no event is lost or repeated; an error answer ends the stream.
    pub async fn next(&mut self) -> Option<Result<Event, Error>> {
        loop {
            if self.ended {
                return None;
            }
            if let Some(event) = self.take_event() {
                self.failures = 0;
                if event.id.is_some() {
                    self.last_id.clone_from(&event.id);
                }
                self.ended = event.event == "done";
                return Some(Ok(event));
            }
            let Some(body) = self.body.as_mut() else {
                let mut r = self.client.request(reqwest::Method::GET, &self.path).header("accept", "text/event-stream");
                if let Some(id) = &self.last_id {
                    r = r.header("last-event-id", id);
                }
                match r.send().await.map_err(Error::from) {
                    Ok(res) => match error::checked(res).await {
                        Ok(res) => self.body = Some(res),
                        Err(e) => {
                            self.ended = true;
                            return Some(Err(e));
                        }
                    },
                    Err(e) => {
                        if let Some(e) = self.failed(e).await {
                            return Some(Err(e));
                        }
                    }
                }
                continue;
            };
            match body.chunk().await {
                Ok(Some(bytes)) => self.buffer.push_str(&String::from_utf8_lossy(&bytes)),
                Ok(None) => {
                    if let Some(e) = self.failed(Error::Protocol("the event stream ended before `done`".into())).await {
                        return Some(Err(e));
                    }
                }
                Err(e) => {
                    if let Some(e) = self.failed(e.into()).await {
                        return Some(Err(e));
                    }
                }
            }
        }
    }

    /// The connection is gone: wait and open it again, or give up after [`MAX_RECONNECTS`].
    async fn failed(&mut self, e: Error) -> Option<Error> {
        self.body = None;
        // A part of an event the connection cut is sent again after the last whole one.
        self.buffer.clear();
        self.failures += 1;
        if self.failures > MAX_RECONNECTS {
            self.ended = true;
            return Some(e);
        }
        tokio::time::sleep(self.retry).await;
        None
    }

    /// The first whole event in the buffer (comments and keep-alives skipped).
    fn take_event(&mut self) -> Option<Event> {
        loop {
            let normal = self.buffer.replace("\r\n", "\n");
            if normal.len() != self.buffer.len() {
                self.buffer = normal;
            }
            let end = self.buffer.find("\n\n")?;
            let block: String = self.buffer.drain(..end + 2).collect();
            let (mut event, mut id, mut data) = (String::from("message"), None, Vec::new());
            for line in block.lines() {
                let (field, value) = line.split_once(':').unwrap_or((line, ""));
                let value = value.strip_prefix(' ').unwrap_or(value);
                match field {
                    "event" => event = value.to_string(),
                    "id" => id = Some(value.to_string()),
                    "data" => data.push(value),
                    "retry" => {
                        if let Ok(ms) = value.parse() {
                            self.retry = Duration::from_millis(ms);
                        }
                    }
                    _ => {}
                }
            }
            if !data.is_empty() {
                return Some(Event { event, id, data: data.join("\n") });
            }
        }
    }

    /// As a `futures` stream.
    pub fn into_stream(self) -> impl Stream<Item = Result<Event, Error>> {
        futures_util::stream::unfold(self, |mut events| async move { events.next().await.map(|e| (e, events)) })
    }
}
