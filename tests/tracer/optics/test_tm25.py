"""TM-25 ray files (issue 38): the binary ANSI/IES TM-25 file of a known Lambertian emitter, uploaded once and named
by its id, gives the `area` light's illuminance in the near and the far field within error bars (the argument of
test_rayfile.py: the tracer replays the file within 4σ of its own Monte Carlo error, and the file's exact value is
the emitter's within its sampling error); the file's flux normalisation and spectral content are kept; a corrupted
header, a truncated file and wrong counts are refused with a message that names what is wrong.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from test_rayfile import A, file_value, lambertian_rays

from tracer.optics import files, spectra
from tracer.optics.lights import LightError, pack_lights, tm25
from tracer.scene import Scene
from tracer.simulate import Simulation

N_RAYS = 100_000


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    d = tmp_path_factory.mktemp("optical-files")
    files.register(d)

    def put(write) -> str:
        tmp = d / "new"
        write(tmp)
        fid = files.file_id(tmp.read_bytes())
        tmp.rename(d / fid)
        return fid
    return put


def body(fid: str, **more) -> dict:
    return {"type": "rayfile", "position": [0.0, 0.0, 0.0], "file": fid, **more}


@pytest.fixture(scope="module")
def sims(store):
    s = Scene()
    v = np.array([[-A, -A, 0], [A, -A, 0], [A, A, 0], [-A, A, 0]], float)
    emitter = s.add_instance(s.add_geometry(v, np.array([[0, 1, 2], [0, 2, 3]])), np.eye(4))
    s.commit()
    rays = lambertian_rays(N_RAYS, seed=5)
    fid = store(lambda p: tm25.write(p, rays, flux="luminous"))
    area_light = {"type": "area", "instances": [emitter], "exitance_lm_m2": 1.0 / (2 * A) ** 2}
    black = {"type": "black"}
    return Simulation(s, {emitter: black}, [body(fid)]), Simulation(s, {emitter: black}, [area_light]), rays


@pytest.mark.parametrize(("h", "radius"), [(3e-3, 1e-3), (0.5, 0.1)], ids=["near field", "far field"])
def test_a_lambertian_tm25_file_gives_the_area_lights_illuminance(sims, h, radius):
    ray_sim, area_sim, rays = sims
    q = {"radius": radius, "max_photons": 200_000, "seed": 4, "estimator": "forward"}
    got = ray_sim.illuminance([[0, 0, h]], [[0, 0, -1]], **q)
    ref = area_sim.illuminance([[0, 0, h]], [[0, 0, -1]], **q)
    own, own_err = file_value(rays.astype(np.float32).astype(np.float64), h, radius)   # the file holds float32
    assert abs(got.lux[0] - own) <= 4 * got.stderr[0], (got.lux, got.stderr, own)
    assert abs(own - ref.lux[0]) <= 4 * math.hypot(own_err, ref.stderr[0]), (own, own_err, ref.lux, ref.stderr)


def test_the_header_total_normalises_the_flux_and_rays_are_read_in_chunks(store, monkeypatch):
    rays = lambertian_rays(5000, seed=2)
    fid = store(lambda p: tm25.write(p, rays, flux="luminous", total=250.0))
    L = pack_lights([body(fid)])
    assert L.flux_total[0] == pytest.approx(250.0)           # Φv of the header, not the column's sum (1 lm)
    assert pack_lights([body(fid, flux_lm=10.0)]).flux_total[0] == pytest.approx(10.0)
    whole = tm25.read(files.path_of(fid, "t"), "t").rays
    monkeypatch.setattr(tm25, "CHUNK", 999)
    chunked = tm25.read(files.path_of(fid, "t"), "t").rays
    np.testing.assert_array_equal(whole, chunked)
    np.testing.assert_allclose(whole[:, :3], rays[:, :3] * 1e-3, rtol=1e-6, atol=1e-12)   # mm -> m
    assert not whole.flags.writeable                        # shared with the cache: never scaled in place
    nan_total = store(lambda p: tm25.write(p, rays[:100], flux="luminous", total=math.nan))
    assert pack_lights([body(nan_total)]).flux_total[0] == pytest.approx(rays[:100, 6].sum(), rel=1e-6)


def test_radiant_files_keep_their_spectrum_and_watts():
    """A radiant file's watts become lumens through its own spectrum: one wavelength (identifier 1), per-ray
    wavelengths (2: a flux-weighted histogram on the 1 nm grid) and one table (3)."""
    rays = lambertian_rays(2000, seed=3)           # flux column: 1/2000 W each
    put = _store_fn()
    mono = put(lambda p: tm25.write(p, rays, flux="radiant", total=2.0, single_nm=555.0))
    k555 = spectra.efficacy(spectra.spectrum({"type": "monochromatic", "nm": 555.0}))
    assert pack_lights([body(mono)]).flux_total[0] == pytest.approx(2.0 * k555)
    lam = np.where(np.arange(2000) < 1000, 450.0, 600.0)
    lam[0] = 1000.0                                        # infrared: outside the grid, left out of the watts
    per_ray = put(lambda p: tm25.write(p, rays, flux="radiant", wavelength_nm=lam))
    got = tm25.read(files.path_of(per_ray, "t"), "t")
    assert got.outside_nm == pytest.approx(1 / 2000, rel=1e-5)
    power = np.asarray(got.spectrum["values"])
    assert power[spectra.GRID_NM == 450.0][0] == pytest.approx(999 / 1000)   # 999 rays at 450, 1000 at 600
    assert power[spectra.GRID_NM == 600.0][0] == pytest.approx(1.0)
    assert power.sum() == pytest.approx(1.999)
    k = (999 * spectra.efficacy(spectra.spectrum({"type": "monochromatic", "nm": 450.0}))
         + 1000 * spectra.efficacy(spectra.spectrum({"type": "monochromatic", "nm": 600.0}))) / 1999
    assert pack_lights([body(per_ray)]).flux_total[0] == pytest.approx(1999 / 2000 * k, rel=1e-6)
    table = put(lambda p: tm25.write(p, rays, flux="radiant", table=([500.0, 600.0], [1.0, 1.0])))
    flat = spectra.efficacy(spectra.spectrum({"type": "table", "nm": [500.0, 600.0], "values": [1.0, 1.0]}))
    assert pack_lights([body(table)]).flux_total[0] == pytest.approx(flat, rel=1e-6)
    # a spectrum in the body wins over the file's
    red = {"type": "monochromatic", "nm": 650.0}
    k650 = spectra.efficacy(spectra.spectrum(red))
    assert pack_lights([body(mono, spectrum=red)]).flux_total[0] == pytest.approx(2.0 * k650)


def _store_fn():
    import tempfile
    from pathlib import Path

    d = Path(tempfile.mkdtemp(prefix="tm25-"))
    files.register(d)

    def put(write) -> str:
        write(d / "new")
        fid = files.file_id((d / "new").read_bytes())
        (d / "new").rename(d / fid)
        return fid
    return put


def _corrupt(raw: bytes, offset: int, fmt: str, value) -> bytes:
    b = bytearray(raw)
    struct.pack_into(fmt, b, offset, value)
    return bytes(b)


@pytest.mark.parametrize(("change", "match"), [
    (lambda b: b"TN25" + b[4:], "not a TM-25 ray file"),
    (lambda b: _corrupt(b, 4, "<i", 1999), "version 1999"),
    (lambda b: b[:-28], "truncated"),
    (lambda b: b[:1000], "truncated"),
    (lambda b: _corrupt(b, 20, "<Q", 11), "11 rays"),            # the header counts more rays than the file holds
    (lambda b: _corrupt(b, 20, "<Q", 0), "no rays"),
    (lambda b: _corrupt(b, 256 + 8, "<i", 2), "radiant flux flag must be 0 or 1"),
    (lambda b: _corrupt(_corrupt(b, 256 + 8, "<i", 0), 256 + 16, "<i", 0), "neither a radiant nor a luminous"),
    (lambda b: _corrupt(b, 60, "<i", 7), "spectral data identifier"),
    (lambda b: _corrupt(b, 60, "<i", 3), "needs spectral tables"),
    (lambda b: _corrupt(b, 76, "<i", -1), "counts are wrong"),
    (lambda b: _corrupt(b, tm25.FIXED + 4 * 5, "<f", 0.0), "zero direction"),
    (lambda b: _corrupt(b, tm25.FIXED + 4 * 6, "<f", -1.0), "negative flux"),
    (lambda b: _corrupt(b, tm25.FIXED + 4 * 7, "<f", math.nan), "ray 1 is not finite"),
], ids=["magic", "version", "truncated rays", "truncated header", "wrong count", "zero count", "flag value",
        "no flux column", "identifier", "no tables", "negative count", "zero direction", "negative flux", "nan"])
def test_a_corrupted_file_is_refused_naming_what_is_wrong(change, match):
    put = _store_fn()
    rays = np.array([[0, 0, 0, 0, 0, 1, 1.0]] * 10)
    good = put(lambda p: tm25.write(p, rays, flux="luminous"))
    raw = files.path_of(good, "t").read_bytes()
    bad = put(lambda p: p.write_bytes(change(raw)))
    with pytest.raises(LightError, match=match):
        pack_lights([body(bad, format="tm25")])


def test_a_file_id_must_name_a_stored_file_and_data_or_file_is_given_once():
    with pytest.raises(LightError, match="'file' names no stored optical file"):
        pack_lights([body("0" * 64)])
    with pytest.raises(LightError, match="'file' must be an optical file's id"):
        pack_lights([body("../etc/passwd")])
    with pytest.raises(LightError, match="exactly one"):
        pack_lights([body("0" * 64, data="0 0 0 0 0 1 1")])
    put = _store_fn()
    text = put(lambda p: p.write_text("0 0 0 0 0 1 2\n1 0 0 0 0 1 2\n"))
    L = pack_lights([body(text)])                # a text ray file uploaded once: its units (mm) apply
    assert L.flux_total[0] == pytest.approx(4.0)
    np.testing.assert_allclose(L.tri[:, 0], [0.0, 1e-3])
    with pytest.raises(LightError, match="not a TM-25 ray file"):
        pack_lights([body(text, format="tm25")])
