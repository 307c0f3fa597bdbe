//! What the service adds to a job, for every kind: the same request timed three ways, one
//! after the other in each round so the machine's drift touches all three alike.
//!
//! - **alone**: the kind's `run` with a sink that drops progress and never asks for a snapshot
//!   (the algorithm and its output files);
//! - **live**: the same with a sink that takes progress and renders a live snapshot whenever
//!   the service would (the first a quarter second into the steps, then one a second),
//!   keeping the PNGs;
//! - **service**: the whole path — the engine on an embedded SQLite store in a temporary
//!   folder: submission, queue, the job's thread, progress events and snapshots stored and
//!   broadcast, artifacts written to the database — from submission until the job is done.
//!
//! Snapshots and progress may add at most 10 % (live ÷ alone ≤ 1.10). Prints a Markdown table
//! of medians. Run with `cargo bench --bench job_path` (`-- --rounds N`, default 5).

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use parking_lot::Mutex;
use serde_json::{json, Value};

use landform::export::MeshSettings;
use landform::jobs::{Engine, EngineConfig, JobKind, ProgressSink, RunContext, SilentProgress, Submitted, Submitter};
use landform::model::{JobStatus, Progress};
use landform::store::SqliteStore;
use landform::validate::Limits;

#[path = "support/mod.rs"]
mod support;

/// A sink that renders snapshots at the service's rate and keeps them: the first a quarter
/// second into the steps, then one a second (as `jobs::live`'s throttle).
struct LiveSink {
    first: Mutex<Option<Instant>>,
    last: Mutex<Option<Instant>>,
    progress: AtomicUsize,
    snapshots: Mutex<Vec<Vec<u8>>>,
}

impl ProgressSink for LiveSink {
    fn progress(&self, progress: Progress) {
        std::hint::black_box(progress);
        self.progress.fetch_add(1, Ordering::Relaxed);
    }
    fn snapshot_due(&self) -> bool {
        match *self.last.lock() {
            Some(at) => at.elapsed() >= Duration::from_secs(1),
            None => self.first.lock().get_or_insert_with(Instant::now).elapsed() >= Duration::from_millis(250),
        }
    }
    fn snapshot(&self, png: Vec<u8>, progress: Progress) {
        *self.last.lock() = Some(Instant::now());
        self.progress(progress);
        self.snapshots.lock().push(png);
    }
}

/// A request of the kind: an example from `api/`, or a body given here.
struct Case {
    label: &'static str,
    kind: &'static str,
    body: Value,
}

fn example(kind: &str, name: &str) -> Value {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("api").join(kind).join(format!("{name}.json"));
    serde_json::from_str(&std::fs::read_to_string(path).expect("example")).expect("json")
}

fn cases() -> Vec<Case> {
    vec![
        Case { label: "bulldoze/hillside-road", kind: "bulldoze", body: example("bulldoze", "hillside-road") },
        Case { label: "deform-terrain/s-road", kind: "deform-terrain", body: example("deform-terrain", "s-road") },
        Case {
            label: "carve-coast/island-defaults",
            kind: "carve-coast",
            body: example("carve-coast", "island-defaults"),
        },
        Case { label: "grow-cave/columns", kind: "grow-cave", body: example("grow-cave", "columns") },
        Case {
            label: "weather-column/goblin-cap",
            kind: "weather-column",
            body: example("weather-column", "goblin-cap"),
        },
        // The case: 160 × 400 × 160 = 10.24 M voxels weathered to nothing.
        Case {
            label: "weather-column/10M column to nothing",
            kind: "weather-column",
            body: json!({
                "grid": {"x": 160, "y": 400, "z": 160},
                "voxel_size_m": 0.1,
                "column": {"profile": {"box": {}}},
                "layers": [{"top_m": 1000.0, "resistance": 1.0, "bubble": {"sphere": {"radius": 4.0}}}],
                "rate": 0.5,
                "steps": 65000,
                "seed": 1,
            }),
        },
    ]
}

/// The kind's prepared parameters and the seed, as the engine would run them.
fn prepared(kind: &dyn JobKind, body: &Value, limits: &Limits) -> (Value, u64) {
    let mut params = body.clone();
    let obj = params.as_object_mut().expect("an object");
    let seed = obj.remove("seed").and_then(|s| s.as_u64()).unwrap_or(0);
    for common in ["label", "compression", "lods"] {
        obj.remove(common);
    }
    (kind.prepare(params, limits).expect("valid").params, seed)
}

fn alone(kind: &dyn JobKind, params: &Value, seed: u64, limits: &Limits) -> f64 {
    let cancel = AtomicBool::new(false);
    let ctx = RunContext {
        cancel: &cancel,
        sink: &SilentProgress,
        terrain: &support::NoStore,
        limits,
        mesh: MeshSettings::default(),
        draft: false,
    };
    let started = Instant::now();
    std::hint::black_box(kind.run(params, seed, &ctx).expect("runs"));
    started.elapsed().as_secs_f64()
}

/// Seconds, progress calls and snapshots.
fn live(kind: &dyn JobKind, params: &Value, seed: u64, limits: &Limits) -> (f64, usize, usize) {
    let cancel = AtomicBool::new(false);
    let sink = LiveSink {
        first: Mutex::new(None),
        last: Mutex::new(None),
        progress: AtomicUsize::new(0),
        snapshots: Mutex::new(Vec::new()),
    };
    let ctx = RunContext {
        cancel: &cancel,
        sink: &sink,
        terrain: &support::NoStore,
        limits,
        mesh: MeshSettings::default(),
        draft: false,
    };
    let started = Instant::now();
    std::hint::black_box(kind.run(params, seed, &ctx).expect("runs"));
    let seconds = started.elapsed().as_secs_f64();
    let snapshots = sink.snapshots.lock().len();
    (seconds, sink.progress.load(Ordering::Relaxed), snapshots)
}

async fn service(engine: &Engine, kind: &str, body: &Value) -> f64 {
    let started = Instant::now();
    let job =
        match engine.submit(kind, body.clone(), usize::MAX / 2, None, &Submitter::default()).await.expect("accepted") {
            Submitted::Created(j) | Submitted::Existing(j) => j,
        };
    loop {
        let now = engine.get(&job.id, None).await.expect("job");
        if now.status.is_terminal() {
            assert_eq!(now.status, JobStatus::Succeeded, "{:?}", now.error);
            return started.elapsed().as_secs_f64();
        }
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rounds = args
        .iter()
        .position(|a| a == "--rounds")
        .and_then(|i| args.get(i + 1))
        .and_then(|n| n.parse().ok())
        .unwrap_or(5usize);
    let only = args.iter().position(|a| a == "--only").and_then(|i| args.get(i + 1)).cloned();
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build().expect("runtime");
    let _guard = runtime.enter();
    let dir = tempfile::tempdir().expect("temporary folder");
    let store = SqliteStore::open(dir.path().join("bench.db").to_str().expect("utf-8")).expect("store");
    let config =
        EngineConfig { limits: Limits { max_voxels: 1 << 30, ..Limits::default() }, ..EngineConfig::default() };
    let limits = config.limits.clone();
    let engine = Engine::new(Arc::new(store), landform::sims::registry(), config).expect("engine");
    engine.start();
    let kinds = landform::sims::registry();

    println!(
        "| job | alone (s) | live (s) | live ÷ alone | snapshots | progress calls | service (s) | service ÷ alone |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for case in cases() {
        if only.as_deref().is_some_and(|o| !case.label.contains(o)) {
            continue;
        }
        let kind = kinds.iter().find(|k| k.name() == case.kind).expect("a kind").as_ref();
        let (params, seed) = prepared(kind, &case.body, &limits);
        let (mut a, mut l, mut s) = (Vec::new(), Vec::new(), Vec::new());
        let (mut calls, mut shots) = (0, 0);
        for _ in 0..rounds {
            a.push(alone(kind, &params, seed, &limits));
            let (seconds, progress, snapshots) = live(kind, &params, seed, &limits);
            (calls, shots) = (progress, snapshots);
            l.push(seconds);
            s.push(runtime.block_on(service(&engine, case.kind, &case.body)));
        }
        let (a, l, s) = (median(a), median(l), median(s));
        println!("| {} | {a:.3} | {l:.3} | {:.3} | {shots} | {calls} | {s:.3} | {:.3} |", case.label, l / a, s / a);
    }
}
