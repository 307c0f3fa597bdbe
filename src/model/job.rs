//! The job as stored and as served.

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use utoipa::ToSchema;

use super::{Cost, Progress};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum JobStatus {
    Queued,
    Running,
    Succeeded,
    Failed,
    Cancelled,
}

impl JobStatus {
    pub const ALL: [JobStatus; 5] =
        [JobStatus::Queued, JobStatus::Running, JobStatus::Succeeded, JobStatus::Failed, JobStatus::Cancelled];

    pub fn as_str(self) -> &'static str {
        match self {
            JobStatus::Queued => "queued",
            JobStatus::Running => "running",
            JobStatus::Succeeded => "succeeded",
            JobStatus::Failed => "failed",
            JobStatus::Cancelled => "cancelled",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|st| st.as_str() == s)
    }

    pub fn is_terminal(self) -> bool {
        matches!(self, JobStatus::Succeeded | JobStatus::Failed | JobStatus::Cancelled)
    }
}

/// A stored artifact's description; `href` is filled in when served.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ArtifactMeta {
    pub name: String,
    pub media_type: String,
    pub bytes: u64,
    /// Hex sha256 of the bytes; also the artifact's ETag.
    pub sha256: String,
    /// Always present in what the server sends (empty only in what it stores).
    #[serde(default)]
    #[schema(required = true)]
    pub href: String,
}

/// What a replay job rebuilds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReplaySpec {
    pub of: String,
    pub until_step: Option<u64>,
}

/// A job: what was asked, where it is, what it made.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Job {
    /// UUIDv7: sorts by creation time.
    pub id: String,
    pub kind: String,
    pub status: JobStatus,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
    pub created_at: DateTime<Utc>,
    pub started_at: Option<DateTime<Utc>>,
    pub finished_at: Option<DateTime<Utc>>,
    pub progress: Progress,
    /// The parameters with every default filled in, `seed` included. In list items and in an
    /// event stream's `done`, a request whose JSON is over 64 KiB is left out (`{}`, with
    /// `request_omitted`): `GET /v1/jobs/{id}` has it whole.
    #[schema(value_type = Object)]
    pub request: Value,
    /// `request` was left out of this summary for its size (see `request`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub request_omitted: bool,
    /// Kind-specific summary figures once the job has succeeded, and in every kind
    /// `sequence_steps`: the steps of the recorded sequence (the largest `until_step` a replay takes).
    #[schema(value_type = Option<Object>)]
    pub result: Option<Value>,
    pub artifacts: Vec<ArtifactMeta>,
    /// A problem object (RFC 9457) when the job failed or was cancelled.
    #[schema(schema_with = problem_or_null)]
    pub error: Option<Value>,
    /// The job this one replays, if it is a replay.
    pub replay_of: Option<String>,
    /// The step a replay stops after (null: the whole sequence).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub replay_until_step: Option<u64>,
    /// The estimate the job was admitted by.
    pub cost: Option<Cost>,
    /// The name of the API key that made the job (none without keys). Never served.
    #[serde(skip)]
    pub owner: Option<String>,
}

/// Largest request (its JSON's bytes) a job summary carries: a list page or a `done` event costs
/// at most this a job for its request, whatever the requests' sizes.
pub const SUMMARY_REQUEST_BYTES: usize = 64 << 10;

impl Job {
    /// The job as a summary shows it: the request left out when it is over
    /// [`SUMMARY_REQUEST_BYTES`].
    pub fn summarised(mut self) -> Self {
        if !self.request_omitted && json_len(&self.request) > SUMMARY_REQUEST_BYTES {
            self.request = Value::Object(Default::default());
            self.request_omitted = true;
        }
        self
    }

    pub fn replay_spec(&self) -> Option<ReplaySpec> {
        self.replay_of.as_ref().map(|of| ReplaySpec { of: of.clone(), until_step: self.replay_until_step })
    }

    /// The seed the request carries (0 when absent).
    pub fn seed(&self) -> u64 {
        self.request.get("seed").and_then(Value::as_u64).unwrap_or(0)
    }

    /// The kind's own parameters: the request without the common fields.
    pub fn params(&self) -> Value {
        let mut p = self.request.clone();
        if let Some(obj) = p.as_object_mut() {
            obj.remove("seed");
            obj.remove("label");
            obj.remove("compression");
            obj.remove("lods");
        }
        p
    }

    /// Fill artifact links for serving.
    pub fn with_hrefs(mut self) -> Self {
        for a in &mut self.artifacts {
            a.href = format!("/v1/jobs/{}/artifacts/{}", self.id, a.name);
        }
        self
    }
}

/// A writer that only counts the bytes written to it: a serialisation's length without a buffer.
#[derive(Debug, Default)]
pub struct ByteCount(pub usize);

impl std::io::Write for ByteCount {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0 += buf.len();
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Length of a value's compact JSON text, without writing it anywhere.
pub fn json_len(value: &Value) -> usize {
    let mut count = ByteCount(0);
    let _ = serde_json::to_writer(&mut count, value);
    count.0
}

/// `Job.error`'s schema: the HTTP layer's `Problem`, named rather than imported (this layer sits
/// below it), or null.
fn problem_or_null() -> utoipa::openapi::schema::Schema {
    use utoipa::openapi::schema::{OneOfBuilder, Type};
    use utoipa::openapi::{ObjectBuilder, Ref};
    OneOfBuilder::new()
        .item(Ref::from_schema_name("Problem"))
        .item(ObjectBuilder::new().schema_type(Type::Null))
        .description(Some("A problem object (RFC 9457) when the job failed or was cancelled."))
        .build()
        .into()
}
