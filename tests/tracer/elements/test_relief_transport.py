"""Light through elements with an inside (issue 36's validations): the element against the same dots meshed, an ideal
prism film that returns all it receives, and no light lost inside an element. Tolerances from the estimates' own
standard errors."""

from __future__ import annotations

import math

import numpy as np

from tests.tracer.elements.meshed_relief import domed_plate
from tests.tracer.transport_scenes import box
from tracer.elements import prepare
from tracer.scene import Scene
from tracer.simulate import Simulation

PMMA = {"type": "dielectric", "ior": 1.49}
N, PITCH, RADIUS, HEIGHT, THICK = 20, 0.2e-3, 0.08e-3, 0.04e-3, 1e-3   # m


def _beam(origin, direction, radius, lux=1000.0):
    return {"type": "collimated", "origin": list(origin), "direction": list(direction), "radius": radius,
            "illuminance_lx": lux}


def _measure(scene, part, light, grids, seed, photons):
    sim = Simulation(scene, {part: PMMA}, [light])
    return [sim.grid(*g, max_photons=photons, seed=seed + k, estimator="forward") for k, g in enumerate(grids)]


def test_a_dot_array_as_an_element_lights_the_floor_as_the_same_dots_meshed():
    """20 x 20 domes on the bottom of a PMMA plate lit at 30 degrees: the illuminance map below it, from the
    element and from the dots meshed explicitly (~250k triangles), agree cell by cell within 4 combined sigma (plus
    the mesh's own facetting, 0.5 % of the mean)."""
    size = N * PITCH
    meshed = Scene()
    v, t = domed_plate(N, PITCH, RADIUS, HEIGHT, THICK)
    meshed_part = meshed.add_instance(meshed.add_geometry(v, t), np.eye(4))
    meshed.commit()
    element = Scene()
    v, t = box([0, 0, 0], [size, size, THICK])
    element_part = element.add_instance(element.add_geometry(v, t), np.eye(4))
    dots = prepare({"type": "microstructure", "layout": {"type": "grid", "pitch_mm": [PITCH * 1e3, PITCH * 1e3]},
                    "feature": {"shape": "dome", "radius_mm": RADIUS * 1e3, "height_mm": HEIGHT * 1e3}})
    element.set_element(element_part, dots, facing=[0, 0, -1])
    element.commit()
    s30 = math.sin(math.radians(30))
    light = _beam([size / 2 - 2e-3 * s30, size / 2, THICK + 2e-3], [s30, 0, -math.cos(math.radians(30))], 1.2e-3)
    floor = ([-2e-3, -2e-3, -1e-3], [size + 4e-3, 0, 0], [0, size + 4e-3, 0], 4, 4)
    a = _measure(meshed, meshed_part, light, [floor], 5, 400_000)[0]
    b = _measure(element, element_part, light, [floor], 5, 400_000)[0]
    lit = a.lux > 0.05 * a.lux.max()
    assert lit.sum() >= 4
    sigma = np.sqrt(a.stderr ** 2 + b.stderr ** 2)
    z = np.abs(a.lux - b.lux)[lit] / (4 * sigma[lit] + 0.005 * a.lux.mean())
    assert (z < 1).all(), (a.lux, b.lux, sigma)
    assert abs(a.lux.sum() - b.lux.sum()) < 4 * math.sqrt((sigma ** 2).sum()) + 0.005 * a.lux.sum()


def _film(apex=90.0):
    """A 6 x 6 x 1 mm PMMA-like sheet (n 1.5) whose top face carries prisms of 50 um."""
    s = Scene()
    v, t = box([0, 0, 0], [6e-3, 6e-3, 1e-3])
    part = s.add_instance(s.add_geometry(v, t), np.eye(4))
    prisms = prepare({"type": "microstructure", "feature": {"shape": "prism", "base_mm": 0.05, "apex_deg": apex},
                      "layout": {"type": "grid", "pitch_mm": [0.05, 0.05]}})
    s.set_element(part, prisms, facing=[0, 0, 1])
    s.commit()
    return s, part


def test_an_ideal_90_degree_prism_film_returns_all_light_it_receives_at_normal_incidence():
    """A beam up through the flat side meets two total internal reflections in every prism and goes back: nothing
    is transmitted, and with no absorption the reflectance is 1 (all the beam's flux comes back down)."""
    s, part = _film()
    sim = Simulation(s, {part: {"type": "dielectric", "ior": 1.5}}, [_beam([3e-3, 3e-3, -1e-3], [0, 0, 1], 2e-3)])
    phi = 1000.0 * math.pi * (2e-3) ** 2
    up = sim.grid([0, 0, 1.5e-3], [0, 6e-3, 0], [6e-3, 0, 0], 1, 1, max_photons=200_000, seed=1,
                  estimator="forward")   # front side down: what leaves the top
    down = sim.grid([0, 0, -0.5e-3], [6e-3, 0, 0], [0, 6e-3, 0], 1, 1, max_photons=200_000, seed=2,
                    estimator="forward")  # front side up, above the source: what comes back
    area = 36e-6
    assert float(up.lux[0, 0]) == 0.0
    back, err = float(down.lux[0, 0]) * area, float(down.stderr[0, 0]) * area
    assert abs(back - phi) <= 4 * err + 1e-9 * phi, (back, phi, err)


def test_a_prism_film_transmits_light_that_does_not_meet_the_condition():
    """The control: at apex 120 degrees the prism faces are 30 degrees from the sheet, below the critical angle, so
    light gets through: the zero above is the 90-degree film's geometry, not a lost photon."""
    s, part = _film(120.0)
    sim = Simulation(s, {part: {"type": "dielectric", "ior": 1.5}}, [_beam([3e-3, 3e-3, -1e-3], [0, 0, 1], 2e-3)])
    up = sim.grid([0, 0, 1.5e-3], [0, 6e-3, 0], [6e-3, 0, 0], 1, 1, max_photons=50_000, seed=1, estimator="forward")
    assert float(up.lux[0, 0]) > 10 * float(up.stderr[0, 0]) > 0


def test_no_light_is_lost_inside_an_element():
    """A clear plate with pits on its bottom in a closed box of six sensors, front sides in: what leaves through
    the six faces is the beam's flux, within 4 sigma (there is no absorption)."""
    size = 4e-3
    s = Scene()
    v, t = box([0, 0, 0], [size, size, 1e-3])
    part = s.add_instance(s.add_geometry(v, t), np.eye(4))
    pits = prepare({"type": "microstructure", "relief": "pit", "layout": {"type": "hex", "pitch_mm": 0.2},
                    "feature": {"shape": "dome", "radius_mm": 0.09, "height_mm": 0.05}})
    s.set_element(part, pits, facing=[0, 0, -1])
    s.commit()
    lo, hi = -3e-3, size + 3e-3
    w = hi - lo
    # each face of the cube [lo, hi]^3, its front side in: (origin, u, v) with u x v pointing inwards
    faces = [([lo, lo, lo], [w, 0, 0], [0, w, 0]), ([lo, lo, hi], [0, w, 0], [w, 0, 0]),
             ([lo, lo, lo], [0, 0, w], [w, 0, 0]), ([lo, hi, lo], [w, 0, 0], [0, 0, w]),
             ([lo, lo, lo], [0, w, 0], [0, 0, w]), ([hi, lo, lo], [0, 0, w], [0, w, 0])]
    light = _beam([size / 2, size / 2, 2.5e-3], [0.3, 0.2, -1.0], 1.5e-3)
    results = _measure(s, part, light, [(*f, 1, 1) for f in faces], 11, 150_000)
    flux = sum(float(r.lux[0, 0]) * w * w for r in results)
    err = math.sqrt(sum((float(r.stderr[0, 0]) * w * w) ** 2 for r in results))
    phi = 1000.0 * math.pi * 1.5e-3 ** 2
    assert abs(flux - phi) <= 4 * err + 1e-9 * phi, (flux, phi, err)
