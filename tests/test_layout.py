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


#: a NamedTuple's own API (``SceneArrays._fields``, ``._replace``): public despite the underscore
NAMEDTUPLE_API = {"_fields", "_replace", "_asdict", "_make"}


def private_names_imported(path: Path, package: str) -> list[str]:
    """``from a.b import _x`` and ``m._x`` (``m`` a module or name imported from ``package``) in one file."""
    tree = ast.parse(path.read_text(), filename=str(path))
    imported: set[str] = set()
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").split(".")[0] == package:
            for a in node.names:
                if a.name.startswith("_") and not a.name.startswith("__"):
                    found.append(f"{path.name}:{node.lineno} from {node.module} import {a.name}")
                imported.add(a.asname or a.name)
        elif isinstance(node, ast.Import):
            imported.update(a.asname or a.name.split(".")[0] for a in node.names if a.name.split(".")[0] == package)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
            base = node.value
            while isinstance(base, ast.Attribute):
                base = base.value
            if isinstance(base, ast.Name) and base.id in imported and node.attr not in NAMEDTUPLE_API:
                found.append(f"{path.name}:{node.lineno} {ast.unparse(node)}")
    return found


def test_tracer_modules_share_public_names_only() -> None:
    """Between tracer's modules (tracer/accel/ and the rest) only public names cross a module line."""
    offenders = [f for path in sorted((ROOT / "tracer").rglob("*.py")) for f in private_names_imported(path, "tracer")]
    assert not offenders, f"private names used across tracer's modules: {offenders}"
