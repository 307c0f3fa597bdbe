//! `landform serve`'s worker: a child process (`landform worker`) that runs the jobs, so a job
//! that brings its process down (an abort, the out-of-memory killer, a SIGKILL) takes only the
//! worker with it. The API process starts it again at once (backing off while it keeps dying),
//! and the job is retried by the lease rules. The child holds a pipe from this process on its
//! standard input: when this process dies, the pipe closes and the child gives its jobs back
//! and exits, so no worker outlives its API.

use std::process::Stdio;
use std::time::{Duration, Instant};

use tokio::sync::watch;
use tokio::task::JoinHandle;

/// Waits before restarting a worker that died, doubling while it keeps dying young.
const FIRST_BACKOFF: Duration = Duration::from_millis(200);
const MAX_BACKOFF: Duration = Duration::from_secs(10);
/// A worker that lived this long died of something new: restart it at once.
const HEALTHY_AFTER: Duration = Duration::from_secs(30);

pub struct Supervisor {
    stop: watch::Sender<bool>,
    task: JoinHandle<()>,
}

impl Supervisor {
    /// Start `landform worker ARGS…` (this same executable) and keep one running.
    pub fn spawn(args: Vec<String>) -> std::io::Result<Self> {
        let exe = std::env::current_exe()?;
        let (stop, stopped) = watch::channel(false);
        let task = tokio::spawn(supervise(exe, args, stopped));
        Ok(Supervisor { stop, task })
    }

    /// SIGTERM the worker and wait until it has exited (it drains within its shutdown
    /// deadline: running jobs finish or go back to the queue).
    pub async fn stop(self) {
        let _ = self.stop.send(true);
        let _ = self.task.await;
    }
}

async fn supervise(exe: std::path::PathBuf, args: Vec<String>, mut stopped: watch::Receiver<bool>) {
    let mut backoff = FIRST_BACKOFF;
    while !*stopped.borrow() {
        let started = Instant::now();
        let spawned = tokio::process::Command::new(&exe)
            .arg("worker")
            .args(&args)
            .arg("--exit-with-parent")
            .stdin(Stdio::piped())
            // The API's standard output is its own (it prints the address it bound).
            .stdout(Stdio::null())
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
        tracing::info!(pid = child.id(), "worker process started");
        tokio::select! {
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
