//! The embedded job store: one SQLite file (WAL mode) holding jobs, their artifacts' bytes and
//! the idempotency keys that created them.
//!
//! Writes go through one mutexed connection in `BEGIN IMMEDIATE` transactions; reads use a
//! small pool of read-only connections, which WAL lets proceed while a write is in flight. Every
//! value is converted (JSON, timestamps, hashes) before a connection is locked, so a lock is held
//! only for the statements themselves.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use chrono::Utc;
use parking_lot::{Mutex, MutexGuard};
use rusqlite::types::Value as SqlValue;
use rusqlite::{params, Connection, OpenFlags, OptionalExtension, Row, TransactionBehavior};

use super::artifacts::{assemble, chunks, span, StoredArtifact, STORED_ARTIFACT};
use super::events::{event_id, EventLog, StoredEvent};
use super::objects::{object_range, ObjectArtifacts};
use super::queue::{count, lease_ms, Claim, JobQueue, Renewal};
use super::row::{describe, summary_columns, timestamp, JobRow, RawJob, JOB_COLUMNS};
use super::{ArtifactStore, IdempotentInsert, JobInputs, JobStore, ListFilter, StoreError, CHUNK_BYTES};
use crate::export::Artifact;
use crate::model::{ArtifactMeta, Job, JobStatus};

/// The schema version this build writes (`PRAGMA user_version`).
pub const SCHEMA_VERSION: i64 = 8;

/// Migrations in order: `MIGRATIONS[n]` takes the schema from version `n` to `n + 1`.
const MIGRATIONS: [&str; SCHEMA_VERSION as usize] = [
    r#"
CREATE TABLE jobs (
    id                TEXT PRIMARY KEY NOT NULL,  -- UUIDv7: text order is creation order
    kind              TEXT NOT NULL,
    status            TEXT NOT NULL,
    label             TEXT,
    created_at        TEXT NOT NULL,              -- RFC 3339, UTC
    started_at        TEXT,
    finished_at       TEXT,
    progress          TEXT NOT NULL,              -- JSON
    request           TEXT NOT NULL,              -- JSON
    result            TEXT,                       -- JSON
    error             TEXT,                       -- JSON problem object
    replay_of         TEXT,                       -- not a foreign key: a replay outlives its original
    replay_until_step INTEGER,
    attempts          INTEGER NOT NULL DEFAULT 0  -- times the job entered `running`
);
CREATE INDEX jobs_by_kind ON jobs (kind, id);
CREATE INDEX jobs_by_status ON jobs (status, id);
CREATE INDEX jobs_by_kind_status ON jobs (kind, status);

CREATE TABLE artifacts (
    job_id     TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    name       TEXT NOT NULL,
    ordinal    INTEGER NOT NULL,  -- the order the job produced them in
    media_type TEXT NOT NULL,
    bytes      INTEGER NOT NULL,
    sha256     TEXT NOT NULL,     -- lowercase hex
    data       BLOB NOT NULL,     -- last, so reading the columns before it skips the blob's pages
    PRIMARY KEY (job_id, name),
    UNIQUE (job_id, ordinal)
);

CREATE TABLE idempotency_keys (
    key         TEXT PRIMARY KEY NOT NULL,
    body_sha256 TEXT NOT NULL,
    job_id      TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE
);
CREATE INDEX idempotency_keys_by_job ON idempotency_keys (job_id);
"#,
    r#"
-- Uploaded files (heightmap PNGs), stored once by content and named by their sha256, so a
-- request and its recorded sequence carry a reference instead of the file.
CREATE TABLE inputs (
    sha256      TEXT PRIMARY KEY NOT NULL,
    bytes       INTEGER NOT NULL,
    created_at  TEXT NOT NULL,
    data        BLOB NOT NULL
);
"#,
    r#"
-- The cost estimate a job was admitted by (JSON), and the API key name that owns it.
ALTER TABLE jobs ADD COLUMN cost TEXT;
ALTER TABLE jobs ADD COLUMN owner TEXT;
CREATE INDEX jobs_by_owner ON jobs (owner, id);
"#,
    r#"
-- Artifact bytes in chunks (one row each, see store/artifacts.rs), so a download reads one
-- chunk at a time. Artifacts stored before move over as one chunk each.
CREATE TABLE artifact_chunks (
    job_id TEXT NOT NULL,
    name   TEXT NOT NULL,
    seq    INTEGER NOT NULL,  -- from 0; chunk k holds bytes k * chunk_bytes ..
    data   BLOB NOT NULL,
    PRIMARY KEY (job_id, name, seq),
    FOREIGN KEY (job_id, name) REFERENCES artifacts (job_id, name) ON DELETE CASCADE
);
ALTER TABLE artifacts ADD COLUMN chunk_bytes INTEGER NOT NULL DEFAULT 1;
INSERT INTO artifact_chunks (job_id, name, seq, data) SELECT job_id, name, 0, data FROM artifacts;
UPDATE artifacts SET chunk_bytes = max(bytes, 1);
ALTER TABLE artifacts DROP COLUMN data;
"#,
    r#"
-- The queue across processes (store/queue.rs): the estimate's memory for claims to compare,
-- a claim's lease by the database's clock (milliseconds since 1970), who holds it, and how
-- often a holder's lease ran out.
ALTER TABLE jobs ADD COLUMN memory_bytes INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN lease_until INTEGER;
ALTER TABLE jobs ADD COLUMN lease_owner TEXT;
ALTER TABLE jobs ADD COLUMN lost_leases INTEGER NOT NULL DEFAULT 0;
UPDATE jobs SET memory_bytes = coalesce(json_extract(cost, '$.memory_bytes'), 0) WHERE cost IS NOT NULL;
"#,
    r#"
-- Job events and live snapshots across processes (store/events.rs), and cancel requests a
-- job's worker reads when it renews its lease.
CREATE TABLE job_events (
    id     INTEGER PRIMARY KEY AUTOINCREMENT,  -- never reused: ids only grow
    job_id TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    event  TEXT NOT NULL,
    data   TEXT NOT NULL
);
CREATE INDEX job_events_by_job ON job_events (job_id, id);
CREATE TABLE job_snapshots (
    job_id   TEXT PRIMARY KEY NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    event_id INTEGER NOT NULL,
    png      BLOB NOT NULL
);
ALTER TABLE jobs ADD COLUMN cancel_requested INTEGER NOT NULL DEFAULT 0;
"#,
    r#"
-- An artifact kept in an object store (store/objects.rs): its key there, and no chunks here.
ALTER TABLE artifacts ADD COLUMN object_key TEXT;
"#,
    r#"
-- Which uploads each job reads: an upload belongs to the keys whose jobs sent or read it, is
-- stored only with an admitted job, and goes with the last job that reads it. Jobs stored
-- before name theirs in their requests (`png_sha256`); uploads no job reads are dropped.
CREATE TABLE job_inputs (
    job_id TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    sha256 TEXT NOT NULL,
    PRIMARY KEY (job_id, sha256)
);
CREATE INDEX job_inputs_by_sha256 ON job_inputs (sha256);
INSERT OR IGNORE INTO job_inputs (job_id, sha256)
    SELECT jobs.id, t.value FROM jobs, json_tree(jobs.request) AS t
    WHERE t.key = 'png_sha256' AND t.type = 'text';
DELETE FROM inputs WHERE sha256 NOT IN (SELECT sha256 FROM job_inputs);
"#,
];

/// The database's clock in milliseconds since 1970: leases are set and compared by it alone.
const NOW_MS: &str = "CAST(unixepoch('subsec') * 1000 AS INTEGER)";

/// Read connections opened beside the writer (none for an in-memory database, whose
/// connections would each see a different database).
const READERS: usize = 4;
/// Attempts of `retry_busy` before a locked database is an error: about 10 s in all, longer
/// than a supervised worker may stay silent before it is killed (`supervisor`), so a worker
/// frozen while it holds the write lock delays the API's writes rather than failing them.
const BUSY_ATTEMPTS: i32 = 1_950;

/// How long to wait before trying a locked database again (SQLite calls this with the number of
/// attempts so far; false gives up). The API and its worker are separate processes writing one
/// file, so the write lock is often held for a moment by the other: SQLite's own busy timeout
/// sleeps 1, 2, 5, 10… 100 ms between attempts, which turns a lock held for a millisecond into
/// a submission that waits tens of them. Short sleeps first, longer ones only when the wait
/// is long anyway.
fn retry_busy(attempts: i32) -> bool {
    let pause = match attempts {
        0..100 => Duration::from_micros(100), // the first 10 ms
        100..300 => Duration::from_millis(1), // then 200 ms
        _ => Duration::from_millis(6),        // then about 9.9 s
    };
    std::thread::sleep(pause);
    attempts < BUSY_ATTEMPTS
}
/// The WAL is truncated back to this size after a checkpoint (large artifacts pass through it).
const JOURNAL_SIZE_LIMIT_BYTES: i64 = 32 * 1024 * 1024;

/// The SQLite job store. See the module documentation.
pub struct SqliteStore {
    writer: Mutex<Connection>,
    readers: Vec<Mutex<Connection>>,
    next_reader: AtomicUsize,
    /// Where new artifacts' bytes go when not into the database.
    objects: Option<ObjectArtifacts>,
}

impl std::fmt::Debug for SqliteStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SqliteStore").field("readers", &self.readers.len()).finish_non_exhaustive()
    }
}

impl SqliteStore {
    /// Open (creating if needed) the database at `path` and bring its schema up to date.
    ///
    /// `path` is a file path, a `file:` URI, or `:memory:` (a private database that lives as
    /// long as the store; for tests).
    pub fn open(path: &str) -> Result<Self, StoreError> {
        let mut writer = Connection::open(path).map_err(|e| open_error(path, e))?;
        configure(&writer, true).map_err(|e| open_error(path, e))?;
        migrate(&mut writer)?;

        let readers = if is_in_memory(path) {
            Vec::new()
        } else {
            let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_URI | OpenFlags::SQLITE_OPEN_NO_MUTEX;
            (0..READERS)
                .map(|_| {
                    let conn = Connection::open_with_flags(path, flags).map_err(|e| open_error(path, e))?;
                    configure(&conn, false).map_err(|e| open_error(path, e))?;
                    Ok(Mutex::new(conn))
                })
                .collect::<Result<Vec<_>, StoreError>>()?
        };
        Ok(Self { writer: Mutex::new(writer), readers, next_reader: AtomicUsize::new(0), objects: None })
    }

    /// Keep the bytes of artifacts finished from now on in `objects`, when given (the rows
    /// stay here).
    pub fn with_objects(mut self, objects: Option<ObjectArtifacts>) -> Self {
        self.objects = objects;
        self
    }

    /// How many times the job has entered `running` (0 if it never ran); `None` if there is
    /// no such job.
    fn attempts_count(&self, id: &str) -> Result<Option<u32>, StoreError> {
        let conn = self.reader();
        let attempts: Option<i64> =
            conn.query_row("SELECT attempts FROM jobs WHERE id = ?1", [id], |r| r.get(0)).optional().map_err(db)?;
        attempts
            .map(|n| u32::try_from(n).map_err(|_| StoreError::Corrupt(format!("job {id}: attempts {n}"))))
            .transpose()
    }

    /// Save a job's row; false when nothing was written (no such job, or the row's fence is
    /// no longer the job's attempt).
    fn update_row(&self, row: JobRow<'_>) -> Result<bool, StoreError> {
        row.update(&self.writer.lock()).map_err(db)
    }

    /// Save a finished job's row and its artifacts in one transaction; false when nothing
    /// was written (no such job, or the row's fence is no longer the job's attempt).
    fn finish_row(&self, row: JobRow<'_>, artifacts: &[Artifact]) -> Result<bool, StoreError> {
        let job = row.job;
        let metas = describe(artifacts)?;
        // Objects first, outside the transaction; removed again if it does not commit.
        let placed = self.objects.as_ref().map(|o| o.put_all(&job.id, artifacts)).transpose()?;
        let mut conn = self.writer.lock();
        let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate).map_err(db)?;
        if !row.update(&tx).map_err(db)? {
            return Ok(false);
        }
        let replaced = object_keys(&tx, &job.id)?;
        // The job's chunks go with its artifact rows (ON DELETE CASCADE).
        tx.prepare_cached("DELETE FROM artifacts WHERE job_id = ?1").map_err(db)?.execute([&job.id]).map_err(db)?;
        {
            let mut artifact = tx
                .prepare_cached(
                    "INSERT INTO artifacts (job_id, name, ordinal, media_type, bytes, sha256, chunk_bytes, object_key) \
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
                )
                .map_err(db)?;
            let mut chunk = tx
                .prepare_cached("INSERT INTO artifact_chunks (job_id, name, seq, data) VALUES (?1, ?2, ?3, ?4)")
                .map_err(db)?;
            for (ordinal, (a, m)) in artifacts.iter().zip(&metas).enumerate() {
                let bytes = a.bytes.len() as i64;
                let key = placed.as_ref().map(|p| p.keys[ordinal].as_str());
                artifact
                    .execute(params![
                        job.id,
                        m.name,
                        ordinal as i64,
                        m.media_type,
                        bytes,
                        m.sha256,
                        CHUNK_BYTES as i64,
                        key
                    ])
                    .map_err(db)?;
                if key.is_none() {
                    for (seq, data) in chunks(&a.bytes) {
                        chunk.execute(params![job.id, m.name, seq, data]).map_err(db)?;
                    }
                }
            }
        }
        tx.commit().map_err(db)?;
        drop(conn);
        if let Some(p) = placed {
            p.keep();
        }
        self.remove_objects(&replaced);
        Ok(true)
    }

    fn remove_objects(&self, keys: &[String]) {
        if let Some(o) = &self.objects {
            o.remove(keys);
        }
    }

    /// A free read connection, or the next one in turn if all are busy.
    fn reader(&self) -> MutexGuard<'_, Connection> {
        if self.readers.is_empty() {
            return self.writer.lock();
        }
        for r in &self.readers {
            if let Some(guard) = r.try_lock() {
                return guard;
            }
        }
        let i = self.next_reader.fetch_add(1, Ordering::Relaxed) % self.readers.len();
        self.readers[i].lock()
    }
}

/// The object keys of a job's artifacts kept in an object store.
fn object_keys(c: &Connection, job_id: &str) -> Result<Vec<String>, StoreError> {
    let mut stmt = c
        .prepare_cached("SELECT object_key FROM artifacts WHERE job_id = ?1 AND object_key IS NOT NULL")
        .map_err(db)?;
    let keys = stmt.query_map([job_id], |r| r.get(0)).map_err(db)?.collect::<Result<Vec<String>, _>>().map_err(db);
    keys
}

fn is_in_memory(path: &str) -> bool {
    path.is_empty() || path == ":memory:" || path.starts_with("file::memory:") || path.contains("mode=memory")
}

fn configure(conn: &Connection, writer: bool) -> rusqlite::Result<()> {
    conn.busy_handler(Some(retry_busy))?;
    conn.pragma_update(None, "foreign_keys", "ON")?;
    if writer {
        // An in-memory database answers "memory"; WAL needs a file.
        let _mode: String = conn.pragma_update_and_check(None, "journal_mode", "WAL", |r| r.get(0))?;
        conn.pragma_update(None, "synchronous", "NORMAL")?;
        conn.pragma_update(None, "journal_size_limit", JOURNAL_SIZE_LIMIT_BYTES)?;
    }
    Ok(())
}

fn migrate(conn: &mut Connection) -> Result<(), StoreError> {
    // IMMEDIATE: two processes opening a new file at once must not both create the schema.
    let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate).map_err(db)?;
    let version: i64 = tx.pragma_query_value(None, "user_version", |r| r.get(0)).map_err(db)?;
    if version > SCHEMA_VERSION {
        return Err(StoreError::Backend(format!(
            "the database has schema version {version}; this build knows only up to {SCHEMA_VERSION}"
        )));
    }
    if version < 0 {
        return Err(StoreError::Corrupt(format!("the database has schema version {version}")));
    }
    for sql in &MIGRATIONS[version as usize..] {
        tx.execute_batch(sql).map_err(db)?;
    }
    if version < SCHEMA_VERSION {
        tx.pragma_update(None, "user_version", SCHEMA_VERSION).map_err(db)?;
    }
    tx.commit().map_err(db)
}

fn open_error(path: &str, e: rusqlite::Error) -> StoreError {
    match db(e) {
        StoreError::Backend(m) => StoreError::Backend(format!("cannot open {path}: {m}")),
        StoreError::Corrupt(m) => StoreError::Corrupt(format!("{path}: {m}")),
    }
}

/// Values a row can't be read as, and a damaged file, are `Corrupt`; the rest `Backend`.
fn db(e: rusqlite::Error) -> StoreError {
    use rusqlite::ffi::ErrorCode;
    use rusqlite::Error as E;
    match &e {
        E::InvalidColumnType(..)
        | E::FromSqlConversionFailure(..)
        | E::IntegralValueOutOfRange(..)
        | E::Utf8Error(..) => StoreError::Corrupt(e.to_string()),
        E::SqliteFailure(f, _) if matches!(f.code, ErrorCode::DatabaseCorrupt | ErrorCode::NotADatabase) => {
            StoreError::Corrupt(e.to_string())
        }
        _ => StoreError::Backend(e.to_string()),
    }
}

impl JobRow<'_> {
    fn insert(&self, conn: &Connection) -> rusqlite::Result<()> {
        let j = self.job;
        conn.prepare_cached(
            "INSERT INTO jobs (id, kind, status, label, created_at, started_at, finished_at, \
             progress, request, result, error, replay_of, replay_until_step, attempts, cost, owner, memory_bytes) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17)",
        )?
        .execute(params![
            j.id,
            j.kind,
            j.status.as_str(),
            j.label,
            self.created_at,
            self.started_at,
            self.finished_at,
            self.progress,
            self.request,
            self.result,
            self.error,
            j.replay_of,
            self.replay_until_step,
            i64::from(j.status == JobStatus::Running),
            self.cost,
            j.owner,
            self.memory_bytes,
        ])?;
        Ok(())
    }

    /// Save the mutable columns; false if there is no such job (or, fenced, the fence is no
    /// longer the job's attempt). An ended job holds no lease.
    fn update(&self, conn: &Connection) -> rusqlite::Result<bool> {
        let j = self.job;
        // SET expressions see the row as it was, so `status` here is the previous status.
        let changed = conn
            .prepare_cached(
                "UPDATE jobs SET status = ?2, label = ?3, started_at = ?4, finished_at = ?5, \
                 progress = ?6, result = ?7, error = ?8, \
                 attempts = attempts + (?2 = 'running' AND status <> 'running'), \
                 lease_until = CASE WHEN ?2 IN ('running', 'queued') THEN lease_until END \
                 WHERE id = ?1 AND (?9 IS NULL OR attempts = ?9)",
            )?
            .execute(params![
                j.id,
                j.status.as_str(),
                j.label,
                self.started_at,
                self.finished_at,
                self.progress,
                self.result,
                self.error,
                self.fence,
            ])?;
        Ok(changed > 0)
    }
}

impl RawJob {
    /// Columns in `JOB_COLUMNS` order.
    fn from_row(row: &Row<'_>) -> rusqlite::Result<Self> {
        Ok(Self {
            id: row.get(0)?,
            kind: row.get(1)?,
            status: row.get(2)?,
            label: row.get(3)?,
            created_at: row.get(4)?,
            started_at: row.get(5)?,
            finished_at: row.get(6)?,
            progress: row.get(7)?,
            request: row.get(8)?,
            result: row.get(9)?,
            error: row.get(10)?,
            replay_of: row.get(11)?,
            replay_until_step: row.get(12)?,
            cost: row.get(13)?,
            owner: row.get(14)?,
        })
    }
}

fn artifact_metas(conn: &Connection, job_id: &str) -> Result<Vec<ArtifactMeta>, StoreError> {
    let mut stmt = conn
        .prepare_cached(
            "SELECT name, media_type, bytes, sha256 FROM artifacts \
             WHERE job_id = ?1 ORDER BY ordinal",
        )
        .map_err(db)?;
    let mut rows = stmt.query([job_id]).map_err(db)?;
    let mut out = Vec::new();
    while let Some(row) = rows.next().map_err(db)? {
        let name: String = row.get(0).map_err(db)?;
        let bytes: i64 = row.get(2).map_err(db)?;
        let bytes = u64::try_from(bytes)
            .map_err(|_| StoreError::Corrupt(format!("job {job_id}: artifact {name}: size {bytes}")))?;
        out.push(ArtifactMeta {
            media_type: row.get(1).map_err(db)?,
            bytes,
            sha256: row.get(3).map_err(db)?,
            href: String::new(),
            name,
        });
    }
    Ok(out)
}

fn load_job(conn: &Connection, id: &str) -> Result<Option<Job>, StoreError> {
    load_job_with(conn, id, JOB_COLUMNS)
}

fn load_job_with(conn: &Connection, id: &str, columns: &str) -> Result<Option<Job>, StoreError> {
    let raw = conn
        .prepare_cached(&format!("SELECT {columns} FROM jobs WHERE id = ?1"))
        .map_err(db)?
        .query_row([id], RawJob::from_row)
        .optional()
        .map_err(db)?;
    match raw {
        None => Ok(None),
        Some(raw) => {
            let artifacts = artifact_metas(conn, &raw.id)?;
            raw.into_job(artifacts).map(Some)
        }
    }
}

/// Run a query returning job rows and attach each job's artifact metas.
fn load_jobs(conn: &Connection, sql: &str, params: impl rusqlite::Params) -> Result<Vec<Job>, StoreError> {
    let raws = {
        let mut stmt = conn.prepare_cached(sql).map_err(db)?;
        let rows = stmt.query_map(params, RawJob::from_row).map_err(db)?;
        rows.collect::<rusqlite::Result<Vec<_>>>().map_err(db)?
    };
    raws.into_iter()
        .map(|raw| {
            let artifacts = artifact_metas(conn, &raw.id)?;
            raw.into_job(artifacts)
        })
        .collect()
}

/// Run `f` inside one read transaction, so the rows it reads belong to one snapshot.
fn read_snapshot<T>(
    conn: &mut Connection,
    f: impl FnOnce(&Connection) -> Result<T, StoreError>,
) -> Result<T, StoreError> {
    let tx = conn.transaction().map_err(db)?;
    let out = f(&tx)?;
    tx.commit().map_err(db)?;
    Ok(out)
}

fn artifact_row(c: &Connection, id: &str, name: &str) -> Result<Option<StoredArtifact>, StoreError> {
    c.prepare_cached(&format!("{STORED_ARTIFACT} WHERE job_id = ?1 AND name = ?2"))
        .map_err(db)?
        .query_row([id, name], |r| {
            Ok(StoredArtifact { media_type: r.get(0)?, total: r.get(1)?, chunk: r.get(2)?, object_key: r.get(3)? })
        })
        .optional()
        .map_err(db)
}

impl ArtifactStore for SqliteStore {
    fn read_artifact(&self, id: &str, name: &str, offset: u64, len: usize) -> Result<Option<Vec<u8>>, StoreError> {
        read_snapshot(&mut self.reader(), |c| {
            let Some(StoredArtifact { total, chunk, object_key, .. }) = artifact_row(c, id, name)? else {
                return Ok(None);
            };
            if let Some(key) = object_key {
                return object_range(self.objects.as_ref(), &key, total, offset, len);
            }
            let Some(s) = span(total.max(0) as u64, chunk.max(0) as u64, offset, len)? else {
                return Ok(Some(Vec::new()));
            };
            let mut stmt = c
                .prepare_cached(
                    "SELECT data FROM artifact_chunks WHERE job_id = ?1 AND name = ?2 AND seq BETWEEN ?3 AND ?4 \
                     ORDER BY seq",
                )
                .map_err(db)?;
            let chunks = stmt
                .query_map(params![id, name, s.first_seq, s.last_seq], |r| r.get::<_, Vec<u8>>(0))
                .map_err(db)?
                .collect::<Result<Vec<_>, _>>()
                .map_err(db)?;
            assemble(&s, chunks).map(Some)
        })
    }

    fn artifact(&self, id: &str, name: &str) -> Result<Option<(String, Vec<u8>)>, StoreError> {
        read_snapshot(&mut self.reader(), |c| {
            let Some(StoredArtifact { media_type, total, object_key, .. }) = artifact_row(c, id, name)? else {
                return Ok(None);
            };
            if let Some(key) = object_key {
                let whole = object_range(self.objects.as_ref(), &key, total, 0, usize::MAX)?;
                return Ok(whole.map(|data| (media_type, data)));
            }
            let mut data = Vec::with_capacity(total.max(0) as usize);
            let mut stmt = c
                .prepare_cached("SELECT data FROM artifact_chunks WHERE job_id = ?1 AND name = ?2 ORDER BY seq")
                .map_err(db)?;
            let mut rows = stmt.query([id, name]).map_err(db)?;
            while let Some(r) = rows.next().map_err(db)? {
                data.extend_from_slice(&r.get::<_, Vec<u8>>(0).map_err(db)?);
            }
            if data.len() as i64 != total {
                return Err(StoreError::Corrupt(format!("job {id}: artifact {name}: {} of {total} bytes", data.len())));
            }
            Ok(Some((media_type, data)))
        })
    }
}

impl JobQueue for SqliteStore {
    fn claim(&self, worker: &str, lease: Duration, max_memory: u64) -> Result<Option<Claim>, StoreError> {
        let mut conn = self.writer.lock();
        // IMMEDIATE: the one writer of the file, across processes, until the claim is made.
        let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate).map_err(db)?;
        let now: i64 = tx.query_row(&format!("SELECT {NOW_MS}"), [], |r| r.get(0)).map_err(db)?;
        let next: Option<(String, i64)> = tx
            .prepare_cached(
                "SELECT id, memory_bytes FROM jobs \
                 WHERE status = 'queued' OR (status = 'running' AND lease_until < ?1) ORDER BY id LIMIT 1",
            )
            .map_err(db)?
            .query_row([now], |r| Ok((r.get(0)?, r.get(1)?)))
            .optional()
            .map_err(db)?;
        let Some((id, memory)) = next else { return Ok(None) };
        if u64::try_from(memory).unwrap_or(0) > max_memory {
            return Ok(None);
        }
        // SET expressions see the row as it was: `status` is the status before the claim.
        tx.prepare_cached(
            "UPDATE jobs SET lost_leases = lost_leases + (status = 'running'), status = 'running', \
             attempts = attempts + 1, lease_until = ?2, lease_owner = ?3 WHERE id = ?1",
        )
        .map_err(db)?
        .execute(params![id, now.saturating_add(lease_ms(lease)), worker])
        .map_err(db)?;
        let (attempt, lost): (i64, i64) = tx
            .query_row("SELECT attempts, lost_leases FROM jobs WHERE id = ?1", [&id], |r| Ok((r.get(0)?, r.get(1)?)))
            .map_err(db)?;
        let sql = format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = ?1");
        let job =
            load_jobs(&tx, &sql, [&id])?.pop().ok_or_else(|| StoreError::Backend(format!("job {id} vanished")))?;
        tx.commit().map_err(db)?;
        Ok(Some(Claim {
            job,
            attempt: count("attempts", &id, attempt)?,
            lost_leases: count("lost_leases", &id, lost)?,
        }))
    }

    fn renew(&self, id: &str, attempt: u32, lease: Duration) -> Result<Renewal, StoreError> {
        let sql = format!(
            "UPDATE jobs SET lease_until = {NOW_MS} + ?3 WHERE id = ?1 AND attempts = ?2 AND status = 'running' \
             RETURNING cancel_requested"
        );
        let cancel: Option<bool> = self
            .writer
            .lock()
            .query_row(&sql, params![id, attempt, lease_ms(lease)], |r| r.get(0))
            .optional()
            .map_err(db)?;
        Ok(cancel.map_or(Renewal::Lost, |cancel_requested| Renewal::Held { cancel_requested }))
    }

    fn request_cancel(&self, id: &str) -> Result<bool, StoreError> {
        let n = self
            .writer
            .lock()
            .execute("UPDATE jobs SET cancel_requested = 1 WHERE id = ?1 AND status IN ('queued', 'running')", [id])
            .map_err(db)?;
        Ok(n > 0)
    }

    fn cancel_requested(&self, id: &str) -> Result<bool, StoreError> {
        let asked: Option<bool> = self
            .reader()
            .prepare_cached("SELECT cancel_requested FROM jobs WHERE id = ?1")
            .and_then(|mut s| s.query_row([id], |r| r.get(0)).optional())
            .map_err(db)?;
        Ok(asked.unwrap_or(false))
    }

    fn release(&self, id: &str, attempt: u32) -> Result<bool, StoreError> {
        let n = self
            .writer
            .lock()
            .execute(
                "UPDATE jobs SET status = 'queued', lease_until = NULL, lease_owner = NULL \
                 WHERE id = ?1 AND attempts = ?2 AND status = 'running'",
                params![id, attempt],
            )
            .map_err(db)?;
        Ok(n > 0)
    }

    fn active(&self, owner: Option<&str>) -> Result<(u32, u64), StoreError> {
        let (n, memory): (i64, i64) = self
            .reader()
            .prepare_cached(
                "SELECT count(*), coalesce(sum(memory_bytes), 0) FROM jobs \
                 WHERE owner IS ?1 AND status IN ('queued', 'running')",
            )
            .map_err(db)?
            .query_row([owner], |r| Ok((r.get(0)?, r.get(1)?)))
            .map_err(db)?;
        Ok((count("active jobs", "*", n)?, u64::try_from(memory).unwrap_or(0)))
    }

    fn reserved(&self) -> Result<u64, StoreError> {
        let n: i64 = self
            .reader()
            .query_row("SELECT coalesce(sum(memory_bytes), 0) FROM jobs WHERE status = 'running'", [], |r| r.get(0))
            .map_err(db)?;
        Ok(u64::try_from(n).unwrap_or(0))
    }

    fn ended_after(&self, after: chrono::DateTime<Utc>, limit: u32) -> Result<Vec<Job>, StoreError> {
        let sql = format!(
            "SELECT {JOB_COLUMNS} FROM jobs WHERE finished_at > ?1 AND status IN ('succeeded', 'failed', 'cancelled') \
             ORDER BY finished_at LIMIT ?2"
        );
        read_snapshot(&mut self.reader(), |c| load_jobs(c, &sql, params![timestamp(&after), limit]))
    }

    fn update_claimed(&self, job: &Job, attempt: u32) -> Result<bool, StoreError> {
        self.update_row(JobRow::encode(job)?.fenced(attempt))
    }

    fn finish_claimed(&self, job: &Job, attempt: u32, artifacts: &[Artifact]) -> Result<bool, StoreError> {
        self.finish_row(JobRow::encode(job)?.fenced(attempt), artifacts)
    }
}

/// Jobs that ended before the time ?1, whose events may go.
const ENDED_BEFORE: &str = "status IN ('succeeded', 'failed', 'cancelled') AND finished_at < ?1";

/// Appends and snapshots under a claim: only while the claim is still the job's.
const HELD: &str = "EXISTS (SELECT 1 FROM jobs WHERE id = ?1 AND attempts = ?4 AND status = 'running')";

impl EventLog for SqliteStore {
    fn append_event(&self, job_id: &str, attempt: u32, event: &str, data: &str) -> Result<Option<u64>, StoreError> {
        let sql = format!("INSERT INTO job_events (job_id, event, data) SELECT ?1, ?2, ?3 WHERE {HELD} RETURNING id");
        let id: Option<i64> = self
            .writer
            .lock()
            .query_row(&sql, params![job_id, event, data, attempt], |r| r.get(0))
            .optional()
            .map_err(db)?;
        id.map(event_id).transpose()
    }

    fn events_after(&self, job_id: &str, after: u64, limit: u32) -> Result<Vec<StoredEvent>, StoreError> {
        let conn = self.reader();
        let mut stmt = conn
            .prepare_cached("SELECT id, event, data FROM job_events WHERE job_id = ?1 AND id > ?2 ORDER BY id LIMIT ?3")
            .map_err(db)?;
        let after = i64::try_from(after).unwrap_or(i64::MAX);
        let rows = stmt
            .query_map(params![job_id, after, limit], |r| Ok((r.get::<_, i64>(0)?, r.get(1)?, r.get(2)?)))
            .map_err(db)?;
        rows.map(|r| {
            let (id, event, data) = r.map_err(db)?;
            Ok(StoredEvent { id: event_id(id)?, event, data })
        })
        .collect()
    }

    fn last_event(&self, job_id: &str, event: &str) -> Result<Option<StoredEvent>, StoreError> {
        let found: Option<(i64, String)> = self
            .reader()
            .prepare_cached("SELECT id, data FROM job_events WHERE job_id = ?1 AND event = ?2 ORDER BY id DESC LIMIT 1")
            .map_err(db)?
            .query_row([job_id, event], |r| Ok((r.get(0)?, r.get(1)?)))
            .optional()
            .map_err(db)?;
        found.map(|(id, data)| Ok(StoredEvent { id: event_id(id)?, event: event.to_string(), data })).transpose()
    }

    fn put_snapshot(&self, job_id: &str, attempt: u32, event: u64, png: &[u8]) -> Result<bool, StoreError> {
        // The WHERE makes the SELECT's end plain to the parser before ON CONFLICT.
        let sql = format!(
            "INSERT INTO job_snapshots (job_id, event_id, png) SELECT ?1, ?2, ?3 WHERE {HELD} \
             ON CONFLICT (job_id) DO UPDATE SET event_id = excluded.event_id, png = excluded.png"
        );
        let event = i64::try_from(event).unwrap_or(i64::MAX);
        let n = self.writer.lock().execute(&sql, params![job_id, event, png, attempt]).map_err(db)?;
        Ok(n > 0)
    }

    fn prune_ended(&self, ended_before: chrono::DateTime<Utc>) -> Result<u64, StoreError> {
        let before = timestamp(&ended_before);
        let conn = self.writer.lock();
        let mut n = 0;
        for table in ["job_events", "job_snapshots"] {
            let sql = format!("DELETE FROM {table} WHERE job_id IN (SELECT id FROM jobs WHERE {ENDED_BEFORE})");
            n += conn.execute(&sql, [&before]).map_err(db)? as u64;
        }
        Ok(n)
    }

    fn snapshot(&self, job_id: &str) -> Result<Option<(u64, Vec<u8>)>, StoreError> {
        let found: Option<(i64, Vec<u8>)> = self
            .reader()
            .prepare_cached("SELECT event_id, png FROM job_snapshots WHERE job_id = ?1")
            .map_err(db)?
            .query_row([job_id], |r| Ok((r.get(0)?, r.get(1)?)))
            .optional()
            .map_err(db)?;
        found.map(|(id, png)| Ok((event_id(id)?, png))).transpose()
    }
}

impl JobStore for SqliteStore {
    fn attempts(&self, id: &str) -> Result<Option<u32>, StoreError> {
        self.attempts_count(id)
    }

    fn status(&self, id: &str) -> Result<Option<(JobStatus, Option<String>)>, StoreError> {
        let conn = self.reader();
        let row: Option<(String, Option<String>)> = conn
            .prepare_cached("SELECT status, owner FROM jobs WHERE id = ?1")
            .and_then(|mut s| s.query_row([id], |r| Ok((r.get(0)?, r.get(1)?))).optional())
            .map_err(db)?;
        row.map(|(status, owner)| {
            JobStatus::parse(&status)
                .map(|s| (s, owner))
                .ok_or_else(|| StoreError::Corrupt(format!("job {id}: unknown status {status:?}")))
        })
        .transpose()
    }

    fn insert_with_inputs(
        &self,
        job: &Job,
        idempotency: Option<(&str, &str)>,
        inputs: JobInputs,
    ) -> Result<IdempotentInsert, StoreError> {
        let row = JobRow::encode(job)?;
        let mut conn = self.writer.lock();
        let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate).map_err(db)?;
        if let Some((key, body_sha256)) = idempotency {
            let earlier: Option<(String, String)> = tx
                .prepare_cached("SELECT body_sha256, job_id FROM idempotency_keys WHERE key = ?1")
                .map_err(db)?
                .query_row([key], |r| Ok((r.get(0)?, r.get(1)?)))
                .optional()
                .map_err(db)?;
            if let Some((stored_sha256, job_id)) = earlier {
                let job = load_job(&tx, &job_id)?.ok_or_else(|| {
                    StoreError::Corrupt(format!("idempotency key {key:?} names job {job_id}, which is missing"))
                })?;
                // Dropping `tx` rolls back: nothing was written.
                return Ok(IdempotentInsert::Existing {
                    job: Box::new(job),
                    same_body: stored_sha256.eq_ignore_ascii_case(body_sha256),
                });
            }
        }
        row.insert(&tx).map_err(db)?;
        for (sha256, data) in inputs.sent {
            tx.prepare_cached(
                "INSERT INTO inputs (sha256, bytes, created_at, data) VALUES (?1, ?2, ?3, ?4) ON CONFLICT DO NOTHING",
            )
            .and_then(|mut s| s.execute(params![sha256, data.len() as i64, Utc::now().to_rfc3339(), data]))
            .map_err(db)?;
        }
        for sha256 in inputs.all() {
            tx.prepare_cached("INSERT OR IGNORE INTO job_inputs (job_id, sha256) VALUES (?1, ?2)")
                .and_then(|mut s| s.execute(params![job.id, sha256]))
                .map_err(db)?;
        }
        if let Some((key, body_sha256)) = idempotency {
            tx.prepare_cached("INSERT INTO idempotency_keys (key, body_sha256, job_id) VALUES (?1, ?2, ?3)")
                .map_err(db)?
                .execute(params![key, body_sha256, job.id])
                .map_err(db)?;
        }
        tx.commit().map_err(db)?;
        Ok(IdempotentInsert::Inserted)
    }

    fn get(&self, id: &str) -> Result<Option<Job>, StoreError> {
        read_snapshot(&mut self.reader(), |c| load_job(c, id))
    }

    fn get_summary(&self, id: &str) -> Result<Option<Job>, StoreError> {
        read_snapshot(&mut self.reader(), |c| load_job_with(c, id, &summary_columns()))
    }

    /// Newest first. A `limit` of 0 means no limit.
    fn list(&self, filter: &ListFilter) -> Result<Vec<Job>, StoreError> {
        let mut conditions: Vec<&str> = Vec::new();
        let mut values: Vec<SqlValue> = Vec::new();
        if let Some(kind) = &filter.kind {
            conditions.push("kind = ?");
            values.push(SqlValue::Text(kind.clone()));
        }
        if let Some(status) = filter.status {
            conditions.push("status = ?");
            values.push(SqlValue::Text(status.as_str().to_string()));
        }
        if let Some(owner) = &filter.owner {
            conditions.push("owner = ?");
            values.push(SqlValue::Text(owner.clone()));
        }
        if filter.no_replays {
            conditions.push("replay_of IS NULL");
        }
        if let Some(before) = &filter.before_id {
            conditions.push("id < ?");
            values.push(SqlValue::Text(before.clone()));
        }
        // Summaries: a large request is not read (see `summary_columns`).
        let mut sql = format!("SELECT {} FROM jobs", summary_columns());
        if !conditions.is_empty() {
            sql.push_str(" WHERE ");
            sql.push_str(&conditions.join(" AND "));
        }
        sql.push_str(" ORDER BY id DESC LIMIT ?");
        values.push(SqlValue::Integer(if filter.limit == 0 { -1 } else { i64::from(filter.limit) }));
        read_snapshot(&mut self.reader(), |c| load_jobs(c, &sql, rusqlite::params_from_iter(values)))
    }

    /// A job that no longer exists (deleted while it ran) is left deleted.
    fn update(&self, job: &Job) -> Result<(), StoreError> {
        self.update_row(JobRow::encode(job)?).map(|_| ())
    }

    /// Replaces any artifacts the job had. A job deleted meanwhile is left deleted.
    fn finish(&self, job: &Job, artifacts: &[Artifact]) -> Result<(), StoreError> {
        self.finish_row(JobRow::encode(job)?, artifacts).map(|_| ())
    }

    fn delete(&self, id: &str) -> Result<bool, StoreError> {
        let mut conn = self.writer.lock();
        let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate).map_err(db)?;
        let objects = object_keys(&tx, id)?;
        let inputs: Vec<String> = tx
            .prepare_cached("SELECT sha256 FROM job_inputs WHERE job_id = ?1")
            .and_then(|mut s| s.query_map([id], |r| r.get(0))?.collect())
            .map_err(db)?;
        // Artifacts, idempotency keys and the job's inputs go with the job (ON DELETE CASCADE);
        // an upload no other job reads goes with it too.
        let n = tx.prepare_cached("DELETE FROM jobs WHERE id = ?1").map_err(db)?.execute([id]).map_err(db)?;
        for sha256 in &inputs {
            tx.prepare_cached(
                "DELETE FROM inputs WHERE sha256 = ?1 AND NOT EXISTS (SELECT 1 FROM job_inputs WHERE sha256 = ?1)",
            )
            .and_then(|mut s| s.execute([sha256]))
            .map_err(db)?;
        }
        tx.commit().map_err(db)?;
        drop(conn);
        self.remove_objects(&objects);
        Ok(n > 0)
    }

    fn unfinished(&self) -> Result<Vec<Job>, StoreError> {
        let sql = format!("SELECT {JOB_COLUMNS} FROM jobs WHERE status IN ('queued', 'running') ORDER BY id ASC");
        read_snapshot(&mut self.reader(), |c| load_jobs(c, &sql, []))
    }

    fn input(&self, sha256: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let conn = self.reader();
        conn.prepare_cached("SELECT data FROM inputs WHERE sha256 = ?1")
            .and_then(|mut s| s.query_row([sha256], |r| r.get(0)).optional())
            .map_err(db)
    }

    fn has_input(&self, sha256: &str, owner: Option<&str>) -> Result<bool, StoreError> {
        let conn = self.reader();
        conn.prepare_cached(
            "SELECT 1 FROM job_inputs JOIN jobs ON jobs.id = job_inputs.job_id \
             WHERE job_inputs.sha256 = ?1 AND jobs.owner IS ?2 \
             AND EXISTS (SELECT 1 FROM inputs WHERE inputs.sha256 = ?1) LIMIT 1",
        )
        .and_then(|mut s| s.exists(params![sha256, owner]))
        .map_err(db)
    }

    fn queued(&self) -> Result<u64, StoreError> {
        let n: i64 = self
            .reader()
            .prepare_cached("SELECT COUNT(*) FROM jobs WHERE status = 'queued'")
            .and_then(|mut s| s.query_row([], |r| r.get(0)))
            .map_err(db)?;
        Ok(n.max(0) as u64)
    }

    fn counts(&self) -> Result<Vec<(String, JobStatus, u64)>, StoreError> {
        let conn = self.reader();
        let mut stmt = conn
            .prepare_cached("SELECT kind, status, COUNT(*) FROM jobs GROUP BY kind, status ORDER BY kind, status")
            .map_err(db)?;
        let rows = stmt
            .query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, String>(1)?, r.get::<_, i64>(2)?)))
            .map_err(db)?;
        let mut out = Vec::new();
        for row in rows {
            let (kind, status, n) = row.map_err(db)?;
            let status = JobStatus::parse(&status)
                .ok_or_else(|| StoreError::Corrupt(format!("a {kind} job has unknown status {status:?}")))?;
            out.push((kind, status, n as u64));
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::model::Progress;
    use crate::store::contract::*;
    use chrono::TimeZone;

    fn fixture() -> Option<Fixture> {
        let (dir, _path, store) = temp_store();
        Some(Fixture { store: Box::new(store), _guard: Box::new(dir) })
    }

    crate::store_contract_tests!(fixture);

    /// The whole contract again with artifacts in an object store (a directory).
    mod with_objects {
        use super::*;
        use crate::store::ObjectArtifacts;

        fn open(dir: &std::path::Path) -> SqliteStore {
            let objects = ObjectArtifacts::open(&format!("file://{}", dir.join("objects").display())).unwrap();
            SqliteStore::open(dir.join("landform.db").to_str().unwrap()).unwrap().with_objects(Some(objects))
        }

        fn fixture() -> Option<Fixture> {
            let dir = tempfile::tempdir().unwrap();
            Some(Fixture { store: Box::new(open(dir.path())), _guard: Box::new(dir) })
        }

        crate::store_contract_tests!(fixture);

        #[test]
        fn objects_hold_the_bytes_and_none_outlives_its_row() {
            let dir = tempfile::tempdir().unwrap();
            crate::store::contract::objects_hold_the_bytes_and_none_outlives_its_row(
                &open(dir.path()),
                &dir.path().join("objects"),
            );
        }
    }

    fn temp_store() -> (tempfile::TempDir, String, SqliteStore) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("landform.db").to_str().unwrap().to_string();
        let store = SqliteStore::open(&path).unwrap();
        (dir, path, store)
    }

    #[test]
    fn reopening_the_file_sees_everything() {
        let (_dir, path, store) = temp_store();
        let mut j = job(1, "weather-column", JobStatus::Queued);
        j.label = Some("durable".into());
        store.insert(&j, Some(("k", "h"))).unwrap();
        j.status = JobStatus::Running;
        j.started_at = Some(Utc.timestamp_opt(1_750_000_010, 0).unwrap());
        store.update(&j).unwrap();
        j.status = JobStatus::Succeeded;
        j.finished_at = Some(Utc.timestamp_opt(1_750_000_020, 0).unwrap());
        store.finish(&j, &artifacts()).unwrap();
        let before = store.get(&j.id).unwrap().unwrap();
        drop(store);

        let store = SqliteStore::open(&path).unwrap();
        assert_eq!(store.get(&j.id).unwrap(), Some(before));
        assert_eq!(store.attempts(&j.id).unwrap(), Some(1));
        assert_eq!(store.artifact(&j.id, "mesh.glb").unwrap().unwrap().1, vec![7; 1000]);
        let again = job(2, "weather-column", JobStatus::Queued);
        assert!(matches!(
            store.insert(&again, Some(("k", "h"))).unwrap(),
            IdempotentInsert::Existing { same_body: true, .. }
        ));
        let conn = Connection::open(&path).unwrap();
        let version: i64 = conn.pragma_query_value(None, "user_version", |r| r.get(0)).unwrap();
        assert_eq!(version, SCHEMA_VERSION);
        let mode: String = conn.pragma_query_value(None, "journal_mode", |r| r.get(0)).unwrap();
        assert_eq!(mode, "wal");
    }

    /// A file written before artifacts were chunked (schema 3, bytes in `artifacts.data`) opens
    /// with its artifacts intact, each now one chunk.
    #[test]
    fn artifacts_stored_whole_by_an_earlier_version_read_back_after_migrating() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.db").to_str().unwrap().to_string();
        {
            let conn = Connection::open(&path).unwrap();
            for sql in &MIGRATIONS[..3] {
                conn.execute_batch(sql).unwrap();
            }
            conn.pragma_update(None, "user_version", 3).unwrap();
            conn.execute(
                "INSERT INTO jobs (id, kind, status, created_at, progress, request) \
                 VALUES ('j1', 'bulldoze', 'succeeded', '2026-01-01T00:00:00.000000000Z', '{}', '{}')",
                [],
            )
            .unwrap();
            for (ordinal, (name, data)) in [("a.bin", vec![1u8, 2, 3, 4, 5]), ("empty.json", vec![])].iter().enumerate()
            {
                conn.execute(
                    "INSERT INTO artifacts (job_id, name, ordinal, media_type, bytes, sha256, data) \
                     VALUES ('j1', ?1, ?2, 'application/octet-stream', ?3, 'x', ?4)",
                    params![name, ordinal as i64, data.len() as i64, data],
                )
                .unwrap();
            }
        }
        let store = SqliteStore::open(&path).unwrap();
        assert_eq!(store.read_artifact("j1", "a.bin", 1, 3).unwrap(), Some(vec![2, 3, 4]));
        assert_eq!(store.artifact("j1", "a.bin").unwrap().unwrap().1, vec![1, 2, 3, 4, 5]);
        assert_eq!(store.artifact("j1", "empty.json").unwrap().unwrap().1, Vec::<u8>::new());
        assert_eq!(store.read_artifact("j1", "empty.json", 0, 10).unwrap(), Some(vec![]));
    }

    #[test]
    fn delete_removes_the_job_its_artifacts_and_its_key() {
        let (_dir, path, store) = temp_store();
        let mut j = job(1, "bulldoze", JobStatus::Running);
        store.insert(&j, Some(("key", "h"))).unwrap();
        j.status = JobStatus::Succeeded;
        store.finish(&j, &artifacts()).unwrap();
        let keep = job(2, "bulldoze", JobStatus::Succeeded);
        store.insert(&keep, None).unwrap();
        store.finish(&keep, &artifacts()).unwrap();

        assert!(store.delete(&j.id).unwrap());
        assert!(!store.delete(&j.id).unwrap());
        assert_eq!(store.get(&j.id).unwrap(), None);
        assert_eq!(store.artifact(&j.id, "mesh.glb").unwrap(), None);

        let conn = Connection::open(&path).unwrap();
        let count = |sql: &str| -> i64 { conn.query_row(sql, [&j.id], |r| r.get(0)).unwrap() };
        assert_eq!(count("SELECT COUNT(*) FROM artifacts WHERE job_id = ?1"), 0);
        assert_eq!(count("SELECT COUNT(*) FROM artifact_chunks WHERE job_id = ?1"), 0);
        assert_eq!(count("SELECT COUNT(*) FROM idempotency_keys WHERE job_id = ?1"), 0);
        assert_eq!(store.get(&keep.id).unwrap().unwrap().artifacts.len(), 3);

        // A job deleted while it ran is not brought back by its last writes.
        store.update(&j).unwrap();
        store.finish(&j, &artifacts()).unwrap();
        assert_eq!(store.get(&j.id).unwrap(), None);
    }

    #[test]
    fn unreadable_rows_are_reported_as_corrupt() {
        let (_dir, path, store) = temp_store();
        let conn = Connection::open(&path).unwrap();
        conn.execute(
            "INSERT INTO jobs (id, kind, status, created_at, progress, request) \
             VALUES ('x1', 'bulldoze', 'exploded', '2025-01-01T00:00:00Z', '{}', '{}')",
            [],
        )
        .unwrap();
        conn.execute(
            "INSERT INTO jobs (id, kind, status, created_at, progress, request) \
             VALUES ('x2', 'bulldoze', 'queued', 'yesterday', ?1, '{}')",
            [serde_json::to_string(&Progress::default()).unwrap()],
        )
        .unwrap();
        assert!(matches!(store.get("x1"), Err(StoreError::Corrupt(m)) if m.contains("exploded")));
        assert!(matches!(store.get("x2"), Err(StoreError::Corrupt(m)) if m.contains("created_at")));
        assert!(matches!(store.counts(), Err(StoreError::Corrupt(_))));
    }

    #[test]
    fn a_newer_schema_is_refused_and_a_non_database_is_corrupt() {
        let dir = tempfile::tempdir().unwrap();
        let newer = dir.path().join("newer.db");
        Connection::open(&newer).unwrap().pragma_update(None, "user_version", SCHEMA_VERSION + 1).unwrap();
        let err = SqliteStore::open(newer.to_str().unwrap()).unwrap_err();
        assert!(err.to_string().contains("schema version"), "{err}");

        let junk = dir.path().join("junk.db");
        std::fs::write(&junk, vec![b'x'; 4096]).unwrap();
        assert!(matches!(SqliteStore::open(junk.to_str().unwrap()), Err(StoreError::Corrupt(_))));
    }

    #[test]
    fn an_in_memory_store_works_for_quick_tests() {
        let store = SqliteStore::open(":memory:").unwrap();
        let mut j = job(1, "bulldoze", JobStatus::Running);
        store.insert(&j, None).unwrap();
        j.status = JobStatus::Succeeded;
        store.finish(&j, &artifacts()).unwrap();
        assert_eq!(store.get(&j.id).unwrap().unwrap().artifacts.len(), 3);
        assert_eq!(store.list(&ListFilter::default()).unwrap().len(), 1);
    }

    #[test]
    fn readers_see_writes_from_other_threads() {
        let (_dir, _path, store) = temp_store();
        let store = Arc::new(store);
        let writer = {
            let store = store.clone();
            std::thread::spawn(move || {
                for n in 0..50 {
                    let mut j = job(n, "bulldoze", JobStatus::Running);
                    store.insert(&j, None).unwrap();
                    j.status = JobStatus::Succeeded;
                    store.finish(&j, &artifacts()).unwrap();
                }
            })
        };
        let readers: Vec<_> = (0..3)
            .map(|_| {
                let store = store.clone();
                std::thread::spawn(move || {
                    for _ in 0..50 {
                        for j in store.list(&ListFilter { limit: 10, ..Default::default() }).unwrap() {
                            // One snapshot: a succeeded job always shows all its artifacts.
                            if j.status == JobStatus::Succeeded {
                                assert_eq!(j.artifacts.len(), 3);
                            }
                        }
                    }
                })
            })
            .collect();
        writer.join().unwrap();
        for r in readers {
            r.join().unwrap();
        }
        assert_eq!(store.list(&ListFilter::default()).unwrap().len(), 50);
    }
}
