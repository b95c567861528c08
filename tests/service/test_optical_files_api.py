"""Optical files through REST and the client (issue 38): a TM-25 ray file and a BRDF table are uploaded once, named
by their SHA-256 in a light and a material, survive a restart; a file the reader refuses is a 422 naming what is
wrong, and nothing is stored.

The physics check: a TM-25 beam of N parallel rays straight down from uniform points of a disk of radius R, total
1 lm, onto a black floor 1 m below. The file's own illuminance on a disk of radius r < R at the centre is the flux
of its rays inside it over πr² (exact, the rays are vertical); the service's answer must equal it within 4σ of
its own error (the file is replayed, not resampled)."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from service_helpers import lit_floor, make_client, uid
from test_simulation_api import query

from tracer.optics.lights import tm25

R, N = 0.2, 20_000


def beam(seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    r, phi = R * np.sqrt(rng.random(N)), 2 * math.pi * rng.random(N)
    xy = np.column_stack([r * np.cos(phi), r * np.sin(phi)]) * 1e3          # mm
    return np.column_stack([xy, np.zeros(N), np.zeros((N, 2)), -np.ones(N), np.full(N, 1.0 / N)])


def tm25_bytes(tmp_path: Path, rays: np.ndarray, **kw: Any) -> bytes:
    p = tmp_path / "beam.tm25ray"
    tm25.write(p, rays, **kw)
    return p.read_bytes()


def upload(client: Any, data: bytes, fmt: str) -> Any:
    return client.post("/optical-files", params={"format": fmt}, content=data,
                       headers={"content-type": "application/octet-stream"})


BRDF = "theta_i_deg 0 45\ntheta_o_deg 0 45 90\ndphi_deg 0 180\n" + "0.2\n0.2\n0.2\n0.2\n"


def test_a_tm25_beam_uploaded_once_lights_a_scene_and_outlives_a_restart(tmp_path: Path) -> None:
    rays = beam()
    data = tm25_bytes(tmp_path, rays, flux="luminous", total=1.0)
    fid = hashlib.sha256(data).hexdigest()
    with make_client(tmp_path / "var") as c:
        r = upload(c, data, "tm25")
        assert r.status_code == 201, r.text
        assert r.json() == {**r.json(), "id": fid, "format": "tm25", "bytes": len(data), "rays": N, "flux_unit": "lm"}
        assert upload(c, data, "tm25").status_code == 200           # the same bytes: stored once
        light = {"type": "rayfile", "position": [0.0, 0.0, 1.0], "file": fid}
        sid = lit_floor(c, 1.0, 0.0, light)
        r = c.post(f"/scenes/{sid}/illuminance", json=query([[0.0, 0.0, 0.0]], radius=0.1, max_photons=20_000,
                                                             seed=2, estimator="forward"))
        assert r.status_code == 200, r.text
        first = r.json()
    inside = np.hypot(rays[:, 0], rays[:, 1]) * 1e-3 <= 0.1
    own = float(rays[inside, 6].astype(np.float32).sum()) / (math.pi * 0.1 ** 2)
    assert abs(first["lux"][0] - own) <= 4 * first["stderr"][0], (first, own)
    with make_client(tmp_path / "var") as c:                         # a restart keeps the file and the light
        assert c.get(f"/optical-files/{fid}").json()["rays"] == N
        assert [f["id"] for f in c.get("/optical-files").json()] == [fid]
        r = c.post(f"/scenes/{sid}/illuminance", json=query([[0.0, 0.0, 0.0]], radius=0.1, max_photons=20_000,
                                                             seed=2, estimator="forward"))
        assert r.status_code == 200, r.text
        assert r.json()["lux"] == first["lux"]


@pytest.mark.parametrize(("cut", "fmt", "match"), [
    (lambda b: b[:-10], "tm25", "truncated"), (lambda b: b"XM25" + b[4:], "tm25", "not a TM-25"),
    (lambda b: b"0 0 0 0 0 1\n", "rays", "7 numbers"), (lambda b: BRDF.replace("0.2", "9"), "brdf", "albedo"),
    (lambda b: b"", "tm25", "empty")])
def test_a_file_the_reader_refuses_is_a_422_and_nothing_is_stored(tmp_path: Path, cut, fmt, match) -> None:
    data = cut(tm25_bytes(tmp_path, beam()[:10], flux="luminous"))
    with make_client(tmp_path / "var") as c:
        r = upload(c, data.encode() if isinstance(data, str) else data, fmt)
        assert r.status_code == 422 and match in r.text, r.text
        assert c.get("/optical-files").json() == []
        assert sorted(p.name for p in (tmp_path / "var" / "optical-files").iterdir()) == []
        r = c.post("/optical-files", params={"format": "zip"}, content=b"x")
        assert r.status_code == 422 and "format" in r.text
        assert c.get("/optical-files/" + "0" * 64).status_code == 404


def test_lights_and_materials_name_a_file_by_id_and_an_unknown_id_is_a_422(tmp_path: Path) -> None:
    with make_client(tmp_path / "var") as c:
        fid = upload(c, BRDF.encode(), "brdf").json()["id"]
        sid = lit_floor(c, 1.0, 0.5, {"type": "point", "position": [0.0, 0.0, 1.0], "intensity_cd": 1.0})
        floor = uid(1)
        r = c.put(f"/scenes/{sid}/materials/{floor}", json={"type": "measured_brdf", "file": fid})
        assert r.status_code in (200, 201), r.text
        r = c.put(f"/scenes/{sid}/materials/{floor}", json={"type": "measured_brdf", "file": "1" * 64})
        assert r.status_code == 422 and "'file'" in r.text, r.text
        r = c.put(f"/scenes/{sid}/materials/{floor}", json={"type": "measured_brdf", "file": fid, "table": BRDF})
        assert r.status_code == 422 and "exactly one" in r.text, r.text
        r = c.post(f"/scenes/{sid}/lights", json={"type": "rayfile", "position": [0, 0, 1], "file": "2" * 64})
        assert r.status_code == 422 and "'file'" in r.text, r.text
        r = c.post(f"/scenes/{sid}/lights", json={"type": "rayfile", "position": [0, 0, 1], "file": fid})
        assert r.status_code == 422 and "7 numbers" in r.text, r.text     # a BRDF table is no ray file


def test_the_client_uploads_a_file_streamed_and_guesses_its_format(tmp_path: Path) -> None:
    from lumenlink.client import Client
    from lumenlink.client_elements import _optical_format

    (tmp_path / "a.tm25ray").write_bytes(tm25_bytes(tmp_path, beam()[:100], flux="radiant", single_nm=555.0))
    (tmp_path / "t.brdf.txt").write_text("# a table\n" + BRDF)
    (tmp_path / "r.txt").write_text("0 0 0 0 0 1 1\n")
    assert [_optical_format(tmp_path / n) for n in ("a.tm25ray", "t.brdf.txt", "r.txt")] == ["tm25", "brdf", "rays"]
    with make_client(tmp_path / "var") as c:
        ll = Client("http://testserver", transport=c._transport)
        a = ll.upload_optical_file(tmp_path / "a.tm25ray")
        assert (a["format"], a["rays"], a["flux_unit"]) == ("tm25", 100, "W")
        assert a["flux"] == pytest.approx(100 / N, rel=1e-6)          # W: the rays' sum (1/N each)
        assert ll.upload_optical_file(tmp_path / "t.brdf.txt")["shape"] == [2, 2, 1]
        assert {f["format"] for f in ll.optical_files()} == {"tm25", "brdf"}


def test_a_zemax_bsdf_file_uploads_as_a_brdf_and_reads_as_its_table(tmp_path: Path) -> None:
    """A Zemax / Radiant BSDF Data Interchange file of a Lambertian sample (ρ 0.4, values in relative units) is a
    `brdf` file: the client guesses it, the service reads it into a table of albedo 0.4, and a material names it."""
    from lumenlink.client import Client
    from lumenlink.client_elements import _optical_format
    from tracer.optics.surfaces import zemax_bsdf

    text = zemax_bsdf.write(lambda ti, r, a: 0.4 / math.pi * np.ones(np.broadcast(r, a).shape), [0, 45],
                            [0, 90, 180], [0, 30, 60, 90], scale=10.0)
    (tmp_path / "vinyl.bsdf").write_text("#Data Generated by a test\n" + text)
    assert _optical_format(tmp_path / "vinyl.bsdf") == "brdf"
    with make_client(tmp_path / "var") as c:
        ll = Client("http://testserver", transport=c._transport)
        got = ll.upload_optical_file(tmp_path / "vinyl.bsdf")
        assert got["format"] == "brdf" and got["albedo_max"] == pytest.approx(0.4, rel=1e-9)
        sid = lit_floor(c, 1.0, 0.5, {"type": "point", "position": [0.0, 0.0, 1.0], "intensity_cd": 1.0})
        r = c.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "measured_brdf", "file": got["id"]})
        assert r.status_code in (200, 201), r.text
        bad = upload(c, text.replace("ScatterType  BRDF", "ScatterType  BTDF").encode(), "brdf")
        assert bad.status_code == 422 and "transmission" in bad.text, bad.text
