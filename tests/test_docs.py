"""The project explains itself (issue 55): a short README that points into docs/, every relative link of the README
and of docs/ resolves to a file of this repository, and no source or document points at a document outside it
(the design and the optics references live in docs/; data fixtures and tools beside the checkout are not documents)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
SOURCES = [p for pkg in ("tracer", "service", "lumenlink", "cad_adapter", "bench", "tests")
           for p in sorted((ROOT / pkg).rglob("*.py"))]


def test_the_readme_is_a_front_page_of_at_most_about_250_lines() -> None:
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines: move the detail into docs/"


def test_every_relative_link_of_the_docs_resolves_to_a_file_here() -> None:
    broken = []
    for doc in DOCUMENTS:
        for target in re.findall(r"\]\(([^)#\s]+)", doc.read_text(encoding="utf-8")):
            if not target.startswith(("http://", "https://", "mailto:")) and not (doc.parent / target).exists():
                broken.append(f"{doc.relative_to(ROOT)} -> {target}")
    assert not broken, broken


def test_no_source_or_document_cites_a_document_outside_the_repository() -> None:
    outside = re.compile(r"(\.\./)?shared/[A-Z][A-Z_]*\.md")
    found = [f"{p.relative_to(ROOT)}: {m.group(0)}" for p in (*SOURCES, *DOCUMENTS)
             for m in outside.finditer(p.read_text(encoding="utf-8"))]
    assert not found, found
