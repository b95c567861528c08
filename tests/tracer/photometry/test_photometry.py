"""IES LM-63 and EULUMDAT parsing: real files' flux against what they state, symmetry expansion, bad input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tracer.photometry.files import PhotometryError, parse_photometry

FIX = Path(__file__).resolve().parents[2] / "fixtures" / "photometry"

REAL = [  # (file, stated flux, relative tolerance): the real luminaires of tests/fixtures/photometry
    ("rab_dled6r8y_7.ies", 532.0, 0.005),       # axial symmetry, absolute photometry, [_ABSOLUTELUMENS]
    ("rab_boa2_5.ies", 754.0, 0.005),           # quadrant symmetry
    ("rab_bayled78_4.ies", 5822.0, 0.005),      # bilateral 0-180, candela multiplier 0.9687
    ("dekolight_acrux_452lm.ldt", 452.85, 0.005),  # EULUMDAT, no symmetry, 36 C planes, LORL 100 %
]


@pytest.mark.parametrize(("name", "stated", "tol"), REAL)
def test_real_file_flux_matches_the_stated_lumens(name, stated, tol):
    p = parse_photometry(name.rsplit(".", 1)[1], (FIX / name).read_text(encoding="latin-1"))
    assert p.stated_lumens == pytest.approx(stated)
    assert p.total_flux() == pytest.approx(stated, rel=tol)


@pytest.mark.parametrize(("name", "stated", "tol"), REAL)
def test_exact_integral_agrees_with_brute_force_quadrature(name, stated, tol):
    """`total_flux` integrates the bilinear model exactly: a fine midpoint rule over the sphere converges to it."""
    p = parse_photometry(name.rsplit(".", 1)[1], (FIX / name).read_text(encoding="latin-1"))
    n_c, n_g = 720, 4000
    c = (np.arange(n_c) + 0.5) * 360.0 / n_c
    g = (np.arange(n_g) + 0.5) * 180.0 / n_g
    i = p.intensity(c[:, None], g[None, :])
    flux = (i * np.sin(np.radians(g))[None, :]).sum() * math.radians(360.0 / n_c) * math.radians(180.0 / n_g)
    assert flux == pytest.approx(p.total_flux(), rel=2e-3)


def test_table_is_closed_over_c_and_covers_the_sphere():
    for name, _, _ in REAL:
        p = parse_photometry(name.rsplit(".", 1)[1], (FIX / name).read_text(encoding="latin-1"))
        assert p.c_deg[0] == 0.0 and p.c_deg[-1] == 360.0
        assert p.gamma_deg[0] == 0.0 and p.gamma_deg[-1] == 180.0
        np.testing.assert_array_equal(p.candela[0], p.candela[-1])
        assert np.all(p.candela >= 0)


def test_ies_symmetries_expand_as_declared():
    quad = parse_photometry("ies", (FIX / "rab_boa2_5.ies").read_text())
    for c in (10.0, 33.0, 80.0):
        ref = quad.intensity(c, 40.0)
        for cc in (180.0 - c, 180.0 + c, 360.0 - c):
            assert quad.intensity(cc, 40.0) == pytest.approx(ref)
    bil = parse_photometry("ies", (FIX / "rab_bayled78_4.ies").read_text())
    assert bil.intensity(300.0, 20.0) == pytest.approx(bil.intensity(60.0, 20.0))
    assert bil.intensity(0.0, 0.0) == pytest.approx(2623.0 * 0.9687)
    axial = parse_photometry("ies", (FIX / "rab_dled6r8y_7.ies").read_text())
    assert axial.intensity(123.0, 30.0) == pytest.approx(200.0)
    assert axial.intensity(0.0, 120.0) == 0.0  # nothing above the horizon of a 0-90 file


def test_ldt_axial_symmetry_and_scaling():
    p = parse_photometry("ldt", (FIX / "wiki_spotlight.ldt").read_text())
    assert p.meta["symmetry"] == "axial"
    # 1000 cd/klm at nadir, 1500 lm of lamps
    assert p.intensity(77.0, 0.0) == pytest.approx(1500.0)
    assert p.intensity(200.0, 15.0) == pytest.approx(820.0 * 1.5)


def _ies(vert="0 45 90", horiz="0", cd="100 50 0", header="1 1000 1 3 1 1 2 0 0 0", tilt="TILT=NONE"):
    return f"IESNA:LM-63-2002\n[TEST] t\n{tilt}\n{header}\n1 1 10\n{vert}\n{horiz}\n{cd}\n"


def test_synthetic_isotropic_ies_has_flux_4_pi_i():
    p = parse_photometry("ies", _ies(vert="0 90 180", cd="10 10 10", header="1 1000 1 3 1 1 2 0 0 0"))
    assert p.total_flux() == pytest.approx(4 * math.pi * 10)


@pytest.mark.parametrize(("text", "match"), [
    ("hello", "no 'TILT=' line"),
    (_ies(tilt="TILT=lamp.tlt"), "TILT=LAMP.TLT is not supported"),
    (_ies(tilt="TILT=INCLUDE"), "TILT=INCLUDE is not supported"),
    (_ies(header="1 1000 1 3 1 2 2 0 0 0"), "type B is not supported"),
    (_ies(header="1 1000 1 3 1 1 7 0 0 0"), "units type"),
    (_ies(header="1 1000 0 3 1 1 2 0 0 0"), "candela multiplier must be > 0"),
    (_ies(header="1 0 1 3 1 1 2 0 0 0"), "lumens per lamp"),
    (_ies(header="1 1000 1 3.5 1 1 2 0 0 0"), "number of vertical angles must be a positive integer"),
    (_ies(cd="100 50"), "ends before candela value 3"),
    (_ies(cd="100 x 0"), "candela value 2 of horizontal angle 1 must be a number, got 'x'"),
    (_ies(cd="100 50 0 7"), "unexpected value '7'"),
    (_ies(vert="0 90 45"), "strictly increasing"),
    (_ies(vert="10 45 90"), "must start at 0 or 90"),
    (_ies(cd="100 -5 0"), "negative candela"),
    (_ies(cd="0 0 0"), "emits nothing"),
    (_ies(horiz="45"), "single horizontal angle must be 0"),
])
def test_bad_ies_is_rejected_with_a_precise_message(text, match):
    with pytest.raises(PhotometryError, match=match):
        parse_photometry("ies", text)
    assert issubclass(PhotometryError, ValueError)


def test_bad_ldt_is_rejected_with_a_precise_message():
    good = (FIX / "wiki_spotlight.ldt").read_text().split("\n")
    bad = list(good)
    bad[2] = "7"   # line 3: Isym
    with pytest.raises(PhotometryError, match="LDT line 3: the symmetry indicator"):
        parse_photometry("ldt", "\n".join(bad))
    bad = list(good)
    bad[28] = "lots"   # line 29: total lamp flux of set 1
    with pytest.raises(PhotometryError, match="LDT line 29: the total lamp flux of set 1 must be a number"):
        parse_photometry("ldt", "\n".join(bad))
    with pytest.raises(PhotometryError, match="ends before intensity value"):
        parse_photometry("ldt", "\n".join(good[:-5]))
    with pytest.raises(PhotometryError, match="unexpected content"):
        parse_photometry("ldt", "\n".join(good) + "\n5\n")
    with pytest.raises(PhotometryError, match="unknown photometry format 'xml'"):
        parse_photometry("xml", "")
    with pytest.raises(PhotometryError, match="expected the file text as str"):
        parse_photometry("ies", b"IESNA")
