//! Sending PostgreSQL notices from a connection of their own, after the data they announce
//! has committed, several ids to a notice.
//!
//! Why not `NOTIFY` inside the transaction that writes the data: a committing transaction that
//! notified holds one database-wide lock until its commit is flushed, so every notifying
//! commit in every process waits for the one before it. Under load (a progress event per job
//! and stage, a submission that must reach the disk) that queue was most of the submissions'
//! p99: sampled from `pg_stat_activity`, the waits were mostly `Lock:object` on the event
//! inserts, finishes and submissions. Here each process sends the ids gathered while its last
//! notice went out in one statement, committed without waiting for the disk (a notice need
//! not outlive a crash: listeners read the tables again after a reconnect, and look anyway
//! every `NOTICE_FALLBACK`).

use std::collections::BTreeSet;
use std::sync::mpsc;

use parking_lot::Mutex;
use postgres::{Client, NoTls};

/// Largest payload PostgreSQL takes is 8000 bytes; stay clear of it.
const PAYLOAD_BYTES: usize = 7000;
/// Separates the ids in a payload (ids never hold one).
pub(super) const SEPARATOR: char = ',';
/// Most notices taken into one statement.
const BATCH: usize = 4096;

/// Hands notices to a sending thread, started when the first one is sent; the thread ends
/// with the store.
pub(super) struct Notifier {
    url: String,
    tx: Mutex<Option<mpsc::Sender<(&'static str, String)>>>,
}

impl Notifier {
    pub fn new(url: &str) -> Self {
        Self { url: url.to_string(), tx: Mutex::new(None) }
    }

    /// Announce `job_id` on `channel` to every listener; call it after the commit.
    pub fn send(&self, channel: &'static str, job_id: &str) {
        let mut tx = self.tx.lock();
        let sender = tx.get_or_insert_with(|| spawn(self.url.clone()));
        if sender.send((channel, job_id.to_string())).is_err() {
            // The thread is gone (it could not start): notices fall back to the listeners' looks.
            tracing::warn!("the notice sender has stopped");
        }
    }
}

fn spawn(url: String) -> mpsc::Sender<(&'static str, String)> {
    let (tx, rx) = mpsc::channel();
    let started = std::thread::Builder::new().name("landform-notify".into()).spawn(move || run(&url, &rx));
    if let Err(e) = started {
        tracing::error!(error = %e, "could not start the notice sender; listeners will poll");
    }
    tx
}

fn run(url: &str, rx: &mpsc::Receiver<(&'static str, String)>) {
    let mut client: Option<Client> = None;
    while let Ok(first) = rx.recv() {
        let mut batch = vec![first];
        while batch.len() < BATCH {
            match rx.try_recv() {
                Ok(n) => batch.push(n),
                Err(_) => break,
            }
        }
        let (channels, payloads) = pack(batch);
        // One retry on a fresh connection: the database may have restarted since the last one.
        for _ in 0..2 {
            if client.is_none() {
                client = connect(url);
            }
            let Some(c) = client.as_mut() else { break };
            let sent = c.execute(
                "SELECT pg_notify(c, p) FROM unnest($1::text[], $2::text[]) AS n(c, p)",
                &[&channels, &payloads],
            );
            match sent {
                Ok(_) => break,
                Err(e) => {
                    tracing::warn!(error = %e, "could not send notices");
                    client = None;
                }
            }
        }
    }
}

fn connect(url: &str) -> Option<Client> {
    let connected = Client::connect(url, NoTls).and_then(|mut c| {
        c.batch_execute("SET synchronous_commit = off")?;
        Ok(c)
    });
    connected.map_err(|e| tracing::warn!(error = %e, "the notice sender cannot connect")).ok()
}

/// Notices as (channels, payloads): each channel's ids once, in order, joined up to the
/// payload limit.
fn pack(batch: Vec<(&'static str, String)>) -> (Vec<String>, Vec<String>) {
    let ids: BTreeSet<(&str, String)> = batch.into_iter().collect();
    let (mut channels, mut payloads) = (Vec::new(), Vec::<String>::new());
    for (channel, id) in ids {
        match (channels.last(), payloads.last_mut()) {
            (Some(c), Some(p)) if c == channel && p.len() + 1 + id.len() <= PAYLOAD_BYTES => {
                p.push(SEPARATOR);
                p.push_str(&id);
            }
            _ => {
                channels.push(channel.to_string());
                payloads.push(id);
            }
        }
    }
    (channels, payloads)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_packed_per_channel_once_each_and_within_the_payload_limit() {
        let mut batch = vec![("b", "x".to_string()), ("a", "y".to_string()), ("b", "x".to_string())];
        let (c, p) = pack(batch.clone());
        assert_eq!((c, p), (vec!["a".to_string(), "b".into()], vec!["y".to_string(), "x".into()]));

        // 2000 ids of 26 characters: 27 bytes each with the separator, 259 to a payload.
        batch = (0..2000).map(|k| ("e", format!("{k:026}"))).collect();
        let (c, p) = pack(batch);
        assert!(c.iter().all(|c| c == "e"));
        assert!(p.iter().all(|p| p.len() <= PAYLOAD_BYTES), "{:?}", p.iter().map(String::len).collect::<Vec<_>>());
        // 26 + 27 × 258 = 6992 ≤ 7000 < 7019.
        assert_eq!(p[0].split(SEPARATOR).count(), 259);
        assert_eq!(p.len(), 8);
        let back: Vec<&str> = p.iter().flat_map(|p| p.split(SEPARATOR)).collect();
        assert_eq!(back, (0..2000).map(|k| format!("{k:026}")).collect::<Vec<_>>());
    }
}
