//! Routes, handlers, problem errors, server-sent events and the OpenAPI document.

pub mod auth;
mod body;
mod drafts;
mod guard;
mod jobs;
mod openapi;
mod openapi_bounds;
mod ops;
mod playground;
mod presets;
mod problem;
mod rejections;
pub mod server;

use std::sync::Arc;
use std::time::Duration;

use axum::extract::{DefaultBodyLimit, State};
use axum::http::{header, HeaderName, HeaderValue, Method};
use axum::middleware;
use axum::routing::{get, post};
use axum::Router;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::sensitive_headers::SetSensitiveRequestHeadersLayer;
use tower_http::trace::TraceLayer;

pub use auth::{ApiKeys, Caller, KeyLimits};
pub use openapi::{openapi_document, openapi_yaml};
pub use problem::Problem;

use crate::jobs::Engine;

/// What the HTTP layer needs besides the engine.
#[derive(Clone, Debug)]
pub struct HttpConfig {
    /// Largest request body accepted (413 beyond).
    pub max_body_bytes: usize,
    /// Origins allowed by CORS (and to change state from their pages); `*` allows any; none:
    /// only the server's own pages.
    pub cors_origins: Vec<String>,
    /// API keys; none: every call is anonymous.
    pub keys: Option<Arc<ApiKeys>>,
    /// Time a request's body may take to arrive (408 beyond).
    pub body_timeout: Duration,
}

pub const DEFAULT_MAX_BODY_BYTES: usize = 64 * 1024 * 1024;

impl Default for HttpConfig {
    fn default() -> Self {
        Self {
            max_body_bytes: DEFAULT_MAX_BODY_BYTES,
            cors_origins: Vec::new(),
            keys: None,
            body_timeout: server::ConnectionLimits::default().body_timeout,
        }
    }
}

pub struct App {
    pub engine: Engine,
    pub config: HttpConfig,
    /// Submitted bodies being parsed and prepared at once, in [`PREPARING_UNIT`]s of their
    /// bytes: the largest body allowed and 8 MiB more, so the API's memory for submissions
    /// (tens of times a body while its JSON is parsed and stored) stays that of about one
    /// large body however many arrive together, while small ones go past a large one.
    pub preparing: tokio::sync::Semaphore,
    /// Drafts running (see `drafts::DRAFTS_AT_ONCE`).
    pub drafts: tokio::sync::Semaphore,
}

/// Bytes of a submitted body per permit of [`App::preparing`].
pub const PREPARING_UNIT: usize = 64 << 10;
/// Room beside the largest body for small ones, bytes.
const PREPARING_HEADROOM: usize = 8 << 20;

impl App {
    pub fn new(engine: Engine, config: HttpConfig) -> Self {
        let preparing = tokio::sync::Semaphore::new(Self::preparing_capacity(&config) as usize);
        Self { engine, config, preparing, drafts: tokio::sync::Semaphore::new(drafts::DRAFTS_AT_ONCE) }
    }

    fn preparing_capacity(config: &HttpConfig) -> u32 {
        let units = config.max_body_bytes.saturating_add(PREPARING_HEADROOM).div_ceil(PREPARING_UNIT);
        units.min(u32::MAX as usize) as u32
    }

    /// Permits for preparing a body of `bytes` (at least one, at most all).
    pub fn preparing_units(&self, bytes: usize) -> u32 {
        let units = bytes.div_ceil(PREPARING_UNIT).min(u32::MAX as usize) as u32;
        units.clamp(1, Self::preparing_capacity(&self.config))
    }
}

/// Shared state of every handler.
#[derive(Clone)]
pub struct AppState(pub Arc<App>);

impl std::ops::Deref for AppState {
    type Target = App;
    fn deref(&self) -> &App {
        &self.0
    }
}

impl App {
    /// `kind` as a filter: a registered kind, else a 422 naming the `kind` parameter.
    pub(crate) fn check_kind(&self, kind: &str) -> Result<(), Problem> {
        if self.engine.has_kind(kind) {
            return Ok(());
        }
        Err(Problem::field("kind", format!("must be one of {}", self.engine.kind_names().join(", "))))
    }
}

/// The whole service as one router.
pub fn app(engine: Engine, config: HttpConfig) -> Router {
    let cors = cors_layer(&config.cors_origins);
    let max_body = config.max_body_bytes;
    let body_timeout = config.body_timeout;
    let state = AppState(Arc::new(App::new(engine, config)));
    let doc = openapi_document(&state.engine.kinds(), state.config.keys.is_some());
    let protect_operations = state.config.keys.as_ref().is_some_and(|k| k.protect_operations);
    // With keys, the counts of every key's jobs are not for anyone without one.
    let protect_metrics = state.config.keys.as_ref().is_some_and(|k| protect_operations || !k.public_metrics);
    let needs_key = middleware::from_fn_with_state(state.clone(), auth::require_key);
    let mut v1 = Router::new()
        .route("/v1/jobs", get(jobs::list::list_jobs))
        .route("/v1/jobs/{id}", get(jobs::get::get_job).delete(jobs::delete::delete_job))
        .route("/v1/jobs/{id}/events", get(jobs::events::job_events))
        .route("/v1/jobs/{id}/live.png", get(jobs::live::live_png))
        .route("/v1/jobs/{id}/artifacts/{*name}", get(jobs::artifacts::get_artifact))
        .route("/v1/jobs/{id}/sequence", get(jobs::sequence::get_sequence))
        .route("/v1/jobs/{id}/replay", post(jobs::replay::replay_job))
        .route("/v1/jobs/{id}/cancel", post(jobs::cancel::cancel_job))
        .route("/v1/presets", get(presets::list_presets));
    for kind in state.engine.kind_names() {
        let submit = move |State(state): State<AppState>, caller: Caller, headers, body| {
            jobs::submit::submit_job(state, caller, kind.to_string(), headers, body)
        };
        v1 = v1.route(&format!("/v1/jobs/{kind}"), post(submit));
        let draft = move |State(state): State<AppState>, caller: Caller, body| {
            drafts::run_draft(state, caller, kind.to_string(), body)
        };
        v1 = v1.route(&format!("/v1/drafts/{kind}"), post(draft));
    }
    let v1 = v1.route_layer(needs_key.clone());
    let mut metrics = Router::new().route("/metrics", get(ops::metrics));
    if protect_metrics {
        metrics = metrics.route_layer(needs_key.clone());
    }
    let mut operations = Router::new()
        .merge(utoipa_swagger_ui::SwaggerUi::new("/docs").url("/openapi.json", doc))
        .layer(middleware::map_response(ops::docs_headers));
    if protect_operations {
        operations = operations.route_layer(needs_key);
    }
    Router::new()
        .merge(v1)
        .merge(metrics)
        .merge(operations)
        .route("/healthz", get(ops::healthz))
        .route("/readyz", get(ops::readyz))
        .route("/", get(playground::index))
        .route("/index.html", get(playground::index))
        .route("/assets/{*path}", get(playground::asset))
        .fallback(ops::not_found)
        .method_not_allowed_fallback(ops::method_not_allowed)
        .layer(DefaultBodyLimit::max(max_body))
        .layer(middleware::from_fn_with_state(state.clone(), guard::refuse_cross_site))
        .layer(middleware::map_response(rejections::as_problem))
        .layer(middleware::from_fn(move |req, next| server::body_deadline(body_timeout, req, next)))
        .layer(cors)
        .layer(CatchPanicLayer::custom(|_| {
            use axum::response::IntoResponse;
            problem::internal().into_response()
        }))
        .layer(TraceLayer::new_for_http())
        // Keys never reach a log, whatever the trace level.
        .layer(SetSensitiveRequestHeadersLayer::new([header::AUTHORIZATION]))
        .with_state(state)
}

fn cors_layer(origins: &[String]) -> CorsLayer {
    let allow = if origins.iter().any(|o| o == "*") {
        AllowOrigin::any()
    } else {
        AllowOrigin::list(origins.iter().filter_map(|o| HeaderValue::from_str(o).ok()))
    };
    CorsLayer::new()
        .allow_origin(allow)
        .allow_methods([Method::GET, Method::POST, Method::DELETE, Method::OPTIONS])
        .allow_headers([
            header::CONTENT_TYPE,
            header::IF_NONE_MATCH,
            header::AUTHORIZATION,
            HeaderName::from_static("prefer"),
            HeaderName::from_static("idempotency-key"),
            HeaderName::from_static("last-event-id"),
        ])
        .expose_headers([
            header::LOCATION,
            header::ETAG,
            header::RETRY_AFTER,
            header::WWW_AUTHENTICATE,
            HeaderName::from_static("preference-applied"),
            HeaderName::from_static("landform-draft-seconds"),
            HeaderName::from_static("landform-draft-result"),
        ])
        .max_age(Duration::from_secs(3600))
}
