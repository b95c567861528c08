"""Physics left out, where asked (issue 24; `Simulation.left_out`): the lux an effect that is off would change,
measured by a pilot with it forced on, against closed forms.

- A lossless glass plate (n = 1.5, 1 cm) at Brewster's angle under unpolarized light. The scene calls for
  polarization (two Fresnel interfaces in a row, `tracer.effects`); the query forces it off (`force_effects_off`),
  so the run averages s and p at each interface: 2R / (1 + R) = 0.137740 of the beam reflects
  (R = Rs / 2). Polarized Fresnel gives Rs / (1 + Rs) = 0.128867 (tests/tracer/optics/test_polarization.py). The
  reported difference must be their difference within 4 combined standard errors, and far from 0.
- A Lambertian room: polarization changes nothing there, so the difference is 0 within 4σ (the pilot runs forward,
  the run backward: two independent estimators of the same value).

Tolerances: 4 × the reported standard error of the difference, √(σ_run² + σ_pilot²) (independent seeds).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.effects import EFFECTS
from tracer.scene import Scene
from tracer.simulate import Simulation, SimulationError
from tracer.warmup import box

N = 1.5
BREWSTER = math.degrees(math.atan(N))
RS = 0.147929                      # s reflectance at Brewster's angle, n = 1.5
POLARIZED = RS / (1 + RS)          # 0.128867: what the thick plate reflects, polarized Fresnel
AVERAGED = 2 * (RS / 2) / (1 + RS / 2)   # 0.137740: s and p averaged at each interface


def plate(beam=0.005):
    """The plate z ∈ [−0.01, 0] under a beam of 100 lx at Brewster's angle; the receiver point and normal across
    the specular reflection, 1 m away."""
    s = Scene()
    glass = s.add_instance(s.add_geometry(*box([-5, -5, -0.01], [5, 5, 0])), np.eye(4))
    s.commit()
    t = math.radians(BREWSTER)
    d = np.array([math.sin(t), 0.0, -math.cos(t)])
    light = {"type": "collimated", "origin": list(-d), "direction": list(d), "radius": beam, "illuminance_lx": 100.0}
    sim = Simulation(s, {glass: {"type": "dielectric", "ior": N}}, [light])
    r = d * np.array([1, 1, -1])
    return sim, [list(r)], [list(-r)]


def test_polarization_left_out_of_a_thick_plate_at_brewster_is_the_closed_form_difference():
    beam, a = 0.005, 0.3
    sim, pts, nrm = plate(beam)
    assert "polarization" in sim.effects
    off = {"force_effects_off": ["polarization"]}
    res = sim.illuminance(pts, nrm, radius=a, max_photons=400_000, seed=7, physics_left_out=["polarization"], **off)
    assert "polarization" not in res.effects and res.effect_reasons["polarization"].startswith("off: forced off")
    to_fraction = a ** 2 / (100.0 * beam ** 2)          # lux at the receiver → fraction of the beam reflected
    assert abs(res.lux[0] * to_fraction - AVERAGED) <= 4 * res.stderr[0] * to_fraction
    e = res.physics_left_out["polarization"]
    assert e["ran"] and e["estimator"] == "forward" and e["photons"] == res.photons and e["seconds"] > 0
    diff, err = e["difference"][0] * to_fraction, e["stderr"][0] * to_fraction
    assert e["stderr"][0] > res.stderr[0]           # √(σ_run² + σ_pilot²)
    assert abs(diff - (POLARIZED - AVERAGED)) <= 4 * err, (diff, err, POLARIZED - AVERAGED)
    assert abs(diff) > 4 * err          # the effect is resolved: 7 % of the value, ~10 σ here
    # bit-identical again (the pilot's seed is derived from the query's), and independent of the run's
    again = sim.illuminance(pts, nrm, radius=a, max_photons=400_000, seed=7, physics_left_out=["polarization"],
                            **off)
    assert np.array_equal(again.physics_left_out["polarization"]["difference"], e["difference"])
    forced = sim.illuminance(pts, nrm, radius=a, max_photons=400_000, seed=7)   # on by default
    assert not np.array_equal(forced.lux, res.lux + e["difference"])


def lambertian_room():
    """Floor z = 0 and ceiling z = 2 (ρ = 0.5, 6 m × 6 m), a 100 cd point source at 1.5 m."""
    s = Scene()
    room = s.add_instance(s.add_geometry(*box([-3, -3, -0.1], [3, 3, 0.0])), np.eye(4))
    top = s.add_instance(s.add_geometry(*box([-3, -3, 2.0], [3, 3, 2.1])), np.eye(4))
    s.commit()
    lam = {"type": "lambertian", "reflectance": 0.5}
    return Simulation(s, {room: lam, top: lam}, [{"type": "point", "position": [0, 0, 1.5], "intensity_cd": 100.0}])


def test_polarization_left_out_of_a_lambertian_room_is_zero_within_its_error():
    sim = lambertian_room()
    pts, nrm = [[0, 0, 0], [1.0, 0.5, 0], [-2, 1, 0]], [[0, 0, 1]] * 3
    res = sim.illuminance(pts, nrm, radius=0.1, target_relative_error=0.01, max_seconds=60, seed=3,
                          physics_left_out=["polarization", "fresnel", "lambertian"])
    assert res.estimator == "backward"
    e = res.physics_left_out["polarization"]
    assert e["ran"] and e["estimator"] == "forward"
    assert np.all(np.abs(e["difference"]) <= 4 * e["stderr"]), (e["difference"], e["stderr"])
    assert np.all(e["stderr"] < 0.02 * res.lux)       # a 1 % target for both: about √2 % each
    for name in ("fresnel", "lambertian"):   # the same photon state: nothing that runs changes, and nothing ran
        z = res.physics_left_out[name]
        assert not z["ran"] and z["photons"] == 0 and np.all(z["difference"] == 0) and np.all(z["stderr"] == 0)


def test_an_effect_already_on_is_not_left_out_and_a_grid_gets_cells():
    sim, pts, nrm = plate()
    res = sim.illuminance(pts, nrm, max_photons=20_000, observe=["stokes"], physics_left_out=["polarization"])
    assert not res.physics_left_out["polarization"]["ran"]
    g = sim.grid([-0.5, -0.5, 0.5], [1, 0, 0], [0, 1, 0], 3, 2, max_photons=20_000, physics_left_out=["spectral"])
    e = g.physics_left_out["spectral"]
    assert e["ran"] and e["difference"].shape == (2, 3) == e["stderr"].shape
    assert res.physics_left_out is not None and sim.illuminance(pts, nrm, max_photons=2000).physics_left_out is None


@pytest.mark.parametrize(("bad", "match"), [(["warp_drive"], "known: "), ("polarization", "must be a list"),
                                            (["spectral", "spectral"], "once"), ([3], "unknown")])
def test_bad_physics_left_out_is_refused_before_any_work(bad, match):
    sim, pts, nrm = plate()
    with pytest.raises(SimulationError, match=match) as info:
        sim.illuminance(pts, nrm, max_photons=1000, physics_left_out=bad)
    if match == "known: ":
        assert all(name in str(info.value) for name in EFFECTS)
    with pytest.raises(SimulationError, match=match):
        sim.grid([0, 0, 1], [1, 0, 0], [0, 1, 0], 2, 2, max_photons=1000, physics_left_out=bad)
