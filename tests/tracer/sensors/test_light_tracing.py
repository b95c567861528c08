"""Light tracing beside the paths from the eye (tracer/transport/radiance.py `trace_light`): a caustic seen by the eye.

Scene: a point source of intensity I at (a, 0, h) in front of a vertical plane mirror of reflectance r (the plane
x = 0, facing +x) over a Lambertian floor of reflectance ρ (z = 0, x > 0). A floor point P has the direct
illuminance E = I h / |P − S|³ and, from the source's image S' = (−a, 0, h) in the mirror, E' = r I h / |P − S'|³
(L S D E paths: paths from the eye cannot find them, light tracing does). Nothing else lights the floor: light the
floor sends up meets the mirror going up and never comes back (the mirrored floor is seen edge on). So the floor's
luminance is ρ(E + E')/π: next-event estimation gives ρE/π, light tracing ρE'/π, and nothing is counted twice.
Tolerances from the estimate's own standard error (Z of them).

The same with a small square area light facing down in place of the point source: E = (M/π) ∫ h²/d⁴ dA over the
square, E' the same over its image, times r. Paths from the eye find E' only by a BSDF sample through the mirror
onto the small emitter; light tracing takes those paths (the eye paths then add nothing there), and the sum is
still ρ(E + E')/π: a path counted twice, or by neither, fails it.

An LED behind a glass pane (a 1 cm² square of exitance M facing +x, a 3 mm slab of n = 1.5 in front of it) lights a
Lambertian wall 2 m away: no shadow ray passes the pane, so only light tracing sees it. The wall's luminance is
ρ/π × T(θ) × (M A cosθ / π) × cosθ / d², T(θ) = (1 − R)/(1 + R) the slab's transmission with its reflections inside
(R Fresnel's, averaged over s and p at each face, as a scene without polarization has it); the pane's 1 mm shift of
the source's image and the light the wall sends back are below 0.2 % here.
"""

from __future__ import annotations

import math

import numpy as np

from tests.tracer.transport_scenes import box, quad, scene_of
from tracer.simulate import Simulation

Z = 4.0
RHO, R_MIRROR, I_CD = 0.7, 0.9, 300.0
SOURCE = np.array([0.5, 0.0, 1.0])
IMAGE = SOURCE * np.array([-1.0, 1.0, 1.0])


M_EXIT, SIDE = 30_000.0, 0.1   # the area light: exitance (lm/m²), side of its square (m), centred at SOURCE


def mirror_sim(mirror: bool = True, area: bool = False) -> Simulation:
    meshes = [quad([0, -5, 0], [10, 0, 0], [0, 10, 0])]                 # the floor, front +z
    mats = [{"type": "lambertian", "reflectance": RHO}]
    if mirror:
        meshes.append(quad([0, -5, 0], [0, 10, 0], [0, 0, 5]))          # the mirror, front +x
        mats.append({"type": "mirror", "reflectance": R_MIRROR})
    if area:   # the square light, front -z (e1 × e2), black behind
        meshes.append(quad(SOURCE - [SIDE / 2, SIDE / 2, 0], [0, SIDE, 0], [SIDE, 0, 0]))
        mats.append({"type": "black"})
    s, ids = scene_of(*meshes)
    light = ({"type": "area", "instances": [ids[-1]], "exitance_lm_m2": M_EXIT} if area else
             {"type": "point", "position": SOURCE.tolist(), "intensity_cd": I_CD})
    return Simulation(s, dict(zip(ids, mats, strict=True)), [light])


def square_illuminance(src: np.ndarray, p: np.ndarray, n: int = 8) -> np.ndarray:
    """E (lx) at floor points p (m, 3) from the square Lambertian emitter of exitance M_EXIT centred at src, facing
    down: (M/π) ∫ cosθ_s cosθ_p / d² dA = (M/π) ∫ h²/d⁴ dA, midpoint rule n × n."""
    s = ((np.arange(n) + 0.5) / n - 0.5) * SIDE
    sx, sy = (a.ravel() for a in np.meshgrid(s, s))
    d = src[None, None, :] + np.stack([sx, sy, 0 * sx], axis=1)[None, :, :] - p[:, None, :]
    d2 = (d * d).sum(axis=2)
    return M_EXIT / math.pi * (d[:, :, 2] ** 2 / d2 ** 2).sum(axis=1) * SIDE * SIDE / (n * n)


def floor_luminance(p: np.ndarray, mirror: bool = True, area: bool = False) -> np.ndarray:
    """ρ(E + E')/π at floor points p (n, 3); E' only with the mirror; from the square light where `area`."""
    def e(src, scale):
        if area:
            return scale * square_illuminance(src, p)
        d = src[None, :] - p
        return scale * I_CD * d[:, 2] / ((d * d).sum(axis=1)) ** 1.5
    return RHO / math.pi * (e(SOURCE, 1.0) + (e(IMAGE, R_MIRROR) if mirror else 0.0))


CAMERA = {"type": "camera", "position": [3.0, 0.0, 2.5], "look_at": [2.0, 0.0, 0.0], "fov_deg": 30.0,
          "width": 6, "height": 4}


def pixel_means(body: dict, mirror: bool = True, n: int = 24, area: bool = False) -> np.ndarray:
    """Each pixel's mean floor luminance over its film area (midpoint rule, n × n), top row first."""
    def mean(eye: np.ndarray, d: np.ndarray) -> float:
        p = eye[None, :] + (-eye[2] / d[:, 2])[:, None] * d
        assert np.all(p[:, 0] > 0.5)   # every pixel sees the floor in front of the mirror
        return float(floor_luminance(p, mirror, area).mean())
    return over_pixels(body, n, mean)


def over_pixels(body: dict, n: int, mean) -> np.ndarray:
    """(height, width), top row first: `mean(eye, directions (n², 3))` of each pixel of camera `body`, its
    directions those of the midpoint rule (n × n) over the pixel's film area."""
    eye = np.asarray(body["position"], float)
    fwd = np.asarray(body["look_at"], float) - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    w, h = body["width"], body["height"]
    hh = math.tan(math.radians(body["fov_deg"]) / 2)
    hw = hh * w / h
    sub = (np.arange(n) + 0.5) / n
    out = np.zeros((h, w))
    for row in range(h):
        for col in range(w):
            X, Y = np.meshgrid(-hw + (col + sub) * 2 * hw / w, hh - (row + sub) * 2 * hh / h)
            out[row, col] = mean(eye, (fwd + X[..., None] * right + Y[..., None] * up).reshape(-1, 3))
    return out


def test_caustic_of_a_point_source_in_a_mirror_reads_rho_e_plus_e_image_over_pi():
    """Every pixel of the floor reads ρ(E + E')/π within 4 σ: the mirror's share, ρE'/π, is 18–26 % of the
    reading and only light tracing finds it; the answer says light tracing ran and nothing is unreachable."""
    r = mirror_sim().run(CAMERA, max_photons=60_000, seed=3)
    exact = pixel_means(CAMERA)
    assert "light tracing" in r.strategy and r.unreachable is None
    assert r.counters["light_paths"] > 0 and r.counters["light_splats"] > 0
    z = (r.luminance - exact) / r.stderr
    assert np.all(np.abs(z) <= Z), z
    assert 0.3 <= float(np.mean(z * z)) <= 2.0, z
    direct_only = pixel_means(CAMERA, mirror=False)
    assert np.all(exact - direct_only > 0.15 * exact)   # the caustic's share is large: a missing one would fail


def test_an_area_light_in_a_mirror_reads_rho_e_plus_e_image_over_pi():
    """The square light instead of the point: every pixel reads ρ(E + E')/π within 4 σ, light tracing ran (the area
    light is traced once the scene has a specular surface) and nothing is unreachable; the mirror's share is at
    least 8 % of every pixel, so a path counted twice or by neither fails."""
    r = mirror_sim(area=True).run(CAMERA, max_photons=60_000, seed=7)
    exact = pixel_means(CAMERA, area=True)
    assert "light tracing" in r.strategy and r.unreachable is None
    assert r.counters["light_paths"] > 0 and r.counters["light_splats"] > 0
    z = (r.luminance - exact) / r.stderr
    assert np.all(np.abs(z) <= Z), z
    assert 0.3 <= float(np.mean(z * z)) <= 2.0, z
    assert np.all(exact - pixel_means(CAMERA, mirror=False, area=True) > 0.08 * exact)


LED_M, LED_SIDE, WALL_X, RHO_WALL = 1.0e6, 0.01, 2.0, 0.8
PANE = (0.02, 0.023)   # the slab's faces, x (m)
WALL_CAMERA = {"type": "camera", "position": [0.8, 0.3, 1.0], "look_at": [2.0, 0.0, 1.0], "fov_deg": 20.0,
               "width": 6, "height": 4}


def led_sim() -> Simulation:
    meshes = [quad([WALL_X, -5, -4], [0, 0, 10], [0, 10, 0]),                                 # the wall, front -x
              box([PANE[0], -0.025, 0.975], [PANE[1], 0.025, 1.025]),                          # the pane
              quad([0.0, -LED_SIDE / 2, 1 - LED_SIDE / 2], [0, LED_SIDE, 0], [0, 0, LED_SIDE])]  # the LED, front +x
    s, ids = scene_of(*meshes)
    mats = [{"type": "lambertian", "reflectance": RHO_WALL}, {"type": "dielectric", "ior": 1.5}, {"type": "black"}]
    light = {"type": "area", "instances": [ids[2]], "exitance_lm_m2": LED_M}
    return Simulation(s, dict(zip(ids, mats, strict=True)), [light])


def pane_transmission(cos_i: np.ndarray, n: float = 1.5) -> np.ndarray:
    """(1 − R)/(1 + R): a non-absorbing slab's transmission with its inner reflections, R = (R_s + R_p)/2."""
    sin_t = np.sqrt(1 - cos_i ** 2) / n
    cos_t = np.sqrt(1 - sin_t ** 2)
    rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)) ** 2
    rp = ((cos_t - n * cos_i) / (cos_t + n * cos_i)) ** 2
    r = (rs + rp) / 2
    return (1 - r) / (1 + r)


def wall_luminance(p: np.ndarray) -> np.ndarray:
    """ρ/π × T(θ) × (M A cosθ/π) × cosθ/d² at wall points p (n, 3), the LED at (0, 0, 1) facing +x."""
    d = p - np.array([0.0, 0.0, 1.0])
    d2 = (d * d).sum(axis=1)
    cos = d[:, 0] / np.sqrt(d2)
    return RHO_WALL / math.pi * pane_transmission(cos) * LED_M * LED_SIDE ** 2 * cos * cos / (math.pi * d2)


def wall_pixel_means(body: dict, n: int = 24) -> np.ndarray:
    """Each pixel's mean wall luminance (midpoint rule, n × n), top row first."""
    return over_pixels(body, n, lambda eye, d: float(
        wall_luminance(eye[None, :] + ((WALL_X - eye[0]) / d[:, 0])[:, None] * d).mean()))


def test_an_led_behind_a_glass_pane_lights_the_wall_by_the_panes_transmission():
    """Every pixel of the wall reads ρ/π × T(θ) E(θ) within 4 σ, and the pilot chose light tracing for the area
    light (without it the paths from the eye find the LED through the pane almost never: their answer would read a
    fraction of this with an error bar of almost nothing)."""
    r = led_sim().run(WALL_CAMERA, max_photons=40_000, seed=11)
    exact = wall_pixel_means(WALL_CAMERA)
    assert "area lights traced" in r.strategy and r.unreachable is None, r.strategy
    assert r.counters["light_splats"] > 0 and r.counters["left_to_light_tracing"] >= 0
    z = (r.luminance - exact) / r.stderr
    assert np.all(np.abs(z) <= Z), z
    assert 0.3 <= float(np.mean(z * z)) <= 2.0, z


def test_meter_sees_the_caustic_too():
    """A luminance meter's 10° cone on the floor: the cone average of ρ(E + E')/π within 4 σ."""
    body = {"type": "luminance", "position": [1.5, 0.0, 1.5], "direction": [0.0, 0.0, -1.0], "aperture_deg": 10.0}
    r = mirror_sim().run(body, max_photons=20_000, seed=5)
    n = 64
    cmax = math.cos(math.radians(5.0))
    c = 1 - (np.arange(n) + 0.5) / n * (1 - cmax)
    phi = 2 * math.pi * (np.arange(n) + 0.5) / n
    c, phi = np.meshgrid(c, phi)
    s = np.sqrt(1 - c * c)
    d = np.stack([s * np.cos(phi), s * np.sin(phi), -c], axis=-1).reshape(-1, 3)
    p = np.array(body["position"])[None, :] + (1.5 / c.reshape(-1))[:, None] * d
    exact = float(floor_luminance(p).mean())
    assert "light tracing" in r.strategy and r.unreachable is None
    assert abs(r.luminance - exact) <= Z * r.stderr, (r.luminance, r.stderr, exact)


def test_thin_lens_in_focus_reads_the_same_caustic():
    """With a thin lens focused on the floor point the view's centre passes through, each pixel's mean is the
    pinhole's (the floor's luminance is smooth over a pixel's circle of confusion: ≤ 1 mm here)."""
    body = dict(CAMERA, lens_diameter_m=0.002)
    r = mirror_sim().run(body, max_photons=60_000, seed=4)
    exact = pixel_means(CAMERA)
    z = (r.luminance - exact) / r.stderr
    assert "light tracing" in r.strategy and np.all(np.abs(z) <= Z), z


def test_without_a_specular_surface_light_tracing_does_not_run():
    """The floor alone: next-event estimation finds all the light, light tracing is not started (an area light's
    neither: paths from the eye find all its light here)."""
    for area in (False, True):
        r = mirror_sim(mirror=False, area=area).run(CAMERA, max_photons=8_000, seed=6)
        assert "light tracing" not in r.strategy and r.counters["light_paths"] == 0
        z = (r.luminance - pixel_means(CAMERA, mirror=False, area=area)) / r.stderr
        assert np.all(np.abs(z) <= Z), z
