"""``lumenlink element | optical-file | pack``: optical elements from the command line, built on `lumenlink.Client`;
exit codes as `lumenlink.commands`: 2 bad usage, 3 the service unreachable, 1 the rest."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from lumenlink.client import Client, LumenLinkError
from lumenlink.commands import (
    DIRECTION,
    EXIT_OK,
    _json_arg,
    _run,
    vec3,
)
from lumenlink.options import DEFAULT_SERVER, Assignment, Create, SceneOpt, Server

MODELS = ("exact", "bsdf")


def _faces(text: str) -> list[int]:
    """``K[,K...]``: B-rep face indices (ints >= 0); a usage error that shows the form otherwise."""
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    if not parts or not all(re.fullmatch(r"\d+", p) for p in parts):
        raise LumenLinkError(f"--faces takes B-rep face indices (whole numbers from 0), e.g. --faces 3 or --faces 3,7;"
                             f" got {text!r} (cad_adapter.tessellate.face_table lists a part's faces)", usage=True)
    return [int(p) for p in parts]


def element(
    ctx: typer.Context,
    body: Annotated[str | None, typer.Option(help="Element JSON (docs/DESIGN.md), e.g. a microstructure of domes on a "
                                                  "grid.")] = None,
    file: Annotated[Path | None, typer.Option(help="Read the element JSON from this file.")] = None,
    element_id: Annotated[str | None, typer.Option("--id", help="A library element's id (instead of a body).")] = None,
    scene: Annotated[str | None, typer.Option(help="Scene name or id (with --node).")] = None,
    node: Annotated[str | None, typer.Option(help="Put the element onto this node (path or UUID).")] = None,
    facing: Annotated[str | None, typer.Option(help="The node's faces that carry it: those facing X,Y,Z in its "
                                                    "frame.")] = None,
    faces: Annotated[str | None, typer.Option(help="The node's faces that carry it: its B-rep faces K[,K...] "
                                                   "(instead of --facing).")] = None,
    model: Annotated[str | None, typer.Option(help="exact (default: its micro-geometry traced) or bsdf (its "
                                                   "tabulated BSDF; a dielectric part, grid or hex layouts).")
                     ] = None,
    server: Server = DEFAULT_SERVER,
    create: Create = False,
) -> int:
    """Prepare an optical element with an inside into the library, put it onto a part, or list the library."""
    if ctx.invoked_subcommand is not None:   # `element list | switch | remove`: theirs to run
        return EXIT_OK
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


def element_list(
    scene: SceneOpt,
    server: Server = DEFAULT_SERVER,
    json_out: Annotated[bool, typer.Option("--json", help="Print the assignments as JSON.")] = False,
) -> int:
    """List the scene's element assignments: id, node, element, model, whether applied (and why not), support."""
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


def element_switch(
    scene: SceneOpt,
    assignment: Assignment,
    element_id: Annotated[str, typer.Argument(help="The library element it carries from now on (a packed one, "
                                                   "say).")],
    server: Server = DEFAULT_SERVER,
) -> int:
    """Switch an assignment to another library element: the same node and faces."""
    def work(console: Console) -> int:
        with Client(server) as ll:
            info = ll.scene(scene)
            a = _assignment(ll, info, assignment)
            answer = ll.switch_element(info, a["id"], element_id)
        print(f"assignment {answer['id']} on {answer['body']['node']} now carries {answer['body']['element']} "
              f"(was {a['body']['element']}), {_element_state(answer)}")
        return EXIT_OK
    return _run(work)


def element_remove(
    scene: SceneOpt,
    assignment: Assignment,
    server: Server = DEFAULT_SERVER,
) -> int:
    """Take an element off its part (the part's faces are plain again)."""
    def work(console: Console) -> int:
        with Client(server) as ll:
            info = ll.scene(scene)
            a = _assignment(ll, info, assignment)
            ll.remove_element(info, a["id"])
        print(f"assignment {a['id']} removed: {a['body']['node']} carries no element {a['body']['element']} now")
        return EXIT_OK
    return _run(work)


def optical_file(
    file: Annotated[Path | None, typer.Argument(help="A ray file (TM-25 or text columns) or a measured BRDF table; "
                                                     "none: list the uploaded files.")] = None,
    format: Annotated[str | None, typer.Option(  # noqa: A002 (the wire's name)
        help="tm25, rays or brdf (default: from the file's first bytes).")] = None,
    server: Server = DEFAULT_SERVER,
) -> int:
    """Upload a ray file or a measured BRDF table once; lights and materials then name it by the printed id."""
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


def pack(
    element_id: Annotated[str, typer.Argument(help="The density element to pack (its library id).")],
    scene: SceneOpt,
    assignment: Annotated[str, typer.Option(help="The element assignment that puts it onto the guide's face.")],
    sensor: Annotated[str, typer.Option(help="A grid sensor over the lit face (its cells are the meters).")],
    target: Annotated[float, typer.Option(help="The uniformity to reach, in (0, 1].")] = 0.8,
    figure: Annotated[str, typer.Option(help="min_max or min_mean.")] = "min_max",
    photons: Annotated[int, typer.Option(help="Photons of the first measurement (x4 as the map converges).")
                       ] = 100_000,
    max_photons: Annotated[int, typer.Option(help="The most photons of one measurement.")] = 1_600_000,
    max_iterations: Annotated[int, typer.Option(help="Budget: measurements at most.")] = 10,
    max_seconds: Annotated[float, typer.Option(help="Budget: seconds.")] = 600.0,
    damping: Annotated[float, typer.Option(help="The multiplicative step's exponent, in (0, 1] (smaller: slower, "
                                                "steadier).")] = 0.7,
    max_fill: Annotated[float, typer.Option(help="The largest fill a map cell may take, in (0, 1].")] = 1.0,
    pitch_mm: Annotated[float | None, typer.Option(help="The lattice pitch, mm (at least the feature's size; "
                                                        "default the element's).")] = None,
    seed: Annotated[int, typer.Option(help="Photon seed.")] = 1,
    quantity: Annotated[str, typer.Option(help="What the cells read: illuminance (lx) or luminance (cd/m², a viewer "
                                               "--distance m in front of each cell).")] = "illuminance",
    distance: Annotated[float, typer.Option(help="With luminance: the viewer's distance from the grid, m.")] = 0.5,
    switch: Annotated[bool, typer.Option("--switch", help="Put the packed element in place of the start.")] = False,
    png: Annotated[Path | None, typer.Option(help="Write pack.png here.")] = None,
    server: Server = DEFAULT_SERVER,
) -> int:
    """Pack a light guide's density element until its lit face is uniform (a job; Ctrl-C cancels it)."""
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
                          pitch_mm=pitch_mm, quantity=quantity, distance=distance)
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
            _picture_and_switch(ll, info, assignment, res["element"], png, ll.pack_png, switch)
        return EXIT_OK
    return _run(work)


def _picture_and_switch(ll: Client, info: dict[str, Any], assignment: str, element: str, png: Path | None,
                        picture: Callable[[str], bytes], switch: bool) -> None:
    """After a pack or a design loop: write the made element's picture (`picture(element)`: PNG bytes) to `png`,
    and put the element in place of the start on `assignment`, where asked."""
    if png is not None:
        Path(png).write_bytes(picture(element))
        print(f"plot {png}")
    if switch:
        ll.switch_element(info, assignment, element)
        print(f"assignment {assignment} now carries {element}")


def _parameter(text: str) -> dict[str, Any]:
    """``NAME=V1,V2,...`` or ``NAME=LO:HI:STEPS`` as a design parameter's body."""
    name, sep, values = text.partition("=")
    try:
        if not sep or not name:
            raise ValueError
        if ":" in values:
            lo, hi, steps = values.split(":")
            return {"name": name, "lo": float(lo), "hi": float(hi), "steps": int(steps)}
        return {"name": name, "values": [float(x) for x in values.split(",")]}
    except ValueError:
        raise LumenLinkError(f"--param {text!r}: give NAME=V1,V2,... or NAME=LO:HI:STEPS (e.g. "
                             f"feature.height_mm=0.05:0.2:4)", usage=True) from None


def design(
    element_id: Annotated[str, typer.Argument(help="The element to start from (its library id).")],
    scene: SceneOpt,
    assignment: Annotated[str, typer.Option(help="The element assignment that puts it onto the guide's face.")],
    sensor: Annotated[str, typer.Option(help="A grid sensor over the lit face (its cells are the meters).")],
    param: Annotated[list[str], typer.Option(help="A number of the element to vary: NAME=V1,V2,... or "
                                                  "NAME=LO:HI:STEPS (feature.height_mm, feature.apex_deg, "
                                                  "layout.pitch_mm[0], material.reflectance); one to three.")],
    objective: Annotated[str, typer.Option(help="min_max, min_mean, mean (the mean reading) or half_angle (the "
                                                "viewing-angle spread of the grid's centre, degrees).")] = "min_max",
    goal: Annotated[str, typer.Option(help="max (raise the objective) or min (lower it: a narrower spread).")
                    ] = "max",
    photons: Annotated[int, typer.Option(help="Photons of each reading.")] = 100_000,
    seed: Annotated[int, typer.Option(help="Photon seed (every candidate reads with the same one).")] = 1,
    pack_map: Annotated[bool, typer.Option("--pack-map", help="Pack the density map before and after the sweep "
                                                              "(to --target).")] = False,
    target: Annotated[float, typer.Option(help="With --pack-map: the uniformity the packs aim at.")] = 0.8,
    quantity: Annotated[str, typer.Option(help="What the cells read: illuminance (lx) or luminance (cd/m²).")
                        ] = "illuminance",
    switch: Annotated[bool, typer.Option("--switch", help="Put the chosen element in place of the start.")] = False,
    png: Annotated[Path | None, typer.Option(help="Write design.png here.")] = None,
    server: Server = DEFAULT_SERVER,
) -> int:
    """Tune an element's numbers against what its lit face reads (a job; Ctrl-C cancels it, keeping the best)."""
    def work(console: Console) -> int:
        parameters = [_parameter(p) for p in param]

        def show(job: dict[str, Any]) -> None:
            p = job["progress"]
            if p.get("stage") == "sweep" and p.get("objective") is not None:
                console.print(f"  candidate {p['candidate'] + 1} of {p['candidates']}: {objective} "
                              f"{p['objective']:.4g} ± {p['objective_stderr']:.2g}")

        with Client(server) as ll:
            info = ll.scene(scene)
            job = ll.design(element_id, info, assignment, sensor, parameters, objective=objective, progress=show,
                            photons=photons, seed=seed, pack_map=pack_map, target=target, quantity=quantity,
                            goal=goal)
            res = job.get("result") or {}
            if job["status"] == "failed" or not res.get("element"):
                raise LumenLinkError(f"the design loop {job['status']}: {job.get('error') or 'nothing was read'}",
                                     problem=job)
            for c in res["candidates"]:
                values = ", ".join(f"{k} {v:g}" for k, v in c["values"].items())
                said = f"refused: {c['refused']}" if c["refused"] else f"{objective} {c['objective']:.4g} ± " \
                    f"{c['stderr']:.2g}"
                print(f"{values}: {said}")
            b, c = res["baseline"], res.get("confirmation")
            print(f"start {b['objective']:.4g} ± {b['stderr']:.2g}; stopped: {res['stopped']}")
            if c:
                print(f"fresh seed: start {c['baseline']:.4g} ± {c['baseline_stderr']:.2g}, chosen {c['objective']:.4g}"
                      f" ± {c['stderr']:.2g}, gain {c['improvement']:.4g} ± {c['improvement_stderr']:.2g} "
                      f"({'beyond' if c['improved'] else 'within'} 2 sigma)")
            if res["element"] == element_id:
                print(f"no candidate read better than the start: element {element_id} stays")
                return EXIT_OK
            print(f"element {res['element']}: {res['values']}")
            _picture_and_switch(ll, info, assignment, res["element"], png, ll.design_png, switch)
        return EXIT_OK
    return _run(work)
