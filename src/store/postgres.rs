//! The job store on PostgreSQL, for many processes on many machines: the same tables as the
//! embedded store (migrated at start-up by refinery, under an advisory lock so replicas
//! starting together migrate once), a few connections used in turn, and every multi-statement
//! write in one transaction. Unique keys decide races between replicas: an idempotency key is
//! inserted with `ON CONFLICT DO NOTHING`, and the loser reads the winner's job.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use parking_lot::{Mutex, MutexGuard};
use postgres::types::ToSql;
use postgres::{Client, NoTls, Row};
use tokio::sync::broadcast;

use super::artifacts::{assemble, chunks, span, StoredArtifact, STORED_ARTIFACT};
use super::events::{event_id, EventLog, Notice, StoredEvent};
use super::listener::{self, EVENTS_CHANNEL, JOBS_CHANNEL};
use super::notifier::Notifier;
use super::objects::{object_range, ObjectArtifacts};
use super::pg_conn::{Conn, Sql, Tx};
use super::queue::{count, lease_ms, Claim, JobQueue, Renewal};
use super::row::{describe, summary_columns, timestamp, JobRow, RawJob, JOB_COLUMNS};
use super::{ArtifactStore, IdempotentInsert, JobInputs, JobStore, ListFilter, StoreError, CHUNK_BYTES};
use crate::export::Artifact;
use crate::model::{ArtifactMeta, Job, JobStatus};

mod embedded {
    refinery::embed_migrations!("migrations/postgres");
}

/// Connections opened per store: a reader or writer each, used in turn.
const CONNECTIONS: usize = 8;
/// Any constant: replicas starting at once take this lock to migrate one after another.
const MIGRATION_LOCK: i64 = 0x4c41_4e44_464f_524d; // "LANDFORM"

pub struct PostgresStore {
    clients: Vec<Mutex<Conn>>,
    next: AtomicUsize,
    url: String,
    /// The listener's fan-out, once anyone in this process has asked for notices.
    notices: Mutex<Option<broadcast::Sender<Notice>>>,
    /// Sends this process's notices, after the commits they announce.
    notifier: Notifier,
    /// Where new artifacts' bytes go when not into the database.
    objects: Option<ObjectArtifacts>,
}

impl std::fmt::Debug for PostgresStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PostgresStore").field("connections", &self.clients.len()).finish_non_exhaustive()
    }
}

fn db(e: postgres::Error) -> StoreError {
    // A value a column can't be read as is a damaged row; the rest is the database's trouble.
    if e.as_db_error().is_none() && e.to_string().contains("error deserializing") {
        StoreError::Corrupt(e.to_string())
    } else {
        StoreError::Backend(e.to_string())
    }
}

fn migration(e: refinery::Error) -> StoreError {
    StoreError::Backend(format!("migrating the schema: {e}"))
}

impl PostgresStore {
    /// Connect to `url` (`postgres://user@host:port/db`, with `?options=-csearch_path%3D…` for a
    /// schema of its own) and bring the schema up to date.
    pub fn open(url: &str) -> Result<Self, StoreError> {
        let connect = || Client::connect(url, NoTls).map_err(|e| StoreError::Backend(format!("cannot connect: {e}")));
        let mut first = connect()?;
        first.execute("SELECT pg_advisory_lock($1)", &[&MIGRATION_LOCK]).map_err(db)?;
        let migrated = embedded::migrations::runner().run(&mut first).map_err(migration);
        first.execute("SELECT pg_advisory_unlock($1)", &[&MIGRATION_LOCK]).map_err(db)?;
        migrated?;
        let mut clients = vec![Mutex::new(Conn::new(first))];
        for _ in 1..CONNECTIONS {
            clients.push(Mutex::new(Conn::new(connect()?)));
        }
        Ok(Self {
            clients,
            next: AtomicUsize::new(0),
            url: url.to_string(),
            notices: Mutex::new(None),
            notifier: Notifier::new(url),
            objects: None,
        })
    }

    /// Commit without waiting for the disk (`synchronous_commit = off`), for a worker: all it
    /// writes can be redone — if the database crashes, a claim, event or result of the last
    /// moments may be lost, and the job is claimed again by the lease rules and recomputed to
    /// the same bytes — while an API replica's commits (accepted jobs) stay durable. Measured:
    /// see loadtests/README.md.
    pub fn with_relaxed_commits(self) -> Result<Self, StoreError> {
        for c in &self.clients {
            c.lock().batch_execute("SET synchronous_commit = off").map_err(db)?;
        }
        Ok(self)
    }

    /// Keep the bytes of artifacts finished from now on in `objects`, when given (the rows
    /// stay here).
    pub fn with_objects(mut self, objects: Option<ObjectArtifacts>) -> Self {
        self.objects = objects;
        self
    }

    /// Tell listeners that `job` ended, when it has.
    fn ended(&self, job: &Job) {
        if job.status.is_terminal() {
            self.notifier.send(EVENTS_CHANNEL, &job.id);
        }
    }

    /// Save the mutable columns and tell listeners when the job ended; false if nothing was
    /// written.
    fn update_announced(&self, row: &JobRow) -> Result<bool, StoreError> {
        let written = update_row(&mut *self.client(), row)?;
        if written {
            self.ended(row.job);
        }
        Ok(written)
    }

    fn remove_objects(&self, keys: &[String]) {
        if let Some(o) = &self.objects {
            o.remove(keys);
        }
    }

    /// Save a finished job's row and its artifacts in one transaction; false when nothing
    /// was written (no such job, or the row's fence is no longer the job's attempt).
    fn finish_row(&self, row: JobRow<'_>, artifacts: &[Artifact]) -> Result<bool, StoreError> {
        let job = row.job;
        let metas = describe(artifacts)?;
        // Objects first, outside the transaction; removed again if it does not commit.
        let placed = self.objects.as_ref().map(|o| o.put_all(&job.id, artifacts)).transpose()?;
        let mut client = self.client();
        let mut tx = client.transaction().map_err(db)?;
        if !update_row(&mut tx, &row)? {
            return Ok(false);
        }
        let replaced = object_keys(&mut tx, &job.id)?;
        // The job's chunks go with its artifact rows (ON DELETE CASCADE).
        tx.execute("DELETE FROM artifacts WHERE job_id = $1", &[&job.id]).map_err(db)?;
        let artifact =
            "INSERT INTO artifacts (job_id, name, ordinal, media_type, bytes, sha256, chunk_bytes, object_key) \
                        VALUES ($1, $2, $3, $4, $5, $6, $7, $8)";
        let chunk = "INSERT INTO artifact_chunks (job_id, name, seq, data) VALUES ($1, $2, $3, $4)";
        let chunk_bytes = CHUNK_BYTES as i64;
        for (ordinal, (a, m)) in artifacts.iter().zip(&metas).enumerate() {
            let (ordinal, bytes) = (ordinal as i32, a.bytes.len() as i64);
            let key = placed.as_ref().map(|p| p.keys[ordinal as usize].as_str());
            tx.execute(artifact, &[&job.id, &m.name, &ordinal, &m.media_type, &bytes, &m.sha256, &chunk_bytes, &key])
                .map_err(db)?;
            if key.is_none() {
                for (seq, data) in chunks(&a.bytes) {
                    tx.execute(chunk, &[&job.id, &m.name, &(seq as i32), &data]).map_err(db)?;
                }
            }
        }
        tx.commit().map_err(db)?;
        drop(client);
        self.ended(job);
        if let Some(p) = placed {
            p.keep();
        }
        self.remove_objects(&replaced);
        Ok(true)
    }

    /// A free connection if there is one, else the next in turn.
    fn client(&self) -> MutexGuard<'_, Conn> {
        let n = self.clients.len();
        let start = self.next.fetch_add(1, Ordering::Relaxed);
        for k in 0..n {
            if let Some(c) = self.clients[(start + k) % n].try_lock() {
                return c;
            }
        }
        self.clients[start % n].lock()
    }
}

fn raw_job(row: &Row) -> Result<RawJob, StoreError> {
    let get = |i: usize| -> Result<Option<String>, StoreError> { row.try_get(i).map_err(db) };
    let need = |i: usize, name: &str| -> Result<String, StoreError> {
        get(i)?.ok_or_else(|| StoreError::Corrupt(format!("a job row has no {name}")))
    };
    Ok(RawJob {
        id: need(0, "id")?,
        kind: need(1, "kind")?,
        status: need(2, "status")?,
        label: get(3)?,
        created_at: need(4, "created_at")?,
        started_at: get(5)?,
        finished_at: get(6)?,
        progress: need(7, "progress")?,
        request: need(8, "request")?,
        result: get(9)?,
        error: get(10)?,
        replay_of: get(11)?,
        replay_until_step: row.try_get(12).map_err(db)?,
        cost: get(13)?,
        owner: get(14)?,
    })
}

/// After the job columns: each job's artifacts' names, media types, sizes and hashes as arrays
/// in production order, so a job and its artifacts come in one statement (one round trip, one
/// snapshot).
const ARTIFACT_ARRAYS: &str = "a.names, a.media_types, a.sizes, a.sha256s FROM jobs LEFT JOIN LATERAL \
    (SELECT array_agg(name ORDER BY ordinal) AS names, array_agg(media_type ORDER BY ordinal) AS media_types, \
    array_agg(bytes ORDER BY ordinal) AS sizes, array_agg(sha256 ORDER BY ordinal) AS sha256s \
    FROM artifacts WHERE artifacts.job_id = jobs.id) a ON true";

/// The artifacts of a row read with `ARTIFACT_ARRAYS` after the 15 job columns.
fn artifact_metas(row: &Row, job_id: &str) -> Result<Vec<ArtifactMeta>, StoreError> {
    let names: Option<Vec<String>> = row.try_get(15).map_err(db)?;
    let types: Option<Vec<String>> = row.try_get(16).map_err(db)?;
    let sizes: Option<Vec<i64>> = row.try_get(17).map_err(db)?;
    let hashes: Option<Vec<String>> = row.try_get(18).map_err(db)?;
    let (names, types, sizes, hashes) =
        (names.unwrap_or_default(), types.unwrap_or_default(), sizes.unwrap_or_default(), hashes.unwrap_or_default());
    if types.len() != names.len() || sizes.len() != names.len() || hashes.len() != names.len() {
        return Err(StoreError::Corrupt(format!("job {job_id}: artifact rows of unequal length")));
    }
    names
        .into_iter()
        .zip(types)
        .zip(sizes)
        .zip(hashes)
        .map(|(((name, media_type), bytes), sha256)| {
            Ok(ArtifactMeta {
                media_type,
                bytes: u64::try_from(bytes)
                    .map_err(|_| StoreError::Corrupt(format!("job {job_id}: artifact {name}: size {bytes}")))?,
                sha256,
                href: String::new(),
                name,
            })
        })
        .collect()
}

fn load_jobs(c: &mut impl Sql, sql: &str, params: &[&(dyn ToSql + Sync)]) -> Result<Vec<Job>, StoreError> {
    let rows = c.query(sql, params).map_err(db)?;
    rows.iter()
        .map(|row| {
            let raw = raw_job(row)?;
            let artifacts = artifact_metas(row, &raw.id)?;
            raw.into_job(artifacts)
        })
        .collect()
}

fn load_job(c: &mut impl Sql, id: &str) -> Result<Option<Job>, StoreError> {
    Ok(load_jobs(c, &format!("SELECT {JOB_COLUMNS}, {ARTIFACT_ARRAYS} WHERE id = $1"), &[&id])?.pop())
}

/// Insert a job's row (announced by the caller after the commit).
fn insert_row(c: &mut impl Sql, row: &JobRow) -> Result<(), StoreError> {
    let j = row.job;
    let running = i32::from(j.status == JobStatus::Running);
    c.execute(
        "INSERT INTO jobs (id, kind, status, label, created_at, started_at, finished_at, progress, request, \
         result, error, replay_of, replay_until_step, attempts, cost, owner, memory_bytes) \
         VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16, $17)",
        &[
            &j.id,
            &j.kind,
            &j.status.as_str(),
            &j.label,
            &row.created_at,
            &row.started_at,
            &row.finished_at,
            &row.progress,
            &row.request,
            &row.result,
            &row.error,
            &j.replay_of,
            &row.replay_until_step,
            &running,
            &row.cost,
            &j.owner,
            &row.memory_bytes,
        ],
    )
    .map_err(db)?;
    Ok(())
}

/// Save the mutable columns; false if there is no such job.
fn update_row(c: &mut impl Sql, row: &JobRow) -> Result<bool, StoreError> {
    let j = row.job;
    // SET expressions see the row as it was, so `status` there is the previous status.
    let n = c
        .execute(
            "UPDATE jobs SET status = $2, label = $3, started_at = $4, finished_at = $5, progress = $6, \
             result = $7, error = $8, \
             attempts = attempts + CASE WHEN $2 = 'running' AND status <> 'running' THEN 1 ELSE 0 END, \
             lease_until = CASE WHEN $2 IN ('running', 'queued') THEN lease_until END \
             WHERE id = $1 AND ($9::bigint IS NULL OR attempts = $9)",
            &[
                &j.id,
                &j.status.as_str(),
                &j.label,
                &row.started_at,
                &row.finished_at,
                &row.progress,
                &row.result,
                &row.error,
                &row.fence,
            ],
        )
        .map_err(db)?;
    Ok(n > 0)
}

/// The object keys of a job's artifacts kept in an object store.
fn object_keys(c: &mut impl Sql, job_id: &str) -> Result<Vec<String>, StoreError> {
    let rows = c
        .query("SELECT object_key FROM artifacts WHERE job_id = $1 AND object_key IS NOT NULL", &[&job_id])
        .map_err(db)?;
    rows.iter().map(|r| r.try_get(0).map_err(db)).collect()
}

/// One read-only snapshot for an artifact's row and chunks: a job finished again meanwhile
/// can't mix its old and new chunks.
fn chunk_snapshot(client: &mut Conn) -> Result<Tx<'_>, StoreError> {
    client.snapshot().map_err(db)
}

fn artifact_row(tx: &mut Tx<'_>, id: &str, name: &str) -> Result<Option<StoredArtifact>, StoreError> {
    let sql = format!("{STORED_ARTIFACT} WHERE job_id = $1 AND name = $2");
    let Some(r) = tx.query_opt(&sql, &[&id, &name]).map_err(db)? else { return Ok(None) };
    Ok(Some(StoredArtifact {
        media_type: r.try_get(0).map_err(db)?,
        total: r.try_get(1).map_err(db)?,
        chunk: r.try_get(2).map_err(db)?,
        object_key: r.try_get(3).map_err(db)?,
    }))
}

impl ArtifactStore for PostgresStore {
    fn read_artifact(&self, id: &str, name: &str, offset: u64, len: usize) -> Result<Option<Vec<u8>>, StoreError> {
        let mut client = self.client();
        let mut tx = chunk_snapshot(&mut client)?;
        let Some(StoredArtifact { total, chunk, object_key, .. }) = artifact_row(&mut tx, id, name)? else {
            return Ok(None);
        };
        if let Some(key) = object_key {
            tx.commit().map_err(db)?;
            drop(client);
            return object_range(self.objects.as_ref(), &key, total, offset, len);
        }
        let Some(s) = span(total.max(0) as u64, chunk.max(0) as u64, offset, len)? else {
            return Ok(Some(Vec::new()));
        };
        let (first, last) = (s.first_seq as i32, s.last_seq as i32);
        let rows = tx
            .query(
                "SELECT data FROM artifact_chunks WHERE job_id = $1 AND name = $2 AND seq BETWEEN $3 AND $4 ORDER BY seq",
                &[&id, &name, &first, &last],
            )
            .map_err(db)?;
        let chunks = rows.iter().map(|r| r.try_get::<_, Vec<u8>>(0).map_err(db)).collect::<Result<Vec<_>, _>>()?;
        tx.commit().map_err(db)?;
        assemble(&s, chunks).map(Some)
    }

    fn artifact(&self, id: &str, name: &str) -> Result<Option<(String, Vec<u8>)>, StoreError> {
        let mut client = self.client();
        let mut tx = chunk_snapshot(&mut client)?;
        let Some(StoredArtifact { media_type, total, object_key, .. }) = artifact_row(&mut tx, id, name)? else {
            return Ok(None);
        };
        if let Some(key) = object_key {
            tx.commit().map_err(db)?;
            drop(client);
            let whole = object_range(self.objects.as_ref(), &key, total, 0, usize::MAX)?;
            return Ok(whole.map(|data| (media_type, data)));
        }
        let mut data = Vec::with_capacity(total.max(0) as usize);
        for r in tx
            .query("SELECT data FROM artifact_chunks WHERE job_id = $1 AND name = $2 ORDER BY seq", &[&id, &name])
            .map_err(db)?
        {
            data.extend_from_slice(r.try_get::<_, &[u8]>(0).map_err(db)?);
        }
        tx.commit().map_err(db)?;
        if data.len() as i64 != total {
            return Err(StoreError::Corrupt(format!("job {id}: artifact {name}: {} of {total} bytes", data.len())));
        }
        Ok(Some((media_type, data)))
    }
}

impl JobQueue for PostgresStore {
    fn claim(&self, worker: &str, lease: Duration, max_memory: u64) -> Result<Option<Claim>, StoreError> {
        let mut client = self.client();
        let mut tx = client.transaction().map_err(db)?;
        // SKIP LOCKED: replicas claiming at once each take a different job, none waits.
        let next = tx
            .query_opt(
                "SELECT id, memory_bytes FROM jobs \
                 WHERE status = 'queued' OR (status = 'running' AND lease_until < now()) \
                 ORDER BY id LIMIT 1 FOR UPDATE SKIP LOCKED",
                &[],
            )
            .map_err(db)?;
        let Some(next) = next else { return Ok(None) };
        let (id, memory): (String, i64) = (next.try_get(0).map_err(db)?, next.try_get(1).map_err(db)?);
        if u64::try_from(memory).unwrap_or(0) > max_memory {
            return Ok(None);
        }
        // SET expressions see the row as it was: `status` is the status before the claim.
        let row = tx
            .query_one(
                "UPDATE jobs SET lost_leases = lost_leases + CASE WHEN status = 'running' THEN 1 ELSE 0 END, \
                 status = 'running', attempts = attempts + 1, \
                 lease_until = now() + $2::bigint * interval '1 millisecond', lease_owner = $3 \
                 WHERE id = $1 RETURNING attempts, lost_leases",
                &[&id, &lease_ms(lease), &worker],
            )
            .map_err(db)?;
        let (attempt, lost): (i32, i32) = (row.try_get(0).map_err(db)?, row.try_get(1).map_err(db)?);
        let job = load_job(&mut tx, &id)?.ok_or_else(|| StoreError::Backend(format!("job {id} vanished")))?;
        tx.commit().map_err(db)?;
        Ok(Some(Claim {
            job,
            attempt: count("attempts", &id, attempt.into())?,
            lost_leases: count("lost_leases", &id, lost.into())?,
        }))
    }

    fn renew(&self, id: &str, attempt: u32, lease: Duration) -> Result<Renewal, StoreError> {
        let found = self
            .client()
            .query_opt(
                "UPDATE jobs SET lease_until = now() + $3::bigint * interval '1 millisecond' \
                 WHERE id = $1 AND attempts = $2::bigint AND status = 'running' RETURNING cancel_requested",
                &[&id, &i64::from(attempt), &lease_ms(lease)],
            )
            .map_err(db)?;
        found.map_or(Ok(Renewal::Lost), |r| Ok(Renewal::Held { cancel_requested: r.try_get(0).map_err(db)? }))
    }

    fn request_cancel(&self, id: &str) -> Result<bool, StoreError> {
        let n = self
            .client()
            .execute(
                "UPDATE jobs SET cancel_requested = true WHERE id = $1 AND status IN ('queued', 'running')",
                &[&id],
            )
            .map_err(db)?;
        Ok(n > 0)
    }

    fn cancel_requested(&self, id: &str) -> Result<bool, StoreError> {
        let found = self.client().query_opt("SELECT cancel_requested FROM jobs WHERE id = $1", &[&id]).map_err(db)?;
        found.map_or(Ok(false), |r| r.try_get(0).map_err(db))
    }

    fn release(&self, id: &str, attempt: u32) -> Result<bool, StoreError> {
        let mut client = self.client();
        let n = client
            .execute(
                "UPDATE jobs SET status = 'queued', lease_until = NULL, lease_owner = NULL \
                 WHERE id = $1 AND attempts = $2::bigint AND status = 'running'",
                &[&id, &i64::from(attempt)],
            )
            .map_err(db)?;
        drop(client);
        if n > 0 {
            self.notifier.send(JOBS_CHANNEL, id);
        }
        Ok(n > 0)
    }

    fn active(&self, owner: Option<&str>) -> Result<(u32, u64), StoreError> {
        let row = self
            .client()
            .query_one(
                "SELECT count(*), coalesce(sum(memory_bytes), 0)::bigint FROM jobs \
                 WHERE owner IS NOT DISTINCT FROM $1 AND status IN ('queued', 'running')",
                &[&owner],
            )
            .map_err(db)?;
        let (n, memory): (i64, i64) = (row.try_get(0).map_err(db)?, row.try_get(1).map_err(db)?);
        Ok((count("active jobs", "*", n)?, u64::try_from(memory).unwrap_or(0)))
    }

    fn reserved(&self) -> Result<u64, StoreError> {
        let row = self
            .client()
            .query_one("SELECT coalesce(sum(memory_bytes), 0)::bigint FROM jobs WHERE status = 'running'", &[])
            .map_err(db)?;
        Ok(u64::try_from(row.try_get::<_, i64>(0).map_err(db)?).unwrap_or(0))
    }

    fn ended_after(&self, after: chrono::DateTime<chrono::Utc>, limit: u32) -> Result<Vec<Job>, StoreError> {
        let sql = format!(
            "SELECT {JOB_COLUMNS}, {ARTIFACT_ARRAYS} WHERE finished_at > $1 AND status IN ('succeeded', 'failed', 'cancelled') \
             ORDER BY finished_at LIMIT $2"
        );
        load_jobs(&mut *self.client(), &sql, &[&timestamp(&after), &i64::from(limit)])
    }

    fn update_claimed(&self, job: &Job, attempt: u32) -> Result<bool, StoreError> {
        self.update_announced(&JobRow::encode(job)?.fenced(attempt))
    }

    fn finish_claimed(&self, job: &Job, attempt: u32, artifacts: &[Artifact]) -> Result<bool, StoreError> {
        self.finish_row(JobRow::encode(job)?.fenced(attempt), artifacts)
    }
}

/// Appends and snapshots under a claim: only while the claim is still the job's.
const HELD: &str = "EXISTS (SELECT 1 FROM jobs WHERE id = $1 AND attempts = $4::bigint AND status = 'running')";

impl EventLog for PostgresStore {
    fn notices(&self) -> Option<broadcast::Receiver<Notice>> {
        let mut notices = self.notices.lock();
        if let Some(tx) = notices.as_ref() {
            return Some(tx.subscribe());
        }
        // Subscribed before the listener starts, so its first `Reconnected` is heard.
        let (tx, rx) = broadcast::channel(1024);
        listener::spawn(self.url.clone(), tx.clone());
        *notices = Some(tx);
        Some(rx)
    }

    fn append_event(&self, job_id: &str, attempt: u32, event: &str, data: &str) -> Result<Option<u64>, StoreError> {
        let sql = format!("INSERT INTO job_events (job_id, event, data) SELECT $1, $2, $3 WHERE {HELD} RETURNING id");
        let found = self.client().query_opt(&sql, &[&job_id, &event, &data, &i64::from(attempt)]).map_err(db)?;
        let id = found.map(|r| event_id(r.try_get(0).map_err(db)?)).transpose()?;
        if id.is_some() {
            self.notifier.send(EVENTS_CHANNEL, job_id);
        }
        Ok(id)
    }

    fn events_after(&self, job_id: &str, after: u64, limit: u32) -> Result<Vec<StoredEvent>, StoreError> {
        let after = i64::try_from(after).unwrap_or(i64::MAX);
        let rows = self
            .client()
            .query(
                "SELECT id, event, data FROM job_events WHERE job_id = $1 AND id > $2 ORDER BY id LIMIT $3",
                &[&job_id, &after, &i64::from(limit)],
            )
            .map_err(db)?;
        rows.iter()
            .map(|r| {
                Ok(StoredEvent {
                    id: event_id(r.try_get(0).map_err(db)?)?,
                    event: r.try_get(1).map_err(db)?,
                    data: r.try_get(2).map_err(db)?,
                })
            })
            .collect()
    }

    fn last_event(&self, job_id: &str, event: &str) -> Result<Option<StoredEvent>, StoreError> {
        let found = self
            .client()
            .query_opt(
                "SELECT id, data FROM job_events WHERE job_id = $1 AND event = $2 ORDER BY id DESC LIMIT 1",
                &[&job_id, &event],
            )
            .map_err(db)?;
        found
            .map(|r| {
                Ok(StoredEvent {
                    id: event_id(r.try_get(0).map_err(db)?)?,
                    event: event.to_string(),
                    data: r.try_get(1).map_err(db)?,
                })
            })
            .transpose()
    }

    fn put_snapshot(&self, job_id: &str, attempt: u32, event: u64, png: &[u8]) -> Result<bool, StoreError> {
        let sql = format!(
            "INSERT INTO job_snapshots (job_id, event_id, png) SELECT $1, $2, $3 WHERE {HELD} \
             ON CONFLICT (job_id) DO UPDATE SET event_id = excluded.event_id, png = excluded.png"
        );
        let event = i64::try_from(event).unwrap_or(i64::MAX);
        let n = self.client().execute(&sql, &[&job_id, &event, &png, &i64::from(attempt)]).map_err(db)?;
        Ok(n > 0)
    }

    fn prune_ended(&self, ended_before: chrono::DateTime<chrono::Utc>) -> Result<u64, StoreError> {
        let before = timestamp(&ended_before);
        let mut client = self.client();
        let mut n = 0;
        for table in ["job_events", "job_snapshots"] {
            let sql = format!(
                "DELETE FROM {table} t WHERE EXISTS (SELECT 1 FROM jobs j WHERE j.id = t.job_id \
                 AND j.status IN ('succeeded', 'failed', 'cancelled') AND j.finished_at < $1)"
            );
            n += client.execute(&sql, &[&before]).map_err(db)?;
        }
        Ok(n)
    }

    fn snapshot(&self, job_id: &str) -> Result<Option<(u64, Vec<u8>)>, StoreError> {
        let found = self
            .client()
            .query_opt("SELECT event_id, png FROM job_snapshots WHERE job_id = $1", &[&job_id])
            .map_err(db)?;
        found.map(|r| Ok((event_id(r.try_get(0).map_err(db)?)?, r.try_get(1).map_err(db)?))).transpose()
    }
}

impl JobStore for PostgresStore {
    fn insert_with_inputs(
        &self,
        job: &Job,
        idempotency: Option<(&str, &str)>,
        inputs: JobInputs,
    ) -> Result<IdempotentInsert, StoreError> {
        let row = JobRow::encode(job)?;
        let mut client = self.client();
        let announce = || {
            if job.status == JobStatus::Queued {
                self.notifier.send(JOBS_CHANNEL, &job.id);
            }
        };
        let reads = inputs.all();
        if idempotency.is_none() && reads.is_empty() {
            insert_row(&mut *client, &row)?;
            drop(client);
            announce();
            return Ok(IdempotentInsert::Inserted);
        }
        let mut tx = client.transaction().map_err(db)?;
        insert_row(&mut tx, &row)?;
        for (sha256, data) in inputs.sent {
            let bytes = data.len() as i64;
            tx.execute(
                "INSERT INTO inputs (sha256, bytes, data) VALUES ($1, $2, $3) ON CONFLICT (sha256) DO NOTHING",
                &[sha256, &bytes, data],
            )
            .map_err(db)?;
        }
        for sha256 in &reads {
            tx.execute(
                "INSERT INTO job_inputs (job_id, sha256) VALUES ($1, $2) ON CONFLICT DO NOTHING",
                &[&job.id, sha256],
            )
            .map_err(db)?;
        }
        if let Some((key, body_sha256)) = idempotency {
            let claimed = tx
                .execute(
                    "INSERT INTO idempotency_keys (key, body_sha256, job_id) VALUES ($1, $2, $3) \
                     ON CONFLICT (key) DO NOTHING",
                    &[&key, &body_sha256, &job.id],
                )
                .map_err(db)?;
            if claimed == 0 {
                // Another request (here or on another replica) holds the key: undo ours and
                // answer with its job.
                tx.rollback().map_err(db)?;
                let found = client
                    .query_opt("SELECT body_sha256, job_id FROM idempotency_keys WHERE key = $1", &[&key])
                    .map_err(db)?;
                let (stored, job_id): (String, String) = match found {
                    Some(r) => (r.try_get(0).map_err(db)?, r.try_get(1).map_err(db)?),
                    None => return Err(StoreError::Backend(format!("idempotency key {key:?} vanished"))),
                };
                let job = load_job(&mut *client, &job_id)?.ok_or_else(|| {
                    StoreError::Corrupt(format!("idempotency key {key:?} names job {job_id}, which is missing"))
                })?;
                return Ok(IdempotentInsert::Existing {
                    job: Box::new(job),
                    same_body: stored.eq_ignore_ascii_case(body_sha256),
                });
            }
        }
        tx.commit().map_err(db)?;
        drop(client);
        announce();
        Ok(IdempotentInsert::Inserted)
    }

    fn get(&self, id: &str) -> Result<Option<Job>, StoreError> {
        load_job(&mut *self.client(), id)
    }

    fn get_summary(&self, id: &str) -> Result<Option<Job>, StoreError> {
        let sql = format!("SELECT {}, {ARTIFACT_ARRAYS} WHERE id = $1", summary_columns());
        Ok(load_jobs(&mut *self.client(), &sql, &[&id])?.pop())
    }

    /// Newest first. A `limit` of 0 means no limit.
    fn list(&self, filter: &ListFilter) -> Result<Vec<Job>, StoreError> {
        let status = filter.status.map(|s| s.as_str());
        let limit: Option<i64> = (filter.limit > 0).then(|| i64::from(filter.limit));
        // Summaries: a large request is not read (see `summary_columns`).
        let sql = format!(
            "SELECT {}, {ARTIFACT_ARRAYS} \
             WHERE ($1::text IS NULL OR kind = $1) AND ($2::text IS NULL OR status = $2) \
             AND ($3::text IS NULL OR owner = $3) AND ($4::text IS NULL OR id < $4) \
             AND (NOT $6 OR replay_of IS NULL) \
             ORDER BY id DESC LIMIT $5",
            summary_columns()
        );
        let jobs = load_jobs(
            &mut *self.client(),
            &sql,
            &[&filter.kind, &status, &filter.owner, &filter.before_id, &limit, &filter.no_replays],
        )?;
        Ok(jobs)
    }

    /// A job that no longer exists (deleted while it ran) is left deleted.
    fn update(&self, job: &Job) -> Result<(), StoreError> {
        self.update_announced(&JobRow::encode(job)?).map(|_| ())
    }

    /// Replaces any artifacts the job had. A job deleted meanwhile is left deleted.
    fn finish(&self, job: &Job, artifacts: &[Artifact]) -> Result<(), StoreError> {
        self.finish_row(JobRow::encode(job)?, artifacts).map(|_| ())
    }

    fn delete(&self, id: &str) -> Result<bool, StoreError> {
        let mut client = self.client();
        let mut tx = client.transaction().map_err(db)?;
        // The job's row locked first: a finish committing meanwhile can't slip objects past.
        tx.execute("SELECT 1 FROM jobs WHERE id = $1 FOR UPDATE", &[&id]).map_err(db)?;
        let objects = object_keys(&mut tx, id)?;
        let inputs: Vec<String> = tx
            .query("SELECT sha256 FROM job_inputs WHERE job_id = $1", &[&id])
            .map_err(db)?
            .iter()
            .map(|r| r.try_get(0).map_err(db))
            .collect::<Result<_, _>>()?;
        // Artifacts, idempotency keys and the job's inputs go with the job (ON DELETE CASCADE);
        // an upload no other job reads goes with it too.
        let n = tx.execute("DELETE FROM jobs WHERE id = $1", &[&id]).map_err(db)?;
        for sha256 in &inputs {
            tx.execute(
                "DELETE FROM inputs WHERE sha256 = $1 AND NOT EXISTS (SELECT 1 FROM job_inputs WHERE sha256 = $1)",
                &[sha256],
            )
            .map_err(db)?;
        }
        tx.commit().map_err(db)?;
        drop(client);
        self.remove_objects(&objects);
        Ok(n > 0)
    }

    fn unfinished(&self) -> Result<Vec<Job>, StoreError> {
        let sql =
            format!("SELECT {JOB_COLUMNS}, {ARTIFACT_ARRAYS} WHERE status IN ('queued', 'running') ORDER BY id ASC");
        load_jobs(&mut *self.client(), &sql, &[])
    }

    fn input(&self, sha256: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let found = self.client().query_opt("SELECT data FROM inputs WHERE sha256 = $1", &[&sha256]).map_err(db)?;
        found.map(|r| r.try_get(0).map_err(db)).transpose()
    }

    fn has_input(&self, sha256: &str, owner: Option<&str>) -> Result<bool, StoreError> {
        let found = self
            .client()
            .query_opt(
                "SELECT 1 FROM job_inputs JOIN jobs ON jobs.id = job_inputs.job_id \
                 WHERE job_inputs.sha256 = $1 AND jobs.owner IS NOT DISTINCT FROM $2 \
                 AND EXISTS (SELECT 1 FROM inputs WHERE inputs.sha256 = $1) LIMIT 1",
                &[&sha256, &owner],
            )
            .map_err(db)?;
        Ok(found.is_some())
    }

    fn status(&self, id: &str) -> Result<Option<(JobStatus, Option<String>)>, StoreError> {
        let found = self.client().query_opt("SELECT status, owner FROM jobs WHERE id = $1", &[&id]).map_err(db)?;
        found
            .map(|r| {
                let status: String = r.try_get(0).map_err(db)?;
                let owner: Option<String> = r.try_get(1).map_err(db)?;
                JobStatus::parse(&status)
                    .map(|s| (s, owner))
                    .ok_or_else(|| StoreError::Corrupt(format!("job {id}: unknown status {status:?}")))
            })
            .transpose()
    }

    fn attempts(&self, id: &str) -> Result<Option<u32>, StoreError> {
        let found = self.client().query_opt("SELECT attempts FROM jobs WHERE id = $1", &[&id]).map_err(db)?;
        found
            .map(|r| {
                let n: i32 = r.try_get(0).map_err(db)?;
                u32::try_from(n).map_err(|_| StoreError::Corrupt(format!("job {id}: attempts {n}")))
            })
            .transpose()
    }

    fn queued(&self) -> Result<u64, StoreError> {
        let n: i64 = self
            .client()
            .query_one("SELECT COUNT(*) FROM jobs WHERE status = 'queued'", &[])
            .map_err(db)?
            .try_get(0)
            .map_err(db)?;
        Ok(n.max(0) as u64)
    }

    fn counts(&self) -> Result<Vec<(String, JobStatus, u64)>, StoreError> {
        let rows = self
            .client()
            .query("SELECT kind, status, COUNT(*) FROM jobs GROUP BY kind, status ORDER BY kind, status", &[])
            .map_err(db)?;
        rows.iter()
            .map(|r| {
                let (kind, status, n): (String, String, i64) =
                    (r.try_get(0).map_err(db)?, r.try_get(1).map_err(db)?, r.try_get(2).map_err(db)?);
                let status = JobStatus::parse(&status)
                    .ok_or_else(|| StoreError::Corrupt(format!("a {kind} job has unknown status {status:?}")))?;
                Ok((kind, status, n as u64))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::contract::Fixture;

    /// A schema of its own on the database `LANDFORM_TEST_DATABASE_URL` names, dropped after the
    /// test; `None` when the variable is not set (then PostgreSQL is not tested here).
    pub fn fixture() -> Option<Fixture> {
        let (guard, scoped) = scoped_schema()?;
        let store = PostgresStore::open(&scoped).expect("open");
        Some(Fixture { store: Box::new(store), _guard: Box::new(guard) })
    }

    /// A fresh schema (dropped with the guard) and the URL whose connections use it; `None`
    /// without `LANDFORM_TEST_DATABASE_URL`.
    fn scoped_schema() -> Option<(DropSchema, String)> {
        let url = std::env::var("LANDFORM_TEST_DATABASE_URL").ok().filter(|u| !u.is_empty())?;
        let schema = format!("t_{}", uuid::Uuid::now_v7().simple());
        let mut admin = Client::connect(&url, NoTls).expect("connect to LANDFORM_TEST_DATABASE_URL");
        admin.batch_execute(&format!("CREATE SCHEMA {schema}")).expect("create a test schema");
        let sep = if url.contains('?') { '&' } else { '?' };
        let scoped = format!("{url}{sep}options=-csearch_path%3D{schema}");
        Some((DropSchema(admin, schema), scoped))
    }

    struct DropSchema(Client, String);

    impl Drop for DropSchema {
        fn drop(&mut self) {
            let _ = self.0.batch_execute(&format!("DROP SCHEMA {} CASCADE", self.1));
        }
    }

    crate::store_contract_tests!(fixture);

    /// The whole contract again with artifacts in an object store (a directory).
    mod with_objects {
        use super::*;
        use crate::store::ObjectArtifacts;

        fn open(dir: &std::path::Path) -> Option<(DropSchema, PostgresStore)> {
            let (guard, scoped) = scoped_schema()?;
            let objects = ObjectArtifacts::open(&format!("file://{}", dir.join("objects").display())).unwrap();
            Some((guard, PostgresStore::open(&scoped).unwrap().with_objects(Some(objects))))
        }

        fn fixture() -> Option<Fixture> {
            let dir = tempfile::tempdir().unwrap();
            let (guard, store) = open(dir.path())?;
            Some(Fixture { store: Box::new(store), _guard: Box::new((guard, dir)) })
        }

        crate::store_contract_tests!(fixture);

        #[test]
        fn objects_hold_the_bytes_and_none_outlives_its_row() {
            let dir = tempfile::tempdir().unwrap();
            let Some((_guard, store)) = open(dir.path()) else { return };
            crate::store::contract::objects_hold_the_bytes_and_none_outlives_its_row(
                &store,
                &dir.path().join("objects"),
            );
        }
    }

    /// A schema migrated before artifacts were chunked (V1, bytes in `artifacts.data`) keeps its
    /// artifacts when V2 moves them into chunks.
    #[test]
    fn artifacts_stored_whole_by_an_earlier_version_read_back_after_migrating() {
        let Some((_drop, scoped)) = scoped_schema() else { return };
        let mut old = Client::connect(&scoped, NoTls).unwrap();
        embedded::migrations::runner().set_target(refinery::Target::Version(1)).run(&mut old).unwrap();
        old.batch_execute(
            "INSERT INTO jobs (id, kind, status, created_at, progress, request) \
             VALUES ('j1', 'bulldoze', 'succeeded', '2026-01-01T00:00:00.000000000Z', '{}', '{}'); \
             INSERT INTO artifacts (job_id, name, ordinal, media_type, bytes, sha256, data) VALUES \
             ('j1', 'a.bin', 0, 'application/octet-stream', 5, 'x', '\\x0102030405'), \
             ('j1', 'empty.json', 1, 'application/json', 0, 'x', '\\x');",
        )
        .unwrap();
        let store = PostgresStore::open(&scoped).unwrap();
        assert_eq!(store.read_artifact("j1", "a.bin", 1, 3).unwrap(), Some(vec![2, 3, 4]));
        assert_eq!(store.artifact("j1", "a.bin").unwrap().unwrap().1, vec![1, 2, 3, 4, 5]);
        assert_eq!(store.artifact("j1", "empty.json").unwrap().unwrap().1, Vec::<u8>::new());
        assert_eq!(store.read_artifact("j1", "empty.json", 0, 10).unwrap(), Some(vec![]));
    }

    /// The next notice that `wanted` accepts, within ten seconds.
    fn expect(rx: &mut broadcast::Receiver<Notice>, wanted: impl Fn(&Notice) -> bool) -> Notice {
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        while std::time::Instant::now() < deadline {
            match rx.try_recv() {
                Ok(n) if wanted(&n) => return n,
                Ok(_) => {}
                Err(broadcast::error::TryRecvError::Empty) => std::thread::sleep(Duration::from_millis(10)),
                Err(e) => panic!("{e}"),
            }
        }
        panic!("no such notice within 10 s");
    }

    #[test]
    fn notices_carry_ids_and_the_listener_comes_back_after_its_connection_drops() {
        let Some(f) = fixture() else { return };
        let store = f.store.as_ref();
        let mut rx = store.notices().expect("PostgreSQL sends notices");
        expect(&mut rx, |n| *n == Notice::Reconnected);
        let job = crate::store::contract::job(1, "bulldoze", JobStatus::Queued);
        store.insert(&job, None).unwrap();
        expect(&mut rx, |n| *n == Notice::Queued(job.id.clone()));
        let claim = store.claim("w", Duration::from_secs(60), u64::MAX).unwrap().unwrap();
        store.append_event(&job.id, claim.attempt, "progress", "{}").unwrap().unwrap();
        expect(&mut rx, |n| *n == Notice::Changed(job.id.clone()));

        // The listener's connection is cut (a restart, a network fault): it connects again,
        // says so, and hears what comes after.
        let url = std::env::var("LANDFORM_TEST_DATABASE_URL").unwrap();
        let mut admin = Client::connect(&url, NoTls).unwrap();
        admin
            .batch_execute(
                "SELECT pg_terminate_backend(pid) FROM pg_stat_activity \
                 WHERE query LIKE 'LISTEN landform_jobs%' AND pid <> pg_backend_pid()",
            )
            .unwrap();
        expect(&mut rx, |n| *n == Notice::Reconnected);
        let next = crate::store::contract::job(2, "bulldoze", JobStatus::Queued);
        store.insert(&next, None).unwrap();
        expect(&mut rx, |n| *n == Notice::Queued(next.id.clone()));
    }

    #[test]
    fn replicas_opening_one_database_at_once_migrate_it_once() {
        let Some((_drop, scoped)) = scoped_schema() else { return };
        let opened: Vec<_> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..4).map(|_| s.spawn(|| PostgresStore::open(&scoped).map(|_| ()))).collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert!(opened.iter().all(Result::is_ok), "{opened:?}");
    }
}
