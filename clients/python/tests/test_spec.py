"""The client checked against openapi.yaml: generated types current, every route it calls real."""

from __future__ import annotations

import functools
import importlib.util
import json
import typing
from pathlib import Path

import yaml

import landform
from landform import ROUTES, types

from conftest import API, CLIENTS, SPEC

HERE = Path(__file__).resolve().parent.parent


def load_generator():
    spec = importlib.util.spec_from_file_location("generate_types", HERE / "generate_types.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@functools.lru_cache(maxsize=1)
def load_spec() -> dict:
    with open(SPEC, encoding="utf-8") as f:
        return yaml.load(f, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))


def spec_routes() -> set[tuple[str, str]]:
    doc = load_spec()
    return {(method.upper(), path) for path, item in doc["paths"].items() for method in item}


def client_routes() -> set[tuple[str, str]]:
    routes = set()
    for method, template in ROUTES.values():
        if "{kind}" in template:
            routes |= {(method, template.replace("{kind}", kind)) for kind in landform.KINDS}
        else:
            routes.add((method, template))
    return routes


def test_generated_types_are_current(tmp_path) -> None:
    generator = load_generator()
    out = tmp_path / "_types.py"
    assert generator.main(["--spec", str(SPEC), "--out", str(out)]) == 0
    committed = (HERE / "src" / "landform" / "_types.py").read_text(encoding="utf-8")
    assert out.read_text(encoding="utf-8") == committed, (
        "src/landform/_types.py is stale: run `python clients/python/generate_types.py`"
    )


def test_every_route_the_client_calls_is_in_the_spec() -> None:
    missing = client_routes() - spec_routes()
    assert not missing, f"routes the client calls that openapi.yaml lacks: {sorted(missing)}"


def test_routes_called_during_the_tests_are_declared() -> None:
    # Runs after the server tests (files run in name order): every request they made went
    # through a declared route, and so (above) through one of the spec's.
    called = set().union(*(c.calls for c in CLIENTS)) if CLIENTS else set()
    assert called <= client_routes(), sorted(called - client_routes())
    assert called <= spec_routes()


def test_kinds_and_bodies_match_the_spec() -> None:
    doc = load_spec()
    kinds = sorted(
        p.removeprefix("/v1/jobs/") for p in doc["paths"] if p.startswith("/v1/jobs/") and p.count("/") == 3 and "{" not in p
    )
    assert list(landform.KINDS) == kinds
    for kind in kinds:
        ref = doc["paths"][f"/v1/jobs/{kind}"]["post"]["requestBody"]["content"]["application/json"]["schema"]["$ref"]
        schema = doc["components"]["schemas"][ref.rsplit("/", 1)[1]]
        body = types.REQUEST_BODIES[kind]
        assert set(typing.get_type_hints(body)) == set(schema["properties"])
        assert body.__required_keys__ == frozenset(schema.get("required", []))


def test_job_document_matches_the_spec() -> None:
    doc = load_spec()
    for name in ("Job", "Problem", "Progress", "ArtifactMeta"):
        schema = doc["components"]["schemas"][name]
        td = getattr(types, name)
        assert set(typing.get_type_hints(td)) == set(schema["properties"]), name
        assert td.__required_keys__ == frozenset(schema["required"]), name


def test_examples_use_only_known_fields() -> None:
    # Each example body's top-level fields are properties of its kind's type.
    for kind in landform.KINDS:
        allowed = set(typing.get_type_hints(types.REQUEST_BODIES[kind]))
        for path in sorted((API / kind).glob("*.json")):
            body = json.loads(path.read_text(encoding="utf-8"))
            assert set(body) <= allowed, (path.name, set(body) - allowed)
