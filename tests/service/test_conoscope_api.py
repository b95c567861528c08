"""A conoscopic view through the REST API (issue 53): luminance against viewing angle at one point of a lit face.

A Lambertian floor of reflectance ρ under a point source of intensity I at height H shows the same luminance in
every direction, L = ρ E / π with E = I cos θ_i / r² at the point: the view is flat, and every reading (a 1° meter
0.5 m from the point, its spot a few millimetres across) is that closed form within 4 of its own standard errors,
their mean squared z-score 1 within 4 of its own spread (sqrt(2/n)). The point lies 1 m from the source's foot,
where L falls by 9 % per centimetre of floor: a meter that looked at any other point would read another luminance.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from service_helpers import lit_floor, make_client

from tracer.errors import SimulationError
from tracer.sensors.luminance import conoscope_views

I_CD, H, RHO, SIDE = 100.0, 1.5, 0.6, 6.0
LIGHT = np.array([0.0, 0.0, H])
POINT = [1.0, 0.0, 0.0]


@pytest.fixture(scope="module")
def client(tmp_path_factory: Any) -> Any:
    with make_client(Path(tmp_path_factory.mktemp("conoscope")), max_points=200) as c:
        yield c


@pytest.fixture(scope="module")
def floor(client: Any) -> str:
    return lit_floor(client, SIDE, RHO, {"type": "point", "position": LIGHT.tolist(), "intensity_cd": I_CD})


def floor_luminance(x: np.ndarray) -> float:
    d = LIGHT - x
    r2 = float(d @ d)
    return RHO * I_CD * (H / math.sqrt(r2)) / r2 / math.pi


def test_the_meters_stand_on_the_polar_grid_and_look_at_the_point() -> None:
    v = conoscope_views(POINT, [0, 0, 2], 60.0, 4, 6, 0.5, phi_zero=[1, 0, 1])
    np.testing.assert_allclose(v["theta_deg"], [0, 20, 40, 60])
    np.testing.assert_allclose(v["phi_deg"], [0, 60, 120, 180, 240, 300])
    np.testing.assert_allclose(v["phi_zero"], [1, 0, 0], atol=1e-15)   # projected into the face's plane
    eyes, dirs = v["eyes"], v["directions"]
    assert eyes.shape == dirs.shape == (1 + 3 * 6, 3)
    np.testing.assert_allclose(eyes + 0.5 * dirs, np.tile(POINT, (len(eyes), 1)), atol=1e-12)
    for (ring, az), eye in zip(v["cell"], eyes, strict=True):
        t, p = math.radians(v["theta_deg"][ring]), math.radians(v["phi_deg"][az])
        np.testing.assert_allclose(eye - POINT, 0.5 * np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p),
                                                               math.cos(t)]), atol=1e-12)
    with pytest.raises(SimulationError, match="phi_zero"):
        conoscope_views(POINT, [0, 0, 1], 60.0, 4, 6, 0.5, phi_zero=[0, 0, -3])
    with pytest.raises(SimulationError, match="theta_max_deg"):
        conoscope_views(POINT, [0, 0, 1], 90.0, 4, 6, 0.5)


def test_a_lambertian_face_is_flat_in_candela_per_square_metre(client: Any, floor: str) -> None:
    r = client.post(f"/scenes/{floor}/luminance/conoscope",
                    json={"point": POINT, "normal": [0, 0, 1], "theta_max_deg": 70.0, "rings": 8, "azimuths": 12,
                          "max_photons": 85 * 4000, "seed": 5})
    assert r.status_code == 200, r.text
    out = r.json()
    lum, err = np.array(out["luminance"]), np.array(out["stderr"])
    assert lum.shape == err.shape == (8, 12)
    np.testing.assert_allclose(out["theta_deg"], np.linspace(0, 70, 8))
    assert np.all(lum[0] == lum[0, 0])   # the axis: one meter
    exact = floor_luminance(np.array(POINT))
    readings, errors = np.concatenate([lum[:1, 0], lum[1:].ravel()]), np.concatenate([err[:1, 0], err[1:].ravel()])
    assert np.all(errors > 0) and np.all(errors < 0.1 * exact)
    z = (readings - exact) / errors
    assert np.all(np.abs(z) < 4.0), z
    assert abs(np.mean(z**2) - 1.0) < 4.0 * math.sqrt(2.0 / len(z)), np.mean(z**2)
    assert abs(out["on_axis"] - exact) < 4.0 * out["on_axis_stderr"]
    flat = out["flatness"]
    assert flat["min_max"] == pytest.approx(readings.min() / readings.max())
    assert 0.0 < flat["min_max_stderr"] < 0.2
    # flat: the luminance never falls to half within the view, so its spread is at least the view's 70 degrees
    assert (out["half_angle_deg"], out["half_angle_stderr"], out["half_angle_within_view"]) == (70.0, 0.0, False)


def test_the_view_as_a_polar_plot(client: Any, floor: str) -> None:
    r = client.post(f"/scenes/{floor}/luminance/conoscope", params={"format": "png"},
                    json={"point": POINT, "normal": [0, 0, 1], "rings": 3, "azimuths": 8, "max_photons": 20_000})
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "image/png" and r.content[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(r.content) > 10_000


def test_the_python_client_asks_the_same_view(client: Any, floor: str) -> None:
    """`lumenlink.Client.conoscope`: the same body, the same answer on the same seed; its PNG; a bad normal is a
    usage error before anything is sent."""
    from lumenlink import Client, LumenLinkError

    ll = Client("http://testserver", transport=client._transport)
    body = {"point": POINT, "normal": [0, 0, 1], "rings": 3, "azimuths": 4, "max_photons": 8000, "seed": 3}
    direct = client.post(f"/scenes/{floor}/luminance/conoscope", json=body).json()
    got = ll.conoscope(floor, POINT, [0, 0, 1], rings=3, azimuths=4, max_photons=8000, seed=3)
    assert got["luminance"] == direct["luminance"] and got["stderr"] == direct["stderr"]
    assert ll.conoscope(floor, POINT, [0, 0, 1], rings=2, azimuths=4, max_photons=2000, png=True)[:4] == b"\x89PNG"
    with pytest.raises(LumenLinkError, match="normal"):
        ll.conoscope(floor, POINT, [0, 0], rings=2)
    with pytest.raises(LumenLinkError) as refused:   # the service's own check: a zero normal
        ll.conoscope(floor, POINT, [0, 0, 0], rings=2)
    assert refused.value.status == 422


def test_the_command_line_prints_each_meter_and_writes_the_plot(client: Any, floor: str, monkeypatch: Any,
                                                                tmp_path: Path) -> None:
    """``lumenlink conoscope``: one CSV row per meter (the axis once), the answer's numbers; ``--png``; bad usage is
    exit 2 naming the option."""
    import json

    from typer.testing import CliRunner

    import lumenlink.commands_luminance as commands_luminance
    from lumenlink import Client
    from lumenlink.cli import app

    monkeypatch.setattr(commands_luminance, "Client", lambda server: Client("http://testserver",
                                                                            transport=client._transport))
    point = ",".join(map(str, POINT))
    args = ["conoscope", "--scene", floor, "--point", point, "--normal", "0,0,1", "--rings", "3", "--azimuths", "4",
            "--max-photons", "8000", "--seed", "3"]
    runner = CliRunner()
    as_json = runner.invoke(app, [*args, "--json"])
    assert as_json.exit_code == 0, as_json.output
    out = json.loads(as_json.stdout)
    plot = tmp_path / "view.png"
    r = runner.invoke(app, [*args, "--png", str(plot)])
    assert r.exit_code == 0, r.output
    rows = r.stdout.splitlines()
    assert rows[0] == "ring,azimuth,theta_deg,phi_deg,cd_m2,stderr_cd_m2" and len(rows) == 1 + 3 * 4
    assert float(rows[-1].split(",")[4]) == out["luminance"][2][3]
    assert "on axis" in r.output and plot.read_bytes()[:4] == b"\x89PNG"
    bad = runner.invoke(app, ["conoscope", "--scene", floor, "--point", "0,0", "--normal", "0,0,1"])
    assert bad.exit_code == 2 and "--point" in bad.output


@pytest.mark.parametrize(("route", "body", "kind"), [
    ("conoscope", {"point": POINT, "normal": [0, 0, 1], "rings": 2, "azimuths": 4}, "conoscope"),
    ("uniformity", {"points": [POINT], "direction": [0, 0, -1]}, "uniformity"),   # was a 500 at GET /jobs/{id}
])
def test_luminance_queries_as_jobs(client: Any, floor: str, route: str, body: dict, kind: str) -> None:
    r = client.post(f"/scenes/{floor}/luminance/{route}", params={"mode": "async"}, json={**body, "max_photons": 5000})
    assert r.status_code == 202, r.text
    url = r.headers["location"]
    for _ in range(1200):
        job = client.get(url)
        assert job.status_code == 200, job.text
        if job.json()["status"] in ("succeeded", "failed", "cancelled"):
            break
        time.sleep(0.05)
    assert job.json()["status"] == "succeeded" and job.json()["kind"] == kind, job.text
    assert job.json()["result"]["luminance"], job.text


@pytest.mark.parametrize(("body", "params", "status", "says"), [
    ({"normal": [0, 0, 0]}, {}, 422, "normal"),
    ({"phi_zero": [0, 0, 2]}, {}, 422, "phi_zero"),
    ({"rings": 1}, {}, 422, "rings"),
    ({"azimuths": 73}, {}, 422, "azimuths"),
    ({"theta_max_deg": 89.0}, {}, 422, "theta_max_deg"),
    ({"estimator": "forward"}, {}, 422, "estimator"),
    ({"observe": ["spectrum"]}, {}, 422, "observe"),
    ({"rings": 20, "azimuths": 12}, {}, 413, "229 meters"),
    ({}, {"format": "png", "mode": "async"}, 422, "format=png"),
    ({}, {"format": "svg"}, 422, "format"),
])
def test_bad_conoscope_queries_say_what_is_wrong(client: Any, floor: str, body: dict, params: dict, status: int,
                                                 says: str) -> None:
    before = client.get(f"/scenes/{floor}").json()
    r = client.post(f"/scenes/{floor}/luminance/conoscope", params=params,
                    json={"point": POINT, "normal": [0, 0, 1], "max_photons": 1000, **body})
    assert r.status_code == status and says in r.text, r.text
    assert client.get(f"/scenes/{floor}").json() == before
