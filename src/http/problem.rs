//! The one error type at the HTTP edge: every failure becomes an RFC 9457 problem+json.

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use crate::jobs::EngineError;
use crate::validate::FieldError;

/// An RFC 9457 problem. Validation problems list each bad field by its JSON path.
#[derive(Debug, Serialize, ToSchema)]
pub struct Problem {
    #[serde(rename = "type")]
    pub type_uri: String,
    pub title: String,
    pub status: u16,
    pub detail: String,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub errors: Vec<FieldError>,
    #[serde(skip)]
    #[schema(ignore)]
    pub retry_after_s: Option<u64>,
}

impl Problem {
    pub fn new(status: StatusCode, slug: &str, title: &str, detail: impl Into<String>) -> Self {
        Self {
            type_uri: format!("{}/{slug}", crate::jobs::PROBLEM_TYPE_BASE),
            title: title.to_string(),
            status: status.as_u16(),
            detail: detail.into(),
            errors: Vec::new(),
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
        Self { errors, ..Self::new(status, slug, title, detail) }
    }

    pub fn field(field: &str, message: impl Into<String>) -> Self {
        Self::invalid(vec![FieldError { field: field.to_string(), message: message.into() }], false)
    }
}

impl IntoResponse for Problem {
    fn into_response(self) -> Response {
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
        }
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
