//! Errors: the server's problem+json answers, typed, and the transport's.

use serde::de::DeserializeOwned;
use serde::Deserialize;
use serde_json::{Map, Value};

/// A bad field, by its JSON path (`terrain.fractal.size`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct FieldError {
    pub field: String,
    pub message: String,
}

/// An RFC 9457 problem, as the server sends it with every error answer.
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct Problem {
    #[serde(rename = "type", default)]
    pub type_uri: String,
    #[serde(default)]
    pub title: String,
    #[serde(default)]
    pub status: u16,
    #[serde(default)]
    pub detail: String,
    /// Each bad field of a 422.
    #[serde(default)]
    pub errors: Vec<FieldError>,
    /// Other members (a refused job's cost figures, say).
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl Problem {
    /// The JSON paths of the bad fields.
    pub fn fields(&self) -> Vec<&str> {
        self.errors.iter().map(|e| e.field.as_str()).collect()
    }
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}: {}", self.status, self.title, self.detail)
    }
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The server answered with an error (its problem+json; a body that is not one is put in
    /// `detail`). `retry_after_s` is the `Retry-After` of a 429 or 503.
    #[error("{problem}")]
    Problem { problem: Box<Problem>, retry_after_s: Option<u64> },
    /// The job ended without succeeding (failed or cancelled): its document, whose `error` is
    /// the problem.
    #[error("job {} ended {}", .0.id, .0.status.as_str())]
    Ended(Box<crate::JobDocument>),
    #[error(transparent)]
    Http(#[from] reqwest::Error),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// The server said something this client does not understand.
    #[error("{0}")]
    Protocol(String),
}

impl Error {
    /// The problem, when the server answered with one.
    pub fn problem(&self) -> Option<&Problem> {
        match self {
            Error::Problem { problem, .. } => Some(problem),
            _ => None,
        }
    }
}

/// The answer, or its problem when its status is not a success.
pub(crate) async fn checked(res: reqwest::Response) -> Result<reqwest::Response, Error> {
    let status = res.status();
    if status.is_success() || status == reqwest::StatusCode::NOT_MODIFIED {
        return Ok(res);
    }
    let retry_after_s = res.headers().get("retry-after").and_then(|v| v.to_str().ok()?.trim().parse().ok());
    let text = res.text().await.unwrap_or_default();
    let problem = serde_json::from_str::<Problem>(&text).ok().filter(|p| p.status != 0).unwrap_or_else(|| Problem {
        type_uri: "about:blank".into(),
        title: status.canonical_reason().unwrap_or("").into(),
        status: status.as_u16(),
        detail: text.chars().take(500).collect(),
        errors: Vec::new(),
        extra: Map::new(),
    });
    Err(Error::Problem { problem: Box::new(problem), retry_after_s })
}

/// A successful answer's JSON body.
pub(crate) async fn json<T: DeserializeOwned>(res: reqwest::Response) -> Result<T, Error> {
    let bytes = checked(res).await?.bytes().await?;
    Ok(serde_json::from_slice(&bytes)?)
}
