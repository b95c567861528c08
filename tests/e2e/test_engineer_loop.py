"""The engineer's loop without curl (issue 22): `lumenlink nodes | assign | light | sensor | simulate` and the
README's `lumenlink.Client` example, against a real `lumenlink serve` process holding the sample car.

Photon budgets are tiny (50,000): these tests check the plumbing and the messages, the physics has its own."""

from __future__ import annotations

import csv
import io
import os
import re
import subprocess
import sys
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from service_process import free_port, running_service  # noqa: E402

from lumenlink import Client, LumenLinkError  # noqa: E402
from lumenlink.cli import app  # noqa: E402

IES = ROOT / "lumenlink" / "data" / "rab_dled6r8y_7.ies"
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    with running_service(tmp_path_factory.mktemp("loop-service")) as url:
        yield url


@pytest.fixture(scope="module")
def sidecar(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("ids") / "ids.json"


@pytest.fixture(scope="module")
def cars(service, sidecar):
    """The sample car pushed twice, as scene `car` (the README example's) and `cli-car` (the commands')."""
    import cad_adapter
    from cad_adapter.client import Pusher
    from cad_adapter.samples import car_assembly

    doc = cad_adapter.read_document(car_assembly(), sidecar=sidecar)
    tess = cad_adapter.tessellate(doc, linear=2.0, angular=0.8)
    with Pusher(service) as p:
        for name in ("car", "cli-car"):
            p.push(doc, tess, scene=name)
    return {n.path: n.uuid for n in doc.nodes}


def cli(service: str, *args: str, env: dict[str, str] | None = None):
    """`lumenlink ARGS` in this process (CliRunner), with --server from the environment as a user would."""
    result = CliRunner().invoke(app, list(args), env={"LUMENLINK_SERVER": service, **(env or {})})
    return result


def test_the_readme_client_example_runs(service, cars, monkeypatch) -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    code = re.search(r"<!-- client-example -->\n```python\n(.*?)```", text, re.S).group(1)
    monkeypatch.setenv("LUMENLINK_SERVER", service)
    monkeypatch.chdir(ROOT)
    out = io.StringIO()
    ns: dict = {}
    with redirect_stdout(out):
        exec(compile(code, "README.md", "exec"), ns)
    assert ns["lens"]["uuid"] == cars["car/headlamp/lens"] and ns["lens"]["path"] == "car/headlamp/lens"
    assert "car/wheel_fl" in ns["paths"] and len(ns["paths"]) == len(cars)
    assert len(ns["lux"]) == 6 and all(len(row) == 8 for row in ns["lux"])
    assert max(max(row) for row in ns["lux"]) > 0.0
    printed = out.getvalue().splitlines()
    assert printed[-3].startswith("succeeded ") and printed[-2].endswith("lx under the light")
    assert float(printed[-2].split()[0]) > 0.0
    # the edit (a paler body) keeps the revision: the two results are its states 0 and 1
    rev = ns["result"][ns["floor"]["id"]]["revision"]
    assert [k["key"] for k in ns["kept"]] == [f"{rev}.1", f"{rev}.0"]
    change = ns["change"]
    assert (change["from"], change["to"]) == (f"{rev}.0", f"{rev}.1") and change["summary"]["cells"] == 48
    assert re.fullmatch(rf"{rev}\.0 -> {rev}\.1: \d+ of 48 cells changed beyond 2σ", printed[-1])
    np.testing.assert_allclose(change["difference"], np.subtract(change["lux_to"], change["lux_from"]), atol=1e-9)
    with Client(service) as ll:
        mats = {m["node"]: m["material"]["type"] for m in ll.materials("car")}
    assert mats == {cars["car/headlamp/lens"]: "dielectric", cars["car/body"]: "lambertian"}


def test_the_commands_find_assign_light_sense_and_simulate(service, cars, tmp_path) -> None:
    r = cli(service, "nodes", "--scene", "cli-car")
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    assert lines[0].startswith("scene cli-car")
    assert lines[1].split() == ["PATH", "UUID", "MATERIAL", "ELEMENT", "LIGHTS"]
    lens_line = next(line for line in lines if line.startswith("car/headlamp/lens "))
    assert cars["car/headlamp/lens"] in lens_line

    r = cli(service, "assign", "--scene", "cli-car", "car/headlamp", '{"type": "mirror", "reflectance": 0.9}')
    assert r.exit_code == 0, r.output
    assert r.stdout.strip() == f"car/headlamp ({cars['car/headlamp']}): mirror reflectance=0.9"
    glass = tmp_path / "glass.json"
    glass.write_text('{"type": "dielectric", "ior": 1.5}')
    r = cli(service, "assign", "--scene", "cli-car", "car/headlamp/lens", "--file", str(glass))
    assert r.exit_code == 0, r.output

    r = cli(service, "light", "--scene", "cli-car", "--ies", str(IES), "--at", "6,0,3")
    assert r.exit_code == 0, r.output
    r = cli(service, "light", "--scene", "cli-car", "--ies", str(IES), "--at", "0.1,0,0", "--attach", "car/headlamp",
            "--name", "lamp")
    assert r.exit_code == 0, r.output
    assert f"attached to car/headlamp ({cars['car/headlamp']})" in r.stdout
    lamp_id = r.stdout.split()[1].rstrip(":")
    r = cli(service, "sensor", "--scene", "cli-car", "--grid", "4,-1.5,0.001", "4,0,0", "0,3,0", "8", "6",
            "--name", "floor")
    assert r.exit_code == 0, r.output
    assert "grid 8 x 6 cells 'floor'" in r.stdout
    r = cli(service, "sensor", "--scene", "cli-car", "--body",
            '{"type": "disk", "center": [6, 0, 0.001], "normal": [0, 0, 1], "radius": 0.1}')
    assert r.exit_code == 0, r.output
    disk_id = r.stdout.split()[1].rstrip(":")

    r = cli(service, "nodes", "--scene", "cli-car")
    rows = {line.split()[0]: line for line in r.stdout.splitlines()[2:]}
    assert "mirror reflectance=0.9" in rows["car/headlamp"] and f"goniometric 'lamp' {lamp_id[:8]}" in \
        rows["car/headlamp"]
    assert "dielectric ior=1.5" in rows["car/headlamp/lens"] and "(from" not in rows["car/headlamp/lens"]
    assert "mirror reflectance=0.9 (from car/headlamp)" in rows["car/headlamp/housing"]

    out = tmp_path / "maps"
    r = cli(service, "simulate", "--scene", "cli-car", "--out", str(out), "--max-photons", "50000")
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in out.iterdir()) == sorted(["floor.csv", "floor.png", f"{disk_id}.csv"])
    assert (out / "floor.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    cells = list(csv.DictReader((out / "floor.csv").open()))
    assert len(cells) == 48 and list(cells[0]) == ["i", "j", "x_m", "y_m", "z_m", "lux", "stderr_lux"]
    first = cells[0]
    assert (float(first["x_m"]), float(first["y_m"]), float(first["z_m"])) == pytest.approx((4.25, -1.25, 0.001))
    assert max(float(c["lux"]) for c in cells) > 0.0
    assert re.search(r"sensor floor \([0-9a-f-]{36}\): lux min .* photons in .* -> .*floor.csv, .*floor.png", r.stdout)
    with Client(service) as ll:   # the CSV is the job's result, cell for cell
        again = ll.simulate("cli-car", "floor", max_photons=50_000)
    lux = next(iter(again.values()))["lux"]
    assert [float(c["lux"]) for c in cells] == pytest.approx([v for row in lux for v in row], rel=1e-6)


def test_edit_then_compare(service, cars, sidecar, tmp_path) -> None:
    """The walkthrough's end: the model edited (the doors opened) and pushed again, simulated, compared."""
    import cad_adapter
    from cad_adapter.client import Pusher
    from cad_adapter.samples import car_assembly

    with Client(service) as ll:
        before = ll.results("cli-car", "floor")
    rev = before[0]["revision"]
    doc = cad_adapter.read_document(car_assembly(door_angle_deg=60.0), sidecar=sidecar)
    with Pusher(service) as p:
        p.push(doc, cad_adapter.tessellate(doc, linear=2.0, angular=0.8), scene="cli-car")
    r = cli(service, "simulate", "--scene", "cli-car", "--sensor", "floor", "--out", str(tmp_path / "after"),
            "--max-photons", "50000")
    assert r.exit_code == 0, r.output
    assert f"revision {rev + 1} ->" in r.stdout
    out = tmp_path / "compare"
    r = cli(service, "compare", "--scene", "cli-car", "--sensor", "floor", "--from", str(rev), "--to", str(rev + 1),
            "--out", str(out))
    assert r.exit_code == 0, r.output
    stem = f"floor_{before[0]['key']}_to_{rev + 1}.0"
    assert sorted(p.name for p in out.iterdir()) == [f"{stem}.csv", f"{stem}.png"]
    assert (out / f"{stem}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert re.search(rf"sensor floor \([0-9a-f-]{{36}}\): {re.escape(before[0]['key'])} -> {rev + 1}\.0: mean .* lx; "
                     r"\d+/48 cells changed beyond 2 sigma", r.stdout), r.stdout
    rows = list(csv.DictReader((out / f"{stem}.csv").open()))
    assert len(rows) == 48 and list(rows[0]) == ["i", "j", "x_m", "y_m", "z_m", "lux_from", "lux_to",
                                                 "difference_lux", "stderr_lux"]
    with Client(service) as ll:
        old, new = ll.result("cli-car", "floor", rev), ll.result("cli-car", "floor", rev + 1)
        by_default = ll.compare("cli-car", "floor")       # the two newest kept: the same pair
    assert [float(c["lux_from"]) for c in rows] == [v for row in old["lux"] for v in row]
    assert [float(c["lux_to"]) for c in rows] == [v for row in new["lux"] for v in row]
    assert [float(c["difference_lux"]) for c in rows] == pytest.approx(
        [b - a for a, b in zip([v for row in old["lux"] for v in row], [v for row in new["lux"] for v in row],
                               strict=True)], abs=1e-9)
    (diff,) = by_default.values()
    assert (diff["from"], diff["to"]) == (before[0]["key"], f"{rev + 1}.0")
    # bad usage: a result nobody kept, a key that is no key
    r = cli(service, "compare", "--scene", "cli-car", "--sensor", "floor", "--from", "99", "--out", str(out))
    assert r.exit_code == 2 and "no kept result '99'" in r.stderr and f"kept: {rev + 1}.0" in r.stderr, r.output
    r = cli(service, "compare", "--scene", "cli-car", "--sensor", "floor", "--from", "r1", "--out", str(out))
    assert r.exit_code == 2 and "from" in r.stderr, r.output


def test_bad_usage_says_what_to_do(service, cars, tmp_path) -> None:
    # a URL without a scheme: exit 2, saying to add http:// (the new commands and push alike)
    r = cli(service, "nodes", "--scene", "cli-car", "--server", "127.0.0.1:8000")
    assert r.exit_code == 2 and "add http://" in r.stderr, r.output
    push = subprocess.run([sys.executable, "-m", "lumenlink.cli", "push", str(tmp_path / "none.step"), "--scene",
                           "x", "--server", "localhost:8000"], capture_output=True, text=True, cwd=ROOT,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
    assert push.returncode == 2 and "add http://" in push.stderr, push.stderr
    # a misspelt scene: an error naming the close names, nothing created
    r = cli(service, "nodes", "--scene", "cli-cra")
    assert r.exit_code == 2 and "did you mean 'cli-car'" in r.stderr, r.output
    with Client(service) as ll:
        assert "cli-cra" not in {s["name"] for s in ll.scenes()}
    r = cli(service, "nodes", "--scene", "fresh", "--create")
    assert r.exit_code == 0 and "no nodes" in r.stdout
    # an unknown path: 404 with "did you mean"
    r = cli(service, "assign", "--scene", "cli-car", "car/headlamp/lenz", '{"type": "black"}')
    assert r.exit_code == 2 and "did you mean 'car/headlamp/lens'" in r.stderr, r.output
    r = cli(service, "light", "--scene", "cli-car", "--ies", str(IES), "--at", "0,0,1", "--attach", "car/lens")
    assert r.exit_code == 2 and "car/headlamp/lens" in r.stderr, r.output
    # malformed options and bodies
    r = cli(service, "light", "--scene", "cli-car", "--ies", str(IES), "--at", "1,2")
    assert r.exit_code == 2 and "--at takes X,Y,Z" in r.stderr, r.output
    r = cli(service, "assign", "--scene", "cli-car", "car/body", "{type: black}")
    assert r.exit_code == 2 and "is not JSON" in r.stderr and '"lambertian"' in r.stderr, r.output
    # a body that is not JSON is shown what its own kind of body looks like, not a material's
    r = cli(service, "light", "--scene", "cli-car", "--body", "{type: point}")
    assert r.exit_code == 2 and "is not JSON" in r.stderr and '"intensity_cd"' in r.stderr, r.output
    assert "lambertian" not in r.stderr, r.output
    r = cli(service, "element", "--scene", "cli-car", "--body", "{dots}")
    assert r.exit_code == 2 and '"microstructure"' in r.stderr and "lambertian" not in r.stderr, r.output
    # a direction is not in metres
    r = cli(service, "element", "--scene", "cli-car", "--id", "0" * 64, "--node", "car/body", "--facing", "0,1")
    assert r.exit_code == 2 and "--facing takes X,Y,Z (three numbers, a direction" in r.stderr, r.output
    assert "metres" not in r.stderr, r.output
    r = cli(service, "assign", "--scene", "cli-car", "car/body", '{"type": "mirror", "reflectance": 7}')
    assert r.exit_code == 2 and "reflectance" in r.stderr, r.output
    r = cli(service, "simulate", "--scene", "cli-car", "--out", str(tmp_path / "m"), "--sensor", "flor")
    assert r.exit_code == 2 and "did you mean 'floor'" in r.stderr, r.output
    # --out that is a file: exit 2 before anything runs, simulate and compare alike, the file left as it was
    (tmp_path / "a-file").write_text("keep me")
    for verb in ("simulate", "compare"):
        r = cli(service, verb, "--scene", "cli-car", "--out", str(tmp_path / "a-file"))
        assert r.exit_code == 2 and "is a file, not a directory" in r.stderr, r.output
    assert (tmp_path / "a-file").read_text() == "keep me"
    # a light placed in millimetres (the car is drawn in mm, the world is metres): added, with a warning saying so
    r = cli(service, "light", "--scene", "cli-car", "--ies", str(IES), "--at", "6000,0,3000")
    assert r.exit_code == 0 and "warning: light" in r.stderr and "document unit is mm" in r.stderr, r.output
    assert "it is [6, 0, 3] m" in r.stderr, r.stderr
    # nothing answers: exit 3
    r = cli(service, "nodes", "--scene", "cli-car", "--server", f"http://127.0.0.1:{free_port()}")
    assert r.exit_code == 3 and "cannot reach the service" in r.stderr, r.output
    # points given flat: the client says the form before asking
    with Client(service) as ll, pytest.raises(LumenLinkError) as err:
        ll.illuminance("cli-car", points=[6, 0, 0.001, 5, 0, 0.001], normals=[[0, 0, 1], [0, 0, 1]])
    assert err.value.usage and "[x, y, z] triples" in str(err.value) and "flat list of 6 numbers" in str(err.value)
    with Client(service) as ll, pytest.raises(LumenLinkError) as err:
        ll.node("cli-car", "car/wheel_f")
    assert err.value.status == 404 and {"car/wheel_fl", "car/wheel_fr"} <= set(err.value.did_you_mean)
