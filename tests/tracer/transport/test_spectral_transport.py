"""Spectral light through the forward tracer: the closed forms of photometry, dispersion, thin films and
fluorescence (docs/REFERENCES.md), and that a grey scene answers the same with or without a wavelength.

Tolerances: four standard errors of the estimate (the estimator's own batch-means error), plus the stated
model error where there is one (a receiver's finite size, the 1 nm grid).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.optics import spectra
from tracer.optics.surfaces.dielectric import fresnel_dielectric
from tracer.optics.thinfilm import stack_reflectance
from tracer.scene import Scene
from tracer.simulate import Simulation, SimulationError
from tracer.warmup import box

BK7 = {"sellmeier": {"b": [1.03961212, 0.231792344, 1.01046945], "c_um2": [0.00600069867, 0.0200179144, 103.560653]}}
LINES = {"F": 486.13, "d": 587.56, "C": 656.27}


def _scene(*solids):
    """A committed scene of boxes (lo, hi); returns it and their instance ids."""
    s = Scene()
    ids = [s.add_instance(s.add_geometry(*box(lo, hi)), np.eye(4)) for lo, hi in solids]
    s.commit()
    return s, ids


def _disk_average(intensity, d, a):
    """Mean illuminance over a disk of radius a at distance d facing an isotropic point source (closed form)."""
    return intensity * 2.0 * math.pi * (1.0 - d / math.hypot(d, a)) / (math.pi * a * a)


def _near(value, expected, err, model=0.0):
    return abs(value - expected) <= 4.0 * err + model * abs(expected)


# --------------------------------------------------------------------------------------- photometry


@pytest.mark.parametrize("spectrum", [None, {"type": "blackbody", "kelvin": 2856},
                                      {"type": "monochromatic", "nm": 450}])
def test_isotropic_1000_lm_source_keeps_the_inverse_square_and_cosine_laws_with_a_wavelength(spectrum):
    """1000 lm: 19.894 lx at 2 m normal incidence, 9.947 lx at 60°, whatever the spectrum."""
    scene, (far,) = _scene(([50, 50, 50], [51, 51, 51]))
    light = {"type": "point", "position": [0, 0, 0], "flux_lm": 1000.0}
    if spectrum:
        light["spectrum"] = spectrum
    sim = Simulation(scene, {far: {"type": "black"}}, [light])
    a, d = 0.2, 2.0
    tilt = math.radians(60.0)
    normals = np.array([[-1.0, 0, 0], [-math.cos(tilt), math.sin(tilt), 0]])
    res = sim.illuminance([[d, 0, 0], [d, 0, 0]], normals, radius=a, max_photons=4_000_000, seed=5,
                          observe=["spectrum"])
    if spectrum and spectrum["type"] == "blackbody":   # ~10⁴ photons per receiver: x and y within ~0.003
        assert np.all(np.abs(res.cie_xy - (0.44757, 0.40745)) < 0.01), res.cie_xy
    assert res.effects == ["lambertian", "spectral"] and res.rejected == 0
    i0 = 1000.0 / (4 * math.pi)
    assert i0 / d ** 2 == pytest.approx(19.894, abs=1e-3)
    assert i0 * math.cos(tilt) / d ** 2 == pytest.approx(9.947, abs=1e-3)
    normal_avg = _disk_average(i0, d, a)
    # the tilted disk: the point-source law averaged over the disk, by quadrature (it differs from 9.947 by (a/d)²)
    r, phi = np.meshgrid((np.arange(400) + 0.5) / 400 * a, (np.arange(400) + 0.5) / 400 * 2 * math.pi)
    t1 = np.cross(normals[1], [0, 0, 1.0])
    t2 = np.cross(normals[1], t1)
    p = np.array([d, 0, 0]) + (r * np.cos(phi))[..., None] * t1 + (r * np.sin(phi))[..., None] * t2
    dist = np.linalg.norm(p, axis=-1)
    e = i0 * np.einsum("ijk,k->ij", -p / dist[..., None], normals[1]) / dist ** 2
    tilted_avg = float(np.sum(e * r) / np.sum(r))
    assert _near(res.lux[0], normal_avg, res.stderr[0]), (res.lux, normal_avg, res.stderr)
    assert _near(res.lux[1], tilted_avg, res.stderr[1]), (res.lux, tilted_avg, res.stderr)


def test_one_radiant_watt_at_550_nm_lights_as_679_55_lumens():
    scene, (far,) = _scene(([50, 50, 50], [51, 51, 51]))
    sim = Simulation(scene, {far: {"type": "black"}}, [{"type": "point", "position": [0, 0, 0], "flux_w": 1.0,
                                                       "spectrum": {"type": "monochromatic", "nm": 550}}])
    res = sim.illuminance([[2.0, 0, 0]], [[-1.0, 0, 0]], radius=0.2, max_photons=2_000_000, seed=2,
                          observe=["spectrum"])
    expected = _disk_average(679.551 / (4 * math.pi), 2.0, 0.2)
    assert _near(res.lux[0], expected, res.stderr[0])
    # the spectrum: all of it in the 550–555 nm band, W/m²/nm × 5 nm = the irradiance in W/m²
    band = int((550 - 360) // 5)
    k550 = spectra.efficacy(spectra.spectrum({"type": "monochromatic", "nm": 550}))   # 679.551 lm/W
    assert res.spectral_irradiance[0, band] * 5 == pytest.approx(res.lux[0] / k550, rel=1e-9)
    assert np.count_nonzero(res.spectral_irradiance[0]) == 1
    assert res.cie_xy[0] == pytest.approx(spectra.chromaticity(np.where(spectra.GRID_NM == 550, 1.0, 0.0)), abs=1e-9)


def test_a_grey_room_answers_the_same_lux_with_and_without_a_wavelength():
    scene, (room,) = _scene(([-2, -2, 0], [2, 2, 3]))
    sim = Simulation(scene, {room: {"type": "lambertian", "reflectance": 0.6}},
                     [{"type": "point", "position": [0.3, 0.2, 2.5], "flux_lm": 2000.0,
                       "spectrum": {"type": "blackbody", "kelvin": 4000}}])
    pts = [[0, 0, 0], [1.5, 1.5, 0], [-1, 0.5, 0]]
    nrm = [[0, 0, 1]] * 3
    white = sim.illuminance(pts, nrm, radius=0.1, max_photons=1_000_000, seed=1, estimator="forward")
    spectral = sim.illuminance(pts, nrm, radius=0.1, max_photons=1_000_000, seed=1, estimator="forward",
                               observe=["spectrum"])
    assert white.effects == ["lambertian"] and spectral.effects == ["lambertian", "spectral"]
    combined = np.hypot(white.stderr, spectral.stderr)
    assert np.all(np.abs(white.lux - spectral.lux) <= 4 * combined), (white.lux, spectral.lux, combined)
    # the spectral answer integrates back to the lux: Σ K_m V(λ) E_λ Δλ over the bands (V read at the band centres)
    v_band = np.interp(spectra.bin_centres(), spectra.GRID_NM, spectra.V_GRID)
    lux_from_spectrum = spectra.KM * spectral.spectral_irradiance @ v_band * spectra.BIN_NM
    assert lux_from_spectrum == pytest.approx(spectral.lux, rel=0.02)


@pytest.mark.parametrize(("nm", "rho"), [(500, 0.8), (600, 0.2)])
def test_a_spectral_reflectance_is_read_at_the_photon_wavelength(nm, rho):
    """A floor of ρ(λ) lit at one line answers as a grey floor of ρ(line): the same paths, the same lux."""
    table = {"nm": [380, 540, 560, 780], "values": [0.8, 0.8, 0.2, 0.2]}
    scene, (floor,) = _scene(([-3, -3, -1], [3, 3, 0]))
    light = [{"type": "point", "position": [0, 0, 1], "flux_lm": 1000.0,
              "spectrum": {"type": "monochromatic", "nm": nm}}]
    up = dict(points=[[0.5, 0, 0.5]], normals=[[0, 0, -1]], radius=0.2, max_photons=400_000, seed=9,
              estimator="forward")
    spectral = Simulation(scene, {floor: {"type": "lambertian", "reflectance": table}}, light)
    grey = Simulation(scene, {floor: {"type": "lambertian", "reflectance": rho}}, light)
    a = spectral.illuminance(**up)
    b = grey.illuminance(**up, force_effects=["spectral"])
    assert spectral.effects == ["lambertian", "spectral"]
    assert a.lux[0] > 0 and a.lux[0] == pytest.approx(b.lux[0], rel=1e-9)


# ---------------------------------------------------------------------------------------- dispersion


def _prism(base: float, width: float):
    """A 60° prism, apex up: cross-section in x–z (base on z = 0), extruded along y; outward triangles."""
    h = base / 2 * math.tan(math.radians(60))
    sec = [(-base / 2, 0.0), (base / 2, 0.0), (0.0, h)]
    v = np.array([[x, y, z] for y in (-width / 2, width / 2) for x, z in sec])
    t = [[0, 1, 2], [3, 5, 4], [0, 3, 4], [0, 4, 1], [1, 4, 5], [1, 5, 2], [2, 5, 3], [2, 3, 0]]
    centre = v.mean(axis=0)
    for tri in t:   # wind each triangle outward
        a, b, c = v[tri]
        if np.dot(np.cross(b - a, c - a), a - centre) < 0:
            tri[1], tri[2] = tri[2], tri[1]
    return v, np.array(t), h


def _refract(d, n, eta):
    """Snell refraction of unit d through unit normal n facing against d (the kernel's formula)."""
    cos_i = -np.dot(d, n)
    cos_t = math.sqrt(1 - eta * eta * (1 - cos_i * cos_i))
    return eta * d + (eta * cos_i - cos_t) * n, cos_i, cos_t


def _tsp(ci: float, ct: float, n1: float, n2: float) -> tuple[float, float]:
    """Fresnel power transmittances (Ts, Tp) from index n1 to n2 at incidence cosine ci, refraction cosine ct."""
    rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)
    rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct)
    return 1 - rs * rs, 1 - rp * rp


def test_bk7_prism_deviates_the_f_d_and_c_lines_by_their_minimum_deviation():
    """A 60° BK7 prism, a beam at the d line's minimum-deviation incidence: each line lands where Snell's law
    with its Sellmeier index sends it (F, d, C: n = 1.52238, 1.51680, 1.51432), and nowhere else, with the power two
    Fresnel interfaces pass when s and p are kept apart."""
    base, dist = 0.05, 2.0
    v, t, h = _prism(base, 0.05)
    scene = Scene()
    prism = scene.add_instance(scene.add_geometry(v, t), np.eye(4))
    scene.commit()
    n_of = {k: float(spectra.Sellmeier(tuple(BK7["sellmeier"]["b"]), tuple(BK7["sellmeier"]["c_um2"])).at(nm))
            for k, nm in LINES.items()}
    assert [round(n_of[k], 5) for k in "FdC"] == [1.52238, 1.51680, 1.51432]
    n_left, n_right = np.array([-math.sin(math.radians(60)), 0, 0.5]), np.array([math.sin(math.radians(60)), 0, 0.5])
    theta1 = math.asin(n_of["d"] * math.sin(math.radians(30)))    # minimum deviation of the d line
    d_in = math.cos(theta1) * -n_left + math.sin(theta1) * np.array([0.5, 0, math.sin(math.radians(60))])
    entry = np.array([-base / 4, 0, h / 2])
    targets, expected_t = [], []
    for k in "FdC":
        inside, cos1, cos1t = _refract(d_in, n_left, 1 / n_of[k])
        inside /= np.linalg.norm(inside)
        # where the inside ray meets the right face (plane through (base/2, 0, 0) with normal n_right)
        s = np.dot(np.array([base / 2, 0, 0]) - entry, n_right) / np.dot(inside, n_right)
        exit_point = entry + s * inside
        out, cos2, cos2t = _refract(inside, -n_right, n_of[k])
        out /= np.linalg.norm(out)
        deviation = math.degrees(math.acos(np.clip(np.dot(d_in, out), -1, 1)))
        if k == "d":   # the symmetric path: δ_min = 2 asin(n sin(A/2)) − A
            assert deviation == pytest.approx(math.degrees(2 * theta1) - 60.0, abs=1e-9)
        targets.append(exit_point + dist * out)
        # s and p apart (the scene carries polarization, issue 38): ½ (Ts₁ Ts₂ + Tp₁ Tp₂), not the product of averages
        (ts1, tp1), (ts2, tp2) = _tsp(cos1, cos1t, 1.0, n_of[k]), _tsp(cos2, cos2t, n_of[k], 1.0)
        expected_t.append(0.5 * (ts1 * ts2 + tp1 * tp2))
        assert expected_t[-1] != pytest.approx((1 - fresnel_dielectric(cos1, 1.0, n_of[k]))
                                               * (1 - fresnel_dielectric(cos2, n_of[k], 1.0)), rel=1e-3)
    normals = [-(p - e) / np.linalg.norm(p - e) for p, e in zip(targets, [entry] * 3, strict=True)]
    r_beam, r_disk, phi = 0.5e-3, 2e-3, 1.0
    for j, k in enumerate("FdC"):
        light = {"type": "collimated", "origin": list(entry - 0.01 * d_in), "direction": list(d_in),
                 "radius": r_beam, "illuminance_lx": phi / (math.pi * r_beam ** 2),
                 "spectrum": {"type": "monochromatic", "nm": LINES[k]}}
        sim = Simulation(scene, {prism: {"type": "dielectric", "ior": BK7}}, [light])
        res = sim.illuminance(targets, normals, radius=r_disk, max_photons=200_000, seed=j, estimator="forward")
        assert "dispersion" in res.effects
        flux = res.lux * math.pi * r_disk ** 2
        assert _near(flux[j], phi * expected_t[j], res.stderr[j] * math.pi * r_disk ** 2, 1e-3), (k, flux, expected_t)
        # the other lines' receivers see none of the beam, only stray light from internal reflections
        assert np.all(np.delete(flux, j) < 1e-3 * phi), (k, flux)


# ---------------------------------------------------------------------------------------- thin films


MGF2 = {"layers": [{"ior": 1.38, "thickness_nm": 550 / (4 * 1.38)}]}


@pytest.mark.parametrize(("nm", "coated"), [(550, True), (450, True), (550, False)])
def test_a_coated_glass_plate_reflects_what_the_transfer_matrices_say(nm, coated):
    """A thick glass plate (n = 1.52) coated with a MgF₂ quarter-wave (the coating covers every face of the
    solid), at normal incidence: it reflects R + T² R / (1 − R²) (incoherent sum inside the plate; a lossless
    stack reflects alike from both sides), with R = 1.2601 % at 550 nm, 1.6204 % at 450 nm and 4.2580 % bare."""
    scene, (plate,) = _scene(([-0.1, -0.1, -0.01], [0.1, 0.1, 0.0]))
    material = {"type": "dielectric", "ior": 1.52, **({"coating": MGF2} if coated else {})}
    r_beam, r_disk, phi = 2e-3, 5e-3, 1.0
    light = {"type": "collimated", "origin": [0, 0, 0.2], "direction": [0, 0, -1], "radius": r_beam,
             "illuminance_lx": phi / (math.pi * r_beam ** 2), "spectrum": {"type": "monochromatic", "nm": nm}}
    sim = Simulation(scene, {plate: material}, [light])
    res = sim.illuminance([[0, 0, 0.1]], [[0, 0, -1]], radius=r_disk, max_photons=1_000_000, seed=4,
                          estimator="forward")
    layers = np.array([[1.38, 550 / (4 * 1.38)]])
    r1 = stack_reflectance(layers, 0, 1 if coated else 0, False, 1.0, 1.52, 0.0, float(nm), 1.0)
    assert r1 == pytest.approx({(550, True): 0.012601, (450, True): 0.016204, (550, False): 0.042580}[nm, coated],
                               abs=5e-7)
    r_inside = stack_reflectance(layers, 0, 1 if coated else 0, True, 1.52, 1.0, 0.0, float(nm), 1.0)
    assert r_inside == pytest.approx(r1, abs=1e-12)
    expected = r1 + (1 - r1) ** 2 * r1 / (1 - r1 * r1)
    area = math.pi * r_disk ** 2
    assert _near(res.lux[0] * area, phi * expected, res.stderr[0] * area), (res.lux[0] * area, expected)
    assert ("coating" in res.effects) == coated


ALUMINIUM = (0.96, 6.69)   # n − ik at 550 nm


@pytest.mark.parametrize("layers", [0, 1])
def test_a_metal_mirror_reflects_by_fresnel_and_through_its_coating(layers):
    """Aluminium (0.96 − 6.69i) at normal incidence: R = ((n−1)² + k²)/((n+1)² + k²) = 0.9209 bare; under a
    quarter-wave of SiO₂ (1.46) at 550 nm the amplitude is r = (r₀₁ − r₁₂)/(1 − r₀₁ r₁₂) (the layer turns the
    phase by π), with r₀₁ = (1 − 1.46)/(1 + 1.46) and r₁₂ = (1.46 − ñ)/(1.46 + ñ), ñ = 0.96 − 6.69i."""
    scene, (mirror,) = _scene(([-0.1, -0.1, -0.01], [0.1, 0.1, 0.0]))
    coating = {"layers": [{"ior": 1.46, "thickness_nm": 550 / (4 * 1.46)}]}
    material = {"type": "mirror", "metal": list(ALUMINIUM), **({"coating": coating} if layers else {})}
    r_beam, r_disk, phi = 2e-3, 5e-3, 1.0
    light = {"type": "collimated", "origin": [0, 0, 0.2], "direction": [0, 0, -1], "radius": r_beam,
             "illuminance_lx": phi / (math.pi * r_beam ** 2), "spectrum": {"type": "monochromatic", "nm": 550}}
    sim = Simulation(scene, {mirror: material}, [light])
    res = sim.illuminance([[0, 0, 0.1]], [[0, 0, -1]], radius=r_disk, max_photons=200_000, seed=6,
                          estimator="forward")
    metal = complex(ALUMINIUM[0], -ALUMINIUM[1])   # n − ik
    if layers:
        r01, r12 = (1 - 1.46) / (1 + 1.46), (1.46 - metal) / (1.46 + metal)
        expected = abs((r01 - r12) / (1 - r01 * r12)) ** 2
    else:
        expected = ((ALUMINIUM[0] - 1) ** 2 + ALUMINIUM[1] ** 2) / ((ALUMINIUM[0] + 1) ** 2 + ALUMINIUM[1] ** 2)
        assert expected == pytest.approx(0.9209, abs=1e-4)
    area = math.pi * r_disk ** 2
    assert _near(res.lux[0] * area, phi * expected, res.stderr[0] * area), (res.lux[0] * area, expected)
    assert ("coating" in res.effects) == bool(layers)


# -------------------------------------------------------------------------------------- fluorescence


def _enclosure_flux(sim, lo, hi, **query):
    """Luminous flux (lm) leaving the box lo–hi through its six faces, and its error bound (the faces' errors
    added: the queries share their photons, so their errors are not independent). With observe spectrum,
    also the radiant flux per 5 nm band (W) and a bound on the error of their sum (W)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    size = hi - lo
    total, err, bands, bands_err = 0.0, 0.0, np.zeros(spectra.N_BINS), 0.0
    for axis in range(3):
        a, b = [i for i in range(3) if i != axis]
        u, v = np.zeros(3), np.zeros(3)
        u[a], v[b] = size[a], size[b]
        for side in (lo, hi):   # u × v must point into the box: light leaving it arrives on the front side
            origin = lo.copy()
            origin[axis] = side[axis]
            inward = np.cross(u, v)[axis] * (1 if side is lo else -1) > 0
            res = sim.grid(origin, u if inward else v, v if inward else u, 1, 1, **query)
            area = size[a] * size[b]
            total += float(res.lux[0, 0]) * area
            err += float(res.stderr[0, 0]) * area
            if res.spectral_irradiance is not None:
                bands += res.spectral_irradiance[0, 0] * area * spectra.BIN_NM
                bands_err += float(res.spectral_stderr[0, 0].sum()) * area * spectra.BIN_NM
    return total, err, bands, bands_err


def _fluorescent_cube(emission):
    scene, (cube,) = _scene(([-0.005, -0.005, -0.005], [0.005, 0.005, 0.005]))
    material = {"type": "dielectric", "ior": 1.0, "fluorescence": {
        "absorption_per_m": {"nm": [400, 500, 520, 700], "values": [1e5, 1e5, 0.0, 0.0]},
        "quantum_yield": 0.9, "emission": emission}}
    r_beam, phi_v = 2e-3, 1.0
    light = {"type": "collimated", "origin": [0, 0, 0.009], "direction": [0, 0, -1], "radius": r_beam,
             "illuminance_lx": phi_v / (math.pi * r_beam ** 2), "spectrum": {"type": "monochromatic", "nm": 450}}
    return Simulation(scene, {cube: material}, [light]), phi_v / spectra.efficacy(spectra.spectrum(light["spectrum"]))


def test_fluorescence_emits_quantum_yield_times_the_wavelength_ratio_of_the_absorbed_power():
    """450 → 550 nm, QY 0.9: emitted / absorbed power = 0.9 × 450 / 550 = 0.736364 (the cube, index 1, absorbs
    the whole beam within a micrometre and is clear at 550 nm: every emitted photon leaves)."""
    sim, watts_in = _fluorescent_cube({"type": "monochromatic", "nm": 550})
    assert sim.effects == ["lambertian", "fresnel", "spectral", "fluorescence"]
    lm_out, err, _, _ = _enclosure_flux(sim, [-0.01] * 3, [0.01] * 3, max_photons=200_000, seed=3)
    k550 = spectra.efficacy(spectra.spectrum({"type": "monochromatic", "nm": 550}))
    ratio, ratio_err = lm_out / k550 / watts_in, err / k550 / watts_in
    assert 0.9 * 450 / 550 == pytest.approx(0.736364, abs=1e-6)
    assert abs(ratio - 0.736364) <= 4 * ratio_err + 1e-9, (ratio, ratio_err)


def test_fluorescence_counts_photons_whatever_the_emission_shape():
    """The same absorber, a line at 552.5 nm or a flat band 520–600 nm: the same number of photons leave
    (Σ P_band λ_band / hc; the line and the band's edges sit on the 5 nm band grid, so the band centres are exact)."""
    counts = []
    for emission in ({"type": "monochromatic", "nm": 552.5}, {"type": "table", "nm": [520, 600], "values": [1, 1]}):
        sim, watts_in = _fluorescent_cube(emission)
        _, _, bands, _ = _enclosure_flux(sim, [-0.01] * 3, [0.01] * 3, max_photons=200_000, seed=7,
                                      observe=["spectrum"])
        counts.append(float(bands @ spectra.bin_centres()) / watts_in / 450.0)   # photons out per photon absorbed
    # a line: every photon absorbed yields QY photons exactly (all leave); a band: its photons, the QY draw's noise
    assert counts[0] == pytest.approx(0.9, rel=0.01)
    assert counts[1] == pytest.approx(counts[0], rel=0.02), counts


def test_everything_on_conserves_energy_and_stays_finite():
    """Dispersion, a coating, fluorescence, scattering, spectral absorption and reflectance tables at once,
    inside a box of receivers: no photon is rejected, nothing leaves but what came in (less what was absorbed)."""
    scene, (glass, floor) = _scene(([-0.004, -0.004, -0.004], [0.004, 0.004, 0.004]),
                                   ([-0.009, -0.009, -0.009], [0.009, 0.009, -0.008]))
    materials = {
        glass: {"type": "dielectric", "ior": BK7, "coating": MGF2, "scattering_per_m": 300.0, "g": 0.6,
                "absorption_per_m": {"nm": [400, 700], "values": [5.0, 50.0]},
                "fluorescence": {"absorption_per_m": {"nm": [380, 480, 500], "values": [800.0, 800.0, 0.0]},
                                 "quantum_yield": 0.95, "emission": {"type": "blackbody", "kelvin": 3000}}},
        floor: {"type": "lambertian", "reflectance": {"nm": [400, 700], "values": [0.9, 0.3]}},
    }
    light = {"type": "point", "position": [0.0, 0.0, 0.008], "flux_w": 1.0}
    sim = Simulation(scene, materials, [light])
    assert set(sim.effects) >= {"dispersion", "coating", "fluorescence", "scattering", "absorption", "spectral"}
    _, _, bands, bands_err = _enclosure_flux(sim, [-0.01] * 3, [0.01] * 3, max_photons=100_000, seed=1,
                                             observe=["spectrum"])
    res = sim.illuminance([[0, 0, 0.0095]], [[0, 0, -1]], radius=1e-3, max_photons=100_000, seed=2,
                          observe=["spectrum"])
    assert res.rejected == 0 and np.all(np.isfinite(res.spectral_irradiance)) and np.isfinite(res.lux).all()
    assert 0.0 < bands.sum() <= 1.0 + 4 * bands_err   # W out ≤ W in: absorption and the Stokes shift only take


@pytest.mark.parametrize(("observe", "match"), [("spectrum", "must be a list"), (["stoke"], "unknown observable"),
                                                ({"spectrum": 1}, "must be a list")])
def test_a_bad_observe_is_refused_naming_it(observe, match):
    scene, (floor,) = _scene(([-1, -1, -1], [1, 1, 0]))
    sim = Simulation(scene, {floor: {"type": "black"}}, [{"type": "point", "position": [0, 0, 1], "flux_lm": 1.0}])
    with pytest.raises(SimulationError, match=match):
        sim.illuminance([[0, 0, 0]], [[0, 0, 1]], max_photons=100, observe=observe)


def test_a_grid_too_large_to_observe_the_spectrum_of_is_refused_before_it_runs():
    scene, (floor,) = _scene(([-1, -1, -1], [1, 1, 0]))
    sim = Simulation(scene, {floor: {"type": "black"}}, [{"type": "point", "position": [0, 0, 1], "flux_lm": 1.0}])
    with pytest.raises(SimulationError, match="use at most 41237 cells"):
        sim.grid([-1, -1, 0], [2, 0, 0], [0, 2, 0], 300, 300, max_photons=100, observe=["spectrum"])
    with pytest.raises(SimulationError, match="backward estimator cannot answer"):
        sim.illuminance([[0, 0, 0]], [[0, 0, 1]], max_photons=100, observe=["spectrum"], estimator="backward")
