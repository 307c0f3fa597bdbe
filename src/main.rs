//! The `landform` command: `serve`, `run`, `openapi`.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use landform::config::{HttpArgs, Role, ServiceArgs, WorkerArgs};
use landform::jobs::{Engine, EngineConfig, EventFeed, JobStatus, Submitted, Worker};
use landform::supervisor::Supervisor;

#[derive(Parser)]
#[command(name = "landform", version, about = "Terrain generation as a service")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the HTTP service (and, with the default role, its jobs).
    Serve {
        /// `all`: the API and the jobs in this process; `api`: the API only, jobs run by
        /// workers (`landform worker`) sharing the database; `worker`: a worker only.
        #[arg(long, env = "LANDFORM_ROLE", value_enum, default_value_t = Role::All)]
        role: Role,
        #[command(flatten)]
        http: HttpArgs,
        #[command(flatten)]
        service: ServiceArgs,
        #[command(flatten)]
        worker: WorkerArgs,
    },
    /// Run a worker: claim jobs from the database's queue and run them, until SIGTERM.
    Worker {
        #[command(flatten)]
        service: ServiceArgs,
        #[command(flatten)]
        worker: WorkerArgs,
    },
    /// Run one job offline with the same engine, and write its artifacts to a folder.
    Run {
        /// A request body, as for POST /v1/jobs/{kind}.
        request: PathBuf,
        /// Folder for the artifacts (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Job kind; default: the request file's folder name (api/<kind>/<name>.json).
        #[arg(long)]
        kind: Option<String>,
        #[command(flatten)]
        service: ServiceArgs,
    },
    /// Print the OpenAPI document (YAML); openapi.yaml is its output.
    Openapi,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Openapi => {
            let kinds: Vec<_> = landform::sims::registry().into_iter().map(Arc::from).collect();
            print!("{}", landform::http::openapi_yaml(&kinds));
            Ok(())
        }
        Command::Serve { role: Role::Worker, service, worker: w, .. } | Command::Worker { service, worker: w } => {
            init_tracing("info");
            lower_priority(w.nice)?;
            runtime()?.block_on(worker(service, w))
        }
        Command::Serve { role, http, service, worker } => runtime()?.block_on(serve(http, service, role, worker)),
        Command::Run { request, out, kind, service } => runtime()?.block_on(run(request, out, kind, service)),
    }
}

/// Lower the process's CPU priority by `nice`. Called before any thread starts: Linux keeps a
/// niceness per thread, and every thread started later inherits this one's.
fn lower_priority(nice: i32) -> anyhow::Result<()> {
    if nice == 0 {
        return Ok(());
    }
    lower_autogroup(nice);
    // SAFETY: setpriority has no memory-safety preconditions; 0 names the calling thread.
    let current = unsafe { libc::getpriority(libc::PRIO_PROCESS, 0) };
    // SAFETY: as above.
    if unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, current.saturating_add(nice).min(19)) } != 0 {
        anyhow::bail!("cannot lower the worker's priority by {nice}: {}", std::io::Error::last_os_error());
    }
    Ok(())
}

/// Under the kernel's autogroup scheduling (`/proc/sys/kernel/sched_autogroup_enabled`, on by
/// default in many distributions' kernels, this machine's among them) the cores are first shared
/// evenly between sessions, and a niceness counts only against processes of the same session.
/// A worker started from the session of its API or load generator then competes at full weight
/// with a database in a session of its own: measured with the load generator (PostgreSQL,
/// 2 API + 2 workers, 30 s), the database's backends waited up to 270 ms for a core and the
/// submissions' p99 was 200 ms; with each worker in a session of its own at nice 10 it was 30 ms.
/// So a worker moves into a session of its own when it can (a process-group leader, such as a
/// job of an interactive shell, cannot: it keeps its session, and its niceness counts within it)
/// and lowers that session's group by `nice` too. The worker never depends on its session:
/// `serve` stops the worker it supervises through its standard input and SIGTERM, not the
/// terminal's signals.
fn lower_autogroup(nice: i32) {
    let enabled = std::fs::read_to_string("/proc/sys/kernel/sched_autogroup_enabled");
    if enabled.map_or(true, |e| e.trim() != "1") {
        return;
    }
    // SAFETY: getsid, getpid and setsid have no memory-safety preconditions.
    let own_session = unsafe { libc::getsid(0) == libc::getpid() || libc::setsid() >= 0 };
    if !own_session {
        tracing::info!(
            "this worker leads a process group, so it keeps its session: its niceness counts within it only"
        );
        return;
    }
    if let Err(e) = std::fs::write("/proc/self/autogroup", nice.to_string()) {
        tracing::warn!(error = %e, "cannot lower this worker's scheduling group");
    }
}

fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    Ok(tokio::runtime::Builder::new_multi_thread().enable_all().build()?)
}

fn init_tracing(default: &str) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| default.into());
    let _ = tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).try_init();
}

/// An engine that runs jobs itself (`runs_jobs`, as `landform run` does), or one that leaves
/// them in the store for workers.
fn engine(service: &ServiceArgs, runs_jobs: bool) -> anyhow::Result<Engine> {
    let store = service.open_store(false)?;
    let config = EngineConfig { runs_jobs, ..service.engine_config() };
    Ok(Engine::new(store, landform::sims::registry(), config)?)
}

async fn serve(http: HttpArgs, service: ServiceArgs, role: Role, worker_args: WorkerArgs) -> anyhow::Result<()> {
    init_tracing("info,tower_http=info");
    landform::http::server::raise_descriptor_limit();
    // Opening a store and recovering talk to it synchronously (PostgreSQL's client runs a
    // runtime of its own): off the async threads. Workers run the jobs: with the role `all`
    // one supervised child process, with `api` workers started on their own.
    let engine = tokio::task::block_in_place(|| engine(&service, false))?;
    let supervisor = match role {
        Role::All => Some(Supervisor::spawn(
            service.worker_command_args(&worker_args),
            std::time::Duration::from_secs(worker_args.lease_secs),
        )?),
        Role::Api | Role::Worker => None,
    };
    let http_config = http.http_config(engine.config().memory_budget)?;
    tokio::task::block_in_place(|| engine.recover())?;
    engine.start();
    let listener = tokio::net::TcpListener::bind(&http.addr).await.with_context(|| format!("binding {}", http.addr))?;
    let addr = listener.local_addr()?;
    tracing::info!(
        %addr,
        database = %service.database_location(),
        workers = engine.config().workers,
        memory_budget = engine.config().memory_budget,
        "listening"
    );
    announce(&format!("listening on http://{addr}"));
    let (engine_handle, deadline_secs) = (engine.clone(), service.shutdown_deadline_secs);
    let app = landform::http::app(engine, http_config);
    let (stopping_tx, stopping_rx) = tokio::sync::oneshot::channel::<()>();
    let (stopping_engine_tx, stopping_engine_rx) = tokio::sync::oneshot::channel::<()>();
    let limits = http.connection_limits();
    tracing::info!(max_connections = limits.max_connections, "connection limits");
    let server = landform::http::server::serve(listener, app, limits, async move {
        shutdown_signal().await;
        let _ = stopping_tx.send(());
        let _ = stopping_engine_tx.send(());
    });
    // Open event streams would hold a graceful shutdown for as long as their jobs run: give
    // them a few seconds, then stop. Unfinished jobs run again on the next start.
    let grace = async {
        let _ = stopping_rx.await;
        tokio::time::sleep(SHUTDOWN_GRACE).await;
    };
    let http = async {
        tokio::select! {
            served = server => served,
            _ = grace => {
                tracing::info!("shut down with streams still open");
                Ok(())
            }
        }
    };
    // Meanwhile the engine takes no more jobs and lets the running ones finish (or returns
    // them to the queue at the deadline).
    let drained = async {
        let _ = stopping_engine_rx.await;
        engine_handle.shutdown(std::time::Duration::from_secs(deadline_secs)).await;
        if let Some(supervisor) = supervisor {
            supervisor.stop().await;
        }
    };
    let (served, ()) = tokio::join!(http, drained);
    served?;
    Ok(())
}

/// A worker process: claims jobs from the store's queue and runs them until SIGTERM, then
/// lets them finish until the shutdown deadline and gives the rest back to the queue.
async fn worker(service: ServiceArgs, args: WorkerArgs) -> anyhow::Result<()> {
    init_tracing("info");
    if args.exit_with_parent {
        // From the start: opening the store may wait for its lock or its migrations.
        let lease = std::time::Duration::from_secs(args.lease_secs);
        tokio::spawn(heartbeat(landform::supervisor::heartbeat_interval(lease)));
    }
    let store = tokio::task::block_in_place(|| service.open_store(true))?;
    let config = service.worker_config(&args);
    landform::jobs::build_pool(service.engine_config().workers);
    tracing::info!(
        name = %config.name,
        database = %service.database_location(),
        memory_budget = config.memory_budget,
        lease_secs = config.lease.as_secs(),
        "worker started"
    );
    announce(&format!("worker {} started", config.name));
    let worker = Worker::new(store, landform::sims::registry(), config);
    let running = tokio::spawn({
        let worker = worker.clone();
        async move { worker.run().await }
    });
    let deadline = tokio::select! {
        _ = shutdown_signal() => {
            tracing::info!("stopping: no more claims; running jobs may finish");
            std::time::Duration::from_secs(service.shutdown_deadline_secs)
        }
        _ = parent_gone(args.exit_with_parent) => {
            tracing::warn!("the API process that started this worker is gone: giving the jobs back");
            std::time::Duration::ZERO
        }
    };
    worker.shutdown(deadline).await;
    running.abort();
    // Everything is written (store calls are synchronous). Exit here rather than drop the
    // store inside the runtime: the synchronous PostgreSQL client closes its connection with a
    // runtime of its own, which may not start within this one.
    std::process::exit(0)
}

/// Tells the supervising process this one is alive: a byte on standard output at every tick.
/// A one-byte write to a pipe the supervisor keeps reading does not block.
async fn heartbeat(every: std::time::Duration) {
    let mut ticks = tokio::time::interval(every);
    loop {
        ticks.tick().await;
        let mut out = std::io::stdout().lock();
        if out.write_all(b".").and_then(|()| out.flush()).is_err() {
            return;
        }
    }
}

/// Resolves when standard input closes (the supervising process has ended), if asked to
/// watch it; never otherwise.
async fn parent_gone(watch: bool) {
    if !watch {
        return std::future::pending().await;
    }
    // A thread of its own, never joined: a blocking task would hold the runtime's shutdown
    // until the pipe closes, which is never while the parent waits for this process.
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    std::thread::spawn(move || {
        let mut buf = [0u8; 64];
        while matches!(std::io::Read::read(&mut std::io::stdin(), &mut buf), Ok(n) if n > 0) {}
        let _ = tx.send(());
    });
    let _ = rx.await;
}

const SHUTDOWN_GRACE: std::time::Duration = std::time::Duration::from_secs(5);

async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        if let Ok(mut s) = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            s.recv().await;
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! { _ = ctrl_c => {}, _ = term => {} }
}

async fn run(request: PathBuf, out: PathBuf, kind: Option<String>, mut service: ServiceArgs) -> anyhow::Result<()> {
    init_tracing("warn");
    let kind = match kind {
        Some(k) => k,
        None => request
            .parent()
            .and_then(|p| p.file_name())
            .and_then(|n| n.to_str())
            .map(str::to_string)
            .context("give --kind: the request's folder does not name one")?,
    };
    let text = std::fs::read(&request).with_context(|| format!("reading {}", request.display()))?;
    let body_bytes = text.len();
    let body: serde_json::Value =
        serde_json::from_slice(&text).with_context(|| format!("{} is not JSON", request.display()))?;
    drop(text);
    let _scratch = if service.database.is_none() && std::env::var("DATABASE_URL").is_err() {
        let scratch = ScratchDb::new();
        service.database = Some(scratch.0.to_string_lossy().into_owned());
        Some(scratch)
    } else {
        None
    };
    let engine = tokio::task::block_in_place(|| engine(&service, true))?;
    engine.start();
    let job = match engine.submit(&kind, body, body_bytes, None, &Default::default()).await {
        Ok(Submitted::Created(j) | Submitted::Existing(j)) => j,
        Err(landform::jobs::EngineError::Invalid { errors, .. }) => {
            for e in errors {
                eprintln!("{}: {}", if e.field.is_empty() { "(body)" } else { &e.field }, e.message);
            }
            anyhow::bail!("the request is invalid");
        }
        Err(e) => return Err(e.into()),
    };

    let bar = ProgressBar::new(1000);
    bar.set_style(ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {percent:>3}% {msg}")?);
    if let EventFeed::Live { backlog, mut rx, .. } = engine.events(&job.id, None, None).await? {
        let mut backlog = backlog.into_iter();
        loop {
            let ev = match backlog.next() {
                Some(ev) => ev,
                None => match rx.recv().await {
                    Ok(ev) => ev,
                    Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => continue,
                    Err(_) => break,
                },
            };
            if ev.event == "progress" {
                let f = ev.data["fraction"].as_f64().unwrap_or(0.0);
                bar.set_position((f * 1000.0) as u64);
                bar.set_message(format!(
                    "{} {}/{} {}",
                    ev.data["stage"].as_str().unwrap_or(""),
                    ev.data["step"],
                    ev.data["steps"],
                    ev.data["message"].as_str().unwrap_or("")
                ));
            }
            if ev.event == "done" {
                break;
            }
        }
    }
    bar.finish_and_clear();
    let job = engine.get(&job.id, None).await?;
    if job.status != JobStatus::Succeeded {
        anyhow::bail!(
            "job {}: {}",
            job.status.as_str(),
            job.error.map(|e| e["detail"].to_string()).unwrap_or_default()
        );
    }
    std::fs::create_dir_all(&out)?;
    for a in &job.artifacts {
        // A chunk at a time, as the server sends them: a large artifact is never whole in memory.
        // Names are the kinds' own (`tiles/0/1_2.glb` has folders), never a client's.
        let path = out.join(&a.name);
        if let Some(folder) = path.parent() {
            std::fs::create_dir_all(folder)?;
        }
        let mut file = std::io::BufWriter::new(std::fs::File::create(&path)?);
        let mut offset = 0u64;
        while offset < a.bytes {
            let piece = engine
                .artifact_piece(&job.id, &a.name, offset, landform::store::CHUNK_BYTES)
                .await?
                .filter(|p| !p.is_empty())
                .context("artifact vanished")?;
            std::io::Write::write_all(&mut file, &piece)?;
            offset += piece.len() as u64;
        }
        std::io::Write::flush(&mut file)?;
        println!("{:>12} bytes  {}", a.bytes, out.join(&a.name).display());
    }
    std::fs::write(out.join("job.json"), serde_json::to_vec_pretty(&job)?)?;
    println!("{}", serde_json::to_string_pretty(&job.result)?);
    Ok(())
}

/// A throwaway store for an offline run, removed with its WAL files however the run ends.
struct ScratchDb(PathBuf);

impl ScratchDb {
    fn new() -> Self {
        Self(std::env::temp_dir().join(format!("landform-run-{}.db", uuid::Uuid::now_v7())))
    }
}

impl Drop for ScratchDb {
    fn drop(&mut self) {
        for suffix in ["", "-wal", "-shm"] {
            let mut p = self.0.clone().into_os_string();
            p.push(suffix);
            let _ = std::fs::remove_file(p);
        }
    }
}

/// A line for the process that started this one, which reads it to learn the address or that
/// the worker is up. A parent already gone (a closed pipe) is no reason to fail: `println!`
/// would panic.
fn announce(line: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}").and_then(|()| out.flush());
}
