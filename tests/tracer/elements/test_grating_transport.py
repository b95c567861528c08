"""A grating on a part's face in the tracer (`tracer.elements.diffraction`, issue 52): light leaves in the orders of
the grating equation and nowhere else, each with the efficiency of the wave solution; two wire grids pass what
their Jones matrices say, crossed and parallel, which a tracer without polarization cannot; the answer counts the
photons that met a grating where its table ran out.

The gratings sit on a sheet (one rectangle, facing +z): every photon meets each face once per passage, so the
closed forms below hold without a plate's internal reflections."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.elements import grating as g
from tracer.elements.diffraction import mueller
from tracer.scene import Scene
from tracer.simulate import Simulation

GLASS = {"type": "dielectric", "ior": 1.5}
LAMBDA = 550.0
PERIOD = 2.0          # um: lambda / period = 0.275
THETA = 10.0          # deg, incidence in the plane of the grating vector (+x)
SIGMAS = 4.0
#: a lamellar glass grating whose table holds the beam's incidence exactly (no interpolation)
GLASS_GRATING = {"type": "grating", "profile": {"shape": "lamellar", "fill": 0.5}, "period_um": PERIOD,
                 "depth_um": 0.3, "ridge": None, "substrate_ior": 1.5, "wavelengths_nm": [LAMBDA, LAMBDA],
                 "angles": {"polar_deg": [0.0, THETA, 20.0], "azimuth_deg": [0.0, 180.0]}, "orders": 10}
#: aluminium lines (n - ik at 550 nm, Rakic 1995) 140 nm apart in air: a wire-grid polarizer
WIRE_GRID = {"type": "grating", "profile": {"shape": "lamellar", "fill": 0.5}, "period_um": 0.14, "depth_um": 0.1,
             "ridge": {"ior": [0.958, 6.69]}, "substrate_ior": 1.0, "wavelengths_nm": [LAMBDA, LAMBDA],
             "angles": {"polar_deg": [0.0], "azimuth_deg": [0.0]}, "orders": 10}


def _sheets(table, heights, grooves):
    """A scene of 20 x 20 mm sheets at the given heights (m), each carrying `table` on its +z face, the grooves of
    sheet k along `grooves[k]` of the face (a second table with grooves along u where asked)."""
    s = Scene()
    v = np.array([[0, 0, 0], [0.02, 0, 0], [0.02, 0.02, 0], [0, 0.02, 0]], float)
    t = np.array([[0, 1, 2], [0, 2, 3]])
    geom = s.add_geometry(v, t)
    parts = []
    for z, along in zip(heights, grooves, strict=True):
        tr = np.eye(4)
        tr[2, 3] = z
        part = s.add_instance(geom, tr)
        s.set_element(part, table[along], facing=[0, 0, 1])
        parts.append(part)
    s.commit()
    return s, parts


def _beam(theta_deg=0.0, nm=LAMBDA, azimuth_deg=0.0):
    th, az = math.radians(theta_deg), math.radians(azimuth_deg)
    d = np.array([math.sin(th) * math.cos(az), math.sin(th) * math.sin(az), -math.cos(th)])
    return {"type": "collimated", "origin": (np.array([0.01, 0.01, 0.0]) + 0.02 / d[2] * d).tolist(),
            "direction": d.tolist(), "radius": 0.002, "illuminance_lx": 1000.0,
            "spectrum": {"type": "monochromatic", "nm": nm}}


def test_orders_leave_along_the_grating_equation_with_the_wave_solutions_efficiencies():
    """n_out sin θ_m = sin θ_i + mλ/Λ: a collimated 550 nm beam at 10° on a 2 µm glass grating leaves in the
    transmitted orders (into the glass, n 1.5: |sin θ_i + mλ/Λ| < 1.5, eleven of them) and the reflected ones (< 1,
    eight), and nowhere else: every far-field bin that holds no order stays exactly dark. Each order carries the
    share of the beam the RCWA table gives it (unpolarized: the mean of s and p), within the far field's own
    standard errors."""
    tab = g.prepare(GLASS_GRATING)
    s, (part,) = _sheets({"v": tab}, [0.0], ["v"])
    sim = Simulation(s, {part: GLASS}, [_beam(THETA)])
    assert {"diffraction", "spectral"} <= set(sim.effects)
    assert sim.effect_reasons["diffraction"] == "on: called for by a grating element"
    r = sim.far_field(2, 181, max_photons=40_000, seed=3)   # 1° bins of γ from the nadir; C 0 (+x) and 180
    flux = r.candela * r.solid_angle
    err = r.stderr * r.solid_angle
    total = float(flux.sum())
    assert total == pytest.approx(1000.0 * math.pi * 0.002 ** 2, rel=1e-9)   # lossless: everything leaves
    expected = np.zeros_like(flux)
    a = int(np.flatnonzero(tab.polar_deg == THETA)[0])
    for k, (m, _) in enumerate(tab.orders):
        sx = math.sin(math.radians(THETA)) + m * LAMBDA / 1000.0 / PERIOD
        for side, n in ((0, 1.0), (1, 1.5)):
            if abs(sx) >= n:
                continue
            gamma = math.degrees(math.asin(abs(sx) / n))
            row = round(180.0 - gamma if side == 0 else gamma)   # reflected orders go up (γ from the nadir)
            expected[row, 0 if sx > 0 else 1] += float(tab.unpolarized[0, a, 0, side, k]) * total
    dark = expected == 0.0
    assert dark.sum() > 300 and (flux[dark] == 0.0).all(), np.argwhere(flux * dark)
    lit = ~dark
    assert lit.sum() == 19
    assert (np.abs(flux[lit] - expected[lit]) <= SIGMAS * err[lit] + 1e-9 * total).all(), \
        np.column_stack([flux[lit], expected[lit], err[lit]])
    assert r.counters["grating_outside_table"] == 0


def _normal(tab, inside=False):
    """(T, R) of the zeroth order at normal incidence, for s (E along the grooves) and p: ((Ts, Tp), (Rs, Rp))."""
    t = tab.inside if inside else tab
    k = tab.order_index(0)
    e = t.efficiency[0, 0, 0, :, :, k].astype(float)   # [pol, side]
    return e[:, 1], e[:, 0]


@pytest.mark.parametrize("oblique", [False, True], ids=["normal", "half a degree, azimuth 30"])
def test_two_wire_grids_pass_what_their_jones_matrices_say_crossed_and_parallel(oblique):
    """Unpolarized light through two wire grids 10 mm apart, at normal incidence. Each grid acts on E along its
    wires (s: Ts, Rs) and across them (p: Tp, Rp) apart, so each linear polarization of the first grid's frame goes
    its own way, with incoherent reflections between the grids: parallel grids pass ½ (Ts² / (1 − Rs Rs') + Tp² /
    (1 − Rp Rp')), crossed ones Ts Tp / (1 − Rs Rp') (and the same with s and p swapped: half each), R' the
    reflectance of the first grid seen from below. Crossed, that is the leak Ts times what passes, orders of
    magnitude below the ((Ts + Tp) / 2)² a tracer without polarization would give.

    Half a degree off the normal, at an azimuth of 30° to the first grid's vector (60° to the second's), on a table
    of polar 0 and 10° and azimuths 0, 90, 180: every photon takes a table point at another azimuth, whose values
    are in that point's own (s, p) bases, turned 30° or 60° from the photon's. Read in the point's bases (the
    polarization keeps its direction in space) the pair acts as at normal incidence; with only the normal points
    read so and the 10° ones by their labels in the photon's bases, the crossed pair leaked 0.013 (19 times the
    closed form), and reading every point by labels turns the polarization by the full 30°.
    The 5 % of photons at the 10° points may move the parallel pair by a few percent and the crossed leak by a few
    times its own size: the closed forms at normal incidence, with those margins."""
    grid = {**WIRE_GRID, "angles": {"polar_deg": [0.0, 10.0], "azimuth_deg": [0.0, 90.0, 180.0]}} if oblique \
        else WIRE_GRID
    table = {"v": g.prepare(grid), "u": g.prepare({**grid, "grooves_along": "u"})}
    (ts, tp), (rs, rp) = _normal(table["v"])
    (_, _), (rs_in, rp_in) = _normal(table["v"], inside=True)
    assert tp > 0.5 and ts < 0.05 * tp     # a polarizer: its extinction below
    flux0 = 1000.0 * math.pi * 0.002 ** 2
    below = ([0.0, 0.0, -0.005], [0.02, 0.0, 0.0], [0.0, 0.02, 0.0], 1, 1)
    out = {}
    for name, grooves in (("parallel", ["v", "v"]), ("crossed", ["v", "u"])):
        s, parts = _sheets(table, [0.01, 0.0], grooves)
        sim = Simulation(s, {p: GLASS for p in parts}, [_beam(0.5, azimuth_deg=30.0) if oblique else _beam()])
        assert "polarization" in sim.effects   # by physics: two diattenuators in a row
        r = sim.grid(*below, max_photons=400_000, seed=7, estimator="forward")
        out[name] = (float(r.lux[0, 0]) * 0.02 ** 2 / flux0, float(r.stderr[0, 0]) * 0.02 ** 2 / flux0)
    parallel = 0.5 * (ts * ts / (1.0 - rs * rs_in) + tp * tp / (1.0 - rp * rp_in))
    crossed = 0.5 * (ts * tp / (1.0 - rp * rs_in) + tp * ts / (1.0 - rs * rp_in))
    margin = {"parallel": 0.05 * parallel, "crossed": 3.0 * crossed} if oblique else {"parallel": 0.0, "crossed": 0.0}
    for name, want in (("parallel", parallel), ("crossed", crossed)):
        got, err = out[name]
        assert abs(got - want) <= SIGMAS * err + margin[name] + 1e-6, (name, got, want, err)
    assert out["crossed"][0] < 0.1 * ((ts + tp) / 2.0) ** 2


def test_mueller_matrices_turn_stokes_vectors_as_their_jones_matrices_turn_fields():
    """S(J E) = M(J) S(E) for random Jones matrices and fields, with S1 = |Ex|² − |Ey|², S2 = 2 Re(Ex Ey*), S3 =
    2 Im(Ex Ey*) (`tracer.optics.polarization`); M00 is the mean of the two polarizations' powers."""
    rng = np.random.default_rng(4)

    def stokes(e):
        return np.array([abs(e[0]) ** 2 + abs(e[1]) ** 2, abs(e[0]) ** 2 - abs(e[1]) ** 2,
                         2 * (e[0] * e[1].conj()).real, 2 * (e[0] * e[1].conj()).imag])

    for _ in range(20):
        j = rng.normal(size=(2, 2)) + 1j * rng.normal(size=(2, 2))
        e = rng.normal(size=2) + 1j * rng.normal(size=2)
        assert mueller(j) @ stokes(e) == pytest.approx(stokes(j @ e), rel=1e-12, abs=1e-12)
        assert mueller(j)[0, 0] == pytest.approx(0.5 * (abs(j) ** 2).sum())


def test_a_wavelength_outside_the_table_is_counted_never_silent():
    """A 600 nm beam on a table solved at 550 nm only: the tracer uses the nearest table point and the answer counts
    each such photon (`grating_outside_table`)."""
    s, (part,) = _sheets({"v": g.prepare(GLASS_GRATING)}, [0.0], ["v"])
    r = Simulation(s, {part: GLASS}, [_beam(THETA, nm=600.0)]).far_field(2, 19, max_photons=2_000, seed=1)
    assert r.counters["grating_outside_table"] == r.photons


def test_a_moth_eye_face_reflects_what_its_wave_solution_says_far_below_flat_glass():
    """Cones 0.5 µm tall on a 0.25 µm square lattice of glass (sub-wavelength: only the zeroth orders leave) on the
    sheet, a 550 nm beam at normal incidence: the share of the beam going back up is the table's zeroth reflected
    order, within 4 standard errors, and far below the 4 % of the same sheet as a plain glass face (Fresnel,
    ((n − 1)/(n + 1))², which the plain sheet also returns)."""
    eye = g.prepare({"type": "grating", "profile": {"shape": "moth_eye", "fill": 1.0}, "period_um": 0.25,
                     "depth_um": 0.5, "substrate_ior": 1.5, "wavelengths_nm": [LAMBDA, LAMBDA],
                     "angles": {"polar_deg": [0.0, 30.0]}, "orders": 3, "layers": 8})
    up = {}
    for name, table in (("moth-eye", {"v": eye}), ("flat", None)):
        if table is None:
            s = Scene()
            v = np.array([[0, 0, 0], [0.02, 0, 0], [0.02, 0.02, 0], [0, 0.02, 0]], float)
            part = s.add_instance(s.add_geometry(v, np.array([[0, 1, 2], [0, 2, 3]])), np.eye(4))
            s.commit()
        else:
            s, (part,) = _sheets(table, [0.0], ["v"])
        r = Simulation(s, {part: GLASS}, [_beam()]).far_field(1, 3, max_photons=200_000, seed=2)
        flux = r.candela * r.solid_angle   # rows: the downward cap, the band around the horizon, the upward cap
        up[name] = (float(flux[2:].sum() / flux.sum()), float(r.stderr[2, 0] * r.solid_angle[2, 0] / flux.sum()))
    k = eye.order_index(0)
    want = float(eye.unpolarized[0, 0, 0, 0, k])
    got, err = up["moth-eye"]
    assert abs(got - want) <= SIGMAS * err, (got, want, err)
    flat = ((1.5 - 1.0) / (1.5 + 1.0)) ** 2
    assert up["flat"][0] == pytest.approx(flat, abs=SIGMAS * up["flat"][1])
    assert got < flat / 4.0, (got, up)
