"""Polarization chosen by physics, not tags (issue 38; `tracer.effects.explain_effects`): a scene whose paths can
meet two polarizing interactions carries Stokes vectors by default, the answer says why each effect is on or off,
and a query may force polarization off.

Closed forms (docs/REFERENCES.md, "Fresnel and polarization"; n = 1.5, Brewster's angle atan 1.5, Rs = 0.147929,
Rp = 0):
- The thick lossless plate under an unpolarized beam reflects Rs / (1 + Rs) = 0.128867 (s and p kept apart; p
  passes both faces), and 2R / (1 + R) = 0.137740 with R = Rs / 2 when s and p are averaged at each interface.
- The Brewster periscope: the plate's reflection is pure s; a second plate whose plane of incidence holds that field
  (turned 90° about the beam) sees it as p at Brewster's angle and reflects nothing: 0. Averaged: 0.137740² of the
  beam.
Tolerances: 4 × the run's own standard error. A point that no photon reaches is 0 ± 0 (`tracer.simulate`), so the
periscope's 0 is exact.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.effects import POLARIZATION_FLOOR, explain_effects, polarization_call, surface_shape
from tracer.optics.surfaces.dispatch import material_spec
from tracer.optics.surfaces.mirror import metal_diattenuation
from tracer.scene import Scene
from tracer.simulate import Simulation, SimulationError
from tracer.warmup import box

N = 1.5
THETA = math.atan(N)
RS = 0.147929
POLARIZED = RS / (1 + RS)                 # 0.128867
AVERAGED = 2 * (RS / 2) / (1 + RS / 2)    # 0.137740
GLASS = {"type": "dielectric", "ior": N}
BEAM, RECEIVER = 0.005, 0.3
TO_FRACTION = RECEIVER ** 2 / (100.0 * BEAM ** 2)   # lux at a receiver across the beam -> fraction of the beam


def _frame(n: np.ndarray) -> np.ndarray:
    """A 4x4 rotation taking local z to the unit vector n."""
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(a, n)
    u /= np.linalg.norm(u)
    t = np.eye(4)
    t[:3, :3] = np.column_stack([u, np.cross(n, u), n])
    return t


def brewster(periscope: bool):
    """The plate z in [-0.01, 0] under a 100 lx beam (radius 5 mm) at Brewster's angle; with `periscope`, a second
    1 cm plate 1 m up the reflected beam, its normal turned so that the first reflection's s field lies in its
    plane of incidence, at Brewster's angle again. Returns the simulation, the receiver point and normal (across the
    last reflection, 1 m on)."""
    s = Scene()
    plate = s.add_instance(s.add_geometry(*box([-5, -5, -0.01], [5, 5, 0])), np.eye(4))
    d = np.array([math.sin(THETA), 0.0, -math.cos(THETA)])
    r = d * np.array([1.0, 1.0, -1.0])               # reflected: s is y, across the plane xz
    mats = {plate: GLASS}
    end, out = r, r
    if periscope:
        n2 = -math.cos(THETA) * r + math.sin(THETA) * np.array([0.0, 1.0, 0.0])   # holds y: s becomes p
        t = _frame(n2)
        t[:3, 3] = r                                  # the second plate's front face at 1 m up the beam
        second = s.add_instance(s.add_geometry(*box([-0.25, -0.25, -0.01], [0.25, 0.25, 0])), t)
        mats[second] = GLASS
        out = r - 2 * float(r @ n2) * n2
        end = r + out
    s.commit()
    light = {"type": "collimated", "origin": list(-d), "direction": list(d), "radius": BEAM, "illuminance_lx": 100.0}
    return Simulation(s, mats, [light]), [list(end)], [list(-out)]


def test_the_thick_plate_at_brewster_is_polarized_by_default():
    sim, pts, nrm = brewster(False)
    assert sim.effects == ["lambertian", "fresnel", "polarization"]
    assert sim.effect_reasons["polarization"].startswith("on: a path can meet a 'dielectric' then a 'dielectric'")
    res = sim.illuminance(pts, nrm, radius=RECEIVER, max_photons=150_000, seed=3)
    assert res.effects == sim.effects and res.effect_reasons == sim.effect_reasons
    f, e = res.lux[0] * TO_FRACTION, res.stderr[0] * TO_FRACTION
    assert abs(f - POLARIZED) <= 4 * e, (f, e, POLARIZED)
    assert abs(f - AVERAGED) > 4 * e          # the old default is resolved away
    off = sim.illuminance(pts, nrm, radius=RECEIVER, max_photons=150_000, seed=3, force_effects_off=["polarization"])
    assert off.effects == ["lambertian", "fresnel"]
    assert off.effect_reasons["polarization"].startswith("off: forced off by the query")
    f, e = off.lux[0] * TO_FRACTION, off.stderr[0] * TO_FRACTION
    assert abs(f - AVERAGED) <= 4 * e, (f, e, AVERAGED)


def test_the_brewster_periscope_is_dark_by_default_and_not_when_forced_off():
    sim, pts, nrm = brewster(True)
    assert "polarization" in sim.effects
    res = sim.illuminance(pts, nrm, radius=RECEIVER, max_photons=150_000, seed=4)
    assert abs(res.lux[0]) <= 4 * res.stderr[0], (res.lux, res.stderr)
    off = sim.illuminance(pts, nrm, radius=RECEIVER, max_photons=150_000, seed=4, force_effects_off=["polarization"])
    f, e = off.lux[0] * TO_FRACTION, off.stderr[0] * TO_FRACTION
    assert abs(f - AVERAGED ** 2) <= 4 * e and f > 10 * e, (f, e, AVERAGED ** 2)
    assert res.lux[0] * TO_FRACTION < 0.05 * AVERAGED ** 2


def test_a_diffuse_room_takes_nothing_new_and_says_why():
    s = Scene()
    room = s.add_instance(s.add_geometry(*box([-3, -3, -0.1], [3, 3, 0.0])), np.eye(4))
    top = s.add_instance(s.add_geometry(*box([-3, -3, 2.0], [3, 3, 2.1])), np.eye(4))
    s.commit()
    lam = {"type": "lambertian", "reflectance": 0.5}
    sim = Simulation(s, {room: lam, top: lam}, [{"type": "point", "position": [0, 0, 1.5], "intensity_cd": 100.0}])
    assert sim.effects == ["lambertian"]
    assert sim.effect_reasons["polarization"].startswith("off: no material polarizes")
    assert sim.effect_reasons["fresnel"] == "off: no material of the scene calls for it"
    res = sim.illuminance([[0, 0, 0]], [[0, 0, 1]], max_photons=2000)
    assert res.estimator == "backward" and res.effects == ["lambertian"]
    assert set(res.effect_reasons) == set(sim.effect_reasons)


AL = {"type": "mirror", "metal": [0.96, 6.69]}


def test_metal_mirrors_count_their_diattenuation():
    # aluminium at 550 nm: max (Rs - Rp) / (Rs + Rp) = 0.1391 at 81.7 degrees (numpy over 9000 angles)
    assert metal_diattenuation(0.96, 6.69) == pytest.approx(0.13912, abs=2e-4)
    one, why = polarization_call([material_spec(AL)])
    assert not one and "at most one polarizing interaction" in why
    two, why = polarization_call([material_spec(AL)] * 2)
    assert two and "1.94 %" in why
    assert explain_effects([AL], counts={material_spec(AL): 2})[0] == ["lambertian", "specular", "polarization"]
    dim = {"type": "mirror", "metal": [0.1, 8.0]}      # nearly perfect: diattenuation 0.0123, bound 0.015 %
    assert metal_diattenuation(0.1, 8.0) ** 2 < POLARIZATION_FLOOR
    assert "polarization" not in explain_effects([dim, dim])[0]
    perfect = {"type": "mirror", "reflectance": 0.9}
    assert "polarization" not in explain_effects([perfect] * 5)[0]
    assert "polarization" in explain_effects([perfect, GLASS])[0]


def test_required_polarization_cannot_be_forced_off_and_bad_fields_name_themselves():
    sim, pts, nrm = brewster(False)
    for bad, match in ((["fresnel"], "cannot be forced off"), (["warp"], "known"), ("polarization", "must be a list"),
                       (["polarization", "polarization"], "once")):
        with pytest.raises(SimulationError, match="force_effects_off|unknown effect") as info:
            sim.illuminance(pts, nrm, max_photons=1000, force_effects_off=bad)
        assert match in str(info.value)
    with pytest.raises(SimulationError, match="force_effects_off.*also forced on"):
        sim.illuminance(pts, nrm, max_photons=1000, observe=["stokes"], force_effects_off=["polarization"])
    e, why = explain_effects([{"type": "polarizer", "axis": [1, 0, 0]}])
    assert "polarization" in e and why["polarization"].startswith("on: required by a 'polarizer' material")
    e, why = explain_effects([{"type": "lambertian", "reflectance": 0.5}],
                             [{"type": "point", "position": [0, 0, 1], "intensity_cd": 1.0,
                               "polarization": {"type": "circular", "handedness": "right"}}])
    assert why["polarization"].startswith("on: required by polarized light(s) [0]")


# ------------------------------------------------------------------ geometry: one reflector met twice

BREWSTER_METAL = {"type": "mirror", "metal": [N, 0.0]}   # reflects as glass does, transmits nothing: Rp = 0 at atan n


def test_a_surface_is_met_once_only_where_it_is_a_plane_or_one_convex_solid():
    ring = np.linspace(0.0, 2.0 * math.pi, 33)[:-1]
    dish_v = np.array([[0.0, 0.0, 0.0]] + [[math.cos(a), math.sin(a), 0.5] for a in ring])   # a cone: concave inside
    dish_t = np.array([[0, 1 + k, 1 + (k + 1) % 32] for k in range(32)])
    cone_v = np.vstack([dish_v, [[0.0, 0.0, 0.5]]])                                          # closed with a lid
    cone_t = np.vstack([dish_t, [[33, 1 + (k + 1) % 32, 1 + k] for k in range(32)]])
    v, t = box([0, 0, 0], [1, 1, 0.01])
    v2, t2 = box([0, 0, 0.5], [1, 0.1, 1])
    assert surface_shape(v, t) == "convex"                                      # a thin plate
    assert surface_shape(v[:4] * [1, 1, 0], [[0, 1, 2], [0, 2, 3]]) == "planar"
    assert surface_shape(cone_v, cone_t) == surface_shape(cone_v, cone_t[:, ::-1]) == "convex"   # either winding
    split = cone_v[cone_t].reshape(-1, 3)                                       # each triangle its own corners
    assert surface_shape(split, np.arange(len(split)).reshape(-1, 3)) == "convex"
    assert surface_shape(dish_v, dish_t) == "other"                             # an open dish
    assert surface_shape(np.vstack([v, v2]), np.vstack([t, t2 + len(v)])) == "other"   # two bodies in one mesh
    dented = cone_v.copy()
    dented[33, 2] = 0.2                                                         # the lid pushed in
    assert surface_shape(dented, cone_t) == "other"


def metal_periscope():
    """The Brewster periscope of `brewster(True)` made of one mesh (both plates, a metal of index 1.5 − 0i, which
    reflects as the glass does and absorbs what glass would pass): one instance, one material, so the materials
    alone allow one interaction; the geometry, two plates that light one another, allows two."""
    s = Scene()
    v1, t1 = box([-5, -5, -0.01], [5, 5, 0])
    d = np.array([math.sin(THETA), 0.0, -math.cos(THETA)])
    r = d * np.array([1.0, 1.0, -1.0])
    n2 = -math.cos(THETA) * r + math.sin(THETA) * np.array([0.0, 1.0, 0.0])
    f = _frame(n2)
    f[:3, 3] = r
    v2, t2 = box([-0.25, -0.25, -0.01], [0.25, 0.25, 0])
    v2 = v2 @ f[:3, :3].T + f[:3, 3]
    both = s.add_instance(s.add_geometry(np.vstack([v1, v2]), np.vstack([t1, t2 + len(v1)])), np.eye(4))
    s.commit()
    out = r - 2 * float(r @ n2) * n2
    light = {"type": "collimated", "origin": list(-d), "direction": list(d), "radius": BEAM, "illuminance_lx": 100.0}
    return Simulation(s, {both: BREWSTER_METAL}, [light]), [list(r + out)], [list(-out)]


def test_one_metal_mesh_that_lights_itself_is_polarized_by_default():
    sim, pts, nrm = metal_periscope()
    assert "polarization" in sim.effects, sim.effect_reasons
    assert "'mirror' surface can be met twice" in sim.effect_reasons["polarization"]
    res = sim.illuminance(pts, nrm, radius=RECEIVER, max_photons=150_000, seed=5)
    assert abs(res.lux[0]) <= 4 * res.stderr[0], (res.lux, res.stderr)
    off = sim.illuminance(pts, nrm, radius=RECEIVER, max_photons=150_000, seed=5, force_effects_off=["polarization"])
    f, e = off.lux[0] * TO_FRACTION, off.stderr[0] * TO_FRACTION
    assert abs(f - (RS / 2) ** 2) <= 4 * e and f > 10 * e, (f, e, (RS / 2) ** 2)


def test_a_convex_metal_body_counts_once_lit_from_outside_and_twice_lit_from_within():
    s = Scene()
    plate = s.add_instance(s.add_geometry(*box([-5, -5, -0.01], [5, 5, 2])), np.eye(4))
    s.commit()
    outside = Simulation(s, {plate: BREWSTER_METAL}, [{"type": "point", "position": [0, 0, 3], "intensity_cd": 1.0}])
    assert "polarization" not in outside.effects
    assert "at most one polarizing interaction" in outside.effect_reasons["polarization"]
    inside = Simulation(s, {plate: BREWSTER_METAL}, [{"type": "point", "position": [0, 0, 1], "intensity_cd": 1.0}])
    assert "polarization" in inside.effects, inside.effect_reasons
