//! PostgreSQL's LISTEN/NOTIFY on a connection of its own: a thread listens on the two
//! channels the store notifies (`landform_jobs` when a job is queued, `landform_events` when a
//! job has new events or ends; payloads are job ids only, several to a notice: see notifier.rs) and passes each notice on to every
//! waiter in this process. When the connection drops it connects again and says
//! `Reconnected`, since notices sent meanwhile are lost: waiters then read the tables afresh.

use std::time::Duration;

use postgres::fallible_iterator::FallibleIterator;
use postgres::{Client, NoTls};
use tokio::sync::broadcast;

use super::notifier::SEPARATOR;
use super::Notice;

pub(super) const JOBS_CHANNEL: &str = "landform_jobs";
pub(super) const EVENTS_CHANNEL: &str = "landform_events";
/// How long the listener waits between attempts to connect again.
const RECONNECT_AFTER: Duration = Duration::from_secs(1);

/// Start listening; notices go to `tx` for as long as anyone may subscribe to it.
pub(super) fn spawn(url: String, tx: broadcast::Sender<Notice>) {
    let spawned = std::thread::Builder::new().name("landform-listen".into()).spawn(move || loop {
        match Client::connect(&url, NoTls) {
            Ok(client) => listen(client, &tx),
            Err(e) => tracing::warn!(error = %e, "the notification listener cannot connect"),
        }
        std::thread::sleep(RECONNECT_AFTER);
    });
    if let Err(e) = spawned {
        tracing::error!(error = %e, "could not start the notification listener; waiters will poll");
    }
}

/// Listen on one connection until it fails.
fn listen(mut client: Client, tx: &broadcast::Sender<Notice>) {
    if let Err(e) = client.batch_execute(&format!("LISTEN {JOBS_CHANNEL}; LISTEN {EVENTS_CHANNEL}")) {
        tracing::warn!(error = %e, "LISTEN failed");
        return;
    }
    let _ = tx.send(Notice::Reconnected);
    loop {
        if let Err(e) = pass_on(&mut client, tx) {
            tracing::warn!(error = %e, "the notification connection failed; connecting again");
            return;
        }
        if client.is_closed() {
            tracing::warn!("the notification connection closed; connecting again");
            return;
        }
    }
}

/// Pass on the notifications that arrive within a second.
fn pass_on(client: &mut Client, tx: &broadcast::Sender<Notice>) -> Result<(), postgres::Error> {
    let mut notifications = client.notifications();
    let mut pending = notifications.timeout_iter(Duration::from_secs(1));
    while let Some(n) = pending.next()? {
        for id in n.payload().split(SEPARATOR).map(str::to_string) {
            let notice = if n.channel() == JOBS_CHANNEL { Notice::Queued(id) } else { Notice::Changed(id) };
            let _ = tx.send(notice);
        }
    }
    Ok(())
}
