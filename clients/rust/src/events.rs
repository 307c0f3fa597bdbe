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
    /// Bytes read and not yet parsed: kept as bytes so a character split between two reads
    /// is decoded whole.
    buffer: Vec<u8>,
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
            buffer: Vec::new(),
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
                        // Busy, or a proxy between: wait (as long as Retry-After asks) and resume.
                        Err(Error::Problem { problem, retry_after_s }) if passing(problem.status) => {
                            if let Some(s) = retry_after_s {
                                self.retry = Duration::from_secs(s.min(60));
                            }
                            if let Some(e) = self.failed(Error::Problem { problem, retry_after_s }).await {
                                return Some(Err(e));
                            }
                        }
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
                Ok(Some(bytes)) => self.buffer.extend_from_slice(&bytes),
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

    /// The first whole event in the buffer (comments and keep-alives skipped). Lines end with
    /// LF, CRLF or CR, as the SSE format allows.
    fn take_event(&mut self) -> Option<Event> {
        loop {
            let (end, after) = block_end(&self.buffer)?;
            let block = String::from_utf8_lossy(&self.buffer[..end]).into_owned();
            self.buffer.drain(..after);
            let (mut event, mut id, mut data) = (String::from("message"), None, Vec::new());
            for line in block.split(['\n', '\r']).filter(|l| !l.is_empty()) {
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

    #[cfg(test)]
    fn feed(&mut self, bytes: &[u8]) {
        self.buffer.extend_from_slice(bytes);
    }

    /// As a `futures` stream.
    pub fn into_stream(self) -> impl Stream<Item = Result<Event, Error>> {
        futures_util::stream::unfold(self, |mut events| async move { events.next().await.map(|e| (e, events)) })
    }
}

/// Statuses a reconnection waits out rather than ends on: rate limits and a busy or restarting
/// server or proxy.
fn passing(status: u16) -> bool {
    matches!(status, 429 | 502 | 503 | 504)
}

/// Where the first event of `buffer` ends (its text's end, and where the next begins): at the
/// first blank line, whichever of LF, CRLF or CR ends its lines. `None` while it is incomplete
/// (a CR last may be the first half of a CRLF).
fn block_end(buffer: &[u8]) -> Option<(usize, usize)> {
    let mut k = 0;
    let mut line_start = 0;
    while k < buffer.len() {
        let eol = match buffer[k] {
            b'\n' => 1,
            b'\r' if k + 1 < buffer.len() => 1 + usize::from(buffer[k + 1] == b'\n'),
            b'\r' => return None,
            _ => {
                k += 1;
                continue;
            }
        };
        if k == line_start && k > 0 {
            return Some((k, k + eol));
        }
        k += eol;
        line_start = k;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn events() -> Events {
        Events::new(Client::new("http://127.0.0.1:9").unwrap(), "j", None)
    }

    /// Every event the bytes hold, fed in pieces of `piece` bytes.
    fn parse(bytes: &[u8], piece: usize) -> Vec<Event> {
        let mut e = events();
        let mut out = Vec::new();
        for chunk in bytes.chunks(piece) {
            e.feed(chunk);
            while let Some(ev) = e.take_event() {
                out.push(ev);
            }
        }
        out
    }

    #[test]
    fn events_split_anywhere_parse_the_same_with_every_line_ending() {
        let text = ": keep-alive\n\nid: 7\nevent: progress\ndata: {\"message\": \"129\u{d7}129 m\u{b3}\"}\n\n\
                    event: done\nid: 8\ndata: line one\ndata: line two\n\n: k\n";
        // (The comment last: a CR that ends the bytes may be half a CRLF, so an event ended by
        // CRs is known whole at the next byte.)
        let expected = vec![
            Event {
                event: "progress".into(),
                id: Some("7".into()),
                data: "{\"message\": \"129\u{d7}129 m\u{b3}\"}".into(),
            },
            Event { event: "done".into(), id: Some("8".into()), data: "line one\nline two".into() },
        ];
        for ending in ["\n", "\r\n", "\r"] {
            let bytes = text.replace('\n', ending).into_bytes();
            for piece in 1..=bytes.len() {
                assert_eq!(parse(&bytes, piece), expected, "{ending:?} in pieces of {piece}");
            }
        }
    }

    #[test]
    fn an_incomplete_event_waits_for_its_blank_line() {
        assert!(parse(b"id: 1\ndata: x\n", 4).is_empty());
        assert!(parse(b"data: x\r", 1).is_empty(), "a CR last may be half a CRLF");
        assert_eq!(parse(b"data: x\n\n", 3)[0].event, "message");
    }
}
