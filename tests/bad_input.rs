//! Bad input gets a problem+json naming the field: never a 500, a panic or a hang, and what was
//! stored before survives.

mod common;

use base64::Engine as _;
use common::bodies::small_bulldoze;
use common::server::TestServer;
use serde_json::{json, Value};

fn png(width: u32, height: u32, color: png::ColorType, depth: png::BitDepth) -> String {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(color);
        enc.set_depth(depth);
        let mut w = enc.write_header().unwrap();
        let channels = match color {
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
            png::ColorType::GrayscaleAlpha => 2,
            _ => 1,
        };
        let bytes_per = if depth == png::BitDepth::Sixteen { 2 } else { 1 };
        w.write_image_data(&vec![128u8; (width * height * channels * bytes_per) as usize]).unwrap();
    }
    base64::engine::general_purpose::STANDARD.encode(out)
}

fn with_terrain(terrain: Value) -> Value {
    json!({ "terrain": terrain, "operations": [] })
}

fn with_op(op: Value) -> Value {
    json!({ "terrain": {"fractal": {"size": 33}}, "operations": [op] })
}

enum Body {
    Json(Value),
    Raw(&'static str),
}

struct Case {
    name: &'static str,
    body: Body,
    status: u16,
    /// The field the problem must name, when it names one.
    field: Option<&'static str>,
}

fn cases() -> Vec<Case> {
    use Body::*;
    let mound = |radius: Value| json!({"primitive": {"shape": {"mound": {"center": {"x": 1, "z": 1}, "radius_m": radius, "height_m": 2}}}});
    vec![
        Case { name: "malformed JSON", body: Raw(r#"{"terrain": {"fractal": "#), status: 400, field: None },
        Case { name: "empty body", body: Raw(""), status: 400, field: None },
        Case { name: "not an object", body: Json(json!([1, 2])), status: 422, field: Some("") },
        Case {
            name: "unknown top-level field",
            body: Json(json!({"terrain": {"fractal": {}}, "operations": [], "colour": "red"})),
            status: 422,
            field: Some("colour"),
        },
        Case {
            name: "unknown nested field",
            body: Json(with_terrain(json!({"fractal": {"size": 33, "sharpness": 2}}))),
            status: 422,
            field: Some("terrain.fractal.sharpness"),
        },
        Case {
            name: "infinite number",
            body: Raw(
                r#"{"terrain": {"fractal": {"size": 33}}, "operations": [{"primitive": {"shape": {"mound": {"center": {"x": 1, "z": 1}, "radius_m": 1e999, "height_m": 2}}}}]}"#,
            ),
            status: 422,
            field: Some("operations[0].primitive.shape.mound.radius_m"),
        },
        Case {
            name: "NaN literal",
            body: Raw(r#"{"terrain": {"fractal": {"size": NaN}}, "operations": []}"#),
            status: 400,
            field: Some("terrain.fractal.size"),
        },
        Case {
            name: "wrong type",
            body: Json(with_op(mound(json!("big")))),
            status: 422,
            field: Some("operations[0].primitive.shape.mound.radius_m"),
        },
        Case {
            name: "negative radius",
            body: Json(with_op(mound(json!(-3.0)))),
            status: 422,
            field: Some("operations[0].primitive.shape.mound.radius_m"),
        },
        Case {
            name: "zero grid size",
            body: Json(with_terrain(json!({"fractal": {"size": 0}}))),
            status: 422,
            field: Some("terrain.fractal.size"),
        },
        Case {
            name: "negative cell size",
            body: Json(with_terrain(json!({"fractal": {"size": 33, "cell_size": -1.0}}))),
            status: 422,
            field: Some("terrain.fractal.cell_size"),
        },
        Case {
            name: "grid over the cap",
            body: Json(with_terrain(json!({"fractal": {"size": 5000}}))),
            status: 413,
            field: Some("terrain.fractal.size"),
        },
        Case {
            name: "a path with one point",
            body: Json(with_op(json!({"pass": {"path": [{"x": 1, "z": 1}], "blade": {"width_m": 4}}}))),
            status: 422,
            field: Some("operations[0].pass.path"),
        },
        Case {
            name: "a blade with no width",
            body: Json(with_op(
                json!({"pass": {"path": [{"x": 1, "z": 1}, {"x": 9, "z": 9}], "blade": {"width_m": 0}}}),
            )),
            status: 422,
            field: Some("operations[0].pass.blade.width_m"),
        },
        Case {
            name: "an unknown operator",
            body: Json(with_op(
                json!({"primitive": {"shape": {"cone": {"center": {"x": 1, "z": 1}, "radius_m": 3, "height_m": 1}}, "operator": "xor"}}),
            )),
            status: 422,
            field: Some("operations[0].primitive.operator"),
        },
        Case {
            name: "a corrupt PNG",
            body: Json(with_terrain(json!({"heightmap": {"png_base64": "aGVsbG8gd29ybGQ="}}))),
            status: 422,
            field: Some("terrain.heightmap.png_base64"),
        },
        Case {
            name: "not base64",
            body: Json(with_terrain(json!({"heightmap": {"png_base64": "%%%"}}))),
            status: 422,
            field: Some("terrain.heightmap.png_base64"),
        },
        Case {
            name: "a colour PNG",
            body: Json(with_terrain(
                json!({"heightmap": {"png_base64": png(8, 8, png::ColorType::Rgb, png::BitDepth::Eight)}}),
            )),
            status: 422,
            field: Some("terrain.heightmap.png_base64"),
        },
        Case {
            name: "a PNG over the grid cap",
            body: Json(with_terrain(
                json!({"heightmap": {"png_base64": png(1100, 1100, png::ColorType::Grayscale, png::BitDepth::Eight)}}),
            )),
            status: 413,
            field: Some("terrain.heightmap.png_base64"),
        },
        Case {
            name: "an unknown terrain job",
            body: Json(with_terrain(json!({"job": "01920000-0000-7000-8000-000000000000"}))),
            status: 422,
            field: Some("terrain.job"),
        },
        Case {
            name: "a terrain job id that is no id",
            body: Json(with_terrain(json!({"job": "../etc/passwd"}))),
            status: 422,
            field: Some("terrain.job"),
        },
        Case {
            name: "a negative seed",
            body: Json(json!({"terrain": {"fractal": {"size": 33}}, "operations": [], "seed": -1})),
            status: 422,
            field: Some("seed"),
        },
        Case {
            name: "no tiles along a side",
            body: Json(json!({"terrain": {"fractal": {"size": 33}}, "operations": [], "tiles": {"count": [0, 2]}})),
            status: 422,
            field: Some("tiles.count"),
        },
        Case {
            name: "too many tiles",
            body: Json(json!({"terrain": {"fractal": {"size": 33}}, "operations": [], "tiles": {"count": [17, 2]}})),
            status: 422,
            field: Some("tiles.count"),
        },
        Case {
            name: "a tile count that is not a pair",
            body: Json(json!({"terrain": {"fractal": {"size": 33}}, "operations": [], "tiles": {"count": [2]}})),
            status: 422,
            field: Some("tiles.count"),
        },
        Case {
            name: "a label that is no string",
            body: Json(json!({"terrain": {"fractal": {"size": 33}}, "operations": [], "label": 5})),
            status: 422,
            field: Some("label"),
        },
    ]
}

#[tokio::test]
async fn every_bad_request_gets_a_problem_naming_the_field() {
    let server = TestServer::start().await;
    let kept = server.run("bulldoze", &small_bulldoze()).await;

    for case in cases() {
        let req = server.client.post(server.url("/v1/jobs/bulldoze"));
        let req = match &case.body {
            Body::Json(v) => req.json(v),
            Body::Raw(s) => req.header("content-type", "application/json").body(*s),
        };
        let res = req.send().await.unwrap();
        let status = res.status().as_u16();
        let ctype = res.headers().get("content-type").map(|v| v.to_str().unwrap().to_string());
        let problem: Value = res.json().await.unwrap_or(Value::Null);
        assert_eq!(status, case.status, "{}: {problem}", case.name);
        assert_eq!(ctype.as_deref(), Some("application/problem+json"), "{}", case.name);
        assert_eq!(problem["status"], case.status, "{}", case.name);
        assert!(problem["title"].is_string() && problem["detail"].is_string(), "{}: {problem}", case.name);
        if let Some(field) = case.field {
            let fields: Vec<&str> =
                problem["errors"].as_array().into_iter().flatten().filter_map(|e| e["field"].as_str()).collect();
            assert!(fields.contains(&field), "{}: wanted field {field:?}, got {problem}", case.name);
        }
    }

    // Not-found and wrong-state answers.
    let (status, _) = server.get_json("/v1/jobs/01920000-0000-7000-8000-000000000000").await;
    assert_eq!(status, 404);
    let (status, _) = server.post("/v1/jobs/no-such-kind", &small_bulldoze()).await;
    assert_eq!(status, 404);
    let id = kept["id"].as_str().unwrap();
    let (status, _) = server.post(&format!("/v1/jobs/{id}/cancel"), &json!({})).await;
    assert_eq!(status, 409);

    // What was stored before is still there.
    let (status, again) = server.get_json(&format!("/v1/jobs/{id}")).await;
    assert_eq!(status, 200);
    assert_eq!(again["artifacts"], kept["artifacts"]);
}

#[tokio::test]
async fn a_body_over_the_size_limit_gets_413() {
    let server = TestServer::start().await; // 8 MiB limit
    let big = "x".repeat(9 * 1024 * 1024);
    let body = format!(r#"{{"terrain": {{"fractal": {{}}}}, "operations": [], "label": "{big}"}}"#);
    let res = server
        .client
        .post(server.url("/v1/jobs/bulldoze"))
        .header("content-type", "application/json")
        .body(body)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 413);
    assert_eq!(res.headers()["content-type"], "application/problem+json");
}
