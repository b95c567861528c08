"""The REST API reference as Markdown, generated from the service's own OpenAPI document: ``docs/API.md``.

``python -m service.api_reference > docs/API.md`` writes it again; tests/service/test_api_reference.py fails where the
committed file is not what the service's routes generate, so the reference cannot drift from the code. One section per
tag, one entry per operation: method and path, summary, its parameters (where, type, whether required, description),
its request body (content type and schema), and the statuses it documents. Schemas are named, not expanded: the live
docs (``/docs``, ``/redoc``) show them with examples.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path
from typing import Any

METHODS = ("get", "put", "post", "patch", "delete")


def openapi_document() -> dict[str, Any]:
    """The OpenAPI document of a service on a throw-away data directory (nothing is stored anywhere else)."""
    from service.app import create_app
    from service.config import Settings

    with tempfile.TemporaryDirectory(prefix="lumenlink-api-") as tmp:
        return create_app(Settings(data_dir=Path(tmp), log_requests=False)).openapi()


def _type(schema: dict[str, Any]) -> str:
    """A short name of a schema: its component's name, its type, or the alternatives."""
    if "$ref" in schema:
        return f"`{schema['$ref'].rsplit('/', 1)[-1]}`"
    for key in ("anyOf", "oneOf"):
        if key in schema:
            return " or ".join(_type(s) for s in schema[key] if s.get("type") != "null") or "null"
    if schema.get("type") == "array":
        return f"array of {_type(schema.get('items', {}))}"
    if "enum" in schema:
        return " \\| ".join(f"`{v}`" for v in schema["enum"])
    if "const" in schema:
        return f"`{schema['const']}`"
    return str(schema.get("type", "any"))


def _answer(response: dict[str, Any]) -> str:
    """`` (`Model`)`` naming what a success answers in JSON (its kinds, where it depends on one); '' for none."""
    schema = response.get("content", {}).get("application/json", {}).get("schema", {})
    named = _type(schema) if schema else ""
    return f" ({_cell(named)})" if "`" in named else ""   # a model (or models), not a bare "object"


def _cell(text: Any) -> str:
    """Text for one cell of a Markdown table: one line, pipes escaped."""
    return " ".join(str(text or "").split()).replace("|", "\\|")


def markdown(doc: dict[str, Any]) -> str:
    """The reference of an OpenAPI document (module docstring)."""
    info = doc["info"]
    out = [f"# {info['title']} REST API {info['version']}", "",
           "Generated from the service's OpenAPI document by `python -m service.api_reference > docs/API.md` (do not "
           "edit by hand; tests/service/test_api_reference.py checks it). A running service shows the same with "
           "schemas and examples at `/docs` and `/redoc`; errors are `application/problem+json` (RFC 9457).", ""]
    errors: dict[str, str] = {}
    for item in doc["paths"].values():
        for method in METHODS:
            for code, r in item.get(method, {}).get("responses", {}).items():
                if code >= "400":
                    errors.setdefault(code, _cell(r.get("description")))
    out += ["Errors (each operation lists the statuses it may answer):", "", "| status | meaning |", "| --- | --- |"]
    out += [f"| {code} | {errors[code]} |" for code in sorted(errors)] + [""]
    by_tag: dict[str, list[tuple[str, str, dict[str, Any]]]] = {}
    for path, item in doc["paths"].items():
        for method in METHODS:
            if method in item:
                op = item[method]
                by_tag.setdefault((op.get("tags") or ["other"])[0], []).append((method, path, op))
    for tag in sorted(by_tag):
        out += [f"## {tag}", ""]
        for method, path, op in by_tag[tag]:
            out += [f"### `{method.upper()} {path}`", "", _cell(op.get("summary")), ""]
            description = (op.get("description") or "").strip().split("\n\n")[0]
            if description:
                out += [" ".join(description.split()), ""]
            params = op.get("parameters", [])
            if params:
                out += ["| parameter | in | type | required | description |", "| --- | --- | --- | --- | --- |"]
                out += [f"| `{p['name']}` | {p['in']} | {_cell(_type(p.get('schema', {})))} | "
                        f"{'yes' if p.get('required') else 'no'} | {_cell(p.get('description'))} |" for p in params]
                out.append("")
            body = op.get("requestBody")
            if body:
                kinds = ", ".join(f"`{ct}` {_type(c.get('schema', {}))}" for ct, c in body.get("content", {}).items())
                out += [f"Body{' (required)' if body.get('required') else ''}: {kinds}", ""]
            codes = list(op.get("responses", {}))
            ok = ", ".join(f"{c} {_cell(op['responses'][c].get('description'))}{_answer(op['responses'][c])}"
                           for c in codes if c < "400")
            out += [f"Answers: {ok}; errors {', '.join(c for c in codes if c >= '400')}", ""]
    return "\n".join(out).rstrip() + "\n"


if __name__ == "__main__":
    sys.stdout.write(markdown(openapi_document()))
