"""CAD adapter: import and tessellation cost on public STEP fixtures at two tolerances, numpy read-out against
cadquery's ``Shape.tessellate`` on a many-part assembly, and a re-push after a one-part edit against a full push.

Sections (all wall-clock seconds on this machine, medians of ``repeat`` runs where stated):

1. Fixtures (``../shared/fixtures/step``) and the sample car at a coarse (0.1 mm, 0.5 rad) and a fine
   (0.01 mm, 0.2 rad) tolerance: import seconds (XCAF read + tree walk), tessellation seconds (no cache)
   and triangles. Accuracy costs time: the fine column shows how much.
2. An assembly of N distinct parts (spheres, cylinders and boxes of sizes over three decades): our
   tessellation (OCCT meshing in parallel, triangulations read straight into numpy), split into meshing
   and read-out, against ``cadquery.Shape.tessellate`` on the same parts and tolerance.
3. The car (fine tolerance) pushed in full (new scene, empty mesh cache) and re-pushed after one part (the
   headlamp lens) changed, then after the doors moved: read, tessellate, upload, push; against the real
   service process when it can be started, otherwise adapter-side only (said so in the result).
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
FIXTURES = ROOT.parent / "shared" / "fixtures" / "step"
TOLERANCES = {"coarse": (0.1, 0.5), "fine": (0.01, 0.2)}  # linear mm, angular rad


def _fixtures() -> list[tuple[str, Path]]:
    names = ["as1-oc-214.stp", "Stamp-S3.step", "STS3215_03a.step", "red_cube_blue_cylinder.step",
             "s1-c5-214/s1-c5-214.stp"]
    return [(n.split("/")[-1], FIXTURES / n) for n in names if (FIXTURES / n).exists()]


def _settings(doc, linear_mm: float, angular: float):
    from cad_adapter.tessellate import Settings
    from cad_adapter.tree import UNIT_METRES

    return Settings(linear=linear_mm * 1e-3 / UNIT_METRES[doc.length_unit], angular=angular)


def bench_fixtures(repeat: int) -> list[dict]:
    from cad_adapter.assembly import read_assembly
    from cad_adapter.samples import car_assembly
    from cad_adapter.step_reader import read_step
    from cad_adapter.tessellate import tessellate

    rows = []
    sources: list[tuple[str, Any]] = [(name, path) for name, path in _fixtures()]
    sources.append(("car sample (cadquery)", None))
    for name, path in sources:
        t_build = None
        if path is None:
            t0 = time.perf_counter()
            assy = car_assembly()
            t_build = time.perf_counter() - t0

            def load(assy=assy):
                return read_assembly(assy)
        else:
            def load(path=path):
                return read_step(path)
        reads = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            doc = load()
            reads.append(time.perf_counter() - t0)
        row: dict[str, Any] = {"name": name, "unit": doc.length_unit, "nodes": len(doc.nodes), "parts": len(doc.parts),
                               "import_s": statistics.median(reads)}
        if t_build is not None:
            row["build_s"] = t_build
        for label, (lin, ang) in TOLERANCES.items():
            times = []
            for _ in range(repeat):
                t = tessellate(load(), _settings(doc, lin, ang))
                times.append(t.seconds)
            row[f"{label}_s"] = statistics.median(times)
            row[f"{label}_triangles"] = t.triangles
            row[f"{label}_failed"] = len(t.failed)
        rows.append(row)
    return rows


def many_parts(n: int):
    import cadquery as cq

    assy = cq.Assembly(name="many")
    for i in range(n):
        size = 10 ** (-1 + 3 * (i % 7) / 6)  # 0.1 .. 100 mm
        kind = i % 3
        if kind == 0:
            wp = cq.Workplane().sphere(size * (1 + 0.01 * i))
        elif kind == 1:
            wp = cq.Workplane().circle(size * (1 + 0.01 * i)).extrude(2 * size)
        else:
            wp = cq.Workplane().box(size, 2 * size * (1 + 0.01 * i), 0.5 * size).edges("|Z").fillet(0.1 * size)
        assy.add(wp, name=f"p{i}", loc=cq.Location((300.0 * (i % 20), 300.0 * (i // 20), 0)))
    return assy


def bench_many(n: int, linear: float, angular: float) -> dict:
    import cadquery as cq
    import numpy as np
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools

    from cad_adapter.assembly import read_assembly
    from cad_adapter.tessellate import _read_faces, mesh_shape

    t0 = time.perf_counter()
    assy = many_parts(n)
    build = time.perf_counter() - t0
    doc = read_assembly(assy)
    shapes = [p.shape for p in doc.parts.values()]
    # ours, end to end
    t0 = time.perf_counter()
    tris = 0
    for s in shapes:
        m, _ = mesh_shape(s, linear, angular, True)
        tris += m.n_triangles
    ours = time.perf_counter() - t0
    # split: OCCT meshing vs numpy read-out
    copies = [BRepBuilderAPI_Copy(s, True, False).Shape() for s in shapes]
    t0 = time.perf_counter()
    for c in copies:
        BRepTools.Clean_s(c, True)
        BRepMesh_IncrementalMesh(c, linear, False, angular, True)
    mesh_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    for c in copies:
        _read_faces(c)
    read_s = time.perf_counter() - t0
    # cadquery's tessellate on the same triangulations: its meshing step is switched off (it would remesh,
    # with a relative deflection), so what is timed is its read-out into lists of Vector and tuples
    cq_shapes = [cq.Shape.cast(c) for c in copies]
    for s in cq_shapes:
        s.mesh = lambda *args, **kwargs: None
    t0 = time.perf_counter()
    cq_tris = 0
    for s in cq_shapes:
        verts, faces = s.tessellate(linear, angular)
        np.array([v.toTuple() for v in verts]), np.array(faces)
        cq_tris += len(faces)
    cq_s = time.perf_counter() - t0
    return {"parts": n, "build_s": build, "ours_s": ours, "occt_mesh_s": mesh_s, "numpy_readout_s": read_s,
            "cadquery_tessellate_s": cq_s, "triangles": tris, "cadquery_triangles": cq_tris,
            "linear": linear, "angular": angular}


def bench_repush() -> dict:
    import cad_adapter
    from cad_adapter.client import Pusher
    from cad_adapter.samples import car_assembly
    from cad_adapter.step_uuid import write_step
    from cad_adapter.tessellate import Settings, TessellationCache, tessellate

    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        step = tmp / "car.step"
        sidecar = tmp / "ids.json"
        write_step(cad_adapter.read_document(car_assembly(), sidecar=sidecar), step)
        edited = tmp / "car_edited.step"
        write_step(cad_adapter.read_document(car_assembly(lens_radius_mm=150.0), sidecar=sidecar), edited)
        moved = tmp / "car_moved.step"
        write_step(cad_adapter.read_document(car_assembly(door_angle_deg=30.0, lens_radius_mm=150.0),
                                             sidecar=sidecar), moved)
        cases = (("full", step), ("one_part_edit", edited), ("doors_moved", moved))
        settings = Settings(linear=TOLERANCES["fine"][0], angular=TOLERANCES["fine"][1])  # mm, as the car
        cache = TessellationCache(tmp / "cache")

        def adapter_side(path: Path) -> tuple[Any, Any, dict]:
            t0 = time.perf_counter()
            doc = cad_adapter.read_document(path)
            t1 = time.perf_counter()
            tess = tessellate(doc, settings, cache=cache)
            t2 = time.perf_counter()
            return doc, tess, {"read": t1 - t0, "tessellate": t2 - t1, "meshed": tess.meshed, "cached": tess.cached}

        service_ctx = None
        try:
            sys.path.insert(0, str(ROOT / "tests"))
            from service_process import running_service

            import service.app  # noqa: F401

            service_ctx = running_service(tmp / "service")
        except Exception as exc:  # no service: adapter side only
            out["service"] = f"not available ({type(exc).__name__}: {exc}); adapter side only"
        if service_ctx is None:
            for label, path in cases:
                _, _, s = adapter_side(path)
                s["total"] = s["read"] + s["tessellate"]
                out[label] = s
            return out
        with service_ctx as url, Pusher(url) as pusher:
            out["service"] = ("real service process (tests/service_process.py), loopback HTTP; warmed up by one push "
                              "of another scene first (the service compiles its kernels on first use)")
            warm = cad_adapter.read_document(car_assembly(door_angle_deg=10.0), write_sidecar=False)
            pusher.push(warm, tessellate(warm, Settings(linear=2.0, angular=0.8)), scene="bench-warmup")
            for label, path in cases:
                doc, tess, s = adapter_side(path)
                t0 = time.perf_counter()
                result = pusher.push(doc, tess, scene="bench-car")
                s["push_total"] = time.perf_counter() - t0
                s.update({f"client_{k}": v for k, v in result.seconds.items()})
                s["uploaded"] = result.uploaded
                s["uploaded_bytes"] = result.uploaded_bytes
                s["service_seconds"] = result.answer.get("seconds", {})
                s["blas_built"] = result.answer.get("blas_built")
                s["geometry_changed"] = len(result.answer.get("geometry_changed", []))
                s["moved"] = len(result.answer.get("moved", []))
                s["total"] = s["read"] + s["tessellate"] + s["push_total"]
                out[label] = s
    return out


def _md(rows: list[dict], many: dict, repush: dict, quick: bool) -> str:
    lines = ["Import (XCAF read and tree walk) and tessellation (no cache; OCCT parallel meshing, numpy read-out)"
             f" seconds, medians; coarse = {TOLERANCES['coarse'][0]} mm / {TOLERANCES['coarse'][1]} rad, "
             f"fine = {TOLERANCES['fine'][0]} mm / {TOLERANCES['fine'][1]} rad (linear converted into each "
             "document's unit).", "",
             "| document | unit | nodes | parts | import s | coarse s | coarse triangles | fine s | fine triangles |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        lines.append(f"| {r['name']} | {r['unit']} | {r['nodes']} | {r['parts']} | {r['import_s']:.3f} | "
                     f"{r['coarse_s']:.3f} | {r['coarse_triangles']:,} | {r['fine_s']:.3f} | {r['fine_triangles']:,} |")
    lines += ["", f"{many['parts']} distinct parts (sizes 0.1-100 mm), linear {many['linear']} mm, angular "
              f"{many['angular']} rad: ours {many['ours_s']:.2f} s ({many['triangles']:,} triangles) = OCCT meshing "
              f"{many['occt_mesh_s']:.2f} s + numpy read-out {many['numpy_readout_s']:.2f} s; "
              f"`cadquery.Shape.tessellate` reading the same triangulations out (into lists, then numpy): "
              f"{many['cadquery_tessellate_s']:.2f} s ({many['cadquery_triangles']:,} triangles, no normals).", ""]
    lines.append(f"Re-push of the sample car (fine tolerance) after one part (the lens) changed, vs a full push (empty "
                 f"mesh cache, new scene) — {repush['service']}:")
    lines.append("")
    keys = [k for k in ("read", "tessellate", "meshed", "cached", "uploaded", "uploaded_bytes", "blas_built",
                        "geometry_changed", "moved", "client_upload", "client_push", "push_total", "total")
            if k in repush["full"]]
    cases = ("full", "one_part_edit", "doors_moved")
    lines += ["| stage | full push | one-part edit (lens) | doors moved |", "| --- | ---: | ---: | ---: |"]
    for k in keys:
        vals = [repush[c][k] for c in cases]
        lines.append(f"| {k} | " + " | ".join(f"{v:.3f}" if isinstance(v, float) else f"{v}" for v in vals) + " |")
    if quick:
        lines += ["", "_quick run: fewer parts and one repetition._"]
    return "\n".join(lines)


def run(quick: bool = False) -> dict:
    """Run the three sections; ``quick``: one repetition and 40 parts instead of 3 repetitions and 200."""
    repeat = 1 if quick else 3
    rows = bench_fixtures(repeat)
    many = bench_many(40 if quick else 200, 0.05, 0.3)
    repush = bench_repush()
    return {"fixtures": rows, "many_parts": many, "repush": repush, "markdown": _md(rows, many, repush, quick)}


if __name__ == "__main__":
    import json

    res = run(quick="--quick" in sys.argv)
    print(res["markdown"])
    print(json.dumps({k: v for k, v in res.items() if k != "markdown"}, indent=1, default=float), file=sys.stderr)
