"""A camera with a thin lens (tracer/sensors/camera.py: lens_diameter_m, focus_distance_m) against closed forms, with
tolerances from the estimator's own standard error (4 of them).

The scene: a plane z = 0, Lambertian (ρ = 0.6) for x < 0 and black for x > 0, under a point source 100 m up (its
illuminance varies by 2e-5 over the 0.8 m seen, which the closed form keeps: the estimator's error bars are
smaller), so the lit half reads L = ρE/π and the edge is sharp. Each pixel's truth is that closed form averaged
over its footprint (and the lens) by the midpoint rule. The camera
looks straight down from 2 m; its 16 columns cover x ∈ [−0.4, 0.4], the edge between columns 7 and 8.

- In focus (focus 2 m, lens 0.2 m): every pixel reads what a pinhole reads, L or 0.
- Focused at 1 m: a ray from a lens point at offset o reaches the plane at the pinhole point − o (z − f)/f, so the
  image is the pinhole's blurred by a uniform disk of radius R = r_lens |z − f| / f = 0.1 m: a pixel reads L times
  the mean, over its footprint [x0, x1], of the share of that disk on the lit side, A(x)/(πR²) with
  A(x) = R² acos(x/R) − x √(R² − x²).
- A point source in view, out of focus: its light spreads over several pixels, and Σ L_pixel × film area × cos³θ
  (the pixels' share of E⊥) adds up to E⊥ = I/d², as the pinhole's single pixel does.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.tracer.transport_scenes import quad, scene_of
from tracer.simulate import Simulation, SimulationError

Z = 4.0
RHO, I_CD, H_LIGHT = 0.6, 1.0e6, 100.0
L_LIT = RHO * I_CD / H_LIGHT ** 2 / math.pi
TAN = 0.025   # tan(fov/2): the 2 rows span ±0.05 m at 2 m, the 16 columns ±0.4 m
CAM = {"type": "camera", "position": [0.0, 0.0, 2.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0],
       "fov_deg": math.degrees(2 * math.atan(TAN)), "width": 16, "height": 2}


@pytest.fixture(scope="module")
def edge():
    s, ids = scene_of(quad([-50, -50, 0], [50, 0, 0], [0, 100, 0]), quad([0, -50, 0], [50, 0, 0], [0, 100, 0]))
    return Simulation(s, {ids[0]: {"type": "lambertian", "reflectance": RHO}, ids[1]: {"type": "black"}},
                      [{"type": "point", "position": [0.0, 0.0, H_LIGHT], "intensity_cd": I_CD}])


def truth(focus: float, lens_radius: float = 0.1, nx: int = 40, ny: int = 8, nr: int = 12,
          nphi: int = 24) -> np.ndarray:
    """Each pixel's mean luminance over its footprint and the lens (midpoint rule: nx × ny film points, nr × nphi
    lens points): the plane's ρE/π, E = I h / r³, on the lit side, at the pinhole point − o (z − f)/f."""
    rr = lens_radius * np.sqrt((np.arange(nr) + 0.5) / nr)
    phi = 2 * math.pi * (np.arange(nphi) + 0.5) / nphi
    ox, oy = (rr[:, None] * np.cos(phi)[None, :]).ravel(), (rr[:, None] * np.sin(phi)[None, :]).ravel()
    k = (2.0 - focus) / focus
    out = np.empty((2, 16))
    for row in range(2):
        for col in range(16):
            x = -0.4 + 0.05 * (col + (np.arange(nx) + 0.5) / nx)
            y = 0.05 - 0.05 * (row + (np.arange(ny) + 0.5) / ny)
            px = (x[:, None, None] - k * ox[None, None, :]) + 0 * y[None, :, None]
            py = y[None, :, None] - k * oy[None, None, :] + 0 * x[:, None, None]
            lum = RHO / math.pi * I_CD * H_LIGHT / (px * px + py * py + H_LIGHT ** 2) ** 1.5 * (px < 0)
            out[row, col] = lum.mean()
    return out


def test_a_plane_in_focus_renders_as_the_pinhole_renders_it(edge):
    r = edge.run({**CAM, "lens_diameter_m": 0.2, "focus_distance_m": 2.0}, max_photons=32 * 2000, seed=1)
    pin = edge.run(CAM, max_photons=32 * 2000, seed=2)
    exact = truth(2.0, nr=1, nphi=1)
    for res in (r, pin):
        assert np.all(np.abs(res.luminance - exact) <= Z * res.stderr + 1e-9 * L_LIT), (res.luminance - exact)
    assert np.all(r.luminance[:, 8:] == 0.0) and np.all(r.stderr[:, :8] > 0)


def test_out_of_focus_the_edge_is_blurred_by_the_circle_of_confusion(edge):
    r = edge.run({**CAM, "lens_diameter_m": 0.2, "focus_distance_m": 1.0}, max_photons=32 * 4000, seed=3)
    exact = truth(1.0)
    assert np.all(np.abs(r.luminance - exact) <= Z * r.stderr + 1e-9 * L_LIT), (r.luminance - exact, r.stderr)
    # measurable: beside the edge the blur takes a third of the light, far beyond the error bars
    assert np.all(exact[:, 7] < 0.7 * L_LIT) and np.all(L_LIT - r.luminance[:, 7] > 10 * r.stderr[:, 7])
    assert np.all(r.luminance[:, 9] > 10 * r.stderr[:, 9])   # and light spills onto the black side


def test_a_point_source_out_of_focus_spreads_its_light_and_keeps_it():
    s, _ = scene_of(quad([100, 100, 100], [1, 0, 0], [0, 1, 0]))   # a scene needs something; far out of view
    d, intensity = 3.0, 50.0
    sim = Simulation(s, {0: {"type": "black"}}, [{"type": "point", "position": [0.02, 0.01, 2.0 - d],
                                                  "intensity_cd": intensity}])
    cam = {"type": "camera", "position": [0.0, 0.0, 2.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0],
           "fov_deg": 6.0, "width": 12, "height": 12}
    e_perp = intensity / (d * d + 0.02 ** 2 + 0.01 ** 2)
    pin = sim.run(cam, max_photons=144 * 8, seed=1)
    r = sim.run({**cam, "lens_diameter_m": 0.05, "focus_distance_m": 1.0}, max_photons=144 * 400, seed=4)
    half = math.tan(math.radians(3.0))
    area = (2 * half / 12) ** 2
    c = -half + (np.arange(12) + 0.5) * 2 * half / 12
    cos3 = (1.0 / np.sqrt(1 + c[None, :] ** 2 + c[:, None] ** 2)) ** 3
    assert np.count_nonzero(pin.luminance) == 1 and np.count_nonzero(r.luminance) > 4
    total = float((r.luminance * area * cos3).sum())
    sigma = float(np.sqrt(((r.stderr * area * cos3) ** 2).sum()))
    # the blur disk (radius 2.5 cm × 2/1 on the plane of the light, 2.2 pixels) stays in the image: all of E⊥
    assert abs(total - e_perp) <= Z * sigma + 1e-3 * e_perp, (total, sigma, e_perp)
    assert float((pin.luminance * area * cos3).sum()) == pytest.approx(e_perp, rel=1e-3)


@pytest.mark.parametrize("extra, field", [({"lens_diameter_m": -0.1}, "lens_diameter_m"),
                                          ({"lens_diameter_m": 0.1, "focus_distance_m": 0}, "focus_distance_m"),
                                          ({"lens_diameter_m": "wide"}, "lens_diameter_m")])
def test_bad_lens_fields_name_themselves(edge, extra, field):
    with pytest.raises(SimulationError, match=field):
        edge.run({**CAM, **extra}, max_photons=100)
