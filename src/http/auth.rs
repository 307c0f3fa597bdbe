//! API keys: optional bearer keys, each with a name that owns the jobs made with it, and
//! per-key quotas (submissions per minute, jobs queued or running at once, memory reserved at
//! once). Keys are compared in constant time (as sha256 digests, so their length leaks
//! nothing either) and never logged: only their names appear in logs and the store.

use std::collections::HashMap;
use std::num::NonZeroU32;
use std::time::Duration;

use axum::extract::{Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use governor::clock::{Clock, DefaultClock};
use governor::{DefaultDirectRateLimiter, Quota, RateLimiter};
use sha2::{Digest, Sha256};
use subtle::ConstantTimeEq;

use super::{AppState, Problem};

/// What one key may do at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyLimits {
    /// Submissions (new jobs and replays) per minute, in a burst of up to this many.
    pub submissions_per_minute: u32,
    /// Jobs queued or running at once.
    pub active_jobs: u32,
    /// Estimated memory of its queued and running jobs at once, bytes.
    pub memory_bytes: u64,
}

pub const DEFAULT_KEY_SUBMISSIONS_PER_MINUTE: u32 = 120;
pub const DEFAULT_KEY_ACTIVE_JOBS: u32 = 16;

struct ApiKey {
    name: String,
    digest: [u8; 32],
    limits: KeyLimits,
}

/// The configured keys, or none (then every call is anonymous and nothing is checked).
pub struct ApiKeys {
    keys: Vec<ApiKey>,
    limiters: HashMap<String, DefaultDirectRateLimiter>,
    clock: DefaultClock,
    /// `/metrics` and `/docs` (with `/openapi.json`) need a key too.
    pub protect_operations: bool,
    /// `/metrics` answers without a key (it needs one by default when there are keys: it counts
    /// every key's jobs).
    pub public_metrics: bool,
}

impl std::fmt::Debug for ApiKeys {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Names only: a key never reaches a log.
        f.debug_struct("ApiKeys").field("names", &self.keys.iter().map(|k| &k.name).collect::<Vec<_>>()).finish()
    }
}

#[derive(Debug, thiserror::Error)]
pub enum KeysError {
    #[error("API keys line {line}: {message}")]
    Line { line: usize, message: String },
    #[error("API keys: {0}")]
    Other(String),
}

fn digest(key: &str) -> [u8; 32] {
    Sha256::digest(key.as_bytes()).into()
}

/// Shortest key accepted: a key must not be guessable.
const MIN_KEY_CHARS: usize = 16;

impl ApiKeys {
    /// Parse the keys file: one key a line, `NAME KEY [submissions_per_minute=N] [active_jobs=N]
    /// [memory_bytes=N]`; blank lines and lines starting with `#` are skipped. Names are unique
    /// and made of letters, digits, `-`, `_` and `.`.
    pub fn parse(text: &str, defaults: KeyLimits, protect_operations: bool) -> Result<Self, KeysError> {
        let mut keys: Vec<ApiKey> = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = i + 1;
            let err = |message: String| KeysError::Line { line, message };
            let trimmed = raw.trim();
            if trimmed.is_empty() || trimmed.starts_with('#') {
                continue;
            }
            let mut words = trimmed.split_whitespace();
            let name = words.next().unwrap_or_default().to_string();
            let key = words.next().ok_or_else(|| err("expected `NAME KEY`".into()))?;
            if !name.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c)) || name.len() > 64 {
                return Err(err("a name is 1 to 64 letters, digits, `-`, `_` or `.`".into()));
            }
            if key.len() < MIN_KEY_CHARS || !key.chars().all(|c| c.is_ascii_graphic()) {
                return Err(err(format!("a key is at least {MIN_KEY_CHARS} visible ASCII characters")));
            }
            let mut limits = defaults;
            for option in words {
                let (k, v) = option.split_once('=').ok_or_else(|| err(format!("expected name=value, got {option}")))?;
                let bad = || err(format!("{k} must be a positive whole number"));
                match k {
                    "submissions_per_minute" => {
                        limits.submissions_per_minute = v.parse().ok().filter(|&n| n > 0).ok_or_else(bad)?
                    }
                    "active_jobs" => limits.active_jobs = v.parse().ok().filter(|&n| n > 0).ok_or_else(bad)?,
                    "memory_bytes" => limits.memory_bytes = v.parse().ok().filter(|&n| n > 0).ok_or_else(bad)?,
                    _ => return Err(err(format!("unknown option {k}"))),
                }
            }
            if keys.iter().any(|k| k.name == name) {
                return Err(err(format!("the name {name} is used twice")));
            }
            let d = digest(key);
            if keys.iter().any(|k| bool::from(k.digest.ct_eq(&d))) {
                return Err(err("the same key is given twice".into()));
            }
            keys.push(ApiKey { name, digest: d, limits });
        }
        if keys.is_empty() {
            return Err(KeysError::Other("the keys file has no key".into()));
        }
        let limiters = keys
            .iter()
            .map(|k| {
                let n = NonZeroU32::new(k.limits.submissions_per_minute).unwrap_or(NonZeroU32::MIN);
                (k.name.clone(), RateLimiter::direct(Quota::per_minute(n)))
            })
            .collect();
        Ok(Self { keys, limiters, clock: DefaultClock::default(), protect_operations, public_metrics: false })
    }

    /// The key's entry, comparing against every key in constant time.
    fn find(&self, presented: &str) -> Option<&ApiKey> {
        let d = digest(presented);
        let mut found = None;
        for k in &self.keys {
            // No early exit: every key is compared whichever matches.
            if bool::from(k.digest.ct_eq(&d)) {
                found = Some(k);
            }
        }
        found
    }

    pub fn limits(&self, name: &str) -> Option<KeyLimits> {
        self.keys.iter().find(|k| k.name == name).map(|k| k.limits)
    }

    /// Count one submission against the key's rate; `Err(wait)` when over it.
    pub fn check_rate(&self, name: &str) -> Result<(), Duration> {
        match self.limiters.get(name) {
            Some(l) => l.check().map_err(|not_until| not_until.wait_time_from(self.clock.now())),
            None => Ok(()),
        }
    }
}

/// Who is calling: the name of the key presented, or nobody when the server has no keys.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Caller(pub Option<String>);

impl Caller {
    pub fn owner(&self) -> Option<&str> {
        self.0.as_deref()
    }
}

impl<S: Send + Sync> axum::extract::FromRequestParts<S> for Caller {
    type Rejection = std::convert::Infallible;

    async fn from_request_parts(parts: &mut axum::http::request::Parts, _: &S) -> Result<Self, Self::Rejection> {
        Ok(parts.extensions.get::<Caller>().cloned().unwrap_or_default())
    }
}

fn unauthorized(detail: &str) -> Response {
    let mut res = Problem::new(StatusCode::UNAUTHORIZED, "unauthorized", "Unauthorized", detail).into_response();
    res.headers_mut().insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer realm=\"landform\""));
    res
}

/// Middleware: with keys configured, a call needs `Authorization: Bearer <key>` of a known key;
/// the key's name goes into the request as its [`Caller`].
pub async fn require_key(State(state): State<AppState>, mut req: Request, next: Next) -> Response {
    let Some(keys) = state.config.keys.as_ref() else {
        return next.run(req).await;
    };
    if req.method() == axum::http::Method::OPTIONS {
        // CORS preflights carry no credentials.
        return next.run(req).await;
    }
    let presented = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer ").or_else(|| v.strip_prefix("bearer ")))
        .map(str::trim);
    let Some(presented) = presented else {
        return unauthorized("this server needs an API key: send `Authorization: Bearer <key>`");
    };
    let Some(key) = keys.find(presented) else {
        return unauthorized("the API key is not known to this server");
    };
    req.extensions_mut().insert(Caller(Some(key.name.clone())));
    next.run(req).await
}

/// Who submits: the caller's key name and its quotas, after counting the submission against
/// its rate (429 with `Retry-After` when over it).
pub fn submitter(state: &AppState, caller: &Caller) -> Result<crate::jobs::Submitter, Problem> {
    let (Some(keys), Some(name)) = (state.config.keys.as_ref(), caller.owner()) else {
        return Ok(crate::jobs::Submitter::default());
    };
    let limits = keys.limits(name).ok_or_else(super::problem::internal)?;
    keys.check_rate(name).map_err(|wait| {
        too_many(
            format!("this key may submit {} jobs a minute; wait before the next", limits.submissions_per_minute),
            wait,
        )
    })?;
    Ok(crate::jobs::Submitter {
        owner: Some(name.to_string()),
        max_active_jobs: Some(limits.active_jobs),
        max_memory_bytes: Some(limits.memory_bytes),
    })
}

/// A 429 with `Retry-After`.
pub fn too_many(detail: String, retry_after: Duration) -> Problem {
    Problem {
        retry_after_s: Some(retry_after.as_secs_f64().ceil().max(1.0) as u32),
        ..Problem::new(StatusCode::TOO_MANY_REQUESTS, "quota-exceeded", "Quota exceeded", detail)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEFAULTS: KeyLimits = KeyLimits { submissions_per_minute: 2, active_jobs: 3, memory_bytes: 1 << 30 };

    #[test]
    fn keys_file_lines_give_names_keys_and_limits() {
        let keys = ApiKeys::parse(
            "# comment\n\nalice aaaaaaaaaaaaaaaaaaaa\nbob bbbbbbbbbbbbbbbbbbbb active_jobs=9 memory_bytes=5\n",
            DEFAULTS,
            false,
        )
        .unwrap();
        assert_eq!(keys.find("aaaaaaaaaaaaaaaaaaaa").map(|k| k.name.as_str()), Some("alice"));
        assert_eq!(keys.find("bbbbbbbbbbbbbbbbbbbb").map(|k| k.name.as_str()), Some("bob"));
        assert!(keys.find("aaaaaaaaaaaaaaaaaaab").is_none());
        assert_eq!(keys.limits("alice"), Some(DEFAULTS));
        assert_eq!(keys.limits("bob"), Some(KeyLimits { active_jobs: 9, memory_bytes: 5, ..DEFAULTS }));
    }

    #[test]
    fn bad_keys_files_are_refused_with_their_line() {
        for (text, line) in [
            ("alice", 1),
            ("alice short", 1),
            ("a aaaaaaaaaaaaaaaaaaaa\na aaaaaaaaaaaaaaaaaaab", 2),
            ("a aaaaaaaaaaaaaaaaaaaa\nb aaaaaaaaaaaaaaaaaaaa", 2),
            ("a aaaaaaaaaaaaaaaaaaaa active_jobs=0", 1),
            ("a aaaaaaaaaaaaaaaaaaaa colour=red", 1),
            ("bad/name aaaaaaaaaaaaaaaaaaaa", 1),
        ] {
            match ApiKeys::parse(text, DEFAULTS, false) {
                Err(KeysError::Line { line: l, .. }) => assert_eq!(l, line, "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        }
        assert!(ApiKeys::parse("# nothing", DEFAULTS, false).is_err());
    }

    #[test]
    fn the_rate_limit_allows_a_burst_then_says_how_long_to_wait() {
        let keys = ApiKeys::parse("a aaaaaaaaaaaaaaaaaaaa", DEFAULTS, false).unwrap();
        assert!(keys.check_rate("a").is_ok());
        assert!(keys.check_rate("a").is_ok());
        let wait = keys.check_rate("a").unwrap_err();
        assert!(wait > Duration::from_secs(20) && wait <= Duration::from_secs(30), "{wait:?}");
    }
}
