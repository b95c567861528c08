"""The simulation endpoints through the real app (real tracer, real transport, SQLite in a temp dir).

The scene: a black 4 m × 4 m floor in z = 0 (a black floor reflects nothing, so the only light at
the floor is the direct light), a 100 cd isotropic point source at height 2 m. Closed form at a
floor point at horizontal distance d: E = I·h / (h² + d²)^{3/2} (inverse square times cos θ).
"""

from __future__ import annotations

import io
import json
import math
import time

import matplotlib.image as mpimg
import numpy as np
import pytest
from service_helpers import UNKNOWN_ID, glb, grid_mesh, make_client, node, translation, uid

I_CD = 100.0
H = 2.0
LIMITS = {"max_points": 50, "max_photons": 4_000_000, "max_seconds": 30.0}


def floor_point_lux(x: float, y: float) -> float:
    return I_CD * H / (H * H + x * x + y * y) ** 1.5


def disk_average_lux(x: float, y: float, radius: float) -> float:
    """The closed form averaged over a floor disk (Gauss–Legendre in r, uniform in angle): what a receiver measures.

    The backward estimator is precise enough (1e-7 relative) to see the disk average differ from the
    point value by 0.75 (r/h)² relative.
    """
    nodes, weights = np.polynomial.legendre.leggauss(24)
    r = 0.5 * radius * (nodes + 1.0)
    w = 0.5 * radius * weights
    phi = 2 * np.pi * (np.arange(64) + 0.5) / 64
    e = floor_point_lux(x + r[:, None] * np.cos(phi), y + r[:, None] * np.sin(phi))
    return float(np.sum(w[:, None] * r[:, None] * e) * (2 * np.pi / 64) / (np.pi * radius**2))


def push_floor(client, scene_id: str, base_revision: int, dx: float = 0.0) -> dict:
    v, f = grid_mesh(n=2, size=4.0)
    gid, data = glb(v, f)
    r = client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"})
    assert r.status_code in (200, 201), r.text
    doc = {"base_revision": base_revision, "length_unit": "m", "source": {"name": "floor"},
           "nodes": [node(uid(0), None, "room"), node(uid(1), uid(0), "floor", translation(-2.0 + dx, -2.0, 0.0),
                                                      geometry=gid)]}
    r = client.put(f"/scenes/{scene_id}/document", json=doc)
    assert r.status_code == 200, r.text
    return r.json()


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """One app and scene for the module (the kernels compile once); tests that change it restore it."""
    client = make_client(tmp_path_factory.mktemp("sim"), **LIMITS)
    with client:
        scene = client.post("/scenes", json={"name": "floor"}).json()
        push_floor(client, scene["id"], 0)
        r = client.put(f"/scenes/{scene['id']}/materials/{uid(1)}", json={"type": "black"})
        assert r.status_code == 200, r.text
        r = client.post(f"/scenes/{scene['id']}/lights",
                        json={"type": "point", "position": [0.0, 0.0, H], "intensity_cd": I_CD})
        assert r.status_code == 201, r.text
        r = client.post(f"/scenes/{scene['id']}/sensors",
                        json={"type": "grid", "origin": [-0.5, -0.5, 0.0], "u": [1.0, 0.0, 0.0],
                              "v": [0.0, 1.0, 0.0], "nu": 4, "nv": 4, "name": "floor centre"})
        assert r.status_code == 201, r.text
        yield client, scene["id"], r.json()["id"]


def query(points, normals=None, **extra) -> dict:
    normals = normals if normals is not None else [[0.0, 0.0, 1.0]] * len(points)
    return {"points": points, "normals": normals, **extra}


def wait_job(client, url: str, done=("succeeded", "failed", "cancelled"), timeout: float = 120.0) -> dict:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        state = client.get(url).json()
        if state["status"] in done:
            return state
        time.sleep(0.05)
    raise AssertionError(f"job {url} did not finish: {state}")


def test_point_source_over_black_floor_follows_inverse_square_cosine_law(world) -> None:
    client, sid, _ = world
    pts = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.5, -1.0, 0.0]]
    r = client.post(f"/scenes/{sid}/illuminance",
                    json=query(pts, radius=0.005, target_relative_error=0.01, max_seconds=20.0))
    assert r.status_code == 200, r.text
    a = r.json()
    assert set(a) == {"lux", "stderr", "photons", "seconds", "effects", "effect_reasons", "revision", "estimator",
                      "stop_reason",
                      "compile_seconds", "cost", "backend", "device", "radius"}
    assert a["radius"] == 0.005   # the receiver the values are means over, as asked
    assert 0.0 <= a["compile_seconds"] <= a["seconds"]
    assert a["backend"]["name"] == "in-process" and a["backend"]["threads"] >= 1
    assert a["device"] == f"cpu:{a['backend']['threads']} threads"
    for (x, y, _), e, s in zip(pts, a["lux"], a["stderr"], strict=True):
        ref = disk_average_lux(x, y, 0.005)
        assert 0 < s <= 0.011 * e or a["stop_reason"] != "target_relative_error"
        assert abs(e - ref) <= 4 * s, f"E({x},{y}) = {e} ± {s}, closed form {ref}"
    assert a["photons"] > 0 and a["seconds"] > 0 and a["estimator"] in ("forward", "backward")


def test_grid_sensor_simulation_and_map(world) -> None:
    client, sid, sensor = world
    r = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 2_000_000, "seed": 3})
    assert r.status_code == 200, r.text
    a = r.json()
    lux, se = np.array(a["lux"]), np.array(a["stderr"])
    assert lux.shape == (4, 4) == se.shape and (a["nu"], a["nv"]) == (4, 4)
    # cell averages of the closed form (midpoint rule on 40×40 sub-cells per cell)
    sub = (np.arange(40) + 0.5) / 40
    for j in range(4):
        for i in range(4):
            xs = -0.5 + (i + sub) / 4
            ys = -0.5 + (j + sub) / 4
            ref = np.mean(floor_point_lux(xs[None, :], ys[:, None]))
            assert abs(lux[j, i] - ref) <= 4 * se[j, i], (j, i, lux[j, i], se[j, i], ref)
    assert a["min_lux"] == pytest.approx(lux.min()) and a["max_lux"] == pytest.approx(lux.max())
    png = client.get(a["map_url"])
    assert png.status_code == 200 and png.headers["content-type"] == "image/png"
    image = mpimg.imread(io.BytesIO(png.content), format="png")
    assert image.ndim == 3 and image.shape[0] > 100
    assert int(png.headers["x-scene-revision"]) == a["revision"]


def test_async_job_gives_the_sync_answer_bit_for_bit(world) -> None:
    client, sid, _ = world
    body = query([[0.3, 0.2, 0.0], [-1.0, 0.5, 0.0]], radius=0.01, max_photons=20_000, seed=11)
    sync = client.post(f"/scenes/{sid}/illuminance", json=body).json()
    r = client.post(f"/scenes/{sid}/illuminance?mode=async", json=body)
    assert r.status_code == 202, r.text
    accepted = r.json()
    assert r.headers["location"] == accepted["url"] == f"/jobs/{accepted['id']}"
    state = wait_job(client, accepted["url"])
    assert state["status"] == "succeeded" and state["current"] is True
    result = state["result"]
    assert result["lux"] == sync["lux"] and result["stderr"] == sync["stderr"]
    assert result["photons"] == sync["photons"] == state["progress"]["photons"]
    assert state["progress"]["seconds_left"] == 0.0


def test_cancel_a_running_job(world) -> None:
    client, sid, sensor = world
    r = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate?mode=async",
                    json={"target_relative_error": 1e-4, "max_seconds": 25.0})
    assert r.status_code == 202, r.text
    url = r.json()["url"]
    running = wait_job(client, url, done=("running",))
    deadline = time.monotonic() + 60
    while running["progress"]["photons"] == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
        running = client.get(url).json()
    assert running["progress"]["photons"] > 0
    assert running["progress"]["worst_relative_error"] is not None
    assert running["progress"]["seconds_left"] is not None and running["progress"]["seconds_left"] > 0
    assert client.delete(url).json()["cancel_requested"] is True
    state = wait_job(client, url)
    assert state["status"] == "cancelled"
    assert state["result"]["stop_reason"] == "cancelled"
    assert state["result"]["seconds"] < 25.0


def test_push_and_assignment_invalidate_results(world) -> None:
    client, sid, sensor = world
    before = client.get(f"/scenes/{sid}").json()["revision"]
    body = query([[0.0, 0.0, 0.0]], max_photons=10_000)
    first = client.post(f"/scenes/{sid}/illuminance", json=body).json()
    assert first["revision"] == before
    job = client.post(f"/scenes/{sid}/illuminance?mode=async", json=body).json()
    assert wait_job(client, job["url"])["current"] is True
    assert client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 20_000}).status_code == 200
    assert client.get(f"/scenes/{sid}/sensors/{sensor}/map.png").status_code == 200

    # a push (the floor moves 1 cm) makes a new revision: the job is stale, the map is gone
    push_floor(client, sid, before, dx=0.01)
    stale = client.get(job["url"]).json()
    assert stale["current"] is False and stale["result"]["revision"] == before
    gone = client.get(f"/scenes/{sid}/sensors/{sensor}/map.png")
    assert gone.status_code == 404 and gone.headers["content-type"] == "application/problem+json"
    again = client.post(f"/scenes/{sid}/illuminance", json=body).json()
    assert again["revision"] == before + 1

    # an assignment keeps the revision number but changes what a query sees
    assert client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 20_000}).status_code == 200
    r = client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [5.0, 5.0, 5.0], "intensity_cd": 0.0})
    assert r.status_code == 201
    assert client.get(f"/scenes/{sid}/sensors/{sensor}/map.png").status_code == 404
    assert client.delete(f"/scenes/{sid}/lights/{r.json()['id']}").status_code == 204
    push_floor(client, sid, before + 1, dx=0.0)


NORMAL = [0.0, 0.0, 1.0]
BAD_BODIES = [
    ("shape mismatch", query([[0, 0, 0], [1, 0, 0]], [NORMAL]), 422, "same length"),
    ("zero normal", query([[0, 0, 0]], [[0.0, 0.0, 0.0]]), 422, "zero vector"),
    ("non-unit normal", query([[0, 0, 0]], [[0.0, 0.0, 2.0]]), 422, "unit vector"),
    ("no points", query([], []), 422, "at least 1"),
    ("point with two numbers", query([[0, 0]]), 422, ""),
    ("too many points", query([[0.01 * k, 0, 0] for k in range(51)]), 413, "at most 50"),
    ("photons beyond limit", query([[0, 0, 0]], max_photons=4_000_001), 422, "limit"),
    ("seconds beyond limit", query([[0, 0, 0]], max_seconds=31.0), 422, "limit"),
    ("zero target error", query([[0, 0, 0]], target_relative_error=0.0), 422, "greater than 0"),
    ("negative target error", query([[0, 0, 0]], target_relative_error=-0.1), 422, "greater than 0"),
    ("negative radius", query([[0, 0, 0]], radius=-1.0), 422, "greater than 0"),
    ("negative seed", query([[0, 0, 0]], seed=-1), 422, ""),
    ("unknown estimator", query([[0, 0, 0]], estimator="magic"), 422, ""),
    ("unknown effect", query([[0, 0, 0]], force_effects=["warp_drive"], max_photons=1000), 422, "warp_drive"),
    ("unknown field", query([[0, 0, 0]], photons=5), 422, "photons"),
]


@pytest.mark.parametrize(("case", "body", "status", "words"), BAD_BODIES, ids=[b[0] for b in BAD_BODIES])
def test_bad_illuminance_bodies_are_refused_and_change_nothing(world, case, body, status, words) -> None:
    client, sid, _ = world
    scene_before = client.get(f"/scenes/{sid}").json()
    jobs_before = client.app.state.simulation_hub.jobs.jobs()
    for mode in ("sync", "async"):
        r = client.post(f"/scenes/{sid}/illuminance?mode={mode}", json=body)
        assert r.status_code == status, r.text
        assert r.headers["content-type"] == "application/problem+json"
        assert words in r.json()["detail"]
    assert client.get(f"/scenes/{sid}").json() == scene_before
    assert client.app.state.simulation_hub.jobs.jobs() == jobs_before


def test_nan_and_infinity_are_refused(world) -> None:
    client, sid, _ = world
    for bad in ("NaN", "Infinity", "-Infinity"):
        raw = '{"points": [[' + bad + ', 0, 0]], "normals": [[0, 0, 1]]}'
        r = client.post(f"/scenes/{sid}/illuminance", content=raw, headers={"content-type": "application/json"})
        assert r.status_code == 422, r.text
        r = client.post(f"/scenes/{sid}/illuminance",
                        content=json.dumps(query([[0, 0, 0]], max_seconds=math.inf)),
                        headers={"content-type": "application/json"})
        assert r.status_code == 422, r.text


def test_unknown_scene_sensor_and_job_are_404(world) -> None:
    client, sid, sensor = world
    cases = [
        client.post(f"/scenes/{UNKNOWN_ID}/illuminance", json=query([[0, 0, 0]])),
        client.post(f"/scenes/{UNKNOWN_ID}/sensors/{UNKNOWN_ID}/simulate", json={}),
        client.post(f"/scenes/{sid}/sensors/{UNKNOWN_ID}/simulate", json={}),
        client.get(f"/scenes/{sid}/sensors/{UNKNOWN_ID}/map.png"),
        client.get(f"/scenes/{UNKNOWN_ID}/sensors/{UNKNOWN_ID}/map.png"),
        client.get("/jobs/00000000000000000000000000000000"),
        client.delete("/jobs/00000000000000000000000000000000"),
    ]
    for r in cases:
        assert r.status_code == 404, r.text
        assert r.headers["content-type"] == "application/problem+json"


def test_map_before_any_simulation_says_what_to_do(tmp_path) -> None:
    with make_client(tmp_path, **LIMITS) as client:
        sid = client.post("/scenes", json={"name": "empty"}).json()["id"]
        push_floor(client, sid, 0)
        sensor = client.post(f"/scenes/{sid}/sensors", json={"type": "grid", "origin": [0, 0, 0], "u": [1, 0, 0],
                                                             "v": [0, 1, 0], "nu": 2, "nv": 2}).json()["id"]
        r = client.get(f"/scenes/{sid}/sensors/{sensor}/map.png")
        assert r.status_code == 404 and "simulate first" in r.json()["detail"]
        disk = client.post(f"/scenes/{sid}/sensors", json={"type": "disk", "center": [0, 0, 0], "normal": [0, 0, 1],
                                                           "radius": 0.1}).json()["id"]
        r = client.get(f"/scenes/{sid}/sensors/{disk}/map.png")
        assert r.status_code == 404 and "grid" in r.json()["detail"]
        # a grid larger than max_points is refused when it is made (issue 54, item 3), nothing stored
        before = client.get(f"/scenes/{sid}/sensors").json()
        r = client.post(f"/scenes/{sid}/sensors", json={"type": "grid", "origin": [0, 0, 0], "u": [1, 0, 0],
                                                        "v": [0, 1, 0], "nu": 10, "nv": 10})
        assert r.status_code == 422 and "100 cells" in r.json()["detail"] and "at most 50" in r.json()["detail"]
        assert client.get(f"/scenes/{sid}/sensors").json() == before


def test_push_while_a_query_runs_leaves_both_intact(world) -> None:
    """The query traces a private copy of the scene: a push during it neither waits nor disturbs it."""
    client, sid, sensor = world
    rev = client.get(f"/scenes/{sid}").json()["revision"]
    objects = client.get(f"/scenes/{sid}").json()["objects"]
    r = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate?mode=async",
                    json={"target_relative_error": 1e-4, "max_seconds": 3.0})
    url = r.json()["url"]
    wait_job(client, url, done=("running",))
    push_floor(client, sid, rev, dx=0.02)  # the live scene changes under the running query
    assert client.get(url).json()["status"] == "running"
    push_floor(client, sid, rev + 1, dx=0.0)
    state = wait_job(client, url)
    # it stops on its own budget: 3 s, or the server's 4M photons when the machine traces them faster
    assert state["status"] == "succeeded" and state["result"]["stop_reason"] in ("max_seconds", "max_photons")
    assert state["result"]["revision"] == rev and state["current"] is False
    assert np.all(np.isfinite(state["result"]["lux"]))
    # the service's scene never held the query's receivers, and the next query sees the new revision
    assert client.get(f"/scenes/{sid}").json()["objects"] == objects
    again = client.post(f"/scenes/{sid}/illuminance", json=query([[0.0, 0.0, 0.0]], max_photons=10_000))
    assert again.status_code == 200 and again.json()["revision"] == rev + 2


def test_every_answer_says_what_tighter_errors_would_cost_and_a_plan_says_it_first(world) -> None:
    """Issue 24, in part: `cost` in every answer (the default targets, or the query's own), and
    `POST …/illuminance/plan`, a pilot of at most 2 s that answers the same before the full run."""
    client, sid, sensor = world
    pts = [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]]
    a = client.post(f"/scenes/{sid}/illuminance", json=query(pts, max_photons=100_000)).json()
    cost = a["cost"]
    assert cost["targets"] == [0.05, 0.02, 0.01, 0.005, 0.002] and cost["dark_points"] == 0
    worst = cost["worst"]
    r = max(s / v for s, v in zip(a["stderr"], a["lux"], strict=True))
    assert worst["relative_error"] == pytest.approx(r)
    assert worst["photons"][2] == pytest.approx(a["photons"] * (r / 0.01) ** 2, rel=1e-6, abs=1)
    assert all(x < y for x, y in zip(worst["seconds"], worst["seconds"][1:], strict=False))   # tighter costs more
    own = client.post(f"/scenes/{sid}/illuminance", json=query(pts, max_photons=100_000, cost_targets=[0.03])).json()
    assert own["cost"]["targets"] == [0.03] and len(own["cost"]["median"]["seconds"]) == 1
    plan = client.post(f"/scenes/{sid}/illuminance/plan", json=query(pts, target_relative_error=0.001))
    assert plan.status_code == 200, plan.text
    p = plan.json()
    assert p["seconds"] <= 2.0 + 1.0 and p["stop_reason"] != "target_relative_error" and p["cost"]["worst"]
    grid = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 100_000}).json()
    assert grid["cost"]["worst"]["relative_error"] > 0
    for bad in ([], [0.0], [1.0], [0.1] * 11, ["0.1"]):
        r = client.post(f"/scenes/{sid}/illuminance", json=query(pts, max_photons=1000, cost_targets=bad))
        assert r.status_code == 422 and "cost_targets" in r.text, r.text
