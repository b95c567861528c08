"""`tracer.simulate.Simulation` as the service uses it: answers, stop rules, determinism, refusals."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from tests.tracer.transport_scenes import box, point_source_e, quad, scene_of
from tracer.optics.lights import LightError
from tracer.optics.surfaces.base import MaterialError
from tracer.simulate import GridResult, IlluminanceResult, Simulation, SimulationError

LAMP = {"type": "point", "position": [1.5, 1.0, 2.2], "flux_lm": 3000.0}
WALLS = {"type": "lambertian", "reflectance": 0.6}


@pytest.fixture(scope="module")
def room():
    s, (r,) = scene_of(box((0, 0, 0), (3, 2, 2.5)))
    return s, r


def test_result_fields_and_sensors_removed_afterwards(room):
    s, r = room
    before = list(s.instances())
    sim = Simulation(s, {r: WALLS}, [LAMP])
    assert sim.effects == ["lambertian"]
    res = sim.illuminance([[1.0, 1.0, 0.0]], [[0, 0, 1.0]], max_photons=20_000, estimator="forward")
    assert isinstance(res, IlluminanceResult)
    assert res.lux.shape == (1,) and res.stderr.shape == (1,) and res.photons <= 20_000
    assert res.estimator == "forward" and res.effects == ["lambertian"] and res.stop_reason == "max_photons"
    assert res.seconds > 0 and res.rejected == 0
    assert list(s.instances()) == before and not s.dirty


def test_same_seed_is_bit_identical_whatever_the_thread_count(room):
    s, r = room
    sim = Simulation(s, {r: WALLS}, [LAMP])
    pts, nrm = [[1.0, 1.0, 0.0], [2.0, 0.5, 0.0]], [[0, 0, 1.0], [0, 0, 1.0]]
    out = {}
    threads = numba.get_num_threads()
    try:
        for n in sorted({1, threads}):
            numba.set_num_threads(n)
            for est in ("forward", "backward"):
                res = sim.illuminance(pts, nrm, max_photons=64_000, seed=42, estimator=est)
                out.setdefault(est, []).append((res.lux.copy(), res.stderr.copy()))
    finally:
        numba.set_num_threads(threads)
    for est, runs in out.items():
        for lux, sd in runs[1:]:
            np.testing.assert_array_equal(lux, runs[0][0], err_msg=est)
            np.testing.assert_array_equal(sd, runs[0][1], err_msg=est)
    again = sim.illuminance(pts, nrm, max_photons=64_000, seed=42, estimator="forward")
    np.testing.assert_array_equal(again.lux, out["forward"][0][0])
    other = sim.illuminance(pts, nrm, max_photons=64_000, seed=43, estimator="forward")
    assert not np.array_equal(other.lux, again.lux)


def test_forcing_effects_a_scene_does_not_need_changes_nothing(room):
    """The media and Fresnel code draws no random numbers where no solid is entered: same paths, same bits."""
    s, r = room
    sim = Simulation(s, {r: WALLS}, [LAMP])
    pts, nrm = [[1.0, 1.0, 0.0]], [[0, 0, 1.0]]
    plain = sim.illuminance(pts, nrm, max_photons=40_000, seed=3, estimator="forward")
    forced = sim.illuminance(pts, nrm, max_photons=40_000, seed=3, estimator="forward",
                             force_effects=("specular", "fresnel", "absorption", "scattering"))
    assert forced.effects == ["lambertian", "specular", "fresnel", "absorption", "scattering"]
    np.testing.assert_array_equal(plain.lux, forced.lux)


def test_target_error_stop_and_progress(room):
    s, r = room
    sim = Simulation(s, {r: WALLS}, [LAMP])
    calls = []
    res = sim.illuminance([[1.0, 1.0, 0.0], [0.3, 1.7, 0.0]], [[0, 0, 1.0]] * 2, target_relative_error=0.02,
                          max_seconds=60, seed=1, progress=lambda *a: calls.append(a))
    assert res.estimator == "backward" and res.stop_reason == "target_relative_error"
    assert np.all(res.stderr <= 0.02 * res.lux)
    assert calls and calls[-1][0] == res.photons and calls[-1][1] <= 0.02
    assert calls[0][0] == 0 and calls[0][2] >= res.compile_seconds   # the report before the first round
    assert all(b[0] > a[0] for a, b in zip(calls, calls[1:], strict=False))


def test_cancel_and_time_budget(room):
    s, r = room
    sim = Simulation(s, {r: WALLS}, [LAMP])
    res = sim.illuminance([[1.0, 1.0, 0.0]], [[0, 0, 1.0]], target_relative_error=1e-6, max_seconds=30,
                          cancel=lambda: True, estimator="forward")
    assert res.stop_reason == "cancelled" and res.photons > 0
    res = sim.illuminance([[1.0, 1.0, 0.0]], [[0, 0, 1.0]], max_seconds=0.2, estimator="forward")
    assert res.stop_reason == "max_seconds"


def test_grid_estimators_agree_and_shape(room):
    s, r = room
    sim = Simulation(s, {r: WALLS}, [LAMP])
    args = ([0.5, 0.5, 0.0], [2.0, 0, 0], [0, 1.0, 0], 4, 2)
    f = sim.grid(*args, target_relative_error=0.05, max_photons=4_000_000, seed=5)
    b = sim.grid(*args, target_relative_error=0.01, max_photons=400_000, seed=5, estimator="backward")
    assert isinstance(f, GridResult) and f.lux.shape == (2, 4) and f.estimator == "forward"
    assert b.estimator == "backward" and b.lux.shape == (2, 4)
    z = np.abs(f.lux - b.lux) / np.hypot(f.stderr, b.stderr)
    assert np.all(z < 4.0), (f.lux, b.lux)


def test_spot_and_goniometric_sources_by_both_estimators():
    from pathlib import Path

    s, (floor,) = scene_of(quad((-30, -30, 0), (60, 0, 0), (0, 60, 0)))
    ies = (Path(__file__).resolve().parents[2] / "fixtures" / "photometry" / "rab_dled6r8y_7.ies").read_text()
    lights = [{"type": "spot", "position": [0, 0, 2], "direction": [0, 0, -1], "cone_deg": 30, "falloff_deg": 10,
               "intensity_cd": 500.0},
              {"type": "goniometric", "position": [1, 0, 2], "format": "ies", "data": ies}]
    sim = Simulation(s, {floor: {"type": "black"}}, lights)
    pts = np.array([[0, 0, 0.0], [0.8, 0.3, 0], [1.0, 0, 0]])
    nrm = np.tile([0, 0, 1.0], (3, 1))
    b = sim.illuminance(pts, nrm, radius=0.2, target_relative_error=0.005, max_photons=200_000, seed=2)
    f = sim.illuminance(pts, nrm, radius=0.2, target_relative_error=0.05, max_photons=4_000_000, seed=2,
                        estimator="forward")
    z = np.abs(f.lux - b.lux) / np.hypot(f.stderr, b.stderr)
    assert np.all(z < 4.0), (f.lux, b.lux)
    # directly under the spot, inside its full-intensity cone, the goniometric light at γ = 26.6°
    from tracer.photometry.files import parse_photometry
    p = parse_photometry("ies", ies)
    gamma = math.degrees(math.atan2(1.0, 2.0))
    gon = float(p.intensity(180.0, gamma)) * math.cos(math.radians(gamma)) / 5.0
    ref0 = 500.0 / 4.0 + gon
    assert b.lux[0] == pytest.approx(ref0, rel=0.02)   # a disk average: within the curvature over 0.2 m


def test_backward_is_refused_where_it_cannot_see_the_light(room):
    s, r = room
    mirror = Simulation(s, {r: {"type": "mirror", "reflectance": 0.9}}, [LAMP])
    assert mirror.effects == ["lambertian", "specular"]
    with pytest.raises(SimulationError, match="backward estimator cannot answer here"):
        mirror.illuminance([[1, 1, 0.0]], [[0, 0, 1.0]], max_photons=1000, estimator="backward")
    every = ("specular", "fresnel", "absorption", "scattering")   # the variant the optics tests compile anyway
    assert mirror.illuminance([[1, 1, 0.0]], [[0, 0, 1.0]], max_photons=1000, force_effects=every).estimator == \
        "forward"
    beam = Simulation(s, {r: WALLS}, [{"type": "collimated", "origin": [1, 1, 2], "direction": [0, 0, -1],
                                       "radius": 0.1, "illuminance_lx": 100}])
    with pytest.raises(SimulationError, match="collimated"):
        beam.illuminance([[1, 1, 0.0]], [[0, 0, 1.0]], max_photons=1000, estimator="backward")
    with pytest.raises(SimulationError, match="backward estimator"):
        Simulation(s, {r: WALLS}, [LAMP]).illuminance([[1, 1, 0.0]], [[0, 0, 1.0]], max_photons=1000,
                                                      estimator="backward", force_effects=("fresnel",))


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"points": [[0, 0]], "normals": [[0, 0, 1]]}, "shape \\(k, 3\\)"),
    ({"points": [[0, 0, np.nan]], "normals": [[0, 0, 1]]}, "finite"),
    ({"points": np.zeros((0, 3)), "normals": np.zeros((0, 3))}, "at least one point"),
    ({"points": [[1, 1, 0]], "normals": [[0, 0, 0]]}, "zero vector"),
    ({"points": [[1, 1, 0]], "normals": [[0, 0, 1], [0, 0, 1]]}, "has 2 rows, expected 1"),
    ({"radius": -1.0}, "radius must be a positive"),
    ({"target_relative_error": 1.5}, "target_relative_error must be in"),
    ({"max_seconds": 0}, "max_seconds must be > 0"),
    ({"max_photons": 0}, "max_photons must be a positive integer"),
    ({"max_photons": 2.5}, "max_photons must be a positive integer"),
    ({"seed": -1}, "seed must be an integer"),
    ({"estimator": "psychic"}, "estimator must be one of"),
    ({"force_effects": ("birefringence",)}, "unknown effect"),
])
def test_bad_queries_are_rejected(room, kwargs, match):
    s, r = room
    sim = Simulation(s, {r: WALLS}, [LAMP])
    call = {"points": [[1, 1, 0]], "normals": [[0, 0, 1]], "max_photons": 1000}
    call.update(kwargs)
    with pytest.raises(SimulationError, match=match):
        sim.illuminance(**call)
    assert issubclass(SimulationError, ValueError)


def test_bad_grids_and_bodies_are_rejected(room):
    s, r = room
    sim = Simulation(s, {r: WALLS}, [LAMP])
    with pytest.raises(SimulationError, match="not parallel"):
        sim.grid([0, 0, 0], [1, 0, 0], [2, 0, 0], 2, 2, max_photons=100)
    with pytest.raises(SimulationError, match="nu must be an integer"):
        sim.grid([0, 0, 0], [1, 0, 0], [0, 1, 0], 0, 2, max_photons=100)
    with pytest.raises(MaterialError, match="no material"):
        Simulation(s, {}, [LAMP])
    assert Simulation(s, {}, [LAMP], default_material={"type": "black"}).effects == ["lambertian"]
    with pytest.raises(LightError, match="instance 99 is not in the scene"):
        Simulation(s, {r: WALLS}, [{"type": "area", "instances": [99], "exitance_lm_m2": 10}])
    with pytest.raises(LightError, match="at least one light"):
        Simulation(s, {r: WALLS}, [])
    with pytest.raises(SimulationError, match="tracer.Scene"):
        Simulation(None, {}, [LAMP])
    # a service-side body: id and name are carried along, not rejected
    Simulation(s, {r: WALLS}, [dict(LAMP, id="abc", name="lamp")])


def test_direct_light_on_the_floor_of_a_black_room_matches_the_closed_form():
    s, (r,) = scene_of(box((0, 0, 0), (3, 2, 2.5)))
    sim = Simulation(s, {r: {"type": "black"}}, [LAMP])
    res = sim.illuminance([[1.5, 1.0, 0.0]], [[0, 0, 1.0]], radius=0.01, max_photons=10_000)
    ref = point_source_e(3000.0 / (4 * math.pi), LAMP["position"], [0, 0, 1])(np.array([[1.5, 1.0, 0.0]]))[0]
    assert res.lux[0] == pytest.approx(ref, rel=1e-4)


def test_concurrent_queries_from_threads_give_the_sequential_answers():
    """The service runs queries in threads: two simulations at once must neither crash nor change bits."""
    import threading

    sims = []
    for _ in range(2):
        s, (r,) = scene_of(box((0, 0, 0), (3, 2, 2.5)))
        sims.append(Simulation(s, {r: WALLS}, [LAMP]))
    args = ([[1.0, 1.0, 0.0]], [[0, 0, 1.0]])
    want = [sim.illuminance(*args, max_photons=40_000, seed=9, estimator=e).lux
            for sim, e in zip(sims, ("forward", "backward"), strict=True)]
    got: dict[int, np.ndarray] = {}

    def run(i, est):
        got[i] = sims[i].illuminance(*args, max_photons=40_000, seed=9, estimator=est).lux

    threads = [threading.Thread(target=run, args=(i, e)) for i, e in enumerate(("forward", "backward"))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i in range(2):
        np.testing.assert_array_equal(got[i], want[i])


def test_goniometric_axes_turn_the_distribution():
    """γ = 0 along `direction`, C = 0 along `c0`: on a wall the light faces, E = I(C, γ) cos³γ / d²."""
    from pathlib import Path

    from tracer.photometry.files import parse_photometry

    ies = (Path(__file__).resolve().parents[2] / "fixtures" / "photometry" / "rab_boa2_5.ies").read_text()
    table = parse_photometry("ies", ies)
    s, (wall,) = scene_of(quad((2, -30, -30), (0, 0, 60), (0, 60, 0)))   # the plane x = 2, facing -x
    light = {"type": "goniometric", "position": [0, 0, 0], "format": "ies", "data": ies,
             "direction": [1, 0, 0], "c0": [0, 0, 1]}                    # C = 90° then lies along +y
    h = 2.0 * math.tan(math.radians(60.0))
    # (C, γ) = (any, 0), (0, 60), (90, 60), (180, 60)
    pts = np.array([[2, 0, 0], [2, 0, h], [2, h, 0], [2, 0, -h]], float)
    radius = 0.02

    def disk_mean_lux(p):
        """E = I(C, γ) cosθ / r² averaged over the receiver disk (midpoint rule in r², φ)."""
        r = radius * np.sqrt((np.arange(40) + 0.5) / 40)
        phi = 2 * np.pi * (np.arange(64) + 0.5) / 64
        r, phi = (a.ravel() for a in np.meshgrid(r, phi))
        q = p + np.stack([np.zeros_like(r), r * np.cos(phi), r * np.sin(phi)], axis=1)
        dist = np.linalg.norm(q, axis=1)
        d = q / dist[:, None]
        gamma = np.degrees(np.arccos(np.clip(d[:, 0], -1, 1)))
        c = np.degrees(np.arctan2(d[:, 1], d[:, 2])) % 360.0
        inten = np.array([float(table.intensity(ci, gi)) for ci, gi in zip(c, gamma, strict=True)])
        return float(np.mean(inten * d[:, 0] / dist**2))

    ref = np.array([disk_mean_lux(p) for p in pts])
    res = Simulation(s, {wall: {"type": "black"}}, [light]).illuminance(
        pts, np.tile([-1.0, 0, 0], (4, 1)), radius=radius, target_relative_error=0.003, max_photons=400_000, seed=5)
    assert np.all(np.abs(res.lux - ref) < 4 * res.stderr), (res.lux, ref, res.stderr)
    # the C = 0 and C = 90° planes of this luminaire differ by 4-5 % at γ = 60°: the test sees the turn
    assert abs(ref[1] - ref[2]) > 8 * max(res.stderr[1], res.stderr[2])


def test_goniometric_axes_must_not_be_parallel():
    from pathlib import Path

    ies = (Path(__file__).resolve().parents[2] / "fixtures" / "photometry" / "rab_boa2_5.ies").read_text()
    s, (floor,) = scene_of(quad((-1, -1, 0), (2, 0, 0), (0, 2, 0)))
    with pytest.raises(LightError, match="'c0' must not be parallel"):
        Simulation(s, {floor: {"type": "black"}}, [{"type": "goniometric", "position": [0, 0, 1], "format": "ies",
                                                     "data": ies, "direction": [0, 0, -1], "c0": [0, 0, 2]}])
