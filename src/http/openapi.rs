//! The OpenAPI document: the common routes from their annotated handlers, plus one submit
//! operation per registered job kind with that kind's request schema.

use std::sync::Arc;

use utoipa::openapi::path::{HttpMethod, OperationBuilder, ParameterBuilder, ParameterIn};
use utoipa::openapi::request_body::RequestBodyBuilder;
use utoipa::openapi::schema::{AllOfBuilder, ObjectBuilder, SchemaType, Type};
use utoipa::openapi::{Content, OpenApi as OpenApiDoc, Ref, RefOr, Required, ResponseBuilder};
use utoipa::OpenApi;

use super::jobs;
use crate::jobs::JobKind;

#[derive(OpenApi)]
#[openapi(
    info(
        title = "Landform",
        description = "Terrain generation as a service: post a simulation job, follow its progress as a stream, download glTF meshes and PNG images, replay any result exactly or up to a step. Lengths in metres, Y up.",
        license(name = "MIT")
    ),
    paths(
        jobs::list::list_jobs,
        jobs::get::get_job,
        jobs::delete::delete_job,
        jobs::events::job_events,
        jobs::live::live_png,
        jobs::artifacts::get_artifact,
        jobs::sequence::get_sequence,
        jobs::replay::replay_job,
        jobs::cancel::cancel_job,
        super::ops::healthz,
        super::ops::readyz,
        super::ops::metrics,
    ),
    components(schemas(crate::jobs::Job, crate::jobs::JobStatus, crate::jobs::Progress, crate::jobs::ArtifactMeta, crate::validate::FieldError, super::Problem)),
    tags(
        (name = "jobs", description = "Submit, follow, download, replay"),
        (name = "operations", description = "Health, readiness, metrics"),
    )
)]
struct ApiDoc;

fn problem_response(description: &str) -> utoipa::openapi::Response {
    ResponseBuilder::new()
        .description(description)
        .content("application/problem+json", Content::new(Some(Ref::from_schema_name("Problem"))))
        .build()
}

/// The whole document for the given kinds.
pub fn openapi_document(kinds: &[Arc<dyn JobKind>]) -> OpenApiDoc {
    let mut doc = ApiDoc::openapi();
    doc.info.version = env!("CARGO_PKG_VERSION").to_string();
    let components = doc.components.get_or_insert_with(Default::default);
    let common = ObjectBuilder::new()
        .property(
            "seed",
            ObjectBuilder::new()
                .schema_type(SchemaType::new(Type::Integer))
                .format(Some(utoipa::openapi::SchemaFormat::KnownFormat(utoipa::openapi::KnownFormat::Int64)))
                .minimum(Some(0))
                .description(Some(
                    "Seed of every random choice the kind makes (default 0): the same request gives the same bytes. A fractal terrain source has its own `seed`.",
                )),
        )
        .property(
            "label",
            ObjectBuilder::new()
                .schema_type(SchemaType::new(Type::String))
                .max_length(Some(200))
                .description(Some("Free text kept with the job")),
        )
        .build();
    components.schemas.insert("CommonJobFields".into(), RefOr::T(common.into()));

    for kind in kinds {
        let (name, schema, refs) = kind.request_schema();
        components.schemas.insert(name.clone(), schema);
        for (n, s) in refs {
            components.schemas.insert(n, s);
        }
        let body_name = format!("{name}Body");
        let body = AllOfBuilder::new()
            .item(Ref::from_schema_name(&name))
            .item(Ref::from_schema_name("CommonJobFields"))
            .build();
        components.schemas.insert(body_name.clone(), RefOr::T(body.into()));

        let op = OperationBuilder::new()
            .tag("jobs")
            .operation_id(Some(format!("submit_{}", kind.name().replace('-', "_"))))
            .summary(Some(format!("Submit a {} job", kind.name())))
            .description(Some(kind.summary()))
            .parameter(
                ParameterBuilder::new()
                    .name("Prefer")
                    .parameter_in(ParameterIn::Header)
                    .description(Some("`wait=N` (N ≤ 60): hold the answer until the job ends or N seconds pass"))
                    .schema(Some(ObjectBuilder::new().schema_type(SchemaType::new(Type::String)))),
            )
            .parameter(
                ParameterBuilder::new()
                    .name("Idempotency-Key")
                    .parameter_in(ParameterIn::Header)
                    .description(Some(
                        "The same key with the same body returns the existing job; with another body, 409",
                    ))
                    .schema(Some(ObjectBuilder::new().schema_type(SchemaType::new(Type::String)))),
            )
            .request_body(Some(
                RequestBodyBuilder::new()
                    .required(Some(Required::True))
                    .content("application/json", Content::new(Some(Ref::from_schema_name(&body_name))))
                    .build(),
            ))
            .response(
                "202",
                ResponseBuilder::new()
                    .description("Accepted; Location names the job")
                    .content("application/json", Content::new(Some(Ref::from_schema_name("Job"))))
                    .build(),
            )
            .response(
                "200",
                ResponseBuilder::new()
                    .description("Prefer: wait and the job has ended, or an Idempotency-Key seen before with this body")
                    .content("application/json", Content::new(Some(Ref::from_schema_name("Job"))))
                    .build(),
            )
            .response("400", problem_response("The body is not JSON"))
            .response("409", problem_response("Idempotency-Key reused with a different body"))
            .response("413", problem_response("The body or the grid it asks for is too large"))
            .response("422", problem_response("Invalid fields; `errors` names each by its JSON path"))
            .response("503", problem_response("The queue is full; see Retry-After"))
            .build();
        doc.paths.add_path_operation(format!("/v1/jobs/{}", kind.name()), vec![HttpMethod::Post], op);
    }
    doc
}

/// The document as YAML: what `landform openapi` prints and `openapi.yaml` holds.
pub fn openapi_yaml(kinds: &[Arc<dyn JobKind>]) -> String {
    openapi_document(kinds).to_yaml().expect("the OpenAPI document serialises")
}
