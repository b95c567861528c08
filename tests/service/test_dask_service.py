"""The service on a Dask cluster (issue 25): real `lumenlink serve` processes, a real scheduler and workers.

The same scene and query through a service computing in-process and through one whose batches run on the
cluster give the same lux to the last bit, and the answer says where it ran; a scheduler that is not there is
a 503 problem, quickly, and leaves the scene as it was; bad addresses are refused where they are given.
"""

from __future__ import annotations

import subprocess
import sys
import time

import httpx
import pytest
from service_helpers import glb, grid_mesh, make_client, node, translation, uid
from service_process import ROOT, free_port, running_service

from bench.dask_cluster import dask_cluster


def _lit_floor(base: str) -> str:
    """A grey 4 m floor under a 100 cd point light at 2 m and a glass block; the scene's id."""
    c = httpx.Client(base_url=base, timeout=60)
    sid = c.post("/scenes", json={"name": "floor"}).json()["id"]
    floor, block = grid_mesh(n=2, size=4.0), grid_mesh(n=1, size=0.6)
    for v, f in (floor, block):
        gid, data = glb(v, f)
        assert c.put(f"/geometries/{gid}", content=data,
                     headers={"content-type": "model/gltf-binary"}).status_code in (200, 201)
    doc = {"base_revision": 0, "length_unit": "m", "source": {"name": "floor"},
           "nodes": [node(uid(0), None, "room"),
                     node(uid(1), uid(0), "floor", translation(-2.0, -2.0, 0.0), geometry=glb(*floor)[0]),
                     node(uid(2), uid(0), "mirror", translation(-0.3, -0.3, 1.0), geometry=glb(*block)[0])]}
    assert c.put(f"/scenes/{sid}/document", json=doc).status_code == 200
    assert c.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "lambertian", "reflectance": 0.5}).is_success
    assert c.put(f"/scenes/{sid}/materials/{uid(2)}", json={"type": "mirror", "reflectance": 0.9}).is_success
    assert c.post(f"/scenes/{sid}/lights",
                  json={"type": "point", "position": [0.0, 0.0, 2.0], "intensity_cd": 100.0}).status_code == 201
    return sid


QUERY = {"points": [[0.6, 0.0, 0.0], [1.0, 0.5, 0.0]], "normals": [[0, 0, 1.0]] * 2, "max_photons": 640_000,
         "seed": 4, "estimator": "forward"}


def test_a_service_on_a_dask_cluster_answers_what_an_in_process_service_answers(tmp_path):
    data = tmp_path / "data"
    with running_service(data) as base:
        sid = _lit_floor(base)
        here = httpx.post(f"{base}/scenes/{sid}/illuminance", json=QUERY, timeout=300).json()
    assert here["backend"]["name"] == "in-process" and here["lux"][0] > 0
    with dask_cluster(tmp_path / "dask", workers=2) as cluster, \
            running_service(data, env={"LUMENLINK_DASK_SCHEDULER": cluster.address}) as base:
        there = httpx.post(f"{base}/scenes/{sid}/illuminance", json=QUERY, timeout=300)
        assert there.status_code == 200, there.text
        there = there.json()
        sensor = httpx.post(f"{base}/scenes/{sid}/sensors", json={
            "type": "grid", "origin": [-1, -1, 0], "u": [2, 0, 0], "v": [0, 2, 0], "nu": 3, "nv": 3}).json()
        grid = httpx.post(f"{base}/scenes/{sid}/sensors/{sensor['id']}/simulate",
                          json={"max_photons": 320_000, "seed": 2}, timeout=300)
        assert grid.status_code == 200, grid.text
    assert there["backend"] == {"name": "dask", "address": cluster.address, "workers": 2, "threads": 2}
    assert there["device"] == "cpu:2 threads on 2 dask workers" and here["device"].startswith("cpu:")
    assert (there["lux"], there["stderr"], there["photons"]) == (here["lux"], here["stderr"], here["photons"])
    assert grid.json()["backend"]["name"] == "dask" and grid.json()["mean_lux"] > 0


def test_no_scheduler_is_a_503_that_changes_nothing(tmp_path):
    client = make_client(tmp_path, dask_scheduler=f"tcp://127.0.0.1:{free_port()}", dask_timeout=2)
    with client:
        sid = client.post("/scenes", json={"name": "s"}).json()["id"]
        v, f = grid_mesh(n=1, size=1.0)
        gid, data = glb(v, f)
        client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"})
        doc = {"base_revision": 0, "length_unit": "m", "source": {"name": "s"},
               "nodes": [node(uid(0), None, "floor", geometry=gid)]}
        assert client.put(f"/scenes/{sid}/document", json=doc).status_code == 200
        client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0, 0, 1.0], "intensity_cd": 1.0})
        before = client.get(f"/scenes/{sid}").json()
        t = time.monotonic()
        r = client.post(f"/scenes/{sid}/illuminance", json={"points": [[0.5, 0.5, 0]], "normals": [[0, 0, 1]],
                                                            "max_photons": 40_000})
        assert time.monotonic() - t < 30
        assert r.status_code == 503 and r.headers["content-type"].startswith("application/problem+json")
        assert "Dask scheduler" in r.json()["detail"] and "does not answer" in r.json()["detail"]
        assert "retry-after" in r.headers
        assert client.get(f"/scenes/{sid}").json() == before


def test_bad_dask_addresses_are_refused_where_they_are_given(tmp_path):
    from pydantic import ValidationError

    from service.config import Settings

    with pytest.raises(ValidationError, match="dask_scheduler"):
        Settings(data_dir=tmp_path, dask_scheduler="127.0.0.1:8786")
    out = subprocess.run([sys.executable, "-m", "lumenlink.cli", "serve", "--data-dir", str(tmp_path),
                          "--dask", "localhost:8786"], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and "tcp://127.0.0.1:8786" in out.stderr, out.stderr
