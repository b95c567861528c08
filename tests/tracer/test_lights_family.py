"""The light family `tracer.optics.lights`: each kind's next-event connection against closed forms, the
registry's consistency, and emission that stays where the light emits."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from transport_scenes import quad, scene_of

from tracer.optics.lights import LightError, connectable, light_connect, pack_lights, sample_emission
from tracer.optics.lights import dispatch as lights_dispatch
from tracer.optics.lights.base import SHADOW_SHORTEN
from tracer.photometry.files import parse_photometry

FIX = Path(__file__).resolve().parents[1] / "fixtures" / "photometry"
UP = (0.0, 0.0, 1.0)


def connect_once(L, j, x, n, u=(0.5, 0.5, 0.5)):
    return light_connect(L, j, *map(float, x), *map(float, n), *u)


def connect_mean(L, j, x, n, samples, seed):
    """Mean and standard error of `samples` connections from x (lx)."""
    rng = np.random.default_rng(seed)
    e = np.array([connect_once(L, j, x, n, tuple(rng.random(3)))[0] for _ in range(samples)])
    return e.mean(), e.std(ddof=1) / math.sqrt(samples)


# ------------------------------------------------------------------------------------ connect vs closed forms


def test_point_connect_is_the_inverse_square_cosine_law():
    """E = I cosθ / d², deterministic; the shadow ray ends on the light (t_max = 1); nothing from behind."""
    L = pack_lights([{"type": "point", "position": [0.3, -0.2, 2.0], "intensity_cd": 250.0}])
    x = np.array([1.0, 0.5, 0.0])
    d = np.array([0.3, -0.2, 2.0]) - x
    e, sx, sy, sz, t_max = connect_once(L, 0, x, UP)
    assert e == pytest.approx(250.0 * d[2] / np.linalg.norm(d) ** 3, rel=1e-12)
    np.testing.assert_allclose(x + t_max * np.array([sx, sy, sz]), [0.3, -0.2, 2.0], rtol=0, atol=1e-12)
    assert t_max == 1.0
    assert connect_once(L, 0, x, (0.0, 0.0, -1.0))[0] == 0.0


def test_spot_connect_follows_the_profile_and_is_dark_outside_the_cone():
    """Inside cone − falloff I = I0, across the falloff a smoothstep in cosθ, outside the cone 0."""
    cone, fall, i0, h = 30.0, 10.0, 400.0, 2.0
    L = pack_lights([{"type": "spot", "position": [0, 0, h], "direction": [0, 0, -1], "cone_deg": cone,
                      "falloff_deg": fall, "intensity_cd": i0}])
    co, ci = math.cos(math.radians(cone)), math.cos(math.radians(cone - fall))
    for theta_deg in (0.0, 12.0, 19.9, 24.0, 29.0, 31.0, 60.0):
        theta = math.radians(theta_deg)
        x = (h * math.tan(theta), 0.0, 0.0)
        c = math.cos(theta)
        s = min(1.0, max(0.0, (c - co) / (ci - co)))
        want = i0 * s * s * (3 - 2 * s) * c / (h / c) ** 2
        e = connect_once(L, 0, x, UP)[0]
        assert e == pytest.approx(want, rel=1e-12, abs=0.0), theta_deg
    assert connect_once(L, 0, (h * math.tan(math.radians(31.0)), 0, 0), UP)[0] == 0.0


def test_goniometric_connect_reads_the_table():
    """E = I(C, γ) cosθ / d² with the file's bilinear intensity (γ from −z, C = 0 along +x, 90° along +y)."""
    text = (FIX / "rab_boa2_5.ies").read_text(encoding="latin-1")
    table = parse_photometry("ies", text)
    pos = np.array([0.0, 0.0, 3.0])
    L = pack_lights([{"type": "goniometric", "position": list(pos), "format": "ies", "data": text}])
    for x in ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.5, 0.0], [-2.0, -0.7, 0.0], [0.4, -3.0, 0.0]):
        d = np.array(x) - pos
        dist = float(np.linalg.norm(d))
        gamma = math.degrees(math.acos(-d[2] / dist))
        c = math.degrees(math.atan2(d[1], d[0])) % 360.0
        want = float(table.intensity(c, gamma)) * (-d[2] / dist) / dist**2
        assert connect_once(L, 0, x, UP)[0] == pytest.approx(want, rel=1e-9), x


def square_on_axis(side: float, h: float) -> float:
    """Configuration factor from a patch to a parallel square of `side` centred on its normal at distance h
    (four corner rectangles; F = 1/(2π) [A/√(1+A²) atan(B/√(1+A²)) + B/√(1+B²) atan(A/√(1+B²))])."""
    a = b = 0.5 * side / h
    ra, rb = math.sqrt(1 + a * a), math.sqrt(1 + b * b)
    return 4.0 * (a / ra * math.atan(b / ra) + b / rb * math.atan(a / rb)) / (2.0 * math.pi)


def test_area_connect_averages_to_the_configuration_factor():
    """A square of exitance M facing a patch on its axis: E = M F. The mean over samples agrees within 4.5σ
    of its own standard error; the shadow ray stops SHADOW_SHORTEN short of the emitter."""
    m_exit, side, h = 800.0, 1.0, 0.7
    s, (panel,) = scene_of(quad((-0.5, -0.5, h), (0, side, 0), (side, 0, 0)))   # front side −z
    L = pack_lights([{"type": "area", "instances": [panel], "exitance_lm_m2": m_exit}], s)
    mean, err = connect_mean(L, 0, (0, 0, 0), UP, 40_000, seed=7)
    want = m_exit * square_on_axis(side, h)
    assert abs(mean - want) < 4.5 * err, (mean, want, err)
    assert err < 0.01 * want   # the check has teeth
    e, sx, sy, sz, t_max = connect_once(L, 0, (0, 0, 0), UP, (0.3, 0.6, 0.2))
    assert e > 0 and t_max == 1.0 - SHADOW_SHORTEN and sz == pytest.approx(h)
    assert connect_once(L, 0, (0, 0, 2 * h), UP)[0] == 0.0        # behind the emitter
    assert connect_once(L, 0, (0, 0, 0), (0, 0, -1.0))[0] == 0.0  # facing away


# ------------------------------------------------------------------------------------- what is not connectable


def test_collimated_is_not_connectable_and_says_why():
    beam = {"type": "collimated", "origin": [0, 0, 2], "direction": [0, 0, -1], "radius": 0.5, "illuminance_lx": 100}
    lamp = {"type": "point", "position": [0, 0, 2], "flux_lm": 100.0}
    L = pack_lights([lamp, beam])
    assert connect_once(L, 1, (0, 0, 0), UP) == (0.0, 0.0, 0.0, 0.0, 0.0)
    ok, why = connectable(L)
    assert not ok and "collimated" in why and "shadow rays" in why
    assert connectable(pack_lights([lamp])) == (True, "")


# ----------------------------------------------------------------------------------------------- the registry

BODIES = {  # a minimal valid body of each kind (area: validated without a scene by Spec.from_body)
    "point": {"type": "point", "position": [0, 0, 1], "intensity_cd": 1.0},
    "spot": {"type": "spot", "position": [0, 0, 1], "direction": [0, 0, -1], "cone_deg": 30, "intensity_cd": 1.0},
    "collimated": {"type": "collimated", "origin": [0, 0, 1], "direction": [0, 0, -1], "width": 1, "height": 2,
                   "illuminance_lx": 1.0},
    "goniometric": {"type": "goniometric", "position": [0, 0, 1], "format": "ies",
                    "data": (FIX / "rab_dled6r8y_7.ies").read_text(encoding="latin-1")},
    "area": {"type": "area", "instances": [0], "exitance_lm_m2": 1.0},
}


def test_every_kind_keeps_the_contract_and_its_id_is_its_position():
    kinds = lights_dispatch.KINDS
    assert sorted(m.NAME for m in kinds) == sorted(BODIES)
    for k, module in enumerate(kinds):
        assert lights_dispatch.KIND_OF_NAME[module.NAME] == k
        assert dataclasses.is_dataclass(module.Spec) and module.Spec.__dataclass_params__.frozen
        assert callable(module.Spec.from_body) and callable(module.pack)
        assert callable(module.sample.py_func) and callable(module.connect.py_func)   # jitted
        assert isinstance(module.CONNECTABLE, bool) and module.EFFECTS == ()
        if not module.CONNECTABLE:
            assert module.NAME in module.WHY_NOT_CONNECTABLE
        assert isinstance(module.Spec.from_body(BODIES[module.NAME], "light 0"), module.Spec)
    d = lights_dispatch
    assert [d.POINT, d.SPOT, d.COLLIMATED, d.GONIOMETRIC, d.AREA] == \
        [kinds.index(m) for m in (d.point, d.spot, d.collimated, d.goniometric, d.area)]
    s, (panel,) = scene_of(quad((0, 0, 0), (1, 0, 0), (0, 1, 0)))
    bodies = [dict(BODIES[m.NAME], instances=[panel]) if m.NAME == "area" else BODIES[m.NAME] for m in kinds]
    assert list(pack_lights(bodies, s).kind) == list(range(len(kinds)))


@pytest.mark.parametrize("name", sorted(BODIES))
def test_every_kind_rejects_unknown_fields(name):
    with pytest.raises(LightError, match=rf"light 0: unknown field\(s\) \['colour'\] for a '{name}' light"):
        pack_lights([dict(BODIES[name], colour="red")])


# ---------------------------------------------------------------------------------------------------- emission


def test_spot_emission_stays_in_the_cone_and_puts_the_flux_where_the_profile_does():
    """Every photon leaves within the cone; the weighted fraction inside θi is 2π I0 (1 − cos θi) / Φ, within
    4σ, and the weights average to 1."""
    cone, fall, i0 = 35.0, 15.0, 100.0
    axis = np.array([0.3, -0.2, -1.0]) / np.linalg.norm([0.3, -0.2, -1.0])
    L = pack_lights([{"type": "spot", "position": [1, 2, 3], "direction": list(axis), "cone_deg": cone,
                      "falloff_deg": fall, "intensity_cd": i0}])
    rng = np.random.default_rng(3)
    out = np.array([sample_emission(L, 0, *rng.random(5)) for _ in range(40_000)])
    np.testing.assert_array_equal(out[:, 0:3], np.tile([1.0, 2.0, 3.0], (len(out), 1)))
    d, f = out[:, 3:6], out[:, 6]
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=0, atol=1e-12)
    cos_t = d @ axis
    assert np.all(cos_t >= math.cos(math.radians(cone)) - 1e-12)
    ci = math.cos(math.radians(cone - fall))
    inner = f * (cos_t >= ci)
    want = 2 * math.pi * i0 * (1 - ci) / L.flux_total[0]
    assert abs(inner.mean() - want) < 4 * inner.std(ddof=1) / math.sqrt(len(f)), (inner.mean(), want)
    assert f.mean() == pytest.approx(1.0, abs=4 * f.std(ddof=1) / math.sqrt(len(f)))
