//! `landform-load`: load tests of Landform with goose. Starts the deployment it drives on
//! 127.0.0.1 (see `servers.rs`), measures the floor — the CPU time one small job of each kind
//! costs in the worker process, hence the most jobs per second the machine's cores could
//! complete — then runs the scenarios (steady small jobs, a burst that fills the queue, a mix
//! with large jobs), checks that every accepted job ended and every artifact downloads with its
//! advertised sha256, and writes a JSON and a Markdown report. Bounded: fixed client counts and
//! durations, a drain deadline, requests only to the processes it started.

mod checks;
mod report;
mod scenarios;
mod servers;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::Parser;
use goose::config::GooseConfiguration;
use goose::metrics::GooseMetrics;
use goose::prelude::*;
use serde_json::Value;

use report::{Floor, FloorKind, Phase, Report};
use scenarios::{burst, large_job, shared, small_job, Shared};
use servers::{Deployment, Setup};

#[derive(Parser, Debug)]
#[command(about = "Load tests for Landform (servers started here, on 127.0.0.1 only)")]
struct Args {
    /// Which deployment to start and drive.
    #[arg(long, value_enum)]
    setup: Setup,
    /// The landform binary (build it with `cargo build --release`).
    #[arg(long, default_value = "target/release/landform")]
    landform: String,
    /// PostgreSQL database to make a fresh schema in (postgres setup).
    #[arg(long, default_value = "postgres://postgres@127.0.0.1:5432/test")]
    database_url: String,
    /// Concurrent clients of the steady, burst and mix phases.
    #[arg(long, default_value_t = 64)]
    clients: usize,
    /// Seconds of the steady phase.
    #[arg(long, default_value_t = 60)]
    seconds: usize,
    /// Seconds of the mix phase (0: skip it).
    #[arg(long, default_value_t = 30)]
    mix_seconds: usize,
    /// Jobs of each kind run one at a time to measure the floor (after two to warm up).
    #[arg(long, default_value_t = 20)]
    floor_jobs: usize,
    /// Milliseconds between a polling client's status requests.
    #[arg(long, default_value_t = 100)]
    poll_ms: u64,
    /// Keep artifacts' bytes in this object store (`file:///dir` or `s3://bucket/prefix`)
    /// instead of the database; passed to every process as `--artifact-store`.
    #[arg(long)]
    artifact_store: Option<String>,
    /// Skip the burst phase.
    #[arg(long)]
    no_burst: bool,
    /// Seconds to wait, after the last phase, for every accepted job to end.
    #[arg(long, default_value_t = 300)]
    drain_seconds: u64,
    /// Where the reports go (`<setup>.json`, `<setup>.md`).
    #[arg(long, default_value = "loadtests/results")]
    out: PathBuf,
    /// A correctness run only (the test command's smoke run, on a debug build and a busy
    /// machine): every body still runs, no request fails, no job is lost, every artifact
    /// matches; the speed requirements (share of the floor, submit p99) are reported, not judged.
    #[arg(long)]
    smoke: bool,
}

fn bodies(dir: &Path) -> Result<Vec<(String, Value)>> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).with_context(|| dir.display().to_string())? {
        let path = e?.path();
        let kind = path.file_stem().and_then(|s| s.to_str()).context("body name")?.to_string();
        out.push((kind, serde_json::from_slice(&std::fs::read(&path)?)?));
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

/// Run each small body one job at a time and measure the worker processes' CPU time.
async fn floor(deployment: &Deployment, client: &reqwest::Client, jobs: usize) -> Result<Floor> {
    let s = shared();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut kinds = Vec::new();
    for (kind, body) in &s.small {
        let run = || async {
            let res = client
                .post(format!("{}/v1/jobs/{kind}", s.apis[0]))
                .header("prefer", "wait=60")
                .json(body)
                .send()
                .await?;
            let job: Value = res.json().await?;
            if job["status"] != "succeeded" {
                bail!("floor: a {kind} job ended {}: {}", job["status"], job["error"]);
            }
            let id = job["id"].as_str().unwrap_or_default().to_string();
            s.accepted.lock().unwrap().push(scenarios::Accepted { id, kind: kind.clone(), phase: "floor".into() });
            Ok(())
        };
        for _ in 0..2 {
            run().await?;
        }
        let (cpu0, t0) = (deployment.worker_cpu(), Instant::now());
        for _ in 0..jobs {
            run().await?;
        }
        let (cpu, wall) = (deployment.worker_cpu() - cpu0, t0.elapsed().as_secs_f64());
        kinds.push(FloorKind {
            kind: kind.clone(),
            jobs,
            cpu_ms_per_job: 1000.0 * cpu / jobs as f64,
            wall_ms_per_job: 1000.0 * wall / jobs as f64,
        });
        eprintln!(
            "floor: {kind}: {:.1} ms CPU, {:.1} ms wall per job",
            1000.0 * cpu / jobs as f64,
            1000.0 * wall / jobs as f64
        );
    }
    let mean_cpu_ms = kinds.iter().map(|k| k.cpu_ms_per_job).sum::<f64>() / kinds.len() as f64;
    Ok(Floor { cores, kinds, mean_cpu_ms, jobs_per_s: cores as f64 * 1000.0 / mean_cpu_ms })
}

/// One goose attack: `scenarios` on `clients` users, for `seconds` (or one iteration each).
async fn attack(host: &str, scenarios: Vec<Scenario>, clients: usize, seconds: Option<usize>) -> Result<GooseMetrics> {
    let mut a = *GooseAttack::initialize_with_config(GooseConfiguration::default())?
        .set_default(GooseDefault::Host, host)?
        .set_default(GooseDefault::Users, clients)?
        .set_default(GooseDefault::IncreaseRate, clients.to_string().as_str())?
        .set_default(GooseDefault::NoPrintMetrics, true)?
        .set_default(GooseDefault::Quiet, 1)?
        // No controllers: the generator listens on no port.
        .set_default(GooseDefault::NoTelnet, true)?
        .set_default(GooseDefault::NoWebSocket, true)?
        .set_default(GooseDefault::Timeout, "600")?;
    a = match seconds {
        // Metrics from the first request on, the ramp included (with iterations they always are).
        Some(s) => *a.set_default(GooseDefault::RunTime, s)?.set_default(GooseDefault::NoResetMetrics, true)?,
        None => *a.set_default(GooseDefault::Iterations, 1)?,
    };
    for s in scenarios {
        a = a.register_scenario(s);
    }
    Ok(a.execute().await?)
}

struct Window {
    name: String,
    clients: usize,
    from: chrono::DateTime<chrono::Utc>,
    to: chrono::DateTime<chrono::Utc>,
    cpu: f64,
    metrics: GooseMetrics,
    burst_503: u64,
}

async fn phase(
    deployment: &Deployment,
    name: &str,
    scenarios: Vec<Scenario>,
    clients: usize,
    seconds: Option<usize>,
) -> Result<Window> {
    let s = shared();
    *s.phase.lock().unwrap() = name.to_string();
    let before_503 = s.burst_503.load(Ordering::Relaxed);
    eprintln!("phase {name}: {clients} clients, {}", seconds.map_or("one round each".into(), |s| format!("{s} s")));
    let (cpu0, from) = (deployment.total_cpu(), chrono::Utc::now());
    let metrics = attack(&s.apis[0], scenarios, clients, seconds).await?;
    let (cpu, to) = (deployment.total_cpu() - cpu0, chrono::Utc::now());
    Ok(Window {
        name: name.into(),
        clients,
        from,
        to,
        cpu,
        metrics,
        burst_503: s.burst_503.load(Ordering::Relaxed) - before_503,
    })
}

#[tokio::main]
async fn main() -> Result<()> {
    let args = Args::parse();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let deployment = Deployment::start(args.setup, &args.landform, &args.database_url, args.artifact_store.as_deref())?;
    eprintln!("started: {} at {:?}", deployment.description, deployment.apis);
    scenarios::init(Shared {
        apis: deployment.apis.clone(),
        small: bodies(&root.join("bodies/small"))?,
        large: bodies(&root.join("bodies/large"))?,
        phase: Mutex::new("floor".into()),
        poll_every: Duration::from_millis(args.poll_ms),
        accepted: Mutex::new(Vec::new()),
        burst_503: Default::default(),
        problems: Mutex::new(Vec::new()),
    });
    let client = reqwest::Client::builder().timeout(Duration::from_secs(120)).build()?;
    let started = chrono::Utc::now();
    let floor = floor(&deployment, &client, args.floor_jobs).await?;

    let mut windows = vec![
        phase(
            &deployment,
            "steady",
            vec![scenario!("steady").register_transaction(transaction!(small_job))],
            args.clients,
            Some(args.seconds),
        )
        .await?,
    ];
    if !args.no_burst {
        // Let the steady phase's last jobs end first, so the burst meets an empty queue.
        checks::drain(&client, Duration::from_secs(args.drain_seconds)).await;
        windows.push(
            phase(
                &deployment,
                "burst",
                vec![scenario!("burst").register_transaction(transaction!(burst))],
                args.clients,
                None,
            )
            .await?,
        );
    }
    if args.mix_seconds > 0 {
        checks::drain(&client, Duration::from_secs(args.drain_seconds)).await;
        let large = (args.clients / 16).max(1);
        windows.push(
            phase(
                &deployment,
                "mix",
                vec![
                    scenario!("small").set_weight(args.clients - large)?.register_transaction(transaction!(small_job)),
                    scenario!("large").set_weight(large)?.register_transaction(transaction!(large_job)),
                ],
                args.clients,
                Some(args.mix_seconds),
            )
            .await?,
        );
    }

    eprintln!("checking every accepted job and artifact");
    let (checks, jobs) = checks::run(&client, Duration::from_secs(args.drain_seconds)).await;
    let phases: Vec<Phase> = windows
        .into_iter()
        .map(|w| {
            let accepted: Vec<scenarios::Accepted> =
                shared().accepted.lock().unwrap().iter().filter(|a| a.phase == w.name).cloned().collect();
            let completed = accepted
                .iter()
                .filter_map(|a| jobs.get(&a.id))
                .filter(|j| j["status"] == "succeeded")
                .filter_map(|j| j["finished_at"].as_str()?.parse::<chrono::DateTime<chrono::Utc>>().ok())
                .filter(|t| *t >= w.from && *t <= w.to)
                .count();
            let seconds = (w.to - w.from).num_milliseconds() as f64 / 1000.0;
            let jobs_per_s = completed as f64 / seconds;
            Phase {
                name: w.name,
                clients: w.clients,
                seconds,
                accepted: accepted.len(),
                completed_in_window: completed,
                jobs_per_s,
                fraction_of_floor: jobs_per_s / floor.jobs_per_s,
                cpu_utilisation: w.cpu / (floor.cores as f64 * seconds),
                burst_503: w.burst_503,
                requests: report::requests(&w.metrics),
            }
        })
        .collect();

    let mut verdicts = BTreeMap::new();
    let need = if args.setup == Setup::Embedded { 0.50 } else { 0.35 };
    if !args.smoke {
        if let Some(steady) = phases.iter().find(|p| p.name == "steady") {
            verdicts.insert(
                format!("steady: at least {:.0} % of the floor", 100.0 * need),
                steady.fraction_of_floor >= need,
            );
        }
        let submit_p99 = phases.iter().filter_map(|p| p.requests.get("submit").map(|r| r.p99_ms)).fold(0.0, f64::max);
        verdicts.insert("submit p99 ≤ 50 ms in every phase".into(), submit_p99 <= 50.0);
    }
    // The burst's 503s are marked as successes when they come, so every failure counts.
    let unexpected: usize = phases.iter().flat_map(|p| p.requests.values()).map(|r| r.failed).sum();
    verdicts.insert(
        "no error but the burst's counted 503s".into(),
        unexpected == 0 && checks.problems.is_empty() && checks.failed == 0,
    );
    verdicts.insert("no job lost".into(), checks.lost == 0);
    verdicts.insert("every artifact matches its sha256".into(), checks.artifact_mismatches == 0);

    let report = Report {
        setup: format!("{:?}", args.setup).to_lowercase(),
        deployment: deployment.description.clone(),
        command: std::env::args().collect::<Vec<_>>().join(" "),
        started: started.to_rfc3339(),
        floor,
        phases,
        checks,
        verdicts,
    };
    std::fs::create_dir_all(&args.out)?;
    let stem = args.out.join(&report.setup);
    std::fs::write(stem.with_extension("json"), serde_json::to_vec_pretty(&report)?)?;
    let md = report.markdown();
    std::fs::write(stem.with_extension("md"), &md)?;
    println!("{md}");
    drop(deployment);
    if report.verdicts.values().all(|v| *v) {
        Ok(())
    } else {
        bail!("a requirement was not met (see the report)")
    }
}
