"""The house's measures (issue 35), so that they keep holding: no module over 600 lines and no class over 250 in
`tracer/` and `service/`; at most 12 modules in `tracer/`'s root (the rest live in families); every family of the
tracer beside its contract (``base.py``) and its one registry."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MAX_MODULE_LINES = 600
MAX_CLASS_LINES = 250
MAX_TRACER_ROOT_MODULES = 12


def sources() -> list[Path]:
    return sorted(p for package in ("tracer", "service") for p in (ROOT / package).rglob("*.py"))


def test_no_module_over_600_lines() -> None:
    long = {str(p.relative_to(ROOT)): n for p in sources() if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_no_class_over_250_lines() -> None:
    big = {}
    for p in sources():
        for node in ast.walk(ast.parse(p.read_text(), filename=str(p))):
            if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > MAX_CLASS_LINES:
                big[f"{p.relative_to(ROOT)}:{node.name}"] = node.end_lineno - node.lineno + 1
    assert not big, f"classes over {MAX_CLASS_LINES} lines: {big}"


def test_tracer_root_holds_at_most_12_modules() -> None:
    root = sorted(p.name for p in (ROOT / "tracer").glob("*.py"))
    assert len(root) <= MAX_TRACER_ROOT_MODULES, root


@pytest.mark.parametrize("family, registry", [
    ("tracer.kinds", "REGISTRY"), ("tracer.sensors.dispatch", "KINDS"), ("tracer.optics.surfaces.dispatch", "KINDS"),
    ("tracer.optics.lights.dispatch", "KINDS"), ("tracer.optics.media.dispatch", "KINDS")])
def test_each_family_has_its_contract_and_registry(family: str, registry: str) -> None:
    """A family is a folder with its contract (``base.py``) and one dispatch: a new kind is a module there plus its
    registration."""
    module = importlib.import_module(family)
    folder = Path(module.__file__).parent
    assert (folder / "base.py").exists(), f"{folder} has no base.py stating the family's contract"
    kinds = getattr(module, registry)
    assert len(kinds) >= 1, (family, kinds)
