"""Light tracing beside the paths from the eye (tracer/transport/radiance.py `trace_light`): a caustic seen by the eye.

Scene: a point source of intensity I at (a, 0, h) in front of a vertical plane mirror of reflectance r (the plane
x = 0, facing +x) over a Lambertian floor of reflectance ρ (z = 0, x > 0). A floor point P has the direct
illuminance E = I h / |P − S|³ and, from the source's image S' = (−a, 0, h) in the mirror, E' = r I h / |P − S'|³
(L S D E paths: paths from the eye cannot find them, light tracing does). Nothing else lights the floor: light the
floor sends up meets the mirror going up and never comes back (the mirrored floor is seen edge on). So the floor's
luminance is ρ(E + E')/π: next-event estimation gives ρE/π, light tracing ρE'/π, and nothing is counted twice.
Tolerances from the estimate's own standard error (Z of them).
"""

from __future__ import annotations

import math

import numpy as np

from tests.tracer.transport_scenes import quad, scene_of
from tracer.simulate import Simulation

Z = 4.0
RHO, R_MIRROR, I_CD = 0.7, 0.9, 300.0
SOURCE = np.array([0.5, 0.0, 1.0])
IMAGE = SOURCE * np.array([-1.0, 1.0, 1.0])


def mirror_sim(mirror: bool = True) -> Simulation:
    meshes = [quad([0, -5, 0], [10, 0, 0], [0, 10, 0])]                 # the floor, front +z
    mats = [{"type": "lambertian", "reflectance": RHO}]
    if mirror:
        meshes.append(quad([0, -5, 0], [0, 10, 0], [0, 0, 5]))          # the mirror, front +x
        mats.append({"type": "mirror", "reflectance": R_MIRROR})
    s, ids = scene_of(*meshes)
    light = {"type": "point", "position": SOURCE.tolist(), "intensity_cd": I_CD}
    return Simulation(s, dict(zip(ids, mats, strict=True)), [light])


def floor_luminance(p: np.ndarray, mirror: bool = True) -> np.ndarray:
    """ρ(E + E')/π at floor points p (n, 3); E' only with the mirror."""
    def e(src, scale):
        d = src[None, :] - p
        return scale * I_CD * d[:, 2] / ((d * d).sum(axis=1)) ** 1.5
    return RHO / math.pi * (e(SOURCE, 1.0) + (e(IMAGE, R_MIRROR) if mirror else 0.0))


CAMERA = {"type": "camera", "position": [3.0, 0.0, 2.5], "look_at": [2.0, 0.0, 0.0], "fov_deg": 30.0,
          "width": 6, "height": 4}


def pixel_means(body: dict, mirror: bool = True, n: int = 24) -> np.ndarray:
    """Each pixel's mean luminance over its film area (midpoint rule, n × n), top row first."""
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
            d = (fwd + X[..., None] * right + Y[..., None] * up).reshape(-1, 3)
            p = eye[None, :] + (-eye[2] / d[:, 2])[:, None] * d
            assert np.all(p[:, 0] > 0.5)   # every pixel sees the floor in front of the mirror
            out[row, col] = floor_luminance(p, mirror).mean()
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
    """The floor alone: next-event estimation finds all the light, light tracing is not started."""
    r = mirror_sim(mirror=False).run(CAMERA, max_photons=8_000, seed=6)
    assert "light tracing" not in r.strategy and r.counters["light_paths"] == 0
    z = (r.luminance - pixel_means(CAMERA, mirror=False)) / r.stderr
    assert np.all(np.abs(z) <= Z), z
