"""`lumenlink element | nodes | pack | simulate` against a real service (issue 54, item 9): an element put on by B-rep
`--faces` and as `--model`, the scene's assignments listed, switched and removed by the CLI, `nodes` showing the
element a node carries, `pack --damping --max-fill --pitch-mm` reaching the pack body, `simulate` printing a grid's
uniformity; each bad value an exit 2 that says what is wrong. Tiny photon budgets: the physics has its own tests."""

from __future__ import annotations

import csv
import json
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from typer.testing import CliRunner

from lumenlink import Client
from lumenlink.cli import app
from lumenlink.demo import running_service
from lumenlink.guide_demo import DOT, GRID, PITCH, SIZE, _scene

cq = pytest.importorskip("cadquery")

from cad_adapter.glb import encode_glb  # noqa: E402
from cad_adapter.tessellate import face_table, mesh_shape  # noqa: E402

pytestmark = pytest.mark.slow

DOTS = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.3, "height_mm": 0.15},
        "layout": {"type": "grid", "pitch_mm": [1.0, 1.0]}}
DENSITY = {"type": "microstructure", "feature": DOT, "relief": "bump",
           "layout": {"type": "density", "origin_mm": [0.0, 0.0], "size_mm": [SIZE[0], SIZE[1]],
                      "fill": [[1.0] * 24], "seed": 1, "pitch_mm": PITCH}}


@pytest.fixture(scope="module")
def service() -> Iterator[str]:
    data = Path(tempfile.mkdtemp(prefix="lumenlink-element-cli-"))
    try:
        with running_service(data) as url:
            yield url
    finally:
        shutil.rmtree(data, ignore_errors=True)


def cli(url: str, *args: str) -> Any:
    return CliRunner().invoke(app, [*args, "--server", url])


@pytest.fixture(scope="module")
def plate(service: str) -> int:
    """Scene `plate`: a 60 x 40 x 3 mm box meshed by the adapter (its triangles name their B-rep faces) at node
    plate/guide, a dielectric; answers its bottom face's B-rep index."""
    shape = cq.Workplane("XY").box(60, 40, 3, centered=(False, False, False)).val().wrapped
    mesh, _ = mesh_shape(shape, 0.5, 0.8)
    bottom = next(f["face"] for f in face_table(shape) if f["normal"] is not None and f["normal"][2] < -0.999)
    with Client(service) as ll, httpx.Client(base_url=service, timeout=120) as http:
        r = http.put(f"/geometries/{mesh.geometry_id}", headers={"content-type": "model/gltf-binary"},
                     content=encode_glb(mesh.vertices, mesh.triangles, mesh.normals, mesh.face_ids))
        assert r.status_code in (200, 201), r.text
        info = ll.scene("plate", create=True)
        nodes = [{"uuid": "5a7e0000-0000-4000-8000-000000000000", "parent": None, "name": "plate",
                  "transform": list(np.eye(4).ravel()), "geometry": None},
                 {"uuid": "5a7e0000-0000-4000-8000-000000000001", "parent": "5a7e0000-0000-4000-8000-000000000000",
                  "name": "guide", "transform": list(np.eye(4).ravel()), "geometry": mesh.geometry_id}]
        r = http.put(f"/scenes/{info['id']}/document", json={"base_revision": 0, "length_unit": "mm",
                                                             "nodes": nodes})
        assert r.status_code == 200, r.text
        ll.assign(info, "plate/guide", {"type": "dielectric", "ior": 1.49})
    return int(bottom)


def test_element_faces_and_model_then_list_switch_and_remove(service: str, plate: int) -> None:
    with Client(service) as ll:
        dots = ll.add_element(DOTS)["id"]
        other = ll.add_element({**DOTS, "relief": "pit"})["id"]
    put = cli(service, "element", "--id", dots, "--scene", "plate", "--node", "plate/guide", "--faces", str(plate),
              "--model", "bsdf")
    assert put.exit_code == 0, put.output
    with Client(service) as ll:
        (a,) = ll.scene_elements("plate")
    assert a["body"]["faces"] == [plate] and a["model"] == "bsdf" and a["applied"], a
    assert a["support"]["normal"] == pytest.approx([0.0, 0.0, -1.0]) and a["support"]["size_mm"] == [60.0, 40.0]
    assert f"assignment {a['id']}, bsdf, applied on {a['support']['triangles']} triangles (60 x 40 mm)" in put.stdout

    listed = cli(service, "element", "list", "--scene", "plate")
    assert listed.exit_code == 0, listed.output
    assert f"{a['id']}  plate/guide ({a['body']['node']})  element {dots}  bsdf, applied" in listed.stdout
    nodes = cli(service, "nodes", "--scene", "plate")
    assert nodes.exit_code == 0 and "ELEMENT" in nodes.stdout, nodes.output
    row = next(line for line in nodes.stdout.splitlines() if line.startswith("plate/guide "))
    assert f"{dots[:12]} bsdf" in row, nodes.stdout
    as_json = json.loads(cli(service, "nodes", "--scene", "plate", "--json").stdout)
    by_path = {n["path"]: n for n in as_json}
    assert by_path["plate/guide"]["element"] == {"id": a["id"], "model": "bsdf", "applied": True, "problem": None,
                                                 "element": dots}
    assert by_path["plate"]["element"] is None

    switched = cli(service, "element", "switch", "--scene", "plate", "plate/guide", other)   # by the node's path
    assert switched.exit_code == 0, switched.output
    assert f"now carries {other} (was {dots})" in switched.stdout
    with Client(service) as ll:
        assert [(e["id"], e["body"]["element"]) for e in ll.scene_elements("plate")] == [(a["id"], other)]
    removed = cli(service, "element", "remove", "--scene", "plate", a["id"])   # by its id
    assert removed.exit_code == 0 and f"assignment {a['id']} removed" in removed.stdout, removed.output
    with Client(service) as ll:
        assert ll.scene_elements("plate") == []
    empty = cli(service, "element", "list", "--scene", "plate")
    assert empty.exit_code == 0 and "no element assignments" in empty.stdout, empty.output


def test_bad_element_values_are_exit_2_saying_what_is_wrong_and_change_nothing(service: str, plate: int) -> None:
    with Client(service) as ll:
        dots = ll.add_element(DOTS)["id"]
    base = ["element", "--id", dots, "--scene", "plate", "--node", "plate/guide"]
    cases = [
        ([*base, "--faces", "bottom"], "--faces takes B-rep face indices (whole numbers from 0)"),
        ([*base, "--faces", "99"], "faces[0] = 99: the part's mesh has no triangle of B-rep face 99"),
        ([*base, "--faces", str(plate), "--model", "fast"], "--model is exact"),
        ([*base, "--faces", str(plate), "--facing", "0,0,-1"], "one of the two"),
        (["element", "--id", dots, "--faces", str(plate)], "give --scene and --node too"),
        (["element", "remove", "--scene", "plate", "7e57aa55-0000-4000-8000-000000000000"],
         "scene plate has no element assignment"),
        (["element", "remove", "--scene", "plate", "plate/gide"], "did you mean 'plate/guide'"),
        (["element", "switch", "--scene", "plate", "plate/guide", dots], "no element assignment"),
    ]
    for args, words in cases:
        r = cli(service, *args)
        assert r.exit_code == 2, (args, r.output)
        assert words in r.stderr, (args, r.stderr)
    with Client(service) as ll:
        assert ll.scene_elements("plate") == []
        aid = ll.put_element("plate", "plate/guide", dots, faces=[plate])["id"]
        r = cli(service, "element", "switch", "--scene", "plate", aid, "0" * 64)
        assert r.exit_code == 2 and "no element " + "0" * 64 in r.stderr, r.output
        assert [e["body"]["element"] for e in ll.scene_elements("plate")] == [dots]
        ll.remove_element("plate", aid)


@pytest.fixture(scope="module")
def guide(service: str) -> dict[str, str]:
    """Scene `guide-el`: the demo guide carrying a density element, with its 9-point grid over the lit face."""
    with Client(service) as ll, httpx.Client(base_url=service, timeout=300) as http:
        eid = ll.add_element(DENSITY)["id"]
        sid, _ = _scene(ll, http, "guide-el")
        aid = ll.put_element(sid, "backlight/guide", eid, facing=[0, 0, -1])["id"]
        sensor = ll.add_sensor(sid, GRID)["id"]
    return {"element": eid, "assignment": aid, "sensor": sensor}


def test_pack_passes_damping_max_fill_and_pitch_and_refuses_bad_ones(service: str, guide: dict[str, str]) -> None:
    start = ["pack", guide["element"], "--scene", "guide-el", "--assignment", guide["assignment"], "--sensor",
             GRID["name"]]
    for args, words in ((["--damping", "1.5"], "damping must be a number in (0, 1], got 1.5"),
                        (["--max-fill", "0"], "max_fill must be a number in (0, 1], got 0.0"),
                        (["--pitch-mm", "0.1"], "pitch_mm")):
        r = cli(service, *start, *args)
        assert r.exit_code == 2, (args, r.output)
        assert words in r.stderr, (args, r.stderr)
    r = cli(service, *start, "--damping", "0.5", "--max-fill", "0.9", "--pitch-mm", "0.8", "--photons", "20000",
            "--max-iterations", "1")
    assert r.exit_code == 0, r.output
    new = next(line.split()[1].rstrip(":") for line in r.stdout.splitlines() if line.startswith("element "))
    with Client(service) as ll:
        packed = ll._call("GET", f"/elements/{new}", "reading the packed element")
    assert packed["body"]["layout"]["pitch_mm"] == 0.8 and new != guide["element"]


def test_simulate_prints_a_grid_s_uniformity(service: str, guide: dict[str, str], tmp_path: Path) -> None:
    r = cli(service, "simulate", "--scene", "guide-el", "--sensor", GRID["name"], "--out", str(tmp_path),
            "--max-photons", "50000", "--seed", "3")
    assert r.exit_code == 0, r.output
    line = next(ln for ln in r.stdout.splitlines() if ln.strip().startswith("uniformity over 9 values:"))
    rows = list(csv.DictReader((tmp_path / "lit_face_9_points.csv").open()))
    lux = [float(x["lux"]) for x in rows]
    assert len(lux) == 9 and min(lux) > 0
    words = line.split()
    assert float(words[5]) == pytest.approx(min(lux) / max(lux), abs=5e-4)          # min/max 0.xxxx ± e
    assert float(words[9]) == pytest.approx(min(lux) / (sum(lux) / 9), abs=5e-4)    # min/mean
    assert words[6] == "±" and float(words[7].rstrip(",")) > 0
