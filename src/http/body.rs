//! Reading request bodies and headers the same way in every handler.

use std::time::Duration;

use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::http::{HeaderMap, StatusCode};
use serde_json::Value;
use sha2::{Digest, Sha256};

use super::Problem;

/// Most seconds `Prefer: wait=N` may hold a response.
pub const MAX_WAIT_S: u64 = 60;

/// The body as JSON; an empty body is `None`.
pub fn json_body(body: Result<Bytes, BytesRejection>) -> Result<Option<Value>, Problem> {
    let bytes = body.map_err(|rejection| {
        if timed_out(&rejection) {
            Problem::new(
                StatusCode::REQUEST_TIMEOUT,
                "body-timeout",
                "Request body timed out",
                "the request body did not arrive whole within the server's body timeout",
            )
        } else if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE {
            Problem::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                "body-too-large",
                "Request body too large",
                "the request body is larger than the server accepts",
            )
        } else {
            Problem::bad_request(rejection.body_text())
        }
    })?;
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Ok(None);
    }
    let mut de = serde_json::Deserializer::from_slice(&bytes);
    let value: Value = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let field = crate::jobs::path_string(e.path());
        let message = e.into_inner().to_string();
        // serde_json refuses numbers beyond f64 (1e999) while parsing: a bad value, not bad JSON.
        let mut problem = if message.contains("number out of range") {
            Problem::field(&field, "must be a finite number")
        } else {
            Problem::bad_request(format!("the body is not valid JSON: {}", super::problem::clip(message.clone())))
        };
        if problem.errors.is_empty() && !field.is_empty() {
            let (field, message) = (super::problem::clip(field), super::problem::clip(message));
            problem.errors.push(crate::validate::FieldError { field, message });
        }
        problem
    })?;
    de.end().map_err(|e| Problem::bad_request(format!("the body is not valid JSON: {e}")))?;
    Ok(Some(value))
}

/// Whether reading the body stopped at its deadline (`server::body_deadline`).
fn timed_out(rejection: &BytesRejection) -> bool {
    let mut error: Option<&(dyn std::error::Error + 'static)> = Some(rejection);
    while let Some(e) = error {
        if e.is::<super::server::BodyTimedOut>() {
            return true;
        }
        error = e.source();
    }
    rejection.body_text().contains(&super::server::BodyTimedOut.to_string())
}

/// `Prefer: wait=N` (RFC 7240), capped at [`MAX_WAIT_S`].
pub fn prefer_wait(headers: &HeaderMap) -> Option<Duration> {
    headers
        .get_all("prefer")
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split([',', ';']))
        .filter_map(|pref| {
            let (k, v) = pref.trim().split_once('=')?;
            (k.trim().eq_ignore_ascii_case("wait")).then(|| v.trim().trim_matches('"').parse::<u64>().ok())?
        })
        .next()
        .map(|n| Duration::from_secs(n.min(MAX_WAIT_S)))
}

/// sha256 of the JSON with object keys sorted, so key order and spacing don't count.
pub fn canonical_sha256(value: &Value) -> String {
    fn canonical(v: &Value, out: &mut String) {
        match v {
            Value::Object(map) => {
                let mut keys: Vec<_> = map.keys().collect();
                keys.sort();
                out.push('{');
                for (i, k) in keys.into_iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    out.push_str(&Value::String(k.clone()).to_string());
                    out.push(':');
                    canonical(&map[k], out);
                }
                out.push('}');
            }
            Value::Array(items) => {
                out.push('[');
                for (i, item) in items.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    canonical(item, out);
                }
                out.push(']');
            }
            other => out.push_str(&other.to_string()),
        }
    }
    let mut s = String::new();
    canonical(value, &mut s);
    hex::encode(Sha256::digest(s.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    #[test]
    fn prefer_wait_reads_the_wait_preference_and_caps_it() {
        let mut h = HeaderMap::new();
        h.insert("prefer", HeaderValue::from_static("respond-async, wait=5"));
        assert_eq!(prefer_wait(&h), Some(Duration::from_secs(5)));
        h.insert("prefer", HeaderValue::from_static("wait=600"));
        assert_eq!(prefer_wait(&h), Some(Duration::from_secs(MAX_WAIT_S)));
        h.insert("prefer", HeaderValue::from_static("return=minimal"));
        assert_eq!(prefer_wait(&h), None);
    }

    #[test]
    fn canonical_hash_ignores_key_order() {
        let a: Value = serde_json::from_str(r#"{"a":1,"b":{"c":[1,2],"d":null}}"#).unwrap();
        let b: Value = serde_json::from_str(r#"{"b":{"d":null,"c":[1,2]},"a":1}"#).unwrap();
        assert_eq!(canonical_sha256(&a), canonical_sha256(&b));
    }
}
