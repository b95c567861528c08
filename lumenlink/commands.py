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
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import Progress, TaskID

from lumenlink.client import Client, LumenLinkError, ServiceUnreachable
from lumenlink.options import DEFAULT_SERVER, Create, SceneOpt, Server
from lumenlink.sensor_outputs import output_of

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
    keys = ("reflectance", "ior", "alpha", "transmittance", "axis", "retardance_deg")
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

def nodes(
    scene: SceneOpt,
    server: Server = DEFAULT_SERVER,
    create: Create = False,
    json_out: Annotated[bool, typer.Option("--json", help="Print the nodes as JSON.")] = False,
) -> int:
    """Print the scene's tree: each node's path, UUID, material (own or inherited), the lights attached and the
    element it carries."""
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

def assign(
    scene: SceneOpt,
    path: Annotated[str, typer.Argument(help="The node's path (`lumenlink nodes` lists them) or UUID.")],
    material: Annotated[str | None, typer.Argument(
        help='Material JSON, e.g. \'{"type": "dielectric", "ior": 1.5}\'.')] = None,
    file: Annotated[Path | None, typer.Option(help="Read the material JSON from this file.")] = None,
    server: Server = DEFAULT_SERVER,
    create: Create = False,
) -> int:
    """Give a node a material (its descendants without one inherit it)."""
    def work(console: Console) -> int:
        body = _json_arg(material, file, "material")
        with Client(server) as ll:
            info = ll.scene(scene, create=create)
            answer = ll.assign(info, path, body)
        print(f"{path} ({answer['node']}): {_material_text(answer['material'])}")
        return EXIT_OK
    return _run(work)


def light(
    scene: SceneOpt,
    ies: Annotated[Path | None, typer.Option(help="IES LM-63 (.ies) or EULUMDAT (.ldt) file.")] = None,
    at: Annotated[str | None, typer.Option(help="Where the light sits: X,Y,Z in metres (in the node's frame with "
                                                "--attach).")] = None,
    attach: Annotated[str | None, typer.Option(help="Node path or UUID the light moves with.")] = None,
    direction: Annotated[str | None, typer.Option(help="The file's gamma = 0 axis, X,Y,Z (default straight "
                                                       "down).")] = None,
    body: Annotated[str | None, typer.Option(help="Any light as a JSON body instead of --ies.")] = None,
    name: Annotated[str | None, typer.Option(help="A name for people.")] = None,
    server: Server = DEFAULT_SERVER,
    create: Create = False,
) -> int:
    """Add a light: a photometric file placed at a point, or a JSON body."""
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


def sensor(
    scene: SceneOpt,
    grid: Annotated[tuple[str, str, str, int, int] | None, typer.Option(
        metavar="ORIGIN U V NU NV", help="A grid sensor: the rectangle ORIGIN + s*U + t*V (each X,Y,Z in metres; "
                                         "front side U x V) in NU x NV cells, e.g. --grid -1,-1,0 2,0,0 0,2,0 20 "
                                         "20.")] = None,
    body: Annotated[str | None, typer.Option(help="Any sensor as a JSON body instead of --grid.")] = None,
    attach: Annotated[str | None, typer.Option(help="Node path or UUID the sensor moves with.")] = None,
    name: Annotated[str | None, typer.Option(help="A name for people (and for the files simulate writes).")] = None,
    server: Server = DEFAULT_SERVER,
    create: Create = False,
) -> int:
    """Add a sensor."""
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
        size = output_of(b).size(b)
        print(f"sensor {answer['id']}: {b.get('type')}{size}{' ' + repr(b['name']) if b.get('name') else ''}")
        _warn(console, answer)
        return EXIT_OK
    return _run(work)


# ---------------------------------------------------------------- shared by the commands' modules

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


def _pm(value: float | None, err: float | None, digits: int = 4) -> str:
    if value is None:
        return "undefined"
    return f"{value:.{digits}g} ± {err:.2g}" if err is not None else f"{value:.{digits}g}"


