"""The package split of docs/DESIGN.md: who may import whom, and the command line's subcommands."""

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
    assert not offenders, f"{package}/ imports what docs/DESIGN.md forbids: {offenders}"


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


def lumenlink_modules_used(path: Path) -> set[str]:
    """The lumenlink modules a file imports (``from lumenlink import glb`` counts as lumenlink.glb)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out: set[str] = set()
    for n in ast.walk(tree):
        if isinstance(n, ast.Import):
            out |= {a.name for a in n.names if a.name.split(".")[0] == "lumenlink"}
        elif isinstance(n, ast.ImportFrom) and n.level == 0 and n.module == "lumenlink":
            out |= {f"lumenlink.{a.name}" for a in n.names}
        elif isinstance(n, ast.ImportFrom) and n.level == 0 and n.module and n.module.startswith("lumenlink."):
            out.add(n.module)
    return out


#: lumenlink's modules that the adapter and the service share, and the only modules of ours each may import
SHARED = {"lumenlink.http": {"lumenlink.errors"}, "lumenlink.errors": set(), "lumenlink.glb": {"tracer.geometry_id"},
          "lumenlink.options": set()}


def test_the_shared_modules_stand_alone() -> None:
    """The adapter and `lumenlink.Client` share one HTTP client (`lumenlink.http`) and one error hierarchy
    (`lumenlink.errors`), the adapter and the service one GLB decoder (`lumenlink.glb`), the adapter's commands and
    lumenlink's the shared options (`lumenlink.options`). Those import nothing of
    ours but what `SHARED` lists, so neither side takes in the command line, the CAD stack or the service through
    them, and neither side uses anything else of lumenlink."""
    ours = {"tracer", "service", "cad_adapter", "lumenlink", "bench"}
    for module, allowed in SHARED.items():
        path = ROOT / (module.replace(".", "/") + ".py")
        tree = ast.parse(path.read_text(), filename=str(path))
        modules = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
        modules |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        assert {m for m in modules if m.split(".")[0] in ours} <= allowed, (module, modules)
    for package, expected in (("cad_adapter", {"lumenlink.http", "lumenlink.errors", "lumenlink.glb",
                                               "lumenlink.options"}),
                              ("service", {"lumenlink.glb"})):
        used = set().union(*(lumenlink_modules_used(p) for p in (ROOT / package).rglob("*.py")))
        assert used == expected, (package, used)


def test_lumenlinks_command_line_takes_the_adapters_commands_as_plugins_never_by_name() -> None:
    """Issue 55: the import runs one way. The adapter's commands (push, watch, freecad-addon: `cad_adapter.commands`)
    join `lumenlink` as installed plugins (entry points of group ``lumenlink.commands``), so no lumenlink module
    imports the adapter's command line or names it; `lumenlink.Client.push` takes the adapter's library
    (`cad_adapter.push`) only."""
    offenders = []
    for path in sorted((ROOT / "lumenlink").rglob("*.py")):
        tree = ast.parse(path.read_text(), filename=str(path))
        for n in ast.walk(tree):
            names = ([n.module] if isinstance(n, ast.ImportFrom) and n.module else []) + (
                [a.name for a in n.names] if isinstance(n, ast.Import) else [])
            names += [f"{n.module}.{a.name}" for a in n.names] if isinstance(n, ast.ImportFrom) and n.module else []
            strings = [n.value] if isinstance(n, ast.Constant) and isinstance(n.value, str) else []
            if any(m.startswith(("cad_adapter.cli", "cad_adapter.commands")) for m in names + strings):
                offenders.append(f"{path.relative_to(ROOT)}:{n.lineno}")
    assert not offenders, offenders
    out = subprocess.run([sys.executable, "-m", "lumenlink.cli", "--help"], capture_output=True, text=True,
                         check=True).stdout
    assert all(c in out for c in ("push", "watch", "freecad-addon")), "the adapter's commands are not installed"


#: the modules that tell sensor kinds apart by name: the kinds' own (service side, client side); and what is not yet
#: one of theirs, with why
SENSOR_KIND_MODULES = {"service/sensor_kinds.py", "service/view_kinds.py", "lumenlink/sensor_outputs.py"}
SENSOR_KIND_TESTS_LEFT: dict[str, str] = {}


def _is_type_field(node: ast.expr) -> bool:
    """``x.get("type")``, ``x["type"]`` or a name ``type``/``kind``: where a body's kind is read."""
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "get":
        return bool(node.args) and isinstance(node.args[0], ast.Constant) and node.args[0].value == "type"
    if isinstance(node, ast.Subscript):
        return isinstance(node.slice, ast.Constant) and node.slice.value == "type"
    return isinstance(node, ast.Name) and node.id in ("type", "kind", "t")


def _sensor_type_tests(path: Path, names: set[str]) -> list[str]:
    """Comparisons of something's ``type`` with a sensor kind's name (``x.get("type") == "grid"``, ``t in ("grid",
    "camera")``) in one file."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if not isinstance(node, ast.Compare):
            continue
        sides = [node.left, *node.comparators]
        consts = {c.value for side in sides for c in ast.walk(side)
                  if isinstance(c, ast.Constant) and isinstance(c.value, str)}
        if consts & names and any(_is_type_field(s) for s in sides):
            found.append(f"{path.relative_to(ROOT)}:{node.lineno} {ast.unparse(node)}")
    return found


def test_sensor_kinds_are_told_apart_only_in_their_own_modules() -> None:
    """Issue 55: a sensor kind's output is its own (its answer model, its kept results, its files and CSV), so no
    other module of the service or the client tests a sensor's type by name."""
    from tracer.sensors.dispatch import KINDS

    names = set(KINDS)
    offenders = [f for package in ("service", "lumenlink") for path in sorted((ROOT / package).rglob("*.py"))
                 if str(path.relative_to(ROOT)) not in SENSOR_KIND_MODULES | set(SENSOR_KIND_TESTS_LEFT)
                 for f in _sensor_type_tests(path, names)]
    assert not offenders, f"sensor kinds told apart by name outside their modules: {offenders}"
