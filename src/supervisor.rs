//! `landform serve`'s worker: a child process (`landform worker`) that runs the jobs, so a job
//! that brings its process down (an abort, the out-of-memory killer, a SIGKILL) takes only the
//! worker with it. The API process starts it again at once (backing off while it keeps dying),
//! and the job is retried by the lease rules. The child holds a pipe from this process on its
//! standard input: when this process dies, the pipe closes and the child gives its jobs back
//! and exits, so no worker outlives its API.
//!
//! The child in turn writes a byte to its standard output every quarter lease (from its async
//! runtime, the one that renews its leases). A child silent for a whole lease — stopped
//! (SIGSTOP), wedged — is killed and replaced: on the embedded store a process frozen inside a
//! write transaction holds SQLite's only write lock, and every writer (this API's submissions
//! too) would wait for it for as long as it stays frozen.
//!
//! Silence alone does not tell a hung worker from a busy one on a loaded machine: a worker at
//! nice 10 beside a load of 18 gets well under 1 % of the cores, and its runtime can miss a
//! lease's worth of beats while its job is computing (measured: three healthy workers killed
//! in a row). So a silent worker whose CPU time still grows (`/proc/PID/stat`) is given more
//! time, up to [`BUSY_GRACE_WINDOWS`] silences; one that is stopped or blocked uses no CPU and
//! is killed at the first.

use std::process::Stdio;
use std::time::{Duration, Instant};

use tokio::io::AsyncReadExt;
use tokio::sync::watch;
use tokio::task::JoinHandle;

/// Waits before restarting a worker that died, doubling while it keeps dying young.
const FIRST_BACKOFF: Duration = Duration::from_millis(200);
const MAX_BACKOFF: Duration = Duration::from_secs(10);
/// A worker that lived this long died of something new: restart it at once.
const HEALTHY_AFTER: Duration = Duration::from_secs(30);

/// How often a supervised worker says it is alive, for a lease of this length.
pub fn heartbeat_interval(lease: Duration) -> Duration {
    lease / 4
}

/// How long a supervised worker may stay silent before it is killed: its lease, by which time
/// its claims have lapsed anyway (four beats missed), and never less than this floor, so a busy
/// machine's scheduling delays are not taken for a hang. Shorter than the embedded store's
/// wait for its lock, so a write of the API's that a frozen worker holds up goes through once
/// the worker is killed.
fn watchdog_timeout(lease: Duration) -> Duration {
    lease.max(WATCHDOG_FLOOR)
}
const WATCHDOG_FLOOR: Duration = Duration::from_secs(3);
/// Silences in a row a worker that keeps using CPU may stay silent before it is killed all
/// the same (2 minutes at the default lease): a runtime wedged while the job's threads spin.
pub const BUSY_GRACE_WINDOWS: u32 = 24;

pub struct Supervisor {
    stop: watch::Sender<bool>,
    task: JoinHandle<()>,
}

impl Supervisor {
    /// Start `landform worker ARGS…` (this same executable) and keep one running; `lease` is
    /// the worker's lease, which sets its heartbeat.
    pub fn spawn(args: Vec<String>, lease: Duration) -> std::io::Result<Self> {
        let exe = std::env::current_exe()?;
        let (stop, stopped) = watch::channel(false);
        let task = tokio::spawn(supervise(exe, args, watchdog_timeout(lease), stopped));
        Ok(Supervisor { stop, task })
    }

    /// SIGTERM the worker and wait until it has exited (it drains within its shutdown
    /// deadline: running jobs finish or go back to the queue).
    pub async fn stop(self) {
        let _ = self.stop.send(true);
        let _ = self.task.await;
    }
}

async fn supervise(exe: std::path::PathBuf, args: Vec<String>, silence: Duration, mut stopped: watch::Receiver<bool>) {
    let mut backoff = FIRST_BACKOFF;
    while !*stopped.borrow() {
        let started = Instant::now();
        let spawned = tokio::process::Command::new(&exe)
            .arg("worker")
            .args(&args)
            .arg("--exit-with-parent")
            .stdin(Stdio::piped())
            // The child's heartbeat; the API's own standard output stays its own (it prints
            // the address it bound).
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn();
        let mut child = match spawned {
            Ok(child) => child,
            Err(e) => {
                tracing::error!(error = %e, "could not start the worker process");
                tokio::time::sleep(MAX_BACKOFF).await;
                continue;
            }
        };
        // Held, never written: it closes when this process ends, however it ends.
        let _parent_alive = child.stdin.take();
        let heartbeat = child.stdout.take();
        tracing::info!(pid = child.id(), "worker process started");
        tokio::select! {
            () = silent_for(heartbeat, silence, child.id()) => {
                tracing::error!(pid = child.id(), ?silence, "the worker process stopped answering; killing it");
                // SIGKILL ends a stopped process too; the next turn of the loop reaps it.
                let _ = child.start_kill();
                let status = child.wait().await;
                tracing::error!(?status, "the silent worker process is gone; starting another");
            }
            status = child.wait() => {
                tracing::error!(?status, "the worker process stopped; starting another");
                backoff = if started.elapsed() > HEALTHY_AFTER { FIRST_BACKOFF } else { (backoff * 2).min(MAX_BACKOFF) };
                tokio::select! {
                    _ = tokio::time::sleep(backoff) => {}
                    _ = stopped.changed() => {}
                }
            }
            _ = stopped.changed() => {
                if let Some(pid) = child.id().and_then(|p| i32::try_from(p).ok()) {
                    // SAFETY: kill(2) on our own child's pid; it is not reaped until the wait
                    // below, so the pid cannot have been reused.
                    unsafe { libc::kill(pid, libc::SIGTERM) };
                }
                let status = child.wait().await;
                tracing::info!(?status, "worker process stopped");
                return;
            }
        }
    }
}

/// Resolves once `heartbeat` has been silent for `silence` while still open and the process
/// `pid` used no CPU meanwhile (or stayed silent for [`BUSY_GRACE_WINDOWS`] silences while
/// busy). A closed pipe (the child exited) is the wait's to report, so that never resolves.
async fn silent_for(heartbeat: Option<tokio::process::ChildStdout>, silence: Duration, pid: Option<u32>) {
    let Some(mut heartbeat) = heartbeat else { return std::future::pending().await };
    let mut buf = [0u8; 256];
    let mut busy_windows = 0;
    let mut cpu = pid.and_then(cpu_time);
    loop {
        match tokio::time::timeout(silence, heartbeat.read(&mut buf)).await {
            Err(_elapsed) => {
                let now = pid.and_then(cpu_time);
                let working = used_cpu(cpu, now);
                cpu = now;
                busy_windows += 1;
                if !working || busy_windows >= BUSY_GRACE_WINDOWS {
                    return;
                }
                tracing::warn!(?pid, ?silence, "the worker process is silent but busy (its CPU time grows): waiting");
            }
            Ok(Ok(n)) if n > 0 => {
                busy_windows = 0;
                cpu = pid.and_then(cpu_time);
            }
            Ok(_closed) => return std::future::pending().await,
        }
    }
}

/// A process's CPU time so far: (clock ticks of user + system time of all its threads, from
/// `/proc/PID/stat`; nanoseconds its live threads have run, from their `schedstat`). The
/// nanoseconds see the few milliseconds a nice-10 worker gets under a heavy load, which may not
/// reach a tick in a window; the ticks keep what threads that ended had used. `None` when it
/// cannot be read (no /proc, or the process is gone).
fn cpu_time(pid: u32) -> Option<(u64, u64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the parenthesised command name: state is the 3rd field, utime the 14th.
    let mut fields = stat.rsplit_once(')')?.1.split_whitespace().skip(11);
    let utime: u64 = fields.next()?.parse().ok()?;
    let stime: u64 = fields.next()?.parse().ok()?;
    let nanos = std::fs::read_dir(format!("/proc/{pid}/task"))
        .into_iter()
        .flatten()
        .filter_map(|task| std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok())
        .filter_map(|line| line.split_whitespace().next()?.parse::<u64>().ok())
        .sum();
    Some((utime + stime, nanos))
}

/// Whether a process used CPU between two readings of [`cpu_time`].
fn used_cpu(before: Option<(u64, u64)>, after: Option<(u64, u64)>) -> bool {
    matches!((before, after), (Some((t0, n0)), Some((t1, n1))) if t1 > t0 || n1 > n0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A child that writes nothing on its standard output: busy spinning, or idle sleeping.
    fn silent_child(script: &str) -> tokio::process::Child {
        niced_child(script, 0)
    }

    /// `sh -c script` in a session of its own (where the kernel shares the cores between
    /// sessions first, each program gets its own share, as a worker does), at nice `nice`.
    fn niced_child(script: &str, nice: i32) -> tokio::process::Child {
        let mut command = tokio::process::Command::new("sh");
        command.args(["-c", script]).stdout(Stdio::piped()).kill_on_drop(true);
        // SAFETY: setsid and setpriority are async-signal-safe and touch only the child.
        unsafe {
            command.pre_exec(move || {
                libc::setsid();
                libc::setpriority(libc::PRIO_PROCESS, 0, nice);
                Ok(())
            });
        }
        command.spawn().expect("sh")
    }

    #[tokio::test]
    async fn a_silent_busy_process_is_waited_for_and_a_silent_idle_one_is_not() {
        let silence = Duration::from_millis(300);
        // Spinning: its CPU time grows at every look, so several silences pass without a verdict.
        let mut busy = silent_child("while :; do :; done");
        let pid = busy.id();
        let waited =
            tokio::time::timeout(Duration::from_millis(1500), silent_for(busy.stdout.take(), silence, pid)).await;
        assert!(waited.is_err(), "a busy process was taken for a hung one");
        // Sleeping (as a stopped or deadlocked worker would): killed at the first silence.
        let mut idle = silent_child("sleep 30");
        let pid = idle.id();
        let started = Instant::now();
        let waited = tokio::time::timeout(Duration::from_secs(5), silent_for(idle.stdout.take(), silence, pid)).await;
        assert!(waited.is_ok(), "an idle silent process was never judged silent");
        assert!(started.elapsed() < Duration::from_secs(2), "judged after {:?}", started.elapsed());
    }

    #[tokio::test]
    async fn a_busy_process_silent_past_the_grace_is_judged_silent_all_the_same() {
        let silence = Duration::from_millis(50);
        let mut busy = silent_child("while :; do :; done");
        let pid = busy.id();
        // BUSY_GRACE_WINDOWS silences at the most (with a margin for a loaded machine).
        let waited =
            tokio::time::timeout(silence * BUSY_GRACE_WINDOWS * 4, silent_for(busy.stdout.take(), silence, pid)).await;
        assert!(waited.is_ok(), "a process silent for good was never judged");
    }

    /// The case the grace is for: a worker at nice 10 computing beside a load of several
    /// programs per core (16 spinning processes on 2 cores, each in a session of its own) gets
    /// well under 1 % of the cores, yet its CPU time grows at every look, so it is waited for;
    /// a stopped worker under the same load uses none and is judged at the first silence.
    #[tokio::test]
    async fn under_a_cpu_hog_a_busy_nice_worker_is_waited_for_and_a_stopped_one_is_not() {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        let _hog: Vec<_> = (0..8 * cores).map(|_| niced_child("while :; do :; done", 0)).collect();
        let silence = Duration::from_millis(1000);
        let mut busy = niced_child("while :; do :; done", 10);
        let pid = busy.id();
        let waited = tokio::time::timeout(silence * 5, silent_for(busy.stdout.take(), silence, pid)).await;
        assert!(waited.is_err(), "a busy worker under a CPU hog was taken for a hung one");
        let mut stopped = niced_child("while :; do :; done", 10);
        let pid = stopped.id();
        unsafe { libc::kill(pid.expect("pid") as i32, libc::SIGSTOP) };
        let started = Instant::now();
        let waited = tokio::time::timeout(silence * 5, silent_for(stopped.stdout.take(), silence, pid)).await;
        assert!(waited.is_ok(), "a stopped worker under a CPU hog was never judged silent");
        assert!(started.elapsed() < silence * 3, "judged after {:?}", started.elapsed());
    }
}
