"""Luminance meters' and cameras' results kept in the result store (issue 37, `service.results`), as grid results
are: listed per revision and state with min/mean/max in cd/m², read back exactly (JSON, CSV), drawn, compared pixel
by pixel with the combined standard error, and still there — the camera's images too — after a restart.

The scene: a Lambertian floor (ρ = 0.6) under a 100 cd point 1.5 m up; a second, equal light doubles every pixel."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from service_helpers import lit_floor, make_client

from service.images import read_exr

SIDE, KEEP = 4.0, 4
LIGHT = {"type": "point", "position": [0.0, 0.0, 1.5], "intensity_cd": 100.0}
CAMERA = {"type": "camera", "position": [0.0, -1.5, 1.2], "look_at": [0.0, 0.3, 0.0], "up": [0.0, 0.0, 1.0],
          "fov_deg": 40.0, "width": 8, "height": 6, "name": "floor view"}
METER = {"type": "luminance", "position": [0.4, 0.1, 1.0], "direction": [0.0, 0.0, -1.0], "aperture_deg": 2.0,
         "name": "meter"}
PNG = b"\x89PNG\r\n\x1a\n"


def _scene(client: Any) -> tuple[str, str, str]:
    sid = lit_floor(client, SIDE, 0.6, LIGHT)
    cam = client.post(f"/scenes/{sid}/sensors", json=CAMERA).json()["id"]
    meter = client.post(f"/scenes/{sid}/sensors", json=METER).json()["id"]
    return sid, cam, meter


def _simulate(client: Any, sid: str, sensor: str, photons: int, seed: int = 1) -> dict:
    r = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": photons, "seed": seed})
    assert r.status_code == 200, r.text
    return r.json()


def test_luminance_results_are_kept_compared_and_outlive_a_restart(tmp_path: Path) -> None:
    with make_client(tmp_path, keep_results=KEEP) as client:
        sid, cam, meter = _scene(client)
        base = f"/scenes/{sid}/sensors/{cam}"
        first = _simulate(client, sid, cam, 48 * 400)
        rev = first["revision"]
        (entry,) = client.get(f"{base}/results").json()["results"]
        lum = np.array(first["luminance"])
        assert entry["key"] == f"{rev}.0" and entry["type"] == "camera" and entry["quantity"] == "luminance"
        assert (entry["width"], entry["height"], entry["fov_deg"]) == (8, 6, 40.0)
        assert entry["min_luminance"] == lum.min() and entry["max_luminance"] == lum.max()
        assert entry["mean_luminance"] == pytest.approx(lum.mean(), rel=1e-15) and "min_lux" not in entry
        kept = client.get(f"{base}/results/{rev}").json()
        assert kept["luminance"] == first["luminance"] and kept["stderr"] == first["stderr"] and "lux" not in kept
        rows = list(csv.DictReader(io.StringIO(client.get(f"{base}/results/{rev}.0", params={"format": "csv"}).text)))
        assert len(rows) == 48 and list(rows[0]) == ["row", "col", "cd_m2", "stderr_cd_m2"]
        assert [float(r["cd_m2"]) for r in rows] == lum.ravel().tolist()
        r = client.get(f"{base}/results/{rev}.0/map.png")
        assert r.status_code == 200 and r.content.startswith(PNG)

        # an assignment (a second, equal light) makes the next state: every lit pixel doubles, beyond the noise
        assert client.post(f"/scenes/{sid}/lights", json=LIGHT).status_code == 201
        doubled = _simulate(client, sid, cam, 48 * 400)
        d = client.get(f"{base}/difference", params={"from": f"{rev}.0", "to": f"{rev}.1"})
        assert d.status_code == 200, d.text
        diff = d.json()
        assert diff["quantity"] == "luminance" and (diff["width"], diff["height"]) == (8, 6)
        np.testing.assert_allclose(diff["difference"], np.subtract(doubled["luminance"], lum), atol=1e-12)
        np.testing.assert_allclose(diff["stderr"], np.hypot(doubled["stderr"], first["stderr"]), rtol=1e-12)
        lit = lum > 0
        delta, sigma = np.array(diff["difference"]), np.array(diff["stderr"])
        assert np.all(np.abs(delta[lit] - lum[lit]) <= 4 * sigma[lit])   # twice the light: + the first image
        assert diff["summary"]["increased"] == int(lit.sum()) and diff["summary"]["decreased"] == 0
        rows = list(csv.DictReader(io.StringIO(client.get(f"{base}/difference", params={
            "from": f"{rev}.0", "to": f"{rev}.1", "format": "csv"}).text)))
        assert len(rows) == 48 and list(rows[0])[2:] == ["cd_m2_from", "cd_m2_to", "difference_cd_m2",
                                                          "stderr_cd_m2"]

        # a meter is kept too: one value
        read = _simulate(client, sid, meter, 20_000)
        (m,) = client.get(f"/scenes/{sid}/sensors/{meter}/results").json()["results"]
        assert m["type"] == "luminance" and m["direction"] == [0.0, 0.0, -1.0] and m["aperture_deg"] == 2.0
        assert client.get(f"/scenes/{sid}/sensors/{meter}/results/{m['key']}").json()["luminance"] == \
            read["luminance"]
        text = client.get(f"/scenes/{sid}/sensors/{meter}/results/{m['key']}", params={"format": "csv"}).text
        assert text.splitlines() == ["row,col,cd_m2,stderr_cd_m2", f"0,0,{read['luminance'][0]!r},"
                                                                  f"{read['stderr'][0]!r}"]
        # a camera's kept pixels are not compared with a meter's value, nor with another size
        bad = client.get(f"{base}/difference", params={"from": f"{rev}.0", "to": "99"})
        assert bad.status_code == 404
        exr_before = client.get(f"{base}/image.exr").content

    # a new process on the same data: the results are listed, and the camera's image of the scene as it is (its
    # revision and state unchanged) is served from the store
    with make_client(tmp_path, keep_results=KEEP) as fresh:
        listed = fresh.get(f"{base}/results").json()["results"]
        assert [e["key"] for e in listed] == [f"{rev}.1", f"{rev}.0"]
        exr = fresh.get(f"{base}/image.exr")
        assert exr.status_code == 200, exr.text
        _, channels = read_exr(exr.content)
        assert np.array_equal(channels["Y"], np.asarray(doubled["luminance"], np.float32))
        assert exr.content[:200] == exr_before[:200]
        assert fresh.get(f"{base}/image.png").status_code == 200
        assert fresh.get(f"{base}/map.png").status_code == 200
        # an edit after the restart: the kept image no longer describes the scene
        assert fresh.post(f"/scenes/{sid}/lights", json=LIGHT).status_code == 201
        assert fresh.get(f"{base}/image.exr").status_code == 404


def test_the_state_a_result_is_kept_under_does_not_depend_on_the_order_lights_are_listed_in() -> None:
    """A restarted service lists lights by creation time, then id: two made in the same instant may come back in
    another order than the process that made them held them. The kept results must still describe the scene
    (this made the restart test above fail about one run in two when the two lights shared a timestamp)."""
    from types import SimpleNamespace

    from service.results import state_digest

    a = {"id": "b-second-by-id", "type": "point", "position": [0.0, 0.0, 1.0], "intensity_cd": 10.0}
    b = {"id": "a-first-by-id", "type": "point", "position": [0.0, 0.0, 1.0], "intensity_cd": 10.0}
    sensor = {"id": "cam", "type": "camera"}
    one = SimpleNamespace(materials={1: {"type": "lambertian"}}, default_material=None, lights=[a, b])
    other = SimpleNamespace(materials={1: {"type": "lambertian"}}, default_material=None, lights=[b, a])
    assert state_digest(one, sensor) == state_digest(other, sensor)
    changed = SimpleNamespace(materials={1: {"type": "lambertian"}}, default_material=None,
                              lights=[a, {**b, "intensity_cd": 20.0}])
    assert state_digest(changed, sensor) != state_digest(one, sensor)


def test_a_black_border_does_not_turn_the_tone_mapped_image_white() -> None:
    """Reinhard's global operator on a uniform 1000 cd/m² field inside a black border: the field shows at its key,
    Ld = a / (1 + a) with a = 0.18 (sRGB 8-bit 110), as it does without the border; with the border's pixels in the
    log-average (δ = 1e-6 cd/m²) it showed at 0.99 (sRGB 254)."""
    from PIL import Image

    from service.images import REINHARD_KEY, tone_mapped_png

    field = np.full((12, 16), 1000.0)
    framed = np.zeros((16, 20))
    framed[2:14, 2:18] = field
    key = REINHARD_KEY / (1.0 + REINHARD_KEY)
    expected = round(255 * (1.055 * key ** (1 / 2.4) - 0.055))
    for image, inside in ((field, np.s_[:, :]), (framed, np.s_[2:14, 2:18])):
        shown = np.asarray(Image.open(io.BytesIO(tone_mapped_png(image))))
        assert np.all(shown[inside] == expected), (shown[inside].min(), shown[inside].max(), expected)
    border = np.asarray(Image.open(io.BytesIO(tone_mapped_png(framed))))
    assert border[0, 0] == 0 and border[-1, -1] == 0
    assert not np.asarray(Image.open(io.BytesIO(tone_mapped_png(np.zeros((4, 4)))))).any()   # no light: black
