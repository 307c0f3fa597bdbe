//! A hostile client at the HTTP edge (issue 28): replies that echo a huge request, connections
//! held open by never finishing (or never reading) a request, cross-site submissions, and the
//! small leaks (text/plain errors, open metrics, frameable docs). Memory is measured as the API
//! process's resident size; time as a fresh client's wait for `/healthz`.

mod common;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use common::bodies::small_bulldoze;
use common::processes::{reset_peak_rss, status_bytes};
use common::server::{Options, TestServer};
use serde_json::Value;

fn addr(server: &TestServer) -> String {
    server.base.trim_start_matches("http://").to_string()
}

/// Sends `head` and `body` on a fresh connection; the connection is returned unread.
fn send_raw(server: &TestServer, head: &str, body: &[u8]) -> TcpStream {
    let mut s = TcpStream::connect(addr(server)).expect("connect");
    s.write_all(head.as_bytes()).expect("head");
    s.write_all(body).expect("body");
    s
}

/// Reads a whole reply (the server closes after it or the test's own timeout ends it).
fn read_reply(mut s: TcpStream) -> (u16, String) {
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut out = Vec::new();
    let mut buf = [0u8; 65536];
    loop {
        match s.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => out.extend_from_slice(&buf[..n]),
        }
        if let Some(end) = out.windows(4).position(|w| w == b"\r\n\r\n") {
            let head = String::from_utf8_lossy(&out[..end]).to_string();
            let length = head
                .lines()
                .find_map(|l| l.to_ascii_lowercase().strip_prefix("content-length:").map(|v| v.trim().to_string()))
                .and_then(|v| v.parse::<usize>().ok());
            if length.is_some_and(|n| out.len() >= end + 4 + n) {
                break;
            }
        }
    }
    let text = String::from_utf8_lossy(&out).to_string();
    let status = text.split_whitespace().nth(1).and_then(|s| s.parse().ok()).unwrap_or(0);
    (status, text)
}

/// Seconds a fresh client waits for `/healthz`.
async fn healthz_wait(server: &TestServer) -> f64 {
    let client = reqwest::Client::builder().timeout(Duration::from_secs(30)).build().unwrap();
    let start = Instant::now();
    let res = client.get(server.url("/healthz")).send().await;
    let took = start.elapsed().as_secs_f64();
    assert!(res.is_ok_and(|r| r.status() == 200), "healthz failed after {took:.3} s");
    took
}

/// Item 1: a 30 MB field name is quoted back clipped, and twelve clients that never read their
/// 422 hold nothing of note.
#[tokio::test]
async fn a_huge_unknown_field_gets_a_small_problem_and_unread_replies_cost_nothing() {
    let server = TestServer::start_with(Options { max_body_bytes: 64 << 20, ..Options::default() }).await;
    let name = "x".repeat(30 << 20);
    let body = format!(r#"{{"terrain": {{"fractal": {{}}}}, "operations": [], "{name}": 1}}"#);
    let res = server
        .client
        .post(server.url("/v1/jobs/bulldoze"))
        .header("content-type", "application/json")
        .body(body.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 422);
    assert_eq!(res.headers()["content-type"], "application/problem+json");
    let text = res.text().await.unwrap();
    assert!(text.len() < 4096, "a {} byte reply to a {} byte body", text.len(), body.len());
    let problem: Value = serde_json::from_str(&text).unwrap();
    let field = problem["errors"][0]["field"].as_str().unwrap();
    assert!(field.starts_with("xxxx") && field.contains("more characters"), "{field}");

    let pid = server.pid();
    let before = reset_peak_rss(pid);
    let head = format!(
        "POST /v1/jobs/bulldoze HTTP/1.1\r\nhost: x\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\r\n",
        body.len()
    );
    // One after the other, each answered before the next is sent: what an unread answer holds
    // adds up, while a request's own parsing is freed for the next to reuse.
    let mut unread = Vec::new();
    for _ in 0..12 {
        let s = send_raw(&server, &head, body.as_bytes());
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        // Wait for the answer to arrive without reading it (peek leaves it in the socket).
        assert!(s.peek(&mut [0u8; 1]).is_ok_and(|n| n == 1), "no answer");
        unread.push(s);
    }
    assert!(healthz_wait(&server).await < 2.0);
    let after = status_bytes(pid, "VmRSS");
    let peak = status_bytes(pid, "VmHWM");
    eprintln!("12 unread 422s of {} MB bodies: RSS {before} -> {after} (peak {peak})", body.len() >> 20);
    // Each body is held only while it is parsed (a few copies of the 30 MB name, reused by the
    // next request); what stays is the answers, a few KiB each. Before: 240 MB an answer.
    assert!(after.saturating_sub(before) < 300 << 20, "the API grew by {} bytes", after - before);
    drop(unread);
}

/// Item 4: headers a byte at a time, a body promised and never sent, and an idle connection
/// are each closed at their timeout.
#[tokio::test(flavor = "multi_thread")]
async fn unfinished_requests_and_idle_connections_are_closed_at_their_timeouts() {
    let server = TestServer::start_with(Options {
        extra: ["--header-timeout-secs", "2", "--body-timeout-secs", "2", "--idle-timeout-secs", "3"]
            .map(String::from)
            .to_vec(),
        ..Options::default()
    })
    .await;
    let closed_within = |mut s: TcpStream, seconds: f64, drip: bool| {
        s.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
        let start = Instant::now();
        let mut buf = [0u8; 4096];
        let mut got = Vec::new();
        while start.elapsed().as_secs_f64() < seconds + 3.0 {
            if drip {
                // One more header byte every 200 ms: never a whole header.
                if s.write_all(b"x").is_err() {
                    return (start.elapsed().as_secs_f64(), got);
                }
            }
            match s.read(&mut buf) {
                Ok(0) => return (start.elapsed().as_secs_f64(), got),
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock || e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(_) => return (start.elapsed().as_secs_f64(), got),
            }
        }
        panic!("still open after {:.1} s", start.elapsed().as_secs_f64());
    };
    let slow_headers = send_raw(&server, "GET /healthz HTTP/1.1\r\nx-slow: ", b"");
    let (t, _) = tokio::task::block_in_place(|| closed_within(slow_headers, 2.0, true));
    eprintln!("slow headers closed after {t:.1} s");
    assert!(t < 4.0, "slow headers: {t:.1} s");

    let no_body = send_raw(
        &server,
        "POST /v1/jobs/bulldoze HTTP/1.1\r\nhost: x\r\ncontent-type: application/json\r\ncontent-length: 1000\r\n\r\n",
        b"{",
    );
    let (t, reply) = tokio::task::block_in_place(|| closed_within(no_body, 2.0, false));
    let reply = String::from_utf8_lossy(&reply).to_string();
    eprintln!("a body never sent: closed after {t:.1} s: {}", reply.lines().next().unwrap_or(""));
    assert!(reply.starts_with("HTTP/1.1 408"), "{reply}");
    assert!(reply.contains("application/problem+json"), "{reply}");
    assert!(t < 4.0, "no body: {t:.1} s");

    let idle = TcpStream::connect(addr(&server)).unwrap();
    let (t, _) = tokio::task::block_in_place(|| closed_within(idle, 3.0, false));
    eprintln!("an idle connection closed after {t:.1} s");
    assert!(t < 6.0, "idle: {t:.1} s");
}

/// Item 4: 1 100 connections that never finish their headers, under a 1 024-descriptor limit,
/// leave `/healthz` answering within 100 ms, and a submission going through.
#[tokio::test(flavor = "multi_thread")]
async fn a_slow_loris_of_1100_connections_leaves_healthz_answering() {
    raise_own_descriptor_limit(4096);
    let server = TestServer::start_with(Options { max_descriptors: Some(1024), ..Options::default() }).await;
    let mut loris = Vec::new();
    for i in 0..1100 {
        match TcpStream::connect(addr(&server)) {
            Ok(mut s) => {
                let _ = s.write_all(format!("GET /healthz HTTP/1.1\r\nx-slow-{i}: ").as_bytes());
                loris.push(s);
            }
            Err(e) => panic!("connection {i}: {e}"),
        }
    }
    tokio::time::sleep(Duration::from_millis(500)).await;
    let mut waits = Vec::new();
    for _ in 0..10 {
        // Keep the loris busy: a byte on every connection still open.
        for s in &mut loris {
            let _ = s.write_all(b"y");
        }
        waits.push(healthz_wait(&server).await);
    }
    waits.sort_by(f64::total_cmp);
    eprintln!("healthz under 1100 loris connections: median {:.1} ms, max {:.1} ms", waits[5] * 1e3, waits[9] * 1e3);
    assert!(waits[5] < 0.1, "median healthz {:.3} s", waits[5]);
    let (status, job) = server.post("/v1/jobs/bulldoze", &small_bulldoze()).await;
    assert_eq!(status, 202, "{job}");
}

fn raise_own_descriptor_limit(want: u64) {
    let mut limit = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: getrlimit / setrlimit read and write only the struct given.
    unsafe {
        libc::getrlimit(libc::RLIMIT_NOFILE, &mut limit);
        limit.rlim_cur = want.min(limit.rlim_max);
        libc::setrlimit(libc::RLIMIT_NOFILE, &limit);
    }
}

/// Item 7: with no keys and no CORS flag, another site's page can neither submit (a
/// `text/plain` body needs no preflight) nor change anything, and gets no CORS permission.
#[tokio::test]
async fn cross_site_submissions_are_refused() {
    let server = TestServer::start().await;
    let body = serde_json::to_string(&small_bulldoze()).unwrap();
    let post = |origin: Option<&'static str>, content_type: &'static str| {
        let mut req =
            server.client.post(server.url("/v1/jobs/bulldoze")).header("content-type", content_type).body(body.clone());
        if let Some(o) = origin {
            req = req.header("origin", o);
        }
        req.send()
    };
    let evil = post(Some("https://evil.example"), "text/plain").await.unwrap();
    assert_eq!(evil.status(), 403);
    assert!(evil.headers().get("access-control-allow-origin").is_none());
    assert_eq!(evil.headers()["content-type"], "application/problem+json");
    // Without an Origin (curl, a backend), a non-JSON body is still not read.
    assert_eq!(post(None, "text/plain").await.unwrap().status(), 415);
    assert_eq!(post(None, "application/x-www-form-urlencoded").await.unwrap().status(), 415);
    // Even JSON from another origin.
    assert_eq!(post(Some("https://evil.example"), "application/json").await.unwrap().status(), 403);
    // The server's own page (same origin) and clients without an Origin submit as before.
    let own = server.base.clone();
    let res = server
        .client
        .post(server.url("/v1/jobs/bulldoze"))
        .header("origin", own)
        .json(&small_bulldoze())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 202);
    assert_eq!(post(None, "application/json; charset=utf-8").await.unwrap().status(), 202);

    // Nothing the evil page sent made a job; cancel and delete from it are refused too.
    let (_, page) = server.get_json("/v1/jobs").await;
    let id = page["items"][0]["id"].as_str().unwrap().to_string();
    assert_eq!(page["items"].as_array().unwrap().len(), 2);
    for req in [
        server.client.post(server.url(&format!("/v1/jobs/{id}/cancel"))),
        server.client.delete(server.url(&format!("/v1/jobs/{id}"))),
    ] {
        let res = req.header("origin", "https://evil.example").send().await.unwrap();
        assert_eq!(res.status(), 403);
    }
    assert_eq!(server.get_json(&format!("/v1/jobs/{id}")).await.0, 200);
}

/// Item 9: the docs page may not be framed; a path that is not UTF-8 gets problem+json.
#[tokio::test]
async fn docs_are_not_frameable_and_bad_paths_get_problems() {
    let server = TestServer::start().await;
    let docs = server.client.get(server.url("/docs/")).send().await.unwrap();
    assert_eq!(docs.status(), 200);
    let csp = docs.headers()["content-security-policy"].to_str().unwrap().to_string();
    assert!(csp.contains("frame-ancestors 'none'"), "{csp}");
    assert_eq!(docs.headers()["x-frame-options"], "DENY");

    let (status, reply) = read_reply(send_raw(&server, "GET /v1/jobs/%FF%FE HTTP/1.1\r\nhost: x\r\n\r\n", b""));
    assert_eq!(status, 400, "{reply}");
    assert!(reply.to_ascii_lowercase().contains("content-type: application/problem+json"), "{reply}");
    let (status, reply) = read_reply(send_raw(&server, "GET /v1/jobs?limit=%FF HTTP/1.1\r\nhost: x\r\n\r\n", b""));
    assert!(status == 400 || status == 422, "{reply}");
    assert!(reply.to_ascii_lowercase().contains("content-type: application/problem+json"), "{reply}");
}
