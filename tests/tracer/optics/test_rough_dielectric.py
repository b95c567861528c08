"""A rough `dielectric` (α > 0: GGX facets, Walter et al. EGSR 2007; issue 38's `rough_dielectric`, a kind of its
own until 2026-12-07) against closed forms, through the switch the transport kernel inlines (`scatter_contract.Case`:
a flat quad, front side +z, the solid below it, node frame = world, N photons each on its own stream). The sampled
density itself is checked by a χ² test in test_chi2_sampling.py.

- White furnace: the reflected and transmitted fractions R and T each equal Walter's BSDF integrated over its
  hemisphere (`ggx_reference.albedo`, midpoint rule in (θ, φ), 1000 × 1000 cells; 2000 × 2000 moves them by
  < 3e-4: the transmitted density ends abruptly where the half vector turns flat, so the rule converges slowly
  there, and 1e-3 is added to the tolerance), within 4σ, from air into n = 1.5 and from inside out (total internal
  reflection included). What
  R + T lacks of 1 is the single-scattering loss (a second bounce between facets), stated in the module docstring.
- Smooth limit: α = 1e-4 reflects and refracts in the shares `dielectric` gives (two independent runs, within 4
  combined σ) along its mirror and Snell directions (within 2e-3, GGX's 99th percentile at that α).
- Polarization: at Brewster's angle (α = 1e-4) a p-polarized photon is not reflected, an s one with Rs = 0.147929
  (docs/REFERENCES.md), and the material calls for polarization by physics as `dielectric` does.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from ggx_reference import albedo
from scatter_contract import Case, mean_and_error

from tracer.effects import explain_effects
from tracer.optics.polarization import S1, E
from tracer.optics.surfaces import dielectric
from tracer.optics.surfaces.base import CONTINUES, GLOSSY, SPECULAR, TRANSMITS, MaterialError, spec_from_body

WHITE = ("white", 0.0, 0.0, 0.0, 0.0)
K = 4.0
N = 20_000
QUAD = 1e-3   # the midpoint rule's error bound (the transmitted lobe ends abruptly where the half vector turns flat)


def spec(**body):
    return spec_from_body(dielectric.Spec, "dielectric", {"type": "dielectric", **body}, "test")


def arriving(theta_deg: float, side: str = "front") -> np.ndarray:
    t = math.radians(theta_deg)
    d = -np.array([math.sin(t), 0.0, math.cos(t)])
    return d if side == "front" else -d * np.array([-1.0, 1.0, 1.0])   # from inside: travelling up


def shares(out):
    """(R, σR, T, σT): the fractions leaving on the arrival side and through, with their standard errors."""
    alive = out[:, 0] == CONTINUES
    up = out[:, 3] > 0
    r = mean_and_error(np.where(alive & up, out[:, 4], 0.0))
    t = mean_and_error(np.where(alive & ~up, out[:, 4], 0.0))
    return r[0], r[1], t[0], t[1]


@pytest.mark.parametrize(("alpha", "theta", "side", "expected"), [
    (0.2, 0.0, "front", (0.038221, 0.956842)), (0.5, 0.0, "front", (0.028175, 0.939939)),
    (1.0, 0.0, "front", (0.012702, 0.880639)), (0.5, 60.0, "front", (0.043935, 0.848903)),
    (0.5, 30.0, "back", (0.155562, 0.564751)), (0.3, 45.0, "back", (0.468422, 0.356206)),
    (0.5, 60.0, "back", (0.434486, 0.225282))])
def test_white_furnace_keeps_walters_reflected_and_transmitted_fractions(alpha, theta, side, expected):
    n1, n2 = (1.0, 1.5) if side == "front" else (1.5, 1.0)
    wi = np.array([math.sin(math.radians(theta)), 0.0, math.cos(math.radians(theta))])   # arrival side's frame
    r_ref, t_ref = albedo(wi, alpha, alpha, n1=n1, n2=n2)
    assert (r_ref, t_ref) == pytest.approx(expected, abs=1e-6)
    out, _ = Case(dielectric, spec(ior=1.5, alpha=alpha), side, theta, arriving(theta, side), WHITE).run(
        n=N, seed=3)
    r, er, t, et = shares(out)
    if side == "back":
        r, t = t, r   # from inside, the arrival side is −z
    assert abs(r - r_ref) <= K * er + QUAD and abs(t - t_ref) <= K * et + QUAD, (r, er, r_ref, t, et, t_ref)
    assert r + t < 1.0


@pytest.mark.parametrize(("theta", "side"), [(0.0, "front"), (45.0, "front"), (80.0, "front"), (30.0, "back"),
                                             (60.0, "back")])
def test_the_smooth_limit_is_the_dielectric(theta, side):
    d = arriving(theta, side)
    rough, _ = Case(dielectric, spec(ior=1.5, alpha=1e-4), side, theta, d, WHITE).run(n=N, seed=4)
    smooth, _ = Case(dielectric, spec_from_body(dielectric.Spec, "dielectric", {"type": "dielectric", "ior": 1.5},
                                                "test"), side, theta, d, WHITE).run(n=N, seed=5)
    a, b = shares(rough), shares(smooth)
    for k in (0, 2):
        assert abs(a[k] - b[k]) <= K * math.hypot(a[k + 1], b[k + 1]) + 1e-12, (a, b)
    assert (rough[:, 0] == CONTINUES).mean() > 0.999          # at α = 1e-4 next to nothing is shadowed
    # every photon leaves along the dielectric's mirror or Snell direction (the smooth kind's photons give them)
    alive = smooth[:, 0] == CONTINUES
    for sign in (1.0, -1.0):
        on = alive & (np.sign(smooth[:, 3]) == sign)
        if not on.any():
            continue
        exact = smooth[on, 1:4][0]
        mine = rough[(rough[:, 0] == CONTINUES) & (np.sign(rough[:, 3]) == sign), 1:4]
        assert np.percentile(np.linalg.norm(mine - exact, axis=1), 99) < 2e-3


def test_at_brewsters_angle_only_s_is_reflected():
    """Smooth limit, n = 1.5 at atan(1.5) = 56.3099°: Rp = 0, Rs = 0.147929, unpolarized (Rs + Rp)/2."""
    theta = math.degrees(math.atan(1.5))
    d = arriving(theta)
    s_dir = np.array([0.0, 1.0, 0.0])                   # across the plane of incidence (x, z)
    p_dir = np.cross(d, s_dir)
    for e, state, rs in ((p_dir, ("linear", 1.0, 1.0, 0.0, 0.0), 0.0), (s_dir, ("linear", 1.0, 1.0, 0.0, 0.0),
                                                                        0.147929),
                         (s_dir, ("unpolarized", 1.0, 0.0, 0.0, 0.0), 0.147929 / 2)):
        case = Case(dielectric, spec(ior=1.5, alpha=1e-4), "front", theta, d, state)
        case.pol0[E:E + 3] = e
        assert case.pol0[S1] == state[2]
        r, er, _, _ = shares(case.run(n=N, seed=6)[0])
        assert abs(r - rs) <= K * max(er, math.sqrt(max(rs, 1e-3) * (1 - rs) / N)), (r, rs)


def test_a_rough_glass_calls_for_polarization_as_the_dielectric_does():
    rough = spec(ior=1.5, alpha=0.3)
    on, why = explain_effects([rough])
    assert "polarization" in on and "fresnel" in on and why["polarization"].startswith("on: ")
    assert "'dielectric'" in why["polarization"]
    assert dielectric.polarizing(rough) == (2, 1.0)
    assert explain_effects([spec(ior=1.0, alpha=0.3)])[0] == ["lambertian", "fresnel"]


def test_the_row_keeps_the_index_where_a_nested_solid_reads_it():
    """A solid inside this one reads its index from column 0 of the row (`dielectric.scatter`), as for a dielectric;
    roughness sits where `microfacet` keeps it."""
    row = dielectric.row(spec(ior=1.7, alpha=0.1, alpha_y=0.3, axis=[1, 0, 0]))
    assert row[0] == 1.7 and tuple(row[4:]) == (0.1, 0.3, 1.0, 0.0, 0.0, 1.0)


@pytest.mark.parametrize(("body", "field"), [
    ({"alpha": 5e-5, "ior": 1.5}, "'alpha'"), ({"alpha": 1.5, "ior": 1.5}, "'alpha'"),
    ({"alpha": 0.1, "alpha_y": -1, "ior": 1.5}, "'alpha_y'"),
    ({"alpha": 0.1, "axis": [0, 0, 0], "ior": 1.5}, "'axis'"), ({"alpha": 0.1, "ior": 0}, "'ior'"),
    ({"alpha": 0.1}, "'ior'"), ({"ior": 1.5, "alpha_y": 0.2}, "'alpha'"),
    ({"alpha": 0.1, "ior": 1.5, "medium": {"type": "homogeneous", "g": 1.0}}, "'g'"),
    ({"alpha": 0.1, "ior": 1.5, "roughness": 2}, "'roughness'")])
def test_bad_bodies_name_their_field(body, field):
    with pytest.raises(MaterialError) as info:
        spec(**body)
    assert field in str(info.value)


def test_the_former_kind_reads_as_a_rough_dielectric():
    """``rough_dielectric`` was a kind of its own until 2026-12-07: its bodies read as a dielectric with their alpha
    (the same spec, so the same packed rows), it still requires alpha > 0, and the rough surface's lobes are glossy."""
    from tracer.optics.surfaces.dispatch import flags_of, material_spec

    old = {"type": "rough_dielectric", "ior": 1.5, "alpha": 0.05, "alpha_y": 0.3, "axis": [1, 0, 0],
           "absorption_per_m": 0.5}
    assert material_spec(old) == material_spec({**old, "type": "dielectric"})
    assert flags_of(material_spec(old)) == GLOSSY | TRANSMITS
    assert flags_of(spec(ior=1.5)) == SPECULAR | TRANSMITS
    for body, message in (({"type": "rough_dielectric", "ior": 1.5}, "missing field(s) ['alpha']"),
                          ({"type": "rough_dielectric", "ior": 1.5, "alpha": 0}, "must be at least 0.0001")):
        with pytest.raises(MaterialError) as info:
            material_spec(body)
        assert message in str(info.value)
