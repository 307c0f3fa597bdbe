//! Routes, handlers, problem errors, server-sent events and the OpenAPI document.

mod body;
mod jobs;
mod openapi;
mod ops;
mod problem;

use std::sync::Arc;
use std::time::Duration;

use axum::extract::DefaultBodyLimit;
use axum::http::{header, HeaderName, HeaderValue, Method};
use axum::routing::{get, post};
use axum::Router;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::trace::TraceLayer;

pub use openapi::{openapi_document, openapi_yaml};
pub use problem::Problem;

use crate::jobs::Engine;

/// What the HTTP layer needs besides the engine.
#[derive(Clone, Debug)]
pub struct HttpConfig {
    /// Largest request body accepted (413 beyond).
    pub max_body_bytes: usize,
    /// Origins allowed by CORS; `*` allows any.
    pub cors_origins: Vec<String>,
}

pub const DEFAULT_MAX_BODY_BYTES: usize = 64 * 1024 * 1024;

impl Default for HttpConfig {
    fn default() -> Self {
        Self { max_body_bytes: DEFAULT_MAX_BODY_BYTES, cors_origins: vec!["*".into()] }
    }
}

pub struct App {
    pub engine: Engine,
    pub config: HttpConfig,
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

/// The whole service as one router.
pub fn app(engine: Engine, config: HttpConfig) -> Router {
    let cors = cors_layer(&config.cors_origins);
    let max_body = config.max_body_bytes;
    let state = AppState(Arc::new(App { engine, config }));
    let doc = openapi_document(&state.engine.kinds());
    Router::new()
        .route("/v1/jobs", get(jobs::list::list_jobs))
        .route(
            "/v1/jobs/{kind_or_id}",
            post(jobs::submit::submit_job).get(jobs::get::get_job).delete(jobs::delete::delete_job),
        )
        .route("/v1/jobs/{id}/events", get(jobs::events::job_events))
        .route("/v1/jobs/{id}/live.png", get(jobs::live::live_png))
        .route("/v1/jobs/{id}/artifacts/{name}", get(jobs::artifacts::get_artifact))
        .route("/v1/jobs/{id}/sequence", get(jobs::sequence::get_sequence))
        .route("/v1/jobs/{id}/replay", post(jobs::replay::replay_job))
        .route("/v1/jobs/{id}/cancel", post(jobs::cancel::cancel_job))
        .route("/healthz", get(ops::healthz))
        .route("/readyz", get(ops::readyz))
        .route("/metrics", get(ops::metrics))
        .merge(utoipa_swagger_ui::SwaggerUi::new("/docs").url("/openapi.json", doc))
        .fallback(ops::not_found)
        .method_not_allowed_fallback(ops::method_not_allowed)
        .layer(DefaultBodyLimit::max(max_body))
        .layer(cors)
        .layer(CatchPanicLayer::custom(|_| {
            use axum::response::IntoResponse;
            problem::internal().into_response()
        }))
        .layer(TraceLayer::new_for_http())
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
            HeaderName::from_static("prefer"),
            HeaderName::from_static("idempotency-key"),
            HeaderName::from_static("last-event-id"),
        ])
        .expose_headers([
            header::LOCATION,
            header::ETAG,
            header::RETRY_AFTER,
            HeaderName::from_static("preference-applied"),
        ])
        .max_age(Duration::from_secs(3600))
}
