"""Light transport against closed forms (issue 6 "Validation").

Each test fails if the reference lies outside 4 standard errors of the estimate, or if the error bar
is larger than the query asked for. References are patch averages (the receivers are disks), computed
by quadrature of the closed-form point value.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.tracer.transport_scenes import (
    box,
    disk_average,
    icosphere,
    mesh_area,
    outward,
    point_source_e,
    polygon_form_factor,
    quad,
    scene_of,
)
from tracer.simulate import Simulation

BLACK = {"type": "black"}
GLASS_EFFECTS = ("specular", "fresnel", "absorption", "scattering")   # one compiled variant for every optics test


def check(res, ref, target=None):
    ref = np.asarray(ref, float)
    z = np.abs(res.lux - ref) / np.maximum(res.stderr, 1e-300)
    assert np.all(np.isfinite(res.lux)) and res.rejected == 0
    assert np.all(z < 4.0), f"lux {res.lux} vs reference {ref}, stderr {res.stderr}"
    if target is not None and res.stop_reason == "target_relative_error":
        assert np.all(res.stderr <= target * np.abs(res.lux) + 1e-12)


def floor_scene(transform=None):
    return scene_of(quad((-60, -60, 0), (120, 0, 0), (0, 120, 0)), transform=transform)


@pytest.mark.parametrize("estimator", ["forward", "backward"])
def test_inverse_square_cosine_law_over_a_black_plane(estimator):
    s, (floor,) = floor_scene()
    sim = Simulation(s, {floor: BLACK}, [{"type": "point", "position": [0, 0, 2], "intensity_cd": 1000.0}])
    xs = [0.0, 1.0, 2.0, 4.0]
    pts = np.array([[x, 0, 0] for x in xs])
    nrm = np.tile([0, 0, 1.0], (len(xs), 1))
    r = 0.25
    res = sim.illuminance(pts, nrm, radius=r, target_relative_error=0.08, max_photons=4_000_000, seed=1,
                          estimator=estimator)
    ref = [disk_average(point_source_e(1000.0, [0, 0, 2], [0, 0, 1]), p, [0, 0, 1], r) for p in pts]
    check(res, ref, 0.08)
    assert res.stop_reason == "target_relative_error" and res.estimator == estimator
    # the receiver lies on the floor: it counts the light arriving at the floor (not zero, not doubled)
    assert res.lux[0] == pytest.approx(250.0, rel=0.3)


def test_grazing_incidence_and_far_from_origin():
    """A source 5 cm above the floor seen from 3 m (cosθ ≈ 0.017); the same scene moved 1e5 m away."""
    for offset in (np.zeros(3), np.array([1e5, -1e5, 0.0])):
        T = np.eye(4)
        T[:3, 3] = offset
        s, (floor,) = floor_scene(T)
        src = offset + [0, 0, 0.05]
        sim = Simulation(s, {floor: BLACK}, [{"type": "point", "position": list(src), "intensity_cd": 1000.0}])
        pts = offset + np.array([[3.0, 0, 0], [0.5, 0.2, 0]])
        res = sim.illuminance(pts, np.tile([0, 0, 1.0], (2, 1)), radius=0.01, target_relative_error=0.01,
                              max_photons=2_000_000, seed=2, estimator="backward")
        ref = [disk_average(point_source_e(1000.0, src, [0, 0, 1]), p, [0, 0, 1], 0.01) for p in pts]
        check(res, ref, 0.01)


def test_far_from_origin_forward_matches_the_origin():
    out = []
    for offset in (np.zeros(3), np.array([1e5, 1e5, 1e5])):
        T = np.eye(4)
        T[:3, 3] = offset
        s, (floor,) = floor_scene(T)
        sim = Simulation(s, {floor: BLACK}, [{"type": "point", "position": list(offset + [0, 0, 1.0]),
                                              "intensity_cd": 100.0}])
        res = sim.illuminance(offset + np.array([[0.3, 0, 0]]), [[0, 0, 1.0]], radius=0.2, max_photons=400_000,
                              seed=3, estimator="forward")
        ref = disk_average(point_source_e(100.0, offset + [0, 0, 1.0], [0, 0, 1]), offset + [0.3, 0, 0],
                           [0, 0, 1], 0.2)
        check(res, [ref])
        out.append(res.lux[0])
    assert out[0] == pytest.approx(out[1], rel=0.1)


@pytest.mark.parametrize("estimator", ["forward", "backward"])
def test_rectangular_lambertian_emitter_parallel_and_perpendicular(estimator):
    # emitter 1 m × 0.5 m at z = 1.5, emitting downwards; black floor
    emitter = quad((-0.5, -0.25, 1.5), (0, 0.5, 0), (1, 0, 0))
    s, (floor, lamp) = scene_of(quad((-60, -60, 0), (120, 0, 0), (0, 120, 0)), emitter)
    m = 1000.0
    sim = Simulation(s, {floor: BLACK, lamp: BLACK}, [{"type": "area", "instances": [lamp], "exitance_lm_m2": m}])
    poly = emitter[0]
    pts = np.array([[0, 0, 0], [0.8, 0.3, 0], [1.0, 0.0, 0.5]])
    nrm = np.array([[0, 0, 1.0], [0, 0, 1.0], [-1.0, 0, 0]])
    r = 0.1
    res = sim.illuminance(pts, nrm, radius=r, target_relative_error=0.05, max_photons=6_000_000, seed=4,
                          estimator=estimator)

    def e(p, n):
        return disk_average(lambda q: np.array([m * polygon_form_factor(x, n, poly) for x in q]), p, n, r,
                            n_r=8, n_phi=16)

    ref = [e(p, n) for p, n in zip(pts, nrm, strict=True)]
    assert ref[0] == pytest.approx(m * polygon_form_factor([0, 0, 0], [0, 0, 1], poly), rel=0.01)
    check(res, ref, 0.05)


@pytest.mark.parametrize("estimator", ["forward", "backward"])
def test_integrating_sphere(estimator):
    """Wall illuminance = direct + ρΦ/(A(1−ρ)), A the tessellated area; receivers at facet centres."""
    v, t = icosphere(1.0, 2)
    s, (sphere,) = scene_of((v, t))
    rho, flux = 0.5, 1000.0
    sim = Simulation(s, {sphere: {"type": "lambertian", "reflectance": rho}},
                     [{"type": "point", "position": [0, 0, 0], "flux_lm": 1000.0}])
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    cross = np.cross(b - a, c - a)
    perimeter = sum(np.linalg.norm(x - y, axis=1) for x, y in ((a, b), (b, c), (c, a)))
    inradius = np.linalg.norm(cross, axis=1) / perimeter
    facets = np.argsort(inradius)[-3:]              # receivers must lie wholly on their facet
    r = 0.9 * float(inradius[facets].min())
    centres = (a[facets] + b[facets] + c[facets]) / 3
    inward = -cross[facets] / np.linalg.norm(cross[facets], axis=1)[:, None]
    area = mesh_area(v, t)
    res = sim.illuminance(centres, inward, radius=r, target_relative_error=0.05, max_photons=8_000_000, seed=5,
                          estimator=estimator)
    ref = [disk_average(point_source_e(flux / (4 * math.pi), [0, 0, 0], n), p, n, r)
           + rho * flux / (area * (1 - rho)) for p, n in zip(centres, inward, strict=True)]
    check(res, ref, 0.05)
    assert area == pytest.approx(4 * math.pi, rel=0.05)


def slab_scene(ior, absorption=0.0, thickness=0.1):
    s, (slab,) = scene_of(box((-1, -1, 0), (1, 1, thickness)))
    mat = {"type": "dielectric", "ior": ior, "absorption_per_m": absorption}
    return s, slab, mat


def beam(radius=0.1, e0=1000.0):
    return {"type": "collimated", "origin": [0, 0, 1], "direction": [0, 0, -1], "radius": radius,
            "illuminance_lx": e0}


def test_glass_slab_transmission_with_multiple_reflections():
    n = 1.5
    s, slab, mat = slab_scene(n)
    sim = Simulation(s, {slab: mat}, [beam()])
    assert sim.effects == ["lambertian", "fresnel", "polarization"]   # two interfaces in a row (issue 38)
    res = sim.illuminance([[0, 0, -0.5]], [[0, 0, 1.0]], radius=0.1, max_photons=300_000, seed=6,
                          force_effects=GLASS_EFFECTS)
    assert res.estimator == "forward"
    check(res, [1000.0 * 2 * n / (n * n + 1)])
    assert res.stderr[0] < 0.005 * res.lux[0]


def prism_scene(ior):
    """Right prism: legs on x = 0 and z = 0, hypotenuse x + z = 1, y in [-1, 1]; outward normals."""
    v = np.array([[0, -1, 0], [1, -1, 0], [0, -1, 1], [0, 1, 0], [1, 1, 0], [0, 1, 1]], float)
    t = np.array([[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [0, 3, 5], [0, 5, 2], [1, 2, 5], [1, 5, 4]])
    s, (prism,) = scene_of(outward(v, t))
    return s, prism, {"type": "dielectric", "ior": ior}


@pytest.mark.parametrize("ior", [1.5, math.sqrt(2) * (1 + 1e-9), math.sqrt(2) * (1 - 1e-9), 1.3])
def test_total_internal_reflection_in_a_right_prism(ior):
    """A beam entering the base normally meets the hypotenuse at 45°: beyond the critical angle for
    n > √2 it is totally reflected and leaves through the other leg, 2n/(n²+1) of it."""
    s, prism, mat = prism_scene(ior)
    light = {"type": "collimated", "origin": [0.5, 0, -0.5], "direction": [0, 0, 1], "radius": 0.1,
             "illuminance_lx": 1000.0}
    sim = Simulation(s, {prism: mat}, [light])
    # beyond the exit leg; and on the path a ray refracted at the hypotenuse would take (Snell)
    n_h, t_h = np.array([1.0, 0, 1.0]) / math.sqrt(2), np.array([-1.0, 0, 1.0]) / math.sqrt(2)
    sin_t = min(ior * math.sin(math.pi / 4), 1.0)
    d = math.sqrt(1 - sin_t ** 2) * n_h + sin_t * t_h
    pts = np.array([[-0.5, 0, 0.5], [0.5, 0, 0.5] + 0.6 * d])
    nrm = np.array([[1.0, 0, 0], -d])
    res = sim.illuminance(pts, nrm, radius=0.1, max_photons=200_000, seed=7, force_effects=GLASS_EFFECTS)
    assert np.all(np.isfinite(res.lux)) and res.rejected == 0
    if ior > math.sqrt(2):
        check(res, [1000.0 * 2 * ior / (ior * ior + 1), 0.0])
        assert res.lux[1] == 0.0
    elif ior == 1.3:
        assert res.lux[1] > 100.0      # below the critical angle light leaves through the hypotenuse
    else:                              # just below critical: refracted at grazing exit, nothing lost
        assert res.lux[0] > 0


@pytest.mark.parametrize(("tau", "absorb"), [(0.0, 0.0), (1e-6, 1e-5), (1.0, 10.0), (1e3, 1e4)])
def test_beer_lambert_through_an_index_matched_absorbing_slab(tau, absorb):
    """n = 1 (no Fresnel reflection at all: n1 = n2 exactly), absorption σ over 0.1 m: E = E0 exp(−τ)."""
    s, slab, mat = slab_scene(1.0, absorb)
    sim = Simulation(s, {slab: mat}, [beam()])
    res = sim.illuminance([[0, 0, -0.5]], [[0, 0, 1.0]], radius=0.1, max_photons=50_000, seed=8,
                          force_effects=GLASS_EFFECTS)
    ref = 1000.0 * math.exp(-tau)
    if tau <= 1.0:   # continuous absorption weights: no noise at all
        assert res.lux[0] == pytest.approx(ref, rel=1e-7, abs=1e-9)   # spawn offsets change the path by ~1e-9 m
        assert res.stderr[0] <= 1e-7 * ref
    else:
        assert res.lux[0] == 0.0
    assert res.rejected == 0


def test_scattering_medium_with_albedo_one_conserves_energy():
    """Point source in an index-matched scattering sphere (σs R = 2, g = 0.6): all flux leaves, and by
    symmetry a disk facing the centre receives Φ (1 − cos α)/2 of it."""
    v, t = icosphere(0.5, 3)
    s, (ball,) = scene_of((v, t))
    mat = {"type": "dielectric", "ior": 1.0, "scattering_per_m": 4.0, "g": 0.6}
    flux = 1000.0
    sim = Simulation(s, {ball: mat}, [{"type": "point", "position": [0, 0, 0], "flux_lm": flux}])
    assert sim.effects == ["lambertian", "fresnel", "scattering"]
    d, r = 2.0, 0.4
    dirs = np.array([[1.0, 0, 0], [0, -0.6, 0.8], [0, 0, -1.0]])
    res = sim.illuminance(dirs * d, -dirs, radius=r, target_relative_error=0.03, max_photons=3_000_000, seed=9,
                          force_effects=GLASS_EFFECTS)
    cos_a = d / math.hypot(d, r)
    check(res, np.full(3, flux * (1 - cos_a) / 2 / (math.pi * r * r)), 0.03)


def test_estimators_agree_in_a_diffuse_room():
    s, (room,) = scene_of(box((0, 0, 0), (3, 2, 2.5)))
    sim = Simulation(s, {room: {"type": "lambertian", "reflectance": 0.6}},
                     [{"type": "point", "position": [1.5, 1.0, 2.2], "flux_lm": 3000.0}])
    pts = np.array([[0.5, 0.5, 0], [1.5, 1.0, 0], [2.9, 1.9, 0], [3.0, 1.0, 1.0]])
    nrm = np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, 1.0], [-1.0, 0, 0]])
    b = sim.illuminance(pts, nrm, radius=0.1, target_relative_error=0.01, max_photons=2_000_000, seed=10)
    f = sim.illuminance(pts, nrm, radius=0.1, target_relative_error=0.05, max_photons=8_000_000, seed=10,
                        estimator="forward")
    assert b.estimator == "backward" and f.estimator == "forward"
    z = np.abs(b.lux - f.lux) / np.sqrt(b.stderr ** 2 + f.stderr ** 2)
    assert np.all(z < 4.0), (b.lux, f.lux, b.stderr, f.stderr)


def test_rays_on_edges_and_vertices_do_not_leak():
    """A pencil beam aimed exactly at a vertex shared by eight triangles (and along their edges): a
    receiver under the black floor must see nothing."""
    ring = [(math.cos(k * math.pi / 4), math.sin(k * math.pi / 4), 0.0) for k in range(8)]
    v = np.array([(0.0, 0.0, 0.0)] + ring)
    t = np.array([[0, 1 + k, 1 + (k + 1) % 8] for k in range(8)])
    s, (fan,) = scene_of((v, t))
    for light in ({"type": "collimated", "origin": [0, 0, 1], "direction": [0, 0, -1], "radius": 1e-12,
                   "illuminance_lx": 1e24},
                  {"type": "collimated", "origin": [0.5, 0, 1], "direction": [0, 0, -1], "width": 0.5,
                   "height": 1e-13, "up": [1, 0, 0], "illuminance_lx": 1e24}):
        sim = Simulation(s, {fan: BLACK}, [light])
        res = sim.illuminance([[0, 0, -0.5], [0.5, 0, -0.5]], [[0, 0, 1.0], [0, 0, 1.0]], radius=0.3,
                              max_photons=100_000, seed=11)
        assert res.lux.tolist() == [0.0, 0.0] and res.rejected == 0


@pytest.mark.slow
def test_error_bars_are_honest_over_200_seeds():
    """2σ covers the reference in 90–99 % of 200 independent runs of a few thousand photons."""
    s, (floor,) = floor_scene()
    sim = Simulation(s, {floor: BLACK}, [{"type": "point", "position": [0, 0, 2], "intensity_cd": 1000.0}])
    r = 0.5
    ref = disk_average(point_source_e(1000.0, [0, 0, 2], [0, 0, 1]), [0.5, 0, 0], [0, 0, 1], r)
    covered = 0
    for seed in range(200):
        res = sim.illuminance([[0.5, 0, 0]], [[0, 0, 1.0]], radius=r, max_photons=12_800, seed=1000 + seed,
                              estimator="forward")
        covered += abs(res.lux[0] - ref) <= 2 * res.stderr[0]
    assert 180 <= covered <= 198, covered


@pytest.mark.parametrize(("g", "tau"), [(-0.999999, 1.0), (-0.999999, 1e-6), (0.999999, 1.0), (0.999999, 1e-6)])
def test_henyey_greenstein_near_plus_minus_one_in_a_slab(g, tau):
    """g → −1 turns every scattering into a reversal: the slab becomes a 1-D rod with transmission
    1/(1 + τ) exactly; g → +1 leaves the beam as it was (transmission 1)."""
    s, (slab,) = scene_of(box((-1, -1, 0), (1, 1, 0.1)))
    mat = {"type": "dielectric", "ior": 1.0, "scattering_per_m": tau / 0.1, "g": g}
    sim = Simulation(s, {slab: mat}, [beam()])
    res = sim.illuminance([[0, 0, -0.5]], [[0, 0, 1.0]], radius=0.1, max_photons=40_000, seed=12,
                          force_effects=GLASS_EFFECTS)
    ref = 1000.0 / (1.0 + tau) if g < 0 else 1000.0
    if tau < 1e-3 or g > 0:   # practically every photon goes straight through
        assert res.lux[0] == pytest.approx(ref, rel=1e-3)
    else:
        check(res, [ref])
    assert res.rejected == 0 and res.counters["truncated"] == 0


def test_mirror_adds_the_image_source_and_mix_reduces_to_its_parts():
    """Over a mirror plane of reflectance R a receiver sees the source and its image R·I below the plane."""
    s, (plane,) = floor_scene()
    src, img, rr = np.array([0, 0, 1.0]), np.array([0, 0, -1.0]), 0.8
    light = [{"type": "point", "position": list(src), "intensity_cd": 1000.0}]
    pts, nrm, r = np.array([[0.5, 0, 2.0], [-1.0, 0.5, 1.5]]), np.array([[0, 0, -1.0], [0.3, 0, -1.0]]), 0.2
    nrm = nrm / np.linalg.norm(nrm, axis=1)[:, None]
    ref = [disk_average(point_source_e(1000.0, src, n), p, n, r) + disk_average(point_source_e(rr * 1000.0, img, n),
                                                                              p, n, r) for p, n in zip(pts, nrm,
                                                                                                       strict=True)]
    mirror = Simulation(s, {plane: {"type": "mirror", "reflectance": rr}}, light)
    res = mirror.illuminance(pts, nrm, radius=r, target_relative_error=0.03, max_photons=4_000_000, seed=13,
                             force_effects=GLASS_EFFECTS)
    check(res, ref, 0.03)
    # a mix with no diffuse part is the mirror, photon for photon
    mix = Simulation(s, {plane: {"type": "mix", "diffuse": 0.0, "specular": rr}}, light)
    same = mix.illuminance(pts, nrm, radius=r, target_relative_error=0.03, max_photons=4_000_000, seed=13,
                           force_effects=GLASS_EFFECTS)
    np.testing.assert_array_equal(same.lux, res.lux)
    # a mix with no specular part is Lambertian: forward agrees with the backward estimate of the Lambertian plane
    diffuse = Simulation(s, {plane: {"type": "mix", "diffuse": 0.5, "specular": 0.0}}, light)
    assert diffuse.effects == ["lambertian"]
    f = diffuse.illuminance(pts, nrm, radius=r, target_relative_error=0.03, max_photons=4_000_000, seed=14,
                            force_effects=GLASS_EFFECTS)
    b = Simulation(s, {plane: {"type": "lambertian", "reflectance": 0.5}}, light).illuminance(
        pts, nrm, radius=r, target_relative_error=0.005, max_photons=1_000_000, seed=14)
    assert np.all(np.abs(f.lux - b.lux) < 4 * np.hypot(f.stderr, b.stderr)), (f.lux, b.lux)
