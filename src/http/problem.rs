//! The one error type at the HTTP edge: every failure becomes an RFC 9457 problem+json.

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use crate::jobs::EngineError;
use crate::validate::FieldError;

/// An RFC 9457 problem. Validation problems list each bad field by its JSON path.
#[derive(Debug, Serialize)]
pub struct Problem {
    #[serde(rename = "type")]
    pub type_uri: String,
    pub title: String,
    pub status: u16,
    pub detail: String,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub errors: Vec<FieldError>,
    /// What a job would cost against what the server allows, when that is why it was refused.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub cost: Option<Box<CostProblem>>,
    #[serde(skip)]
    pub retry_after_s: Option<u32>,
}

/// The problem's schema written out, so the cost figures are plain optional members.
impl utoipa::PartialSchema for Problem {
    fn schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
        use utoipa::openapi::schema::{ArrayBuilder, ObjectBuilder, SchemaType, Type};
        use utoipa::openapi::{KnownFormat, Ref, SchemaFormat};
        let text = |d: &str| ObjectBuilder::new().schema_type(SchemaType::new(Type::String)).description(Some(d));
        let whole = |d: &str| {
            ObjectBuilder::new()
                .schema_type(SchemaType::new(Type::Integer))
                .format(Some(SchemaFormat::KnownFormat(KnownFormat::Int64)))
                .minimum(Some(0))
                .description(Some(d))
        };
        ObjectBuilder::new()
            .description(Some("An RFC 9457 problem. Validation problems list each bad field by its JSON path."))
            .property("type", text("A URI naming the kind of problem"))
            .required("type")
            .property("title", text("A short summary of the kind of problem"))
            .required("title")
            .property(
                "status",
                ObjectBuilder::new()
                    .schema_type(SchemaType::new(Type::Integer))
                    .minimum(Some(400))
                    .maximum(Some(599))
                    .description(Some("The HTTP status")),
            )
            .required("status")
            .property("detail", text("What went wrong, for a person"))
            .required("detail")
            .property(
                "errors",
                ArrayBuilder::new()
                    .items(Ref::from_schema_name("FieldError"))
                    .description(Some("Each bad field by its JSON path (validation problems)")),
            )
            .property("memory_estimate_bytes", whole("Over the memory budget (413): the job's estimated peak memory"))
            .property("memory_budget_bytes", whole("Over the memory budget (413): the server's budget"))
            .property(
                "work_estimate_seconds",
                ObjectBuilder::new()
                    .schema_type(SchemaType::new(Type::Number))
                    .minimum(Some(0))
                    .description(Some("Over the time limit (422): the least time the job's work would take")),
            )
            .property("time_limit_seconds", whole("Over the time limit (422): the job time limit"))
            .into()
    }
}

impl ToSchema for Problem {}

/// The figures of a request refused for its cost.
#[derive(Debug, Default, Serialize)]
pub struct CostProblem {
    /// Over the memory budget (413): the job's estimated peak memory, bytes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub memory_estimate_bytes: Option<u64>,
    /// Over the memory budget (413): the budget, bytes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub memory_budget_bytes: Option<u64>,
    /// Over the time limit (422): the least time the job's work would take, seconds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub work_estimate_seconds: Option<f64>,
    /// Over the time limit (422): the job time limit, seconds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_limit_seconds: Option<u64>,
}

impl Problem {
    pub fn new(status: StatusCode, slug: &str, title: &str, detail: impl Into<String>) -> Self {
        Self {
            type_uri: format!("{}/{slug}", crate::jobs::PROBLEM_TYPE_BASE),
            title: title.to_string(),
            status: status.as_u16(),
            detail: detail.into(),
            errors: Vec::new(),
            cost: None,
            retry_after_s: None,
        }
    }

    pub fn not_found(detail: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, "not-found", "Not found", detail)
    }

    pub fn bad_request(detail: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, "malformed-request", "Malformed request", detail)
    }

    pub fn invalid(errors: Vec<FieldError>, too_large: bool) -> Self {
        // A request's own text (an unknown field's name, a value) may be megabytes: each is quoted
        // clipped, and only the first errors are listed, so an answer stays small however large
        // the request (a client that never reads it pins no more than a socket buffer).
        let listed = errors.len().min(MAX_ERRORS);
        let errors: Vec<FieldError> = errors
            .into_iter()
            .take(MAX_ERRORS)
            .map(|e| FieldError { field: clip(e.field), message: clip(e.message) })
            .collect();
        let (status, slug, title) = if too_large {
            (StatusCode::PAYLOAD_TOO_LARGE, "too-large", "Request too large")
        } else {
            (StatusCode::UNPROCESSABLE_ENTITY, "invalid-request", "Invalid request")
        };
        let detail = errors
            .iter()
            .map(|e| if e.field.is_empty() { e.message.clone() } else { format!("{}: {}", e.field, e.message) })
            .collect::<Vec<_>>()
            .join("; ");
        let detail = if listed < MAX_ERRORS {
            detail
        } else {
            format!("{detail}; (only the first {MAX_ERRORS} errors are listed)")
        };
        Self { errors, ..Self::new(status, slug, title, detail) }
    }

    pub fn field(field: &str, message: impl Into<String>) -> Self {
        Self::invalid(vec![FieldError { field: field.to_string(), message: message.into() }], false)
    }
}

/// Longest text of a request quoted back in a problem (a field's path, a message), in characters.
pub const MAX_QUOTED_CHARS: usize = 200;
/// Most field errors one problem lists.
pub const MAX_ERRORS: usize = 50;

/// `text`, or its first [`MAX_QUOTED_CHARS`] characters and how many more there were.
pub fn clip(text: String) -> String {
    match text.char_indices().nth(MAX_QUOTED_CHARS) {
        None => text,
        Some((cut, _)) => {
            let more = text[cut..].chars().count();
            format!("{}… ({more} more characters)", &text[..cut])
        }
    }
}

impl IntoResponse for Problem {
    fn into_response(mut self) -> Response {
        // Details are built by many callers, some with a request's text in them (a parser's
        // message quoting the input): the list's entries are already clipped, the detail is
        // clipped here to what they could add up to.
        let most = (MAX_ERRORS + 1) * (2 * MAX_QUOTED_CHARS + 64);
        if self.detail.len() > most {
            let cut = (0..=most).rev().find(|&i| self.detail.is_char_boundary(i)).unwrap_or(0);
            self.detail.truncate(cut);
            self.detail.push('…');
        }
        let status = StatusCode::from_u16(self.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        let body = serde_json::to_vec(&self).unwrap_or_default();
        let mut res = (status, body).into_response();
        res.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static("application/problem+json"));
        if let Some(s) = self.retry_after_s {
            res.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(s));
        }
        res
    }
}

impl From<EngineError> for Problem {
    fn from(e: EngineError) -> Self {
        match e {
            EngineError::UnknownKind(k) => Problem::not_found(format!("no job kind named {k}")),
            EngineError::NotFound(id) => Problem::not_found(format!("no job with id {id}")),
            EngineError::Conflict(m) => Problem::new(StatusCode::CONFLICT, "conflict", "Conflict", m),
            EngineError::QueueFull(n) => Problem {
                retry_after_s: Some(5),
                ..Problem::new(
                    StatusCode::SERVICE_UNAVAILABLE,
                    "queue-full",
                    "Queue full",
                    format!("{n} jobs are already waiting; try again shortly"),
                )
            },
            EngineError::OverBudget { field, needed, budget } => {
                let message = format!(
                    "the job would need about {} of memory (an estimate from this field and the ones it \
                     derives); the server's memory budget is {}",
                    human_bytes(needed),
                    human_bytes(budget)
                );
                Problem {
                    cost: Some(Box::new(CostProblem {
                        memory_estimate_bytes: Some(needed),
                        memory_budget_bytes: Some(budget),
                        ..CostProblem::default()
                    })),
                    ..Problem::invalid(vec![FieldError { field, message }], true)
                }
            }
            EngineError::OverTime { field, seconds, limit } => {
                let message = format!(
                    "the job's work would take at least {seconds:.0} s at the fastest this server runs; the job \
                     time limit is {limit} s"
                );
                Problem {
                    cost: Some(Box::new(CostProblem {
                        work_estimate_seconds: Some(seconds),
                        time_limit_seconds: Some(limit),
                        ..CostProblem::default()
                    })),
                    ..Problem::invalid(vec![FieldError { field, message }], false)
                }
            }
            EngineError::OverQuota(m) => super::auth::too_many(m, std::time::Duration::from_secs(5)),
            EngineError::Malformed(m) => Problem::bad_request(m),
            EngineError::Invalid { errors, too_large } => Problem::invalid(errors, too_large),
            EngineError::Store(err) => {
                tracing::error!(error = %err, "store failure");
                internal()
            }
            EngineError::Internal(err) => {
                tracing::error!(error = %err, "internal failure");
                internal()
            }
            EngineError::Busy(m) => Problem {
                retry_after_s: Some(1),
                ..Problem::new(StatusCode::SERVICE_UNAVAILABLE, "busy", "Too busy for a draft", m)
            },
            EngineError::DraftFailed { message, timed_out: true } => {
                Problem::new(StatusCode::GATEWAY_TIMEOUT, "draft-timeout", "Draft time limit exceeded", message)
            }
            EngineError::DraftFailed { message, timed_out: false } => {
                Problem::new(StatusCode::UNPROCESSABLE_ENTITY, "draft-failed", "Draft failed", message)
            }
        }
    }
}

/// Bytes for a person: `1.5 GiB`.
pub fn human_bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    let mut v = n as f64;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < UNITS.len() {
        v /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{n} bytes")
    } else {
        format!("{v:.1} {}", UNITS[unit])
    }
}

/// A 500 that says nothing of the internals (they go to the log).
pub fn internal() -> Problem {
    Problem::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", "Internal error", "the server failed; see its log")
}

impl From<crate::jobs::RequestError> for Problem {
    fn from(e: crate::jobs::RequestError) -> Self {
        match e {
            crate::jobs::RequestError::Malformed(m) => Problem::bad_request(m),
            crate::jobs::RequestError::Invalid { errors, too_large } => Problem::invalid(errors, too_large),
        }
    }
}
