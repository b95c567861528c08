"""The sensor family's contract (tracer/sensors/base.py), run over every registered kind (`KINDS`).

Each kind: declares its TYPE, FORWARD_ONLY and OBSERVES; `Simulation.run` answers it with the run's photons,
seconds, effects, estimator, stop reason and backend; its bins equal those of the named query on the same seed (the
named queries are thin calls of `run`); a forward-only kind runs "auto" forward and refuses "backward"; a kind that
does not observe refuses `observe`; a bad body is refused before anything runs, naming the field. And the physics
that ties the kinds together: on a closed-form scene (a point source over a black floor, E = I cos θ / r²) a disk, a
one-point `points` query and a one-cell grid over the same patch measure the same illuminance within 4 combined
standard errors.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.tracer.transport_scenes import box, quad, scene_of
from tracer.sensors import dispatch
from tracer.simulate import Simulation, SimulationError

Z = 4.0
LIGHT = {"type": "point", "position": [0.2, -0.1, 2.0], "intensity_cd": 1000.0}
BODIES = {   # one body of each kind over the room below; a kind registered without one here fails the contract
    "points": {"type": "points", "points": [[0.0, 0.0, 0.0], [1.0, 0.3, 0.0]], "normals": [[0, 0, 1], [0, 0, 1]],
               "radius": 0.3},
    "disk": {"type": "disk", "center": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "radius": 0.3},
    "grid": {"type": "grid", "origin": [-1.5, -1.5, 0.0], "u": [3.0, 0, 0], "v": [0, 3.0, 0], "nu": 3, "nv": 2},
    "surface": {"type": "surface", "instances": [0]},
    "far_field": {"type": "far_field", "nc": 4, "ngamma": 5},
    "luminance": {"type": "luminance", "position": [0.5, 0.0, 1.0], "direction": [0, 0, -1], "aperture_deg": 2.0},
    "camera": {"type": "camera", "position": [0.0, -1.5, 2.0], "look_at": [0, 0, 0], "fov_deg": 50, "width": 4,
               "height": 3},
}


@pytest.fixture(scope="module")
def room():
    s, ids = scene_of(box([-2, -2, 0], [2, 2, 2.5]))
    return Simulation(s, {ids[0]: {"type": "lambertian", "reflectance": 0.5}}, [LIGHT])


def test_every_kind_has_a_body_here():
    assert set(dispatch.KINDS) == set(BODIES)


@pytest.mark.parametrize("kind", sorted(dispatch.KINDS))
def test_contract(room, kind):
    module = dispatch.KINDS[kind]
    assert module.TYPE == kind and isinstance(module.FORWARD_ONLY, bool) and isinstance(module.OBSERVES, bool)
    res = room.run(BODIES[kind], max_photons=8000, seed=3)
    assert res.photons > 0 and res.seconds > 0 and res.batches >= 2
    assert res.stop_reason == "max_photons" and "lambertian" in res.effects
    assert res.backend["name"] == "in-process"
    assert res.estimator == ("forward" if module.FORWARD_ONLY or kind == "grid" else "backward")
    if module.FORWARD_ONLY:
        with pytest.raises(SimulationError, match="forward only"):
            room.run(BODIES[kind], max_photons=8000, estimator="backward")
    if not module.OBSERVES:
        with pytest.raises(SimulationError, match="takes no observe"):
            room.run(BODIES[kind], max_photons=8000, observe=["spectrum"])


def test_named_queries_are_thin_calls_of_run(room):
    """Same seed, same budget: the named query and `run` give the very same bins."""
    q = dict(max_photons=8000, seed=5)
    b = BODIES["points"]
    assert np.array_equal(room.illuminance(b["points"], b["normals"], radius=0.3, **q).lux, room.run(b, **q).lux)
    b = BODIES["grid"]
    assert np.array_equal(room.grid(b["origin"], b["u"], b["v"], 3, 2, **q).lux, room.run(b, **q).lux)
    assert np.array_equal(room.far_field(4, 5, **q).candela, room.run(BODIES["far_field"], **q).candela)
    surf = room.surface([0], **q)
    assert all(np.array_equal(a, b) for a, b in zip(surf.lux, room.run(BODIES["surface"], **q).lux, strict=True))


@pytest.mark.parametrize("body, field", [
    ({"type": "nope"}, "sensor type 'nope' is unknown"),
    ([1, 2], "a sensor is a dict"),
    ({"type": "disk", "center": [0, 0, 0], "normal": [0, 0, 0], "radius": 0.1}, "normal 0 is the zero vector"),
    ({"type": "disk", "center": [0, 0, 0], "normal": [0, 0, 1], "radius": -1}, "radius must be a positive"),
    ({"type": "grid", "origin": [0, 0, 0], "u": [1, 0, 0], "v": [2, 0, 0], "nu": 2, "nv": 2}, "not parallel"),
    ({"type": "grid", "origin": [0, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0], "nu": 0, "nv": 2}, "nu must be"),
    ({"type": "surface", "instances": [7]}, "7 is not an instance"),
    ({"type": "far_field", "nc": 4, "ngamma": 1}, "ngamma must be"),
])
def test_bad_bodies_are_refused_naming_the_field(room, body, field):
    with pytest.raises(SimulationError, match=field):
        room.run(body, max_photons=1000)


def test_kinds_agree_on_a_closed_form_patch():
    """A point source 1.5 m over a black floor: a disk, a one-point query and a one-cell grid (a square of the
    disk's area, centred alike, so the averages differ by ≪ σ at r = 0.1 m) measure the same illuminance, and it is
    E = I cos θ / r² at the centre within 4 σ (the patch average differs from it by < 0.3 %)."""
    s, ids = scene_of(quad([-5, -5, 0], [10, 0, 0], [0, 10, 0]))
    light = {"type": "point", "position": [0.0, 0.0, 1.5], "intensity_cd": 500.0}
    sim = Simulation(s, {ids[0]: {"type": "black"}}, [light])
    r = 0.1
    side = r * np.sqrt(np.pi)
    q = dict(max_photons=400_000, seed=11, estimator="forward")
    answers = [sim.run({"type": "disk", "center": [0, 0, 0], "normal": [0, 0, 1], "radius": r}, **q),
               sim.run({"type": "points", "points": [[0, 0, 0]], "normals": [[0, 0, 1]], "radius": r},
                       **{**q, "seed": 12}),
               sim.run({"type": "grid", "origin": [-side / 2, -side / 2, 0], "u": [side, 0, 0], "v": [0, side, 0],
                        "nu": 1, "nv": 1}, **{**q, "seed": 13})]
    lux = np.array([float(np.ravel(a.lux)[0]) for a in answers])
    err = np.array([float(np.ravel(a.stderr)[0]) for a in answers])
    exact = 500.0 / 1.5 ** 2
    assert np.all(np.abs(lux - exact) <= Z * err + 0.003 * exact), (lux, err, exact)
    for i in range(3):
        for j in range(i):
            assert abs(lux[i] - lux[j]) <= Z * np.hypot(err[i], err[j]) + 0.003 * exact, (lux, err)
