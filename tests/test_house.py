"""The house's measures (issue 35), so that they keep holding: no module over 600 lines and no class over 250 in
`tracer/` and `service/`; at most 12 modules in `tracer/`'s root (the rest live in families); every family of the
tracer beside its contract (``base.py``) and its one registry.

Over every package (issue 55: `tracer`, `service`, `cad_adapter`, `lumenlink`, `bench`), the same measures and no
function over 80 lines outside numba kernels, as a ratchet: what exceeds them today is listed in `OVER` with its
size, to be split; a listed one may shrink but not grow, and nothing new may join it."""

from __future__ import annotations

import ast
import graphlib
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
    ("tracer.optics.lights.dispatch", "KINDS"), ("tracer.optics.media.dispatch", "KINDS"),
    ("tracer.elements.shapes.dispatch", "KINDS")])
def test_each_family_has_its_contract_and_registry(family: str, registry: str) -> None:
    """A family is a folder with its contract (``base.py``) and one dispatch: a new kind is a module there plus its
    registration."""
    module = importlib.import_module(family)
    folder = Path(module.__file__).parent
    assert (folder / "base.py").exists(), f"{folder} has no base.py stating the family's contract"
    kinds = getattr(module, registry)
    assert len(kinds) >= 1, (family, kinds)


PACKAGES = ("tracer", "service", "cad_adapter", "lumenlink", "bench")
MAX_FUNCTION_LINES = 80
#: what exceeds the measures, with its size in lines: to be split, never to grow (empty since 2026-12-07: every module,
#: class and function of every package keeps them)
OVER: dict[str, int] = {}


def _jitted(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """A numba kernel (``@njit``, ``@cuda.jit``...): its length is the kernel's, measured by its compile instead."""
    return any("jit" in ast.unparse(d) for d in node.decorator_list)


def measures() -> dict[str, int]:
    """Everything over the measures in every package: {"module path" | "class path:Name" | "function path:name":
    lines}."""
    out: dict[str, int] = {}
    for package in PACKAGES:
        for p in sorted((ROOT / package).rglob("*.py")):
            text, rel = p.read_text(), p.relative_to(ROOT).as_posix()
            if (n := len(text.splitlines())) > MAX_MODULE_LINES:
                out[f"module {rel}"] = n
            for node in ast.walk(ast.parse(text, filename=str(p))):
                if not isinstance(node, ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
                    continue
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if isinstance(node, ast.ClassDef) and lines > MAX_CLASS_LINES:
                    out[f"class {rel}:{node.name}"] = lines
                elif (isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and lines > MAX_FUNCTION_LINES
                      and not _jitted(node)):
                    out[f"function {rel}:{node.name}"] = lines
    return out


def test_every_package_keeps_the_measures_or_shrinks_what_is_listed_over_them() -> None:
    found = measures()
    new = {k: v for k, v in found.items() if k not in OVER}
    grown = {k: (OVER[k], v) for k, v in found.items() if k in OVER and v > OVER[k]}
    assert not new, f"over the measures ({MAX_MODULE_LINES} lines a module, {MAX_CLASS_LINES} a class, " \
                    f"{MAX_FUNCTION_LINES} a function): {new}; split them"
    assert not grown, f"listed as over the measures and grown (listed, now): {grown}; split them instead"
    stale = sorted(set(OVER) - set(found))
    assert not stale, f"listed as over the measures but within them now: {stale}; take them off OVER"



def module_names() -> dict[str, Path]:
    """Every module of every package by its dotted name (a package by its ``__init__``)."""
    out = {}
    for package in PACKAGES:
        for p in (ROOT / package).rglob("*.py"):
            parts = p.relative_to(ROOT).with_suffix("").parts
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    return out


def imports_of(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The modules of ours that one module imports anywhere in it (inside functions too: an import put off to
    run time still ties the two). ``from pkg import sub`` ties to ``pkg.sub`` where that is a module, else to
    ``pkg``; a name not itself a module ties to its nearest enclosing module."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            subs = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in known]
            targets = subs + ([base] if len(subs) < len(node.names) else [])
        else:
            continue
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def test_no_module_import_circle() -> None:
    """Issue 55's measures: modules of ours import one another one way only, so each can be read (and loaded)
    before what uses it."""
    known = module_names()
    graph = {name: imports_of(name, path, known) for name, path in known.items()}
    try:
        tuple(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as exc:
        pytest.fail(f"modules that import each other, in a circle: {' -> '.join(exc.args[1])}; move what both need "
                    f"into a module of its own")
