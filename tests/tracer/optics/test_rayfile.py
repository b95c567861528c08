"""The `rayfile` light (issue 38): a ray file written from a known Lambertian emitter gives the illuminance the `area`
light gives for the same emitter, in the near field and the far field, within the combined error bars.

The emitter: a 2 mm × 2 mm square in z = 0, front +z, flux 1 lm. The file: N rays from uniform points of the square,
cosine-distributed directions, flux 1/N each (numpy, seeded), written in the kind's text columns (mm). The file is a
sample itself: its own value at a receiver (the flux of its rays that cross the receiver disk, over the disk's area,
computed exactly here by ray-disk intersection) differs from the emitter's by its sampling error, binomial:
√k / N / area for k rays through the disk. The tracer's answer from the file must equal the file's own value within
4σ of its Monte Carlo error (the file is replayed, not resampled), and the file's value equals the area light's
answer within 4 √(σ_file² + σ_area²).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.optics.lights import LightError, pack_lights
from tracer.scene import Scene
from tracer.simulate import Simulation, SimulationError

A = 1e-3            # half side of the emitter, m
N_RAYS = 100_000


def lambertian_rays(n: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    p = rng.uniform(-A, A, (n, 2))
    u1, u2 = rng.random(n), rng.random(n)
    r, phi = np.sqrt(u1), 2 * math.pi * u2
    d = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1)])
    return np.column_stack([p * 1e3, np.zeros(n), d, np.full(n, 1.0 / n)])   # start points in mm


def as_text(rays: np.ndarray) -> str:
    return "# x y z (mm) l m n flux (lm)\n" + "\n".join(" ".join(f"{v:.9g}" for v in r) for r in rays)


def file_value(rays: np.ndarray, h: float, radius: float) -> tuple[float, float]:
    """(lx, its standard error) the file's rays give on a disk of `radius` at height h facing down."""
    o, d = rays[:, :3] * 1e-3, rays[:, 3:6]
    t = (h - o[:, 2]) / d[:, 2]
    x = o[:, :2] + t[:, None] * d[:, :2]
    hit = (t > 0) & (np.hypot(x[:, 0], x[:, 1]) <= radius)
    area = math.pi * radius ** 2
    return float(rays[hit, 6].sum() / area), float(math.sqrt(hit.sum()) / len(rays) / area)


@pytest.fixture(scope="module")
def setup():
    s = Scene()
    v = np.array([[-A, -A, 0], [A, -A, 0], [A, A, 0], [-A, A, 0]], float)
    emitter = s.add_instance(s.add_geometry(v, np.array([[0, 1, 2], [0, 2, 3]])), np.eye(4))
    s.commit()
    rays = lambertian_rays(N_RAYS)
    ray_light = {"type": "rayfile", "position": [0.0, 0.0, 0.0], "units": "mm", "data": as_text(rays)}
    area_light = {"type": "area", "instances": [emitter], "exitance_lm_m2": 1.0 / (2 * A) ** 2}
    black = {"type": "black"}
    return (Simulation(s, {emitter: black}, [ray_light]), Simulation(s, {emitter: black}, [area_light]), rays)


@pytest.mark.parametrize(("h", "radius"), [(3e-3, 1e-3), (0.5, 0.1)], ids=["near field", "far field"])
def test_a_lambertian_ray_file_gives_the_area_lights_illuminance(setup, h, radius):
    ray_sim, area_sim, rays = setup
    q = {"radius": radius, "max_photons": 200_000, "seed": 3, "estimator": "forward"}
    got = ray_sim.illuminance([[0, 0, h]], [[0, 0, -1]], **q)
    ref = area_sim.illuminance([[0, 0, h]], [[0, 0, -1]], **q)
    own, own_err = file_value(rays, h, radius)
    assert abs(got.lux[0] - own) <= 4 * got.stderr[0], (got.lux, got.stderr, own)
    assert abs(own - ref.lux[0]) <= 4 * math.hypot(own_err, ref.stderr[0]), (own, own_err, ref.lux, ref.stderr)
    if h > 0.1:   # far away, the square is a point: I(0) = Φ/π, E = I / h²
        assert abs(ref.lux[0] - 1 / math.pi / h ** 2) <= 0.02 / math.pi / h ** 2 + 4 * ref.stderr[0]


def test_flux_lm_scales_the_file_and_the_frame_turns_it():
    rays = np.array([[0, 0, 0, 0, 0, 1, 2.0], [1, 0, 0, 0, 0, 2, 6.0]])
    body = {"type": "rayfile", "position": [1.0, 2.0, 3.0], "data": as_text(rays), "direction": [1, 0, 0],
            "c0": [0, 1, 0]}
    L = pack_lights([body])
    assert L.flux_total[0] == pytest.approx(8.0)
    np.testing.assert_allclose(L.tri[:, :6], [[1, 2, 3, 1, 0, 0], [1, 2.001, 3, 1, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(L.tri_cdf, [0.25, 1.0])
    assert pack_lights([{**body, "flux_lm": 100.0}]).flux_total[0] == pytest.approx(100.0)


def test_the_backward_estimator_is_refused_with_the_reason(setup):
    ray_sim, _, _ = setup
    with pytest.raises(SimulationError, match="rayfile"):
        ray_sim.illuminance([[0, 0, 0.5]], [[0, 0, -1]], max_photons=1000, estimator="backward")
    assert ray_sim.illuminance([[0, 0, 0.5]], [[0, 0, -1]], max_photons=1000).estimator == "forward"


@pytest.mark.parametrize(("patch", "match"), [
    ({"data": ""}, "'data'"), ({"data": "0 0 0 0 0 1"}, "7 numbers"), ({"data": "0 0 0 0 0 0 1"}, "zero direction"),
    ({"data": "0 0 0 0 0 1 -1"}, "negative flux"), ({"data": "0 0 0 0 0 1 0"}, "no flux"),
    ({"data": "0 0 0 x 0 1 1"}, "'data'"), ({"data": "0 0 0 0 0 1 nan"}, "not finite"),
    ({"units": "inch"}, "'units'"), ({"flux_lm": -1.0}, "'flux_lm'"), ({"c0": [0, 0, 1]}, "'c0'"),
    ({"colour": 1}, "unknown field")])
def test_bad_ray_files_name_the_field(patch, match):
    body = {"type": "rayfile", "position": [0.0, 0.0, 0.0], "data": "0 0 0 0 0 1 1", "direction": [0, 0, 1], **patch}
    with pytest.raises(LightError, match=match):
        pack_lights([body])
