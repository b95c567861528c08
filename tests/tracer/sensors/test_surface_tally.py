"""The surface tally (`Simulation.surface`, `tracer.transport.forward.SensorArrays.surf`): illuminance per triangle of
the model itself, against closed forms, and proof that it observes and changes nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.tracer.transport_scenes import box, quad, scene_of
from tracer.optics.surfaces.dispatch import bind
from tracer.scene import Scene
from tracer.simulate import Simulation, SimulationError
from tracer.transport.forward import SensorArrays, forward_batches

I_CD = 100.0
H = 2.0
FLOOR = {"type": "lambertian", "reflectance": 0.5}
BLACK = {"type": "lambertian", "reflectance": 0.0}
LAMP = {"type": "point", "position": [0.0, 0.0, H], "intensity_cd": I_CD}


def tiled_floor(half: float, n: int):
    """An n × n grid of squares over [-half, half]² at z = 0, two triangles each, front side +z."""
    xs = np.linspace(-half, half, n + 1)
    v = np.array([[x, y, 0.0] for y in xs for x in xs])
    t = []
    for j in range(n):
        for i in range(n):
            a, b, c, d = j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i
            t += [[a, b, c], [a, c, d]]
    return v, np.array(t)


def triangle_mean(fn, a, b, c, n=24) -> float:
    """Mean of fn over triangle abc: the centroids of its n² congruent sub-triangles (midpoint rule)."""
    pts = []
    for i in range(n):
        for j in range(n - i):
            pts.append(((i + 1 / 3) / n, (j + 1 / 3) / n))        # upward sub-triangles
            if i + j < n - 1:
                pts.append(((i + 2 / 3) / n, (j + 2 / 3) / n))    # downward ones
    s = np.array(pts)
    p = a + s[:, :1] * (b - a) + s[:, 1:] * (c - a)
    return float(fn(p).mean())


def point_on_floor(p):
    d2 = p[:, 0] ** 2 + p[:, 1] ** 2
    return I_CD * H / (H * H + d2) ** 1.5


def test_floor_triangles_match_the_closed_form():
    v, t = tiled_floor(4.0, 20)   # 800 triangles of 0.08 m²
    s, (floor,) = scene_of((v, t))
    res = Simulation(s, {floor: FLOOR}, [LAMP]).surface([floor], max_photons=4_000_000, seed=7)
    assert res.instances == [floor] and res.estimator == "forward" and res.stop_reason == "max_photons"
    lux, err, area = res.lux[0], res.stderr[0], res.area[0]
    assert lux.shape == err.shape == area.shape == (800,)
    np.testing.assert_allclose(area, 0.08, rtol=1e-6)   # float32 vertices
    ref = np.array([triangle_mean(point_on_floor, *v[tri]) for tri in t])
    z = (lux - ref) / err
    assert np.all(err > 0)
    assert np.max(np.abs(z)) < 4.0, (np.argmax(np.abs(z)), lux[np.argmax(np.abs(z))], ref[np.argmax(np.abs(z))])
    outside = int(np.sum(np.abs(z) > 3.0))
    assert outside <= 10, outside           # ~0.27 % of 800 = 2.2 expected; 10 is 5 binomial sigma above
    assert 0.7 < float(np.sqrt(np.mean(z * z))) < 1.3   # the reported errors are the real ones


def test_closed_box_receives_the_source_flux():
    v, t = box((-1.0, -1.5, -0.5), (1.0, 1.5, 2.5))
    t = t[:, [0, 2, 1]]                       # inward: the front side faces the source
    s, (room,) = scene_of((v, t))
    lamp = {**LAMP, "position": [0.1, 0.2, 0.3]}
    res = Simulation(s, {room: BLACK}, [lamp]).surface([room], max_photons=200_000, seed=3)
    flux = float(np.sum(res.lux[0] * res.area[0]))
    sigma = float(np.sqrt(np.sum((res.stderr[0] * res.area[0]) ** 2)))
    assert abs(flux - 4 * math.pi * I_CD) <= 4 * sigma
    # black walls: every photon arrives exactly once, so the total per batch is exact
    assert flux == pytest.approx(4 * math.pi * I_CD, rel=1e-9)
    # seen from behind (outward normals) nothing arrives on a front side
    s2, (room2,) = scene_of(box((-1.0, -1.5, -0.5), (1.0, 1.5, 2.5)))
    back = Simulation(s2, {room2: BLACK}, [lamp]).surface([room2], max_photons=20_000, seed=3)
    assert np.all(back.lux[0] == 0.0)


def test_surface_tally_changes_nothing():
    """Same batches with and without the surface tally: every receiver bin and counter bit-identical."""
    fv, ft = quad((-3.0, -3.0, 0.0), (6.0, 0.0, 0.0), (0.0, 6.0, 0.0))
    s, (floor, block) = scene_of((fv, ft), box((0.3, -0.4, 0.0), (1.0, 0.4, 0.8)))
    sim = Simulation(s, {floor: FLOOR, block: {"type": "lambertian", "reflectance": 0.7}}, [LAMP])
    receivers = Scene()
    rid = receivers.add_rect_sensor((-2.0, -2.0, 0.01), (4.0, 0.0, 0.0), (0.0, 4.0, 0.0))
    receivers.commit()
    n = rid + 1
    bin0, nu, nv = np.full(n, -1, np.int64), np.ones(n, np.int64), np.ones(n, np.int64)
    bin0[rid], nu[rid], nv[rid] = 0, 8, 8
    plain = SensorArrays(bin0, nu, nv, np.zeros(2, np.int64), np.zeros((n, 3)))
    surf = np.full(max(floor, block) + 1, -1, np.int64)
    surf[floor], surf[block] = 64, 64 + len(ft)
    tallied = plain._replace(surf=surf)
    args = (s.arrays(), receivers.arrays(), bind(s.arrays(), sim._mats), sim._lights)
    out0, c0 = forward_batches(*args, plain, 64, 11, 0, 3, 20_000)
    out1, c1 = forward_batches(*args, tallied, 64 + len(ft) + 12, 11, 0, 3, 20_000)
    assert np.array_equal(out0, out1[:, :64]) and np.array_equal(c0, c1)
    assert out0.sum() > 0 and np.all(out1[:, 64:].sum(axis=1) > 0)


def test_surface_of_a_transformed_instance_and_bad_input():
    v, t = quad((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    s = Scene()
    g = s.add_geometry(v, t)
    m = np.diag([2.0, 3.0, 1.0, 1.0])
    m[:3, 3] = (-1.0, -1.5, 0.0)
    i = s.add_instance(g, m)
    s.commit()
    sim = Simulation(s, {i: BLACK}, [LAMP])
    res = sim.surface([i], max_photons=100_000, seed=1)
    np.testing.assert_allclose(res.area[0], [3.0, 3.0])   # world areas: the instance's transform applied
    exact = triangle_mean(point_on_floor, *np.array([[-1, -1.5, 0], [1, -1.5, 0], [1, 1.5, 0.0]]))
    assert abs(res.lux[0][0] - exact) < 4 * res.stderr[0][0]
    for bad, what in (([], "at least one"), ([i, i], "twice"), ([i + 5], "not an instance"), ("x", "list"),
                      ([1.5], "ints")):
        with pytest.raises(SimulationError, match=what):
            sim.surface(bad, max_photons=1000)
