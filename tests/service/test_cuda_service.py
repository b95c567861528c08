"""The service on CUDA (issue 27), without a GPU: a real ``lumenlink serve`` with ``LUMENLINK_DEVICE=cuda`` in
numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) runs a query's photon batches through
`tracer.gpu.backend.CudaBackend`; its answer says ``device`` "cuda:0 simulator" and agrees with a CPU service's
answer (another seed: two independent estimates) within 4 combined standard errors.
"""

from __future__ import annotations

import importlib.util

import httpx
import numpy as np
import pytest
from service_helpers import glb, grid_mesh, node, translation, uid
from service_process import running_service

Z = 4.0   # combined standard errors (the issue's |ΔE| ≤ 4σ)
QUERY = {"points": [[0.3, 0.0, 0.0], [1.0, 0.5, 0.0]], "normals": [[0, 0, 1.0]] * 2, "radius": 0.3,
         "max_photons": 200_000, "estimator": "forward",
         "max_seconds": 600.0}   # photons, not the clock, end it: a loaded machine gives the same count


def _lit_floor(base: str) -> str:
    """A grey 4 m floor under a 100 cd point light at 2 m; the scene's id."""
    c = httpx.Client(base_url=base, timeout=60)
    sid = c.post("/scenes", json={"name": "floor"}).json()["id"]
    v, f = grid_mesh(n=2, size=4.0)
    gid, data = glb(v, f)
    assert c.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"}).is_success
    doc = {"base_revision": 0, "length_unit": "m", "source": {"name": "floor"},
           "nodes": [node(uid(0), None, "room"), node(uid(1), uid(0), "floor", translation(-2.0, -2.0, 0.0),
                                                     geometry=gid)]}
    assert c.put(f"/scenes/{sid}/document", json=doc).status_code == 200
    assert c.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "lambertian", "reflectance": 0.5}).is_success
    assert c.post(f"/scenes/{sid}/lights",
                  json={"type": "point", "position": [0.0, 0.0, 2.0], "intensity_cd": 100.0}).status_code == 201
    return sid


def test_a_cuda_service_in_the_simulator_answers_as_a_cpu_service(tmp_path):
    if importlib.util.find_spec("numba_cuda") is None:
        pytest.skip("numba-cuda is not installed (pip install -e '.[gpu]')")
    data = tmp_path / "data"
    with running_service(data, env={"LUMENLINK_DEVICE": "cpu"}) as base:
        sid = _lit_floor(base)
        r = httpx.post(f"{base}/scenes/{sid}/illuminance", json={**QUERY, "seed": 1}, timeout=600)
        assert r.status_code == 200, r.text
        cpu = r.json()
    with running_service(data, env={"LUMENLINK_DEVICE": "cuda", "NUMBA_ENABLE_CUDASIM": "1"},
                         log_name="cuda.log") as base:
        r = httpx.post(f"{base}/scenes/{sid}/illuminance", json={**QUERY, "seed": 2}, timeout=600)
        assert r.status_code == 200, r.text
        gpu = r.json()
    assert cpu["device"].startswith("cpu:") and cpu["backend"]["name"] == "in-process", cpu["backend"]
    assert gpu["device"] == "cuda:0 simulator", gpu["device"]
    assert gpu["backend"] == {"name": "cuda", "device": "cuda:0 simulator"}
    budget = QUERY["max_photons"]   # the card's cut of the query has other batches (tracer.gpu.backend.GPU_SHAPE)
    assert 0.99 * budget <= gpu["photons"] <= budget and 0.99 * budget <= cpu["photons"] <= budget
    assert min(gpu["lux"]) > 0
    lux_c, lux_g = np.asarray(cpu["lux"]), np.asarray(gpu["lux"])
    sigma = np.hypot(cpu["stderr"], gpu["stderr"])
    assert np.all(sigma < 0.1 * lux_c), (cpu, gpu)
    assert np.all(np.abs(lux_g - lux_c) <= Z * sigma), (lux_c, lux_g, sigma)


def test_the_answer_carries_why_it_ran_on_the_cpu():
    """A query that CUDA could not take (`tracer.simulate` fell back to the CPU) keeps its reason through the wire
    schema: `backend.fallback`, beside `device` "cpu:…"; a CUDA answer's `backend` names the card."""
    from types import SimpleNamespace

    from service.routes.simulation import IlluminancePublic
    from service.simulation import result_payload

    why = "ran on the CPU because the scene needs 3.0 GiB on cuda:0 X, which has 1.0 GiB free (64 MiB kept in reserve)"
    for backend, device in (({"name": "in-process", "threads": 2, "fallback": why}, "cpu:2 threads"),
                            ({"name": "cuda", "device": "cuda:0 X"}, "cuda:0 X")):
        result = SimpleNamespace(lux=[1.0], stderr=[0.1], photons=10, seconds=0.1, effects=["lambertian"],
                                 estimator="forward", stop_reason="max_photons", backend=backend)
        wire = IlluminancePublic.model_validate(result_payload(result, 3)).model_dump(exclude_none=True)
        assert wire["backend"] == backend and wire["device"] == device, wire
