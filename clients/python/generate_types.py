#!/usr/bin/env python3
"""Write src/landform/_types.py from the server's OpenAPI document.

    python generate_types.py                 # ../../openapi.yaml -> src/landform/_types.py
    python generate_types.py --check         # exit 1 when the committed file is stale
    python generate_types.py --spec S --out O

The output holds, for the Python client:

- a TypedDict for each job kind's request body and for the job document (``Job``), the problem
  (``Problem``), and every schema they reach, each property marked required or ``NotRequired``
  as the schema says;
- ``KINDS``: the job kinds (the ``POST /v1/jobs/<kind>`` routes), and ``REQUEST_BODIES``: each
  kind's body type;
- ``PATHS``: every path of the document with its methods, and ``OPERATIONS``: each operation id's
  method and path.

Only the structure is written (names, types, required): descriptions and bounds are left out, so
a change of wording in the server does not make the file stale, and a change of a field does.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import yaml

HERE = Path(__file__).resolve().parent
DEFAULT_SPEC = HERE.parent.parent / "openapi.yaml"
DEFAULT_OUT = HERE / "src" / "landform" / "_types.py"

# Schemas the client states beside the kinds' bodies (everything they reach comes too).
ROOTS = ["Job", "JobPage", "JobStatus", "Problem", "FieldError", "Progress", "ArtifactMeta", "Cost", "ReplayRequest", "SseEvent"]

KIND_PATH = re.compile(r"^/v1/jobs/([a-z][a-z0-9-]*)$")
REF = "#/components/schemas/"


def camel(text: str) -> str:
    return "".join(p[:1].upper() + p[1:] for p in re.split(r"[^A-Za-z0-9]+", text) if p)


class Generator:
    def __init__(self, spec: dict):
        self.spec = spec
        self.schemas: dict = spec.get("components", {}).get("schemas", {})
        self.defs: dict[str, str] = {}  # name -> definition source
        self.pending: list[str] = []  # component schemas still to write
        self.seen: set[str] = set()

    # -- names --------------------------------------------------------------------------------

    def ref_name(self, ref: str) -> str:
        if not ref.startswith(REF):
            raise SystemExit(f"unsupported $ref {ref!r}")
        name = ref[len(REF):]
        if name not in self.schemas:
            raise SystemExit(f"$ref to a missing schema {name!r}")
        if name not in self.seen:
            self.seen.add(name)
            self.pending.append(name)
        return name

    def fresh(self, name: str) -> str:
        base, n = name, 2
        while name in self.defs or name in self.schemas:
            name = f"{base}{n}"
            n += 1
        return name

    # -- types --------------------------------------------------------------------------------

    def annotation(self, schema, context: str) -> str:
        """A Python type expression for a schema; named types are quoted (forward references)."""
        if schema is True or schema is None or schema == {}:
            return "Any"
        if "$ref" in schema:
            return repr(self.ref_name(schema["$ref"]))
        if "oneOf" in schema or "anyOf" in schema:
            members = schema.get("oneOf") or schema.get("anyOf")
            parts: list[str] = []
            for i, member in enumerate(members):
                parts.append(self.annotation(member, self.variant_name(member, context, i)))
            return union(parts)
        if "allOf" in schema:
            raise SystemExit(f"allOf is not supported ({context})")
        if "const" in schema:
            return f"Literal[{schema['const']!r}]"
        types = schema.get("type")
        if types is None:
            if "properties" in schema:
                types = "object"
            elif "items" in schema:
                types = "array"
            else:
                return "Any"
        if isinstance(types, str):
            types = [types]
        parts = [self.single(t, schema, context) for t in types]
        return union(parts)

    def single(self, t: str, schema: dict, context: str) -> str:
        if t == "null":
            return "None"
        if t == "string":
            if "enum" in schema:
                return "Literal[" + ", ".join(repr(v) for v in schema["enum"]) + "]"
            return "str"
        if t == "integer":
            return "int"
        if t == "number":
            return "float"
        if t == "boolean":
            return "bool"
        if t == "array":
            if "prefixItems" in schema:
                # A fixed pair or triple, each item with its own schema: a tuple.
                parts = [self.annotation(s, f"{context}Item{i}") for i, s in enumerate(schema["prefixItems"])]
                return f"tuple[{', '.join(parts)}]"
            items = schema.get("items")
            return f"list[{self.annotation(items, context + 'Item')}]" if items is not None else "list[Any]"
        if t == "object":
            if "properties" in schema:
                name = self.fresh(context)
                self.typed_dict(name, schema)
                return repr(name)
            extra = schema.get("additionalProperties")
            if isinstance(extra, dict):
                return f"dict[str, {self.annotation(extra, context + 'Value')}]"
            return "dict[str, Any]"
        raise SystemExit(f"unsupported type {t!r} ({context})")

    def variant_name(self, member, context: str, index: int) -> str:
        # A one-key wrapper ({"fractal": {...}}) is named after its key: TerrainSourceFractal.
        if isinstance(member, dict) and len(member.get("required", [])) == 1 and len(member.get("properties", {})) == 1:
            return context + camel(member["required"][0])
        return f"{context}Variant{index + 1}"

    # -- definitions --------------------------------------------------------------------------

    def typed_dict(self, name: str, schema: dict) -> None:
        self.defs[name] = ""  # reserve the name before nested types take theirs
        required = set(schema.get("required", []))
        lines = []
        for prop, sub in schema.get("properties", {}).items():
            ann = self.annotation(sub, name + camel(prop))
            if prop not in required:
                ann = f"NotRequired[{ann}]"
            lines.append(f"        {prop!r}: {ann},")
        body = "\n".join(lines)
        self.defs[name] = f"{name} = TypedDict(\n    {name!r},\n    {{\n{body}\n    }},\n)"

    def component(self, name: str) -> None:
        schema = self.schemas[name]
        if (schema.get("type") == "object" or "properties" in schema) and "oneOf" not in schema:
            self.typed_dict(name, schema)
            return
        self.defs[name] = ""
        self.defs[name] = f"{name} = {self.annotation(schema, name)}"

    def drain(self) -> None:
        while self.pending:
            self.component(self.pending.pop(0))

    # -- the document -------------------------------------------------------------------------

    def run(self) -> str:
        paths: dict = self.spec.get("paths", {})
        kinds: dict[str, str] = {}
        operations: dict[str, tuple[str, str]] = {}
        for path, item in paths.items():
            for method, op in item.items():
                if method.lower() not in ("get", "put", "post", "delete", "patch", "head", "options"):
                    continue
                if "operationId" in op:
                    operations[op["operationId"]] = (method.upper(), path)
                m = KIND_PATH.match(path)
                if m and method.lower() == "post":
                    body = op.get("requestBody", {}).get("content", {}).get("application/json", {}).get("schema", {})
                    if "$ref" not in body:
                        raise SystemExit(f"POST {path}: the body is not a named schema")
                    kinds[m.group(1)] = self.ref_name(body["$ref"])
        if not kinds:
            raise SystemExit("no job kinds (POST /v1/jobs/<kind>) in the document")
        # The list route's kind filter must name the same kinds.
        for param in paths.get("/v1/jobs", {}).get("get", {}).get("parameters", []):
            if param.get("name") == "kind":
                listed = [k for k in param.get("schema", {}).get("enum", []) if k]
                if sorted(listed) != sorted(kinds):
                    raise SystemExit(f"the kinds of POST routes {sorted(kinds)} differ from GET /v1/jobs?kind= {sorted(listed)}")
        for root in ROOTS:
            if root not in self.schemas:
                raise SystemExit(f"the document has no schema {root!r}")
            self.ref_name(REF + root)
        self.drain()

        out = [
            '"""Types of the Landform API, generated from openapi.yaml by clients/python/generate_types.py.',
            "",
            "Do not edit: run `python clients/python/generate_types.py` after the server's schema changes",
            "(a test fails while this file differs from what the generator writes).",
            '"""',
            "",
            "# ruff: noqa",
            "import sys",
            "from typing import Any, Literal, Union",
            "",
            "if sys.version_info >= (3, 11):",
            "    from typing import NotRequired, TypedDict",
            "else:  # pragma: no cover",
            "    from typing_extensions import NotRequired, TypedDict",
            "",
            f"KINDS: tuple[str, ...] = {tuple(sorted(kinds))!r}",
            "Kind = Literal[" + ", ".join(repr(k) for k in sorted(kinds)) + "]",
            "",
            "# Every path of the document and its methods.",
            "PATHS: dict[str, tuple[str, ...]] = {",
        ]
        for path in sorted(paths):
            methods = sorted(m.upper() for m in paths[path] if m.lower() in ("get", "put", "post", "delete", "patch", "head", "options"))
            out.append(f"    {path!r}: {tuple(methods)!r},")
        out += ["}", "", "# Each operation id's method and path.", "OPERATIONS: dict[str, tuple[str, str]] = {"]
        for op_id in sorted(operations):
            out.append(f"    {op_id!r}: {operations[op_id]!r},")
        out += ["}", ""]
        for name in sorted(self.defs):
            out += ["", self.defs[name]]
        out += ["", "", "# Each kind's request body."]
        out.append("REQUEST_BODIES: dict[str, Any] = {")
        for kind in sorted(kinds):
            out.append(f"    {kind!r}: {kinds[kind]},")
        out += ["}", ""]
        return "\n".join(out)


def union(parts: list[str]) -> str:
    unique: list[str] = []
    for p in parts:
        if p not in unique:
            unique.append(p)
    if len(unique) == 1:
        return unique[0]
    if "None" in unique and len(unique) == 2:
        other = unique[0] if unique[1] == "None" else unique[1]
        return f"Union[{other}, None]"
    return "Union[" + ", ".join(unique) + "]"


def generate(spec_path: Path) -> str:
    with open(spec_path, encoding="utf-8") as f:
        spec = yaml.load(f, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    return Generator(spec).run()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spec", type=Path, default=DEFAULT_SPEC)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--check", action="store_true", help="exit 1 when --out differs from what would be written")
    args = parser.parse_args(argv)
    text = generate(args.spec)
    if args.check:
        current = args.out.read_text(encoding="utf-8") if args.out.exists() else ""
        if current != text:
            print(f"{args.out} is stale: run python {Path(__file__).name}", file=sys.stderr)
            return 1
        return 0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
