//! What the handlers' annotations leave out of the OpenAPI document, filled in once for every
//! operation: the bearer key and its 401, the quota's 429 and the queue's 503 with
//! `Retry-After`, the 500 any route may give, `Location` and `ETag` headers, the formats of
//! the request headers, and the media types binary responses really have. A generated client
//! learns every status and limit from here.

use utoipa::openapi::header::HeaderBuilder;
use utoipa::openapi::path::{Operation, Parameter};
use utoipa::openapi::schema::{AdditionalProperties, ArrayItems, ObjectBuilder, SchemaType, Type};
use utoipa::openapi::security::{Http, HttpAuthScheme, SecurityRequirement, SecurityScheme};
use utoipa::openapi::{Content, OpenApi as OpenApiDoc, RefOr, Response, Schema};

use super::openapi::problem_response;

const BEARER: &str = "bearer";

fn string_schema(pattern: Option<&str>, min: Option<usize>, max: Option<usize>, description: &str) -> Schema {
    ObjectBuilder::new()
        .schema_type(SchemaType::new(Type::String))
        .pattern(pattern)
        .min_length(min)
        .max_length(max)
        .description(Some(description))
        .into()
}

fn binary() -> Content {
    Content::new(Some(
        ObjectBuilder::new()
            .schema_type(SchemaType::new(Type::String))
            .format(Some(utoipa::openapi::SchemaFormat::Custom("binary".into()))),
    ))
}

/// Each header parameter a route reads, with its format.
fn header_schema(name: &str) -> Option<Schema> {
    Some(match name.to_ascii_lowercase().as_str() {
        // RFC 7240: preferences a server does not know are ignored, so any text is valid.
        "prefer" => string_schema(None, None, None, "RFC 7240 preferences; `wait=N` (N up to 60 seconds) is honoured"),
        "idempotency-key" => {
            string_schema(Some("^[!-~]{1,256}$"), Some(1), Some(256), "1 to 256 visible ASCII characters")
        }
        "last-event-id" => string_schema(
            Some("^[0-9]{1,19}$"),
            Some(1),
            Some(19),
            "An event id this server sent (an unsigned integer)",
        ),
        "if-none-match" => string_schema(None, None, None, "ETags from before, as RFC 9110 writes them"),
        // RFC 9110: a Range a server cannot use is ignored, so any text is valid here too.
        "range" => string_schema(None, None, None, "`bytes=FIRST-LAST`, `bytes=FIRST-` or `bytes=-SUFFIX`"),
        _ => return None,
    })
}

fn retry_after() -> utoipa::openapi::header::Header {
    HeaderBuilder::new()
        .schema(ObjectBuilder::new().schema_type(SchemaType::new(Type::Integer)).minimum(Some(1)))
        .description(Some("Seconds to wait before trying again"))
        .build()
}

fn with_retry_after(mut r: Response) -> Response {
    r.headers.insert("Retry-After".into(), retry_after());
    r
}

fn add(op: &mut Operation, status: &str, response: Response) {
    op.responses.responses.entry(status.to_string()).or_insert(RefOr::T(response));
}

/// Close every object of a request schema (`additionalProperties: false`), as serde refuses
/// unknown fields everywhere in a request — enum variants included, which utoipa leaves open.
pub fn close_objects(schema: &mut RefOr<Schema>) {
    let RefOr::T(schema) = schema else { return };
    match schema {
        Schema::Object(o) => {
            if !o.properties.is_empty() && o.additional_properties.is_none() {
                o.additional_properties = Some(Box::new(AdditionalProperties::FreeForm(false)));
            }
            o.properties.values_mut().for_each(close_objects);
        }
        Schema::Array(a) => {
            if let ArrayItems::RefOrSchema(items) = &mut a.items {
                close_objects(items);
            }
        }
        Schema::OneOf(o) => o.items.iter_mut().for_each(close_objects),
        Schema::AllOf(o) => o.items.iter_mut().for_each(close_objects),
        Schema::AnyOf(o) => o.items.iter_mut().for_each(close_objects),
        _ => {}
    }
}

/// A job id: a UUID as the server writes them.
pub const JOB_ID_PATTERN: &str = "^[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}$";

/// Bounds JSON Schema can state that the derives leave out, so that a body valid by the schema
/// is not refused for them (schemathesis's positive data):
/// - a positive `f32` (`exclusiveMinimum: 0`, format `float`) is at least the smallest normal
///   `f32`: a smaller number (`5e-324`) is read as 0 and refused;
/// - a terrain source's `job` is a job id (a UUID);
/// - an explicit list of grow-cave sites has at least one.
pub fn state_bounds(schema: &mut RefOr<Schema>) {
    use utoipa::openapi::schema::{KnownFormat, SchemaFormat};
    use utoipa::Number;
    let RefOr::T(schema) = schema else { return };
    match schema {
        Schema::Object(o) => {
            let is_f32 = matches!(o.format, Some(SchemaFormat::KnownFormat(KnownFormat::Float)));
            let above_zero = matches!(o.exclusive_minimum, Some(Number::Float(z)) if z == 0.0)
                || matches!(o.exclusive_minimum, Some(Number::Int(0) | Number::UInt(0)));
            if is_f32 && above_zero {
                o.exclusive_minimum = None;
                o.minimum = Some(Number::Float(f64::from(f32::MIN_POSITIVE)));
            }
            for (name, property) in o.properties.iter_mut() {
                if let RefOr::T(Schema::Object(p)) = property {
                    if name == "job" && p.pattern.is_none() {
                        p.pattern = Some(JOB_ID_PATTERN.into());
                    }
                }
                if let RefOr::T(Schema::Array(a)) = property {
                    if name == "explicit" && a.min_items.is_none() {
                        a.min_items = Some(1);
                    }
                }
                state_bounds(property);
            }
        }
        Schema::Array(a) => {
            if let ArrayItems::RefOrSchema(items) = &mut a.items {
                state_bounds(items);
            }
        }
        Schema::OneOf(o) => o.items.iter_mut().for_each(state_bounds),
        Schema::AllOf(o) => o.items.iter_mut().for_each(state_bounds),
        Schema::AnyOf(o) => o.items.iter_mut().for_each(state_bounds),
        _ => {}
    }
}

/// Complete every operation of the document.
pub fn complete(doc: &mut OpenApiDoc, keys_required: bool) {
    let components = doc.components.get_or_insert_with(Default::default);
    components.security_schemes.insert(
        BEARER.into(),
        SecurityScheme::Http(
            Http::builder()
                .scheme(HttpAuthScheme::Bearer)
                .description(Some(
                    "An API key, when the server is configured with keys (`--api-keys`): `Authorization: Bearer <key>`",
                ))
                .build(),
        ),
    );
    for (path, item) in doc.paths.paths.iter_mut() {
        let v1 = path.starts_with("/v1/");
        let ops = [
            (&mut item.get, false),
            (&mut item.post, true),
            (&mut item.delete, true),
            (&mut item.put, true),
            (&mut item.patch, true),
        ];
        for (op, changes_state) in ops {
            if let Some(op) = op {
                complete_operation(path, op, v1, keys_required);
                if v1 && changes_state {
                    // See http/guard.rs and http/server.rs.
                    add(
                        op,
                        "403",
                        problem_response(
                            "From a page of another origin than the server's own or those `--cors-origins` allows",
                        ),
                    );
                    add(op, "415", problem_response("A body that is not `application/json`"));
                    add(op, "408", problem_response("The body did not arrive whole within the server's body timeout"));
                }
            }
        }
    }
}

fn complete_operation(path: &str, op: &mut Operation, v1: bool, keys_required: bool) {
    for p in op.parameters.iter_mut().flatten() {
        complete_parameter(p);
    }
    let id = op.operation_id.clone().unwrap_or_default();
    let submits = id.starts_with("submit_") || id.starts_with("draft_") || id == "replay_job";
    if v1 {
        add(op, "400", problem_response("A malformed request: its body, a query parameter or a header"));
        add(op, "401", {
            let mut r = problem_response("No key, or a key this server does not know (only when it has keys)");
            r.headers.insert(
                "WWW-Authenticate".into(),
                HeaderBuilder::new()
                    .schema(ObjectBuilder::new().schema_type(SchemaType::new(Type::String)))
                    .description(Some("`Bearer realm=\"landform\"`"))
                    .build(),
            );
            r
        });
        if keys_required {
            op.security = Some(vec![SecurityRequirement::new(BEARER, Vec::<String>::new())]);
        }
    }
    if submits {
        add(
            op,
            "429",
            with_retry_after(problem_response("Over the key's quota: submissions per minute, jobs or memory at once")),
        );
        if let Some(RefOr::T(r)) = op.responses.responses.get_mut("503") {
            r.headers.insert("Retry-After".into(), retry_after());
        }
        if let Some(RefOr::T(r)) = op.responses.responses.get_mut("202") {
            r.headers.insert(
                "Location".into(),
                HeaderBuilder::new()
                    .schema(
                        ObjectBuilder::new()
                            .schema_type(SchemaType::new(Type::String))
                            .pattern(Some("^/v1/jobs/[0-9a-f-]{36}$")),
                    )
                    .description(Some("The job's URL"))
                    .build(),
            );
        }
        add(
            op,
            "413",
            problem_response("The body is too large, or the job's estimated memory is over the server's budget"),
        );
    }
    if path.ends_with("/live.png") || path.ends_with("/sequence") {
        // They serve a stored artifact the same way, ranges included.
        let media = if path.ends_with("/live.png") { "image/png" } else { "application/json" };
        let mut part = Response::new("The requested range of the bytes, with Content-Range");
        part.content.insert(media.into(), binary());
        add(op, "206", part);
        add(op, "416", problem_response("The range lies past the end; Content-Range gives the length"));
    }
    if path.ends_with("/artifacts/{name}") {
        if let Some(RefOr::T(r)) = op.responses.responses.get_mut("206") {
            r.content.clear();
            for media in ["model/gltf-binary", "image/png", "application/octet-stream", "application/json"] {
                r.content.insert(media.into(), binary());
            }
            r.headers.insert(
                "Content-Range".into(),
                HeaderBuilder::new()
                    .schema(
                        ObjectBuilder::new()
                            .schema_type(SchemaType::new(Type::String))
                            .pattern(Some("^bytes [0-9]+-[0-9]+/[0-9]+$")),
                    )
                    .description(Some("`bytes FIRST-LAST/LENGTH`"))
                    .build(),
            );
        }
    }
    if path.ends_with("/artifacts/{name}") || path.ends_with("/live.png") || path.ends_with("/sequence") {
        if let Some(RefOr::T(r)) = op.responses.responses.get_mut("200") {
            if path.ends_with("/artifacts/{name}") {
                r.content.clear();
                for media in ["model/gltf-binary", "image/png", "application/octet-stream"] {
                    r.content.insert(media.into(), binary());
                }
                r.content.insert("application/json".into(), Content::new(Some(ObjectBuilder::new())));
            } else if path.ends_with("/live.png") {
                r.content.clear();
                r.content.insert("image/png".into(), binary());
            }
            r.headers.insert(
                "ETag".into(),
                HeaderBuilder::new()
                    .schema(ObjectBuilder::new().schema_type(SchemaType::new(Type::String)))
                    .description(Some("The quoted sha256 of the bytes (not for live snapshots)"))
                    .build(),
            );
        }
    }
    add(op, "500", problem_response("The server failed; its log has the details"));
}

fn complete_parameter(p: &mut Parameter) {
    if let Some(schema) = header_schema(&p.name) {
        p.schema = Some(RefOr::T(schema));
    }
}
