"""The grating element's wave solution (issue 52): `tracer.elements.grating.prepare` solves a relief by RCWA (inkstone)
and keeps each propagating order's efficiency and Jones matrix. Checked against closed forms (the grating equation,
the scalar limit, effective-medium films, Fresnel), a published benchmark and published wire-grid figures; energy at
every table point; bad bodies refused with what to do."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.elements import grating as g
from tracer.elements.checks import ElementError
from tracer.optics import thinfilm

LOSSLESS_SUM = 1e-5
"""Energy: for real permittivities the truncated RCWA scattering matrix is itself unitary (power is conserved exactly
in the kept orders whatever the truncation), so the kept efficiencies sum to 1 up to rounding; the table stores them
as float32 (relative 6e-8 each, a few dozen orders). 1e-5 leaves room for that and for nothing else: a wrong
power scaling of the Jones matrices (kz ratio, projection onto s and p) moves the sum by percents."""


def _body(**over: object) -> dict:
    body = {"type": "grating", "profile": {"shape": "lamellar", "fill": 0.5}, "period_um": 1.2, "depth_um": 0.3,
            "ridge": None, "substrate_ior": 1.5, "wavelengths_nm": [550, 550],
            "angles": {"polar_deg": [0.0], "azimuth_deg": [0.0]}, "orders": 8}
    body.update(over)
    return body


def _sums(tab: g.GratingTable) -> np.ndarray:
    """Total efficiency (both sides, all orders) per table point and polarization: (W, A, Z, 2)."""
    return np.nansum(tab.efficiency.astype(np.float64), axis=(-1, -2))


def test_orders_leave_along_the_grating_equation_and_exactly_those_below_the_index_propagate() -> None:
    """sin θ_m = sin θ_i + mλ/Λ (in the plane of the grating vector), and in a conical mount the tangential wave
    vector is the incident's plus m times the grating vector; an order propagates on a side exactly where its
    tangential index |k_t| / k0 is below that side's n. The table's directions come from the solver's own wave
    vectors, its NaNs from their kz: both checked against the equation here."""
    both = g.prepare(_body(wavelengths_nm=[450, 650], wavelength_count=3,
                           angles={"polar_deg": [0.0, 25.0, 50.0], "azimuth_deg": [0.0, 30.0, 180.0]}))
    assert both.inside is not None
    # lit from the ambient (n 1) and from the substrate (n 1.5, the frame turned about x: reflected orders go back
    # into the substrate, transmitted ones out into the air)
    for tab, n_side in ((both, (1.0, 1.5)), (both.inside, (1.5, 1.0))):
        for i, lam in enumerate(tab.wavelength_nm):
            for a, th in enumerate(tab.polar_deg):
                for b, ph in enumerate(tab.azimuth_deg):
                    kt0 = n_side[0] * math.sin(math.radians(th)) * np.array([math.cos(math.radians(ph)),
                                                                             math.sin(math.radians(ph))])
                    for k, (m, _) in enumerate(tab.orders):
                        kt = kt0 + np.array([m * lam / 1000.0 / 1.2, 0.0])
                        for side in (0, 1):
                            expect = float(kt @ kt) < n_side[side] ** 2
                            got = np.isfinite(tab.efficiency[i, a, b, :, side, k])
                            assert got.all() == expect and got.any() == expect, (lam, th, ph, m, side)
                            if expect:
                                d = tab.direction[i, a, b, side, k].astype(float)
                                # a point where an order grazes (here 4 λ/Λ = 1.5 at 450 nm) is solved GRAZING longer
                                assert d[:2] * n_side[side] == pytest.approx(kt, abs=2e-5)
                                assert math.copysign(1.0, d[2]) == (-1.0 if side == 0 else 1.0)
                                if ph == 0.0 and side == 0:   # sin θ_m = sin θ_i + mλ/Λ, in the incident medium
                                    assert d[0] * n_side[0] == pytest.approx(
                                        n_side[0] * math.sin(math.radians(th)) + m * lam / 1200.0, abs=3e-5)
        assert abs(_sums(tab) - 1.0).max() < LOSSLESS_SUM
    tab = both
    # in the classical mount (azimuth 0 or 180: incidence in the plane of the grating vector) s stays s and p stays p
    # in every order (TE and TM decouple); in the conical mount (30°) the orders convert some of one into the other.
    # This checks the (s, p) bases of the incident and the diffracted waves, not just the powers.
    cross = np.abs(tab.jones[..., 0, 1]) ** 2 + np.abs(tab.jones[..., 1, 0]) ** 2
    assert np.nanmax(cross[:, :, [0, 2]]) < 1e-9
    assert np.nanmax(cross[:, 1:, 1]) > 1e-4
    # every order the table holds propagates somewhere, lit from one side or the other
    assert (np.isfinite(tab.efficiency).any(axis=(0, 1, 2, 3, 4)) |
            np.isfinite(tab.inside.efficiency).any(axis=(0, 1, 2, 3, 4))).all()


def test_scalar_limit_orders_follow_the_thin_phase_grating() -> None:
    """Period 20λ, a shallow lamellar phase grating of fill ½ and phase depth φ = 2π (n − 1) d / λ: scalar theory
    gives η±1/η0 = (2/π)² tan²(φ/2), η±3/η0 = (2/3π)² tan²(φ/2) and no even orders. Its own error at Λ/λ = 20 is of
    the order λ/Λ (obliquity of the orders, shadowing by the walls): Pommet, Moharam, Grann, JOSA A 11, 1827 (1994),
    "Limits of scalar diffraction theory for diffractive phase elements", find it within about 5 % for periods
    above ~14 λ. So 5 % relative on the ratios; the even orders, zero in scalar theory, stay below 1e-3 of η0."""
    for phi in (1.0, math.pi / 2.0):
        depth = phi / (2.0 * math.pi * 0.5)   # um at λ = 1 um, n = 1.5 in air
        tab = g.prepare(_body(period_um=20.0, depth_um=depth, wavelengths_nm=[1000, 1000], orders=40))
        e = tab.unpolarized[0, 0, 0, 1].astype(float)   # transmitted, into the n = 1.5 substrate
        m = tab.orders[:, 0]
        e0 = e[m == 0][0]
        t2 = math.tan(phi / 2.0) ** 2
        for order, coeff in ((1, (2 / math.pi) ** 2), (-1, (2 / math.pi) ** 2), (3, (2 / (3 * math.pi)) ** 2)):
            assert e[m == order][0] / e0 == pytest.approx(coeff * t2, rel=0.05), (phi, order)
        for order in (2, -2, 4):
            assert e[m == order][0] / e0 < 1e-3, (phi, order)
        assert abs(_sums(tab) - 1.0).max() < LOSSLESS_SUM


def _film_r(n_film: float, d_nm: float, lam_nm: float, n_sub: float) -> float:
    """Normal-incidence reflectance of one film on a substrate, from the tracer's transfer-matrix code (the plain
    Python of `thinfilm.stack_rt`: no compile)."""
    rs, rp, _, _ = thinfilm.stack_rt.py_func(np.array([[n_film, d_nm]]), 0, 1, False, 1.0, n_sub, 0.0, lam_nm, 1.0)
    assert rs == pytest.approx(rp)
    return float(rs)


def test_sub_wavelength_relief_reflects_as_its_effective_medium_film() -> None:
    """Period 0.1 λ: only the zeroth order propagates, and the relief is a film of the effective index: TE (E along
    the grooves, s at azimuth 0) n² = f n₁² + (1 − f) n₂², TM n⁻² = f/n₁² + (1 − f)/n₂². Zeroth-order EMT's own
    accuracy is its first neglected term, Rytov's second order in Λ/λ (Raguin & Morris, Appl. Opt. 32, 1154 (1993),
    eqs. 5-6): the rigorous reflectance must lie within twice that term's effect on R of the zeroth-order film
    (twice: the terms beyond, and the solver's slower TM truncation), and closer to the second-order film than to
    the zeroth-order one (the rigorous solution sees the period)."""
    f, n1, n2, lam, d = 0.5, 1.5, 1.0, 1000.0, 200.0
    tab = g.prepare(_body(period_um=0.1, depth_um=d / 1000.0, wavelengths_nm=[lam, lam], orders=20))
    assert tab.orders.tolist() == [[0, 0]]
    te0, tm0 = f * n1 ** 2 + (1 - f) * n2 ** 2, 1.0 / (f / n1 ** 2 + (1 - f) / n2 ** 2)
    c = (math.pi * 0.1 * f * (1 - f)) ** 2 / 3.0
    te2, tm2 = te0 + c * (n1 ** 2 - n2 ** 2) ** 2, tm0 + c * (1 / n1 ** 2 - 1 / n2 ** 2) ** 2 * tm0 ** 3 * te0
    for pol, (e0, e2) in enumerate(((te0, te2), (tm0, tm2))):
        r = float(tab.efficiency[0, 0, 0, pol, 0, 0])
        r0, r2 = _film_r(math.sqrt(e0), d, lam, 1.5), _film_r(math.sqrt(e2), d, lam, 1.5)
        assert abs(r - r0) <= 2.0 * abs(r2 - r0), (pol, r, r0, r2)
        assert abs(r - r2) < abs(r - r0), (pol, r, r0, r2)
    assert abs(_sums(tab) - 1.0).max() < LOSSLESS_SUM


def test_moth_eye_cones_reflect_less_than_the_flat_glass_face() -> None:
    """Cones 0.5 um tall on a 0.25 um square lattice of n = 1.5 (sub-wavelength at 550 nm: only the zeroth order
    leaves on either side): a graded index, so the face reflects far less than the flat face's Fresnel
    ((n − 1)/(n + 1))² = 4 %."""
    tab = g.prepare(_body(profile={"shape": "moth_eye", "fill": 1.0}, period_um=0.25, depth_um=0.5, orders=3,
                          layers=8, angles={"polar_deg": [0.0, 30.0], "azimuth_deg": [0.0]}))
    flat = ((1.5 - 1.0) / (1.5 + 1.0)) ** 2
    lit = np.isfinite(tab.efficiency).any(axis=(0, 1, 2, 3, 4))   # from the air (from the glass, -1 may turn back)
    assert tab.orders[lit].tolist() == [[0, 0]]
    r = tab.efficiency[:, :, :, :, 0, tab.order_index(0, 0)]
    assert (r < flat / 4.0).all(), r
    assert abs(_sums(tab) - 1.0).max() < LOSSLESS_SUM


def test_reflected_orders_are_reciprocal() -> None:
    """Reciprocity (the grating reciprocity theorem, e.g. Petit, *Electromagnetic Theory of Gratings* (1980) ch. 1):
    reversing an outgoing order makes it the incidence and the reversed incidence its outgoing order, with the same
    efficiency. Incidence at 20° whose order -1 leaves at sin θ = sin 20° - λ/Λ < 0: from sin|θ| in the same plane
    (azimuth 0), order -1 leaves back along the reversed 20° wave. A blazed (asymmetric) relief, so no mirror symmetry
    makes it trivial. The truncated solve keeps it to 1e-5 relative (dielectric, both polarizations; Al, TE) at 21
    orders: tolerance 1e-4. Honest limit: TM on the aluminium sawtooth misses it by 0.05-0.08 at 21 and 41 orders (its
    Fourier series of a metal's permittivity converges badly across the ramp's steps): not asserted."""
    lam, period = 550.0, 1.2
    back = math.degrees(math.asin(abs(math.sin(math.radians(20.0)) - lam / 1000.0 / period)))
    for ridge, pols in ((None, (0, 1)), ({"ior": [0.958, 6.69]}, (0,))):
        base = _body(profile={"shape": "sawtooth", "blaze_deg": 15.0}, depth_um=None, period_um=period, ridge=ridge,
                     wavelengths_nm=[lam, lam], orders=10, layers=10)
        a = g.prepare({**base, "angles": {"polar_deg": [20.0], "azimuth_deg": [0.0]}})
        b = g.prepare({**base, "angles": {"polar_deg": [back], "azimuth_deg": [0.0]}})
        for pol in pols:
            ea = float(a.efficiency[0, 0, 0, pol, 0, a.order_index(-1)])
            eb = float(b.efficiency[0, 0, 0, pol, 0, b.order_index(-1)])
            assert ea == pytest.approx(eb, rel=1e-4), (ridge, pol, ea, eb)


@pytest.mark.parametrize("profile", [{"shape": "sinusoidal"}, {"shape": "sawtooth", "blaze_deg": 20.0},
                                     {"shape": "pillars", "fill": 0.6}, {"shape": "holes", "fill": 0.6}])
def test_every_profile_conserves_energy_at_every_table_point(profile: dict) -> None:
    """Lossless reliefs of each shape, 2 wavelengths x 2 polar angles x 2 azimuths (conical mounts included). The 2-D
    lattices' period (0.6 um) lets ±2 orders hold every propagating one at 500 nm and 35 deg (0.8 um did not: orders
    ±3 propagated, left out of the solve, and the kept ones still summed to 1: `check` now refuses such a body)."""
    two_d = profile["shape"] in g.SHAPES_2D
    tab = g.prepare(_body(profile=profile, period_um=0.6 if two_d else 1.2,
                          depth_um=None if profile["shape"] == "sawtooth" else 0.3,
                          orders=2 if two_d else 8, layers=6, wavelengths_nm=[500, 650], wavelength_count=2,
                          angles={"polar_deg": [0.0, 35.0], "azimuth_deg": [0.0, 30.0]}))
    assert abs(_sums(tab) - 1.0).max() < LOSSLESS_SUM
    assert len(tab.orders) > 1 and np.isfinite(tab.jones[np.isfinite(tab.jones)]).all()


# L. Li, "Multilayer modal method for diffraction gratings of arbitrary profile, depth, and permittivity", JOSA A 10,
# 2581-2591 (1993), Table 2: a sinusoidal grating of permittivity 4 on its own substrate, period d, λ = d/2, depth
# 0.6 λ, 50 centre-sectioned strata, 41 orders, conical incidence (θ3 = 75°, φ3 = 60° in the paper's angles: polar
# 61.12°, azimuth 17.19° from the grating vector here). The converged values as tabulated by K. C. Johnson's GD-Calc
# (gdc_demo1a.m, "Compare computation results with published numeric data"), for s (eff1) and p (eff2) incidence:
LI_1993 = {"R": {-3: (0.011769, 0.020237), -2: (0.039664, 0.033315), -1: (0.040045, 0.0054773),
                 0: (0.10368, 0.010056)},
           "T": {-3: (0.0073647, 0.016271), -2: (0.049306, 0.097487), -1: (0.099548, 0.17061),
                 0: (0.070222, 0.048023), 1: (0.51523, 0.55687), 2: (0.06294, 0.040671)}}


def test_matches_the_published_sinusoidal_grating_of_li_1993() -> None:
    """Tolerance 0.003 absolute: inkstone's Fourier truncation error at 41 orders, measured as the change from 41
    to 81 orders, is at most 0.0024 (p, T-1) and moves every value towards the published one (at 81 orders all lie
    within 0.0015 of it); a wrong polarization, angle or staircase misses by 0.005 to 0.05."""
    t3, p3 = math.radians(75.0), math.radians(60.0)
    polar = math.degrees(math.acos(math.sin(t3) * math.cos(p3)))
    azimuth = math.degrees(math.atan2(math.cos(t3), math.sin(t3) * math.sin(p3)))
    tab = g.prepare(_body(profile={"shape": "sinusoidal"}, period_um=1.0, depth_um=0.3, substrate_ior=2.0,
                          wavelengths_nm=[500, 500], angles={"polar_deg": [polar], "azimuth_deg": [azimuth]},
                          orders=20, layers=50))
    for side, rows in enumerate((LI_1993["R"], LI_1993["T"])):
        for m, published in rows.items():
            k = tab.order_index(m)
            assert k is not None
            got = tab.efficiency[0, 0, 0, :, side, k].astype(float)
            assert got == pytest.approx(published, abs=0.003), (side, m, got, published)
    assert abs(_sums(tab) - 1.0).max() < LOSSLESS_SUM


def test_aluminium_wire_grid_transmits_tm_and_reflects_te() -> None:
    """Al lines 140 nm period, fill ½, 150 nm tall on glass at 550 nm (Al n − ik = 0.958 − 6.69i: Rakić, Appl. Opt.
    37, 5271 (1998), as tabulated at refractiveindex.info). TE (s at azimuth 0: E along the wires) is reflected,
    TM (E across them) transmitted. Published: Mélen, Rosenfeld, Weinfurter, Opt. Express 23 (2015)
    (arXiv:1508.04355) reach measured extinction ratios well above 1000 and say that simulations of ideal
    rectangular lines always predict more; this ideal grid must reach at least that. TM of metal lines converges
    slowly in the Fourier modal method (Laurent's factorization): T_TM moved from 0.82 to 0.745 between 21 and 81
    orders, so its bound (0.7) sits below the converged value; TE changed by 1e-3."""
    tab = g.prepare(_body(period_um=0.14, depth_um=0.15, ridge={"ior": [0.958, 6.69]}, orders=20))
    assert tab.orders.tolist() == [[0, 0]]
    (r_te, r_tm), (t_te, t_tm) = tab.efficiency[0, 0, 0, :, :, 0].T.astype(float)
    assert r_te > 0.85 and t_tm > 0.7
    assert t_tm / t_te > 1000.0
    assert t_tm / t_te < 1e6   # and not a fake zero: a finite leak, from the skin depth through 150 nm of Al
    assert r_te + t_te < 1.0 and r_tm + t_tm < 1.0   # the metal absorbs a little


def test_lookup_interpolates_and_says_where_the_table_runs_out() -> None:
    tab = g.prepare(_body(wavelengths_nm=[500, 600], wavelength_count=2,
                          angles={"polar_deg": [0.0, 40.0], "azimuth_deg": [0.0]}))
    at = tab.lookup(500.0, 0.0, 0.0, (0, 0), 1)
    assert at.status == g.OK
    assert at.efficiency_s == pytest.approx(float(tab.efficiency[0, 0, 0, 0, 1, tab.order_index(0)]))
    assert (abs(at.jones[:, 0]) ** 2).sum() == pytest.approx(at.efficiency_s, rel=1e-5)
    mid = tab.lookup(550.0, 20.0, 0.0, (0, 0), 1)
    assert mid.status == g.OK and 0.0 < mid.unpolarized < 1.0
    assert tab.lookup(700.0, 0.0, 0.0, (0, 0), 1).status == g.WAVELENGTH_OUTSIDE
    assert tab.lookup(550.0, 60.0, 0.0, (0, 0), 1).status == g.ANGLE_OUTSIDE
    assert tab.lookup(550.0, 20.0, 0.0, (9, 0), 1).status == g.NOT_KEPT
    # order -4 in air: sin θ = sin 40° - 4 λ/Λ = -1.02 at 500 nm: cut off there (it propagates in the glass, so the
    # table holds it), and the lookup says so (NaN, no zero)
    cut = tab.lookup(500.0, 40.0, 0.0, (-4, 0), 0)
    assert cut.status == g.CUT_OFF and math.isnan(cut.efficiency_s) and cut.reason == "order does not propagate there"


def test_the_same_body_gives_the_same_id_and_bytes_and_they_read_back() -> None:
    a = g.prepare(_body(layers=3))
    b = g.prepare({**_body(), "grooves_along": "v"})
    assert a.id == b.id and a.to_bytes() == b.to_bytes()   # lamellar: layers is 1 whatever asked
    assert g.check(a.body) == a.body   # the canonical body checks to itself
    back = g.GratingTable.from_bytes(a.to_bytes())
    assert back.id == a.id and back.body == a.body
    for name in g.GratingTable.ARRAYS:
        np.testing.assert_array_equal(getattr(back, name), getattr(a, name))
    assert g.prepare(_body(depth_um=0.31)).id != a.id
    fractions: list[float] = []
    g.prepare(_body(angles={"polar_deg": [0.0, 10.0], "azimuth_deg": [0.0]}), progress=fractions.append)
    assert fractions == [0.25, 0.5, 0.75, 1.0]   # two table points, each lit from both sides


@pytest.mark.parametrize(("change", "says"), [
    ({"profile": {"shape": "blazed"}}, "profile.shape 'blazed' is unknown; known: ['lamellar'"),
    ({"profile": {"shape": "lamellar", "fill": 1.5}}, "profile.fill must be in (0, 1]"),
    ({"profile": {"shape": "lamellar", "fill": 1.0}}, "a flat face needs no grating"),
    ({"period_um": [1, 1]}, "one number in um"),
    ({"period_um": -1}, "period_um must be in (0, 1000]"),
    ({"depth_um": "deep"}, "depth_um must be a finite number"),
    ({"ridge": {"ior": [1.5]}}, "ridge.ior must be n or [n, k]"),
    ({"substrate_ior": [1.5, 0.1]}, "substrate_ior must be lossless"),
    ({"wavelengths_nm": [700, 400]}, "must be ascending"),
    ({"wavelengths_nm": [400, 700], "wavelength_count": 1}, "give at least 2"),
    ({"angles": {"polar_deg": [0, 95]}}, "angles.polar_deg[1] must be in [0, 89]"),
    ({"angles": {"polar_deg": [10, 0]}}, "strictly ascending"),
    ({"grooves_along": "w"}, "grooves_along must be 'u' or 'v'"),
    ({"orders": 0}, "orders must be an integer in [1, 60]"),
    ({"period_um": 10.0, "wavelengths_nm": [400, 400], "orders": 10}, "orders 10 keeps -10..10, but orders up to "
                                                                      "|m| = 37 propagate"),   # 1.5 x 10 / 0.4
    ({"period_um": 10.0, "wavelengths_nm": [400, 400], "orders": 10}, "give orders >= 37"),
    ({"period_um": 100.0, "wavelengths_nm": [400, 400]}, "more than the 60 a rigorous solve takes here"),
    ({"colour": "red"}, "unknown field(s) ['colour']"),
    ({"profile": {"shape": "sawtooth", "blaze_deg": 10}, "depth_um": 0.5}, "disagrees with profile.blaze_deg"),
    ({"profile": {"shape": "pillars", "fill": 0.5}, "grooves_along": "u"}, "grooves_along is for 1-D profiles"),
    ({"wavelengths_nm": [380, 780], "wavelength_count": 401, "orders": 9, "angles": {"polar_deg": list(range(0, 90)),
                                                                        "azimuth_deg": [0, 90, 180]}},
     "one request prepares at most"),
])
def test_bad_bodies_are_refused_saying_what_is_wrong(change: dict, says: str) -> None:
    with pytest.raises(ElementError) as exc:
        g.prepare(_body(**change))
    assert says in str(exc.value)


def test_sawtooth_depth_follows_its_blaze() -> None:
    canon = g.check(_body(profile={"shape": "sawtooth", "blaze_deg": 10.0}, depth_um=None))
    assert canon["depth_um"] == pytest.approx(1.2 * math.tan(math.radians(10.0)))
    assert g.check(_body(profile={"shape": "sawtooth"}, depth_um=0.2))["profile"]["blaze_deg"] == pytest.approx(
        math.degrees(math.atan(0.2 / 1.2)))


def test_lit_from_the_substrate_a_flat_face_reflects_by_fresnel_and_totally_past_the_critical_angle() -> None:
    """The table's second half, lit from the glass (n 1.5 into air): a relief 0.5 nm deep on a 0.2 um period (only
    the zeroth order leaves at 550 nm) is a flat face, whose reflectances are Fresnel's: at 30°, sin θt = 0.75,
    Rs = ((n cos θi − cos θt) / (n cos θi + cos θt))² = 0.1058, Rp = ((cos θi − n cos θt) / (cos θi + n cos θt))² =
    0.0046; past the critical angle (41.8°) at 50°, total internal reflection, R = 1 and nothing transmitted. The
    0.5 nm step moves these by less than 1e-3."""
    tab = g.prepare(_body(period_um=0.2, depth_um=0.0005, orders=5,
                          angles={"polar_deg": [30.0, 50.0], "azimuth_deg": [0.0]})).inside
    k0 = tab.order_index(0)
    ci = math.cos(math.radians(30.0))
    ct = math.sqrt(1.0 - (1.5 * 0.5) ** 2)
    rs = ((1.5 * ci - ct) / (1.5 * ci + ct)) ** 2
    rp = ((ci - 1.5 * ct) / (ci + 1.5 * ct)) ** 2
    r30 = tab.efficiency[0, 0, 0, :, 0, k0].astype(float)
    assert r30 == pytest.approx([rs, rp], abs=1e-3)
    assert tab.efficiency[0, 1, 0, :, 0, k0].astype(float) == pytest.approx([1.0, 1.0], abs=1e-4)
    assert not np.isfinite(tab.efficiency[0, 1, 0, :, 1, :]).any()   # nothing leaves into the air
    assert abs(_sums(tab) - 1.0).max() < LOSSLESS_SUM


def test_normal_incidence_is_one_problem_at_every_azimuth() -> None:
    """At normal incidence the azimuth only turns the (s, p) basis: every azimuth of the table holds the same
    unpolarized efficiencies, and on a 1-D grating s at 90° is p at 0° (E across the lines in both). The table solves
    it once (inkstone converges more slowly for TM through metal lines away from azimuth 0: solved apart, this wire
    grid's T_TM read 0.68 at 0° and 0.53 at 90°)."""
    tab = g.prepare(_body(period_um=0.14, depth_um=0.1, ridge={"ior": [0.958, 6.69]}, substrate_ior=1.0, orders=10,
                          angles={"polar_deg": [0.0], "azimuth_deg": [0.0, 30.0, 90.0, 180.0]}))
    k = tab.order_index(0)
    for half in (tab, tab.inside):
        e = half.efficiency[0, 0, :, :, :, k].astype(float)   # (azimuth, pol, side)
        assert e.mean(axis=1) == pytest.approx(np.broadcast_to(e[0].mean(axis=0), e[:, 0].shape), abs=1e-6)
        assert e[2, 0] == pytest.approx(e[0, 1], abs=1e-6) and e[2, 1] == pytest.approx(e[0, 0], abs=1e-6)
        assert e[3] == pytest.approx(e[0], abs=1e-6)
