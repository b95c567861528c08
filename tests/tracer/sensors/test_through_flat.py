"""Light tracing joined to the eye through one flat glass face (`tracer.transport.through_flat`): a diffuse plate
under a glass slab, seen from above.

Scene: a Lambertian plate (reflectance ρ) inside a glass slab (n = 1.5), both far wider than the slab is thick, lit
at normal incidence by a collimated beam of illuminance E₀ through the slab's top face. The plate receives E₀ T(0);
what it sends up comes back from the top face in the share r_i (the face's hemispherical reflectance for Lambertian
light from inside, total internal reflection included), so its radiance inside the glass is
L = ρ E₀ T(0) / (π (1 − ρ r_i)) (the geometric series of its bounces), and seen from air through the top face at
θ₂ (sin θ₂ = n sin θ₁) it reads T(θ₁) L / n² (radiance over n² is kept across an interface, less what reflects).
Paths from the eye cannot reach a collimated beam; before the join through the face no light path reached the eye
either (the straight shadow ray stops at the glass): the meter read 0. T and r_i are the unpolarised Fresnel
values (s and p averaged), as a scene without polarization has them. Tolerances from the estimate's own standard
error (Z of them).

The plate below the slab instead, in air (a backlight's reflector sheet under its light guide): the join crosses
the slab's two faces. The plate receives E₀ T_s(0), T_s = (1 − R)/(1 + R) the slab's transmission with its inner
reflections (the photons follow them); the slab sends back the share R_d = ∫ 2R/(1 + R) 2 sin θ cos θ dθ of the
plate's Lambertian light, so L = ρ E₀ T_s(0) / (π (1 − ρ R_d)); the join takes the path straight through, (1 − R(θ))²
L. What it leaves out, paths that reflect twice inside the slab on their way to the eye (another 0.15 % at 0°, 0.7 %
at 60° here), no path from the eye adds either: they find no light from a collimated beam.

A square area light above the slab in place of the beam: paths from the eye find its light through the plate (a
BSDF sample from the plate out through the face onto the emitter) and so does light tracing (the photon through the
face onto the plate, joined back through it); each path must be counted by one of them only, so the answer with
area lights traced equals the one from paths from the eye alone within their combined error bars.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad as integrate

import tracer.transport.light_tracing as light_tracing
import tracer.transport.rounds as rounds
from tests.tracer.transport_scenes import box, quad, scene_of
from tracer.optics.surfaces.fresnel import fresnel_dielectric
from tracer.simulate import Simulation

Z = 4.0
N_GLASS, RHO, E0 = 1.5, 0.5, 1000.0
HALF, TOP, PLATE_TOP = 0.05, 0.001, 0.0003   # the slab [-HALF, HALF]² x [0, TOP] (m); the plate's top inside it


def slab_sim(light: dict, below: bool = False) -> Simulation:
    """The slab and the plate (inside it, or `below` it in air) under `light`."""
    z0, z1 = (-0.0013, -0.0003) if below else (0.0001, PLATE_TOP)
    meshes = [box([-HALF, -HALF, 0.0], [HALF, HALF, TOP]),                              # the glass slab
              box([-HALF + 0.001, -HALF + 0.001, z0], [HALF - 0.001, HALF - 0.001, z1])]   # the plate
    mats = [{"type": "dielectric", "ior": N_GLASS}, {"type": "lambertian", "reflectance": RHO}]
    if light["type"] == "area":   # the emitter: a square facing down, black behind
        meshes.append(quad([-0.015, -0.015, 0.03], [0, 0.03, 0], [0.03, 0, 0]))
        mats.append({"type": "black"})
        light = {**light, "instances": [2]}
    s, ids = scene_of(*meshes)
    return Simulation(s, dict(zip(ids, mats, strict=True)), [light])


def transmittance(cos_i: float) -> float:
    """1 − R̄ from inside the glass at the angle of cosine cos_i (0 beyond the critical angle)."""
    return 1.0 - fresnel_dielectric(cos_i, N_GLASS, 1.0)


def plate_luminance_through_the_top(theta_out_deg: float) -> float:
    """T(θ₁) L / n², L = ρ E₀ T(0) / (π (1 − ρ r_i)) (module docstring)."""
    r_i = integrate(lambda t: (1.0 - transmittance(math.cos(t))) * 2.0 * math.sin(t) * math.cos(t), 0.0,
                    math.pi / 2, points=[math.asin(1 / N_GLASS)], limit=200)[0]
    inside = RHO * E0 * (1.0 - fresnel_dielectric(1.0, 1.0, N_GLASS)) / (math.pi * (1.0 - RHO * r_i))
    sin_1 = math.sin(math.radians(theta_out_deg)) / N_GLASS
    return transmittance(math.sqrt(1.0 - sin_1 ** 2)) * inside / N_GLASS ** 2


def meter(theta_deg: float) -> dict:
    """A 5-degree luminance meter 0.1 m from the slab's centre, θ from the vertical, looking at it."""
    d = np.array([math.sin(math.radians(theta_deg)), 0.0, math.cos(math.radians(theta_deg))])
    return {"type": "luminance", "position": (np.array([0.0, 0.0, TOP]) + 0.1 * d).tolist(),
            "direction": (-d).tolist(), "aperture_deg": 5.0}


def test_a_plate_under_glass_lit_by_a_beam_reads_its_radiance_through_the_face():
    """Meters at 0, 30 and 60 degrees read T(θ₁) L / n² within 4 σ: only light tracing joined through the face sees
    the plate (every path from the eye misses a collimated beam), and the three angles test the join's Fresnel
    factor and spread (n² J against the straight d²). Nor does the answer say any longer that this light is missing."""
    beam = {"type": "collimated", "origin": [0.0, 0.0, 0.05], "direction": [0.0, 0.0, -1.0], "radius": 0.045,
            "illuminance_lx": E0}
    sim = slab_sim(beam)
    for theta in (0.0, 30.0, 60.0):
        r = sim.run(meter(theta), max_photons=30_000, seed=3)
        exact = plate_luminance_through_the_top(theta)
        assert "light tracing" in r.strategy and r.counters["light_splats"] > 0, r.strategy
        assert abs(r.luminance - exact) <= Z * r.stderr and r.stderr < 0.05 * exact, (theta, r.luminance,
                                                                                    r.stderr, exact)
        # what may still be missing: the beam seen reflected in the top face (its Fresnel share of the paths), not
        # the plate seen through it (every path went on through the face: 100 % before)
        assert r.unreachable is not None and r.unreachable["through_specular"] < 0.2, r.unreachable


def fresnel_air(cos_i: float) -> float:
    """R̄ of the glass seen from air at the angle of cosine cos_i."""
    return fresnel_dielectric(cos_i, 1.0, N_GLASS)


def plate_luminance_through_the_slab(theta_deg: float) -> float:
    """(1 − R(θ))² L, L = ρ E₀ T_s(0) / (π (1 − ρ R_d)) (module docstring)."""
    r_d = integrate(lambda t: 2 * fresnel_air(math.cos(t)) / (1 + fresnel_air(math.cos(t))) * 2.0 * math.sin(t)
                    * math.cos(t), 0.0, math.pi / 2, limit=200)[0]
    r0 = fresnel_air(1.0)
    plate = RHO * E0 * (1 - r0) / (1 + r0) / (math.pi * (1.0 - RHO * r_d))
    return (1.0 - fresnel_air(math.cos(math.radians(theta_deg)))) ** 2 * plate


def test_a_plate_under_a_glass_slab_reads_its_radiance_through_both_faces():
    """The plate 0.3 mm below the slab, in air: meters at 0, 30 and 60 degrees read (1 − R(θ))² L within 4 σ (the
    join crosses two parallel faces; before, the shadow ray stopped at the slab and they read 0)."""
    beam = {"type": "collimated", "origin": [0.0, 0.0, 0.05], "direction": [0.0, 0.0, -1.0], "radius": 0.045,
            "illuminance_lx": E0}
    sim = slab_sim(beam, below=True)
    for theta in (0.0, 30.0, 60.0):
        r = sim.run(meter(theta), max_photons=30_000, seed=8)
        exact = plate_luminance_through_the_slab(theta)
        assert r.counters["light_splats"] > 0
        assert abs(r.luminance - exact) <= Z * r.stderr and r.stderr < 0.05 * exact, (theta, r.luminance,
                                                                                    r.stderr, exact)


@pytest.mark.parametrize("below", [False, True])
def test_an_area_light_through_the_faces_is_counted_once_whichever_strategy_finds_it(monkeypatch, below):
    """The square light above the slab, the plate in it or below it: a meter at 40 degrees reads the same within 4
    combined σ with the area light traced (light tracing joins through the faces; the paths from the eye leave it
    those paths; the pilot, which would leave this light to the paths from the eye, is overruled) and with paths from
    the eye alone; light tracing carries about half of the reading, so a path counted twice or by neither fails."""
    pilot = rounds.area_light_pilot

    def traced_anyway(*args, **kwargs):
        found, _ = pilot(*args, **kwargs)
        return {**found, "traced": True, "per_batch": 4096}, None

    monkeypatch.setattr(rounds, "area_light_pilot", traced_anyway)
    both = slab_sim({"type": "area", "exitance_lm_m2": 1000.0}, below).run(meter(40.0), max_photons=24_000, seed=5)
    assert "area lights traced" in both.strategy, both.strategy
    assert both.counters["left_to_light_tracing"] > 0 and both.counters["light_splats"] > 0
    monkeypatch.setattr(rounds, "area_light_pilot", pilot)
    monkeypatch.setattr(light_tracing, "AREA_LIGHT_TRACING", False)
    alone = slab_sim({"type": "area", "exitance_lm_m2": 1000.0}, below).run(meter(40.0), max_photons=24_000,
                                                                            seed=6)
    assert "light tracing" not in alone.strategy
    sigma = math.hypot(both.stderr, alone.stderr)
    assert abs(both.luminance - alone.luminance) <= Z * sigma, (both.luminance, alone.luminance, sigma)
    assert sigma < 0.08 * alone.luminance   # a path counted twice: light tracing's half again, 6 sigma or more
