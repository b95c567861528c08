"""The package split of DESIGN.md: who may import whom, and the command line's subcommands."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

FORBIDDEN = {
    "tracer": {"service", "cad_adapter", "fastapi", "sqlalchemy", "cadquery", "OCP", "httpx", "trimesh"},
    "service": {"cadquery", "OCP", "cad_adapter"},
    "cad_adapter": {"service"},
}


def imported_top_levels(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_import_rules(package: str) -> None:
    offenders = {}
    for path in (ROOT / package).rglob("*.py"):
        bad = imported_top_levels(path) & FORBIDDEN[package]
        if bad:
            offenders[str(path.relative_to(ROOT))] = sorted(bad)
    assert not offenders, f"{package}/ imports what DESIGN.md forbids: {offenders}"


def test_cli_lists_subcommands() -> None:
    out = subprocess.run([sys.executable, "-m", "lumenlink.cli", "--help"], capture_output=True, text=True,
                         check=True).stdout
    for command in ("serve", "push", "watch", "demo", "bench"):
        assert command in out, f"`lumenlink --help` does not list {command}"


def test_cli_help_does_not_import_heavy_stacks() -> None:
    code = ("import sys, lumenlink.cli; heavy = [m for m in ('numba', 'cadquery', 'OCP', 'fastapi') "
            "if m in sys.modules]; print(','.join(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"`lumenlink --help` imports {out}"


def test_geometry_id_imports_without_numba() -> None:
    """The adapter hashes meshes through tracer.geometry_id; that must not load the kernels."""
    code = "import sys, tracer.geometry_id; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "False"


def test_the_service_client_stands_alone() -> None:
    """The adapter and `lumenlink.Client` share one HTTP client (`lumenlink.http`) and one error hierarchy
    (`lumenlink.errors`); those two import nothing of ours besides each other, so the adapter may use them
    without taking in the command line, the service or the tracer, and the adapter uses nothing else of lumenlink."""
    ours = {"tracer", "service", "cad_adapter", "lumenlink", "bench"}
    for name in ("http", "errors"):
        path = ROOT / "lumenlink" / f"{name}.py"
        tree = ast.parse(path.read_text(), filename=str(path))
        modules = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
        modules |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        assert {m for m in modules if m.split(".")[0] in ours} <= {"lumenlink.errors"}, (name, modules)
    used = set()
    for path in (ROOT / "cad_adapter").rglob("*.py"):
        tree = ast.parse(path.read_text(), filename=str(path))
        used |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module
                 and n.module.split(".")[0] == "lumenlink"}
        used |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names
                 if a.name.split(".")[0] == "lumenlink"}
    assert used == {"lumenlink.http", "lumenlink.errors"}, used
