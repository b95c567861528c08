"""Polarized light: Stokes vectors and Mueller matrices against the closed forms of docs/REFERENCES.md and
the polarization issue (Malus, Fresnel at n = 1.5, Brewster, total internal reflection, the thick plate and the
pile of plates, a quarter-wave plate).

Tolerances: four standard errors of the estimate (the estimator's own batch-means error). A degree of
polarization P = |S| / S0 is a ratio of two estimates; its error is bounded by (σ_|S| + P σ_S0) / S0 whatever
their correlation. Where the model has a known bias (an extinction ratio of 1e6) it is added and stated.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.optics import polarization as P
from tracer.optics.thinfilm import stack_mueller
from tracer.scene import Scene
from tracer.simulate import Simulation, SimulationError
from tracer.warmup import box

N = 1.5
BREWSTER = math.degrees(math.atan(N))          # 56.3099°
NO_LAYERS = np.zeros((1, 2))


def _fresnel(theta_deg, n1=1.0, n2=N):
    return stack_mueller(NO_LAYERS, 0, 0, False, n1, n2, 0.0, 550.0, math.cos(math.radians(theta_deg)))


def _sheet(s, z, half=2.0):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]], float)
    return s.add_instance(s.add_geometry(v, np.array([[0, 1, 2], [0, 2, 3]])), np.eye(4))


def _near(value, expected, err, model=0.0):
    return abs(value - expected) <= 4.0 * err + model


def _dop_err(res, k=0):
    """Upper bound of the standard error of the degree of polarization at point k (module docstring)."""
    s, e = res.stokes[k], res.stokes_stderr[k]
    return (float(np.sqrt(np.sum(e[1:] ** 2))) + res.dop[k] * e[0]) / s[0]


def _beam(direction, target=(0.0, 0.0, 0.0), radius=0.2, polarization=None, back=1.0):
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    light = {"type": "collimated", "origin": list(np.asarray(target) - back * d), "direction": list(d),
             "radius": radius, "illuminance_lx": 100.0}
    if polarization:
        light["polarization"] = polarization
    return light


def _incidence(theta_deg):
    """A unit direction hitting the plane z = 0 from above at θ from its normal, in the xz plane."""
    t = math.radians(theta_deg)
    return np.array([math.sin(t), 0.0, -math.cos(t)])


# ------------------------------------------------------------------------------------------ closed forms


def test_fresnel_mueller_parameters_at_n_1_5():
    rs, rp, cr, dr, ts, tp, ct, dt = _fresnel(0.0)
    assert rs == pytest.approx(0.04, abs=1e-12) and rp == pytest.approx(0.04, abs=1e-12)
    assert cr == pytest.approx(-0.04, abs=1e-12)      # normal incidence: S2 and S3 turn over, S1 stays
    rs, rp, cr, dr, ts, tp, ct, dt = _fresnel(45.0)
    assert (rs, rp) == (pytest.approx(0.092013, abs=1e-6), pytest.approx(0.008466, abs=1e-6))
    assert (rs - rp) / (rs + rp) == pytest.approx(0.831479, abs=1e-6)
    assert rs + ts == pytest.approx(1.0, abs=1e-12) and rp + tp == pytest.approx(1.0, abs=1e-12)
    assert cr ** 2 + dr ** 2 == pytest.approx(rs * rp, rel=1e-9)       # a pure (non-depolarizing) interface
    assert ct ** 2 + dt ** 2 == pytest.approx(ts * tp, rel=1e-9)
    assert BREWSTER == pytest.approx(56.3099, abs=1e-4)
    rs, rp, *_ = _fresnel(BREWSTER)
    assert rs == pytest.approx(0.147929, abs=1e-6) and rp < 1e-15


def test_total_internal_reflection_beyond_41_81_degrees_and_its_phase():
    critical = math.degrees(math.asin(1.0 / N))
    assert critical == pytest.approx(41.8103, abs=1e-4)
    rs, rp, *_ = _fresnel(critical - 0.05, N, 1.0)
    assert rs < 1.0 and rp < 1.0
    for theta in (critical + 0.05, 54.6, 80.0):
        rs, rp, cr, dr, ts, tp, ct, dt = _fresnel(theta, N, 1.0)
        assert (rs, rp, ts, tp) == (pytest.approx(1.0), pytest.approx(1.0), 0.0, 0.0)
        # the s−p phase difference δ of total reflection: tan(δ/2) = cosθ √(sin²θ − 1/n²) / sin²θ (Born & Wolf)
        t = math.radians(theta)
        delta = 2.0 * math.atan(math.cos(t) * math.sqrt(math.sin(t) ** 2 - 1.0 / N ** 2) / math.sin(t) ** 2)
        assert abs(cr) == pytest.approx(abs(math.cos(delta)), abs=1e-9)
        assert abs(dr) == pytest.approx(abs(math.sin(delta)), abs=1e-9)


def test_two_total_reflections_of_a_fresnel_rhomb_make_linear_light_circular():
    """n = 1.51 at 54.6°: δ = 45° per reflection; two turn linear light at 45° into circular (|S3| = S0)."""
    pol = np.zeros(P.N_POL)
    pol[P.S2] = 1.0                      # linear at 45° to the plane of incidence, frame x = s
    for _ in range(2):
        rs, rp, cr, dr, *_ = _fresnel(54.6, 1.51, 1.0)
        P.apply_interface(pol, rs, rp, cr, dr)
    assert abs(pol[P.S3]) == pytest.approx(1.0, abs=2e-3) and abs(pol[P.S2]) < 0.07


def test_bad_polarization_bodies_name_the_field():
    for body, match in [({"type": "linear"}, "exactly the fields"), ({"type": "linear", "axis": [0, 0, 0]}, "axis"),
                        ({"type": "linear", "axis": [1, True, 0]}, "axis"), ({"type": "elliptic"}, "must be"),
                        ({"type": "circular", "handedness": "up"}, "handedness"), ([1, 0, 0], "must be")]:
        with pytest.raises(P.PolarizationError, match=match):
            P.light_polarization(body, "light 0")


# ---------------------------------------------------------------------------------------- through the tracer


def _polarizers(angles, light_pol=None, retarder=None, photons=200_000):
    s = Scene()
    mats = {}
    for k, a in enumerate(angles):
        mats[_sheet(s, 1.0 + k)] = {"type": "polarizer", "axis": [math.cos(math.radians(a)), math.sin(math.radians(a)),
                                                                    0.0], "extinction_ratio": 1e6}
    if retarder is not None:
        mats[_sheet(s, 0.5)] = {"type": "retarder", "fast_axis": [1, 0, 0], "retardance_deg": retarder}
    s.commit()
    sim = Simulation(s, mats, [_beam([0, 0, 1], (0, 0, 0.1), 0.3, light_pol, back=0.1)])
    return sim.illuminance([[0, 0, 10]], [[0, 0, -1]], radius=0.1, max_photons=photons, seed=3, observe=["stokes"],
                           reference=[1, 0, 0])


@pytest.mark.parametrize(("angles", "fraction"), [([0], 0.5), ([0, 30], 0.375), ([0, 45, 90], 0.125), ([0, 90], 0.0)])
def test_malus_law_through_polarizer_sheets(angles, fraction):
    """Unpolarized light: one polarizer passes 0.5, two at 30° 0.375, 0°/45°/90° 0.125, crossed 0 (extinction
    ratio 1e6: the crossed pair passes 1e-6 in power, the others within 1e-6 of the ideal)."""
    res = _polarizers(angles)
    assert res.effects == ["lambertian", "polarization"] and res.rejected == 0
    assert _near(res.lux[0], 100.0 * fraction, res.stderr[0], model=100.0 * 1e-6), (res.lux, res.stderr)
    if fraction > 0:
        a = math.radians(angles[-1])     # the light leaves along the last polarizer's axis: fully polarized
        assert res.dop[0] == pytest.approx(1.0, abs=3e-6)
        # the leak across the axis is √(k2/k1) = 1e-3 in amplitude: it turns the field by up to ~1e-3 rad
        assert res.stokes[0, 1] / res.stokes[0, 0] == pytest.approx(math.cos(2 * a), abs=3e-3)


def test_a_quarter_wave_plate_turns_linear_light_at_45_degrees_circular():
    res = _polarizers([], light_pol={"type": "linear", "axis": [1, 1, 0]}, retarder=90.0, photons=40_000)
    s0, s1, s2, s3 = res.stokes[0]
    assert abs(abs(s3) - s0) <= 1e-9 * s0 and abs(s1) <= 1e-9 * s0 and abs(s2) <= 1e-9 * s0
    half = _polarizers([], light_pol={"type": "linear", "axis": [1, 1, 0]}, retarder=180.0, photons=40_000)
    assert half.stokes[0, 2] == pytest.approx(-half.stokes[0, 0], rel=1e-9)   # a half-wave plate mirrors 45° to −45°


def test_a_mirror_turns_circular_light_to_the_other_hand():
    s = Scene()
    mirror = _sheet(s, 0.0)
    s.commit()
    light = _beam([0, 0, -1], (0, 0, 0), 0.3, {"type": "circular", "handedness": "right"}, back=5.0)
    sim = Simulation(s, {mirror: {"type": "mirror", "reflectance": 0.8}}, [light])
    res = sim.illuminance([[0, 0, 2], [0, 0, 3]], [[0, 0, 1], [0, 0, -1]], radius=0.1, max_photons=100_000, seed=1,
                          observe=["stokes"])
    incoming, reflected = res.stokes
    assert incoming[3] == pytest.approx(incoming[0], rel=1e-9)        # right-handed as it comes
    assert reflected[3] == pytest.approx(-reflected[0], rel=1e-9)     # left-handed after the mirror
    assert _near(reflected[0], 80.0, res.stderr[1])


def _glass_surface(theta_deg, polarization=None, photons=200_000, thickness=1.0, absorption=50.0, beam=0.2,
                   receiver=0.05):
    """A beam at θ onto glass (n = 1.5) filling z < 0; a receiver across the specular reflection, 1 m away."""
    s = Scene()
    glass = s.add_instance(s.add_geometry(*box([-5, -5, -thickness], [5, 5, 0])), np.eye(4))
    s.commit()
    d = _incidence(theta_deg)
    r = d * np.array([1, 1, -1])
    sim = Simulation(s, {glass: {"type": "dielectric", "ior": N, "absorption_per_m": absorption}},
                     [_beam(d, (0, 0, 0), beam, polarization)])
    return sim.illuminance([list(r)], [list(-r)], radius=receiver, max_photons=photons, seed=7, observe=["stokes"],
                           reference=[0, 1, 0])


def test_fresnel_reflection_at_45_degrees_polarizes_the_reflected_light():
    """R = (Rs + Rp) / 2 = 0.05024, degree of polarization (Rs − Rp) / (Rs + Rp) = 0.831479, along s."""
    res = _glass_surface(45.0)
    assert _near(res.lux[0], 100.0 * (0.092013 + 0.008466) / 2, res.stderr[0])
    assert res.dop[0] == pytest.approx(0.831479, abs=1e-6)   # every reflected photon leaves in this one state
    assert res.stokes[0, 1] > 0    # S1 > 0 in the frame x = s: the s wave dominates


def test_brewster_reflection_is_fully_s_polarized_and_p_light_passes():
    res = _glass_surface(BREWSTER)
    assert _near(res.lux[0], 100.0 * 0.147929 / 2, res.stderr[0])
    assert res.dop[0] == pytest.approx(1.0, abs=1e-9)
    p_light = _glass_surface(BREWSTER, polarization={"type": "linear", "axis": list(np.cross(_incidence(BREWSTER),
                                                                                                [0, 1, 0]))},
                             photons=50_000)
    assert p_light.lux[0] == 0.0      # p-polarized light at Brewster's angle: nothing reflects


def test_thick_plate_at_brewster_reflects_2rs_over_1_plus_rs_of_the_s_light():
    """A lossless plate, incoherent multiple reflections: unpolarized light reflects Rs / (1 + Rs) = 0.128867.
    Averaging s and p at each interface instead gives 2R / (1 + R) = 0.137740, R = (Rs + Rp) / 2: 7 % more,
    far beyond the 4σ here (about 2 %)."""
    beam, a = 0.005, 0.3
    res = _glass_surface(BREWSTER, thickness=0.01, absorption=0.0, beam=beam, receiver=a, photons=400_000)
    fraction = res.lux[0] * a ** 2 / (100.0 * beam ** 2)
    err = res.stderr[0] * a ** 2 / (100.0 * beam ** 2)
    rs = 0.147929
    assert _near(fraction, rs / (1 + rs), err), (fraction, err)
    r = rs / 2
    assert not _near(fraction, 2 * r / (1 + r), err)


@pytest.mark.parametrize(("plates", "dop"), [(1, 0.147929), (5, 0.464684), (10, 0.634518), (20, 0.776398)])
def test_pile_of_plates_polarizes_the_transmitted_light(plates, dop):
    """m plates at Brewster's angle, incoherent multiple reflections within and between them: the transmitted
    light's degree of polarization is m / (m + (2n / (1 − n²))²)."""
    assert plates / (plates + (2 * N / (1 - N * N)) ** 2) == pytest.approx(dop, abs=1e-6)
    s = Scene()
    for k in range(plates):
        top = -0.005 * k
        s.add_instance(s.add_geometry(*box([-5, -5, top - 0.002], [5, 5, top])), np.eye(4))
    s.commit()
    d = _incidence(BREWSTER)
    sim = Simulation(s, {}, [_beam(d, (0, 0, 0), 0.005)], default_material={"type": "dielectric", "ior": N})
    behind = np.array([0, 0, -0.005 * plates]) + 1.0 * d
    res = sim.illuminance([list(behind)], [list(-d)], radius=0.5, max_photons=100_000, seed=11, observe=["stokes"],
                          reference=[0, 1, 0])
    assert _dop_err(res) < 0.01      # a sharp test: 4σ well inside the steps between m = 1, 5, 10, 20
    assert _near(res.dop[0], dop, _dop_err(res)), (res.dop, _dop_err(res))
    assert res.stokes[0, 1] < 0      # p light passes: the transmitted light is polarized across s


def test_receivers_frame_and_bad_references():
    s = Scene()
    s.add_instance(s.add_geometry(*box([50, 50, 50], [51, 51, 51])), np.eye(4))
    s.commit()
    sim = Simulation(s, {}, [_beam([0, 0, -1], (0, 0, 0), 0.3, {"type": "linear", "axis": [1, 0, 0]}, back=2.0)],
                     default_material={"type": "black"})
    assert sim.effects == ["lambertian", "polarization"]
    for ref, s1 in (([1, 0, 0], 1.0), ([0, 1, 0], -1.0), ([1, 1, 0], 0.0)):
        res = sim.illuminance([[0, 0, 0]], [[0, 0, 1]], radius=0.1, max_photons=2_000, observe=["stokes"],
                              reference=ref)
        assert res.stokes[0, 1] / res.stokes[0, 0] == pytest.approx(s1, abs=1e-9)
    with pytest.raises(SimulationError, match="lies along the normal"):
        sim.illuminance([[0, 0, 0]], [[0, 0, 1]], observe=["stokes"], reference=[0, 0, 2])
    with pytest.raises(SimulationError, match="reference must be 3 finite numbers"):
        sim.illuminance([[0, 0, 0]], [[0, 0, 1]], observe=["stokes"], reference=[0, math.nan, 1])
    with pytest.raises(SimulationError, match="unknown observable"):
        sim.illuminance([[0, 0, 0]], [[0, 0, 1]], observe=["stoke"])
