//! The OpenAPI document: the common routes from their annotated handlers, plus one submit
//! operation per registered job kind with that kind's request schema.

use std::sync::Arc;

use utoipa::openapi::path::{HttpMethod, OperationBuilder, ParameterBuilder, ParameterIn};
use utoipa::openapi::request_body::RequestBodyBuilder;
use utoipa::openapi::schema::{ObjectBuilder, SchemaType, Type};
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
        super::presets::list_presets,
        super::ops::healthz,
        super::ops::readyz,
        super::ops::metrics,
    ),
    components(schemas(crate::jobs::Job, crate::jobs::JobStatus, crate::jobs::Progress, crate::jobs::ArtifactMeta, crate::validate::FieldError, super::Problem)),
    tags(
        (name = "jobs", description = "Submit, follow, download, replay"),
        (name = "drafts", description = "A request run at once at reduced resolution, answered with its mesh"),
        (name = "operations", description = "Health, readiness, metrics"),
    )
)]
struct ApiDoc;

pub(super) fn problem_response(description: &str) -> utoipa::openapi::Response {
    ResponseBuilder::new()
        .description(description)
        .content("application/problem+json", Content::new(Some(Ref::from_schema_name("Problem"))))
        .build()
}

/// The whole document for the given kinds; with `keys_required`, every `/v1` operation needs
/// the bearer key (the served document says so when the server has keys).
pub fn openapi_document(kinds: &[Arc<dyn JobKind>], keys_required: bool) -> OpenApiDoc {
    let mut doc = ApiDoc::openapi();
    doc.info.version = env!("CARGO_PKG_VERSION").to_string();
    let components = doc.components.get_or_insert_with(Default::default);
    let seed: utoipa::openapi::schema::Schema = ObjectBuilder::new()
        .schema_type(SchemaType::new(Type::Integer))
        .format(Some(utoipa::openapi::SchemaFormat::KnownFormat(utoipa::openapi::KnownFormat::Int64)))
        .minimum(Some(0))
        .maximum(Some(u64::MAX as f64))
        .description(Some(
            "Seed of every random choice the kind makes (default 0): the same request gives the same bytes. A fractal terrain source has its own `seed`.",
        ))
        .into();
    let label: utoipa::openapi::schema::Schema = ObjectBuilder::new()
        .schema_type(SchemaType::new(Type::String))
        .max_length(Some(200))
        .description(Some("Free text kept with the job, at most 200 characters"))
        .into();

    let compression: utoipa::openapi::schema::Schema = ObjectBuilder::new()
        .schema_type(SchemaType::new(Type::String))
        .enum_values(Some(crate::export::GlbForm::NAMES))
        .default(Some(serde_json::Value::from(crate::export::GlbForm::default().name())))
        .description(Some(
            "How glb artifacts store their vertices: `none` (the default): 32-bit floats, read by every glTF importer, every object at scale 1 with its origin (the node's translation) at the piece's own base — a speleothem's root on the roof or floor, else the middle of the bottom of its box; `quantize` with KHR_mesh_quantization — 16-bit positions (the node's translation and scale give metres, so each object's origin is the scene's lowest corner and Blender shows its scale as the quantisation step; one grid for the whole scene; error at most half of the scene's longest side ÷ 65535), 8-bit normals, 16-bit texcoords, read by three.js, Babylon.js and Blender; or `meshopt`: the quantised arrays with 14-bit positions compressed with EXT_meshopt_compression, declared required (no uncompressed fallback is written; three.js reads it with MeshoptDecoder, Babylon.js as it is; Blender 3.4 refuses it).",
        ))
        .into();

    let (lod_min, lod_max) = crate::export::LOD_FRACTION_RANGE;
    let lods: utoipa::openapi::schema::Schema = utoipa::openapi::schema::ArrayBuilder::new()
        .items(ObjectBuilder::new().schema_type(SchemaType::new(Type::Number)).minimum(Some(lod_min)).maximum(Some(lod_max)))
        .max_items(Some(crate::export::MAX_LODS))
        .default(Some(serde_json::json!(crate::export::DEFAULT_LODS)))
        .examples([serde_json::json!(crate::export::SUGGESTED_LODS)])
        .description(Some(format!(
            "Levels of detail: one per error bound, each a fraction of the scene's longest side, increasing (default `[0.002, 0.008, 0.032]`; `[]` for none). `mesh.glb` carries them (`MSFT_lod` on each node, with `MSFT_screencoverage` hints; Babylon.js and UnityGLTF pick levels themselves, three.js with a small loader plugin, and loaders without the extension show the full mesh), and each is also written alone as `mesh_lod1.glb`, `mesh_lod2.glb`, …. A heightfield kind's terrain is triangulated from its grid at each bound (a right-triangulated irregular network, each triangle's vertical distance from the grid's mesh exact: `sample_spacing_m` 0); every other mesh is simplified from the level before (meshoptimizer's edge collapser: one try more when a try misses the bound, and up to eight more while a try gives an edge a third triangle) with the vertices on its open borders and on the rims of its bounding box's sides held in place, and measured against the full mesh (a level made from a level is bounded through it by the triangle inequality, and measured directly where that bound passes its own; the first level weighs the change of the normals as well). The result's `glb.levels` gives each level's triangles, its two-sided deviation (measured, or that bound), which never exceeds the bound, `tries`, and `unreduced`: the nodes a level keeps as the level before, because no try kept within the bound without crowding an edge, with the reason. At most {} levels.",
            crate::export::MAX_LODS
        )))
        .into();

    for kind in kinds {
        let (name, mut schema, refs) = kind.request_schema();
        super::openapi_bounds::close_objects(&mut schema);
        super::openapi_bounds::state_bounds(&mut schema);
        for (n, mut s) in refs {
            super::openapi_bounds::close_objects(&mut s);
            super::openapi_bounds::state_bounds(&mut s);
            components.schemas.insert(n, s);
        }
        // The body is the kind's parameters with the common fields beside them, one closed
        // object (an allOf of closed objects would refuse every field of the other).
        let body_name = format!("{name}Body");
        let mut body = schema.clone();
        if let RefOr::T(utoipa::openapi::schema::Schema::Object(o)) = &mut body {
            o.properties.insert("seed".into(), RefOr::T(seed.clone()));
            o.properties.insert("label".into(), RefOr::T(label.clone()));
            o.properties.insert("compression".into(), RefOr::T(compression.clone()));
            o.properties.insert("lods".into(), RefOr::T(lods.clone()));
        }
        components.schemas.insert(name.clone(), schema);
        components.schemas.insert(body_name.clone(), body);

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
            .response("400", problem_response("The body is not JSON, or a header is malformed"))
            .response("404", problem_response("No job kind of that name"))
            .response("409", problem_response("Idempotency-Key reused with a different body"))
            .response(
                "413",
                problem_response(
                    "The body, the grid it asks for, or the memory the job would need (`memory_estimate_bytes` over `memory_budget_bytes`) is too large",
                ),
            )
            .response(
                "422",
                problem_response(
                    "Invalid fields, or work over the time limit; `errors` names each field by its JSON path",
                ),
            )
            .response("503", problem_response("The queue is full; see Retry-After"))
            .build();
        doc.paths.add_path_operation(format!("/v1/jobs/{}", kind.name()), vec![HttpMethod::Post], op);
        doc.paths.add_path_operation(
            format!("/v1/drafts/{}", kind.name()),
            vec![HttpMethod::Post],
            draft_operation(kind.as_ref(), &body_name),
        );
    }
    // The list's filters take the kinds this server runs and the statuses; empty is no filter.
    let kind_names: Vec<&'static str> = std::iter::once("").chain(kinds.iter().map(|k| k.name())).collect();
    let statuses: Vec<&'static str> =
        std::iter::once("").chain(crate::jobs::JobStatus::ALL.iter().map(|s| s.as_str())).collect();
    if let Some(list) = doc.paths.paths.get_mut("/v1/jobs").and_then(|item| item.get.as_mut()) {
        for p in list.parameters.iter_mut().flatten() {
            let values = match p.name.as_str() {
                "kind" => kind_names.clone(),
                "status" => statuses.clone(),
                _ => continue,
            };
            p.schema = Some(RefOr::T(
                ObjectBuilder::new().schema_type(SchemaType::new(Type::String)).enum_values(Some(values)).into(),
            ));
        }
    }
    super::openapi_bounds::complete(&mut doc, keys_required);
    doc
}

/// `POST /v1/drafts/{kind}`: the same body as the kind's submission, answered with a mesh.
fn draft_operation(kind: &dyn JobKind, body_name: &str) -> utoipa::openapi::path::Operation {
    OperationBuilder::new()
        .tag("drafts")
        .operation_id(Some(format!("draft_{}", kind.name().replace('-', "_"))))
        .summary(Some(format!("Run a {} draft and answer with its mesh", kind.name())))
        .description(Some(format!(
            "The body of `POST /v1/jobs/{name}`, checked the same way, run at once at reduced resolution and answered with the full mesh as glb (`lods` are ignored; `compression` applies); nothing is stored. The draft rule: {rule}. Terrain sources are read at most {side} samples a side (bilinear, same extent). At most {at_once} drafts run at once (503 with Retry-After beyond, and while the jobs running leave too little of the memory budget); a draft is stopped after {timeout} s (504), or when its client goes away, and one whose estimated work is over {work} s is refused (422 naming the field). `Landform-Draft-Seconds` gives the run's time, `Landform-Draft-Result` the kind's result figures as JSON (when under 8 KiB). For a page that shows a result while it is edited; submit the same body to `POST /v1/jobs/{name}` for the full job.",
            name = kind.name(),
            rule = kind.draft_rule(),
            side = crate::jobs::DRAFT_MAX_SIDE,
            at_once = super::drafts::DRAFTS_AT_ONCE,
            timeout = crate::jobs::DRAFT_TIMEOUT.as_secs(),
            work = crate::jobs::DRAFT_MAX_WORK_S,
        )))
        .request_body(Some(
            RequestBodyBuilder::new()
                .required(Some(Required::True))
                .content("application/json", Content::new(Some(Ref::from_schema_name(body_name))))
                .build(),
        ))
        .response(
            "200",
            ResponseBuilder::new()
                .description("The draft's mesh")
                .content(
                    "model/gltf-binary",
                    Content::new(Some(ObjectBuilder::new().schema_type(SchemaType::new(Type::String)).format(Some(utoipa::openapi::SchemaFormat::KnownFormat(utoipa::openapi::KnownFormat::Binary))))),
                )
                .build(),
        )
        .response("400", problem_response("The body is not JSON"))
        .response("413", problem_response("The body, the grid it asks for, or the memory the draft would need is too large"))
        .response("422", problem_response("Invalid fields (`errors` names each by its JSON path), or the draft failed"))
        .response("503", problem_response("Too many drafts or jobs running; see Retry-After"))
        .response("504", problem_response("The draft ran past its time limit"))
        .build()
}

/// The document as YAML: what `landform openapi` prints and `openapi.yaml` holds.
pub fn openapi_yaml(kinds: &[Arc<dyn JobKind>]) -> String {
    openapi_document(kinds, false).to_yaml().expect("the OpenAPI document serialises")
}
