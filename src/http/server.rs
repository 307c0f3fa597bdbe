//! The accept loop, in place of `axum::serve`, which has no timeouts and no connection limit: a
//! client could hold a connection (and its descriptor) for ever by sending headers a byte a
//! second, never sending a promised body, never reading a reply, or just staying idle, and a
//! thousand such clients used every descriptor of the process, so nobody else got in.
//!
//! Here every connection is tracked. Headers must arrive within `header_timeout` (hyper's own
//! timer); a connection with no request in flight is closed after `idle_timeout`; a reply the
//! client stops reading for `write_timeout` ends its connection; bodies have `body_timeout`
//! (see [`body_deadline`]). At most `max_connections` are open: when a new one comes at the limit,
//! the connection that has been waiting longest without a request in flight (a slow-loris one,
//! or an idle keep-alive) is closed to make room, and when every connection is busy with a
//! request the newcomer gets a `503` and is closed. So a flood of unfinished requests can delay
//! a real one by a connection's set-up, not a timeout.

use std::collections::HashMap;
use std::convert::Infallible;
use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use axum::body::Body;
use axum::extract::Request;
use axum::http::StatusCode;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::Router;
use bytes::Bytes;
use hyper_util::rt::{TokioIo, TokioTimer};
use parking_lot::Mutex;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{watch, Notify};
use tower::Service;

use super::Problem;

/// Limits on connections (flags of `serve`; see `config.rs`).
#[derive(Clone, Debug)]
pub struct ConnectionLimits {
    /// Most connections open at once.
    pub max_connections: usize,
    /// Time a client has to send a request's headers, from the moment the server waits for them.
    pub header_timeout: Duration,
    /// Time a request's body may take to arrive, whole.
    pub body_timeout: Duration,
    /// Time a connection may stay open with no request in flight.
    pub idle_timeout: Duration,
    /// Time a reply may wait for the client to read any of it.
    pub write_timeout: Duration,
}

impl Default for ConnectionLimits {
    fn default() -> Self {
        Self {
            max_connections: default_max_connections(),
            header_timeout: Duration::from_secs(10),
            body_timeout: Duration::from_secs(60),
            idle_timeout: Duration::from_secs(60),
            write_timeout: Duration::from_secs(30),
        }
    }
}

/// Descriptors kept for what is not a client connection (the store, the worker's pipes, logs,
/// blocking threads' files).
const RESERVED_DESCRIPTORS: u64 = 128;

/// Three quarters of what the process may open (raised to its hard limit first, see
/// [`raise_descriptor_limit`]), less what the rest of the process needs, and at most 16 384.
pub fn default_max_connections() -> usize {
    let soft = descriptor_limit().unwrap_or(1024);
    (soft.saturating_sub(RESERVED_DESCRIPTORS) * 3 / 4).clamp(16, 16_384) as usize
}

fn descriptor_limit() -> Option<u64> {
    let mut limit = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: getrlimit writes the struct it is given and nothing else.
    (unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut limit) } == 0).then_some(limit.rlim_cur)
}

/// Raise the soft limit of open descriptors to the hard one (what many servers do at start): a
/// soft limit of 1 024 is a default of shells, not a decision about this process.
pub fn raise_descriptor_limit() {
    let mut limit = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: as above; setrlimit reads the struct it is given.
    unsafe {
        if libc::getrlimit(libc::RLIMIT_NOFILE, &mut limit) == 0 && limit.rlim_cur < limit.rlim_max {
            limit.rlim_cur = limit.rlim_max;
            libc::setrlimit(libc::RLIMIT_NOFILE, &limit);
        }
    }
}

/// One open connection as the loop tracks it.
struct Tracked {
    /// Requests whose reply has not been sent whole.
    in_flight: AtomicUsize,
    /// When it last had a request in flight (or opened), in ms since the server started.
    quiet_since_ms: AtomicU64,
    /// Told to close (evicted, or idle too long).
    close: Notify,
}

struct Connections {
    open: Mutex<HashMap<u64, Arc<Tracked>>>,
    started: Instant,
    next_id: AtomicU64,
}

impl Connections {
    fn now_ms(&self) -> u64 {
        self.started.elapsed().as_millis() as u64
    }

    /// Take out the connection waiting longest with no request in flight, if any, and tell it
    /// to close. It leaves the count at once (its task ends a moment later), so the next
    /// newcomer picks another.
    fn evict_quietest(&self) -> bool {
        let mut open = self.open.lock();
        let victim = open
            .iter()
            .filter(|(_, c)| c.in_flight.load(Ordering::Acquire) == 0)
            .min_by_key(|(_, c)| c.quiet_since_ms.load(Ordering::Relaxed))
            .map(|(id, _)| *id);
        match victim.and_then(|id| open.remove(&id)) {
            Some(c) => {
                c.close.notify_one();
                true
            }
            None => false,
        }
    }
}

/// Serve `app` on `listener` until `shutdown` resolves, then let open connections finish their
/// requests (the caller bounds how long it waits for this future).
pub async fn serve(
    listener: TcpListener,
    app: Router,
    limits: ConnectionLimits,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> io::Result<()> {
    let conns =
        Arc::new(Connections { open: Mutex::new(HashMap::new()), started: Instant::now(), next_id: AtomicU64::new(0) });
    let (stop_tx, stop_rx) = watch::channel(false);
    tokio::spawn(async move {
        shutdown.await;
        let _ = stop_tx.send(true);
    });
    let sweeper = tokio::spawn(sweep(conns.clone(), limits.idle_timeout));
    let mut stopping = stop_rx.clone();
    loop {
        let accepted = tokio::select! {
            a = listener.accept() => a,
            _ = stopping.wait_for(|s| *s) => break,
        };
        let stream = match accepted {
            Ok((stream, _)) => stream,
            Err(e) => {
                // Out of descriptors (or a connection reset before it was taken): the limit
                // should keep the first from happening; wait a moment rather than spin.
                tracing::warn!(error = %e, "accept failed");
                tokio::time::sleep(Duration::from_millis(20)).await;
                continue;
            }
        };
        let _ = stream.set_nodelay(true);
        if conns.open.lock().len() >= limits.max_connections && !conns.evict_quietest() {
            tokio::spawn(refuse(stream));
            continue;
        }
        let id = conns.next_id.fetch_add(1, Ordering::Relaxed);
        let tracked = Arc::new(Tracked {
            in_flight: AtomicUsize::new(0),
            quiet_since_ms: AtomicU64::new(conns.now_ms()),
            close: Notify::new(),
        });
        conns.open.lock().insert(id, tracked.clone());
        let (conns, app, limits, stop) = (conns.clone(), app.clone(), limits.clone(), stop_rx.clone());
        tokio::spawn(async move {
            connection(stream, app, &limits, tracked, conns.clone(), stop).await;
            conns.open.lock().remove(&id);
        });
    }
    // No new connections; the open ones finish what they are doing (graceful shutdown each).
    while !conns.open.lock().is_empty() {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    sweeper.abort();
    Ok(())
}

/// Close connections that have had no request in flight for `idle`.
async fn sweep(conns: Arc<Connections>, idle: Duration) {
    let mut tick = tokio::time::interval(Duration::from_millis(250).min(idle));
    loop {
        tick.tick().await;
        let now = conns.now_ms();
        let idle_ms = idle.as_millis() as u64;
        for c in conns.open.lock().values() {
            let quiet = c.in_flight.load(Ordering::Acquire) == 0;
            if quiet && now.saturating_sub(c.quiet_since_ms.load(Ordering::Relaxed)) >= idle_ms {
                c.close.notify_one();
            }
        }
    }
}

/// Every connection is busy with a request: say so and close.
async fn refuse(mut stream: TcpStream) {
    let body = serde_json::to_vec(&Problem {
        retry_after_s: Some(1),
        ..Problem::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "too-many-connections",
            "Too many connections",
            "every connection this server may hold is busy; try again shortly",
        )
    })
    .unwrap_or_default();
    let head = format!(
        "HTTP/1.1 503 Service Unavailable\r\ncontent-type: application/problem+json\r\nretry-after: 1\r\n\
         connection: close\r\ncontent-length: {}\r\n\r\n",
        body.len()
    );
    let write = async {
        stream.write_all(head.as_bytes()).await?;
        stream.write_all(&body).await?;
        stream.shutdown().await
    };
    let _ = tokio::time::timeout(Duration::from_secs(1), write).await;
}

async fn connection(
    stream: TcpStream,
    app: Router,
    limits: &ConnectionLimits,
    tracked: Arc<Tracked>,
    conns: Arc<Connections>,
    mut stop: watch::Receiver<bool>,
) {
    let io = TokioIo::new(WriteDeadline::new(stream, limits.write_timeout));
    let service = {
        let tracked = tracked.clone();
        hyper::service::service_fn(move |req: hyper::Request<hyper::body::Incoming>| {
            let guard = InFlight::begin(tracked.clone(), conns.clone());
            let mut app = app.clone();
            async move {
                let response = app.call(req.map(Body::new)).await.unwrap_or_else(|e: Infallible| match e {});
                // The request counts as in flight until its reply's body has been sent (or dropped).
                Ok::<_, Infallible>(response.map(|body| Body::new(Guarded { body, _guard: guard })))
            }
        })
    };
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder.timer(TokioTimer::new()).header_read_timeout(limits.header_timeout).keep_alive(true);
    let conn = builder.serve_connection(io, service);
    tokio::pin!(conn);
    tokio::select! {
        _ = conn.as_mut() => return,
        // Dropping the connection closes its socket; it has no request in flight.
        _ = tracked.close.notified() => return,
        _ = stop.wait_for(|s| *s) => {}
    }
    conn.as_mut().graceful_shutdown();
    let _ = conn.await;
}

/// Counts a request in flight on its connection until dropped.
struct InFlight {
    tracked: Arc<Tracked>,
    conns: Arc<Connections>,
}

impl InFlight {
    fn begin(tracked: Arc<Tracked>, conns: Arc<Connections>) -> Self {
        tracked.in_flight.fetch_add(1, Ordering::AcqRel);
        Self { tracked, conns }
    }
}

impl Drop for InFlight {
    fn drop(&mut self) {
        self.tracked.quiet_since_ms.store(self.conns.now_ms(), Ordering::Relaxed);
        self.tracked.in_flight.fetch_sub(1, Ordering::AcqRel);
    }
}

/// A reply's body that keeps its request counted as in flight.
struct Guarded {
    body: Body,
    _guard: InFlight,
}

impl http_body::Body for Guarded {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Bytes>, axum::Error>>> {
        Pin::new(&mut self.body).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.body.size_hint()
    }
}

/// A socket whose writes fail once they have waited `timeout` for the client to read: a client
/// that stops reading a reply (or a stream) holds no more than the socket's buffers, and only
/// for that long.
struct WriteDeadline {
    stream: TcpStream,
    timeout: Duration,
    stalled: Option<Pin<Box<tokio::time::Sleep>>>,
}

impl WriteDeadline {
    fn new(stream: TcpStream, timeout: Duration) -> Self {
        Self { stream, timeout, stalled: None }
    }

    /// `Pending` from the socket starts (or continues) the clock; anything else stops it.
    fn watch<T>(&mut self, cx: &mut Context<'_>, polled: Poll<io::Result<T>>) -> Poll<io::Result<T>> {
        if polled.is_ready() {
            self.stalled = None;
            return polled;
        }
        let timeout = self.timeout;
        let sleep = self.stalled.get_or_insert_with(|| Box::pin(tokio::time::sleep(timeout)));
        match sleep.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(io::Error::new(io::ErrorKind::TimedOut, "the client stopped reading"))),
            Poll::Pending => Poll::Pending,
        }
    }
}

impl AsyncRead for WriteDeadline {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for WriteDeadline {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        let polled = Pin::new(&mut self.stream).poll_write(cx, buf);
        self.watch(cx, polled)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let polled = Pin::new(&mut self.stream).poll_write_vectored(cx, bufs);
        self.watch(cx, polled)
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let polled = Pin::new(&mut self.stream).poll_flush(cx);
        self.watch(cx, polled)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let polled = Pin::new(&mut self.stream).poll_shutdown(cx);
        self.watch(cx, polled)
    }
}

/// Middleware: a request body must arrive whole within `limit` (a client that promises a body
/// and never sends it, or drips it, holds a connection and a handler for no longer). The
/// handler that reads it answers `408` (see `body.rs`).
pub async fn body_deadline(limit: Duration, req: Request, next: Next) -> Response {
    let (parts, body) = req.into_parts();
    let deadline = tokio::time::Instant::now() + limit;
    let body = Body::new(Deadlined { body, sleep: Box::pin(tokio::time::sleep_until(deadline)) });
    next.run(Request::from_parts(parts, body)).await.into_response()
}

/// The error a body past its deadline ends with; `body.rs` recognises it.
#[derive(Debug, thiserror::Error)]
#[error("the request body did not arrive within the server's body timeout")]
pub struct BodyTimedOut;

struct Deadlined {
    body: Body,
    sleep: Pin<Box<tokio::time::Sleep>>,
}

impl http_body::Body for Deadlined {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Bytes>, axum::Error>>> {
        if let Poll::Ready(frame) = Pin::new(&mut self.body).poll_frame(cx) {
            return Poll::Ready(frame);
        }
        match self.sleep.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Some(Err(axum::Error::new(BodyTimedOut)))),
            Poll::Pending => Poll::Pending,
        }
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.body.size_hint()
    }
}
