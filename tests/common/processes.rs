//! The service as separate processes: workers (`landform worker`) and API replicas
//! (`serve --role api`) on one database, and a PostgreSQL schema of their own.

use std::process::{Child, Command, Stdio};

use super::server::{Options, TestServer};

/// A `landform worker` process, killed when dropped.
pub struct WorkerProcess(pub Child);

impl WorkerProcess {
    /// A worker on `database` whose claims last `lease_secs`; returns once it has started.
    pub fn start(database: &str, lease_secs: u64) -> Self {
        Self::start_with(database, lease_secs, &[], &[])
    }

    /// A worker with more flags and environment variables.
    pub fn start_with(database: &str, lease_secs: u64, extra: &[String], envs: &[(String, String)]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_landform"))
            .args(["worker", "--database", database, "--workers", "2", "--lease-secs", &lease_secs.to_string()])
            .args(extra)
            .envs(envs.iter().map(|(k, v)| (k, v)))
            .env("RUST_LOG", "warn")
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start a worker");
        let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        std::io::BufRead::read_line(&mut out, &mut line).expect("the worker's first line");
        assert!(line.starts_with("worker "), "{line}");
        std::thread::spawn(move || std::io::copy(&mut out, &mut std::io::sink()));
        WorkerProcess(child)
    }

    /// Send a signal (`KILL`, `STOP`, `CONT`, `TERM`).
    pub fn signal(&self, name: &str) {
        let ok = Command::new("kill").args([&format!("-{name}"), &self.0.id().to_string()]).status().unwrap();
        assert!(ok.success(), "kill -{name}");
    }
}

impl Drop for WorkerProcess {
    fn drop(&mut self) {
        let _ = Command::new("kill").args(["-CONT", &self.0.id().to_string()]).status();
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// An API replica on `database` that runs no job itself.
pub async fn api_replica(database: &str) -> TestServer {
    let options = Options {
        database_url: Some(database.to_string()),
        extra: vec!["--role".into(), "api".into()],
        ..Options::default()
    };
    TestServer::start_on(std::path::Path::new("unused"), &options).await
}

/// A fresh schema on `LANDFORM_TEST_DATABASE_URL`, dropped afterwards; None without the variable.
pub struct Schema {
    base: String,
    name: String,
    pub url: String,
}

pub fn with_schema() -> Option<Schema> {
    let base = std::env::var("LANDFORM_TEST_DATABASE_URL").ok().filter(|u| !u.is_empty())?;
    let name = format!("p_{}", uuid::Uuid::now_v7().simple());
    run_sql(&base, format!("CREATE SCHEMA {name}"));
    let sep = if base.contains('?') { '&' } else { '?' };
    let url = format!("{base}{sep}options=-csearch_path%3D{name}");
    Some(Schema { base, name, url })
}

impl Drop for Schema {
    fn drop(&mut self) {
        run_sql(&self.base, format!("DROP SCHEMA {} CASCADE", self.name));
    }
}

/// The synchronous client runs a runtime of its own: on a thread of its own.
fn run_sql(url: &str, sql: String) {
    let url = url.to_string();
    std::thread::spawn(move || postgres::Client::connect(&url, postgres::NoTls).unwrap().batch_execute(&sql))
        .join()
        .unwrap()
        .unwrap();
}

/// The processes whose parent is `pid` (from /proc).
pub fn children_of(pid: u32) -> Vec<u32> {
    let Ok(entries) = std::fs::read_dir("/proc") else { return Vec::new() };
    entries
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
        .filter(|child| {
            // Field 4 of /proc/PID/stat, after the parenthesised command name.
            std::fs::read_to_string(format!("/proc/{child}/stat"))
                .ok()
                .and_then(|s| s.rsplit_once(')').map(|(_, rest)| rest.split_whitespace().nth(1).map(str::to_string)))
                .flatten()
                .and_then(|ppid| ppid.parse::<u32>().ok())
                == Some(pid)
        })
        .collect()
}

/// SIGKILL a process by id.
pub fn kill_pid(pid: u32) {
    signal_pid(pid, "KILL");
}

/// Send the signal `name` (`STOP`, `CONT`, …) to a process, if it is still there.
pub fn signal_pid(pid: u32, name: &str) {
    let _ = Command::new("kill").args([&format!("-{name}"), &pid.to_string()]).status();
}

/// A field of /proc/PID/status in bytes (VmRSS, VmHWM).
pub fn status_bytes(pid: u32, field: &str) -> u64 {
    let text = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("read /proc status");
    let kib: u64 = text
        .lines()
        .find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or_else(|| panic!("{field} in /proc/{pid}/status"));
    kib * 1024
}

/// Start measuring a process's peak resident memory from now (writing 5 to clear_refs resets
/// VmHWM to VmRSS); returns VmRSS now.
pub fn reset_peak_rss(pid: u32) -> u64 {
    std::fs::write(format!("/proc/{pid}/clear_refs"), "5").expect("reset the peak RSS");
    status_bytes(pid, "VmRSS")
}

/// A CPU hog: `per_core` spinning shells per core, each in a session of its own (where the
/// kernel shares the cores between sessions first, each counts as a program of its own, as on
/// a machine shared with other services); killed when dropped.
pub struct CpuHog(Vec<Child>);

impl CpuHog {
    pub fn start(per_core: usize) -> Self {
        use std::os::unix::process::CommandExt;
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        let spinners = (0..per_core * cores)
            .map(|_| {
                let mut command = Command::new("sh");
                command.args(["-c", "while :; do :; done"]).stdout(Stdio::null());
                // SAFETY: setsid is async-signal-safe and touches only the child.
                unsafe {
                    command.pre_exec(|| {
                        libc::setsid();
                        Ok(())
                    });
                }
                command.spawn().expect("sh")
            })
            .collect();
        Self(spinners)
    }
}

impl Drop for CpuHog {
    fn drop(&mut self) {
        for child in &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}
