"""Particle media through the forward tracer: Beer–Lambert extinction by Mie cross-sections, Rayleigh's 90°
polarization, a Mie medium against Henyey–Greenstein of the same g, and every optical element at once.

Tolerances: four standard errors of the estimate plus the stated model error.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.optics.mie import Particles, mie_table
from tracer.optics.surfaces.base import MaterialError
from tracer.scene import Scene
from tracer.simulate import Simulation
from tracer.warmup import box

LINE = {"type": "monochromatic", "nm": 550}


def _beam(radius, origin=(0, 0, 1), direction=(0, 0, -1), **extra):
    return {"type": "collimated", "origin": list(origin), "direction": list(direction), "radius": radius,
            "illuminance_lx": 100.0, "spectrum": LINE, **extra}


def _one(lo, hi):
    s = Scene()
    i = s.add_instance(s.add_geometry(*box(lo, hi)), np.eye(4))
    s.commit()
    return s, i


def test_a_slab_of_spheres_transmits_exp_minus_n_c_ext_l():
    """Polystyrene spheres (r = 0.5 µm, n = 1.59) in an index-1 host, 0.1 m: the unscattered beam keeps
    exp(−N C_ext L) of its illuminance. A receiver of 5 mm at 10 m sees 8e-7 sr: the light the spheres scatter
    into it (τ p(0) Ω, p(0) < 100/sr) is below 1e-4 of the beam, the model error allowed."""
    p = {"radius_um": 0.5, "ior": [1.59, 0.0], "number_per_m3": 1e12}
    scene, slab = _one([-5, -5, -0.1], [5, 5, 0])
    sim = Simulation(scene, {slab: {"type": "dielectric", "ior": 1.0, "particles": p}}, [_beam(0.01)])
    assert sim.effects == ["lambertian", "fresnel", "spectral", "mie", "polarization"]   # Mie polarizes (issue 38)
    res = sim.illuminance([[0, 0, -10]], [[0, 0, 1]], radius=0.005, max_photons=200_000, seed=1)
    sigma_ext = mie_table(Particles(0.5, 1.59, 0.0, 1e12), np.ones(471)).sigma_ext[550 - 360]
    expected = 100.0 * math.exp(-sigma_ext * 0.1)
    assert 1.0 < sigma_ext * 0.1 * 10 < 3.0       # a real extinction: τ ≈ 0.18
    assert abs(res.lux[0] - expected) <= 4 * res.stderr[0] + 1e-4 * 100.0, (res.lux, expected, res.stderr)


def test_small_spheres_scatter_fully_polarized_light_at_90_degrees():
    """Rayleigh limit (r = 5 nm, x = 0.057): unpolarized light scattered at 90° is polarized across the
    scattering plane. The receiver sees 90° ± 6° (DOP ≥ 1 − 2 cos² 84° = 0.978) and τ = 0.05 lets ~2.5 % of
    the light scatter twice (at worst unpolarized): DOP ≥ 0.95."""
    scene, blob = _one([-0.05, -0.05, -0.05], [0.05, 0.05, 0.05])
    p = {"radius_um": 0.005, "ior": [1.5, 0.0], "number_per_m3": 2.6e21}
    sim = Simulation(scene, {blob: {"type": "dielectric", "ior": 1.0, "particles": p}}, [_beam(0.02)])
    res = sim.illuminance([[1, 0, 0], [0, 1, 0]], [[-1, 0, 0], [0, -1, 0]], radius=0.05, max_photons=1_000_000,
                          seed=2, observe=["stokes"], reference=[0, 0, 1])
    for k in range(2):
        assert res.stokes[k, 0] > 0 and res.dop[k] >= 0.95, (res.stokes, res.dop)
        assert res.stokes[k, 1] < -0.95 * res.stokes[k, 0]     # along the receiver's x = z: I_z ≪ I_across


def test_a_mie_medium_transmits_like_henyey_greenstein_of_the_same_g_through_a_thin_slab():
    """Single scattering dominates (τ ≈ 0.18): the total flux through the slab's far side depends on the phase
    function only through how much goes forward; with g ≈ 0.7 both media send the same light through to 1 %."""
    p = {"radius_um": 0.5, "ior": [1.59, 0.0], "number_per_m3": 1e12}
    t = mie_table(Particles(0.5, 1.59, 0.0, 1e12), np.ones(471))
    g, sigma_s = float(t.g[190]), float(t.sigma_sca[190])
    hg = {"type": "dielectric", "ior": 1.0, "scattering_per_m": sigma_s, "g": g,
          "absorption_per_m": float(t.sigma_ext[190] - sigma_s)}
    below = []
    for mat in ({"type": "dielectric", "ior": 1.0, "particles": p}, hg):
        scene, slab = _one([-5, -5, -0.1], [5, 5, 0])
        sim = Simulation(scene, {slab: mat}, [_beam(0.01)])
        below.append(sim.illuminance([[0, 0, -0.1001]], [[0, 0, 1]], radius=0.5, max_photons=200_000, seed=3))
    (mie, hgr) = below
    assert abs(mie.lux[0] - hgr.lux[0]) <= 4 * math.hypot(mie.stderr[0], hgr.stderr[0]) + 0.01 * hgr.lux[0]


def test_particles_in_a_dielectric_are_validated():
    base = {"type": "dielectric", "ior": 1.5}
    scene, slab = _one([0, 0, 0], [1, 1, 1])
    cases = [({"radius_um": 0.5, "ior": [1.59, 0.0], "number_per_m3": 1e12, "shape": "cube"}, "unknown"),
             ({"radius_um": -1, "ior": [1.59, 0.0], "number_per_m3": 1e12}, "radius_um"),
             ({"radius_um": 0.5, "ior": [1.59], "number_per_m3": 1e12}, "ior"),
             ({"radius_um": 0.5, "ior": [1.59, 0.0], "number_per_m3": 1e30}, "number_per_m3"),
             ({"radius_um": 1001, "ior": [1.59, 0.0], "number_per_m3": 1.0}, "radius_um")]
    for particles, match in cases:
        with pytest.raises(MaterialError, match=match):
            Simulation(scene, {slab: {**base, "particles": particles}}, [_beam(0.01)])
    with pytest.raises(MaterialError, match="size parameter"):   # x = 2π 1000 µm × 2 / 360 nm > 3e4: not built
        Simulation(scene, {slab: {**base, "ior": 2.0, "particles": {"radius_um": 1000, "ior": [2.5, 0.0],
                                                                     "number_per_m3": 1.0}}}, [_beam(0.01)])
    good = {"radius_um": 0.5, "ior": [1.59, 0.0], "number_per_m3": 1e12}
    with pytest.raises(MaterialError, match="not both"):
        Simulation(scene, {slab: {**base, "scattering_per_m": 1.0, "particles": good}}, [_beam(0.01)])


def test_everything_on_at_once_neither_rejects_nor_gains_power():
    """A polarized, spectral beam through a retarder, a polarizer, a coated and dispersive glass block holding
    absorbing spheres and fluorescing, onto a metal mirror, inside a closed box of receivers: no photon is
    rejected and the power the receivers catch is at most what the light emits (+ 4σ). The receivers are the disks
    inscribed in the box's faces: a photon leaves the box once, through at most one of them."""
    s = Scene()
    half = 2.0

    def sheet(z):
        v = np.array([[-1, -1, z], [1, -1, z], [1, 1, z], [-1, 1, z]], float)
        return s.add_instance(s.add_geometry(v, np.array([[0, 1, 2], [0, 2, 3]])), np.eye(4))

    ret, pol = sheet(0.9), sheet(0.8)
    glass = s.add_instance(s.add_geometry(*box([-0.3, -0.3, 0.2], [0.3, 0.3, 0.5])), np.eye(4))
    mirror = s.add_instance(s.add_geometry(*box([-1, -1, -0.5], [1, 1, -0.4])), np.eye(4))
    s.commit()
    mats = {ret: {"type": "retarder", "fast_axis": [1, 0, 0], "retardance_deg": 60},
            pol: {"type": "polarizer", "axis": [1, 1, 0], "extinction_ratio": 1e3},
            glass: {"type": "dielectric", "ior": {"sellmeier": {"b": [1.03961212, 0.231792344, 1.01046945],
                                                               "c_um2": [0.00600069867, 0.0200179144, 103.560653]}},
                    "coating": {"layers": [{"ior": 1.38, "thickness_nm": 99.64}]},
                    "particles": {"radius_um": 0.3, "ior": [1.8, 0.01], "number_per_m3": 5e12},
                    "fluorescence": {"absorption_per_m": 2.0, "quantum_yield": 0.8,
                                     "emission": {"type": "monochromatic", "nm": 560}}},
            mirror: {"type": "mirror", "metal": [0.96, 6.69]}}
    light = _beam(0.25, origin=(0.05, 0, 1.0), direction=(0.1, 0.05, -1), spectrum={"type": "blackbody",
                                                                                    "kelvin": 5000},
                  polarization={"type": "linear", "axis": [1, 0, 0]})
    sim = Simulation(s, mats, [light])
    assert {"polarization", "mie", "coating", "dispersion", "fluorescence", "spectral"} <= set(sim.effects)
    faces = [([0, 0, half], [0, 0, -1]), ([0, 0, -half], [0, 0, 1]), ([half, 0, 0], [-1, 0, 0]),
             ([-half, 0, 0], [1, 0, 0]), ([0, half, 0], [0, -1, 0]), ([0, -half, 0], [0, 1, 0])]
    res = sim.grid([-half, -half, -half + 1e-6], [2 * half, 0, 0], [0, 2 * half, 0], 1, 1, max_photons=100_000,
                   seed=4, observe=["stokes"])
    assert res.rejected == 0 and np.all(np.isfinite(res.stokes)) and np.all(np.isfinite(res.lux))
    caught = 0.0
    err2 = 0.0
    for centre, normal in faces:
        r = sim.illuminance([centre], [normal], radius=2.0, max_photons=100_000, seed=5, observe=["stokes"])
        assert r.rejected == 0 and np.all(np.isfinite(r.stokes)) and np.all(r.dop[np.isfinite(r.dop)] <= 1 + 1e-9)
        caught += r.lux[0] * math.pi * 2.0 ** 2
        err2 += (r.stderr[0] * math.pi * 2.0 ** 2) ** 2
    emitted = 100.0 * math.pi * 0.25 ** 2
    assert caught <= emitted + 4 * math.sqrt(err2), (caught, emitted)
    assert caught > 0.05 * emitted


def test_a_polarized_mie_scattering_takes_its_frame_across_the_direction_whatever_it_was_left():
    """A depolarizing event (a diffuse bounce, a re-emission) may leave the frame axis along the new direction;
    the next Mie scattering must still scatter by the phase function: the mean cos θ over many events is g."""
    from tracer.optics import polarization as P
    from tracer.optics.media.homogeneous import mie_scatter
    from tracer.optics.mie import packed
    from tracer.rng import path_key

    t = mie_table(Particles(0.5, 1.59, 0.0, 1e12), np.ones(471))
    tab = packed(t)
    n = 20_000
    mus = np.empty(n)
    for i in range(n):
        pol = np.zeros(P.N_POL)
        pol[P.ON] = 1.0
        pol[P.E + 2] = 1.0            # stale: along d
        dx, dy, dz, _ = mie_scatter(tab, 0, 0.0, 0.0, 1.0, 550.0, np.uint64(path_key(7, 0, i)), 0, pol)
        mus[i] = dz
        assert abs(math.sqrt(dx * dx + dy * dy + dz * dz) - 1.0) < 1e-12
    g = float(t.g[550 - 360])
    assert abs(mus.mean() - g) <= 4 * mus.std() / math.sqrt(n), (mus.mean(), g)
