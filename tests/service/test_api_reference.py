"""docs/API.md is what the service's own OpenAPI document generates (`service.api_reference`): it cannot drift from
the routes. Where this fails, write it again: ``.venv/bin/python -m service.api_reference > docs/API.md``."""

from __future__ import annotations

from pathlib import Path

from service.api_reference import markdown, openapi_document

ROOT = Path(__file__).resolve().parents[2]


def test_the_committed_api_reference_is_the_one_the_routes_generate() -> None:
    doc = openapi_document()
    generated = markdown(doc)
    committed = (ROOT / "docs" / "API.md").read_text(encoding="utf-8")
    assert committed == generated, ("docs/API.md is stale: run `.venv/bin/python -m service.api_reference > "
                                    "docs/API.md`")
    # every operation of the document has its entry, under its method and path
    for path, item in doc["paths"].items():
        for method in ("get", "put", "post", "patch", "delete"):
            if method in item:
                assert f"### `{method.upper()} {path}`" in committed, (method, path)
