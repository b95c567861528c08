"""The `diffuser` element (a thin Lambertian sheet): the closed forms it must reproduce.

A sheet of diffuse transmittance T and reflectance R, lit by a point source of intensity I at height h
above its centre, receives Φ = I Ω with Ω = 4 asin(a² / (a² + h²)) (a square of half-side a); it must
send T Φ downward and R Φ back up, whatever the angles (energy: T + R + A = 1). Lit by a thin oblique
beam of flux Φ, its transmitted radiance is Lambertian: a receiver at distance d facing the spot under
angle θ from the normal gets E = T Φ cosθ / (π d²), the same law at θ = −60° and at +60° (where a sheet
that let the beam through unchanged would put it all). Tolerances: four standard errors of the
estimate plus the receivers' finite size (≤ 0.1 %).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.optics.surfaces.base import MaterialError
from tracer.optics.surfaces.dispatch import material_spec
from tracer.scene import Scene
from tracer.simulate import Simulation


def _sheet(a: float):
    s = Scene()
    v = np.array([[-a, -a, 0.0], [a, -a, 0.0], [a, a, 0.0], [-a, a, 0.0]])
    t = np.array([[0, 1, 2], [0, 2, 3]])
    i = s.add_instance(s.add_geometry(v, t), np.eye(4))
    s.commit()
    return s, i


def test_diffuser_energy_is_split_into_t_r_and_absorbed():
    a, h, intensity = 1.0, 1.0, 100.0
    trans, refl = 0.6, 0.25
    scene, sheet = _sheet(a)
    sim = Simulation(scene, {sheet: {"type": "diffuser", "transmittance": trans, "reflectance": refl}},
                     [{"type": "point", "position": [0, 0, h], "intensity_cd": intensity}])
    phi_hit = intensity * 4.0 * math.asin(a * a / (a * a + h * h))
    area = 4.0 * a * a
    gap = 1e-4
    # below the sheet, front side up: light going down; above it, front side down: light coming back up
    down = sim.grid([-a, -a, -gap], [2 * a, 0, 0], [0, 2 * a, 0], 1, 1, max_photons=400_000, seed=3)
    up = sim.grid([-a, -a, gap], [0, 2 * a, 0], [2 * a, 0, 0], 1, 1, max_photons=400_000, seed=4)
    for res, frac in ((down, trans), (up, refl)):
        flux, err = float(res.lux[0, 0]) * area, float(res.stderr[0, 0]) * area
        assert abs(flux - frac * phi_hit) <= 4 * err + 1e-3 * phi_hit, (flux, frac * phi_hit, err)
    assert sim.effects == ["lambertian"]
    assert not sim.backward_applies()[0]       # transmission: the backward estimator cannot follow it


def test_diffuser_transmits_lambertian_radiance_whatever_the_incidence():
    trans = 0.8
    scene, sheet = _sheet(0.5)
    r_beam, incidence = 1e-3, math.radians(60.0)
    d = np.array([math.sin(incidence), 0.0, -math.cos(incidence)])
    phi = 1.0
    sim = Simulation(scene, {sheet: {"type": "diffuser", "transmittance": trans, "reflectance": 0.1}},
                     [{"type": "collimated", "origin": list(-0.1 * d), "direction": list(d), "radius": r_beam,
                       "illuminance_lx": phi / (math.pi * r_beam ** 2)}])
    dist = 1.0
    thetas = np.radians([-60.0, 0.0, 30.0, 60.0])
    normals = np.stack([np.sin(thetas), np.zeros(4), np.cos(thetas)], axis=1)   # facing back at the spot
    points = -dist * normals
    res = sim.illuminance(points, normals, radius=0.02, max_photons=3_000_000, seed=11, estimator="forward")
    expected = trans * phi * np.cos(thetas) / (math.pi * dist ** 2)
    assert np.all(np.abs(res.lux - expected) <= 4 * res.stderr + 1e-3 * expected), (res.lux, expected, res.stderr)


@pytest.mark.parametrize("body, match", [
    ({"type": "diffuser", "transmittance": 0.8, "reflectance": 0.3}, "transmittance \\+ reflectance"),
    ({"type": "diffuser", "reflectance": 0.3}, "missing field"),
    ({"type": "diffuser", "transmittance": 1.2}, "'transmittance' must be in"),
    ({"type": "diffuser", "transmittance": 0.5, "haze": 1}, "unknown field"),
])
def test_bad_diffuser_bodies_are_rejected(body, match):
    with pytest.raises(MaterialError, match=match):
        material_spec(body)
