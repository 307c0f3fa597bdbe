//! A job as the stores keep it: every column encoded as text before a connection is locked
//! (JSON, fixed-width RFC 3339 timestamps), and decoded back, the same for every backend.

use chrono::{DateTime, SecondsFormat, Utc};
use serde_json::Value;
use sha2::{Digest, Sha256};

use super::StoreError;
use crate::export::Artifact;
use crate::model::{ArtifactMeta, Job, JobStatus, Progress, SUMMARY_REQUEST_BYTES};

/// The job columns every query reads, in the order `RawJob` takes them.
pub(super) const JOB_COLUMNS: &str = "id, kind, status, label, created_at, started_at, finished_at, progress, \
                           request, result, error, replay_of, replay_until_step, cost, owner";

/// What a summary reads for a request over [`SUMMARY_REQUEST_BYTES`] instead of its text (no
/// stored request is this text: every one has a seed).
const OMITTED_REQUEST: &str = "{\"request omitted\":true}";

/// [`JOB_COLUMNS`] for job summaries (lists): a request over [`SUMMARY_REQUEST_BYTES`] is not
/// read at all, so a page costs the same whatever its jobs' sizes. `octet_length`, not
/// `length`: SQLite counts a text's characters by reading it whole, but takes its byte length
/// from the row's header; PostgreSQL takes it from the TOAST header.
pub(super) fn summary_columns() -> String {
    JOB_COLUMNS.replace(
        "request,",
        &format!(
            "CASE WHEN octet_length(request) <= {SUMMARY_REQUEST_BYTES} THEN request ELSE '{OMITTED_REQUEST}' END,"
        ),
    )
}

pub(super) fn timestamp(t: &DateTime<Utc>) -> String {
    // Fixed width (nanoseconds, `Z`): lossless, and text order is time order.
    t.to_rfc3339_opts(SecondsFormat::Nanos, true)
}

pub(super) fn to_json<T: serde::Serialize>(what: &str, v: &T) -> Result<String, StoreError> {
    serde_json::to_string(v).map_err(|e| StoreError::Backend(format!("cannot encode {what}: {e}")))
}

/// A job's columns, encoded before any connection is locked.
pub(super) struct JobRow<'a> {
    pub job: &'a Job,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    pub progress: String,
    pub request: String,
    pub result: Option<String>,
    pub error: Option<String>,
    pub replay_until_step: Option<i64>,
    pub cost: Option<String>,
    /// The estimate's peak memory, a column of its own so a claim can compare it in SQL.
    pub memory_bytes: i64,
    /// Write only while the job's attempt number is this one (a claim's fence), when set.
    pub fence: Option<i64>,
}

impl<'a> JobRow<'a> {
    /// The same row, written only under the claim whose attempt number is `attempt`.
    pub fn fenced(self, attempt: u32) -> Self {
        Self { fence: Some(i64::from(attempt)), ..self }
    }

    pub fn encode(job: &'a Job) -> Result<Self, StoreError> {
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
            cost: job.cost.as_ref().map(|v| to_json("cost", v)).transpose()?,
            memory_bytes: job.cost.as_ref().map_or(0, |c| i64::try_from(c.memory_bytes).unwrap_or(i64::MAX)),
            fence: None,
        })
    }
}

/// A job row as read, before its text is parsed.
pub(super) struct RawJob {
    pub id: String,
    pub kind: String,
    pub status: String,
    pub label: Option<String>,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    pub progress: String,
    pub request: String,
    pub result: Option<String>,
    pub error: Option<String>,
    pub replay_of: Option<String>,
    pub replay_until_step: Option<i64>,
    pub cost: Option<String>,
    pub owner: Option<String>,
}

impl RawJob {
    pub fn into_job(self, artifacts: Vec<ArtifactMeta>) -> Result<Job, StoreError> {
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
            request_omitted: self.request == OMITTED_REQUEST,
            request: if self.request == OMITTED_REQUEST {
                Value::Object(Default::default())
            } else {
                json("request", &self.request)?
            },
            result: self.result.map(|s| json("result", &s)).transpose()?,
            artifacts,
            error: self.error.map(|s| json("error", &s)).transpose()?,
            replay_of: self.replay_of,
            replay_until_step,
            cost: self.cost.map(|s| serde_json::from_str(&s).map_err(|e| bad("cost", e.to_string()))).transpose()?,
            owner: self.owner,
            id,
        })
    }
}

pub(super) fn describe(artifacts: &[Artifact]) -> Result<Vec<ArtifactMeta>, StoreError> {
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
