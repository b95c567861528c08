"""A spectral scene through the REST API (real app, real tracer): spectra on lights, spectral material values,
observed spectra and chromaticity in the answers and maps, and the 422s for bad spectral input.

The scene: a 4 m × 4 m floor in z = 0 whose reflectance is a table over λ (the scene is then spectral) and a
point source of 1 W radiant flux at 550 nm, 2 m above it: I = 679.551 / 4π cd. Receivers face up at the
floor, so they see only the direct light: E = I h / (h² + d²)^{3/2} (the floor sends its light upward).
"""

from __future__ import annotations

import io
import math

import matplotlib.image as mpimg
import numpy as np
import pytest
from service_helpers import make_client, uid
from test_simulation_api import H, disk_average_lux, push_floor, query

K550 = 683.0 * 0.99495010   # lm/W at 550 nm: 679.551
TABLE = {"nm": [380, 540, 560, 780], "values": [0.8, 0.8, 0.2, 0.2]}


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    client = make_client(tmp_path_factory.mktemp("spectral"), max_points=50, max_photons=4_000_000,
                         max_seconds=30.0)
    with client:
        scene = client.post("/scenes", json={"name": "spectral floor"}).json()
        sid = scene["id"]
        push_floor(client, sid, 0)
        r = client.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "lambertian", "reflectance": TABLE})
        assert r.status_code == 200, r.text
        r = client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0.0, 0.0, H], "flux_w": 1.0,
                                                      "spectrum": {"type": "monochromatic", "nm": 550}})
        assert r.status_code == 201, r.text
        r = client.post(f"/scenes/{sid}/sensors", json={"type": "grid", "origin": [-0.5, -0.5, 0.0],
                                                       "u": [1.0, 0.0, 0.0], "v": [0.0, 1.0, 0.0], "nu": 2, "nv": 2})
        assert r.status_code == 201, r.text
        yield client, sid, r.json()["id"]


def test_a_spectral_scene_answers_lux_spectrum_and_chromaticity(world):
    client, sid, _ = world
    pts = [[0.0, 0.0, 0.0], [0.8, 0.0, 0.0]]
    r = client.post(f"/scenes/{sid}/illuminance", json=query(pts, radius=0.2, max_photons=1_000_000, seed=3,
                                                            observe=["spectrum"]))
    assert r.status_code == 200, r.text
    a = r.json()
    assert "spectral" in a["effects"] and a["estimator"] == "forward"
    intensity = K550 / (4 * math.pi)
    for (x, y, _), e, s in zip(pts, a["lux"], a["stderr"], strict=True):
        expected = disk_average_lux(x, y, 0.2) * intensity / 100.0   # the helper's source is 100 cd
        assert abs(e - expected) <= 4 * s, (e, expected, s)
    assert len(a["nm"]) == 94 and a["nm"][0] == 362.5
    spectrum = np.asarray(a["spectral_irradiance"])
    assert spectrum.shape == (2, 94) and np.count_nonzero(spectrum, axis=1).tolist() == [1, 1]
    assert spectrum[:, 38] * 5 == pytest.approx(np.asarray(a["lux"]) / K550, rel=1e-6)   # 550–555 nm band
    assert np.abs(np.asarray(a["cie_xy"]) - [0.30160, 0.69230]).max() < 2e-4   # the 550 nm line's chromaticity


def test_without_observe_the_answer_has_no_spectrum_and_the_backward_estimator_is_refused(world):
    client, sid, _ = world
    r = client.post(f"/scenes/{sid}/illuminance", json=query([[0.0, 0.0, 0.0]], max_photons=20_000))
    assert r.status_code == 200 and "spectral_irradiance" not in r.json()
    r = client.post(f"/scenes/{sid}/illuminance", json=query([[0.0, 0.0, 0.0]], max_photons=20_000,
                                                            estimator="backward"))
    assert r.status_code == 422 and "backward" in r.json()["detail"]


def test_a_grid_observes_chromaticity_and_maps_it_in_colour(world):
    client, sid, sensor = world
    r = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 400_000, "observe": ["spectrum"]})
    assert r.status_code == 200, r.text
    a = r.json()
    assert np.asarray(a["cie_xy"]).shape == (2, 2, 2)
    assert np.asarray(a["spectral_irradiance"]).shape == (2, 2, 94)
    r = client.get(f"/scenes/{sid}/sensors/{sensor}/map.png", params={"show": "colour"})
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    img = mpimg.imread(io.BytesIO(r.content))
    rgb = img[..., :3].reshape(-1, 3)
    lit = rgb[(np.abs(rgb[:, 1] - rgb[:, 0]) > 0.2)]   # 550 nm is a saturated yellow-green: green ≫ blue
    assert len(lit) > 100 and np.median(lit[:, 1]) > np.median(lit[:, 2]) + 0.3
    # a map in colour needs an observed spectrum: a plain simulation has none
    client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 20_000})
    r = client.get(f"/scenes/{sid}/sensors/{sensor}/map.png", params={"show": "colour"})
    assert r.status_code == 404 and "observe" in r.json()["detail"]


def test_stored_spectral_bodies_come_back_as_given(world):
    client, sid, _ = world
    r = client.get(f"/scenes/{sid}/materials")
    assert r.status_code == 200
    assert [m["material"]["reflectance"] for m in r.json() if m["node"] == uid(1)] == [TABLE]


@pytest.mark.parametrize(("path", "body", "match"), [
    ("lights", {"type": "point", "position": [0, 0, 1], "flux_lm": 1, "spectrum": {"type": "laser"}}, "spectrum"),
    ("lights", {"type": "point", "position": [0, 0, 1], "flux_lm": 1,
                "spectrum": {"type": "table", "nm": [600, 500], "values": [1, 1]}}, "increase strictly"),
    ("lights", {"type": "point", "position": [0, 0, 1], "flux_lm": 1,
                "spectrum": {"type": "table", "nm": [500, 600], "values": [0, 0]}}, "no power"),
    ("lights", {"type": "point", "position": [0, 0, 1], "flux_lm": 1, "flux_w": 1}, "exactly one of"),
    ("lights", {"type": "point", "position": [0, 0, 1], "flux_w": -1}, "flux_w"),
    ("lights", {"type": "point", "position": [0, 0, 1], "flux_lm": 1,
                "spectrum": {"type": "monochromatic", "nm": 1064}}, "nm"),
    ("materials", {"type": "lambertian", "reflectance": {"nm": [400, 700], "values": [0.5, 1.5]}}, "reflectance"),
    ("materials", {"type": "lambertian", "reflectance": 0.5, "coating": {"layers": []}}, "coating"),
    ("materials", {"type": "dielectric", "ior": {"sellmeier": {"b": [1.0], "c_um2": [0.25]}}}, "pole"),
    ("materials", {"type": "mirror", "reflectance": 0.9, "coating": {"layers": [{"ior": 1.46, "thickness_nm": 94}]}},
     "metal"),
    ("materials", {"type": "mirror", "metal": [0.96, 6.69, 1.0]}, "metal"),
    ("materials", {"type": "dielectric", "ior": 1.5, "coating": {"layers": [{"ior": 1.38}]}}, "thickness_nm"),
    ("materials", {"type": "dielectric", "ior": 1.5, "fluorescence": {
        "absorption_per_m": 10, "quantum_yield": 2, "emission": {"type": "monochromatic", "nm": 550}}},
     "quantum_yield"),
])
def test_bad_spectral_input_is_a_422_that_names_the_field_and_changes_nothing(world, path, body, match):
    client, sid, _ = world
    before = client.get(f"/scenes/{sid}").json()
    lights_before = client.get(f"/scenes/{sid}/lights").json()
    materials_before = client.get(f"/scenes/{sid}/materials").json()
    if path == "lights":
        r = client.post(f"/scenes/{sid}/lights", json=body)
    else:
        r = client.put(f"/scenes/{sid}/materials/{uid(1)}", json=body)
    assert r.status_code == 422, r.text
    assert match in r.text
    assert client.get(f"/scenes/{sid}").json() == before
    assert client.get(f"/scenes/{sid}/lights").json() == lights_before
    assert client.get(f"/scenes/{sid}/materials").json() == materials_before


@pytest.mark.parametrize("observe", [["polarisation"], "spectrum", ["spectrum", "spectrum"]])
def test_an_unknown_observable_is_a_422(world, observe):
    client, sid, _ = world
    r = client.post(f"/scenes/{sid}/illuminance", json=query([[0.0, 0.0, 0.0]], observe=observe))
    assert r.status_code == 422, r.text
    assert "observe" in r.text
