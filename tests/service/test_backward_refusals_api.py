"""Issue 38: everything new works with the backward estimator where it can be sampled, and is refused by it with a
clear 422 where it cannot. Rough (`microfacet`) and tabulated (`measured_brdf`) surfaces are not purely diffuse, and
a `rayfile` light is a set of exact rays that a shadow ray cannot pick: a query that asks for `"estimator":
"backward"` on such a scene gets a 422 that names the kind and why, and nothing stored changes; `"auto"` answers
through forward photons and says so. The Lambertian floor itself answers backward (the control)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from service_helpers import lit_floor, make_client, uid

from tracer.sensors.points import DEFAULT_RADIUS

POINT = {"type": "point", "position": [0.0, 0.0, 1.0], "intensity_cd": 100.0}
RAYS = {"type": "rayfile", "position": [0.0, 0.0, 1.0], "units": "mm", "direction": [0.0, 0.0, -1.0],
        "data": "# x y z l m n flux\n0 0 0 0 0 1 0.5\n0.1 0 0 0.6 0 0.8 0.5\n"}
ROUGH = {"type": "microfacet", "alpha": 0.3, "reflectance": 0.8}
TABLE = {"type": "measured_brdf", "table": {"theta_i_deg": [0.0], "theta_o_deg": [0.0, 90.0],
                                            "dphi_deg": [0.0, 180.0], "brdf": [[[0.5 / math.pi]]]}}
QUERY = {"points": [[0.0, 0.0, 0.0]], "normals": [[0.0, 0.0, 1.0]], "max_photons": 2000, "seed": 1}


@pytest.fixture(scope="module")
def client(tmp_path_factory: Any) -> Any:
    with make_client(Path(tmp_path_factory.mktemp("backward"))) as c:
        yield c


@pytest.mark.parametrize("material, light, why", [
    (None, RAYS, "'rayfile' light is a set of exact rays"),
    (ROUGH, POINT, "'microfacet' surface is not purely diffuse"),
    (TABLE, POINT, "'measured_brdf' surface is not purely diffuse"),
])
def test_backward_refuses_what_it_cannot_sample_and_auto_runs_forward(client: Any, material: dict | None,
                                                                      light: dict, why: str) -> None:
    sid = lit_floor(client, 2.0, 0.5, light, name=why)
    if material is not None:
        assert client.put(f"/scenes/{sid}/materials/{uid(1)}", json=material).status_code in (200, 201)
    before = client.get(f"/scenes/{sid}").json()
    r = client.post(f"/scenes/{sid}/illuminance", json={**QUERY, "estimator": "backward"})
    assert r.status_code == 422, r.text
    assert why in r.text and "backward" in r.text, r.text
    assert client.get(f"/scenes/{sid}").json() == before
    r = client.post(f"/scenes/{sid}/illuminance", json={**QUERY, "estimator": "auto"})
    assert r.status_code == 200, r.text
    assert r.json()["estimator"] == "forward"


def test_the_lambertian_control_answers_backward(client: Any) -> None:
    sid = lit_floor(client, 2.0, 0.5, POINT, name="control")
    r = client.post(f"/scenes/{sid}/illuminance", json={**QUERY, "estimator": "backward"})
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["estimator"] == "backward"
    # the receiver is a disk of radius a (the default) straight below the point light (I = 100 cd, h = 1 m): the mean
    # of I h / (h² + r²)^(3/2) over it is 2 I h (1/h − 1/√(h² + a²)) / a²
    a, h = DEFAULT_RADIUS, 1.0
    exact = 2 * 100.0 * h * (1 / h - 1 / math.hypot(h, a)) / a ** 2
    assert abs(out["lux"][0] - exact) <= 4 * out["stderr"][0] + 1e-9 * exact, (out, exact)
