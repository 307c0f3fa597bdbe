//! A client of the Landform terrain-generation service, on reqwest (async, rustls).
//!
//! ```no_run
//! # async fn demo() -> Result<(), landform_client::Error> {
//! use landform_client::{Client, Request};
//! let client = Client::new("http://127.0.0.1:8080")?.with_api_key("k-123");
//! let params = client.preset::<landform_client::BulldozeParams>("ziggurat").await?;
//! let job = client.submit(&Request::new(params).seed(7)).await?;
//! let done = job.wait().await?;                       // follows the event stream
//! let glb = job.artifact_bytes("mesh.glb").await?;
//! # Ok(()) }
//! ```
//!
//! The request bodies are the server's own parameter types ([`BulldozeParams`], …), re-exported:
//! a client built from this crate cannot drift from the server it was built with. Untyped
//! bodies go through [`Client::submit_json`]. Every error answer is a [`Problem`]
//! (problem+json) inside [`Error::Problem`].

mod error;
mod events;
mod job;

use std::time::Duration;

use serde::{Deserialize, Serialize};
use serde_json::Value;

pub use error::{Error, FieldError, Problem};
pub use events::{Event, Events};
pub use job::Job;
pub use landform::model::{ArtifactMeta, Job as JobDocument, JobStatus, Progress};
pub use landform::sims::bulldoze::BulldozeParams;
pub use landform::sims::carve_coast::CarveCoastParams;
pub use landform::sims::deform_terrain::DeformTerrainParams;
pub use landform::sims::erode::ErodeParams;
pub use landform::sims::grow_cave::GrowCaveParams;
pub use landform::sims::weather_column::WeatherColumnParams;

/// A job kind's parameters: what `POST /v1/jobs/{NAME}` takes beside the common fields.
pub trait Kind: Serialize + for<'de> Deserialize<'de> {
    /// The kind's name in the path.
    const NAME: &'static str;
}

macro_rules! kinds {
    ($($t:ty => $name:literal),* $(,)?) => { $(impl Kind for $t { const NAME: &'static str = $name; })* };
}
kinds! {
    BulldozeParams => "bulldoze",
    CarveCoastParams => "carve-coast",
    DeformTerrainParams => "deform-terrain",
    ErodeParams => "erode",
    GrowCaveParams => "grow-cave",
    WeatherColumnParams => "weather-column",
}

/// A request body: a kind's parameters and the fields every kind takes.
#[derive(Clone, Debug, Serialize)]
pub struct Request<P> {
    #[serde(flatten)]
    pub params: P,
    /// Seed of every random choice (default 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Free text kept with the job.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
    /// How glb artifacts store their vertices: `none`, `quantize` or `meshopt`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compression: Option<String>,
    /// Levels of detail' bounds (fractions of the scene's longest side); `[]` for none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lods: Option<Vec<f64>>,
}

impl<P: Kind> Request<P> {
    pub fn new(params: P) -> Self {
        Self { params, seed: None, label: None, compression: None, lods: None }
    }
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = Some(seed);
        self
    }
    pub fn label(mut self, label: impl Into<String>) -> Self {
        self.label = Some(label.into());
        self
    }
    pub fn compression(mut self, form: impl Into<String>) -> Self {
        self.compression = Some(form.into());
        self
    }
    pub fn lods(mut self, bounds: impl Into<Vec<f64>>) -> Self {
        self.lods = Some(bounds.into());
        self
    }
}

/// How a job is submitted.
#[derive(Clone, Debug, Default)]
pub struct Submit {
    /// `Idempotency-Key`: the same key and body give the same job; another body, a 409.
    pub idempotency_key: Option<String>,
    /// `Prefer: wait=N` (N ≤ 60): the answer waits until the job ends or N seconds pass.
    pub wait_s: Option<u32>,
}

/// One of the server's examples (`GET /v1/presets`).
#[derive(Clone, Debug, Deserialize)]
pub struct Preset {
    pub kind: String,
    pub name: String,
    pub label: Option<String>,
    pub body: Value,
}

#[derive(Deserialize)]
struct Items<T> {
    items: Vec<T>,
}

/// The routes this client calls (method, OpenAPI path), checked against the server's document
/// by the tests.
pub const ROUTES: &[(&str, &str)] = &[
    ("post", "/v1/jobs/{kind}"),
    ("get", "/v1/jobs/{id}"),
    ("delete", "/v1/jobs/{id}"),
    ("get", "/v1/jobs/{id}/events"),
    ("get", "/v1/jobs/{id}/artifacts/{name}"),
    ("post", "/v1/jobs/{id}/replay"),
    ("post", "/v1/jobs/{id}/cancel"),
    ("get", "/v1/presets"),
];

/// A connection to one server; cheap to clone (the connection pool is shared).
#[derive(Clone, Debug)]
pub struct Client {
    http: reqwest::Client,
    base: String,
    key: Option<String>,
}

impl Client {
    /// A client of the server at `base` (e.g. `http://127.0.0.1:8080`): 30 s to connect, and
    /// 60 s at most between two reads (an idle event stream gets a keep-alive every 15 s, so a
    /// silent connection is a dead one, and the stream resumes on a new one).
    pub fn new(base: impl Into<String>) -> Result<Self, Error> {
        let http = reqwest::Client::builder()
            .connect_timeout(Duration::from_secs(30))
            .read_timeout(Duration::from_secs(60))
            .build()?;
        Ok(Self::with_http(http, base))
    }

    /// A client on a reqwest client of the caller's (timeouts, proxies, TLS roots).
    pub fn with_http(http: reqwest::Client, base: impl Into<String>) -> Self {
        Self { http, base: base.into().trim_end_matches('/').to_string(), key: None }
    }

    /// Send `Authorization: Bearer KEY` with every call.
    pub fn with_api_key(mut self, key: impl Into<String>) -> Self {
        self.key = Some(key.into());
        self
    }

    pub(crate) fn request(&self, method: reqwest::Method, path: &str) -> reqwest::RequestBuilder {
        let r = self.http.request(method, format!("{}{path}", self.base));
        match &self.key {
            Some(k) => r.bearer_auth(k),
            None => r,
        }
    }

    /// Submit a typed request.
    pub async fn submit<P: Kind>(&self, request: &Request<P>) -> Result<Job, Error> {
        self.submit_with(request, &Submit::default()).await
    }

    /// [`Client::submit`] with an idempotency key or a wait.
    pub async fn submit_with<P: Kind>(&self, request: &Request<P>, how: &Submit) -> Result<Job, Error> {
        self.submit_json(P::NAME, &serde_json::to_value(request)?, how).await
    }

    /// Submit an untyped body to `POST /v1/jobs/{kind}`.
    pub async fn submit_json(&self, kind: &str, body: &Value, how: &Submit) -> Result<Job, Error> {
        let mut r = self.request(reqwest::Method::POST, &format!("/v1/jobs/{kind}")).json(body);
        if let Some(key) = &how.idempotency_key {
            r = r.header("idempotency-key", key);
        }
        if let Some(s) = how.wait_s {
            r = r.header("prefer", format!("wait={s}"));
        }
        Ok(Job::new(self.clone(), error::json(r.send().await?).await?))
    }

    /// The job `id`.
    pub async fn job(&self, id: &str) -> Result<Job, Error> {
        let doc = error::json(self.request(reqwest::Method::GET, &format!("/v1/jobs/{id}")).send().await?).await?;
        Ok(Job::new(self.clone(), doc))
    }

    /// The server's examples, of one kind or all.
    pub async fn presets(&self, kind: Option<&str>) -> Result<Vec<Preset>, Error> {
        let mut r = self.request(reqwest::Method::GET, "/v1/presets");
        if let Some(k) = kind {
            r = r.query(&[("kind", k)]);
        }
        Ok(error::json::<Items<Preset>>(r.send().await?).await?.items)
    }

    /// The example `name` of `P`'s kind, as typed parameters (its common fields dropped).
    pub async fn preset<P: Kind>(&self, name: &str) -> Result<P, Error> {
        let found = self.presets(Some(P::NAME)).await?.into_iter().find(|p| p.name == name);
        let Some(Preset { body: Value::Object(mut body), .. }) = found else {
            return Err(Error::Protocol(format!("the server has no {} preset {name:?}", P::NAME)));
        };
        for common in ["seed", "label", "compression", "lods"] {
            body.remove(common);
        }
        Ok(serde_json::from_value(Value::Object(body))?)
    }
}
