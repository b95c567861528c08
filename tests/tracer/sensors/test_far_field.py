"""The far-field tally (`Simulation.far_field`, `tracer.transport.forward.SensorArrays.far`): the luminous intensity
(cd) of a scene seen from far away against closed forms and a real luminaire file, and proof that it observes and
changes nothing."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tests.tracer.transport_scenes import box, quad, scene_of
from tracer.optics.surfaces.dispatch import bind
from tracer.photometry.files import parse_photometry
from tracer.scene import Scene
from tracer.simulate import Simulation, SimulationError, far_field_bins
from tracer.transport.forward import SensorArrays, forward_batches

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "photometry"
I_CD = 100.0
BLACK = {"type": "lambertian", "reflectance": 0.0}


def empty_scene():
    """A committed scene holding one small black square far off every ray of interest (below the lamp's
    horizon plane is never reached: it sits 1 km away to the side, 1 mm wide)."""
    s, (far,) = scene_of(quad((1000.0, 0.0, 0.0), (0.001, 0.0, 0.0), (0.0, 0.001, 0.0)))
    return s, far


def bin_mean(fn, c_deg, gamma_deg, n=24):
    """The solid-angle mean of fn(C, γ) (degrees) over each far-field bin (`FarFieldResult`), (nγ, nc)."""
    nc, ng = len(c_deg), len(gamma_deg)
    dc, dg = 360.0 / nc, 180.0 / (ng - 1)
    out = np.empty((ng, nc))
    s = (np.arange(n) + 0.5) / n
    for j, g in enumerate(gamma_deg):
        glo, ghi = max(g - dg / 2, 0.0), min(g + dg / 2, 180.0)
        cap = j in (0, ng - 1)
        # uniform in cos γ: equal solid angle per sub-band
        cg = np.cos(np.radians(glo)) + s * (np.cos(np.radians(ghi)) - np.cos(np.radians(glo)))
        gs = np.degrees(np.arccos(cg))
        for i, c in enumerate(c_deg):
            cs = (s * 360.0) if cap else (c - dc / 2 + s * dc)
            cc, gg = np.meshgrid(cs, gs)
            out[j, i] = float(fn(np.mod(cc, 360.0), gg).mean())
    return out


def test_isotropic_point_gives_its_intensity_in_every_bin():
    s, far = empty_scene()
    lamp = {"type": "point", "position": [0.0, 0.0, 0.0], "intensity_cd": I_CD}
    res = Simulation(s, {far: BLACK}, [lamp]).far_field(12, 19, max_photons=800_000, seed=5)
    assert res.candela.shape == res.stderr.shape == res.solid_angle.shape == (19, 12)
    np.testing.assert_allclose(res.c_deg, np.arange(12) * 30.0)
    np.testing.assert_allclose(res.gamma_deg, np.arange(19) * 10.0)
    assert res.solid_angle[0].sum() / 12 + res.solid_angle[1:-1].sum() + res.solid_angle[-1].sum() / 12 \
        == pytest.approx(4 * math.pi, rel=1e-12)
    assert np.all(res.stderr > 0)
    z = (res.candela - I_CD) / res.stderr
    assert np.max(np.abs(z)) < 4.0, np.unravel_index(np.argmax(np.abs(z)), z.shape)
    assert 0.7 < float(np.sqrt(np.mean(z[1:-1] ** 2))) < 1.3     # the reported errors are the real ones
    # every photon leaves (the square is not on any path of note): the total per batch is exact
    assert res.flux_lm == pytest.approx(4 * math.pi * I_CD, rel=1e-6)
    assert np.all(res.candela[0] == res.candela[0, 0]) and np.all(res.candela[-1] == res.candela[-1, 0])
    assert res.estimator == "forward" and res.stop_reason == "max_photons"


@pytest.mark.parametrize("name", ["rab_boa2_5.ies", "dekolight_acrux_452lm.ldt"])
def test_goniometric_light_gives_back_its_file(name):
    text = (FIXTURES / name).read_text()
    fmt = name.rsplit(".", 1)[1]
    ph = parse_photometry(fmt, text)
    s, far = empty_scene()
    # a turned frame: the lamp points along +x with C = 0 along +y; the far field asked in the same frame
    axis, c0 = [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]
    lamp = {"type": "goniometric", "position": [0.0, 0.0, 0.0], "format": fmt, "data": text, "direction": axis,
            "c0": c0}
    # 296 bins, 40 batches: a batch-means z has a t tail (seed 2 put one Acrux bin at 4.4 σ; at 3.2M photons that
    # bin read 2.7 σ and the worst one 2.7 σ)
    res = Simulation(s, {far: BLACK}, [lamp]).far_field(8, 37, direction=axis, c0=c0, max_photons=800_000, seed=3)
    ref = bin_mean(ph.intensity, res.c_deg, res.gamma_deg)
    lit = ref > 1e-3 * ref.max()
    z = np.where(res.stderr > 0, (res.candela - ref) / np.where(res.stderr > 0, res.stderr, 1.0), 0.0)
    assert np.max(np.abs(z[lit])) < 4.0, (np.max(np.abs(z[lit])), res.candela[lit][np.argmax(np.abs(z[lit]))])
    assert np.all(res.candela[ref == 0.0] == 0.0)           # no light where the file has none
    assert abs(res.flux_lm - ph.total_flux()) < 4 * res.flux_stderr


def test_mirror_plane_doubles_the_upper_half_space():
    """A point source h above a large horizontal mirror of reflectance ρ: seen from above, the source and its
    image, (1 + ρ) I; below, nothing where the mirror covers the view, and I beyond its edge."""
    rho, h, a = 0.8, 0.01, 10.0      # the mirror reaches out to γ = atan(a/h) = 89.94° (corners further)
    s, (mirror,) = scene_of(quad((-a, -a, 0.0), (2 * a, 0.0, 0.0), (0.0, 2 * a, 0.0)))
    lamp = {"type": "point", "position": [0.0, 0.0, h], "intensity_cd": I_CD}
    res = Simulation(s, {mirror: {"type": "mirror", "reflectance": rho}}, [lamp]).far_field(
        8, 19, max_photons=800_000, seed=9)
    g = res.gamma_deg
    up = g - 5.0 >= 90.0 - 1e-9               # bins wholly above the horizon
    down = g + 5.0 <= 90.0 + 1e-9              # wholly below, the mirror under them
    z = (res.candela[up] - (1 + rho) * I_CD) / res.stderr[up]
    assert np.max(np.abs(z)) < 4.0
    assert np.all(res.candela[down] == 0.0)
    # the horizon bin: its upper half (1 + ρ) I, its lower half 0 up to the mirror's edge
    omega = res.solid_angle[9, 0]
    half = 2 * math.pi / 8 * (math.cos(math.radians(90.0)) - math.cos(math.radians(95.0)))
    exact = (1 + rho) * I_CD * half / omega
    assert abs(res.candela[9].mean() - exact) < 4 * math.sqrt(np.mean(res.stderr[9] ** 2) / 8) + 0.01 * exact
    # what leaves: half the flux directly, ρ times the other half (and the sliver past the edge, < 0.06 %)
    exact_flux = 2 * math.pi * I_CD * (1 + rho)
    assert abs(res.flux_lm - exact_flux) < 4 * res.flux_stderr + 6e-4 * exact_flux


def test_far_field_changes_nothing():
    """Same batches with and without the far-field tally: every receiver bin and counter bit-identical."""
    fv, ft = quad((-3.0, -3.0, 0.0), (6.0, 0.0, 0.0), (0.0, 6.0, 0.0))
    s, (floor, block) = scene_of((fv, ft), box((0.3, -0.4, 0.0), (1.0, 0.4, 0.8)))
    lamp = {"type": "point", "position": [0.0, 0.0, 2.0], "intensity_cd": I_CD}
    sim = Simulation(s, {floor: {"type": "lambertian", "reflectance": 0.5},
                         block: {"type": "mirror", "reflectance": 0.7}}, [lamp])
    receivers = Scene()
    rid = receivers.add_rect_sensor((-2.0, -2.0, 0.01), (4.0, 0.0, 0.0), (0.0, 4.0, 0.0))
    receivers.commit()
    n = rid + 1
    bin0, nu, nv = np.full(n, -1, np.int64), np.ones(n, np.int64), np.ones(n, np.int64)
    bin0[rid], nu[rid], nv[rid] = 0, 8, 8
    plain = SensorArrays(bin0, nu, nv, np.zeros(2, np.int64), np.zeros((n, 3)))
    surf = np.full(max(floor, block) + 1, -1, np.int64)
    surf[floor] = 64
    far = np.array([64 + len(ft), 6, 7, 0, 0, -1, 1, 0, 0, 0, 1, 0], np.float64)
    tallied = plain._replace(surf=surf)
    both = tallied._replace(far=far)
    args = (s.arrays(), receivers.arrays(), bind(s.arrays(), sim._mats), sim._lights)
    out0, c0 = forward_batches(*args, plain, 64, 11, 0, 3, 20_000)
    out1, c1 = forward_batches(*args, tallied, 64 + len(ft), 11, 0, 3, 20_000)
    out2, c2 = forward_batches(*args, both, 64 + len(ft) + 43, 11, 0, 3, 20_000)
    assert np.array_equal(out0, out2[:, :64]) and np.array_equal(out1, out2[:, :64 + len(ft)])
    assert np.array_equal(c0, c2)
    far_bins = out2[:, 64 + len(ft):]
    assert np.all(far_bins[:, -1] > 0)
    np.testing.assert_allclose(far_bins[:, :-1].sum(axis=1), far_bins[:, -1], rtol=1e-12)


def test_bins_and_bad_input():
    c, g, omega = far_field_bins(4, 3)
    np.testing.assert_allclose(c, [0, 90, 180, 270])
    np.testing.assert_allclose(g, [0, 90, 180])
    np.testing.assert_allclose(omega[0], 2 * math.pi * (1 - math.cos(math.radians(45))))
    np.testing.assert_allclose(omega[1], 2 * math.pi * 2 * math.cos(math.radians(45)) / 4)
    s, far = empty_scene()
    sim = Simulation(s, {far: BLACK}, [{"type": "point", "position": [0.0, 0.0, 0.0], "intensity_cd": 1.0}])
    for kw, what in (({"nc": 0}, "nc must be"), ({"nc": 2.5}, "nc must be"), ({"ngamma": 1}, "ngamma must be"),
                     ({"nc": True}, "nc must be"), ({"direction": [0, 0, 0]}, "zero vector"),
                     ({"c0": [0, 0, 2]}, "parallel"), ({"direction": [1, 2]}, "3 finite numbers"),
                     ({"c0": [float("nan"), 0, 0]}, "3 finite numbers")):
        args = {"nc": 4, "ngamma": 5, **kw}
        with pytest.raises(SimulationError, match=what):
            sim.far_field(max_photons=1000, **args)
