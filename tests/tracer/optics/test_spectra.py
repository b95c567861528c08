"""Spectra and photometry: the CIE tables, light spectra, their sampling, and spectral material values.

Reference values: docs/REFERENCES.md ("Spectra and photometry", BK7 Sellmeier).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.optics import spectra
from tracer.optics.lights import LightError, pack_lights
from tracer.optics.surfaces.base import MaterialError
from tracer.optics.surfaces.dispatch import material_spec


def test_shipped_cie_tables_are_colour_sciences_to_the_last_digit():
    colour = pytest.importorskip("colour")
    v = colour.colorimetry.SDS_LEFS_PHOTOPIC["CIE 1924 Photopic Standard Observer"]
    cmfs = colour.colorimetry.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    nm = np.arange(360, 831)
    assert np.array_equal(spectra.V_GRID, v[nm])
    assert np.array_equal(spectra.CMF_GRID, cmfs[nm])


@pytest.mark.parametrize(("nm", "v"), [(555, 1.0), (550, 0.994950), (500, 0.323), (450, 0.038), (600, 0.631),
                                       (650, 0.107)])
def test_luminous_efficiency_matches_cie_1924(nm, v):
    assert spectra.luminous(float(nm)) / spectra.KM == pytest.approx(v, abs=5e-7)


def test_one_watt_at_550_nm_is_679_55_lumens():
    s = spectra.spectrum({"type": "monochromatic", "nm": 550})
    assert spectra.efficacy(s) == pytest.approx(679.551, abs=1e-3)


def test_a_flux_w_light_carries_the_luminous_flux_of_its_spectrum():
    L = pack_lights([{"type": "point", "position": [0, 0, 0], "flux_w": 2.0,
                      "spectrum": {"type": "monochromatic", "nm": 550}}])
    assert L.flux_total[0] == pytest.approx(2 * 679.551, abs=2e-3)


def test_blackbody_2856_k_is_cie_illuminant_a():
    s = spectra.spectrum({"type": "blackbody", "kelvin": 2856})
    x, y = spectra.chromaticity(s.power)
    # CIE illuminant A: (0.44757, 0.40745); the 360-830 nm grid leaves out 300-360 nm (~1e-5 of its power)
    assert (x, y) == pytest.approx((0.44757, 0.40745), abs=2e-4)


def test_equal_energy_is_the_white_point():
    x, y = spectra.chromaticity(np.ones(spectra.GRID_N))
    assert (x, y) == pytest.approx((1 / 3, 1 / 3), abs=2e-4)


def test_planck_peaks_where_wien_says():
    nm = np.linspace(360, 830, 47001)
    peak = nm[np.argmax(spectra.planck(nm, 5000.0))]
    assert peak == pytest.approx(2.897771955e6 / 5000.0, abs=0.02)


@pytest.mark.parametrize("body", [None, {"type": "blackbody", "kelvin": 2856},
                                  {"type": "table", "nm": [400, 450, 700], "values": [0.0, 1.0, 0.2]}])
def test_wavelength_sampling_is_unbiased_for_power_and_luminous_flux(body):
    """Weighted by f, the drawn wavelengths reproduce S (radiant power per band) and K(S) (lm per W)."""
    s = spectra.spectrum(body)
    cdf, f = spectra.sampling_table(s)
    n = 400_000
    u = (np.arange(n) + 0.5) / n   # stratified: the error is far below any tolerance here
    lam = np.empty(n)
    w = np.empty(n)
    for i in range(n):
        lam[i], w[i] = spectra.sample_grid(cdf, f, u[i])
    assert np.mean(w) == pytest.approx(1.0, abs=1e-4)
    lum = np.mean(w * spectra.KM * np.interp(lam, spectra.GRID_NM, spectra.V_GRID))
    # V is read by linear interpolation within each 1 nm band: the band average differs from the grid sample by
    # the curvature of V over 1 nm, ≤ 2e-4 relative
    assert lum == pytest.approx(spectra.efficacy(s), rel=2e-4)
    # grid sample i stands for [λ_i − ½, λ_i + ½) nm: ten samples to a band
    hist = np.histogram(lam, bins=np.append(np.arange(359.5, 830, 10.0), 830.5), weights=w)[0] / n
    expect = np.add.reduceat(s.power / s.power.sum(), np.arange(0, 471, 10))
    assert np.max(np.abs(hist - expect)) < 2e-3


def test_bk7_sellmeier_gives_the_catalogue_indices_on_the_grid():
    spec = material_spec({"type": "dielectric", "ior": {"sellmeier": {
        "b": [1.03961212, 0.231792344, 1.01046945], "c_um2": [0.00600069867, 0.0200179144, 103.560653]}}})
    table = spec.ior.grid()
    for nm, n in ((486.13, 1.52238), (587.56, 1.51680), (656.27, 1.51432)):
        assert spectra.grid_value(table, nm) == pytest.approx(n, abs=1e-5)
        assert abs(spectra.grid_value(table, nm) - float(spec.ior.at(nm))) < 2e-7   # the grid's own error


@pytest.mark.parametrize(("body", "match"), [
    ({"type": "laser"}, "unknown spectrum type 'laser'"),
    ({"type": "monochromatic", "nm": 300}, "'nm' must be a finite number in \\[360, 830\\]"),
    ({"type": "monochromatic", "nm": 550, "width": 2}, "unknown field"),
    ({"type": "blackbody", "kelvin": -1}, "'kelvin'"),
    ({"type": "table", "nm": [500, 400], "values": [1, 1]}, "increase strictly"),
    ({"type": "table", "nm": [400, 500], "values": [1]}, "at least 2"),
    ({"type": "table", "nm": [400, 500, 600], "values": [1, 2]}, "3 samples but 'values' has 2"),
    ({"type": "table", "nm": [400, 500], "values": [0, 0]}, "no power"),
    ({"type": "table", "nm": [400, 500], "values": [1, -1]}, "'values'"),
    ("red", "expected an object"),
])
def test_bad_spectra_are_rejected_naming_the_field(body, match):
    with pytest.raises(spectra.SpectrumError, match=match):
        spectra.spectrum(body)
    with pytest.raises(LightError, match=match):
        pack_lights([{"type": "point", "position": [0, 0, 0], "flux_lm": 1, "spectrum": body}])


@pytest.mark.parametrize(("light", "match"), [
    ({"type": "point", "position": [0, 0, 0], "flux_w": 1, "flux_lm": 1},
     "exactly one of 'intensity_cd', 'flux_lm' and 'flux_w'"),
    ({"type": "point", "position": [0, 0, 0], "flux_w": -1}, "'flux_w' must be a number of watts"),
    ({"type": "point", "position": [0, 0, 0], "flux_w": math.inf}, "'flux_w'"),
    ({"type": "collimated", "origin": [0, 0, 0], "direction": [0, 0, -1], "radius": 1, "flux_w": 1,
      "illuminance_lx": 1}, "'flux_w' is for lights given by their flux"),
])
def test_bad_radiant_flux_is_rejected(light, match):
    with pytest.raises(LightError, match=match):
        pack_lights([light])


@pytest.mark.parametrize(("body", "match"), [
    ({"type": "lambertian", "reflectance": {"nm": [400, 700], "values": [0.5, 1.2]}}, "in \\[0, 1\\]"),
    ({"type": "lambertian", "reflectance": {"nm": [400, 700], "values": [0.5]}}, "'values'"),
    ({"type": "lambertian", "reflectance": {"nm": [400, 700], "value": [0.5, 0.5]}}, "unknown field"),
    ({"type": "diffuser", "transmittance": {"nm": [400, 700], "values": [0.9, 0.2]}, "reflectance": 0.2},
     "at most 1"),
    ({"type": "dielectric", "ior": {"sellmeier": {"b": [1.0], "c_um2": [0.2]}}}, "pole"),
    ({"type": "dielectric", "ior": {"sellmeier": {"b": [1.0, 2.0], "c_um2": [0.01]}}}, "as many 'b'"),
    ({"type": "dielectric", "ior": {"table": {"nm": [400, 700], "n": [1.5, 0.0]}}}, "'n'"),
    ({"type": "dielectric", "ior": {"abbe": 64}}, "sellmeier"),
    ({"type": "dielectric", "ior": 1.5, "coating": {"layers": []}}, "1 to 200 layers"),
    ({"type": "dielectric", "ior": 1.5, "coating": {"layers": [{"ior": 1.38}]}}, "layers\\[0\\]"),
    ({"type": "dielectric", "ior": 1.5, "coating": {"layers": [{"ior": 0.5, "thickness_nm": 100}]}},
     "'ior' must be a number in \\[1, 5\\]"),
    ({"type": "mirror", "reflectance": 0.9, "metal": [0.96, 6.69]}, "exactly one of 'reflectance' and 'metal'"),
    ({"type": "mirror"}, "exactly one of 'reflectance' and 'metal'"),
    ({"type": "mirror", "reflectance": 0.9, "coating": {"layers": [{"ior": 1.46, "thickness_nm": 94}]}},
     "needs its 'metal'"),
    ({"type": "mirror", "metal": [0.96]}, "'metal' must be \\[n, k\\]"),
    ({"type": "mirror", "metal": [0.96, -1]}, "'metal' must be"),
    ({"type": "dielectric", "ior": 1.5, "fluorescence": {"absorption_per_m": 10, "quantum_yield": 1.5,
                                                         "emission": {"type": "monochromatic", "nm": 550}}},
     "'quantum_yield'"),
    ({"type": "dielectric", "ior": 1.5, "fluorescence": {"absorption_per_m": 10, "quantum_yield": 0.5}},
     "missing \\['emission'\\]"),
    ({"type": "dielectric", "ior": 1.5, "fluorescence": {"absorption_per_m": 10, "quantum_yield": 0.5,
                                                         "emission": {"type": "monochromatic", "nm": 900}}},
     "emission"),
])
def test_bad_spectral_material_values_are_rejected_naming_the_field(body, match):
    with pytest.raises(MaterialError, match=match):
        material_spec(body)
