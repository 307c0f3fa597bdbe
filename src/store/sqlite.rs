//! The embedded job store: one SQLite file (WAL mode) holding jobs, their artifacts' bytes and
//! the idempotency keys that created them.
//!
//! Writes go through one mutexed connection in `BEGIN IMMEDIATE` transactions; reads use a
//! small pool of read-only connections, which WAL lets proceed while a write is in flight. Every
//! value is converted (JSON, timestamps, hashes) before a connection is locked, so a lock is held
//! only for the statements themselves.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use chrono::{DateTime, SecondsFormat, Utc};
use parking_lot::{Mutex, MutexGuard};
use rusqlite::types::Value as SqlValue;
use rusqlite::{params, Connection, OpenFlags, OptionalExtension, Row, TransactionBehavior};
use serde_json::Value;
use sha2::{Digest, Sha256};

use super::{IdempotentInsert, JobStore, ListFilter, StoreError};
use crate::jobs::{Artifact, ArtifactMeta, Job, JobStatus, Progress};

/// The schema version this build writes (`PRAGMA user_version`).
pub const SCHEMA_VERSION: i64 = 2;

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
];

/// Read connections opened beside the writer (none for an in-memory database, whose
/// connections would each see a different database).
const READERS: usize = 4;
const BUSY_TIMEOUT: Duration = Duration::from_secs(5);
/// The WAL is truncated back to this size after a checkpoint (large artifacts pass through it).
const JOURNAL_SIZE_LIMIT_BYTES: i64 = 32 * 1024 * 1024;

const JOB_COLUMNS: &str = "id, kind, status, label, created_at, started_at, finished_at, progress, \
                           request, result, error, replay_of, replay_until_step";

/// The SQLite job store. See the module documentation.
pub struct SqliteStore {
    writer: Mutex<Connection>,
    readers: Vec<Mutex<Connection>>,
    next_reader: AtomicUsize,
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
        Ok(Self { writer: Mutex::new(writer), readers, next_reader: AtomicUsize::new(0) })
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

fn is_in_memory(path: &str) -> bool {
    path.is_empty() || path == ":memory:" || path.starts_with("file::memory:") || path.contains("mode=memory")
}

fn configure(conn: &Connection, writer: bool) -> rusqlite::Result<()> {
    conn.busy_timeout(BUSY_TIMEOUT)?;
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

fn timestamp(t: &DateTime<Utc>) -> String {
    // Fixed width (nanoseconds, `Z`): lossless, and text order is time order.
    t.to_rfc3339_opts(SecondsFormat::Nanos, true)
}

fn to_json<T: serde::Serialize>(what: &str, v: &T) -> Result<String, StoreError> {
    serde_json::to_string(v).map_err(|e| StoreError::Backend(format!("cannot encode {what}: {e}")))
}

/// A job's columns, encoded before any connection is locked.
struct JobRow<'a> {
    job: &'a Job,
    created_at: String,
    started_at: Option<String>,
    finished_at: Option<String>,
    progress: String,
    request: String,
    result: Option<String>,
    error: Option<String>,
    replay_until_step: Option<i64>,
}

impl<'a> JobRow<'a> {
    fn encode(job: &'a Job) -> Result<Self, StoreError> {
        let mut progress = job.progress.clone();
        if !progress.fraction.is_finite() {
            // JSON has no NaN: serde_json would write `null`, which reads back as an error.
            progress.fraction = 0.0;
        }
        let replay_until_step = job
            .replay_until_step
            .map(|s| {
                i64::try_from(s).map_err(|_| StoreError::Backend(format!("replay_until_step {s} is out of range")))
            })
            .transpose()?;
        Ok(Self {
            job,
            created_at: timestamp(&job.created_at),
            started_at: job.started_at.as_ref().map(timestamp),
            finished_at: job.finished_at.as_ref().map(timestamp),
            progress: to_json("progress", &progress)?,
            request: to_json("request", &job.request)?,
            result: job.result.as_ref().map(|v| to_json("result", v)).transpose()?,
            error: job.error.as_ref().map(|v| to_json("error", v)).transpose()?,
            replay_until_step,
        })
    }

    fn insert(&self, conn: &Connection) -> rusqlite::Result<()> {
        let j = self.job;
        conn.prepare_cached(
            "INSERT INTO jobs (id, kind, status, label, created_at, started_at, finished_at, \
             progress, request, result, error, replay_of, replay_until_step, attempts) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14)",
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
        ])?;
        Ok(())
    }

    /// Save the mutable columns; false if there is no such job.
    fn update(&self, conn: &Connection) -> rusqlite::Result<bool> {
        let j = self.job;
        // SET expressions see the row as it was, so `status` here is the previous status.
        let changed = conn
            .prepare_cached(
                "UPDATE jobs SET status = ?2, label = ?3, started_at = ?4, finished_at = ?5, \
                 progress = ?6, result = ?7, error = ?8, \
                 attempts = attempts + (?2 = 'running' AND status <> 'running') \
                 WHERE id = ?1",
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
            ])?;
        Ok(changed > 0)
    }
}

/// A job row as read, before its text is parsed.
struct RawJob {
    id: String,
    kind: String,
    status: String,
    label: Option<String>,
    created_at: String,
    started_at: Option<String>,
    finished_at: Option<String>,
    progress: String,
    request: String,
    result: Option<String>,
    error: Option<String>,
    replay_of: Option<String>,
    replay_until_step: Option<i64>,
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
        })
    }

    fn into_job(self, artifacts: Vec<ArtifactMeta>) -> Result<Job, StoreError> {
        let id = self.id;
        let bad = |field: &str, why: String| StoreError::Corrupt(format!("job {id}: {field}: {why}"));
        let time = |field: &str, s: &str| {
            DateTime::parse_from_rfc3339(s)
                .map(|t| t.with_timezone(&Utc))
                .map_err(|e| bad(field, format!("{s:?}: {e}")))
        };
        let json = |field: &str, s: &str| serde_json::from_str::<Value>(s).map_err(|e| bad(field, e.to_string()));
        let status =
            JobStatus::parse(&self.status).ok_or_else(|| bad("status", format!("unknown status {:?}", self.status)))?;
        let progress: Progress = serde_json::from_str(&self.progress).map_err(|e| bad("progress", e.to_string()))?;
        let replay_until_step = self
            .replay_until_step
            .map(|s| u64::try_from(s).map_err(|_| bad("replay_until_step", s.to_string())))
            .transpose()?;
        Ok(Job {
            kind: self.kind,
            status,
            label: self.label,
            created_at: time("created_at", &self.created_at)?,
            started_at: self.started_at.map(|s| time("started_at", &s)).transpose()?,
            finished_at: self.finished_at.map(|s| time("finished_at", &s)).transpose()?,
            progress,
            request: json("request", &self.request)?,
            result: self.result.map(|s| json("result", &s)).transpose()?,
            artifacts,
            error: self.error.map(|s| json("error", &s)).transpose()?,
            replay_of: self.replay_of,
            replay_until_step,
            id,
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
    let raw = conn
        .prepare_cached(&format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = ?1"))
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

fn describe(artifacts: &[Artifact]) -> Result<Vec<ArtifactMeta>, StoreError> {
    let mut metas: Vec<ArtifactMeta> = Vec::with_capacity(artifacts.len());
    for a in artifacts {
        if metas.iter().any(|m| m.name == a.name) {
            return Err(StoreError::Backend(format!("two artifacts are named {:?}", a.name)));
        }
        metas.push(ArtifactMeta {
            name: a.name.clone(),
            media_type: a.media_type.clone(),
            bytes: a.bytes.len() as u64,
            sha256: hex::encode(Sha256::digest(&a.bytes)),
            href: String::new(),
        });
    }
    Ok(metas)
}

impl JobStore for SqliteStore {
    fn attempts(&self, id: &str) -> Result<Option<u32>, StoreError> {
        self.attempts_count(id)
    }

    fn insert(&self, job: &Job, idempotency: Option<(&str, &str)>) -> Result<IdempotentInsert, StoreError> {
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
        if let Some(before) = &filter.before_id {
            conditions.push("id < ?");
            values.push(SqlValue::Text(before.clone()));
        }
        let mut sql = format!("SELECT {JOB_COLUMNS} FROM jobs");
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
        let row = JobRow::encode(job)?;
        let conn = self.writer.lock();
        row.update(&conn).map_err(db)?;
        Ok(())
    }

    /// Replaces any artifacts the job had. A job deleted meanwhile is left deleted.
    fn finish(&self, job: &Job, artifacts: &[Artifact]) -> Result<(), StoreError> {
        let row = JobRow::encode(job)?;
        let metas = describe(artifacts)?;
        let mut conn = self.writer.lock();
        let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate).map_err(db)?;
        if !row.update(&tx).map_err(db)? {
            return Ok(());
        }
        tx.prepare_cached("DELETE FROM artifacts WHERE job_id = ?1").map_err(db)?.execute([&job.id]).map_err(db)?;
        {
            let mut stmt = tx
                .prepare_cached(
                    "INSERT INTO artifacts (job_id, name, ordinal, media_type, bytes, sha256, data) \
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                )
                .map_err(db)?;
            for (ordinal, (a, m)) in artifacts.iter().zip(&metas).enumerate() {
                stmt.execute(params![
                    job.id,
                    m.name,
                    ordinal as i64,
                    m.media_type,
                    a.bytes.len() as i64,
                    m.sha256,
                    a.bytes,
                ])
                .map_err(db)?;
            }
        }
        tx.commit().map_err(db)
    }

    fn artifact(&self, id: &str, name: &str) -> Result<Option<(String, Vec<u8>)>, StoreError> {
        let conn = self.reader();
        let found = conn
            .prepare_cached("SELECT media_type, data FROM artifacts WHERE job_id = ?1 AND name = ?2")
            .map_err(db)?
            .query_row([id, name], |r| Ok((r.get(0)?, r.get(1)?)))
            .optional()
            .map_err(db)?;
        Ok(found)
    }

    fn delete(&self, id: &str) -> Result<bool, StoreError> {
        let conn = self.writer.lock();
        // Artifacts and idempotency keys go with the job (ON DELETE CASCADE).
        let n = conn.prepare_cached("DELETE FROM jobs WHERE id = ?1").map_err(db)?.execute([id]).map_err(db)?;
        Ok(n > 0)
    }

    fn unfinished(&self) -> Result<Vec<Job>, StoreError> {
        let sql = format!("SELECT {JOB_COLUMNS} FROM jobs WHERE status IN ('queued', 'running') ORDER BY id ASC");
        read_snapshot(&mut self.reader(), |c| load_jobs(c, &sql, []))
    }

    fn put_input(&self, sha256: &str, data: &[u8]) -> Result<(), StoreError> {
        let conn = self.writer.lock();
        conn.prepare_cached(
            "INSERT INTO inputs (sha256, bytes, created_at, data) VALUES (?1, ?2, ?3, ?4) ON CONFLICT DO NOTHING",
        )
        .and_then(|mut s| s.execute(rusqlite::params![sha256, data.len() as i64, Utc::now().to_rfc3339(), data]))
        .map_err(db)?;
        Ok(())
    }

    fn input(&self, sha256: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let conn = self.reader();
        conn.prepare_cached("SELECT data FROM inputs WHERE sha256 = ?1")
            .and_then(|mut s| s.query_row([sha256], |r| r.get(0)).optional())
            .map_err(db)
    }

    fn has_input(&self, sha256: &str) -> Result<bool, StoreError> {
        let conn = self.reader();
        conn.prepare_cached("SELECT 1 FROM inputs WHERE sha256 = ?1").and_then(|mut s| s.exists([sha256])).map_err(db)
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

    use chrono::TimeZone;
    use serde_json::json;

    use super::*;

    /// UUIDv7 ids whose order is `n`'s order, as the engine's would be.
    fn id(n: u64) -> String {
        uuid::Builder::from_unix_timestamp_millis(1_750_000_000_000 + n * 1000, &[n as u8; 10]).into_uuid().to_string()
    }

    fn job(n: u64, kind: &str, status: JobStatus) -> Job {
        Job {
            id: id(n),
            kind: kind.to_string(),
            status,
            label: None,
            created_at: Utc.timestamp_opt(1_750_000_000 + n as i64, 0).unwrap(),
            started_at: None,
            finished_at: None,
            progress: Progress::default(),
            request: json!({ "seed": n }),
            result: None,
            artifacts: Vec::new(),
            error: None,
            replay_of: None,
            replay_until_step: None,
        }
    }

    fn temp_store() -> (tempfile::TempDir, String, SqliteStore) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("landform.db").to_str().unwrap().to_string();
        let store = SqliteStore::open(&path).unwrap();
        (dir, path, store)
    }

    fn ids(jobs: &[Job]) -> Vec<String> {
        jobs.iter().map(|j| j.id.clone()).collect()
    }

    fn artifacts() -> Vec<Artifact> {
        vec![
            Artifact::new("mesh.glb", "model/gltf-binary", vec![7; 1000]),
            Artifact::new("heightmap.png", "image/png", b"abc".to_vec()),
            Artifact::new("a-last.json", "application/json", Vec::new()),
        ]
    }

    const SHA256_ABC: &str = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
    const SHA256_EMPTY: &str = "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855";

    #[test]
    fn insert_then_get_round_trips_every_field() {
        let (_dir, _path, store) = temp_store();
        let mut j = job(1, "deform-terrain", JobStatus::Failed);
        j.label = Some("ridge «north»".into());
        j.created_at = Utc.timestamp_opt(1_750_000_001, 123_456_789).unwrap();
        j.started_at = Some(Utc.timestamp_opt(1_750_000_002, 5).unwrap());
        j.finished_at = Some(Utc.timestamp_opt(1_750_000_003, 999_999_999).unwrap());
        j.progress =
            Progress { fraction: 0.25, step: 3, steps: 12, stage: "search".into(), message: "iteration 3".into() };
        j.request = json!({ "seed": 18446744073709551615u64, "terrain": { "fractal": { "size": 65 } } });
        j.result = Some(json!({ "z_min": -1.5, "z_max": 99.25 }));
        j.error = Some(json!({ "type": "about:blank", "status": 500 }));
        j.replay_of = Some(id(0));
        j.replay_until_step = Some(7);

        assert!(matches!(store.insert(&j, None).unwrap(), IdempotentInsert::Inserted));
        assert_eq!(store.get(&j.id).unwrap(), Some(j.clone()));
        assert_eq!(store.get(&id(99)).unwrap(), None);
        assert_eq!(store.attempts(&j.id).unwrap(), Some(0));
    }

    #[test]
    fn list_pages_newest_first_with_filters() {
        let (_dir, _path, store) = temp_store();
        let statuses = [JobStatus::Queued, JobStatus::Succeeded, JobStatus::Failed];
        let mut all = Vec::new();
        for n in 0..10u64 {
            let kind = if n % 2 == 0 { "bulldoze" } else { "grow-cave" };
            let j = job(n, kind, statuses[n as usize % 3]);
            store.insert(&j, None).unwrap();
            all.push(j);
        }
        let newest: Vec<String> = all.iter().rev().map(|j| j.id.clone()).collect();

        let page = |filter: ListFilter| ids(&store.list(&filter).unwrap());
        let first = page(ListFilter { limit: 4, ..Default::default() });
        assert_eq!(first, newest[..4]);
        let second = page(ListFilter { limit: 4, before_id: first.last().cloned(), ..Default::default() });
        assert_eq!(second, newest[4..8]);
        let third = page(ListFilter { limit: 4, before_id: second.last().cloned(), ..Default::default() });
        assert_eq!(third, newest[8..]);
        assert_eq!(page(ListFilter::default()), newest, "limit 0 is no limit");

        let expect = |pred: &dyn Fn(&Job) -> bool| -> Vec<String> {
            all.iter().rev().filter(|j| pred(j)).map(|j| j.id.clone()).collect()
        };
        let caves = page(ListFilter { kind: Some("grow-cave".into()), limit: 100, ..Default::default() });
        assert_eq!(caves, expect(&|j| j.kind == "grow-cave"));
        let failed = page(ListFilter { status: Some(JobStatus::Failed), limit: 100, ..Default::default() });
        assert_eq!(failed, expect(&|j| j.status == JobStatus::Failed));
        let both = page(ListFilter {
            kind: Some("bulldoze".into()),
            status: Some(JobStatus::Queued),
            before_id: Some(id(6)),
            limit: 100,
        });
        assert_eq!(both, vec![id(0)]);
        assert!(page(ListFilter { kind: Some("nope".into()), limit: 5, ..Default::default() }).is_empty());
    }

    #[test]
    fn idempotency_key_returns_the_first_job_and_compares_the_body() {
        let (_dir, _path, store) = temp_store();
        let first = job(1, "bulldoze", JobStatus::Queued);
        let retry = job(2, "bulldoze", JobStatus::Queued);
        let key = Some(("key-1", "aa11"));

        assert!(matches!(store.insert(&first, key).unwrap(), IdempotentInsert::Inserted));
        match store.insert(&retry, key).unwrap() {
            IdempotentInsert::Existing { job, same_body } => {
                assert_eq!(*job, first);
                assert!(same_body);
            }
            other => panic!("expected Existing, got {other:?}"),
        }
        match store.insert(&retry, Some(("key-1", "bb22"))).unwrap() {
            IdempotentInsert::Existing { job, same_body } => {
                assert_eq!(job.id, first.id);
                assert!(!same_body);
            }
            other => panic!("expected Existing, got {other:?}"),
        }
        assert_eq!(store.get(&retry.id).unwrap(), None, "a repeated key writes nothing");

        // Another key is another job; deleting a job frees its key.
        assert!(matches!(store.insert(&retry, Some(("key-2", "aa11"))).unwrap(), IdempotentInsert::Inserted));
        assert!(store.delete(&first.id).unwrap());
        let third = job(3, "bulldoze", JobStatus::Queued);
        assert!(matches!(store.insert(&third, key).unwrap(), IdempotentInsert::Inserted));
    }

    #[test]
    fn finish_stores_artifacts_with_sha256_in_production_order() {
        let (_dir, _path, store) = temp_store();
        let mut j = job(1, "carve-coast", JobStatus::Running);
        store.insert(&j, None).unwrap();
        j.status = JobStatus::Succeeded;
        j.finished_at = Some(Utc.timestamp_opt(1_750_000_100, 0).unwrap());
        j.result = Some(json!({ "caves": 3 }));
        store.finish(&j, &artifacts()).unwrap();

        let got = store.get(&j.id).unwrap().unwrap();
        assert_eq!(got.status, JobStatus::Succeeded);
        assert_eq!(got.result, j.result);
        let names: Vec<&str> = got.artifacts.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, ["mesh.glb", "heightmap.png", "a-last.json"]);
        let png = &got.artifacts[1];
        assert_eq!((png.media_type.as_str(), png.bytes, png.sha256.as_str()), ("image/png", 3, SHA256_ABC));
        assert_eq!(got.artifacts[2].sha256, SHA256_EMPTY);
        assert_eq!(got.artifacts[0].bytes, 1000);
        assert!(got.artifacts.iter().all(|a| a.href.is_empty()));

        assert_eq!(store.artifact(&j.id, "heightmap.png").unwrap(), Some(("image/png".into(), b"abc".to_vec())));
        assert_eq!(store.artifact(&j.id, "a-last.json").unwrap(), Some(("application/json".into(), Vec::new())));
        assert_eq!(store.artifact(&j.id, "nope.bin").unwrap(), None);

        // Finishing again replaces the artifacts.
        store.finish(&j, &[Artifact::new("sequence.json", "application/json", b"[]".to_vec())]).unwrap();
        let got = store.get(&j.id).unwrap().unwrap();
        assert_eq!(ids_of_artifacts(&got), ["sequence.json"]);
        assert_eq!(store.artifact(&j.id, "mesh.glb").unwrap(), None);
    }

    fn ids_of_artifacts(j: &Job) -> Vec<&str> {
        j.artifacts.iter().map(|a| a.name.as_str()).collect()
    }

    #[test]
    fn finish_refuses_duplicate_names_and_leaves_the_job_untouched() {
        let (_dir, _path, store) = temp_store();
        let j = job(1, "bulldoze", JobStatus::Running);
        store.insert(&j, None).unwrap();
        let mut done = j.clone();
        done.status = JobStatus::Succeeded;
        let twice = [Artifact::new("a", "x/y", vec![1]), Artifact::new("a", "x/y", vec![2])];
        assert!(matches!(store.finish(&done, &twice), Err(StoreError::Backend(_))));
        assert_eq!(store.get(&j.id).unwrap(), Some(j));
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
        assert_eq!(count("SELECT COUNT(*) FROM idempotency_keys WHERE job_id = ?1"), 0);
        assert_eq!(store.get(&keep.id).unwrap().unwrap().artifacts.len(), 3);

        // A job deleted while it ran is not brought back by its last writes.
        store.update(&j).unwrap();
        store.finish(&j, &artifacts()).unwrap();
        assert_eq!(store.get(&j.id).unwrap(), None);
    }

    #[test]
    fn unfinished_is_oldest_first_and_counts_group_by_kind_and_status() {
        let (_dir, _path, store) = temp_store();
        let plan = [
            ("bulldoze", JobStatus::Running),
            ("grow-cave", JobStatus::Succeeded),
            ("bulldoze", JobStatus::Queued),
            ("bulldoze", JobStatus::Queued),
            ("grow-cave", JobStatus::Cancelled),
            ("grow-cave", JobStatus::Queued),
        ];
        for (n, (kind, status)) in plan.iter().enumerate() {
            store.insert(&job(n as u64, kind, *status), None).unwrap();
        }
        assert_eq!(ids(&store.unfinished().unwrap()), vec![id(0), id(2), id(3), id(5)]);
        assert_eq!(
            store.counts().unwrap(),
            vec![
                ("bulldoze".to_string(), JobStatus::Queued, 2),
                ("bulldoze".to_string(), JobStatus::Running, 1),
                ("grow-cave".to_string(), JobStatus::Cancelled, 1),
                ("grow-cave".to_string(), JobStatus::Queued, 1),
                ("grow-cave".to_string(), JobStatus::Succeeded, 1),
            ]
        );
    }

    #[test]
    fn attempts_count_each_entry_into_running() {
        let (_dir, _path, store) = temp_store();
        let mut j = job(1, "bulldoze", JobStatus::Queued);
        store.insert(&j, None).unwrap();
        for status in [JobStatus::Running, JobStatus::Running, JobStatus::Queued, JobStatus::Running] {
            j.status = status;
            store.update(&j).unwrap();
        }
        assert_eq!(store.attempts(&j.id).unwrap(), Some(2));
        assert_eq!(store.attempts("missing").unwrap(), None);
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
