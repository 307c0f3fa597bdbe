//! The deployments a load test drives, started here on 127.0.0.1 and stopped when dropped:
//! `landform serve` on a fresh SQLite file (the API and its supervised worker process), or two
//! API replicas (`serve --role api`) and two workers (`landform worker`) on a fresh PostgreSQL
//! schema.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};

use anyhow::{bail, Context, Result};

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Setup {
    /// `landform serve` on the embedded SQLite store.
    Embedded,
    /// Two API and two worker processes on PostgreSQL.
    Postgres,
}

pub struct Deployment {
    pub apis: Vec<String>,
    /// The API processes (for `serve`, its worker is found among its children).
    api_pids: Vec<u32>,
    /// Workers started on their own.
    worker_pids: Vec<u32>,
    children: Vec<Child>,
    schema: Option<(String, String)>,
    _dir: tempfile::TempDir,
    pub description: String,
}

/// Flags every process gets: the queue holds 64 waiting jobs (the default), logs stay quiet.
const COMMON: [&str; 2] = ["--queue-capacity", "64"];

/// Start a process whose first line of output starts with `first_line`; its log (stderr) goes to
/// `log`.
fn spawn(binary: &str, args: &[&str], first_line: &str, log: &std::path::Path) -> Result<(Child, String)> {
    let mut child = Command::new(binary)
        .args(args)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(log)?)
        .spawn()
        .with_context(|| format!("start {binary}"))?;
    let mut lines = BufReader::new(child.stdout.take().expect("piped")).lines();
    let line = lines.next().context("the process printed nothing")??;
    if !line.starts_with(first_line) {
        bail!("{binary} {args:?} printed {line:?}");
    }
    // Keep draining, so the process never blocks on a full pipe.
    std::thread::spawn(move || for _ in lines {});
    Ok((child, line))
}

impl Deployment {
    pub fn start(setup: Setup, binary: &str, database_url: &str, artifact_store: Option<&str>) -> Result<Self> {
        let dir = tempfile::tempdir()?;
        let mut common = COMMON.to_vec();
        if let Some(store) = artifact_store {
            common.extend(["--artifact-store", store]);
        }
        match setup {
            Setup::Embedded => {
                let db = dir.path().join("landform.db");
                let db = db.to_str().context("temp path")?;
                let mut args = vec!["serve", "--addr", "127.0.0.1:0", "--database", db];
                args.extend(&common);
                let (child, line) = spawn(binary, &args, "listening on ", &dir.path().join("serve.log"))?;
                let base = line.trim_start_matches("listening on ").trim().to_string();
                Ok(Self {
                    apis: vec![base],
                    api_pids: vec![child.id()],
                    worker_pids: Vec::new(),
                    children: vec![child],
                    schema: None,
                    _dir: dir,
                    description: "`landform serve` (API + supervised worker process), embedded SQLite store".into(),
                })
            }
            Setup::Postgres => {
                let schema = format!("load_{}", uuid::Uuid::now_v7().simple());
                admin(database_url, &format!("CREATE SCHEMA {schema}"))?;
                let sep = if database_url.contains('?') { '&' } else { '?' };
                let url = format!("{database_url}{sep}options=-csearch_path%3D{schema}");
                let mut d = Self {
                    apis: Vec::new(),
                    api_pids: Vec::new(),
                    worker_pids: Vec::new(),
                    children: Vec::new(),
                    schema: Some((database_url.to_string(), schema)),
                    _dir: dir,
                    description: "2 API processes (`serve --role api`) + 2 workers (`landform worker`), PostgreSQL"
                        .into(),
                };
                for n in 0..2 {
                    let mut args = vec!["serve", "--role", "api", "--addr", "127.0.0.1:0", "--database", &url];
                    args.extend(&common);
                    let log = d._dir.path().join(format!("api-{n}.log"));
                    let (child, line) = spawn(binary, &args, "listening on ", &log)?;
                    d.apis.push(line.trim_start_matches("listening on ").trim().to_string());
                    d.api_pids.push(child.id());
                    d.children.push(child);
                }
                for n in 0..2 {
                    let log = d._dir.path().join(format!("worker-{n}.log"));
                    let mut args = vec!["worker", "--database", &url];
                    args.extend(&common[2..]);
                    let (child, _) = spawn(binary, &args, "worker ", &log)?;
                    d.worker_pids.push(child.id());
                    d.children.push(child);
                }
                Ok(d)
            }
        }
    }

    /// The processes that run jobs now (a supervised worker may have been restarted).
    fn workers(&self) -> Vec<u32> {
        let mut pids = self.worker_pids.clone();
        for &api in &self.api_pids {
            pids.extend(children_of(api));
        }
        pids
    }

    /// CPU seconds (user + system) the worker processes have used.
    pub fn worker_cpu(&self) -> f64 {
        self.workers().into_iter().map(cpu_seconds).sum()
    }

    /// CPU seconds of every process of the deployment.
    pub fn total_cpu(&self) -> f64 {
        self.worker_cpu() + self.api_pids.iter().copied().map(cpu_seconds).sum::<f64>()
    }
}

impl Drop for Deployment {
    fn drop(&mut self) {
        for c in &mut self.children {
            let _ = c.kill();
            let _ = c.wait();
        }
        if let Some((url, schema)) = &self.schema {
            let _ = admin(url, &format!("DROP SCHEMA {schema} CASCADE"));
        }
    }
}

fn admin(url: &str, sql: &str) -> Result<()> {
    let (url, sql) = (url.to_string(), sql.to_string());
    // The synchronous client runs a runtime of its own: on a thread of its own.
    std::thread::spawn(move || -> Result<()> {
        postgres::Client::connect(&url, postgres::NoTls)?.batch_execute(&sql)?;
        Ok(())
    })
    .join()
    .map_err(|_| anyhow::anyhow!("the PostgreSQL admin thread panicked"))?
}

/// User + system CPU seconds of a process, from /proc (0 when it is gone).
pub fn cpu_seconds(pid: u32) -> f64 {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else { return 0.0 };
    let Some((_, rest)) = stat.rsplit_once(')') else { return 0.0 };
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // Fields 14 and 15 of stat(5); `rest` starts at field 3.
    let ticks: u64 = fields.get(11..13).map_or(0, |f| f.iter().filter_map(|v| v.parse::<u64>().ok()).sum());
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as f64;
    ticks as f64 / hz
}

/// The processes whose parent is `pid`.
fn children_of(pid: u32) -> Vec<u32> {
    let Ok(entries) = std::fs::read_dir("/proc") else { return Vec::new() };
    entries
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
        .filter(|child| {
            std::fs::read_to_string(format!("/proc/{child}/stat"))
                .ok()
                .and_then(|s| s.rsplit_once(')').and_then(|(_, rest)| rest.split_whitespace().nth(1)?.parse().ok()))
                == Some(pid)
        })
        .collect()
}
