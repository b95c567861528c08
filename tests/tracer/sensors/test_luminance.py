"""Luminance meters and cameras (tracer/sensors/luminance.py, camera.py; tracer/transport/radiance.py) against
closed forms, with tolerances from the estimator's own standard error (Z of them), and their bodies' bad fields.

Scenes: a Lambertian plane of reflectance ρ under a point source (L = ρE/π, E = I cosθ/r², averaged over the meter's
cone or each pixel by quadrature: nothing else lights the plane); a Lambertian emitter of exitance M = Φ/A (L = M/π)
seen directly, in a mirror of reflectance r (r M/π), through a clear pane of n = 1.5 ((1 − R)/(1 + R) M/π, the
incoherent sum of its multiple reflections); a plane under that emitter (ρE/π with E of a parallel rectangle: the
MIS weights of light and BSDF sampling sum to 1 there, or the reading moves).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.tracer.transport_scenes import box, quad, scene_of
from tracer.simulate import Simulation, SimulationError

Z = 4.0
RHO = 0.6
I_CD = 200.0
LIGHT_AT = np.array([0.3, -0.2, 2.0])
M_EXIT = 1500.0   # lm/m²


def plane_sim():
    s, ids = scene_of(quad([-50, -50, 0], [100, 0, 0], [0, 100, 0]))
    light = {"type": "point", "position": LIGHT_AT.tolist(), "intensity_cd": I_CD}
    return Simulation(s, {ids[0]: {"type": "lambertian", "reflectance": RHO}}, [light])


def plane_luminance(x: np.ndarray) -> np.ndarray:
    """ρE/π at points (n, 3) of the plane z = 0 under the point source."""
    d = LIGHT_AT[None, :] - x
    r2 = (d * d).sum(axis=1)
    return RHO / math.pi * I_CD * d[:, 2] / r2 ** 1.5


def on_plane(eye: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    return eye[None, :] + (-eye[2] / dirs[:, 2])[:, None] * dirs


def cone_average(eye, axis, aperture_deg, n=200) -> float:
    """The plane's luminance averaged uniformly in solid angle over the cone (midpoint rule in cosθ and φ)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    t = np.cross(axis, [1.0, 0, 0]) if abs(axis[0]) < 0.9 else np.cross(axis, [0, 1.0, 0])
    t /= np.linalg.norm(t)
    b = np.cross(axis, t)
    cmax = math.cos(math.radians(aperture_deg) / 2)
    c = 1 - (np.arange(n) + 0.5) / n * (1 - cmax)
    phi = 2 * math.pi * (np.arange(n) + 0.5) / n
    c, phi = np.meshgrid(c, phi)
    s = np.sqrt(1 - c * c)
    dirs = (s * np.cos(phi))[..., None] * t + (s * np.sin(phi))[..., None] * b + c[..., None] * axis
    return float(plane_luminance(on_plane(np.asarray(eye, float), dirs.reshape(-1, 3))).mean())


def test_meter_on_a_lambertian_plane_reads_rho_e_over_pi():
    """L = ρE/π averaged over the 2° cone, within 4 σ."""
    sim = plane_sim()
    body = {"type": "luminance", "position": [1.0, 0.5, 1.2], "direction": [-0.3, 0.1, -1.0], "aperture_deg": 2.0}
    r = sim.run(body, max_photons=40_000, seed=1)
    exact = cone_average(body["position"], body["direction"], 2.0)
    assert r.estimator == "backward" and r.unreachable is None and "next-event" in r.strategy
    assert r.stderr > 0 and abs(r.luminance - exact) <= Z * r.stderr, (r.luminance, r.stderr, exact)


def test_meter_stderr_is_honest_over_seeds():
    """Twelve seeds: each reading within 4 of its own σ of the closed form, and the mean squared z-score in the
    central 99.9 % of χ²₁₂/12 (0.26 … 2.9): the error bars are neither too small nor much too large."""
    sim = plane_sim()
    body = {"type": "luminance", "position": [0.0, 0.0, 0.5], "direction": [0.2, 0.0, -1.0], "aperture_deg": 20.0}
    exact = cone_average(body["position"], body["direction"], 20.0)
    z = []
    for seed in range(12):
        r = sim.run(body, max_photons=4096, seed=100 + seed)
        z.append((r.luminance - exact) / r.stderr)
    z = np.array(z)
    assert np.all(np.abs(z) <= Z), z
    assert 0.26 <= float(np.mean(z * z)) <= 2.9, z


def test_camera_image_of_the_plane_is_rho_e_over_pi_per_pixel():
    """Every pixel reads the plane's ρE(x)/π averaged over the pixel's film area (32 × 32 midpoint rule), within 4
    of its own σ, and the z-scores over the 48 pixels have a mean square in χ²₄₈/48's central 99.9 % (0.5 … 1.7)."""
    sim = plane_sim()
    eye, look, fov, w, h = np.array([0.5, -2.0, 1.5]), np.array([0.2, 0.3, 0.0]), 40.0, 8, 6
    body = {"type": "camera", "position": eye.tolist(), "look_at": look.tolist(), "up": [0, 0, 1], "fov_deg": fov,
            "width": w, "height": h}
    r = sim.run(body, max_photons=200_000, seed=2)
    assert r.luminance.shape == (h, w) and r.stderr.shape == (h, w)
    fwd = (look - eye) / np.linalg.norm(look - eye)
    right = np.cross(fwd, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    hh = math.tan(math.radians(fov) / 2)
    hw = hh * w / h
    n = 32
    sub = (np.arange(n) + 0.5) / n
    exact = np.zeros((h, w))
    for row in range(h):
        for col in range(w):
            xs = -hw + (col + sub) * 2 * hw / w
            ys = hh - (row + sub) * 2 * hh / h
            X, Y = np.meshgrid(xs, ys)
            dirs = fwd + X[..., None] * right + Y[..., None] * up
            dirs = dirs.reshape(-1, 3) / np.linalg.norm(dirs.reshape(-1, 3), axis=1)[:, None]
            exact[row, col] = plane_luminance(on_plane(eye, dirs)).mean()
    z = (r.luminance - exact) / r.stderr
    assert np.all(np.abs(z) <= Z), z
    assert 0.5 <= float(np.mean(z * z)) <= 1.7, z
    assert exact[0].mean() < exact[-1].mean()   # top row first: the far plane, darker, is at the top


def emitter_sim(between=None, floor=None, emitter_size=4.0):
    """A Lambertian emitter of exitance `M_EXIT` at z = 2 facing down (black behind), and optionally a mirror or a
    pane below it (`between`: (mesh, material)) or a floor (`floor`: material)."""
    e = emitter_size
    meshes = [quad([-e / 2, e / 2, 2.0], [e, 0, 0], [0, -e, 0])]   # e1 × e2 = −z: its front faces down
    mats = [{"type": "black"}]
    for extra in (between, (quad([-50, -50, 0], [100, 0, 0], [0, 100, 0]), floor) if floor else None):
        if extra is not None:
            meshes.append(extra[0])
            mats.append(extra[1])
    s, ids = scene_of(*meshes)
    light = {"type": "area", "instances": [ids[0]], "exitance_lm_m2": M_EXIT}
    return Simulation(s, dict(zip(ids, mats, strict=True)), [light])


UP_METER = {"type": "luminance", "position": [0.1, 0.0, 1.0], "direction": [0, 0, 1], "aperture_deg": 1.0}


def test_area_light_seen_directly_reads_its_exitance_over_pi():
    """An emitter of flux Φ over area A reads Φ/(πA) = M/π."""
    r = emitter_sim().run(UP_METER, max_photons=20_000, seed=3)
    assert abs(r.luminance - M_EXIT / math.pi) <= Z * r.stderr + 1e-9 * M_EXIT, (r.luminance, r.stderr)
    assert r.unreachable is None


def test_mirror_shows_r_times_the_mirrored_view():
    """Looking down at a mirror of reflectance r under the emitter reads r M/π, and r × the meter that looks up
    from the same point (the mirrored view), within 4 combined σ."""
    r_m = 0.8
    sim = emitter_sim(between=(quad([-5, -5, 0], [10, 0, 0], [0, 10, 0]), {"type": "mirror", "reflectance": r_m}))
    down = sim.run({**UP_METER, "direction": [0, 0, -1]}, max_photons=40_000, seed=4)
    up = sim.run(UP_METER, max_photons=20_000, seed=5)
    assert abs(down.luminance - r_m * M_EXIT / math.pi) <= Z * down.stderr, (down.luminance, down.stderr)
    assert abs(down.luminance - r_m * up.luminance) <= Z * math.hypot(down.stderr, r_m * up.stderr)
    assert down.through_specular == 1.0 and down.unreachable is None


def test_clear_pane_transmits_one_minus_r_over_one_plus_r():
    """Through a pane of n = 1.5 at normal incidence (R = 0.04): (1 − R)²/(1 − R²) = (1 − R)/(1 + R) of M/π."""
    pane = box([-3, -3, 1.4], [3, 3, 1.45])
    sim = emitter_sim(between=(pane, {"type": "dielectric", "ior": 1.5}))
    r = sim.run(UP_METER, max_photons=60_000, seed=6)
    big_r = 0.04
    exact = (1 - big_r) / (1 + big_r) * M_EXIT / math.pi
    assert "fresnel" in r.effects
    assert abs(r.luminance - exact) <= Z * r.stderr, (r.luminance, r.stderr, exact)


def rectangle_corner_e(m, a, b, h):
    """Illuminance under a corner of a parallel Lambertian rectangle a × b of exitance m at height h."""
    pa, pb = math.hypot(a, h), math.hypot(b, h)
    return m / (2 * math.pi) * (a / pa * math.atan(b / pa) + b / pb * math.atan(a / pb))


def test_plane_under_an_area_light_reads_rho_e_over_pi_with_mis():
    """A floor of ρ under a 1 m square emitter 2 m up: the meter at the centre reads ρE/π with E = 4 × the corner
    illuminance of a 0.5 × 0.5 m rectangle. Light sampling and BSDF hits on the emitter are both weighted: a wrong
    weight moves this reading. The 1° cone sees a 1.7 cm spot, where E varies by < 1e-4."""
    sim = emitter_sim(floor={"type": "lambertian", "reflectance": RHO}, emitter_size=1.0)
    r = sim.run({"type": "luminance", "position": [0, 0, 1.0], "direction": [0, 0, -1], "aperture_deg": 1.0},
                max_photons=80_000, seed=7)
    exact = RHO / math.pi * 4 * rectangle_corner_e(M_EXIT, 0.5, 0.5, 2.0)
    assert abs(r.luminance - exact) <= Z * r.stderr + 1e-4 * exact, (r.luminance, r.stderr, exact)


def test_an_led_box_emits_from_its_chosen_face_only():
    """An area light on a 1 × 1 × 0.2 m box with ``facing`` down: the floor 1.5 m off its axis reads ρE/π with E
    from the bottom face alone (E = 2 × (corner(2.0, 0.5) − corner(1.0, 0.5)) at h = 2; the box's +x side, which
    that point sees, must not glow; E's curvature over the 1° spot moves it by < 1e-5), and meters see M/π on the
    bottom face and 0 on the side."""
    s, ids = scene_of(box([-0.5, -0.5, 2.0], [0.5, 0.5, 2.2]), quad([-50, -50, 0], [100, 0, 0], [0, 100, 0]))
    light = {"type": "area", "instances": [ids[0]], "exitance_lm_m2": M_EXIT, "facing": [0, 0, -1]}
    sim = Simulation(s, {ids[0]: {"type": "black"}, ids[1]: {"type": "lambertian", "reflectance": RHO}}, [light])
    r = sim.run({"type": "luminance", "position": [1.5, 0, 1.0], "direction": [0, 0, -1], "aperture_deg": 1.0},
                max_photons=80_000, seed=8)
    e = 2 * (rectangle_corner_e(M_EXIT, 2.0, 0.5, 2.0) - rectangle_corner_e(M_EXIT, 1.0, 0.5, 2.0))
    exact = RHO / math.pi * e
    assert abs(r.luminance - exact) <= Z * r.stderr + 1e-4 * exact, (r.luminance, r.stderr, exact)
    bottom = sim.run(UP_METER, max_photons=4_000, seed=9)
    side = sim.run({"type": "luminance", "position": [1.5, 0.0, 2.1], "direction": [-1, 0, 0], "aperture_deg": 1.0},
                   max_photons=4_000, seed=9)
    assert bottom.luminance == pytest.approx(M_EXIT / math.pi) and side.luminance == 0.0


def test_point_source_seen_in_a_mirror_is_unreachable():
    """A meter looking into a mirror toward a point source: paths from the eye cannot find it; the answer says so
    (`unreachable`) rather than a silent 0."""
    s, ids = scene_of(quad([-5, -5, 0], [10, 0, 0], [0, 10, 0]))
    sim = Simulation(s, {ids[0]: {"type": "mirror", "reflectance": 0.9}},
                     [{"type": "point", "position": [0, 0, 2.0], "intensity_cd": 100.0}])
    r = sim.run({"type": "luminance", "position": [0, 0, 1.0], "direction": [0, 0, -1], "aperture_deg": 1.0},
                max_photons=4000, seed=8)
    assert r.luminance == 0.0
    assert r.unreachable is not None and r.unreachable["lights"] == [0] and r.unreachable["through_specular"] == 1.0
    assert "mirror" in r.unreachable["why"]


def test_point_source_in_view_reads_its_illuminance_over_the_cone():
    """A bare point source inside the meter's cone: the mean luminance over the cone is E⊥/Ω = I/(d² Ω)."""
    sim = plane_sim()
    eye = LIGHT_AT - np.array([0.0, 0.0, 1.0])
    r = sim.run({"type": "luminance", "position": eye.tolist(), "direction": [0, 0, 1], "aperture_deg": 10.0},
                max_photons=4000, seed=9)
    omega = 2 * math.pi * (1 - math.cos(math.radians(5.0)))
    assert r.luminance == pytest.approx(I_CD / 1.0 / omega, rel=1e-9)
    assert r.stderr <= 1e-6 * r.luminance   # the same value every batch: σ is rounding (Σx² − b m² cancels)


def test_the_forward_estimator_and_media_are_refused():
    sim = plane_sim()
    with pytest.raises(SimulationError, match="estimator must be 'auto' or 'backward'"):
        sim.run(UP_METER, max_photons=1000, estimator="forward")
    s, ids = scene_of(box([-1, -1, 0], [1, 1, 1]))
    murky = Simulation(s, {ids[0]: {"type": "dielectric", "ior": 1.5, "absorption_per_m": 2.0}},
                       [{"type": "point", "position": [0, 0, 3.0], "intensity_cd": 10.0}])
    with pytest.raises(SimulationError, match="absorption"):
        murky.run(UP_METER, max_photons=1000)


METER = {"type": "luminance", "position": [0, 0, 1], "direction": [0, 0, -1], "aperture_deg": 1.0}
CAMERA = {"type": "camera", "position": [0, -2, 1], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_deg": 40,
          "width": 4, "height": 3}


@pytest.mark.parametrize("body, message", [
    ({**METER, "position": None}, "position must be 3 finite numbers"),
    ({**METER, "position": [0, 0]}, "position must be 3 finite numbers"),
    ({**METER, "position": [0, 0, math.inf]}, "position must be 3 finite numbers"),
    ({**METER, "direction": [0, 0, 0]}, "direction must not be the zero vector"),
    ({**METER, "direction": "down"}, "direction must be 3"),
    ({**METER, "aperture_deg": 0}, "aperture_deg must be"),
    ({**METER, "aperture_deg": 181}, "aperture_deg must be"),
    ({**METER, "aperture_deg": True}, "aperture_deg must be"),
    ({**METER, "aperture_deg": "1"}, "aperture_deg must be"),
    ({**METER, "radius": 1}, r"unknown field\(s\) \['radius'\]"),
    ({**CAMERA, "position": "here"}, "position must be 3"),
    ({**CAMERA, "look_at": [0, -2, 1]}, "look_at − position must not be the zero vector"),
    ({**CAMERA, "look_at": [1, 2]}, "look_at must be 3"),
    ({**CAMERA, "up": [0, 0, 0]}, "up must not be the zero vector"),
    ({**CAMERA, "up": [0, 2, -1]}, "up must not lie along the view"),
    ({**CAMERA, "fov_deg": 0}, "fov_deg must be"),
    ({**CAMERA, "fov_deg": 180}, "fov_deg must be"),
    ({**CAMERA, "fov_deg": None}, "fov_deg must be"),
    ({**CAMERA, "width": 0}, "width must be an integer"),
    ({**CAMERA, "width": 2.5}, "width must be an integer"),
    ({**CAMERA, "width": True}, "width must be an integer"),
    ({**CAMERA, "height": 5000}, "height must be an integer"),
    ({**CAMERA, "height": None}, "height must be an integer"),
    ({**CAMERA, "aperture_deg": 1}, r"unknown field\(s\) \['aperture_deg'\]"),
])
def test_bad_fields_are_refused_naming_them(body, message):
    with pytest.raises(SimulationError, match=message):
        plane_sim().run(body, max_photons=1000)
