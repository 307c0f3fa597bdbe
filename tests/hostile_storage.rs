//! What a hostile client can make the service keep and re-read (issue 28, items 2 and 3): a
//! request that grows when stored, list pages and event streams over large jobs, and streams
//! that poll a large queued job. Memory is the API process's resident size, CPU its own.

mod common;

use std::io::Write;
use std::net::TcpStream;
use std::time::{Duration, Instant};

use common::processes::{reset_peak_rss, status_bytes};
use common::server::{Options, TestServer};
use serde_json::{json, Value};

/// A bulldoze body of about `mb` MB: one pass along a path of decimal points.
fn big_path_body(mb: usize, salt: u64) -> Value {
    let points = mb * 1_000_000 / 28;
    let path: Vec<Value> = (0..points as u64)
        .map(|i| {
            let j = i.wrapping_mul(2_654_435_761).wrapping_add(salt);
            json!({"x": (j % 12_700) as f64 / 100.0 + 0.05, "z": ((j / 12_700) % 12_700) as f64 / 100.0 + 0.05})
        })
        .collect();
    json!({"terrain": {"fractal": {"size": 129}}, "label": format!("big {salt}"),
        "operations": [{"pass": {"path": path, "blade": {"width_m": 2.5}, "operator": "replace"}}]})
}

/// `n` connections that ask for a job's event stream and never read it.
fn unread_streams(server: &TestServer, id: &str, n: usize) -> Vec<TcpStream> {
    let addr = server.base.trim_start_matches("http://").to_string();
    (0..n)
        .map(|_| {
            let mut s = TcpStream::connect(&addr).unwrap();
            s.write_all(format!("GET /v1/jobs/{id}/events HTTP/1.1\r\nhost: x\r\n\r\n").as_bytes()).unwrap();
            s
        })
        .collect()
}

fn options() -> Options {
    Options {
        max_body_bytes: 64 << 20,
        extra: vec!["--max-operations".into(), "10000000".into()],
        ..Options::default()
    }
}

/// The stored request is no larger than 1.2 × the body it came from; a body that would grow
/// past the stated bound (defaults filled into many minimal elements) is refused with 413.
#[tokio::test]
async fn stored_requests_stay_within_their_bound() {
    let server = TestServer::start_with(options()).await;
    let body = big_path_body(4, 1);
    let sent = serde_json::to_vec(&body).unwrap().len();
    let job = server.submit("bulldoze", &body).await;
    // The 202 carries the job as a summary: the request is not echoed back.
    assert_eq!(job["request_omitted"], true, "{}", job["request_omitted"]);
    let id = job["id"].as_str().unwrap();
    let res = server.client.get(server.url(&format!("/v1/jobs/{id}"))).send().await.unwrap();
    let got: Value = res.json().await.unwrap();
    let stored = serde_json::to_vec(&got["request"]).unwrap().len();
    eprintln!("sent {sent} bytes, stored {stored}");
    assert!(stored as f64 <= 1.2 * sent as f64, "stored {stored} for {sent}");
    let x = got["request"]["operations"][0]["pass"]["path"][0]["x"].to_string();
    assert!(x.len() <= 6, "a coordinate stored as {x}");

    // 20 000 two-point passes that leave their blades' defaults out: each gains its angle,
    // offset and profile when stored, past 1.5 × the body.
    let ops: Vec<Value> = (0..20_000)
        .map(|i| json!({"pass": {"path": [{"x": i % 100, "z": 1}, {"x": 2, "z": 2}], "blade": {"width_m": 1}}}))
        .collect();
    let (status, problem) =
        server.post("/v1/jobs/bulldoze", &json!({"terrain": {"fractal": {"size": 129}}, "operations": ops})).await;
    assert_eq!(status, 413, "{problem}");
    assert_eq!(problem["errors"][0]["field"], "");
    assert!(problem["detail"].as_str().unwrap().contains("stored"), "{problem}");
}

/// Four 8 MB jobs: a page of them costs the API no more than its page (the requests are left
/// out of list items over 64 KiB), where it used to parse every request whole.
#[tokio::test]
async fn a_list_page_costs_its_page_not_its_jobs() {
    let server = TestServer::start_with(options()).await;
    for salt in 0..4 {
        server.submit("bulldoze", &big_path_body(8, salt)).await;
    }
    let pid = server.pid();
    let before = reset_peak_rss(pid);
    let res = server.client.get(server.url("/v1/jobs?limit=4")).send().await.unwrap();
    assert_eq!(res.status(), 200);
    let text = res.text().await.unwrap();
    let peak = status_bytes(pid, "VmHWM");
    eprintln!("a page of four 8 MB jobs: {} bytes; API peak {} MB over {} MB", text.len(), peak >> 20, before >> 20);
    let page: Value = serde_json::from_str(&text).unwrap();
    let items = page["items"].as_array().unwrap();
    assert_eq!(items.len(), 4);
    for item in items {
        assert_eq!(item["request_omitted"], true, "{}", item["id"]);
        assert_eq!(item["request"], json!({}));
    }
    assert!(text.len() < 64 << 10, "a page of {} bytes", text.len());
    assert!(peak.saturating_sub(before) < 16 << 20, "the API peaked {} MB above", (peak - before) >> 20);
    // The job itself still has its whole request.
    let id = items[0]["id"].as_str().unwrap();
    let (_, job) = server.get_json(&format!("/v1/jobs/{id}")).await;
    assert!(job["request"]["operations"][0]["pass"]["path"].as_array().unwrap().len() > 100_000);
    assert!(job.get("request_omitted").is_none());
}

/// 200 clients that never read the event stream of an ended 8 MB job hold little, and the
/// server keeps answering promptly.
#[tokio::test(flavor = "multi_thread")]
async fn unread_event_streams_of_an_ended_large_job_cost_little() {
    let server = TestServer::start_with(options()).await;
    let mut body = big_path_body(8, 9);
    body["terrain"] = json!({"fractal": {"size": 33}});
    let job = server.submit("bulldoze", &body).await;
    let id = job["id"].as_str().unwrap().to_string();
    let done = server.wait_done(&id).await;
    assert!(matches!(done["status"].as_str(), Some("succeeded" | "failed")), "{done}");
    let pid = server.pid();
    let before = reset_peak_rss(pid);
    let streams = unread_streams(&server, &id, 200);
    tokio::time::sleep(Duration::from_secs(3)).await;
    let start = Instant::now();
    let (status, _) = server.get_json("/healthz").await;
    let healthz = start.elapsed().as_secs_f64();
    let (rss, peak) = (status_bytes(pid, "VmRSS"), status_bytes(pid, "VmHWM"));
    eprintln!(
        "200 unread streams: healthz {:.1} ms, RSS {} -> {} MB (peak {} MB)",
        healthz * 1e3,
        before >> 20,
        rss >> 20,
        peak >> 20
    );
    assert_eq!(status, 200);
    assert!(healthz < 0.5, "healthz took {healthz:.3} s");
    // Each stream reads the job's summary (its request left unread) and sends it: a few KiB.
    assert!(rss.saturating_sub(before) < 40 << 20, "RSS grew by {} MB", (rss - before) >> 20);
    drop(streams);
}

/// Streams following a queued job through the store (an API without workers, as replicas are)
/// poll its status, not its whole row: 100 of them on a 4 MB job cost the API little CPU.
#[tokio::test(flavor = "multi_thread")]
async fn streams_on_a_large_queued_job_poll_its_status_only() {
    let server = TestServer::start_with(Options {
        extra: ["--role", "api", "--max-operations", "10000000"].map(String::from).to_vec(),
        ..options()
    })
    .await;
    let job = server.submit("bulldoze", &big_path_body(4, 3)).await;
    let id = job["id"].as_str().unwrap().to_string();
    let streams = unread_streams(&server, &id, 100);
    tokio::time::sleep(Duration::from_secs(1)).await;
    let cpu = |pid: u32| -> f64 {
        let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
        let fields: Vec<&str> = stat.rsplit_once(')').unwrap().1.split_whitespace().collect();
        // utime and stime (fields 14 and 15), in clock ticks of 10 ms.
        (fields[11].parse::<f64>().unwrap() + fields[12].parse::<f64>().unwrap()) / 100.0
    };
    let (c0, t0) = (cpu(server.pid()), Instant::now());
    tokio::time::sleep(Duration::from_secs(3)).await;
    let share = (cpu(server.pid()) - c0) / t0.elapsed().as_secs_f64();
    eprintln!("100 streams on a queued 4 MB job: API at {:.0} % of a core", share * 100.0);
    // Before: each stream parsed the whole row every 100 ms (1 000 parses of 4 MB a second).
    assert!(share < 0.5, "the API used {:.0} % of a core", share * 100.0);
    drop(streams);
}

/// Large submissions arriving together are parsed and prepared a few at a time (bodies of
/// at most the largest allowed and 8 MiB more at once; the rest wait their turn), so four
/// 7 MB bodies at once cost the API well under four of them (two, at times three).
#[tokio::test(flavor = "multi_thread")]
async fn large_submissions_at_once_are_prepared_a_few_at_a_time() {
    let server = TestServer::start_with(Options { max_body_bytes: 8 << 20, ..options() }).await;
    let pid = server.pid();
    let bodies: Vec<Vec<u8>> = (0..5).map(|s| serde_json::to_vec(&big_path_body(7, 20 + s)).unwrap()).collect();
    let post = |body: Vec<u8>| {
        let request = server
            .client
            .post(server.url("/v1/jobs/bulldoze"))
            .header("content-type", "application/json")
            .body(body)
            .send();
        async move { request.await.unwrap().status().as_u16() }
    };
    let before = reset_peak_rss(pid);
    assert_eq!(post(bodies[0].clone()).await, 202);
    let one = status_bytes(pid, "VmHWM").saturating_sub(before);
    let before = reset_peak_rss(pid);
    let statuses = futures::future::join_all(bodies[1..].iter().cloned().map(post)).await;
    let four = status_bytes(pid, "VmHWM").saturating_sub(before);
    eprintln!("one 7 MB submission: API peak +{} MB; four at once: +{} MB", one >> 20, four >> 20);
    assert_eq!(statuses, [202; 4]);
    // Two bodies' worth with the allocator's slack is 2.2–2.6 × one; under CI's parallel tests
    // about one run in three peaks near three (2.9–3.05 ×, cause not yet found: the turn is now
    // held until the answer is built, which did not remove it). All four at once would be 4 ×.
    assert!(four < one * 7 / 2, "four at once peaked at +{} MB, one alone at +{} MB", four >> 20, one >> 20);
}
