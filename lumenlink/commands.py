"""``lumenlink nodes | assign | light | sensor | simulate | export | compare``: the engineer's loop from the command
line, built on :class:`lumenlink.client.Client`.

Exit codes, as ``lumenlink push``: 0 done; 2 bad usage (a bad option or file, a server URL without its scheme, a
scene or node path that does not exist, a body the service refuses as invalid: 4xx); 3 the service cannot be
reached; 1 anything else (the service failed, a job failed, a conflict). Messages and progress go to stderr,
results to stdout.
"""

from __future__ import annotations

import json
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TaskID, TextColumn, TimeElapsedColumn

from lumenlink.client import Client, LumenLinkError, ServiceUnreachable, sensor_csv

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_UNREACHABLE = 0, 1, 2, 3


def _err() -> Console:
    return Console(stderr=True, soft_wrap=True, highlight=False)


def _run(work: Callable[[Console], int]) -> int:
    """Run a command; turn every failure into its message on stderr and its exit code."""
    console = _err()
    try:
        return work(console)
    except ServiceUnreachable as exc:
        console.print(f"[red]error:[/] {escape(str(exc))}")
        return EXIT_UNREACHABLE
    except LumenLinkError as exc:
        console.print(f"[red]error:[/] {escape(str(exc))}")
        for e in (exc.problem.get("errors") or [])[:10]:
            console.print(f"  {escape('.'.join(map(str, e.get('loc', []))))}: {escape(str(e.get('msg')))}")
        return EXIT_USAGE if exc.usage else EXIT_FAILED
    except KeyboardInterrupt:
        console.print("interrupted (a running simulation job was cancelled)")
        return EXIT_FAILED


DIRECTION = "a direction, any length"


def vec3(text: str, option: str, meaning: str = "metres") -> list[float]:
    """``X,Y,Z`` as three floats; a usage error that shows the form otherwise, saying what the numbers are
    (`meaning`: "metres" for a position or an edge, a direction's words for a direction)."""
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(abs(v) < float("inf") for v in values):
        raise LumenLinkError(f"{option} takes X,Y,Z (three numbers, {meaning}), e.g. {option} "
                             f"{'0,0,2.5' if meaning == 'metres' else '0,0,-1'}; got {text!r}", usage=True)
    return values


#: what a body of each kind looks like, for the error that says a body is not JSON
JSON_EXAMPLES = {
    "material": '{"type": "lambertian", "reflectance": 0.8}',
    "light body": '{"type": "point", "position": [0, 0, 2.5], "intensity_cd": 1000}',
    "element": '{"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.3, "height_mm": 0.15}, '
               '"layout": {"type": "grid", "pitch_mm": [1.0, 1.0]}}',
    "sensor body": '{"type": "grid", "origin": [-1, -1, 0], "u": [2, 0, 0], "v": [0, 2, 0], "nu": 10, "nv": 10}',
}


def _json_arg(text: str | None, file: Path | None, what: str) -> dict[str, Any]:
    if (text is None) == (file is None):
        raise LumenLinkError(f"give the {what} as a JSON argument or with --file FILE, one of them", usage=True)
    if file is not None:
        try:
            text = Path(file).read_text(encoding="utf-8")
        except OSError as exc:
            raise LumenLinkError(f"cannot read {file}: {exc}", usage=True) from exc
    assert text is not None
    try:
        body = json.loads(text)
    except ValueError as exc:
        raise LumenLinkError(f"the {what} is not JSON ({exc}); e.g. '{JSON_EXAMPLES[what]}'", usage=True) from exc
    if not isinstance(body, dict):
        raise LumenLinkError(f"the {what} must be a JSON object, got {type(body).__name__}", usage=True)
    return body


def _material_text(body: dict[str, Any]) -> str:
    keys = ("reflectance", "ior", "transmittance", "absorption_per_m", "axis", "retardance_deg")
    extra = " ".join(f"{k}={json.dumps(body[k])}" for k in keys if k in body and not isinstance(body[k], dict))
    return f"{body.get('type', '?')} {extra}".strip()


def _light_text(light: dict[str, Any]) -> str:
    body = light["body"]
    name = f" {body['name']!r}" if body.get("name") else ""
    return f"{body.get('type')}{name} {light['id'][:8]}"


def _warn(console: Console, answer: dict[str, Any]) -> None:
    """The service's warnings (e.g. a position far outside the model: millimetres meant?) on stderr."""
    for w in answer.get("warnings") or []:
        console.print(f"[yellow]warning:[/] {escape(str(w))}")


def _reasons(answer: dict[str, Any]) -> None:
    """Why each effect is on, or off where that was a choice (forced off, or a physics call that could have gone the
    other way), from the answer's ``effect_reasons``; effects no material calls for are left unsaid."""
    for name, why in sorted((answer.get("effect_reasons") or {}).items()):
        if why.startswith("on") or "no material of the scene calls for it" not in why:
            print(f"  effect {name}: {why}")


# ---------------------------------------------------------------- nodes

def nodes(scene: str, server: str, create: bool = False, json_out: bool = False) -> int:
    """Print the scene's tree: path, UUID, material (own, or inherited from an ancestor), the element it carries
    (its id's first 12 digits and model; `lumenlink element list` says more), lights attached."""
    def work(console: Console) -> int:
        with Client(server) as ll:
            info = ll.scene(scene, create=create)
            listed = ll.nodes(info)
            materials = {m["node"]: m["material"] for m in ll.materials(info)}
            lights: dict[str, list[dict[str, Any]]] = {}
            for light in ll.lights(info):
                body = light["body"]
                anchor = body.get("attached_to") or (body.get("node") if body.get("type") == "area" else None)
                if anchor:
                    lights.setdefault(anchor, []).append(light)
            elements = {a["body"]["node"]: a for a in ll.scene_elements(info)}
        by_uuid = {n["uuid"]: n for n in listed}

        def effective(u: str) -> tuple[dict[str, Any] | None, str | None]:
            seen: str | None = u
            while seen is not None:
                if seen in materials:
                    return materials[seen], (None if seen == u else by_uuid[seen]["path"])
                seen = by_uuid[seen]["parent"] if seen in by_uuid else None
            return None, None

        rows = []
        for n in listed:
            mat, source = effective(n["uuid"])
            mat_text = "" if mat is None else _material_text(mat) + (f" (from {source})" if source else "")
            el = elements.get(n["uuid"])
            el_text = "" if el is None else (f"{el['body']['element'][:12]} {el['model']}"
                                             + ("" if el["applied"] else " (not applied)"))
            rows.append({**n, "material": mat, "material_from": source,
                         "lights": [{"id": li["id"], "type": li["body"].get("type"), "name": li["body"].get("name")}
                                    for li in lights.get(n["uuid"], [])],
                         "element": None if el is None else {k: el[k] for k in ("id", "model", "applied", "problem")}
                         | {"element": el["body"]["element"]},
                         "_text": (n["path"], n["uuid"], mat_text, el_text,
                                   ", ".join(_light_text(li) for li in lights.get(n["uuid"], [])))})
        if json_out:
            sys.stdout.write(json.dumps([{k: v for k, v in r.items() if k != "_text"} for r in rows], indent=2)
                             + "\n")
            return EXIT_OK
        unit = info.get("length_unit") or "?"
        print(f"scene {info['name']} ({info['id']}), revision {info['revision']}, {len(listed)} nodes, "
              f"document unit {unit}")
        if not rows:
            print("(no nodes: push a document first, `lumenlink push FILE --scene NAME`)")
            return EXIT_OK
        head = ("PATH", "UUID", "MATERIAL", "ELEMENT", "LIGHTS")
        width = [max(len(head[k]), *(len(r["_text"][k]) for r in rows)) for k in range(4)]
        print("  ".join(h.ljust(width[k]) if k < 4 else h for k, h in enumerate(head)).rstrip())
        for r in rows:
            print("  ".join(t.ljust(width[k]) if k < 4 else t for k, t in enumerate(r["_text"])).rstrip())
        return EXIT_OK
    return _run(work)


# ---------------------------------------------------------------- assign, light, sensor

def assign(scene: str, path: str, material: str | None, file: Path | None, server: str,
           create: bool = False) -> int:
    """Give the node at PATH (or UUID) a material."""
    def work(console: Console) -> int:
        body = _json_arg(material, file, "material")
        with Client(server) as ll:
            info = ll.scene(scene, create=create)
            answer = ll.assign(info, path, body)
        print(f"{path} ({answer['node']}): {_material_text(answer['material'])}")
        return EXIT_OK
    return _run(work)


def light(scene: str, server: str, ies: Path | None = None, at: str | None = None, attach: str | None = None,
          body: str | None = None, name: str | None = None, direction: str | None = None,
          create: bool = False) -> int:
    """Add a light from an IES / EULUMDAT file placed at X,Y,Z (metres), or from a JSON body."""
    def work(console: Console) -> int:
        if (ies is None) == (body is None):
            raise LumenLinkError("give --ies FILE --at X,Y,Z, or --body JSON, one of them", usage=True)
        if ies is not None:
            if at is None:
                raise LumenLinkError("--ies needs --at X,Y,Z (metres; in the node's frame with --attach)", usage=True)
            if not Path(ies).is_file():
                raise LumenLinkError(f"{ies}: no such file", usage=True)
            position = vec3(at, "--at")
            aim = vec3(direction, "--direction", DIRECTION) if direction is not None else None
            with Client(server) as ll:
                info = ll.scene(scene, create=create)
                answer = ll.add_light(info, ies=ies, at=position, attach=attach, name=name, direction=aim)
        else:
            parsed = _json_arg(body, None, "light body")
            with Client(server) as ll:
                info = ll.scene(scene, create=create)
                answer = ll.add_light(info, parsed, attach=attach, name=name)
        where = f" attached to {attach} ({answer['body'].get('attached_to')})" if attach else ""
        print(f"light {answer['id']}: {answer['body'].get('type')}{where}")
        _warn(console, answer)
        return EXIT_OK
    return _run(work)


def _faces(text: str) -> list[int]:
    """``K[,K...]``: B-rep face indices (ints >= 0); a usage error that shows the form otherwise."""
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    if not parts or not all(re.fullmatch(r"\d+", p) for p in parts):
        raise LumenLinkError(f"--faces takes B-rep face indices (whole numbers from 0), e.g. --faces 3 or --faces 3,7;"
                             f" got {text!r} (cad_adapter.tessellate.face_table lists a part's faces)", usage=True)
    return [int(p) for p in parts]


MODELS = ("exact", "bsdf")


def element(scene: str | None, server: str, body: str | None = None, file: Path | None = None,
            node: str | None = None, facing: str | None = None, element_id: str | None = None,
            create: bool = False, faces: str | None = None, model: str | None = None) -> int:
    """Prepare an element into the library (--body JSON or --file), and with --node put it onto the node's faces
    that face --facing X,Y,Z (its frame) or onto its B-rep --faces, as --model exact or bsdf; with neither body nor
    file, list the library."""
    def work(console: Console) -> int:
        if model is not None and model not in MODELS:
            raise LumenLinkError(f"--model is exact (its micro-geometry traced) or bsdf (its tabulated BSDF), got "
                                 f"{model!r}", usage=True)
        if node is None and (facing, faces, model) != (None, None, None):
            raise LumenLinkError("--facing, --faces and --model say how the element goes onto a part: give --scene "
                                 "and --node too", usage=True)
        if node is not None and (scene is None or (facing is None) == (faces is None)):
            raise LumenLinkError("--node needs --scene and the faces that carry it: --facing X,Y,Z (a direction in "
                                 "the node's frame) or --faces K[,K...] (its B-rep faces), one of the two", usage=True)
        along = vec3(facing, "--facing", DIRECTION) if facing is not None else None
        brep = _faces(faces) if faces is not None else None
        with Client(server) as ll:
            if body is None and file is None and element_id is None:
                for e in ll.elements():
                    print(f"{e['id']}  {e['type']}  features {'periodic' if e['features'] is None else e['features']}"
                          f"  {e['bytes']} bytes  prepared in {e['prepare_seconds']:.3f} s")
                return EXIT_OK
            eid = element_id or ll.add_element(_json_arg(body, file, "element"))["id"]
            print(f"element {eid}")
            if node is not None:
                assert scene is not None
                answer = ll.put_element(ll.scene(scene, create=create), node, eid, facing=along, faces=brep,
                                        model=model)
                print(f"on {node} ({answer['body']['node']}): assignment {answer['id']}, {_element_state(answer)}")
        return EXIT_OK
    return _run(work)


def _element_state(a: dict[str, Any]) -> str:
    """An assignment's state in words: its model, applied on what support, or why not."""
    if not a["applied"]:
        return f"{a['model']}, not applied: {a['problem']}"
    sup = a.get("support") or {}
    size = " x ".join(f"{x:.4g}" for x in sup.get("size_mm") or [])
    return f"{a['model']}, applied on {sup.get('triangles')} triangles ({size} mm)"


def _assignment(ll: Client, info: dict[str, Any], which: str) -> dict[str, Any]:
    """The scene's element assignment `which`: its id, or the node (UUID or path) that carries it."""
    listed = ll.scene_elements(info)
    found = [a for a in listed if which.lower() in (a["id"], a["body"]["node"])]
    if not found and not re.fullmatch(r"[0-9a-fA-F-]{36}", which):
        uuid = ll.node(info, which)["uuid"]   # a path: the service's 404 names close ones
        found = [a for a in listed if a["body"]["node"] == uuid]
    if not found:
        have = ", ".join(f"{a['id']} (on {a['body']['node']})" for a in listed) or "none"
        raise LumenLinkError(f"scene {info['name']} has no element assignment {which!r} (an assignment id, or the "
                             f"node that carries it); its assignments: {have}. `lumenlink element list --scene "
                             f"{info['name']}` lists them", usage=True)
    return found[0]


def element_list(scene: str, server: str, json_out: bool = False) -> int:
    """Print the scene's element assignments: id, node path, element id, model, applied (on what) or why not."""
    def work(console: Console) -> int:
        with Client(server) as ll:
            info = ll.scene(scene)
            listed = ll.scene_elements(info)
            paths = {n["uuid"]: n["path"] for n in ll.nodes(info)}
        if json_out:
            print(json.dumps(listed, indent=2))
            return EXIT_OK
        if not listed:
            print(f"scene {info['name']}: no element assignments (lumenlink element --id E --scene S --node PATH "
                  f"--facing X,Y,Z puts one on)")
        for a in listed:
            b = a["body"]
            where = paths.get(b["node"], "(node removed)")
            print(f"{a['id']}  {where} ({b['node']})  element {b['element']}  {_element_state(a)}")
        return EXIT_OK
    return _run(work)


def element_switch(scene: str, server: str, assignment: str, element_id: str) -> int:
    """Switch an element assignment (its id, or the node carrying it) to another library element."""
    def work(console: Console) -> int:
        with Client(server) as ll:
            info = ll.scene(scene)
            a = _assignment(ll, info, assignment)
            answer = ll.switch_element(info, a["id"], element_id)
        print(f"assignment {answer['id']} on {answer['body']['node']} now carries {answer['body']['element']} "
              f"(was {a['body']['element']}), {_element_state(answer)}")
        return EXIT_OK
    return _run(work)


def element_remove(scene: str, server: str, assignment: str) -> int:
    """Take an element assignment (its id, or the node carrying it) off its part."""
    def work(console: Console) -> int:
        with Client(server) as ll:
            info = ll.scene(scene)
            a = _assignment(ll, info, assignment)
            ll.remove_element(info, a["id"])
        print(f"assignment {a['id']} removed: {a['body']['node']} carries no element {a['body']['element']} now")
        return EXIT_OK
    return _run(work)


def optical_file(server: str, file: Path | None = None, format: str | None = None) -> int:  # noqa: A002
    """Upload a ray file or BRDF table once and print its id; with no file, list the uploaded ones."""
    def work(console: Console) -> int:
        with Client(server) as ll:
            if file is None:
                for f in ll.optical_files():
                    print(f"{f['id']}  {f['format']}  {f['bytes']} bytes")
                return EXIT_OK
            answer = ll.upload_optical_file(file, format)
            what = (f"{answer['rays']} rays, {answer['flux']:.6g} {answer['flux_unit']}" if "rays" in answer
                    else f"table {answer.get('shape')}")
            print(f"optical file {answer['id']}  ({answer['format']}, {answer['bytes']} bytes, {what})")
        return EXIT_OK
    return _run(work)


def pack(element_id: str, scene: str, assignment: str, sensor: str, server: str, target: float = 0.8,
         figure: str = "min_max", photons: int = 100_000, max_photons: int = 1_600_000, max_iterations: int = 10,
         max_seconds: float = 600.0, seed: int = 1, switch: bool = False, png: Path | None = None,
         damping: float = 0.7, max_fill: float = 1.0, pitch_mm: float | None = None) -> int:
    """Pack a density element against a grid over the lit face; print each iteration, the packed element's id,
    and with --switch put it in place of the start on the scene; --png writes pack.png. `damping`, `max_fill`
    (in (0, 1]) and `pitch_mm` (mm) are the pack body's fields (the service refuses a bad one, naming it)."""
    def work(console: Console) -> int:
        seen: set[int] = set()

        def show(job: dict[str, Any]) -> None:
            p = job["progress"]   # the uniformity is iteration "measured"'s ("iteration" is the one running)
            measured = p.get("measured")
            if p.get("uniformity") is not None and measured is not None and measured not in seen:
                seen.add(measured)
                console.print(f"  after iteration {measured}: {figure} {p['uniformity']:.3f} ± "
                              f"{p['uniformity_stderr']:.3f}, {p['seconds']:.1f} s")

        with Client(server) as ll:
            info = ll.scene(scene)
            job = ll.pack(element_id, info, assignment, sensor, progress=show, target=target, figure=figure,
                          photons=photons, max_photons=max_photons, max_iterations=max_iterations,
                          max_seconds=max_seconds, seed=seed, damping=damping, max_fill=max_fill,
                          pitch_mm=pitch_mm)
            res = job.get("result") or {}
            if job["status"] == "failed" or not res.get("element"):
                raise LumenLinkError(f"the pack {job['status']}: {job.get('error') or 'nothing was measured'}",
                                     problem=job)
            for h in res["history"]:
                print(f"iteration {h['iteration']}: {figure} {h['uniformity']:.3f} ± {h['stderr']:.3f}  "
                      f"{h['photons']} photons  {h['features']} features  {h['seconds']:.2f} s "
                      f"(update {h['update_seconds'] * 1000:.1f} ms)")
            print(f"element {res['element']}: {figure} {res['uniformity']:.3f} ± {res['uniformity_stderr']:.3f} "
                  f"(iteration {res['best']}; stopped: {res['stopped']}); a full rebuild took "
                  f"{res['rebuild_seconds']:.2f} s, an iteration's update {res['update_seconds_mean'] * 1000:.1f} ms")
            if png is not None:
                Path(png).write_bytes(ll.pack_png(res["element"]))
                print(f"plot {png}")
            if switch:
                ll.switch_element(info, assignment, res["element"])
                print(f"assignment {assignment} now carries {res['element']}")
        return EXIT_OK
    return _run(work)


def sensor(scene: str, server: str, grid: tuple[str, str, str, int, int] | None = None, body: str | None = None,
           attach: str | None = None, name: str | None = None, create: bool = False) -> int:
    """Add a grid sensor (--grid ORIGIN U V NU NV, vectors X,Y,Z in metres) or any sensor from a JSON body."""
    def work(console: Console) -> int:
        if (grid is None) == (body is None):
            raise LumenLinkError("give --grid ORIGIN U V NU NV (e.g. --grid -1,-1,0 2,0,0 0,2,0 20 20), or --body "
                                 "JSON, one of them", usage=True)
        if grid is not None:
            origin, u, v, nu, nv = grid
            parsed = Client.grid(vec3(origin, "ORIGIN"), vec3(u, "U"), vec3(v, "V"), nu, nv, name=name)
        else:
            parsed = _json_arg(body, None, "sensor body")
            if name:
                parsed["name"] = name
        with Client(server) as ll:
            info = ll.scene(scene, create=create)
            answer = ll.add_sensor(info, parsed, attach=attach)
        b = answer["body"]
        size = f" {b['nu']} x {b['nv']} cells" if b.get("type") == "grid" else ""
        print(f"sensor {answer['id']}: {b.get('type')}{size}{' ' + repr(b['name']) if b.get('name') else ''}")
        _warn(console, answer)
        return EXIT_OK
    return _run(work)


# ---------------------------------------------------------------- simulate

def _file_stem(sensor: dict[str, Any], taken: set[str]) -> str:
    """The sensor's name made safe for a file name, else its id; unique within one run."""
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", str(sensor["body"].get("name") or "")).strip("._")
    stem = name or sensor["id"]
    if stem in taken:
        stem = f"{stem}-{sensor['id'][:8]}"
    taken.add(stem)
    return stem


def _flat(x: Any) -> list[Any]:
    return [z for y in x for z in _flat(y)] if isinstance(x, list) else [x]


def _tessellation(result: dict[str, Any]) -> None:
    """The answer's tessellation error, where it has one: the bound and, where asked, the estimate with its cost
    (largest over the values, and at the brightest value), lx."""
    budget = result.get("error_budget") or {}
    if not budget.get("tessellation"):
        return
    lux = [float(x) for x in _flat(result.get("lux") or [])]
    bound = [float(x) for x in _flat(budget["tessellation"])]
    k = max(range(len(lux)), key=lambda i: lux[i]) if lux else 0
    line = f"  tessellation: bound <= {max(bound):.4g} lx"
    if budget.get("tessellation_estimate") is not None:
        est = [float(x) for x in _flat(budget["tessellation_estimate"])]
        se = [float(x) for x in _flat(budget["tessellation_estimate_stderr"])]
        j = max(range(len(est)), key=lambda i: est[i])
        line += (f"; estimate {est[j]:.4g} +- {se[j]:.2g} lx at most, {est[k]:.4g} lx at the brightest value "
                 f"({lux[k]:.4g} lx) [{budget.get('tessellation_estimate_levels')} refinements, "
                 f"{float(budget.get('tessellation_estimate_seconds') or 0):.2f} s]")
    else:
        line += " (a bound; --tessellation-estimate estimates the error itself)"
    print(line)


def _uniformity(result: dict[str, Any]) -> None:
    """A grid's or points' uniformity: min/max and min/mean of its values ± their standard errors (delta method,
    `tracer.photometry.glare.uniformity`); nothing for one value, a surface (min over triangles of very different
    sizes: see its robust max) or a result without values."""
    if result.get("type") not in ("grid", "points"):
        return
    lux = [float(x) for x in _flat(result.get("lux") or [])]
    if len(lux) < 2:
        return
    if not max(lux) > 0:
        print(f"  uniformity over {len(lux)} values: undefined (every value is 0 lx)")
        return
    from tracer.photometry.glare import uniformity

    u = uniformity(lux, [float(x) for x in _flat(result["stderr"])])
    print(f"  uniformity over {len(lux)} values: min/max {_pm(u['min_max'], u['min_max_stderr'])}, min/mean "
          f"{_pm(u['min_mean'], u['min_mean_stderr'])}")


def simulate(scene: str, server: str, out: Path, sensor: str = "all", target: float | None = None,
             max_seconds: float | None = None, max_photons: int | None = None, seed: int = 0,
             force_effects_off: list[str] | None = None, tessellation_estimate: bool = False) -> int:
    """Simulate sensors as jobs (a progress bar per sensor); write <sensor>.csv and, for a grid, <sensor>.png (its map);
    for a camera <sensor>.exr (HDR, cd/m², with its standard error), <sensor>.png (tone-mapped) and
    <sensor>_map.png. `force_effects_off`: effects the query leaves out (the service refuses one it cannot, 422 ->
    exit 2). Each sensor's line is followed by the reasons its effects are on or off (`_reasons`) and, where the
    scene has curved mirror or glass meshes, the tessellation's error (`_tessellation`; `tessellation_estimate`
    asks for the estimate beside the bound)."""
    def work(console: Console) -> int:
        out_dir = Path(out)
        if out_dir.exists() and not out_dir.is_dir():
            raise LumenLinkError(f"--out {out_dir} is a file, not a directory", usage=True)
        with Client(server) as ll:
            info = ll.scene(scene)
            listed = {s["id"]: s for s in ll.sensors(info)}
            chosen = ll._sensor_ids(info["id"], sensor)
            out_dir.mkdir(parents=True, exist_ok=True)
            taken: set[str] = set()
            progress = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[state]}"),
                                TimeElapsedColumn(), console=console, transient=True,
                                disable=not console.is_terminal)
            for s in chosen:
                stem = _file_stem(listed.get(s["id"], s), taken)
                with progress:
                    task = progress.add_task(f"sensor {stem}", total=None, state="queued")
                    update = _progress_update(progress, task, target, max_seconds, max_photons)
                    result = ll.simulate(info, s["id"], target=target, max_seconds=max_seconds,
                                         max_photons=max_photons, seed=seed, progress=update,
                                         force_effects_off=force_effects_off,
                                         tessellation_estimate=tessellation_estimate)[s["id"]]
                csv_path = out_dir / f"{stem}.csv"
                csv_path.write_text(sensor_csv(result), encoding="utf-8")
                written = [csv_path]
                if result.get("type") == "grid":
                    try:
                        png = ll.map_png(info, s["id"])
                    except LumenLinkError as exc:
                        console.print(f"[yellow]warning:[/] no map for sensor {stem}: {escape(str(exc))}")
                    else:
                        (out_dir / f"{stem}.png").write_bytes(png)
                        written.append(out_dir / f"{stem}.png")
                _warn(console, result)
                _reasons(result)
                if result.get("type") in ("luminance", "camera"):
                    if result["type"] == "camera":
                        for name, fmt in ((f"{stem}.exr", "exr"), (f"{stem}.png", "png"), (f"{stem}_map.png", "map")):
                            (out_dir / name).write_bytes(ll.image(info, s["id"], fmt))
                            written.append(out_dir / name)
                    lum = [float(x) for x in _flat(result["luminance"])]
                    print(f"sensor {stem} ({s['id']}): luminance min {min(lum):.4g}, mean {sum(lum) / len(lum):.4g}, "
                          f"max {max(lum):.4g} cd/m2; {result['photons']:,} paths in {result['seconds']:.2f} s "
                          f"({result['stop_reason']}), revision {result['revision']} -> "
                          + ", ".join(str(p) for p in written))
                    continue
                if result.get("type") == "far_field":
                    ies = out_dir / f"{stem}.ies"
                    ll.export(info, s["id"], "ies", out=ies)
                    written.append(ies)
                    print(f"sensor {stem} ({s['id']}): far field, {result['flux_lm']:.6g} +- "
                          f"{result['flux_stderr']:.2g} lm leaving, max {result['max_cd']:.6g} cd; "
                          f"{result['photons']:,} photons in {result['seconds']:.2f} s ({result['stop_reason']}), "
                          f"revision {result['revision']} -> " + ", ".join(str(p) for p in written))
                    continue
                print(f"sensor {stem} ({s['id']}): lux min {result['min_lux']:.4g}, mean {result['mean_lux']:.4g}, "
                      f"max {result['max_lux']:.4g}; {result['photons']:,} photons in {result['seconds']:.2f} s "
                      f"({result['stop_reason']}), revision {result['revision']} -> "
                      + ", ".join(str(p) for p in written))
                _uniformity(result)
                _tessellation(result)
        return EXIT_OK
    return _run(work)


# ---------------------------------------------------------------- export

def export(scene: str, server: str, sensor: str, format: str, out: Path) -> int:
    """Write a far-field sensor's latest result as an IES (LM-63-2002) or EULUMDAT file."""
    def work(console: Console) -> int:
        if format not in ("ies", "ldt"):
            raise LumenLinkError(f"--format is ies (IES LM-63) or ldt (EULUMDAT), got {format!r}", usage=True)
        if Path(out).is_dir():
            raise LumenLinkError(f"--out {out} is a directory: give the file to write, e.g. {Path(out) / 'lamp'}."
                                 f"{format}", usage=True)
        with Client(server) as ll:
            info = ll.scene(scene)
            text = ll.export(info, sensor, format, out=out)
        lines = text.count("\n")
        print(f"sensor {sensor}: {'IES LM-63-2002' if format == 'ies' else 'EULUMDAT'} ({lines} lines) -> {out}")
        return EXIT_OK
    return _run(work)


# ---------------------------------------------------------------- compare

def compare(scene: str, server: str, out: Path, sensor: str = "all", from_key: str | None = None,
            to_key: str | None = None) -> int:
    """Compare two kept results of each sensor: write <sensor>_<from>_to_<to>.csv and .png, print what changed."""
    def work(console: Console) -> int:
        out_dir = Path(out)
        if out_dir.exists() and not out_dir.is_dir():
            raise LumenLinkError(f"--out {out_dir} is a file, not a directory", usage=True)
        with Client(server) as ll:
            info = ll.scene(scene)
            names = {s["id"]: s["body"].get("name") or s["id"] for s in ll.sensors(info)}
            answers = ll.compare(info, sensor, from_key, to_key, out=out_dir)
        for sensor_id, d in answers.items():
            s = d["summary"]
            unit = "cd/m2" if d.get("quantity") == "luminance" else "lx"
            before, after = (s.get(f"mean_{w}_lux", s.get(f"mean_{w}_cd_m2")) for w in ("before", "after"))
            line = (f"sensor {names.get(sensor_id, sensor_id)} ({sensor_id}): {d['from']} -> {d['to']}: mean "
                    f"{before:.4g} -> {after:.4g} {unit}; {s['significant']}/{s['cells']} "
                    f"cells changed beyond {d['significance_sigmas']:g} sigma ({s['increased']} brighter, "
                    f"{s['decreased']} darker)")
            if s.get("max_increase_lux"):
                line += f"; largest rise +{s['max_increase_lux']:.4g} lx at ({_xyz(s['max_increase_at'])}) m"
            if s.get("max_decrease_lux"):
                line += f"; largest fall -{s['max_decrease_lux']:.4g} lx at ({_xyz(s['max_decrease_at'])}) m"
            print(line + " -> " + ", ".join(d["files"]))
            for w in d.get("warnings") or []:
                console.print(f"[yellow]warning:[/] {escape(w)}")
        return EXIT_OK
    return _run(work)


def _xyz(p: list[float]) -> str:
    return ", ".join(f"{c:.3g}" for c in p)


def _progress_update(progress: Progress, task: TaskID, target: float | None, max_seconds: float | None,
                     max_photons: int | None) -> Callable[[dict[str, Any], dict[str, Any]], None]:
    """Moves the bar by whichever budget is given (photons, seconds, then the target error by 1/√N)."""
    def update(sensor: dict[str, Any], job: dict[str, Any]) -> None:
        p = job.get("progress") or {}
        photons, seconds, err = p.get("photons") or 0, p.get("seconds") or 0.0, p.get("worst_relative_error")
        fractions = []
        if max_photons:
            fractions.append(photons / max_photons)
        if max_seconds:
            fractions.append(seconds / max_seconds)
        if target and err:
            fractions.append(min(1.0, (target / err) ** 2))
        left = p.get("seconds_left")
        state = f"{job['status']}: {photons:,} photons" + (f", worst error {err:.1%}" if err else "") + \
            (f", ~{left:.0f} s left" if left is not None else "")
        if fractions:
            progress.update(task, total=1.0, completed=min(1.0, max(fractions)), state=state)
        else:
            progress.update(task, state=state)
    return update


# ---------------------------------------------------------------- glare and uniformity (issue 37)

def _pm(value: float | None, err: float | None, digits: int = 4) -> str:
    if value is None:
        return "undefined"
    return f"{value:.{digits}g} ± {err:.2g}" if err is not None else f"{value:.{digits}g}"


def ugr(scene: str, server: str, sensor: str, background: float | None = None, threshold: float | None = None,
        simulate_first: bool = True, max_seconds: float | None = None, max_photons: int | None = None,
        seed: int = 0, json_out: bool = False) -> int:
    """Simulate a camera (unless told not to) and print the UGR its observer sees, with its error bar."""
    def work(console: Console) -> int:
        with Client(server) as ll:
            info = ll.scene(scene)
            if simulate_first:
                ll.simulate(info, sensor, max_seconds=max_seconds, max_photons=max_photons, seed=seed)
            out = ll.ugr(info, sensor, background=background, threshold=threshold)
        if json_out:
            print(json.dumps(out))
            return EXIT_OK
        bg = _pm(out["background"], out["background_stderr"])
        print(f"UGR {out['ugr']:.2f} ± {out['stderr']:.2f}  (background {bg} cd/m², {out['source_pixels']} source "
              f"pixels ≥ {out['threshold']:.4g} cd/m², revision {out['revision']})")
        return EXIT_OK
    return _run(work)
