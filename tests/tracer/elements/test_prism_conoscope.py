"""A prism film's conoscopic view peaks where its geometry says (issue 53's validation).

A PMMA film (n = 1.49) whose top face carries prisms of apex 120 deg (facets 30 deg from the face, ridges along v)
is lit from 1 m below by a small Lambertian source (20 mm: within 0.57 deg of the axis). Light going straight up
crosses the flat bottom undeviated and meets a facet at 30 deg from its normal; it leaves at asin(1.49 sin 30 deg) =
48.16 deg from that normal, 18.16 deg from the film's normal, tilted across the ridges: the view of the lit face is
dark but at that polar angle, on both sides across the ridges (azimuths 0 and 180 deg from u), and dark along them.
Paths from the eye (the conoscope's meters) find it; a film whose facets lay at another angle would peak elsewhere.
"""

from __future__ import annotations

import math

import numpy as np

from tests.tracer.transport_scenes import box
from tracer.elements import prepare
from tracer.scene import Scene
from tracer.sensors.luminance import conoscope
from tracer.simulate import Simulation

N_PMMA = 1.49
APEX = 120.0
PEAK_DEG = math.degrees(math.asin(N_PMMA * math.sin(math.radians(90 - APEX / 2)))) - (90 - APEX / 2)   # 18.16


def test_a_prism_film_s_conoscopic_view_peaks_at_the_angle_its_facets_refract_to() -> None:
    s = Scene()
    v, t = box([0.0, 0.0, 0.0], [0.02, 0.02, 0.0005])
    film = s.add_instance(s.add_geometry(v, t), np.eye(4))
    lamp = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0], [0.02, 0.02, 0.0], [0.0, 0.02, 0.0]]) + [0.0, 0.0, -1.0]
    led = s.add_instance(s.add_geometry(lamp, np.array([[0, 1, 2], [0, 2, 3]])), np.eye(4))   # front side up
    prisms = prepare({"type": "microstructure", "feature": {"shape": "prism", "base_mm": 0.1, "apex_deg": APEX},
                      "layout": {"type": "grid", "pitch_mm": [0.1, 0.1]}})
    s.set_element(film, prisms, facing=[0, 0, 1])
    s.commit()
    sim = Simulation(s, {film: {"type": "dielectric", "ior": N_PMMA}, led: {"type": "black"}},
                     [{"type": "area", "instances": [led], "exitance_lm_m2": 1000.0}])
    rings = 11   # 0 to 2 x PEAK: ring 5 looks from the peak's angle
    views, _ = conoscope(sim, [0.01, 0.01, 0.0005], [0, 0, 1], theta_max_deg=2 * PEAK_DEG, rings=rings, azimuths=4,
                         phi_zero=[1, 0, 0], max_photons=400_000, seed=3)
    lum, err = views["luminance"], views["stderr"]
    assert math.isclose(views["theta_deg"][5], PEAK_DEG)
    for az in (0, 2):   # across the ridges, both sides
        peak = lum[5, az]
        assert peak > 10 * err[5, az] > 0, (lum[:, az], err[:, az])
        assert int(np.argmax(lum[:, az])) == 5
        others = np.delete(lum[:, az], 5)
        assert (others < 0.1 * peak).all(), lum[:, az]
    for az in (1, 3):   # along them: dark
        assert (lum[1:, az] < 0.1 * lum[5, 0]).all(), lum[:, az]
    assert lum[0, 0] < 0.1 * lum[5, 0]   # and straight on
