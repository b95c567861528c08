"""IES / EULUMDAT export of a far field (`tracer.photometry.export`): the files read back through the project's own
parsers (`tracer.photometry.files`) to the same candela table, to the printed precision, and to the flux that left the
scene within 0.5 %."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tests.tracer.transport_scenes import box, quad, scene_of
from tracer.photometry.export import decimals, write_ies, write_ldt, write_photometry
from tracer.photometry.files import PhotometryError, parse_photometry
from tracer.simulate import Simulation

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "photometry"


def lamp_far_field(name: str, nc: int, ngamma: int, photons: int = 800_000):
    """The far field of a real luminaire file behind a half-open black box's rim: a downlight as a scene."""
    text = (FIXTURES / name).read_text()
    s, (shade,) = scene_of(box((-0.2, -0.2, 0.05), (0.2, 0.2, 0.3)))    # above the lamp: blocks its uplight
    lamp = {"type": "goniometric", "position": [0.0, 0.0, 0.0], "format": name.rsplit(".", 1)[1], "data": text}
    return Simulation(s, {shade: {"type": "lambertian", "reflectance": 0.6}}, [lamp]).far_field(
        nc, ngamma, max_photons=photons, seed=4)


def read_back(fmt: str, text: str, res):
    """The parsed table in the far field's layout (nγ, nc), and the parsed Photometry."""
    ph = parse_photometry(fmt, text)
    nc = len(res.c_deg)
    np.testing.assert_allclose(ph.gamma_deg, res.gamma_deg, atol=1e-6)
    np.testing.assert_allclose(ph.c_deg[:-1] if nc > 1 else ph.c_deg[:1], res.c_deg, atol=1e-6)
    return ph.candela[:nc].T, ph


@pytest.mark.parametrize("name", ["rab_dled6r8y_7.ies", "rab_bayled78_4.ies", "dekolight_acrux_452lm.ldt"])
@pytest.mark.parametrize("fmt", ["ies", "ldt"])
def test_round_trip_of_a_lamp_in_a_scene(name, fmt):
    res = lamp_far_field(name, 24, 37)          # ΔC = 15°, Δγ = 5°
    assert res.flux_lm > 0
    text = write_photometry(fmt, res.candela, res.c_deg, res.gamma_deg, res.flux_lm, name=name,
                            notes=f"{res.photons} photons")
    table, ph = read_back(fmt, text, res)
    if fmt == "ies":
        tol = 0.5 * 10.0 ** -decimals(res.candela)
    else:
        tol = 0.5 * 10.0 ** -decimals(res.candela * 1000.0 / res.flux_lm) * res.flux_lm / 1000.0
    assert np.max(np.abs(table - res.candela)) <= tol * (1 + 1e-9) + 1e-12 * res.candela.max()
    assert ph.total_flux() == pytest.approx(res.flux_lm, rel=0.005)
    assert ph.stated_lumens == pytest.approx(res.flux_lm, rel=1e-9)


def test_round_trip_of_an_isotropic_point_and_an_axial_table():
    s, (sq,) = scene_of(quad((1000.0, 0.0, 0.0), (0.001, 0.0, 0.0), (0.0, 0.001, 0.0)))
    lamp = {"type": "point", "position": [0.0, 0.0, 0.0], "intensity_cd": 250.0}
    res = Simulation(s, {sq: {"type": "lambertian", "reflectance": 0.0}}, [lamp]).far_field(
        1, 19, max_photons=200_000, seed=1)
    for fmt in ("ies", "ldt"):
        text = write_photometry(fmt, res.candela, res.c_deg, res.gamma_deg, res.flux_lm)
        table, ph = read_back(fmt, text, res)
        assert ph.meta["symmetry"] == "axial"
        np.testing.assert_allclose(table, res.candela, rtol=1e-5)
        assert ph.total_flux() == pytest.approx(4 * math.pi * 250.0, rel=0.005)
    ies = write_ies(res.candela, res.c_deg, res.gamma_deg, res.flux_lm)
    assert ies.startswith("IESNA:LM-63-2002\n") and "TILT=NONE" in ies and "[_ABSOLUTELUMENS]" in ies
    assert max(len(line) for line in ies.splitlines()) <= 256
    ldt = write_ldt(res.candela, res.c_deg, res.gamma_deg, res.flux_lm).split("\r\n")
    assert ldt[2] == "1" and ldt[22] == "100"                  # Isym 1, LORL 100 %
    assert float(ldt[21]) == pytest.approx(50.0, abs=1.0)      # DFF: half the isotropic flux goes down


def test_bad_tables():
    c, g = np.array([0.0, 180.0]), np.array([0.0, 90.0, 180.0])
    ok = np.ones((3, 2))
    for args, what in (((np.zeros((3, 2)), c, g, 1.0), "nothing left"), ((ok, c, g, 0.0), "nothing left"),
                       ((np.ones((2, 2)), c, g, 1.0), "candela must be"),
                       ((ok, c, np.array([0.0, 90.0, 170.0]), 1.0), "gamma_deg"),
                       ((ok, np.array([10.0, 180.0]), g, 1.0), "c_deg"),
                       ((-ok, c, g, 1.0), "finite and")):
        for fmt in ("ies", "ldt"):
            with pytest.raises(PhotometryError, match=what):
                write_photometry(fmt, *args)
    with pytest.raises(PhotometryError, match="unknown photometry format"):
        write_photometry("csv", ok, c, g, 1.0)
