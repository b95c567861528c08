"""A pack driven by luminance (issue 53: a backlight is judged by the luminance a viewer sees, not by illuminance).

- `read` with a luminance `Reading`: meters a distance in front of each cell of the grid, looking through it at a
  Lambertian floor of reflectance ρ under a point source of intensity I, read L = ρ I cosθ / (π r²) at each cell's
  centre within 4 of their standard errors, in the grid's order (rows along v, columns along u: a 2 x 3 grid whose
  cells all differ), with the unit cd/m².
- `pack` with that reading measures every iteration, and its confirmation, through the meters (a scripted stand-in
  for `tracer.sensors.luminance.meters`, so which reading reaches the target is known): the eyes stand `distance`
  behind the cell centres on the grid's back side and look along its front normal u × v with the reading's
  aperture, and the result says what it read.
- A reading that cannot be taken is refused naming its field.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from tests.tracer.transport_scenes import box, quad, scene_of
from tracer.elements import prepare
from tracer.elements.pack import PackError, Reading, cell_centres, pack, read
from tracer.simulate import Simulation

I_CD, H, RHO = 100.0, 1.5, 0.6
GRID = {"type": "grid", "origin": [-0.9, -0.5, 0.01], "u": [0.0, 1.0, 0.0], "v": [1.8, 0.0, 0.0], "nu": 3, "nv": 2}


def test_luminance_at_the_cells_is_the_lambertian_floor_s_closed_form():
    s, (floor,) = scene_of(quad([-3.0, -3.0, 0.0], [6.0, 0.0, 0.0], [0.0, 6.0, 0.0]))
    light = np.array([0.3, 0.2, H])
    sim = Simulation(s, {floor: {"type": "lambertian", "reflectance": RHO}},
                     [{"type": "point", "position": light.tolist(), "intensity_cd": I_CD}])
    values, err, traced = read(sim, GRID, Reading("luminance", distance=0.5, aperture_deg=1.0), 6 * 8000, 3, None,
                               None)
    assert values.shape == err.shape == (2, 3) and traced > 0
    centres, front = cell_centres(GRID)
    np.testing.assert_allclose(front, [0.0, 0.0, -1.0])   # u x v: the grid's front side faces the floor
    foot = centres * [1.0, 1.0, 0.0]                       # the meters look straight down at the floor
    d = light - foot
    r2 = np.sum(d * d, axis=1)
    exact = (RHO * I_CD * (H / np.sqrt(r2)) / r2 / math.pi).reshape(2, 3)
    assert len(np.unique(np.round(exact, 6))) == 6         # every cell differs: the order is tested
    assert np.all(err > 0) and np.all(np.abs(values - exact) <= 4 * err + 1e-4 * exact), (values, err, exact)
    assert Reading("luminance").unit == "cd/m²" and Reading().unit == "lx"


START = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.25, "height_mm": 0.1},
         "layout": {"type": "density", "origin_mm": [0.0, 0.0], "size_mm": [30.0, 20.0], "fill": [[0.5] * 3] * 2,
                    "seed": 1, "pitch_mm": 0.6}}
SENSOR = {"type": "grid", "origin": [0.0, 0.0, 0.004], "u": [0.03, 0.0, 0.0], "v": [0.0, -0.02, 0.0], "nu": 3,
          "nv": 2}   # u x v = -z: the front side faces the plate below


def test_a_pack_reads_luminance_through_meters_in_front_of_the_cells(monkeypatch):
    import tracer.sensors.luminance as luminance

    script = [0.5, 0.85, 0.84]    # iteration 0 far; iteration 1 reaches 0.8 and its confirmation does too
    calls = []

    def meters(sim, positions, directions, aperture_deg, **options):
        calls.append((np.array(positions), np.array(directions), aperture_deg, options))
        lum = np.full(6, 1000.0)
        lum[0] *= script.pop(0)
        return SimpleNamespace(luminance=lum, stderr=0.01 * lum, photons=int(options["max_photons"]))

    monkeypatch.setattr(luminance, "meters", meters)
    s, (plate,) = scene_of(box([0.0, -0.02, 0.0], [0.03, 0.0, 0.003]))
    reading = Reading("luminance", distance=0.3, aperture_deg=2.0)
    res = pack(s, plate, prepare(START), SENSOR, lambda scene: None,
               assign={"facing": [0, 0, -1], "mm_per_unit": 1000.0}, target=0.8, photons=5000, max_iterations=4,
               seed=7, reading=reading)
    assert res.stopped == "target" and len(res.history) == 2 and res.reading == reading
    assert len(calls) == 3   # two iterations and one confirmation, all through the meters
    centres, front = cell_centres(SENSOR)
    for positions, directions, aperture, options in calls:
        np.testing.assert_allclose(positions, centres - 0.3 * front)
        np.testing.assert_allclose(directions, np.tile(front, (6, 1)))
        assert aperture == 2.0 and options["estimator"] == "backward"
    assert res.history[0].lux[0][0] == pytest.approx(500.0) and res.history[1].confirmation["confirmed"]


@pytest.mark.parametrize("reading, field", [(Reading("brightness"), "quantity"),
                                            (Reading("luminance", distance=0.0), "distance"),
                                            (Reading("luminance", aperture_deg=200.0), "aperture_deg"),
                                            (Reading("luminance", distance=True), "distance")])
def test_a_reading_that_cannot_be_taken_is_refused_naming_it(reading, field):
    with pytest.raises(PackError) as info:
        reading.check()
    assert str(info.value).startswith(field)
